//! Positional byte sources: the I/O trait behind which the scene file lives.
//!
//! Everything that reads a scene goes through [`ByteSource::read_at`], so tests can
//! use [`MemSource`] and the runtime can wrap a source in a throttled disk model.

use std::collections::VecDeque;
use std::fs::File;
use std::io;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

/// One answer of a source that times its requests
/// ([`ByteSource::times_requests`]): its bytes, the time from asking to its
/// head (status and headers: the round trip and the server's time, whatever
/// the size) and to its last byte.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Response {
    pub bytes: u64,
    pub first_byte: Duration,
    pub took: Duration,
}

/// The newest answers of a source that times its requests, numbered in the
/// order they came: each reader ([`ByteSource::responses_since`]) keeps the
/// number of the last one it saw, so that a new walk on the same source
/// starts from the answers before it (the skeleton's, the last walk's).
#[derive(Clone, Debug)]
pub struct AnswerLog {
    next: u64,
    kept: VecDeque<Response>,
    cap: usize,
}

impl AnswerLog {
    /// Keeps the newest `cap` answers.
    pub fn new(cap: usize) -> Self {
        Self {
            next: 0,
            kept: VecDeque::new(),
            cap: cap.max(1),
        }
    }

    pub fn record(&mut self, r: Response) {
        if self.kept.len() == self.cap {
            self.kept.pop_front();
        }
        self.kept.push_back(r);
        self.next += 1;
    }

    /// Appends the answers kept that came after number `*seen` to `out`,
    /// oldest first, and moves `*seen` past the newest.
    pub fn since(&self, seen: &mut u64, out: &mut Vec<Response>) {
        let first = self.next - self.kept.len() as u64;
        let from = (*seen).clamp(first, self.next);
        out.extend(self.kept.iter().skip((from - first) as usize));
        *seen = self.next;
    }
}

/// A random-access, read-only byte source (a file, a buffer, a disk model).
pub trait ByteSource: Send + Sync {
    /// Total length in bytes.
    fn len(&self) -> u64;

    /// Whether the source holds no bytes.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Fills `buf` with the bytes at `offset..offset + buf.len()`.
    ///
    /// Reading past the end is an [`io::ErrorKind::UnexpectedEof`] error.
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()>;

    /// The most bytes this source would hold for reads started ahead of
    /// time ([`hint`](Self::hint)); 0, the default, when it starts none (a
    /// file or a buffer: a request costs nothing that starting early saves).
    fn read_ahead_max(&self) -> u64 {
        0
    }

    /// How many requests it starts ahead at once, at most (1, the default,
    /// for a source that starts none): P_I cuts what it hints into ranges
    /// small enough that that many fit the bytes it may hold.
    fn max_requests(&self) -> usize {
        1
    }

    /// Sets the bytes that reads started ahead may hold, in flight or done
    /// and not yet read: the runtime takes them out of the footprint
    /// ([`crate::runtime::Footprint`]). 0 turns reading ahead off.
    fn set_read_ahead(&self, _bytes: u64) {}

    /// The reads that come next, most urgent first, as byte ranges
    /// `start..end`: a source whose requests have a high fixed cost (a
    /// network's round trip) starts several of them at once, within what
    /// [`set_read_ahead`](Self::set_read_ahead) allows, and serves a later
    /// [`read_at`](Self::read_at) inside one from it. A hint replaces the
    /// one before: ranges no longer hinted are dropped, and their requests
    /// cancelled.
    fn hint(&self, _ranges: &[(u64, u64)]) {}

    /// Whether a read of `offset..offset + len` would be served at once,
    /// from an answer to a request started ahead that is already here
    /// (P_I may then start it whatever a request costs).
    fn is_ready(&self, _offset: u64, _len: u64) -> bool {
        false
    }

    /// Whether this source times its own requests (a network's, whose
    /// answers may come before they are read): P_I then learns what a
    /// request costs from [`responses_since`](Self::responses_since) — a
    /// round trip and a rate — rather than from how long its reads take,
    /// since a read served from an answer already here takes no time.
    /// `false`, the default: a read is a request (a file, a disk model).
    fn times_requests(&self) -> bool {
        false
    }

    /// Appends the answers after number `*seen` to `out`, oldest first, and
    /// moves `*seen` past them (a source keeps a bounded number:
    /// [`AnswerLog`]; 0 gives all it kept).
    fn responses_since(&self, _seen: &mut u64, _out: &mut Vec<Response>) {}
}

/// A shared source is a source (a walk and a reader of the skeleton may
/// hold the same one).
impl<T: ByteSource + ?Sized> ByteSource for Arc<T> {
    fn len(&self) -> u64 {
        (**self).len()
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        (**self).read_at(offset, buf)
    }

    fn read_ahead_max(&self) -> u64 {
        (**self).read_ahead_max()
    }

    fn set_read_ahead(&self, bytes: u64) {
        (**self).set_read_ahead(bytes);
    }

    fn max_requests(&self) -> usize {
        (**self).max_requests()
    }

    fn hint(&self, ranges: &[(u64, u64)]) {
        (**self).hint(ranges);
    }

    fn is_ready(&self, offset: u64, len: u64) -> bool {
        (**self).is_ready(offset, len)
    }

    fn times_requests(&self) -> bool {
        (**self).times_requests()
    }

    fn responses_since(&self, seen: &mut u64, out: &mut Vec<Response>) {
        (**self).responses_since(seen, out);
    }
}

/// A scene file on disk, read with positional reads (no shared cursor).
#[derive(Debug)]
pub struct FileSource {
    file: File,
    len: u64,
}

impl FileSource {
    /// Opens `path` for reading (a regular file: [`crate::infile`]).
    pub fn open(path: &Path) -> io::Result<Self> {
        Self::from_file(crate::infile::open(path)?)
    }

    /// Reads from an open file.
    pub fn from_file(file: File) -> io::Result<Self> {
        let len = file.metadata()?.len();
        Ok(Self { file, len })
    }

    /// The underlying file.
    pub fn file(&self) -> &File {
        &self.file
    }
}

impl ByteSource for FileSource {
    fn len(&self) -> u64 {
        self.len
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        check_range(offset, buf.len(), self.len)?;
        #[cfg(unix)]
        {
            std::os::unix::fs::FileExt::read_exact_at(&self.file, buf, offset)
        }
        #[cfg(windows)]
        {
            let mut done = 0;
            while done < buf.len() {
                let n = std::os::windows::fs::FileExt::seek_read(
                    &self.file,
                    &mut buf[done..],
                    offset + done as u64,
                )?;
                if n == 0 {
                    return Err(io::ErrorKind::UnexpectedEof.into());
                }
                done += n;
            }
            Ok(())
        }
    }
}

/// An in-memory byte source (tests, in-core mode, fault injection).
#[derive(Debug, Clone)]
pub struct MemSource {
    bytes: Arc<[u8]>,
}

impl MemSource {
    /// Wraps `bytes`.
    pub fn new(bytes: impl Into<Arc<[u8]>>) -> Self {
        Self {
            bytes: bytes.into(),
        }
    }
}

impl ByteSource for MemSource {
    fn len(&self) -> u64 {
        self.bytes.len() as u64
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        check_range(offset, buf.len(), self.len())?;
        let start = offset as usize;
        buf.copy_from_slice(&self.bytes[start..start + buf.len()]);
        Ok(())
    }
}

/// A window `base..base + len` of another source, whose first bytes may be
/// held in memory already: an object embedded in a scene file (a
/// view-dependence tree, whose in-core part P_I has read as its payload).
#[derive(Clone)]
pub struct WindowSource {
    inner: Arc<dyn ByteSource>,
    base: u64,
    len: u64,
    prefix: Arc<[u8]>,
}

impl std::fmt::Debug for WindowSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WindowSource")
            .field("base", &self.base)
            .field("len", &self.len)
            .field("prefix", &self.prefix.len())
            .finish()
    }
}

impl WindowSource {
    /// The bytes `base..base + len` of `inner`, the first `prefix.len()` of
    /// them served from `prefix`. Fails when the window is not inside
    /// `inner` or the prefix is longer than the window.
    pub fn new(
        inner: Arc<dyn ByteSource>,
        base: u64,
        len: u64,
        prefix: Arc<[u8]>,
    ) -> io::Result<Self> {
        if base.checked_add(len).is_none_or(|e| e > inner.len()) || prefix.len() as u64 > len {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "window {base}+{len} outside a source of {} bytes",
                    inner.len()
                ),
            ));
        }
        Ok(Self {
            inner,
            base,
            len,
            prefix,
        })
    }
}

impl ByteSource for WindowSource {
    fn len(&self) -> u64 {
        self.len
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        check_range(offset, buf.len(), self.len)?;
        let p = self.prefix.len() as u64;
        let mut done = 0usize;
        if offset < p {
            let n = ((p - offset) as usize).min(buf.len());
            let at = offset as usize;
            buf[..n].copy_from_slice(&self.prefix[at..at + n]);
            done = n;
        }
        if done < buf.len() {
            let at = offset + done as u64;
            self.inner.read_at(self.base + at, &mut buf[done..])?;
        }
        Ok(())
    }
}

/// A read of `len` bytes at `offset` ends within `total` bytes, else the
/// [`io::ErrorKind::UnexpectedEof`] every source answers.
pub fn check_range(offset: u64, len: usize, total: u64) -> io::Result<()> {
    match offset.checked_add(len as u64) {
        Some(end) if end <= total => Ok(()),
        _ => Err(io::Error::new(
            io::ErrorKind::UnexpectedEof,
            format!("read of {len} bytes at offset {offset} past the end ({total} bytes)"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mem_source_reads_and_rejects_out_of_range() {
        let src = MemSource::new(vec![1u8, 2, 3, 4]);
        let mut buf = [0u8; 2];
        src.read_at(2, &mut buf).unwrap();
        assert_eq!(buf, [3, 4]);
        assert_eq!(
            src.read_at(3, &mut buf).unwrap_err().kind(),
            io::ErrorKind::UnexpectedEof
        );
        assert!(src.read_at(u64::MAX, &mut buf).is_err());
    }

    #[test]
    fn window_reads_prefix_then_inner() {
        let inner: Arc<dyn ByteSource> = Arc::new(MemSource::new((0u8..32).collect::<Vec<_>>()));
        let w = WindowSource::new(inner.clone(), 8, 16, Arc::from(vec![100u8, 101, 102])).unwrap();
        let mut buf = [0u8; 6];
        w.read_at(1, &mut buf).unwrap();
        assert_eq!(buf, [101, 102, 11, 12, 13, 14]);
        w.read_at(10, &mut buf).unwrap();
        assert_eq!(buf, [18, 19, 20, 21, 22, 23]);
        assert!(w.read_at(11, &mut buf).is_err());
        assert!(WindowSource::new(inner.clone(), 20, 16, Arc::from(vec![])).is_err());
        assert!(WindowSource::new(inner, 0, 2, Arc::from(vec![0u8; 3])).is_err());
    }

    #[test]
    fn an_answer_log_keeps_the_newest_and_each_reader_its_place() {
        let a = |n: u64| Response {
            bytes: n,
            first_byte: Duration::from_millis(1),
            took: Duration::from_millis(n),
        };
        let mut log = AnswerLog::new(3);
        let (mut seen, mut out) = (0u64, Vec::new());
        log.since(&mut seen, &mut out);
        assert!(out.is_empty());
        for n in 1..=5 {
            log.record(a(n));
        }
        // The newest three; older ones are gone.
        log.since(&mut seen, &mut out);
        assert_eq!(out, vec![a(3), a(4), a(5)]);
        assert_eq!(seen, 5);
        log.record(a(6));
        out.clear();
        log.since(&mut seen, &mut out);
        assert_eq!(out, vec![a(6)]);
        // A new reader starts from all that is kept.
        out.clear();
        log.since(&mut 0, &mut out);
        assert_eq!(out, vec![a(4), a(5), a(6)]);
    }
}
