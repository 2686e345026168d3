//! Disk models behind [`ByteSource`]: a device with a seek latency and a
//! bandwidth whose reads take their time on a [`Clock`] (slept out on the
//! system's, advanced on a [`crate::clock::ManualClock`]), so that the
//! papers' slow-disk regime can be reproduced here and tested without
//! waiting; and the fault injectors the tests use. Opening a real file
//! behind a model (page cache dropped or warmed) is the programs' business
//! (`engine_cli::disk`).

use crate::clock::{Clock, SystemClock};
use std::io;
use std::sync::{Arc, Mutex};
use std::time::Duration;

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

/// A source whose reads take the time the model says on `clock`: the rest
/// of the read's modelled cost is slept out on a real clock, and a manual
/// clock is moved on by it (a read that continues where the previous one
/// ended pays no seek). With the runtime started on the same manual clock
/// ([`crate::runtime::Walkthrough::start_with_clock`]), P_I's timing policy
/// runs as on the device, exactly and without waiting.
#[derive(Debug)]
pub struct ThrottledSource<S> {
    inner: S,
    model: DiskModel,
    clock: Arc<dyn Clock>,
    last_end: Mutex<Option<u64>>,
}

impl<S: ByteSource> ThrottledSource<S> {
    /// Wraps `inner` in `model` on the system's clock.
    pub fn new(inner: S, model: DiskModel) -> Self {
        Self::with_clock(inner, model, Arc::new(SystemClock))
    }

    /// Wraps `inner` in `model` on `clock`.
    pub fn with_clock(inner: S, model: DiskModel, clock: Arc<dyn Clock>) -> Self {
        Self {
            inner,
            model,
            clock,
            last_end: Mutex::new(None),
        }
    }
}

impl<S: ByteSource> ByteSource for ThrottledSource<S> {
    fn len(&self) -> u64 {
        self.inner.len()
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let start = self.clock.now();
        let seek = is_seek(&self.last_end, offset, buf.len());
        self.inner.read_at(offset, buf)?;
        self.clock
            .sleep_until(start + self.model.cost(buf.len(), seek));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clock::ManualClock;
    use crate::io::MemSource;

    #[test]
    fn throttled_reads_take_model_time_and_sequential_reads_skip_the_seek() {
        let m = DiskModel {
            latency: Duration::from_millis(20),
            bytes_per_sec: 1e6,
        };
        let clock = Arc::new(ManualClock::new());
        let src = ThrottledSource::with_clock(MemSource::new(vec![7u8; 100_000]), m, clock.clone());
        let mut buf = vec![0u8; 10_000];
        src.read_at(0, &mut buf).unwrap(); // seek + 10 ms
        assert_eq!(clock.elapsed(), Duration::from_millis(30));
        src.read_at(10_000, &mut buf).unwrap(); // sequential: 10 ms
        assert_eq!(clock.elapsed(), Duration::from_millis(40));
        src.read_at(0, &mut buf).unwrap(); // back: a seek again
        assert_eq!(clock.elapsed(), Duration::from_millis(70));
        assert!(buf.iter().all(|&b| b == 7));
        assert_eq!(m.cost(10_000, true), Duration::from_millis(30));
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
    fn faulty_source_fails_only_its_ranges() {
        let src = FaultySource::new(MemSource::new(vec![0u8; 100]), vec![(40, 50)]);
        let mut b = [0u8; 10];
        assert!(src.read_at(0, &mut b).is_ok());
        assert!(src.read_at(35, &mut b).is_err());
        assert!(src.read_at(50, &mut b).is_ok());
    }
}
