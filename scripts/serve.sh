#!/usr/bin/env bash
# Serves the files of DIR over HTTP on 127.0.0.1:PORT with nginx (range
# requests, ETag and Last-Modified, as a web server or CDN answers them), so
# that a scene there opens as http://127.0.0.1:PORT/NAME.hlod:
#
#   bash scripts/serve.sh DIR [PORT]        (default port 8080; Ctrl-C stops it)
#
# nginx runs in the foreground as the calling user, from a configuration
# written to a temporary directory (SERVE_TMP, if set) that also holds its
# logs (access.log: one line per request, with the range asked) and temp
# paths. scripts/setup.sh installs nginx-light; the remote tests start the
# server through this script.
set -euo pipefail
if [ $# -lt 1 ] || [ ! -d "$1" ]; then
  echo "usage: serve.sh DIR [PORT]  (DIR: an existing folder)" >&2
  exit 2
fi
root=$(cd "$1" && pwd)
port=${2:-8080}
case "$port" in ''|*[!0-9]*) echo "serve.sh: port $port is not a number" >&2; exit 2 ;; esac
nginx=$(command -v nginx || echo /usr/sbin/nginx)
[ -x "$nginx" ] || { echo "serve.sh: nginx not found (run scripts/setup.sh)" >&2; exit 1; }
tmp=${SERVE_TMP:-$(mktemp -d)}
mkdir -p "$tmp"
user=""
# As root, the worker would switch to nobody and lose access to DIR.
if [ "$(id -u)" = 0 ]; then user="user root root;"; fi
cat > "$tmp/nginx.conf" <<CONF
daemon off;
master_process off;
worker_processes 1;
$user
pid $tmp/nginx.pid;
error_log $tmp/error.log warn;
events { worker_connections 256; }
http {
  include /etc/nginx/mime.types;
  default_type application/octet-stream;
  log_format ranges '\$request_method \$uri \$status \$body_bytes_sent "\$http_range"';
  access_log $tmp/access.log ranges;
  client_body_temp_path $tmp/body;
  proxy_temp_path $tmp/proxy;
  fastcgi_temp_path $tmp/fastcgi;
  uwsgi_temp_path $tmp/uwsgi;
  scgi_temp_path $tmp/scgi;
  sendfile on;
  keepalive_requests 100000;
  server {
    listen 127.0.0.1:$port;
    root $root;
    location / { }
  }
}
CONF
echo "serve: http://127.0.0.1:$port/ serves $root (logs in $tmp)"
exec "$nginx" -e "$tmp/error.log" -p "$tmp" -c "$tmp/nginx.conf"
