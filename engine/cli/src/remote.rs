//! Scenes on a web server (`http://`, `https://`) or in S3-compatible
//! object storage (`s3://bucket/key`), read with ranged GETs.
//!
//! Through `object_store`: one API over HTTP range requests and S3 (and
//! GCS or Azure later), with retries and exponential backoff, connect,
//! read (stall) and whole-request time-outs, and a check of every ranged
//! answer (a `206` with the asked `Content-Range`: a server that ignores
//! `Range` and answers `200` with the whole file is refused before its body
//! is read). The engine's loader threads are plain threads, so a source owns
//! a small tokio runtime and blocks on each request.
//!
//! **Consistency.** Opening pins the object's version (length, ETag, else
//! Last-Modified). Every later read asks for that version (`If-Match`, else
//! `If-Unmodified-Since`) and checks what comes back; when the object
//! changed, the source says so once and fails every later read without
//! asking again: the old skeleton is never fed the new file's bytes.
//!
//! **Credentials** come from the environment (`AWS_ACCESS_KEY_ID`,
//! `AWS_SECRET_ACCESS_KEY`, `AWS_SESSION_TOKEN`, `AWS_REGION`,
//! `AWS_ENDPOINT_URL`, `AWS_ALLOW_HTTP`, as object_store reads them); a URL
//! with a user name, password or query string is refused, so that no secret
//! is ever given on a command line or written to a log.

use std::io;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use object_store::aws::{AmazonS3Builder, AmazonS3ConfigKey};
use object_store::http::HttpBuilder;
use object_store::path::Path as StorePath;
use object_store::{
    BackoffConfig, ClientConfigKey, ClientOptions, GetOptions, GetRange, ObjectMeta, ObjectStore,
    ObjectStoreExt, RetryConfig,
};

use engine::io::{AnswerLog, ByteSource, Response};
use futures_util::StreamExt;
use tokio::task::JoinHandle;

use crate::read_ahead::{Lookup, ReadAhead};

/// Whether `s` names a remote scene (a URL this module reads).
pub fn is_remote(s: &str) -> bool {
    ["http://", "https://", "s3://"]
        .iter()
        .any(|p| s.len() > p.len() && s[..p.len()].eq_ignore_ascii_case(p))
}

/// Time-outs and retries of a remote source.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RemoteOptions {
    /// Establishing a connection.
    pub connect_timeout: Duration,
    /// The longest wait for the next bytes of an answer (a stalled server).
    pub read_timeout: Duration,
    /// The longest a whole request may take.
    pub timeout: Duration,
    /// Retries of a failed request (connection refused or reset, 5xx,
    /// time-out), with exponential backoff.
    pub retries: usize,
    /// The first backoff; it doubles up to `max_backoff`.
    pub init_backoff: Duration,
    /// The longest backoff.
    pub max_backoff: Duration,
    /// No retry starts later than this after the first try.
    pub retry_timeout: Duration,
    /// Requests P_I may have in flight at once for the ranges it reads
    /// next ([`engine::ByteSource::hint`]); 1 reads one range at a time.
    pub max_requests: usize,
    /// The most bytes those requests may hold (the runtime takes them out
    /// of the footprint, and may give them less).
    pub read_ahead_bytes: u64,
}

impl Default for RemoteOptions {
    fn default() -> Self {
        Self {
            connect_timeout: Duration::from_secs(5),
            read_timeout: Duration::from_secs(10),
            timeout: Duration::from_secs(120),
            retries: 4,
            init_backoff: Duration::from_millis(100),
            max_backoff: Duration::from_secs(2),
            retry_timeout: Duration::from_secs(20),
            max_requests: crate::scene_handle::DEFAULT_REQUESTS,
            read_ahead_bytes: crate::scene_handle::DEFAULT_READ_AHEAD,
        }
    }
}

/// What opening a remote scene can fail with.
#[derive(Debug, thiserror::Error)]
pub enum RemoteError {
    /// The text is not a URL this module reads.
    #[error("{url}: {why}")]
    BadUrl {
        /// The URL as given (only when it holds no credentials).
        url: String,
        /// What is wrong with it.
        why: String,
    },
    /// The object is not on the server (404, or no such bucket or key).
    #[error("{url}: not found on the server")]
    NotFound {
        /// The scene's URL.
        url: String,
    },
    /// The client could not be set up, or the first request failed.
    #[error("{url}: {what}: {source}")]
    Store {
        /// The scene's URL.
        url: String,
        /// What was being done.
        what: &'static str,
        /// object_store's error.
        #[source]
        source: object_store::Error,
    },
    /// The runtime the requests run on could not start.
    #[error("{url}: starting the HTTP client's runtime: {source}")]
    Runtime {
        /// The scene's URL.
        url: String,
        /// The OS error.
        #[source]
        source: io::Error,
    },
}

/// Requests and bytes a remote source has served (shared by its clones).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RemoteStats {
    /// Ranged GETs answered.
    pub requests: u64,
    /// Bytes they returned.
    pub bytes: u64,
    /// Reads that failed (after object_store's retries).
    pub failures: u64,
    /// Reading ahead: reads served from requests started ahead, requests
    /// started, dropped (no longer hinted) and the bytes dropped unread,
    /// the most in flight at once.
    pub ahead: crate::read_ahead::AheadStats,
}

/// A scene object on a server, pinned to the version it had when opened.
/// Clones share the connection pool, the runtime and the counters.
#[derive(Clone)]
pub struct RemoteSource {
    inner: Arc<Inner>,
}

struct Inner {
    conn: Arc<Conn>,
    rt: tokio::runtime::Runtime,
    ahead: std::sync::Mutex<ReadAhead<JoinHandle<io::Result<Vec<u8>>>>>,
    read_ahead_max: u64,
    max_requests: usize,
}

/// What a request needs (shared with the requests in flight, which must
/// not own the runtime they run on).
struct Conn {
    url: String,
    store: Arc<dyn ObjectStore>,
    path: StorePath,
    meta: ObjectMeta,
    changed: AtomicBool,
    requests: AtomicU64,
    bytes: AtomicU64,
    failures: AtomicU64,
    /// The newest [`ANSWERS_KEPT`] answers, for P_I to learn from.
    answers: std::sync::Mutex<AnswerLog>,
}

/// Answers kept for P_I to learn from; older ones are dropped.
const ANSWERS_KEPT: usize = 1024;

impl std::fmt::Debug for RemoteSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RemoteSource")
            .field("url", &self.inner.conn.url)
            .field("len", &self.inner.conn.meta.size)
            .field("e_tag", &self.inner.conn.meta.e_tag)
            .finish()
    }
}

impl RemoteSource {
    /// Opens the scene at `url` (`http(s)://…` or `s3://bucket/key`): asks
    /// for its length and version (a HEAD request), which every later read
    /// must match.
    pub fn open(url: &str, opts: &RemoteOptions) -> Result<Self, RemoteError> {
        let (store, path) = store_for(url, opts)?;
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("hlod-remote")
            .enable_all()
            .build()
            .map_err(|source| RemoteError::Runtime {
                url: url.to_string(),
                source,
            })?;
        let meta = rt.block_on(store.head(&path)).map_err(|e| match e {
            object_store::Error::NotFound { .. } => RemoteError::NotFound {
                url: url.to_string(),
            },
            source => RemoteError::Store {
                url: url.to_string(),
                what: "asking for the scene's length and version",
                source,
            },
        })?;
        Ok(Self {
            inner: Arc::new(Inner {
                conn: Arc::new(Conn {
                    url: url.to_string(),
                    store,
                    path,
                    meta,
                    changed: AtomicBool::new(false),
                    requests: AtomicU64::new(0),
                    bytes: AtomicU64::new(0),
                    failures: AtomicU64::new(0),
                    answers: std::sync::Mutex::new(AnswerLog::new(ANSWERS_KEPT)),
                }),
                rt,
                ahead: std::sync::Mutex::new(ReadAhead::new(opts.max_requests)),
                max_requests: opts.max_requests.max(1),
                read_ahead_max: if opts.max_requests > 1 {
                    opts.read_ahead_bytes
                } else {
                    0
                },
            }),
        })
    }

    /// The URL it was opened with.
    pub fn url(&self) -> &str {
        &self.inner.conn.url
    }

    /// The version pinned at open: the ETag, else the Last-Modified time.
    pub fn version(&self) -> String {
        self.inner.conn.version()
    }

    /// Whether the object changed on the server since it was opened (then
    /// every read fails).
    pub fn changed(&self) -> bool {
        self.inner.conn.changed.load(Ordering::Relaxed)
    }

    /// What it has served so far (all clones together).
    pub fn stats(&self) -> RemoteStats {
        let c = &self.inner.conn;
        RemoteStats {
            requests: c.requests.load(Ordering::Relaxed),
            bytes: c.bytes.load(Ordering::Relaxed),
            failures: c.failures.load(Ordering::Relaxed),
            ahead: self.ahead().stats(),
        }
    }

    fn ahead(&self) -> std::sync::MutexGuard<'_, ReadAhead<JoinHandle<io::Result<Vec<u8>>>>> {
        self.inner.ahead.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Starts a request for `start..end` on the runtime.
    fn starter(&self) -> impl FnMut(u64, u64) -> JoinHandle<io::Result<Vec<u8>>> + '_ {
        move |a, b| {
            let conn = self.inner.conn.clone();
            self.inner.rt.spawn(async move {
                let mut buf = vec![0u8; (b - a) as usize];
                conn.get(a, &mut buf).await.map(|()| buf)
            })
        }
    }

    /// A read inside a range requested ahead: `true` when served from it.
    fn read_from_ahead(&self, offset: u64, buf: &mut [u8]) -> bool {
        let looked = self.ahead().lookup(offset, buf);
        match looked {
            Lookup::Done => {
                let cancel = self.ahead().refill(self.starter());
                cancel.iter().for_each(JoinHandle::abort);
                true
            }
            Lookup::Miss => false,
            Lookup::Wait { handle, start } => {
                let answer = self.inner.rt.block_on(handle).ok().and_then(Result::ok);
                let (ok, cancel) = self
                    .ahead()
                    .finish(start, answer, offset, buf, self.starter());
                cancel.iter().for_each(JoinHandle::abort);
                ok
            }
        }
    }
}

impl Conn {
    fn record(&self, r: Response) {
        let mut answers = self.answers.lock().unwrap_or_else(|e| e.into_inner());
        answers.record(r);
    }

    /// The version pinned at open: the ETag, else the Last-Modified time.
    fn version(&self) -> String {
        match &self.meta.e_tag {
            Some(t) => format!("ETag {t}"),
            None => format!("Last-Modified {}", self.meta.last_modified),
        }
    }

    fn changed_error(&self, what: &str) -> io::Error {
        let first = !self.changed.swap(true, Ordering::Relaxed);
        if first {
            tracing::error!(
                "{} changed on the server during the walk ({}; opened at {}): reads of the old scene stop, its resident reps stay drawn; open it again to see the new version",
                self.url,
                what,
                self.version()
            );
        }
        io::Error::new(
            io::ErrorKind::StaleNetworkFileHandle,
            format!(
                "{}: the scene changed on the server since it was opened ({})",
                self.url,
                self.version()
            ),
        )
    }

    /// One ranged GET of the pinned version into `buf`; an answer counts
    /// as a request and its bytes.
    async fn get(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let asked = Instant::now();
        let end = offset + buf.len() as u64;
        let opts = GetOptions {
            range: Some(GetRange::Bounded(offset..end)),
            if_match: self.meta.e_tag.clone(),
            if_unmodified_since: self.meta.e_tag.is_none().then_some(self.meta.last_modified),
            ..GetOptions::default()
        };
        let res = match self.store.get_opts(&self.path, opts).await {
            Ok(r) => r,
            Err(object_store::Error::Precondition { .. }) => {
                return Err(self.changed_error("the server refused the pinned version"));
            }
            Err(object_store::Error::NotFound { .. }) => {
                return Err(self.changed_error("it is no longer there"));
            }
            Err(e) => {
                return Err(io::Error::other(format!(
                    "{}: bytes {offset}..{end}: {e}",
                    self.url
                )));
            }
        };
        // The head is here: a round trip and the server's time, whatever the
        // size (the cost model learns the round trip from it).
        let first_byte = asked.elapsed();
        if res.meta.size != self.meta.size
            || (self.meta.e_tag.is_some() && res.meta.e_tag != self.meta.e_tag)
        {
            return Err(self.changed_error(&format!(
                "now {} bytes, ETag {}",
                res.meta.size,
                res.meta.e_tag.as_deref().unwrap_or("none")
            )));
        }
        if res.range != (offset..end) {
            return Err(io::Error::other(format!(
                "{}: asked for bytes {offset}..{end}, the server sent {:?}",
                self.url, res.range
            )));
        }
        // The body goes into `buf` as it arrives: no second copy of the
        // range is held (only the chunk being copied), so what a request
        // holds is what the footprint counts for it.
        let mut body = res.into_stream();
        let mut got = 0usize;
        while let Some(chunk) = body.next().await {
            let chunk = chunk.map_err(|e| {
                io::Error::other(format!("{}: bytes {offset}..{end}: {e}", self.url))
            })?;
            let Some(to) = buf.get_mut(got..got + chunk.len()) else {
                return Err(io::Error::other(format!(
                    "{}: bytes {offset}..{end}: the answer is longer than asked",
                    self.url
                )));
            };
            to.copy_from_slice(&chunk);
            got += chunk.len();
        }
        if got != buf.len() {
            return Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                format!(
                    "{}: bytes {offset}..{end}: a short answer of {got} bytes",
                    self.url
                ),
            ));
        }
        self.record(Response {
            bytes: buf.len() as u64,
            first_byte,
            took: asked.elapsed(),
        });
        self.requests.fetch_add(1, Ordering::Relaxed);
        self.bytes.fetch_add(buf.len() as u64, Ordering::Relaxed);
        Ok(())
    }
}

impl ByteSource for RemoteSource {
    fn len(&self) -> u64 {
        self.inner.conn.meta.size
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        engine::io::check_range(offset, buf.len(), self.len())?;
        if buf.is_empty() {
            return Ok(());
        }
        let conn = &self.inner.conn;
        if self.changed() {
            // No request for a version the server no longer has.
            conn.failures.fetch_add(1, Ordering::Relaxed);
            return Err(conn.changed_error(""));
        }
        if self.read_from_ahead(offset, buf) {
            return Ok(());
        }
        let res = self.inner.rt.block_on(conn.get(offset, buf));
        if res.is_err() {
            conn.failures.fetch_add(1, Ordering::Relaxed);
        }
        res
    }

    fn read_ahead_max(&self) -> u64 {
        self.inner.read_ahead_max
    }

    fn max_requests(&self) -> usize {
        self.inner.max_requests
    }

    fn set_read_ahead(&self, bytes: u64) {
        let cancel = self.ahead().set_cap(bytes.min(self.inner.read_ahead_max));
        cancel.iter().for_each(JoinHandle::abort);
    }

    fn is_ready(&self, offset: u64, len: u64) -> bool {
        self.ahead().is_ready(offset, len, JoinHandle::is_finished)
    }

    fn times_requests(&self) -> bool {
        true
    }

    fn responses_since(&self, seen: &mut u64, out: &mut Vec<Response>) {
        let answers = self
            .inner
            .conn
            .answers
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        answers.since(seen, out);
    }

    fn hint(&self, ranges: &[(u64, u64)]) {
        let len = self.len();
        let ranges: Vec<(u64, u64)> = ranges
            .iter()
            .map(|&(a, b)| (a, b.min(len)))
            .filter(|&(a, b)| a < b)
            .collect();
        let cancel = self.ahead().hint(&ranges, self.starter());
        cancel.iter().for_each(JoinHandle::abort);
    }
}

/// The store and object path a URL names, with `opts`' time-outs and
/// retries.
fn store_for(
    url: &str,
    opts: &RemoteOptions,
) -> Result<(Arc<dyn ObjectStore>, StorePath), RemoteError> {
    let bad = |why: &str| RemoteError::BadUrl {
        url: url.to_string(),
        why: why.to_string(),
    };
    let (scheme, rest) = url.split_once("://").ok_or_else(|| bad("not a URL"))?;
    let scheme = scheme.to_ascii_lowercase();
    if rest.contains(['?', '#']) {
        return Err(bad(
            "a query string or fragment is not accepted (credentials come from the environment)",
        ));
    }
    let (authority, key) = rest.split_once('/').unwrap_or((rest, ""));
    if authority.contains('@') {
        // Not echoed: the text before '@' may be a password.
        return Err(RemoteError::BadUrl {
            url: format!("{scheme}://…@{}", authority.rsplit('@').next().unwrap_or("")),
            why: "a user name or password in the URL is not accepted; give credentials through the environment".into(),
        });
    }
    if authority.is_empty() || key.is_empty() || key.ends_with('/') {
        return Err(bad("names no object (expected scheme://host/…/scene.hlod)"));
    }
    let retry = RetryConfig {
        backoff: BackoffConfig {
            init_backoff: opts.init_backoff,
            max_backoff: opts.max_backoff,
            base: 2.0,
        },
        max_retries: opts.retries,
        retry_timeout: opts.retry_timeout,
    };
    let store_err = |source| RemoteError::Store {
        url: url.to_string(),
        what: "setting up the client",
        source,
    };
    let path = |k: &str| StorePath::from_url_path(k).map_err(|e| bad(&format!("its path: {e}")));
    match scheme.as_str() {
        "http" | "https" => {
            // The store's URL is the object's folder; the path its name.
            let (dir, name) = key.rsplit_once('/').unwrap_or(("", key));
            let base = if dir.is_empty() {
                format!("{scheme}://{authority}")
            } else {
                format!("{scheme}://{authority}/{dir}")
            };
            let client = ClientOptions::new()
                .with_allow_http(scheme == "http")
                .with_connect_timeout(opts.connect_timeout)
                .with_read_timeout(opts.read_timeout)
                .with_timeout(opts.timeout);
            let store = HttpBuilder::new()
                .with_url(base)
                .with_client_options(client)
                .with_retry(retry)
                .build()
                .map_err(store_err)?;
            Ok((Arc::new(store), path(name)?))
        }
        "s3" => {
            let secs = |d: Duration| format!("{}ms", d.as_millis());
            let store = AmazonS3Builder::from_env()
                .with_bucket_name(authority)
                .with_config(
                    AmazonS3ConfigKey::Client(ClientConfigKey::ConnectTimeout),
                    secs(opts.connect_timeout),
                )
                .with_config(
                    AmazonS3ConfigKey::Client(ClientConfigKey::ReadTimeout),
                    secs(opts.read_timeout),
                )
                .with_config(
                    AmazonS3ConfigKey::Client(ClientConfigKey::Timeout),
                    secs(opts.timeout),
                )
                .with_retry(retry)
                .build()
                .map_err(store_err)?;
            Ok((Arc::new(store), path(key)?))
        }
        _ => Err(bad("use http://, https:// or s3://")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recognises_remote_names() {
        for s in ["http://h/a.hlod", "HTTPS://h/a", "s3://b/k"] {
            assert!(is_remote(s), "{s}");
        }
        for s in ["a.hlod", "dir/http://x", "http://", "file:///a"] {
            assert!(!is_remote(s), "{s}");
        }
    }

    #[test]
    fn refuses_credentials_queries_and_folders() {
        let o = RemoteOptions::default();
        let e = store_for("http://user:hunter2@h/a.hlod", &o)
            .err()
            .unwrap()
            .to_string();
        assert!(!e.contains("hunter2") && e.contains("environment"), "{e}");
        for u in [
            "http://h/a.hlod?X-Amz-Signature=1",
            "http://h/",
            "http://h",
            "ftp://h/a",
        ] {
            assert!(store_for(u, &o).is_err(), "{u}");
        }
        assert!(store_for("http://127.0.0.1:1/d/a%20b.hlod", &o).is_ok());
    }

    #[test]
    fn a_server_that_is_down_is_a_clear_error() {
        let o = RemoteOptions {
            retries: 1,
            init_backoff: Duration::from_millis(10),
            ..RemoteOptions::default()
        };
        // A port nothing listens on (bound, then released).
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let url = format!("http://127.0.0.1:{port}/s.hlod");
        let e = RemoteSource::open(&url, &o).unwrap_err().to_string();
        assert!(
            e.starts_with(&url) && e.contains("length and version"),
            "{e}"
        );
    }
}
