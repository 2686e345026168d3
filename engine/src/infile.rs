//! The one input-file policy of every reader in the workspace (models and
//! their buffers, scene files, shards, path files, cache entries), the
//! counterpart of [`crate::outfile`].
//!
//! - An input is a regular file. A FIFO, a socket or a device is refused
//!   with one error before anything is read from it: the file is opened
//!   non-blocking (so opening a FIFO with no writer cannot hang) and its
//!   type checked on the open handle (so swapping the path between a check
//!   and the open changes nothing).
//! - In a command-line program ([`track_inputs`], which every binary of the
//!   workspace calls first through `engine_cli::main_with`), every input
//!   opened here is remembered for the life of the process, by device,
//!   inode and birth time ([`is_input`]). The output policy refuses to
//!   write any of them, so no command overwrites a file it read, whichever
//!   of its options named it (a glTF's external buffer, a path file, a
//!   shard). A library user that runs many jobs in one process (the tests
//!   build one scene after another into one file) leaves tracking off and
//!   names each job's inputs to the output policy itself.

use std::fs::{File, Metadata};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// One file read by this process: its device and inode, and its birth
/// time where the file system records one. An inode number is reused once
/// its file is deleted; the birth time tells the new file from the input
/// (a long-running process, or the tests of one crate in one process, see
/// many files come and go).
#[derive(Clone, Debug, PartialEq, Eq)]
struct Input {
    id: FileId,
    path: PathBuf,
}

/// What makes a file the same file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct FileId {
    dev: u64,
    ino: u64,
    born: Option<std::time::SystemTime>,
}

impl FileId {
    /// The same file: same device and inode, and the same birth time where
    /// both know one (without one, the device and inode decide, erring on
    /// the side of refusing an output).
    fn same(&self, other: &FileId) -> bool {
        self.dev == other.dev
            && self.ino == other.ino
            && match (self.born, other.born) {
                (Some(a), Some(b)) => a == b,
                _ => true,
            }
    }
}

static INPUTS: Mutex<Vec<Input>> = Mutex::new(Vec::new());

static TRACKING: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// From now on, every input this process opens through this module is
/// one of its inputs until it exits (see the module documentation).
pub fn track_inputs() {
    TRACKING.store(true, std::sync::atomic::Ordering::Relaxed);
}

fn inputs() -> std::sync::MutexGuard<'static, Vec<Input>> {
    INPUTS.lock().unwrap_or_else(|e| e.into_inner())
}

/// Opens `path` for reading under the policy: a regular file, opened
/// without blocking, and remembered as an input of this process.
///
/// The error says what the path is when it is not a regular file
/// ("is a FIFO, not a regular file"); the caller names the file.
pub fn open(path: &Path) -> io::Result<File> {
    let file = open_nonblocking(path)?;
    let meta = file.metadata()?;
    refuse_irregular(&meta)?;
    remember(&meta, path);
    Ok(file)
}

/// [`open`] without remembering the file as an input: for a file the
/// process checks and may then replace (a build cache's entry).
pub fn open_unremembered(path: &Path) -> io::Result<File> {
    let file = open_nonblocking(path)?;
    refuse_irregular(&file.metadata()?)?;
    Ok(file)
}

/// [`open`], returning the file's metadata too.
pub fn open_with_meta(path: &Path) -> io::Result<(File, Metadata)> {
    let file = open(path)?;
    let meta = file.metadata()?;
    Ok((file, meta))
}

/// Remembers a file opened some other way (an open handle's path) as an
/// input; a path that cannot be examined is ignored (its reader reports it).
pub fn register(path: &Path) {
    if let Ok(meta) = std::fs::metadata(path) {
        remember(&meta, path);
    }
}

/// The input of this process that `meta` is (same device and inode), if any.
pub fn is_input(meta: &Metadata) -> Option<PathBuf> {
    let id = id(meta)?;
    inputs()
        .iter()
        .find(|i| i.id.same(&id))
        .map(|i| i.path.clone())
}

/// An error unless `meta` is a regular file's.
pub fn refuse_irregular(meta: &Metadata) -> io::Result<()> {
    if meta.is_file() {
        return Ok(());
    }
    let kind = if meta.is_dir() {
        io::ErrorKind::IsADirectory
    } else {
        io::ErrorKind::InvalidInput
    };
    Err(io::Error::new(
        kind,
        format!(
            "is {}, not a regular file (save it to a file first)",
            kind_of(meta)
        ),
    ))
}

/// What a file that is not regular is, in words ("a FIFO").
pub fn kind_of(meta: &Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "a directory";
    }
    if t.is_symlink() {
        return "a symbolic link";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_file() {
        return "a regular file";
    }
    "not a regular file"
}

/// The process's effective user id (0 where there are none).
pub fn user_id() -> u32 {
    #[cfg(unix)]
    {
        rustix::process::geteuid().as_raw()
    }
    #[cfg(not(unix))]
    0
}

fn remember(meta: &Metadata, path: &Path) {
    if !TRACKING.load(std::sync::atomic::Ordering::Relaxed) {
        return;
    }
    let Some(id) = id(meta) else { return };
    let mut v = inputs();
    if !v.iter().any(|i| i.id == id) {
        v.push(Input {
            id,
            path: path.to_path_buf(),
        });
    }
}

fn id(meta: &Metadata) -> Option<FileId> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        Some(FileId {
            dev: meta.dev(),
            ino: meta.ino(),
            born: meta.created().ok(),
        })
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        None
    }
}

fn open_nonblocking(path: &Path) -> io::Result<File> {
    let mut o = std::fs::OpenOptions::new();
    o.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        // Opening a FIFO for reading blocks until a writer comes; with
        // O_NONBLOCK it returns at once, and the type check refuses it.
        // On a regular file the flag changes nothing.
        o.custom_flags(rustix::fs::OFlags::NONBLOCK.bits() as i32);
    }
    o.open(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_files_open_and_are_remembered_devices_and_folders_do_not() {
        track_inputs();
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("a.txt");
        std::fs::write(&f, b"x").unwrap();
        let (_, meta) = open_with_meta(&f).unwrap();
        assert_eq!(is_input(&meta), Some(f.clone()));
        let hard = dir.path().join("b.txt");
        std::fs::hard_link(&f, &hard).unwrap();
        assert_eq!(
            is_input(&std::fs::metadata(&hard).unwrap()),
            Some(f),
            "a hard link is the same input"
        );
        for (p, what) in [
            (Path::new("/dev/zero"), "character device"),
            (dir.path(), "directory"),
        ] {
            let e = open(p).unwrap_err();
            assert!(e.to_string().contains(what), "{e}");
        }
    }

    #[test]
    fn a_new_file_on_a_deleted_inputs_inode_is_not_that_input() {
        track_inputs();
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("gone.txt");
        std::fs::write(&f, b"x").unwrap();
        let (_, meta) = open_with_meta(&f).unwrap();
        if meta.created().is_err() {
            return; // a file system without birth times: inodes decide
        }
        std::fs::remove_file(&f).unwrap();
        // Files made until one takes the freed inode (most file systems
        // hand it out again at once); none of them is the input.
        use std::os::unix::fs::MetadataExt;
        for k in 0..64 {
            let g = dir.path().join(format!("new{k}.txt"));
            std::fs::write(&g, b"y").unwrap();
            let m = std::fs::metadata(&g).unwrap();
            assert_eq!(is_input(&m), None, "inode {} reused", m.ino());
        }
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_fifo_is_refused_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        rustix::fs::mknodat(
            rustix::fs::CWD,
            &fifo,
            rustix::fs::FileType::Fifo,
            rustix::fs::Mode::from_raw_mode(0o600),
            0,
        )
        .unwrap();
        let e = open(&fifo).unwrap_err();
        assert!(e.to_string().contains("a FIFO"), "{e}");
    }
}
