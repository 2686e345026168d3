//! Disk models behind [`ByteSource`]: the real file (optionally with its page
//! cache dropped first) or a throttled device with a seek latency and a
//! bandwidth, so that the papers' slow-disk regime can be reproduced here.

use crate::clock::ManualClock;
use std::io;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use crate::io::ByteSource;

/// A device model: a seek costs `latency` (reads that continue where the
/// previous one ended do not seek), every byte `1 / bytes_per_sec`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiskModel {
    pub latency: Duration,
    pub bytes_per_sec: f64,
}

impl DiskModel {
    /// A 2002-era disk as in the papers: 10 ms seeks, 30 MB/s.
    pub const HDD: Self = Self {
        latency: Duration::from_millis(10),
        bytes_per_sec: 30e6,
    };
    /// A SATA SSD: 0.1 ms, 500 MB/s.
    pub const SSD: Self = Self {
        latency: Duration::from_micros(100),
        bytes_per_sec: 500e6,
    };
    /// An NVMe drive: 20 µs, 3 GB/s.
    pub const NVME: Self = Self {
        latency: Duration::from_micros(20),
        bytes_per_sec: 3e9,
    };

    /// A preset by name (`hdd`, `ssd`, `nvme`) or `LATENCY_MS:MB_PER_S`.
    pub fn parse(s: &str) -> Result<Self, String> {
        match s {
            "hdd" => Ok(Self::HDD),
            "ssd" => Ok(Self::SSD),
            "nvme" => Ok(Self::NVME),
            _ => {
                let (l, b) = s.split_once(':').ok_or_else(|| {
                    format!(
                        "unknown disk model {s:?}: use file, hdd, ssd, nvme or LATENCY_MS:MB_PER_S"
                    )
                })?;
                let l: f64 = l.parse().map_err(|_| format!("bad latency in {s:?}"))?;
                let b: f64 = b.parse().map_err(|_| format!("bad bandwidth in {s:?}"))?;
                if !((0.0..10_000.0).contains(&l) && (1e-3..=1e6).contains(&b)) {
                    return Err(format!(
                        "disk model {s:?} out of range: latency in [0, 10000) ms, bandwidth in [0.001, 1000000] MB/s"
                    ));
                }
                Ok(Self {
                    latency: Duration::from_secs_f64(l / 1000.0),
                    bytes_per_sec: b * 1e6,
                })
            }
        }
    }

    /// Model time of a read of `len` bytes, with or without a seek.
    pub fn cost(&self, len: usize, seek: bool) -> Duration {
        let transfer = crate::limits::duration_s(len as f64 / self.bytes_per_sec);
        if seek {
            self.latency + transfer
        } else {
            transfer
        }
    }
}

/// Sleeps natively until 150 µs before a deadline, then spins (yielding).
fn sleeper() -> spin_sleep::SpinSleeper {
    spin_sleep::SpinSleeper::new(150_000).with_spin_strategy(spin_sleep::SpinStrategy::YieldThread)
}

/// A source whose reads take the time the model says (sleeping out the rest).
#[derive(Debug)]
pub struct ThrottledSource<S> {
    inner: S,
    model: DiskModel,
    last_end: Mutex<Option<u64>>,
}

impl<S: ByteSource> ThrottledSource<S> {
    /// Wraps `inner` in `model`.
    pub fn new(inner: S, model: DiskModel) -> Self {
        Self {
            inner,
            model,
            last_end: Mutex::new(None),
        }
    }
}

impl<S: ByteSource> ByteSource for ThrottledSource<S> {
    fn len(&self) -> u64 {
        self.inner.len()
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let start = Instant::now();
        let seek = is_seek(&self.last_end, offset, buf.len());
        self.inner.read_at(offset, buf)?;
        let due = self.model.cost(buf.len(), seek);
        // `thread::sleep` oversleeps by the timer slack (50-80 µs on Linux),
        // several times a small read's transfer on an SSD: the last stretch
        // is spun, yielding the core.
        sleeper().sleep_until(start + due);
        Ok(())
    }
}

/// Whether a read of `len` bytes at `offset` seeks (does not continue
/// where the previous one, recorded in `last_end`, ended); records its end.
fn is_seek(last_end: &Mutex<Option<u64>>, offset: u64, len: usize) -> bool {
    let mut last = last_end.lock().unwrap_or_else(|e| e.into_inner());
    let seek = *last != Some(offset);
    *last = Some(offset + len as u64);
    seek
}

/// A simulated device: reads cost `model`'s time on a [`ManualClock`],
/// advanced by the read instead of slept (a read that continues where the
/// previous one ended pays no seek). With the runtime started on the same
/// clock ([`crate::runtime::Walkthrough::start_with_clock`]), P_I's timing
/// policy runs as on the device, exactly and without waiting.
#[derive(Debug)]
pub struct ClockedSource<S> {
    inner: S,
    model: DiskModel,
    clock: std::sync::Arc<ManualClock>,
    last_end: Mutex<Option<u64>>,
}

impl<S: ByteSource> ClockedSource<S> {
    pub fn new(inner: S, model: DiskModel, clock: std::sync::Arc<ManualClock>) -> Self {
        Self {
            inner,
            model,
            clock,
            last_end: Mutex::new(None),
        }
    }
}

impl<S: ByteSource> ByteSource for ClockedSource<S> {
    fn len(&self) -> u64 {
        self.inner.len()
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let seek = is_seek(&self.last_end, offset, buf.len());
        self.inner.read_at(offset, buf)?;
        self.clock.advance(self.model.cost(buf.len(), seek));
        Ok(())
    }
}

/// A source that fails reads touching `bad` byte ranges (fault injection).
#[derive(Debug)]
pub struct FaultySource<S> {
    inner: S,
    bad: Vec<(u64, u64)>,
}

impl<S: ByteSource> FaultySource<S> {
    /// Reads overlapping any `start..end` in `bad` fail with an I/O error.
    pub fn new(inner: S, bad: Vec<(u64, u64)>) -> Self {
        Self { inner, bad }
    }
}

impl<S: ByteSource> ByteSource for FaultySource<S> {
    fn len(&self) -> u64 {
        self.inner.len()
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let end = offset + buf.len() as u64;
        if self.bad.iter().any(|&(s, e)| offset < e && s < end) {
            return Err(io::Error::other(format!(
                "injected read error at {offset}+{}",
                buf.len()
            )));
        }
        self.inner.read_at(offset, buf)
    }
}

/// A source that becomes another after a number of reads (fault
/// injection): the scene file truncated, overwritten or replaced under a
/// running walk, or a disk that starts failing, counted in reads rather
/// than in time so that tests are deterministic.
#[derive(Debug)]
pub struct SwitchingSource<A, B> {
    before: A,
    after: B,
    reads_before: u64,
    reads: std::sync::atomic::AtomicU64,
}

impl<A: ByteSource, B: ByteSource> SwitchingSource<A, B> {
    /// Serves `before` for the first `reads_before` reads, then `after`.
    pub fn new(before: A, after: B, reads_before: u64) -> Self {
        Self {
            before,
            after,
            reads_before,
            reads: std::sync::atomic::AtomicU64::new(0),
        }
    }

    fn switched(&self) -> bool {
        self.reads.load(std::sync::atomic::Ordering::Relaxed) >= self.reads_before
    }
}

impl<A: ByteSource, B: ByteSource> ByteSource for SwitchingSource<A, B> {
    fn len(&self) -> u64 {
        if self.switched() {
            self.after.len()
        } else {
            self.before.len()
        }
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let n = self
            .reads
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        if n >= self.reads_before {
            self.after.read_at(offset, buf)
        } else {
            self.before.read_at(offset, buf)
        }
    }
}

/// Asks the OS to drop the file's pages from the page cache (Linux); returns
/// whether it was done.
pub fn drop_page_cache(file: &std::fs::File) -> bool {
    #[cfg(target_os = "linux")]
    {
        rustix::fs::fadvise(file, 0, None, rustix::fs::Advice::DontNeed).is_ok()
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = file;
        false
    }
}

/// Reads the whole file once so that its pages are in the page cache: under
/// a disk model the model alone must set what a read costs (a cold page
/// cache added the real disk's latency to every first read, several times
/// an SSD model's 0.1 ms seek). Returns the bytes read.
pub fn warm_page_cache(file: &std::fs::File) -> io::Result<u64> {
    use std::io::Read;
    #[cfg(target_os = "linux")]
    let _ = rustix::fs::fadvise(file, 0, None, rustix::fs::Advice::WillNeed);
    let mut r = file;
    let mut buf = vec![0u8; 4 << 20];
    let mut n = 0u64;
    loop {
        match r.read(&mut buf) {
            Ok(0) => return Ok(n),
            Ok(k) => n += k as u64,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
}

/// Opens a scene file as a rep source: the real file with its page cache
/// dropped (a cold start), or behind a throttled disk model with its page
/// cache warmed ([`warm_page_cache`]).
pub fn open_scene_source(
    path: &std::path::Path,
    model: Option<DiskModel>,
) -> io::Result<std::sync::Arc<dyn ByteSource>> {
    scene_source(crate::infile::open(path)?, model)
}

/// [`open_scene_source`] over a file already open: a program that runs
/// several walks opens the scene once and hands each a clone of the handle
/// (`File::try_clone`), so every walk reads the same file even if the path
/// is replaced meanwhile (a rebuild renames a new file over it).
pub fn scene_source(
    file: std::fs::File,
    model: Option<DiskModel>,
) -> io::Result<std::sync::Arc<dyn ByteSource>> {
    let f = crate::io::FileSource::from_file(file)?;
    Ok(match model {
        None => {
            drop_page_cache(f.file());
            std::sync::Arc::new(f)
        }
        Some(m) => {
            warm_page_cache(f.file())?;
            std::sync::Arc::new(ThrottledSource::new(f, m))
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::MemSource;

    #[test]
    fn throttled_reads_take_model_time_and_sequential_reads_skip_the_seek() {
        let m = DiskModel {
            latency: Duration::from_millis(20),
            bytes_per_sec: 1e6,
        };
        let src = ThrottledSource::new(MemSource::new(vec![7u8; 100_000]), m);
        let mut buf = vec![0u8; 10_000];
        let t = Instant::now();
        src.read_at(0, &mut buf).unwrap(); // seek + 10 ms
        src.read_at(10_000, &mut buf).unwrap(); // sequential: 10 ms
        let took = t.elapsed();
        assert!(took >= Duration::from_millis(40), "{took:?}");
        assert!(buf.iter().all(|&b| b == 7));
        assert_eq!(m.cost(10_000, true), Duration::from_millis(30));
    }

    #[test]
    fn warming_reads_the_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f");
        std::fs::write(&p, vec![7u8; (9 << 20) + 5]).unwrap();
        let f = std::fs::File::open(&p).unwrap();
        assert_eq!(warm_page_cache(&f).unwrap(), (9 << 20) + 5);
    }

    #[test]
    fn parse_presets_and_custom_models() {
        assert_eq!(DiskModel::parse("hdd").unwrap(), DiskModel::HDD);
        let c = DiskModel::parse("5:100").unwrap();
        assert_eq!(c.latency, Duration::from_millis(5));
        assert_eq!(c.bytes_per_sec, 100e6);
        for bad in [
            "floppy", "5", "x:1", "1:0", "-1:5", "1:NaN", "0:1e-30", "1e30:5",
        ] {
            assert!(DiskModel::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn switching_source_changes_after_its_reads() {
        let src = SwitchingSource::new(
            MemSource::new(vec![1u8; 8]),
            MemSource::new(vec![2u8; 4]),
            2,
        );
        let mut b = [0u8; 2];
        assert_eq!(src.len(), 8);
        src.read_at(6, &mut b).unwrap();
        assert_eq!(b, [1, 1]);
        src.read_at(0, &mut b).unwrap();
        assert_eq!((src.len(), b), (4, [1, 1]));
        src.read_at(0, &mut b).unwrap();
        assert_eq!(b, [2, 2]);
        assert!(src.read_at(6, &mut b).is_err(), "truncated");
    }

    #[test]
    fn a_scene_source_reads_the_file_it_was_opened_on_after_the_path_is_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.hlod");
        std::fs::write(&path, [1u8; 4096]).unwrap();
        let file = std::fs::File::open(&path).unwrap();
        let src = scene_source(file.try_clone().unwrap(), None).unwrap();
        // A rebuild: a new file renamed over the path.
        let new = dir.path().join("new.hlod");
        std::fs::write(&new, [2u8; 100]).unwrap();
        std::fs::rename(&new, &path).unwrap();
        let later = scene_source(file.try_clone().unwrap(), Some(DiskModel::NVME)).unwrap();
        let mut b = [0u8; 16];
        for s in [src, later] {
            assert_eq!(s.len(), 4096);
            s.read_at(4000, &mut b).unwrap();
            assert_eq!(b, [1u8; 16]);
        }
    }

    #[test]
    fn faulty_source_fails_only_its_ranges() {
        let src = FaultySource::new(MemSource::new(vec![0u8; 100]), vec![(40, 50)]);
        let mut b = [0u8; 10];
        assert!(src.read_at(0, &mut b).is_ok());
        assert!(src.read_at(35, &mut b).is_err());
        assert!(src.read_at(50, &mut b).is_ok());
    }
}
