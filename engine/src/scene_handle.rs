//! A scene held open for a whole program: a local file, or (with the
//! `remote` feature) an object on a web server or in object storage. Every
//! walk of the program reads the same version of it: the file through
//! clones of its handle (a rebuild that renames a new file over the path is
//! not seen), the remote object through its pinned version.

use std::io;
use std::path::Path;
use std::sync::Arc;

use crate::disk::{DiskModel, scene_source};
use crate::io::{ByteSource, FileSource};

/// A scene opened once, from which each walk takes its own source.
#[derive(Debug)]
pub enum SceneHandle {
    /// A local file.
    File(std::fs::File),
    /// An object on a server.
    #[cfg(feature = "remote")]
    Remote(crate::remote::RemoteSource),
}

impl SceneHandle {
    /// Opens `path`: a URL (`http://`, `https://`, `s3://`) when the
    /// `remote` feature is on and the text is one, else a local file.
    pub fn open(path: &Path) -> io::Result<Self> {
        #[cfg(feature = "remote")]
        if let Some(url) = path.to_str().filter(|s| crate::remote::is_remote(s)) {
            let opts = crate::remote::RemoteOptions::default();
            return crate::remote::RemoteSource::open(url, &opts)
                .map(Self::Remote)
                .map_err(io::Error::other);
        }
        crate::infile::open(path).map(Self::File)
    }

    /// Whether the scene is read over a network.
    pub fn is_remote(&self) -> bool {
        !matches!(self, Self::File(_))
    }

    /// The scene's bytes as they are, for its skeleton, object table and
    /// checks (no disk model, the page cache untouched).
    pub fn raw(&self) -> io::Result<Arc<dyn ByteSource>> {
        Ok(match self {
            Self::File(f) => Arc::new(FileSource::from_file(f.try_clone()?)?),
            #[cfg(feature = "remote")]
            Self::Remote(r) => Arc::new(r.clone()),
        })
    }

    /// A walk's rep source: a file with its page cache dropped, or behind a
    /// throttled disk model ([`scene_source`]); a remote object as it is,
    /// the network being the model (a disk model is refused there).
    pub fn source(&self, model: Option<DiskModel>) -> io::Result<Arc<dyn ByteSource>> {
        match self {
            Self::File(f) => scene_source(f.try_clone()?, model),
            #[cfg(feature = "remote")]
            Self::Remote(r) => match model {
                None => Ok(Arc::new(r.clone())),
                Some(_) => Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    format!(
                        "{}: a disk model applies to local files only (the network sets what a remote read costs)",
                        r.url()
                    ),
                )),
            },
        }
    }
}
