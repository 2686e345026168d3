//! The one output-file policy of every writer in the workspace (scene files,
//! generated GLBs, `.vdt` files, benchmark CSVs, summaries and plots).
//!
//! - An output is a regular file or a new one: a device (`/dev/null`), a
//!   directory, a FIFO or a socket is refused, never replaced.
//! - A symbolic link is refused: a writer never writes through a link it
//!   did not make (a link planted where an output goes would aim the write
//!   at any file the user can write).
//! - An output is never one of the command's inputs (same device and inode,
//!   hard links included): neither those the caller names nor any file the
//!   process read through [`engine::infile`] (a glTF's buffers, a path file,
//!   shards). The check is made when the output is created and again just
//!   before it is renamed into place.
//! - It is written to a temporary file beside the target and renamed over it
//!   only when complete ([`OutputFile::commit`]), so the target appears whole
//!   or not at all. The temporary file is removed when the writer fails or is
//!   dropped, and on SIGINT, SIGTERM and SIGHUP; one left by a process killed
//!   outright (SIGKILL, power loss) is removed by the next writer into the
//!   same folder: every live temporary file holds an exclusive lock, so one
//!   whose lock can be taken has no owner (a file is locked before it gets
//!   the name sweepers look for, so concurrent writers into one folder, such
//!   as shard jobs, never take each other's).
//! - [`ensure_free`] checks the free space of the target's file system.

use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, Once};

/// Suffix of every temporary output file; also how stale ones are found.
pub const TEMP_SUFFIX: &str = ".hlod-tmp";

/// Why an output cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{}: is {what}, not a regular file; refusing to replace it", path.display())]
    NotRegular { path: PathBuf, what: &'static str },
    #[error("{}: is the input {}; refusing to overwrite it", path.display(), input.display())]
    IsInput { path: PathBuf, input: PathBuf },
    #[error(
        "{}: is a symbolic link; refusing to write through it (name its target, or remove the link)",
        path.display()
    )]
    Symlink { path: PathBuf },
    #[error(
        "{}: needs {} free, the file system has {}",
        path.display(),
        engine::limits::human(*need),
        engine::limits::human(*free)
    )]
    NoSpace { path: PathBuf, need: u64, free: u64 },
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: io::Error },
}

impl From<OutputError> for io::Error {
    fn from(e: OutputError) -> Self {
        match e {
            OutputError::Io { source, .. } => source,
            OutputError::NoSpace { .. } => {
                io::Error::new(io::ErrorKind::StorageFull, e.to_string())
            }
            e => io::Error::new(io::ErrorKind::InvalidInput, e.to_string()),
        }
    }
}

/// An output being written: a locked temporary file beside its target.
#[derive(Debug)]
pub struct OutputFile {
    target: PathBuf,
    tmp: Option<tempfile::NamedTempFile>,
}

impl OutputFile {
    /// Starts writing `path` (see the module's policy); `inputs` are the
    /// command's input files, which the output may not be.
    pub fn create(path: &Path, inputs: &[&Path]) -> Result<Self, OutputError> {
        let target = resolve_target(path, inputs)?;
        let dir = parent_dir(&target);
        let io_err = |source| OutputError::Io {
            path: target.clone(),
            source,
        };
        sweep_once(dir);
        install_signal_cleanup();
        // The target's name, shortened so that the temporary name stays
        // within a file system's 255 bytes.
        let name: String = target
            .file_name()
            .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned())
            .chars()
            .take(50)
            .collect();
        let tmp = claim_temp(dir, &name).map_err(io_err)?;
        live().push(tmp.path().to_path_buf());
        Ok(Self {
            target,
            tmp: Some(tmp),
        })
    }

    /// The file to write (the temporary file).
    pub fn file(&self) -> &File {
        self.tmp.as_ref().expect("not committed").as_file()
    }

    /// Where the output goes.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Makes the written file the target: mode 0644, synced, renamed over
    /// the target.
    pub fn commit(mut self) -> Result<(), OutputError> {
        // An input read since the output was created may be the target.
        resolve_target(&self.target, &[])?;
        let tmp = self.tmp.take().expect("committed once");
        let io_err = |source| OutputError::Io {
            path: self.target.clone(),
            source,
        };
        set_public_mode(tmp.as_file()).map_err(io_err)?;
        tmp.as_file().sync_all().map_err(io_err)?;
        let tmp_path = tmp.path().to_path_buf();
        let persisted = tmp.persist(&self.target);
        forget_live(&tmp_path);
        let file = persisted.map_err(|e| io_err(e.error))?;
        // The lock goes with the file; the name is the target's now.
        drop(file);
        Ok(())
    }
}

impl Drop for OutputFile {
    fn drop(&mut self) {
        if let Some(tmp) = self.tmp.take() {
            forget_live(tmp.path());
            // `NamedTempFile`'s drop removes the file.
        }
    }
}

/// Writes `path` through an [`OutputFile`]: `fill` writes into a buffered
/// writer, and the target appears only when it returned `Ok`.
pub fn write_with<T>(
    path: &Path,
    inputs: &[&Path],
    fill: impl FnOnce(&mut io::BufWriter<&File>) -> io::Result<T>,
) -> io::Result<T> {
    use io::Write;
    let out = OutputFile::create(path, inputs)?;
    let mut w = io::BufWriter::with_capacity(1 << 20, out.file());
    let v = fill(&mut w)?;
    w.flush()?;
    drop(w);
    out.commit()?;
    Ok(v)
}

/// Writes `bytes` to `path` under the policy (no inputs to protect).
pub fn write_bytes(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_with(path, &[], |w| io::Write::write_all(w, bytes))
}

/// Fails unless the file system holding `path` (a file or a folder) has at
/// least `need` bytes free.
pub fn ensure_free(path: &Path, need: u64) -> Result<(), OutputError> {
    let free = free_bytes(path).map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if free < need {
        return Err(OutputError::NoSpace {
            path: path.to_path_buf(),
            need,
            free,
        });
    }
    Ok(())
}

/// Bytes available to an unprivileged writer on `path`'s file system
/// (`u64::MAX` where it cannot be asked).
pub fn free_bytes(path: &Path) -> io::Result<u64> {
    #[cfg(target_os = "linux")]
    {
        let dir = if path.is_dir() {
            path
        } else {
            parent_dir(path)
        };
        let s = rustix::fs::statvfs(dir)?;
        Ok(s.f_bavail.saturating_mul(s.f_frsize))
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = path;
        Ok(u64::MAX)
    }
}

/// The folder a file path lives in (`.` for a bare name).
pub fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Checks `path` against the policy without writing anything (a command
/// that works long before it writes calls this first); returns the path
/// that will be written.
pub fn check_output(path: &Path, inputs: &[&Path]) -> Result<PathBuf, OutputError> {
    resolve_target(path, inputs)
}

/// Applies the policy to `path`: the path to write.
fn resolve_target(path: &Path, inputs: &[&Path]) -> Result<PathBuf, OutputError> {
    let meta = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(path.to_path_buf()),
        Err(source) => {
            return Err(OutputError::Io {
                path: path.to_path_buf(),
                source,
            });
        }
    };
    if meta.file_type().is_symlink() {
        return Err(OutputError::Symlink {
            path: path.to_path_buf(),
        });
    }
    if !meta.is_file() {
        return Err(OutputError::NotRegular {
            path: path.to_path_buf(),
            what: engine::infile::kind_of(&meta),
        });
    }
    for input in inputs {
        if let Ok(im) = std::fs::metadata(input)
            && same_file(&meta, &im)
        {
            return Err(OutputError::IsInput {
                path: path.to_path_buf(),
                input: input.to_path_buf(),
            });
        }
    }
    if let Some(input) = engine::infile::is_input(&meta) {
        return Err(OutputError::IsInput {
            path: path.to_path_buf(),
            input,
        });
    }
    Ok(path.to_path_buf())
}

fn same_file(a: &std::fs::Metadata, b: &std::fs::Metadata) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        a.dev() == b.dev() && a.ino() == b.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (a, b);
        false
    }
}

/// A new temporary output in `dir`, locked. It is made under a claim name
/// that sweepers leave alone while it is young, locked, and only then
/// linked under its [`TEMP_SUFFIX`] name: a writer in another process that
/// sweeps the folder at that moment cannot take the lock of a file not yet
/// locked (and remove it, or make the lock fail with "would block").
fn claim_temp(dir: &Path, name: &str) -> io::Result<tempfile::NamedTempFile> {
    let claim = tempfile::Builder::new()
        .prefix(&format!(".{name}."))
        .suffix(CLAIM_SUFFIX)
        .tempfile_in(dir)?;
    claim.as_file().try_lock().map_err(io::Error::from)?;
    let (file, claim_path) = claim.into_parts();
    let claimed = claim_path.to_string_lossy().into_owned();
    let tmp_path = PathBuf::from(format!(
        "{}{TEMP_SUFFIX}",
        claimed.strip_suffix(CLAIM_SUFFIX).unwrap_or(&claimed)
    ));
    // A hard link never replaces an existing file; the claim name goes
    // when `claim_path` drops.
    std::fs::hard_link(&claim_path, &tmp_path)?;
    drop(claim_path);
    Ok(tempfile::NamedTempFile::from_parts(
        file,
        tempfile::TempPath::try_from_path(tmp_path)?,
    ))
}

/// Suffix of a temporary output being created, before its lock is held.
const CLAIM_SUFFIX: &str = ".hlod-new";

/// How old an unlocked claim must be to count as left behind (a live one
/// is younger than a millisecond before it is locked).
const CLAIM_STALE: std::time::Duration = std::time::Duration::from_secs(60);

/// [`remove_stale`] the first time this process writes into `dir` (a run
/// writing hundreds of files into one folder lists it once).
fn sweep_once(dir: &Path) {
    static SWEPT: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
    let key = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    let mut swept = SWEPT.lock().unwrap_or_else(|e| e.into_inner());
    if !swept.contains(&key) {
        swept.push(key);
        remove_stale(dir);
    }
}

/// Removes temporary outputs in `dir` whose writer is gone (their lock can
/// be taken). Best effort: a folder that cannot be listed is left alone.
pub fn remove_stale(dir: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut removed = 0;
    for e in entries.flatten() {
        let name = e.file_name();
        let name = name.to_string_lossy();
        let claim = name.ends_with(CLAIM_SUFFIX);
        if !(name.starts_with('.') && (name.ends_with(TEMP_SUFFIX) || claim)) {
            continue;
        }
        let path = e.path();
        let young =
            |m: std::fs::Metadata| m.modified().ok()?.elapsed().ok().map(|a| a < CLAIM_STALE);
        if claim && e.metadata().ok().and_then(young).unwrap_or(true) {
            continue;
        }
        let Ok(f) = File::open(&path) else { continue };
        if f.try_lock().is_ok() && std::fs::remove_file(&path).is_ok() {
            tracing::info!("removed {} left by an interrupted run", path.display());
            removed += 1;
        }
    }
    removed
}

/// Gives a finished output the usual 0644 mode (temporary files are 0600).
fn set_public_mode(file: &File) -> io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        file.set_permissions(std::fs::Permissions::from_mode(0o644))?;
    }
    #[cfg(not(unix))]
    let _ = file;
    Ok(())
}

/// Temporary outputs of this process, removed on a terminating signal.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn live() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

fn forget_live(path: &Path) {
    live().retain(|p| p != path);
}

/// Once per process: a thread that removes the live temporary outputs on
/// SIGINT, SIGTERM or SIGHUP and then ends the process as that signal
/// would have.
fn install_signal_cleanup() {
    #[cfg(unix)]
    {
        static ONCE: Once = Once::new();
        ONCE.call_once(|| {
            use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
            let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])
            else {
                return;
            };
            let spawned = std::thread::Builder::new()
                .name("output-cleanup".into())
                .spawn(move || {
                    if let Some(sig) = signals.forever().next() {
                        for p in live().drain(..) {
                            let _ = std::fs::remove_file(p);
                        }
                        let _ = signal_hook::low_level::emulate_default_handler(sig);
                        std::process::exit(128 + sig);
                    }
                });
            drop(spawned);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn devices_directories_and_inputs_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        for dev in ["/dev/null", "/dev/full"] {
            let e = OutputFile::create(Path::new(dev), &[]).unwrap_err();
            assert!(matches!(e, OutputError::NotRegular { .. }), "{e}");
        }
        let e = OutputFile::create(dir.path(), &[]).unwrap_err();
        assert!(matches!(e, OutputError::NotRegular { .. }), "{e}");
        let input = dir.path().join("in.glb");
        std::fs::write(&input, b"x").unwrap();
        let e = OutputFile::create(&input, &[&input]).unwrap_err();
        assert!(matches!(e, OutputError::IsInput { .. }), "{e}");
        let hard = dir.path().join("hard.glb");
        std::fs::hard_link(&input, &hard).unwrap();
        assert!(OutputFile::create(&hard, &[&input]).is_err());
        assert_eq!(std::fs::read(&input).unwrap(), b"x");
        assert_eq!(names(dir.path()), ["hard.glb", "in.glb"]);
    }

    #[cfg(unix)]
    #[test]
    fn a_symlink_is_refused_and_its_target_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.hlod");
        std::fs::write(&real, b"old").unwrap();
        let link = dir.path().join("link.hlod");
        std::os::unix::fs::symlink(&real, &link).unwrap();
        assert!(matches!(
            write_bytes(&link, b"new").map_err(|e| e.to_string()),
            Err(e) if e.contains("symbolic link")
        ));
        assert_eq!(std::fs::read(&real).unwrap(), b"old");
        let dangling = dir.path().join("dangling");
        std::os::unix::fs::symlink(dir.path().join("nowhere/x"), &dangling).unwrap();
        assert!(matches!(
            OutputFile::create(&dangling, &[]),
            Err(OutputError::Symlink { .. })
        ));
    }

    #[test]
    fn a_file_the_process_read_is_never_an_output() {
        engine::infile::track_inputs();
        let dir = tempfile::tempdir().unwrap();
        let read = dir.path().join("buffer.bin");
        std::fs::write(&read, b"data").unwrap();
        drop(engine::infile::open(&read).unwrap());
        let e = OutputFile::create(&read, &[]).unwrap_err();
        assert!(matches!(e, OutputError::IsInput { .. }), "{e}");
        // Read after the output was created: refused at commit.
        let late = dir.path().join("late.csv");
        std::fs::write(&late, b"keep").unwrap();
        let out = OutputFile::create(&late, &[]).unwrap();
        drop(engine::infile::open(&late).unwrap());
        assert!(matches!(out.commit(), Err(OutputError::IsInput { .. })));
        assert_eq!(std::fs::read(&late).unwrap(), b"keep");
        assert_eq!(std::fs::read(&read).unwrap(), b"data");
    }

    #[test]
    fn a_failed_or_dropped_write_leaves_nothing_and_stale_files_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("o.csv");
        let r = write_with(&out, &[], |_| -> io::Result<()> {
            Err(io::Error::other("fail"))
        });
        assert!(r.is_err());
        drop(OutputFile::create(&out, &[]).unwrap());
        assert!(names(dir.path()).is_empty());
        // One of a live writer: locked.
        let busy = OutputFile::create(&dir.path().join("p.csv"), &[]).unwrap();
        // One left by a killed writer: no lock held on it.
        let stale = dir.path().join(format!(".o.csv.abc{TEMP_SUFFIX}"));
        std::fs::write(&stale, b"partial").unwrap();
        assert_eq!(remove_stale(dir.path()), 1);
        assert_eq!(names(dir.path()).len(), 1, "the live one stays");
        drop(busy);
        write_bytes(&out, b"ok").unwrap();
        assert_eq!(names(dir.path()), ["o.csv"]);
        assert_eq!(std::fs::read(&out).unwrap(), b"ok");
    }

    #[test]
    fn concurrent_writers_into_one_folder_never_take_each_others_files() {
        // Found by four shard jobs writing into one folder: one job's sweep
        // took the lock of another's file between its creation and its lock.
        use std::sync::atomic::{AtomicBool, Ordering};
        let dir = tempfile::tempdir().unwrap();
        let done = AtomicBool::new(false);
        std::thread::scope(|s| {
            s.spawn(|| {
                while !done.load(Ordering::Relaxed) {
                    remove_stale(dir.path());
                }
            });
            let writers: Vec<_> = (0..3)
                .map(|t| {
                    let dir = dir.path();
                    s.spawn(move || {
                        for k in 0..150 {
                            let out = dir.join(format!("o{t}-{k}.csv"));
                            write_bytes(&out, format!("{t} {k}").as_bytes()).unwrap();
                        }
                    })
                })
                .collect();
            let ended: Vec<bool> = writers.into_iter().map(|w| w.join().is_ok()).collect();
            done.store(true, Ordering::Relaxed);
            assert!(ended.iter().all(|&ok| ok), "a writer failed: {ended:?}");
        });
        let mut n = names(dir.path());
        n.retain(|f| f.ends_with(".csv"));
        assert_eq!(n.len(), 450, "every write landed, nothing temporary left");
        assert_eq!(std::fs::read(dir.path().join("o2-7.csv")).unwrap(), b"2 7");
    }

    #[test]
    fn a_claim_left_behind_is_removed_once_old() {
        let dir = tempfile::tempdir().unwrap();
        let young = dir.path().join(format!(".a.csv.x1{CLAIM_SUFFIX}"));
        let old = dir.path().join(format!(".b.csv.x2{CLAIM_SUFFIX}"));
        std::fs::write(&young, b"").unwrap();
        std::fs::write(&old, b"").unwrap();
        let hour_ago = std::time::SystemTime::now() - std::time::Duration::from_secs(3600);
        File::options()
            .write(true)
            .open(&old)
            .unwrap()
            .set_modified(hour_ago)
            .unwrap();
        assert_eq!(remove_stale(dir.path()), 1);
        assert!(young.exists() && !old.exists());
    }

    #[test]
    fn free_space_is_checked() {
        let dir = tempfile::tempdir().unwrap();
        assert!(ensure_free(dir.path(), 1).is_ok());
        assert!(matches!(
            ensure_free(dir.path(), u64::MAX),
            Err(OutputError::NoSpace { .. })
        ));
    }
}
