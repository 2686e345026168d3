//! Bounds on what untrusted input may make the engine do: seconds turned into
//! durations without panicking, allocations and file reads sized by what the
//! format, the file's real size and the machine allow before anything is
//! allocated.
//!
//! Every reader of the workspace that sizes a buffer from a number it read
//! (a header's counts, a glTF buffer's length, a path file) goes through
//! [`alloc_bytes`] or [`read_bounded`], so a lying header or an endless file
//! (`/dev/zero`) is a typed error instead of an abort or an exhausted machine.

use std::io::{self, Read};
use std::path::Path;
use std::time::{Duration, Instant};

/// The longest duration a parameter may turn into (about 31 years): far
/// beyond any sensible value, small enough to add to an [`Instant`].
pub const MAX_DURATION: Duration = Duration::from_secs(1_000_000_000);

/// `secs` seconds as a [`Duration`], saturating: NaN and negative values
/// give zero, values beyond [`MAX_DURATION`] (infinity included) give it.
/// The parameter layer rejects such values first; this keeps policy code
/// from panicking whatever it is handed.
pub fn duration_s(secs: f64) -> Duration {
    if secs.is_nan() || secs <= 0.0 {
        Duration::ZERO
    } else {
        Duration::try_from_secs_f64(secs)
            .unwrap_or(MAX_DURATION)
            .min(MAX_DURATION)
    }
}

/// `at + secs`, or `None` when the instant would overflow the clock.
pub fn after(at: Instant, secs: f64) -> Option<Instant> {
    at.checked_add(duration_s(secs))
}

/// Physical memory of this machine in bytes (`MemTotal`); `u64::MAX / 4`
/// where it cannot be read.
pub fn memory_total() -> u64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("MemTotal:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
        .map_or(u64::MAX / 4, |kib| kib.saturating_mul(1024))
}

/// Why a buffer could not be had.
#[derive(Debug, thiserror::Error)]
pub enum LimitError {
    #[error(
        "{what} needs {} but this machine has {} of memory",
        human(*bytes),
        human(*limit)
    )]
    TooLarge {
        what: String,
        bytes: u64,
        limit: u64,
    },
    #[error("{what}: cannot allocate {}", human(*bytes))]
    Alloc { what: String, bytes: u64 },
}

impl From<LimitError> for io::Error {
    fn from(e: LimitError) -> Self {
        io::Error::new(io::ErrorKind::OutOfMemory, e.to_string())
    }
}

/// Refuses a buffer of `len` bytes for `what` that exceeds the machine's
/// memory, before anything is allocated (for decoders that allocate
/// themselves). The memory size is read once.
pub fn check_alloc(len: u64, what: &str) -> Result<(), LimitError> {
    static TOTAL: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    let limit = *TOTAL.get_or_init(memory_total);
    if len > limit {
        return Err(LimitError::TooLarge {
            what: what.to_string(),
            bytes: len,
            limit,
        });
    }
    Ok(())
}

/// A zeroed buffer of `len` bytes for `what`, refused when it exceeds the
/// machine's memory and allocated fallibly (an error, not an abort).
pub fn alloc_bytes(len: u64, what: &str) -> Result<Vec<u8>, LimitError> {
    let limit = memory_total();
    if len > limit {
        return Err(LimitError::TooLarge {
            what: what.to_string(),
            bytes: len,
            limit,
        });
    }
    let n = usize::try_from(len).map_err(|_| LimitError::TooLarge {
        what: what.to_string(),
        bytes: len,
        limit,
    })?;
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| LimitError::Alloc {
        what: what.to_string(),
        bytes: len,
    })?;
    v.resize(n, 0);
    Ok(v)
}

/// Reads the regular file at `path` whole ([`crate::infile::open`]: a pipe
/// or a device such as `/dev/zero` is refused), refusing more than `max`
/// bytes before reading; one that grows while read is cut at `max + 1`.
pub fn read_bounded(path: &Path, max: u64) -> io::Result<Vec<u8>> {
    let (file, meta) = crate::infile::open_with_meta(path)?;
    let too_large = |len: String| {
        io::Error::new(
            io::ErrorKind::FileTooLarge,
            format!("{len}, more than the {} this reader accepts", human(max)),
        )
    };
    if meta.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::IsADirectory,
            "is a directory, not a file",
        ));
    }
    if meta.is_file() && meta.len() > max {
        return Err(too_large(format!("the file has {}", human(meta.len()))));
    }
    let cap = if meta.is_file() { meta.len() } else { 1 << 16 };
    let mut out = Vec::new();
    out.try_reserve(usize::try_from(cap).unwrap_or(usize::MAX))
        .map_err(|_| io::Error::from(io::ErrorKind::OutOfMemory))?;
    file.take(max.saturating_add(1)).read_to_end(&mut out)?;
    if out.len() as u64 > max {
        return Err(too_large("it goes on past that".into()));
    }
    Ok(out)
}

/// `bytes` with a binary unit (`12.34 MiB`).
pub fn human(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.2} {}", UNITS[u])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_saturate_instead_of_panicking() {
        assert_eq!(duration_s(f64::NAN), Duration::ZERO);
        assert_eq!(duration_s(-1.0), Duration::ZERO);
        assert_eq!(duration_s(1e30), MAX_DURATION);
        assert_eq!(duration_s(f64::INFINITY), MAX_DURATION);
        assert_eq!(duration_s(0.25), Duration::from_millis(250));
        assert!(after(Instant::now(), 1e300).is_some());
    }

    #[test]
    fn huge_allocations_are_errors() {
        assert!(alloc_bytes(u64::MAX, "x").is_err());
        assert!(alloc_bytes(memory_total() + 1, "x").is_err());
        assert_eq!(alloc_bytes(10, "x").unwrap(), vec![0u8; 10]);
    }

    #[test]
    fn endless_and_large_files_are_refused() {
        // An endless device is refused before anything is read.
        let e = read_bounded(Path::new("/dev/zero"), 1 << 20).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{e}");
        assert!(e.to_string().contains("a character device"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f");
        std::fs::write(&p, [1u8; 100]).unwrap();
        assert_eq!(read_bounded(&p, 100).unwrap().len(), 100);
        assert_eq!(
            read_bounded(&p, 99).unwrap_err().kind(),
            io::ErrorKind::FileTooLarge
        );
        assert!(read_bounded(dir.path(), 100).is_err());
    }
}
