//! Real servers for the remote-scene tests: nginx serving a folder (started
//! through `scripts/serve.sh`, as a user would start it), and a fault proxy
//! in front of it that answers chosen requests wrongly: a status code, the
//! whole file instead of the range, a short body, a reset or a stall, or
//! every answer late (a round-trip time) and through a link of a given rate.

use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A port free now (bound, then released).
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

/// nginx serving a folder on 127.0.0.1, stopped on drop.
#[derive(Debug)]
pub struct Nginx {
    child: Child,
    /// The server's base URL (`http://127.0.0.1:PORT`).
    pub base: String,
    /// Its port.
    pub port: u16,
    /// Its log folder (`access.log`: method, path, status, bytes, range).
    pub logs: tempfile::TempDir,
}

impl Nginx {
    /// Serves `dir`, or `None` (the skip recorded) when nginx is not
    /// installed; with `HLOD_REQUIRE_NGINX` set a missing nginx fails.
    pub fn start(test: &str, dir: &Path) -> Option<Self> {
        Self::start_script(test, "serve.sh", dir)
    }

    /// The web viewer with the 3D Tiles export in `dir`, through
    /// `scripts/serve-web.sh` (the page at `/`, the tileset at `/tiles/`).
    pub fn start_web(test: &str, dir: &Path) -> Option<Self> {
        Self::start_script(test, "serve-web.sh", dir)
    }

    /// `scripts/SCRIPT DIR PORT` on a free port.
    fn start_script(test: &str, script: &str, dir: &Path) -> Option<Self> {
        let have = Path::new("/usr/sbin/nginx").exists()
            || Command::new("nginx").arg("-v").output().is_ok();
        if !have {
            if std::env::var_os("HLOD_REQUIRE_NGINX").is_some() {
                panic!("{test}: nginx not found although HLOD_REQUIRE_NGINX is set");
            }
            crate::record_skip(test, "nginx not installed (scripts/setup.sh installs it)");
            return None;
        }
        let script = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../scripts")
            .join(script);
        let logs = tempfile::tempdir().expect("a temp dir");
        for _ in 0..5 {
            let port = free_port();
            let mut child = Command::new("bash")
                .arg(&script)
                .arg(dir)
                .arg(port.to_string())
                .env("SERVE_TMP", logs.path())
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                // Its own process group: `serve-web.sh` runs nginx as a
                // child of its shell, which a kill of the shell alone would
                // leave running (two were left by every test run).
                .process_group(0)
                .spawn()
                .expect("serve.sh starts");
            let t = Instant::now();
            while t.elapsed() < Duration::from_secs(10) {
                if TcpStream::connect(("127.0.0.1", port)).is_ok() {
                    return Some(Self {
                        child,
                        base: format!("http://127.0.0.1:{port}"),
                        port,
                        logs,
                    });
                }
                if child.try_wait().ok().flatten().is_some() {
                    break; // the port was taken meanwhile: try another
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            stop_group(&mut child);
        }
        panic!(
            "{test}: nginx did not start: {}",
            std::fs::read_to_string(logs.path().join("error.log")).unwrap_or_default()
        );
    }

    /// The lines of its access log so far.
    pub fn access_log(&self) -> Vec<String> {
        std::fs::read_to_string(self.logs.path().join("access.log"))
            .unwrap_or_default()
            .lines()
            .map(str::to_string)
            .collect()
    }
}

impl Drop for Nginx {
    fn drop(&mut self) {
        stop_group(&mut self.child);
    }
}

/// Stops `child` and every process of its group (it leads one): `TERM`
/// (nginx shuts down, the scripts' clean-up traps run), then `KILL` to
/// whatever is left after 5 s.
fn stop_group(child: &mut Child) {
    let group = format!("-{}", child.id());
    let signal = |sig: &str| {
        let _ = Command::new("kill")
            .args([sig, "--", &group])
            .stderr(Stdio::null())
            .status();
    };
    signal("-TERM");
    let t = Instant::now();
    while t.elapsed() < Duration::from_secs(5) {
        if child.try_wait().ok().flatten().is_some() {
            // nginx may outlive the shell by a moment.
            std::thread::sleep(Duration::from_millis(50));
            signal("-KILL");
            return;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    signal("-KILL");
    let _ = child.wait();
}

/// How the proxy answers one request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// Forwarded to nginx and its answer passed back.
    Pass,
    /// This status with an empty body (503, 404, 416, …).
    Status(u16),
    /// The `Range` header removed: nginx's `200` with the whole file.
    IgnoreRange,
    /// The answer's head and half its body, then the connection closed.
    ShortBody,
    /// The connection closed without an answer.
    Reset,
    /// No answer for this long, then the connection closed.
    Stall(Duration),
}

/// A proxy on 127.0.0.1 in front of a server: answers each request as the
/// next fault queued says (then [`Fault::Pass`]), each answer `delay` late
/// (a round-trip time added per request, as a far server's; a new
/// connection's handshake is not delayed). Runs until the process ends.
#[derive(Debug, Clone)]
pub struct FaultProxy {
    /// The proxy's base URL.
    pub base: String,
    queue: Arc<Mutex<VecDeque<Fault>>>,
    /// Requests seen.
    pub requests: Arc<AtomicU64>,
}

impl FaultProxy {
    /// Starts a proxy to `upstream_port`, each answer `delay` late.
    pub fn start(upstream_port: u16, delay: Duration) -> Self {
        Self::start_on(0, upstream_port, delay)
    }

    /// The same on port `port` (0: any free one).
    pub fn start_on(port: u16, upstream_port: u16, delay: Duration) -> Self {
        Self::start_link(port, upstream_port, delay, None)
    }

    /// The same with every answer's bytes sent through one link of
    /// `bytes_per_sec` that all connections share (none: as fast as the
    /// loopback): the rate a far server's path would allow.
    pub fn start_link(
        port: u16,
        upstream_port: u16,
        delay: Duration,
        bytes_per_sec: Option<f64>,
    ) -> Self {
        let link = bytes_per_sec.map(Link::new);
        let listener = TcpListener::bind(("127.0.0.1", port)).expect("binds");
        let port = listener.local_addr().expect("addr").port();
        let queue: Arc<Mutex<VecDeque<Fault>>> = Arc::default();
        let requests = Arc::new(AtomicU64::new(0));
        let (q, n) = (queue.clone(), requests.clone());
        std::thread::spawn(move || {
            for conn in listener.incoming().flatten() {
                let (q, n, link) = (q.clone(), n.clone(), link.clone());
                std::thread::spawn(move || {
                    let _ = serve_conn(conn, (upstream_port, delay, link), &q, &n);
                });
            }
        });
        Self {
            base: format!("http://127.0.0.1:{port}"),
            queue,
            requests,
        }
    }

    /// Queues `faults` for the next requests.
    pub fn push(&self, faults: &[Fault]) {
        self.queue.lock().expect("lock").extend(faults);
    }

    /// Drops the faults not yet used.
    pub fn clear(&self) {
        self.queue.lock().expect("lock").clear();
    }
}

/// A link of a fixed rate shared by the proxy's connections: each chunk
/// sent waits for the link to be free and holds it for its transfer (first
/// come, first served), so answers in flight together share the rate.
#[derive(Debug, Clone)]
struct Link {
    bytes_per_sec: f64,
    free_at: Arc<Mutex<Instant>>,
}

impl Link {
    /// Chunks sent through the link at a time.
    const CHUNK: usize = 16 << 10;

    fn new(bytes_per_sec: f64) -> Self {
        Self {
            bytes_per_sec,
            free_at: Arc::new(Mutex::new(Instant::now())),
        }
    }

    /// Writes `bytes` to `to` at the link's rate.
    fn send(&self, to: &mut TcpStream, bytes: &[u8]) -> std::io::Result<()> {
        for chunk in bytes.chunks(Self::CHUNK) {
            let done = {
                let mut free = self.free_at.lock().expect("lock");
                let start = (*free).max(Instant::now());
                *free = start + Duration::from_secs_f64(chunk.len() as f64 / self.bytes_per_sec);
                *free
            };
            std::thread::sleep(done.saturating_duration_since(Instant::now()));
            to.write_all(chunk)?;
        }
        Ok(())
    }
}

/// A request's head (through the blank line), or `None` at the end.
fn read_head(r: &mut BufReader<TcpStream>) -> std::io::Result<Option<Vec<String>>> {
    let mut lines = Vec::new();
    loop {
        let mut line = String::new();
        if r.read_line(&mut line)? == 0 {
            return Ok(None);
        }
        let line = line.trim_end().to_string();
        if line.is_empty() {
            return Ok(Some(lines));
        }
        lines.push(line);
    }
}

/// The content length a head gives (0 when none).
fn content_length(head: &[String]) -> usize {
    head.iter()
        .filter_map(|l| l.split_once(':'))
        .find(|(k, _)| k.trim().eq_ignore_ascii_case("content-length"))
        .and_then(|(_, v)| v.trim().parse().ok())
        .unwrap_or(0)
}

fn serve_conn(
    client: TcpStream,
    (upstream_port, delay, link): (u16, Duration, Option<Link>),
    queue: &Mutex<VecDeque<Fault>>,
    requests: &AtomicU64,
) -> std::io::Result<()> {
    // No Nagle: a head and a body written apart would wait for the
    // client's delayed ACK (40 ms per answer).
    client.set_nodelay(true)?;
    let mut reader = BufReader::new(client.try_clone()?);
    let mut client = client;
    let connect = || -> std::io::Result<(TcpStream, BufReader<TcpStream>)> {
        let up = TcpStream::connect(("127.0.0.1", upstream_port))?;
        up.set_nodelay(true)?;
        let r = BufReader::new(up.try_clone()?);
        Ok((up, r))
    };
    let (mut upstream, mut up_reader) = connect()?;
    while let Some(head) = read_head(&mut reader)? {
        requests.fetch_add(1, Ordering::Relaxed);
        let fault = queue
            .lock()
            .expect("lock")
            .pop_front()
            .unwrap_or(Fault::Pass);
        let is_head = head.first().is_some_and(|l| l.starts_with("HEAD "));
        std::thread::sleep(delay);
        match fault {
            Fault::Status(code) => {
                write!(client, "HTTP/1.1 {code} Fault\r\nContent-Length: 0\r\n\r\n")?;
                continue;
            }
            Fault::Reset => return Ok(()),
            Fault::Stall(d) => {
                std::thread::sleep(d);
                return Ok(());
            }
            Fault::Pass | Fault::IgnoreRange | Fault::ShortBody => {}
        }
        let mut req = String::new();
        for l in &head {
            let dropped = fault == Fault::IgnoreRange
                && l.split_once(':')
                    .is_some_and(|(k, _)| k.trim().eq_ignore_ascii_case("range"));
            if !dropped {
                req.push_str(l);
                req.push_str("\r\n");
            }
        }
        req.push_str("\r\n");
        // nginx closes a kept-alive connection after its idle timeout or
        // its request count: the request then goes on a new connection
        // (dropping the client's connection instead, with its request
        // unanswered, made the client retry: "error sending request").
        let sent_up = upstream.write_all(req.as_bytes()).is_ok();
        let resp = match sent_up.then(|| read_head(&mut up_reader)) {
            Some(Ok(Some(resp))) => resp,
            _ => {
                (upstream, up_reader) = connect()?;
                upstream.write_all(req.as_bytes())?;
                let Some(resp) = read_head(&mut up_reader)? else {
                    return Ok(());
                };
                resp
            }
        };
        let len = if is_head { 0 } else { content_length(&resp) };
        let mut body = vec![0u8; len];
        up_reader.read_exact(&mut body)?;
        let mut out = String::new();
        for l in &resp {
            out.push_str(l);
            out.push_str("\r\n");
        }
        out.push_str("\r\n");
        let mut answer = out.into_bytes();
        let sent = if fault == Fault::ShortBody {
            len / 2
        } else {
            len
        };
        answer.extend_from_slice(&body[..sent]);
        match &link {
            Some(link) => link.send(&mut client, &answer)?,
            None => client.write_all(&answer)?,
        }
        if fault == Fault::ShortBody {
            return Ok(());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An upstream that answers one request per connection and closes it
    /// (as nginx does once a kept-alive connection idles too long).
    fn one_per_connection() -> u16 {
        let listener = TcpListener::bind(("127.0.0.1", 0)).unwrap();
        let port = listener.local_addr().unwrap().port();
        std::thread::spawn(move || {
            for conn in listener.incoming().flatten() {
                let mut r = BufReader::new(conn.try_clone().unwrap());
                if read_head(&mut r).unwrap().is_some() {
                    let mut c = conn;
                    let _ = c.write_all(b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\n\r\nok");
                }
            }
        });
        port
    }

    #[test]
    fn the_proxy_answers_every_request_when_the_server_closes_its_connection() {
        let proxy = FaultProxy::start(one_per_connection(), Duration::ZERO);
        let port = proxy
            .base
            .rsplit(':')
            .next()
            .unwrap()
            .parse::<u16>()
            .unwrap();
        let client = TcpStream::connect(("127.0.0.1", port)).unwrap();
        let mut r = BufReader::new(client.try_clone().unwrap());
        let mut c = client;
        for _ in 0..3 {
            c.write_all(b"GET /x HTTP/1.1\r\nHost: a\r\n\r\n").unwrap();
            let head = read_head(&mut r)
                .unwrap()
                .expect("an answer on the same connection");
            assert!(head[0].contains("200"), "{head:?}");
            let mut body = vec![0u8; content_length(&head)];
            r.read_exact(&mut body).unwrap();
            assert_eq!(body, b"ok");
        }
        assert_eq!(proxy.requests.load(Ordering::Relaxed), 3);
    }
}
