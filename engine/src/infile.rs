//! The one input-file policy of every reader in the workspace (models and
//! their buffers, scene files, shards, path files, cache entries), the
//! counterpart of [`crate::outfile`].
//!
//! - An input is a regular file. A FIFO, a socket or a device is refused
//!   with one error before anything is read from it: the file is opened
//!   non-blocking (so opening a FIFO with no writer cannot hang) and its
//!   type checked on the open handle (so swapping the path between a check
//!   and the open changes nothing).
//! - Every input opened here is remembered for the life of the process, by
//!   device and inode ([`is_input`]). The output policy refuses to write any
//!   of them, so no command overwrites a file it read, whichever of its
//!   options named it (a glTF's external buffer, a path file, a shard).

use std::fs::{File, Metadata};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// One file read by this process.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Input {
    dev: u64,
    ino: u64,
    path: PathBuf,
}

static INPUTS: Mutex<Vec<Input>> = Mutex::new(Vec::new());

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
    let (dev, ino) = id(meta)?;
    inputs()
        .iter()
        .find(|i| i.dev == dev && i.ino == ino)
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
    let Some((dev, ino)) = id(meta) else { return };
    let mut v = inputs();
    if !v.iter().any(|i| i.dev == dev && i.ino == ino) {
        v.push(Input {
            dev,
            ino,
            path: path.to_path_buf(),
        });
    }
}

fn id(meta: &Metadata) -> Option<(u64, u64)> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        Some((meta.dev(), meta.ino()))
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
