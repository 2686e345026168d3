//! A persistent, bounded local cache of the bytes read from a remote scene
//! (`--disk-cache DIR --disk-cache-size SIZE`), so that a second walk of the
//! same scene reads nothing from the network.
//!
//! **Layout.** `DIR/KEY/` per scene version, `KEY` a hash of the URL, the
//! length and the version pinned at open (ETag, else Last-Modified): a new
//! version of the scene on the server has another key, so a stale entry is
//! never read for it (`KEY/scene.txt` names the URL and version for people).
//! In it, one file per aligned block of [`BLOCK`] bytes (`N.blk`: the bytes,
//! then their CRC-32), written to a temporary name and renamed, so a block
//! is whole or absent.
//!
//! **What is written** is only what the remote source returned for the
//! pinned version (its length checked); **what is read** is checked against
//! the block's CRC, and a block that fails (a damaged disk, a torn copy) is
//! deleted and fetched again. The block the last read checked is kept in
//! memory for the reads after it (P_I reads in file order, many reps to a
//! block).
//!
//! **Bound.** The blocks of all scenes together stay within the size given;
//! the least recently used go first (recency in this process; at start the
//! oldest files first). Two processes sharing a folder keep their own count
//! and may together exceed it until either starts again.

use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use crate::remote::RemoteSource;
use engine::evict::lru::LruMap;
use engine::io::{ByteSource, Response};

/// Bytes per cached block: a miss fetches the aligned blocks around a read
/// (at most two blocks more than asked).
pub const BLOCK: u64 = 64 << 10;

/// The cache folder and its bound, shared by every scene read through it.
#[derive(Debug)]
pub struct DiskCache {
    dir: PathBuf,
    max_bytes: u64,
    state: Mutex<State>,
}

/// A cached block: its scene folder (an index into `State::scenes`) and
/// its index in the scene.
type BlockKey = (u32, u64);

#[derive(Debug, Default)]
struct State {
    /// The scene folders seen, numbered in the order they were.
    scenes: Vec<PathBuf>,
    /// The block files' sizes, evicted least recently used first.
    blocks: LruMap<BlockKey, u64>,
    total: u64,
}

impl State {
    /// The number of scene folder `dir`, numbered now if new.
    fn scene(&mut self, dir: &Path) -> u32 {
        match self.scenes.iter().position(|d| d == dir) {
            Some(n) => n as u32,
            None => {
                self.scenes.push(dir.to_path_buf());
                (self.scenes.len() - 1) as u32
            }
        }
    }

    fn path(&self, (scene, i): BlockKey) -> PathBuf {
        block_path(&self.scenes[scene as usize], i)
    }
}

/// Block `i`'s file in scene folder `dir`.
fn block_path(dir: &Path, i: u64) -> PathBuf {
    dir.join(format!("{i}.blk"))
}

impl DiskCache {
    /// Opens (creating) the cache in `dir`, bounded to `max_bytes`; the
    /// blocks already there count, oldest evicted first if over.
    pub fn open(dir: &Path, max_bytes: u64) -> io::Result<Arc<Self>> {
        std::fs::create_dir_all(dir)?;
        let mut state = State::default();
        let mut files = Vec::new();
        let mut scenes: Vec<_> = std::fs::read_dir(dir)?.collect::<io::Result<_>>()?;
        scenes.sort_by_key(|e| e.file_name());
        for scene in scenes {
            if !scene.file_type()?.is_dir() {
                continue;
            }
            let n = state.scene(&scene.path());
            for f in std::fs::read_dir(scene.path())? {
                let f = f?;
                let p = f.path();
                let block = p.file_stem().and_then(|s| s.to_str()?.parse::<u64>().ok());
                if let (Some(i), true) = (block, p.extension().is_some_and(|e| e == "blk")) {
                    let m = f.metadata()?;
                    files.push((m.modified().ok(), (n, i), m.len()));
                } else if p.extension().is_some_and(|e| e == "tmp") {
                    let _ = std::fs::remove_file(&p); // a copy torn by a crash
                }
            }
        }
        files.sort();
        for (_, key, len) in files {
            state.total += len;
            state.blocks.put(key, len);
        }
        let cache = Self {
            dir: dir.to_path_buf(),
            max_bytes,
            state: Mutex::new(state),
        };
        cache.evict_to(max_bytes);
        Ok(Arc::new(cache))
    }

    /// The bytes of all cached blocks (as this process counts them).
    pub fn bytes(&self) -> u64 {
        self.lock().total
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Deletes least recently used blocks until at most `room` bytes stay.
    fn evict_to(&self, room: u64) {
        let mut s = self.lock();
        while s.total > room {
            let Some((key, len)) = s.blocks.pop_victim() else {
                break;
            };
            s.total -= len;
            let _ = std::fs::remove_file(s.path(key));
        }
    }

    /// The number of scene folder `dir` in this cache's index.
    fn scene(&self, dir: &Path) -> u32 {
        self.lock().scene(dir)
    }

    /// Whether a block is in the index (no system call: P_I asks this for
    /// every candidate it times). A block another process wrote since this
    /// one opened the cache is not: it is fetched again.
    fn holds(&self, key: BlockKey) -> bool {
        self.lock().blocks.contains(key)
    }

    fn touch(&self, key: BlockKey) {
        let _ = self.lock().blocks.get(key);
    }

    /// Forgets a block and deletes its file `p`.
    fn forget(&self, key: BlockKey, p: &Path) {
        let mut s = self.lock();
        if let Some(len) = s.blocks.remove(key) {
            s.total -= len;
        }
        let _ = std::fs::remove_file(p);
    }

    /// Stores a block as file `p` (bytes and CRC), atomically, within the
    /// bound.
    fn store(&self, key: BlockKey, p: &Path, data: &[u8]) {
        let len = data.len() as u64 + 4;
        if len > self.max_bytes {
            return;
        }
        self.evict_to(self.max_bytes - len);
        // A name of its own per writer (threads and processes).
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let tmp = p.with_extension(format!("{}-{n}.tmp", std::process::id()));
        let mut bytes = Vec::with_capacity(data.len() + 4);
        bytes.extend_from_slice(data);
        bytes.extend_from_slice(&crc32fast::hash(data).to_le_bytes());
        let written = std::fs::write(&tmp, &bytes).and_then(|()| std::fs::rename(&tmp, p));
        if written.is_err() {
            let _ = std::fs::remove_file(&tmp);
            return; // a full disk: the read itself went through
        }
        let mut s = self.lock();
        if let Some(old) = s.blocks.put(key, len) {
            s.total -= old;
        }
        s.total += len;
    }
}

/// What a cached source served from where.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CacheStats {
    /// Bytes served from cached blocks.
    pub hit_bytes: u64,
    /// Bytes fetched from the server (whole blocks).
    pub fetched_bytes: u64,
    /// Cached blocks that failed their check and were fetched again.
    pub damaged: u64,
}

/// A checked block kept after a read: its index and bytes.
type LastBlock = (u64, Arc<[u8]>);

/// A remote scene read through a [`DiskCache`].
#[derive(Debug, Clone)]
pub struct CachedSource {
    remote: RemoteSource,
    cache: Arc<DiskCache>,
    dir: PathBuf,
    /// `dir`'s number in the cache's index.
    scene: u32,
    /// The last cached block read and checked: the reps P_I reads in file
    /// order lie tens to a block, and each would otherwise open, read and
    /// check the whole block again (32 times 64 KiB for reps of 2 KiB). It
    /// is the one block a read holds beside its buffer, kept until the
    /// next block is read (dropped first, so that one is held at a time).
    last: Arc<Mutex<Option<LastBlock>>>,
    hit: Arc<AtomicU64>,
    fetched: Arc<AtomicU64>,
    damaged: Arc<AtomicU64>,
}

impl CachedSource {
    /// `remote` through `cache`, in the folder of its URL and pinned version.
    pub fn new(remote: RemoteSource, cache: Arc<DiskCache>) -> io::Result<Self> {
        let id = format!("{}\n{}\n{}", remote.url(), remote.len(), remote.version());
        let key = blake3::hash(id.as_bytes()).to_hex();
        let dir = cache.dir.join(&key.as_str()[..32]);
        std::fs::create_dir_all(&dir)?;
        let note = dir.join("scene.txt");
        if !note.exists() {
            std::fs::write(&note, format!("{id}\n"))?;
        }
        let scene = cache.scene(&dir);
        Ok(Self {
            remote,
            cache,
            dir,
            scene,
            last: Arc::default(),
            hit: Arc::default(),
            fetched: Arc::default(),
            damaged: Arc::default(),
        })
    }

    /// The remote source behind it.
    pub fn remote(&self) -> &RemoteSource {
        &self.remote
    }

    /// What it served so far (all clones together).
    pub fn stats(&self) -> CacheStats {
        CacheStats {
            hit_bytes: self.hit.load(Ordering::Relaxed),
            fetched_bytes: self.fetched.load(Ordering::Relaxed),
            damaged: self.damaged.load(Ordering::Relaxed),
        }
    }

    fn block_path(&self, i: u64) -> PathBuf {
        block_path(&self.dir, i)
    }

    /// Whether block `i` is cached (as far as this process knows).
    fn holds(&self, i: u64) -> bool {
        self.cache.holds((self.scene, i))
    }

    fn block_len(&self, i: u64) -> usize {
        (self.remote.len() - i * BLOCK).min(BLOCK) as usize
    }

    /// Block `i` from the cache, checked; `None` when absent or damaged.
    fn cached(&self, i: u64) -> Option<Arc<[u8]>> {
        let mut last = self.last.lock().unwrap_or_else(|p| p.into_inner());
        // Its file was touched when it was read: no other block has been
        // read through this source since.
        if let Some((j, b)) = last.as_ref()
            && *j == i
        {
            return Some(b.clone());
        }
        *last = None;
        drop(last);
        let block: Arc<[u8]> = self.read_block(i)?.into();
        *self.last.lock().unwrap_or_else(|p| p.into_inner()) = Some((i, block.clone()));
        Some(block)
    }

    /// Block `i`'s file, checked; `None` when absent or damaged.
    fn read_block(&self, i: u64) -> Option<Vec<u8>> {
        let p = self.block_path(i);
        let mut bytes = std::fs::read(&p).ok()?;
        let want = self.block_len(i);
        let ok = bytes.len() == want + 4 && {
            let crc = u32::from_le_bytes(bytes[want..].try_into().ok()?);
            crc32fast::hash(&bytes[..want]) == crc
        };
        if !ok {
            self.damaged.fetch_add(1, Ordering::Relaxed);
            tracing::warn!("{}: a damaged cached block, fetched again", p.display());
            self.cache.forget((self.scene, i), &p);
            return None;
        }
        self.cache.touch((self.scene, i));
        bytes.truncate(want);
        Some(bytes)
    }
}

impl ByteSource for CachedSource {
    fn len(&self) -> u64 {
        self.remote.len()
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        engine::io::check_range(offset, buf.len(), self.len())?;
        if buf.is_empty() {
            return Ok(());
        }
        let end = offset + buf.len() as u64;
        let (first, last) = (offset / BLOCK, (end - 1) / BLOCK);
        // Block by block into `buf`, a run of missing blocks in one ranged
        // request: at most one cached block or one run is held beside `buf`.
        let copy = |buf: &mut [u8], start: u64, bytes: &[u8]| {
            let lo = offset.max(start);
            let hi = end.min(start + bytes.len() as u64);
            buf[(lo - offset) as usize..(hi - offset) as usize]
                .copy_from_slice(&bytes[(lo - start) as usize..(hi - start) as usize]);
            hi - lo
        };
        let mut hit = 0u64;
        let mut i = first;
        while i <= last {
            if let Some(block) = self.cached(i) {
                hit += copy(buf, i * BLOCK, &block);
                i += 1;
                continue;
            }
            let mut j = i;
            while j < last && !self.holds(j + 1) {
                j += 1;
            }
            let from = i * BLOCK;
            let to = ((j + 1) * BLOCK).min(self.len());
            let mut got = vec![0u8; (to - from) as usize];
            self.remote.read_at(from, &mut got)?;
            self.fetched.fetch_add(got.len() as u64, Ordering::Relaxed);
            for (n, chunk) in got.chunks(BLOCK as usize).enumerate() {
                let j = i + n as u64;
                self.cache
                    .store((self.scene, j), &self.block_path(j), chunk);
            }
            copy(buf, from, &got);
            i = j + 1;
        }
        self.hit.fetch_add(hit, Ordering::Relaxed);
        Ok(())
    }

    fn read_ahead_max(&self) -> u64 {
        self.remote.read_ahead_max()
    }

    fn max_requests(&self) -> usize {
        self.remote.max_requests()
    }

    fn times_requests(&self) -> bool {
        true
    }

    /// The server's answers only: a read the cache serves whole is
    /// [`is_ready`](ByteSource::is_ready) (a copy, whatever a request
    /// costs), so what P_I learns stays what a request to the server costs.
    fn responses_since(&self, seen: &mut u64, out: &mut Vec<Response>) {
        self.remote.responses_since(seen, out);
    }

    /// Served at once: every block of the range is in the cache, or the
    /// server's answer to a request started ahead is here.
    fn is_ready(&self, offset: u64, len: u64) -> bool {
        if len == 0 || offset.saturating_add(len) > self.len() {
            return false;
        }
        let (first, last) = (offset / BLOCK, (offset + len - 1) / BLOCK);
        (first..=last).all(|i| self.holds(i)) || self.remote.is_ready(offset, len)
    }

    fn set_read_ahead(&self, bytes: u64) {
        self.remote.set_read_ahead(bytes);
    }

    /// The hinted ranges' runs of blocks not in the cache, as the reads
    /// will ask the server for them (aligned to blocks): what is cached is
    /// not requested again.
    fn hint(&self, ranges: &[(u64, u64)]) {
        let len = self.len();
        let mut runs: Vec<(u64, u64)> = Vec::new();
        for &(a, b) in ranges {
            let b = b.min(len);
            if a >= b {
                continue;
            }
            let mut run: Option<(u64, u64)> = None;
            for i in a / BLOCK..=(b - 1) / BLOCK {
                if self.holds(i) {
                    runs.extend(run.take());
                } else {
                    let end = ((i + 1) * BLOCK).min(len);
                    run = Some(run.map_or((i * BLOCK, end), |(s, _)| (s, end)));
                }
            }
            runs.extend(run);
        }
        runs.dedup();
        self.remote.hint(&runs);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, SystemTime};

    #[test]
    fn opening_counts_the_blocks_there_and_evicts_the_oldest_first() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        std::fs::create_dir_all(&a).unwrap();
        std::fs::create_dir_all(&b).unwrap();
        let t0 = SystemTime::UNIX_EPOCH + Duration::from_secs(1_000_000);
        // Four blocks of 100 bytes, written at t0 + 0, 1, 2, 3 s.
        for (k, (d, i)) in [(&b, 7), (&a, 0), (&b, 2), (&a, 1)].into_iter().enumerate() {
            let p = block_path(d, i);
            std::fs::write(&p, [0u8; 100]).unwrap();
            let f = std::fs::File::options().write(true).open(&p).unwrap();
            f.set_modified(t0 + Duration::from_secs(k as u64)).unwrap();
        }
        let torn = a.join("3.123-0.tmp");
        std::fs::write(&torn, [0u8; 10]).unwrap();
        std::fs::write(a.join("scene.txt"), "a note").unwrap();

        let cache = DiskCache::open(dir.path(), 250).unwrap();
        assert_eq!(cache.bytes(), 200, "the two oldest went");
        assert!(!block_path(&b, 7).exists() && !block_path(&a, 0).exists());
        assert!(block_path(&b, 2).exists() && block_path(&a, 1).exists());
        assert!(!torn.exists(), "a torn copy is removed");
        let (na, nb) = (cache.scene(&a), cache.scene(&b));
        assert!(cache.holds((na, 1)) && cache.holds((nb, 2)));
        assert!(!cache.holds((na, 0)) && !cache.holds((nb, 7)));

        // A use moves a block to the back; a store evicts from the front.
        cache.touch((nb, 2));
        cache.store((na, 5), &block_path(&a, 5), &[1u8; 96]);
        assert!(!block_path(&a, 1).exists() && block_path(&b, 2).exists());
        assert_eq!(cache.bytes(), 200);
        cache.forget((nb, 2), &block_path(&b, 2));
        assert_eq!(cache.bytes(), 100);
        assert!(!block_path(&b, 2).exists());
        let stored = std::fs::read(block_path(&a, 5)).unwrap();
        assert_eq!(stored.len(), 100);
        assert_eq!(stored[96..], crc32fast::hash(&[1u8; 96]).to_le_bytes());
    }
}
