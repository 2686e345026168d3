//! The build cache behind `hlod-view MODEL.glb`: a model is built once per
//! content and parameters, then reused.
//!
//! The key is a BLAKE3 hash of the model's bytes, of every external buffer
//! it names, of the build parameters, and of the builder's version and the
//! scene format's version; the scene is `DIR/STEM-KEY.hlod`, and its header
//! records the key it was built for ([`engine::FileHeader::source_key`]).
//!
//! The directory is the first of: the caller's choice (`hlod-view --cache
//! DIR`), `$HLOD_CACHE_DIR`, `$XDG_CACHE_HOME/hlod`, `$HOME/.cache/hlod`,
//! else a private folder of the user's in the system's temporary directory
//! (`hlod-cache-UID`, mode 0700). It must be the user's and writable by no
//! one else ([`prepare_dir`]): an entry planted there by another user is
//! never opened.
//!
//! An entry is used only when it is a regular file (not a link) owned by
//! the user, its header records this model's key, and every rep passes its
//! checksum ([`check_entry`]); anything else is rebuilt, with a warning
//! that says why. Entries are written atomically by
//! [`crate::build::build_file_reporting`].

use std::path::{Path, PathBuf};

use crate::build::{BuildError, BuildParams, Report, build_file_reporting};
use crate::import::{self, ImportError};

/// The cache directory (see the module documentation).
pub fn cache_dir(chosen: Option<&Path>) -> PathBuf {
    cache_dir_in(chosen, |k| std::env::var_os(k))
}

/// [`cache_dir`] with the environment given.
fn cache_dir_in(
    chosen: Option<&Path>,
    var: impl Fn(&str) -> Option<std::ffi::OsString>,
) -> PathBuf {
    if let Some(d) = chosen {
        return d.to_path_buf();
    }
    let env = |k: &str| var(k).filter(|v| !v.is_empty()).map(PathBuf::from);
    env("HLOD_CACHE_DIR")
        .or_else(|| env("XDG_CACHE_HOME").map(|d| d.join("hlod")))
        .or_else(|| env("HOME").map(|d| d.join(".cache").join("hlod")))
        .unwrap_or_else(|| std::env::temp_dir().join(format!("hlod-cache-{}", user_id())))
}

use engine::infile::user_id;

/// Makes `dir` (mode 0700 when new) and checks that it is a directory of
/// the user's that no other user can write: entries in a folder others
/// can write could be planted.
pub fn prepare_dir(dir: &Path) -> Result<(), BuildError> {
    let io = |source| BuildError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut b = std::fs::DirBuilder::new();
    b.recursive(true);
    #[cfg(unix)]
    std::os::unix::fs::DirBuilderExt::mode(&mut b, 0o700);
    b.create(dir).map_err(io)?;
    let meta = std::fs::symlink_metadata(dir).map_err(io)?;
    let refuse = |why: String| {
        Err(BuildError::Io {
            path: dir.to_path_buf(),
            source: std::io::Error::new(
                std::io::ErrorKind::PermissionDenied,
                format!("{why}: refusing it as a build cache (choose another with --cache DIR)"),
            ),
        })
    };
    if meta.file_type().is_symlink() {
        // A link the user made to a folder of theirs is fine; its target
        // is checked below.
        let target = std::fs::metadata(dir).map_err(io)?;
        return check_dir_meta(&target).or_else(refuse);
    }
    check_dir_meta(&meta).or_else(refuse)
}

fn check_dir_meta(meta: &std::fs::Metadata) -> Result<(), String> {
    if !meta.is_dir() {
        return Err("is not a directory".into());
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if meta.uid() != user_id() {
            return Err(format!(
                "belongs to user {}, not to you ({})",
                meta.uid(),
                user_id()
            ));
        }
        if meta.mode() & 0o022 != 0 {
            return Err(format!(
                "can be written by other users (mode {:o})",
                meta.mode() & 0o7777
            ));
        }
    }
    Ok(())
}

/// Why the cache entry at `scene` cannot be used for `key`, if it cannot:
/// not a regular file of the user's, not a scene, built for another key,
/// or a rep failing its checksum. The entry is read without being taken as
/// an input of the process, so that a rebuild may replace it.
pub fn check_entry(scene: &Path, key: &[u8; 16]) -> Result<engine::SceneMeta, String> {
    let meta = std::fs::symlink_metadata(scene).map_err(|e| e.to_string())?;
    if meta.file_type().is_symlink() || !meta.is_file() {
        return Err(format!("is {}", engine::infile::kind_of(&meta)));
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if meta.uid() != user_id() {
            return Err(format!("belongs to user {}, not to you", meta.uid()));
        }
    }
    let file = engine::infile::open_unremembered(scene).map_err(|e| e.to_string())?;
    let src = engine::FileSource::from_file(file).map_err(|e| e.to_string())?;
    check_entry_source(src, key)
}

/// The checks of [`check_entry`] on an entry's bytes: a scene, built for
/// `key` (its header records it), every rep passing its checksum (the fuzz
/// target's entry: `tests/fuzz/fuzz_targets/cache_entry.rs`). Returns the
/// scene's description.
pub fn check_entry_source<S: engine::ByteSource>(
    src: S,
    key: &[u8; 16],
) -> Result<engine::SceneMeta, String> {
    let opened = engine::SceneFile::from_source(src).map_err(|e| e.to_string())?;
    let found = opened.header().source_key;
    if &found != key {
        return Err(if found == [0; 16] {
            "records no source (built by another hlod-build)".into()
        } else {
            format!(
                "was built from another model or with other parameters ({})",
                hex(&found)
            )
        });
    }
    opened.verify_all_reps().map_err(|e| e.to_string())?;
    Ok(opened.meta())
}

/// Lower-case hex digits of `bytes`.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The cache key of building `input` with `params`: 32 hex digits of
/// [`key_bytes`].
pub fn key(input: &Path, params: &BuildParams) -> Result<String, ImportError> {
    key_bytes(input, params).map(|k| hex(&k))
}

/// The 16 bytes that identify building `input` with `params` (what a scene
/// file's header records as its source). The files are hashed as they are
/// read, a megabyte at a time (opening a model costs no memory for its key).
pub fn key_bytes(input: &Path, params: &BuildParams) -> Result<[u8; 16], ImportError> {
    let read_err = |path: &Path, source| ImportError::Read {
        path: path.to_path_buf(),
        source,
    };
    let mut h = blake3::Hasher::new();
    h.update(b"hlod-build cache v2\0");
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(&engine::format::VERSION.to_le_bytes());
    h.update(&crate::lod::SIMPLIFICATION_REVISION.to_le_bytes());
    h.update(format!("{params:?}").as_bytes());
    hash_file(&mut h, input, u64::MAX).map_err(|e| read_err(input, e))?;
    for (f, len) in import::read_files(input) {
        // A missing buffer is the build's error to report; it keys as absent.
        if hash_file(&mut h, &f, len).is_err() {
            h.update(b"missing");
        }
    }
    let mut k = [0u8; 16];
    k.copy_from_slice(&h.finalize().as_bytes()[..16]);
    Ok(k)
}

/// Adds the first `limit` bytes of a regular file (what the importer reads
/// of it: a buffer's declared length) and their count to `h`, read in
/// chunks.
fn hash_file(h: &mut blake3::Hasher, path: &Path, limit: u64) -> std::io::Result<()> {
    use std::io::Read;
    let (f, meta) = engine::infile::open_with_meta(path)?;
    h.update(&meta.len().min(limit).to_le_bytes());
    let mut f = f.take(limit);
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            return Ok(());
        }
        h.update(&buf[..n]);
    }
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

/// A cached scene, whether it was already there, and what its build left
/// out ([`BuildParams::ifc_voids`]).
#[derive(Clone, Debug)]
pub struct Cached {
    pub scene: PathBuf,
    pub hit: bool,
    /// Triangles of the IFC opening voids and spaces left out (recorded in
    /// the scene file).
    pub hidden_triangles: u64,
    /// How many objects those were: known when the scene was built now,
    /// not recorded in the file.
    pub hidden_objects: Option<u64>,
}

/// The scene of `input` from the cache in `dir`, built first when absent
/// (or when the entry cannot be used: [`check_entry`], said as a warning).
pub fn cached_scene(
    input: &Path,
    params: &BuildParams,
    dir: &Path,
    report: Report<'_>,
) -> Result<Cached, BuildError> {
    report("hashing the model", 0, 0);
    prepare_dir(dir)?;
    let scene = entry(input, params, dir)?;
    let key = key_bytes(input, params)?;
    match std::fs::symlink_metadata(&scene) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        _ => {
            report("checking the cached scene", 0, 0);
            match check_entry(&scene, &key) {
                Ok(meta) => {
                    return Ok(Cached {
                        scene,
                        hit: true,
                        hidden_triangles: meta.hidden_triangles,
                        hidden_objects: None,
                    });
                }
                Err(why) => {
                    tracing::warn!("{}: cache entry {why}; rebuilding it", scene.display());
                    // A link or another file type is removed, never
                    // written through; a scene file is replaced whole.
                    let meta = std::fs::symlink_metadata(&scene);
                    if meta.is_ok_and(|m| !m.is_file()) {
                        std::fs::remove_file(&scene).map_err(|source| BuildError::Io {
                            path: scene.clone(),
                            source,
                        })?;
                    }
                }
            }
        }
    }
    let stats = build_file_reporting(input, &scene, params, false, report)?;
    Ok(Cached {
        scene,
        hit: false,
        hidden_triangles: stats.hidden_triangles,
        hidden_objects: Some(stats.hidden_objects),
    })
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

    /// A model, its cache folder and its entry's path.
    fn cached_model(dir: &Path, seed: u64) -> (PathBuf, PathBuf, PathBuf) {
        let model = dir.join(format!("m{seed}.glb"));
        crate::scenegen::plant::write_plant(
            &crate::scenegen::plant::PlantParams {
                seed,
                objects: 12,
                triangles: 4_000,
            },
            &model,
        )
        .unwrap();
        let cache = dir.join("cache");
        let e = entry(&model, &BuildParams::default(), &cache).unwrap();
        (model, cache, e)
    }

    fn fresh(model: &Path, cache: &Path) -> Cached {
        let c = cached_scene(model, &BuildParams::default(), cache, &|_, _, _| {}).unwrap();
        let key = key_bytes(model, &BuildParams::default()).unwrap();
        check_entry(&c.scene, &key).unwrap();
        c
    }

    #[test]
    fn a_planted_link_is_removed_never_written_through() {
        let dir = tempfile::tempdir().unwrap();
        let (model, cache, e) = cached_model(dir.path(), 4);
        prepare_dir(&cache).unwrap();
        let victim = dir.path().join("victim.txt");
        std::fs::write(&victim, b"precious").unwrap();
        std::os::unix::fs::symlink(&victim, &e).unwrap();
        let c = fresh(&model, &cache);
        assert!(!c.hit);
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
        assert!(std::fs::symlink_metadata(&e).unwrap().is_file());
        // A link to a valid entry is not used either.
        let real = dir.path().join("real.hlod");
        std::fs::rename(&e, &real).unwrap();
        std::os::unix::fs::symlink(&real, &e).unwrap();
        let key = key_bytes(&model, &BuildParams::default()).unwrap();
        assert!(check_entry(&e, &key).unwrap_err().contains("symbolic link"));
        assert!(!fresh(&model, &cache).hit);
    }

    #[test]
    fn a_damaged_entry_or_another_scene_under_the_key_is_rebuilt() {
        let dir = tempfile::tempdir().unwrap();
        let (model, cache, e) = cached_model(dir.path(), 5);
        let key = key_bytes(&model, &BuildParams::default()).unwrap();
        assert!(!fresh(&model, &cache).hit);
        assert!(fresh(&model, &cache).hit);
        // One rep byte flipped: its checksum fails, the entry is rebuilt.
        let good = std::fs::read(&e).unwrap();
        let rep = engine::SceneFile::open(&e).unwrap().skeleton().reps[1];
        let mut bad = good.clone();
        bad[rep.offset as usize + rep.len as usize / 2] ^= 0x10;
        std::fs::write(&e, &bad).unwrap();
        assert!(check_entry(&e, &key).is_err());
        assert!(!fresh(&model, &cache).hit);
        assert_eq!(std::fs::read(&e).unwrap(), good, "rebuilt byte for byte");
        // Another model's valid scene under this model's key.
        let (other, _, other_entry) = cached_model(dir.path(), 6);
        fresh(&other, &cache);
        std::fs::copy(&other_entry, &e).unwrap();
        let why = check_entry(&e, &key).unwrap_err();
        assert!(why.contains("another model"), "{why}");
        assert!(!fresh(&model, &cache).hit);
        assert_eq!(std::fs::read(&e).unwrap(), good);
    }

    #[test]
    fn the_cache_folder_is_the_users_own() {
        let home = |k: &str| (k == "HOME").then(|| "home-u".into());
        assert_eq!(cache_dir_in(None, home), Path::new("home-u/.cache/hlod"));
        let xdg = |k: &str| (k == "XDG_CACHE_HOME").then(|| "xdg".into());
        assert_eq!(cache_dir_in(None, xdg), Path::new("xdg/hlod"));
        // Without HOME or XDG_CACHE_HOME: a folder of this user's, never
        // one shared by all.
        let none = cache_dir_in(None, |_| None);
        assert_eq!(
            none,
            std::env::temp_dir().join(format!("hlod-cache-{}", user_id()))
        );
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().join("c");
        prepare_dir(&d).unwrap();
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&d).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o700, "made private");
        // A folder others may write (as /tmp is) is refused.
        std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o1777)).unwrap();
        let e = prepare_dir(&d).unwrap_err().to_string();
        assert!(e.contains("can be written by other users"), "{e}");
    }

    #[test]
    fn an_obj_files_material_library_is_part_of_the_key() {
        let dir = tempfile::tempdir().unwrap();
        let obj = dir.path().join("m.obj");
        std::fs::write(
            &obj,
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
        )
        .unwrap();
        std::fs::write(dir.path().join("m.mtl"), "newmtl a\nKd 1 0 0\n").unwrap();
        let p = BuildParams::default();
        let k1 = key(&obj, &p).unwrap();
        std::fs::write(dir.path().join("m.mtl"), "newmtl a\nKd 0 1 0\n").unwrap();
        assert_ne!(k1, key(&obj, &p).unwrap(), "a new colour, a new entry");
    }

    #[test]
    fn an_external_buffer_is_part_of_the_key() {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/2CylinderEngine");
        let dir = tempfile::tempdir().unwrap();
        for f in ["2CylinderEngine.gltf", "2CylinderEngine0.bin"] {
            std::fs::copy(src.join(f), dir.path().join(f)).unwrap();
        }
        let model = dir.path().join("2CylinderEngine.gltf");
        let p = BuildParams::default();
        let k1 = key(&model, &p).unwrap();
        let bin = dir.path().join("2CylinderEngine0.bin");
        let mut b = std::fs::read(&bin).unwrap();
        b[100] ^= 1;
        std::fs::write(&bin, b).unwrap();
        assert_ne!(k1, key(&model, &p).unwrap());
        // And a GLB's JSON chunk alone names its buffers.
        let glb = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/bunny.glb");
        let part = import::json_part(&glb).unwrap();
        assert!(part.len() < 4096, "{} bytes read for the JSON", part.len());
        assert!(import::external_files(&part, Path::new(".")).is_empty());
    }
}
