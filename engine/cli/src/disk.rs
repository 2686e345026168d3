//! A scene file behind a disk model, as the programs open it: the real
//! file with its page cache dropped (a cold start), or behind a modelled
//! device ([`engine::disk::ThrottledSource`]) with its page cache warmed, on
//! a clock whose sleeps are precise to a few microseconds ([`SpinClock`]).

use engine::ByteSource;
use engine::clock::Clock;
use engine::disk::{DiskModel, ThrottledSource};
use std::io;
use std::time::Instant;

/// The system's clock with sleeps that end within a few microseconds:
/// `thread::sleep` oversleeps by the timer slack (50–80 µs on Linux),
/// several times a small read's transfer on an SSD model, so the last
/// 150 µs are spun, yielding the core.
#[derive(Clone, Copy, Debug, Default)]
pub struct SpinClock;

impl Clock for SpinClock {
    fn now(&self) -> Instant {
        Instant::now()
    }

    fn sleep_until(&self, t: Instant) {
        spin_sleep::SpinSleeper::new(150_000)
            .with_spin_strategy(spin_sleep::SpinStrategy::YieldThread)
            .sleep_until(t);
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
    scene_source(engine::infile::open(path)?, model)
}

/// [`open_scene_source`] over a file already open: a program that runs
/// several walks opens the scene once and hands each a clone of the handle
/// (`File::try_clone`), so every walk reads the same file even if the path
/// is replaced meanwhile (a rebuild renames a new file over it).
pub fn scene_source(
    file: std::fs::File,
    model: Option<DiskModel>,
) -> io::Result<std::sync::Arc<dyn ByteSource>> {
    let f = engine::io::FileSource::from_file(file)?;
    Ok(match model {
        None => {
            drop_page_cache(f.file());
            std::sync::Arc::new(f)
        }
        Some(m) => {
            warm_page_cache(f.file())?;
            std::sync::Arc::new(ThrottledSource::with_clock(
                f,
                m,
                std::sync::Arc::new(SpinClock),
            ))
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use engine::MemSource;
    use std::time::Duration;

    #[test]
    fn a_modelled_read_on_the_spin_clock_takes_its_time() {
        let m = DiskModel {
            latency: Duration::from_millis(20),
            bytes_per_sec: 1e6,
        };
        let clock = std::sync::Arc::new(SpinClock);
        let src = ThrottledSource::with_clock(MemSource::new(vec![7u8; 100_000]), m, clock);
        let mut buf = vec![0u8; 10_000];
        let t = Instant::now();
        src.read_at(0, &mut buf).unwrap(); // seek + 10 ms
        src.read_at(10_000, &mut buf).unwrap(); // sequential: 10 ms
        let took = t.elapsed();
        assert!(took >= Duration::from_millis(40), "{took:?}");
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
}
