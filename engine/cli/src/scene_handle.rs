//! A scene held open for a whole program: a local file, or (with the
//! `remote` feature) an object on a web server or in object storage. Every
//! walk of the program reads the same version of it: the file through
//! clones of its handle (a rebuild that renames a new file over the path is
//! not seen), the remote object through its pinned version.

use std::io;
use std::path::Path;
use std::sync::Arc;

use crate::disk::scene_source;
use engine::disk::DiskModel;
use engine::io::{ByteSource, FileSource};

/// Requests in flight at once for a remote scene, unless told otherwise
/// (CesiumJS allows 18 per server, 3DTilesRendererJS 25).
pub const DEFAULT_REQUESTS: usize = 16;

/// The bytes those requests may hold at most, unless told otherwise (the
/// runtime gives them at most an eighth of P_I's share of the footprint).
pub const DEFAULT_READ_AHEAD: u64 = 4 << 20;

/// How a remote scene is read ahead: at most `max` requests in flight
/// (1: one at a time), holding at most `ahead_bytes`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Requests {
    pub max: usize,
    pub ahead_bytes: u64,
}

impl Default for Requests {
    fn default() -> Self {
        Self {
            max: DEFAULT_REQUESTS,
            ahead_bytes: DEFAULT_READ_AHEAD,
        }
    }
}

/// A scene opened once, from which each walk takes its own source.
#[derive(Debug)]
pub enum SceneHandle {
    /// A local file.
    File(std::fs::File),
    /// An object on a server, read through a local disk cache if given.
    #[cfg(feature = "remote")]
    Remote(
        crate::remote::RemoteSource,
        Option<crate::disk_cache::CachedSource>,
    ),
}

/// What a scene's reads cost on the network (counters since it was opened).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct NetworkCounters {
    /// Ranged GETs answered.
    pub requests: u64,
    /// Bytes they returned.
    pub bytes: u64,
    /// Reads that failed after retries.
    pub failures: u64,
    /// Bytes the disk cache served instead.
    pub cache_hit_bytes: u64,
    /// Reads served from requests started ahead, and the bytes of answers
    /// dropped unread (their ranges no longer hinted).
    pub ahead_hits: u64,
    pub ahead_dropped_bytes: u64,
    /// The most requests in flight at once so far (not a difference).
    pub peak_in_flight: u64,
}

impl std::ops::Sub for NetworkCounters {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self {
            requests: self.requests - o.requests,
            bytes: self.bytes - o.bytes,
            failures: self.failures - o.failures,
            cache_hit_bytes: self.cache_hit_bytes - o.cache_hit_bytes,
            ahead_hits: self.ahead_hits - o.ahead_hits,
            ahead_dropped_bytes: self.ahead_dropped_bytes - o.ahead_dropped_bytes,
            peak_in_flight: self.peak_in_flight,
        }
    }
}

/// Where fetched bytes of a remote scene are kept between runs.
#[derive(Debug, Clone)]
pub struct DiskCacheSpec {
    /// The cache folder.
    pub dir: std::path::PathBuf,
    /// Its bound in bytes.
    pub max_bytes: u64,
}

impl SceneHandle {
    /// Opens `path`: a URL (`http://`, `https://`, `s3://`) when the
    /// `remote` feature is on and the text is one, else a local file.
    pub fn open(path: &Path) -> io::Result<Self> {
        Self::open_cached(path, None)
    }

    /// [`Self::open`], a remote scene read through the disk cache `cache`
    /// (ignored for a local file).
    pub fn open_cached(path: &Path, cache: Option<&DiskCacheSpec>) -> io::Result<Self> {
        Self::open_with(path, cache, Requests::default())
    }

    /// [`Self::open_cached`] with `requests` in flight for a remote scene.
    pub fn open_with(
        path: &Path,
        cache: Option<&DiskCacheSpec>,
        requests: Requests,
    ) -> io::Result<Self> {
        #[cfg(feature = "remote")]
        if let Some(url) = path.to_str().filter(|s| crate::remote::is_remote(s)) {
            let opts = crate::remote::RemoteOptions {
                max_requests: requests.max,
                read_ahead_bytes: requests.ahead_bytes,
                ..crate::remote::RemoteOptions::default()
            };
            let remote = crate::remote::RemoteSource::open(url, &opts).map_err(io::Error::other)?;
            let cached = match cache {
                Some(c) => {
                    let dc =
                        crate::disk_cache::DiskCache::open(&c.dir, c.max_bytes).map_err(|e| {
                            io::Error::new(e.kind(), format!("disk cache {}: {e}", c.dir.display()))
                        })?;
                    Some(crate::disk_cache::CachedSource::new(remote.clone(), dc)?)
                }
                None => None,
            };
            return Ok(Self::Remote(remote, cached));
        }
        let _ = (cache, requests);
        engine::infile::open(path).map(Self::File)
    }

    /// Requests made to the server and the bytes they returned so far, and
    /// the bytes the disk cache served (zeros for a local file).
    pub fn network(&self) -> NetworkCounters {
        match self {
            Self::File(_) => NetworkCounters::default(),
            #[cfg(feature = "remote")]
            Self::Remote(r, c) => {
                let s = r.stats();
                NetworkCounters {
                    requests: s.requests,
                    bytes: s.bytes,
                    failures: s.failures,
                    cache_hit_bytes: c.as_ref().map_or(0, |c| c.stats().hit_bytes),
                    ahead_hits: s.ahead.hits,
                    ahead_dropped_bytes: s.ahead.dropped_bytes,
                    peak_in_flight: s.ahead.peak_in_flight,
                }
            }
        }
    }

    /// Bytes served by the disk cache and fetched from the server so far
    /// (a remote scene read through a cache).
    #[cfg(feature = "remote")]
    pub fn cache_stats(&self) -> Option<crate::disk_cache::CacheStats> {
        match self {
            Self::Remote(_, Some(c)) => Some(c.stats()),
            _ => None,
        }
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
            Self::Remote(r, None) => Arc::new(r.clone()),
            #[cfg(feature = "remote")]
            Self::Remote(_, Some(c)) => Arc::new(c.clone()),
        })
    }

    /// A walk's rep source: a file with its page cache dropped, or behind a
    /// throttled disk model ([`scene_source`]); a remote object as it is,
    /// the network being the model (a disk model is refused there).
    pub fn source(&self, model: Option<DiskModel>) -> io::Result<Arc<dyn ByteSource>> {
        match self {
            Self::File(f) => scene_source(f.try_clone()?, model),
            #[cfg(feature = "remote")]
            Self::Remote(r, _) => match model {
                None => self.raw(),
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
