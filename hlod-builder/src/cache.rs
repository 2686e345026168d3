//! The build cache behind `hlod-view MODEL.glb`: a model is built once per
//! content and parameters, then reused.
//!
//! The key is a BLAKE3 hash of the model's bytes, of every external buffer
//! it names, of the build parameters, and of the builder's version and the
//! scene format's version; the scene is `DIR/STEM-KEY.hlod`. The directory
//! is the first of: the caller's choice (`hlod-view --cache DIR`),
//! `$HLOD_CACHE_DIR`, `$XDG_CACHE_HOME/hlod`, `$HOME/.cache/hlod`, and the
//! system's temporary directory. Entries are written atomically by
//! [`crate::build::build_file_reporting`]; an entry that no longer opens is
//! rebuilt.

use std::path::{Path, PathBuf};

use crate::build::{BuildError, BuildParams, Report, build_file_reporting};
use crate::import::{self, ImportError};

/// The cache directory (see the module documentation).
pub fn cache_dir(chosen: Option<&Path>) -> PathBuf {
    if let Some(d) = chosen {
        return d.to_path_buf();
    }
    let env = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    env("HLOD_CACHE_DIR")
        .or_else(|| env("XDG_CACHE_HOME").map(|d| d.join("hlod")))
        .or_else(|| env("HOME").map(|d| d.join(".cache").join("hlod")))
        .unwrap_or_else(|| std::env::temp_dir().join("hlod-cache"))
}

/// The cache key of building `input` with `params`: 32 hex digits.
pub fn key(input: &Path, params: &BuildParams) -> Result<String, ImportError> {
    let read_err = |path: &Path, source| ImportError::Read {
        path: path.to_path_buf(),
        source,
    };
    let bytes = engine::limits::read_bounded(input, import::max_input_bytes())
        .map_err(|e| read_err(input, e))?;
    let mut h = blake3::Hasher::new();
    h.update(b"hlod-build cache v1\0");
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(&engine::format::VERSION.to_le_bytes());
    h.update(format!("{params:?}").as_bytes());
    h.update(&(bytes.len() as u64).to_le_bytes());
    h.update(&bytes);
    let base = input.parent().unwrap_or(Path::new("."));
    for f in import::external_files(&bytes, base) {
        // A missing buffer is the build's error to report; it keys as absent.
        match engine::limits::read_bounded(&f, import::max_input_bytes()) {
            Ok(b) => {
                h.update(&(b.len() as u64).to_le_bytes());
                h.update(&b);
            }
            Err(_) => {
                h.update(b"missing");
            }
        }
    }
    Ok(h.finalize().to_hex()[..32].to_string())
}

/// Where the cached scene of `input` lives.
pub fn entry(input: &Path, params: &BuildParams, dir: &Path) -> Result<PathBuf, ImportError> {
    let stem = input
        .file_stem()
        .map_or_else(|| "model".into(), |s| s.to_string_lossy().into_owned());
    let safe: String = stem
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .take(64)
        .collect();
    Ok(dir.join(format!("{safe}-{}.hlod", key(input, params)?)))
}

/// A cached scene and whether it was already there.
#[derive(Clone, Debug)]
pub struct Cached {
    pub scene: PathBuf,
    pub hit: bool,
}

/// The scene of `input` from the cache in `dir`, built first when absent
/// (or when the entry does not open).
pub fn cached_scene(
    input: &Path,
    params: &BuildParams,
    dir: &Path,
    report: Report<'_>,
) -> Result<Cached, BuildError> {
    report("hashing the model", 0, 0);
    let scene = entry(input, params, dir)?;
    if scene.is_file() && engine::SceneFile::open(&scene).is_ok() {
        return Ok(Cached { scene, hit: true });
    }
    std::fs::create_dir_all(dir).map_err(|source| BuildError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    build_file_reporting(input, &scene, params, false, report)?;
    Ok(Cached { scene, hit: false })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_key_follows_content_and_parameters_and_a_hit_reuses_the_scene() {
        let dir = tempfile::tempdir().unwrap();
        let model = dir.path().join("m.glb");
        crate::scenegen::plant::write_plant(
            &crate::scenegen::plant::PlantParams {
                seed: 3,
                objects: 20,
                triangles: 5_000,
            },
            &model,
        )
        .unwrap();
        let p = BuildParams::default();
        let k1 = key(&model, &p).unwrap();
        assert_eq!(k1, key(&model, &p).unwrap(), "deterministic");
        let other = BuildParams {
            leaf_tris: 512,
            ..p
        };
        assert_ne!(
            k1,
            key(&model, &other).unwrap(),
            "parameters are in the key"
        );
        let cache = dir.path().join("cache");
        let first = cached_scene(&model, &p, &cache, &|_, _, _| {}).unwrap();
        assert!(!first.hit);
        let second = cached_scene(&model, &p, &cache, &|_, _, _| {}).unwrap();
        assert!(second.hit);
        assert_eq!(first.scene, second.scene);
        // New content, new entry.
        let mut bytes = std::fs::read(&model).unwrap();
        bytes.extend_from_slice(b"    ");
        std::fs::write(&model, &bytes).unwrap();
        assert_ne!(k1, key(&model, &p).unwrap());
        // A damaged entry is rebuilt, not trusted.
        std::fs::write(&second.scene, b"junk").unwrap();
        let k = entry(&model, &p, &cache).unwrap();
        std::fs::write(&k, b"junk").unwrap();
        let again = cached_scene(&model, &p, &cache, &|_, _, _| {}).unwrap();
        assert!(!again.hit);
        engine::SceneFile::open(&again.scene).unwrap();
    }
}
