#!/usr/bin/env bash
# A single-node Slurm cluster on this machine, with job accounting (slurmdbd on
# MariaDB) so that `sacct` reports each job's time and peak memory. Everything
# lives under DIR: configuration, state, spool, logs and the database. Nothing is
# started by systemd; `scripts/setup.sh slurm` installs the packages.
#
#   scripts/slurm-local.sh start DIR   # prints the line to source: export SLURM_CONF=DIR/slurm.conf
#   scripts/slurm-local.sh stop DIR
#
# Needs root (slurmd starts jobs as the submitting user; munged runs as `munge`).
set -euo pipefail

cmd="${1:-}"
dir="${2:-}"
if [ -z "$cmd" ] || [ -z "$dir" ]; then
  echo "usage: $0 start|stop DIR" >&2
  exit 2
fi

stop() {
  for p in ctld d dbd db; do
    [ -f "$dir/$p.pid" ] || continue
    pid="$(cat "$dir/$p.pid" 2>/dev/null || true)"
    [ -n "$pid" ] && kill "$pid" 2>/dev/null || true
  done
  # slurmctld's script helper leaves with its parent; wait for all of them.
  for _ in $(seq 50); do
    alive=0
    for p in ctld d dbd db; do
      pid="$(cat "$dir/$p.pid" 2>/dev/null || true)"
      [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null && alive=1
    done
    [ "$alive" = 0 ] && break
    sleep 0.2
  done
  rm -f "$dir"/{ctld,d,dbd,db}.pid
}

if [ "$cmd" = stop ]; then
  stop
  exit 0
fi
[ "$cmd" = start ] || {
  echo "$0: unknown command '$cmd' (start or stop)" >&2
  exit 2
}
[ "$(id -u)" = 0 ] || {
  echo "$0: needs root (slurmd and munged)" >&2
  exit 1
}
for tool in slurmctld slurmd slurmdbd sacctmgr munged mariadbd mariadb-install-db; do
  command -v "$tool" >/dev/null 2>&1 || [ -x "/usr/sbin/$tool" ] || {
    echo "$0: $tool not found; run scripts/setup.sh slurm" >&2
    exit 1
  }
done
export PATH="$PATH:/usr/sbin"

mkdir -p "$dir"
dir="$(cd "$dir" && pwd)"
mkdir -p "$dir"/{state,spool,log,db}
trap 'echo "$0: start failed; logs in $dir/log" >&2; stop' ERR

free_port() {
  python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}
wait_for() { # seconds, description, command...
  local secs="$1" what="$2"
  shift 2
  for _ in $(seq $((secs * 5))); do
    "$@" >/dev/null 2>&1 && return 0
    sleep 0.2
  done
  echo "$0: $what did not come up in ${secs} s (logs in $dir/log)" >&2
  return 1
}

# Munge: the machine's daemon, started if it is not running.
if ! pgrep -x munged >/dev/null; then
  mkdir -p /run/munge
  chown munge:munge /run/munge
  runuser -u munge -- munged
fi

db_port="$(free_port)"
dbd_port="$(free_port)"
ctld_port="$(free_port)"
d_port="$(free_port)"
host="$(hostname -s)"
cluster="hlod$(printf '%s' "$dir" | cksum | cut -c1-6)"

# MariaDB for slurmdbd, on loopback only.
if [ ! -d "$dir/db/mysql" ]; then
  mariadb-install-db --no-defaults --datadir="$dir/db" --user=root --skip-test-db \
    >"$dir/log/db-init.log" 2>&1
fi
mariadbd --no-defaults --datadir="$dir/db" --socket="$dir/db.sock" --bind-address=127.0.0.1 \
  --port="$db_port" --user=root --pid-file="$dir/db.pid" --log-error="$dir/log/db.err" \
  --innodb-buffer-pool-size=64M --innodb-lock-wait-timeout=900 </dev/null >/dev/null 2>&1 &
wait_for 30 MariaDB mariadb --no-defaults -S "$dir/db.sock" -uroot -e 'select 1'
mariadb --no-defaults -S "$dir/db.sock" -uroot -e \
  "CREATE USER IF NOT EXISTS 'slurm'@'127.0.0.1' IDENTIFIED BY 'slurm';
   GRANT ALL ON slurm_acct_db.* TO 'slurm'@'127.0.0.1';"

# slurmdbd reads slurmdbd.conf next to slurm.conf; it must be private.
umask 077
cat >"$dir/slurmdbd.conf" <<EOF
AuthType=auth/munge
DbdHost=localhost
DbdAddr=127.0.0.1
DbdPort=$dbd_port
SlurmUser=root
StorageType=accounting_storage/mysql
StorageHost=127.0.0.1
StoragePort=$db_port
StorageUser=slurm
StoragePass=slurm
StorageLoc=slurm_acct_db
PidFile=$dir/dbd.pid
LogFile=$dir/log/dbd.log
EOF
umask 022
cat >"$dir/slurm.conf" <<EOF
ClusterName=$cluster
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/ctld.pid
SlurmdPidFile=$dir/d.pid
SlurmctldLogFile=$dir/log/ctld.log
SlurmdLogFile=$dir/log/d.log
SlurmctldPort=$ctld_port
SlurmdPort=$d_port
JobAcctGatherType=jobacct_gather/linux
JobAcctGatherFrequency=task=1
AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=127.0.0.1
AccountingStoragePort=$dbd_port
ReturnToService=2
MinJobAge=300
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) RealMemory=$(($(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 - 512)) State=UNKNOWN
PartitionName=main Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$dir/slurm.conf"

setsid slurmdbd -D </dev/null >"$dir/log/dbd.out" 2>&1 &
wait_for 30 slurmdbd sacctmgr -n list cluster
sacctmgr -i add cluster "$cluster" >"$dir/log/sacctmgr.log" 2>&1 || true
setsid slurmctld -D </dev/null >"$dir/log/ctld.out" 2>&1 &
wait_for 30 slurmctld scontrol ping
setsid slurmd -D </dev/null >"$dir/log/d.out" 2>&1 &
wait_for 30 "the node" bash -c '[ "$(sinfo -h -o %T)" = idle ]'
trap - ERR
echo "export SLURM_CONF=$dir/slurm.conf"
