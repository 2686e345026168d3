//! Opening a scene without holding its geometry ([`open`]): the JSON is
//! parsed, every mesh is read once for its size and box and dropped, and
//! [`Opened::mesh`] reads a mesh again when the builder needs it. The GLB's
//! BIN chunk and external `.bin` files stay on disk, read by span; so a
//! build's memory does not grow with the input's geometry, and inputs past
//! the in-memory loader's limit (half the machine) open.

use std::io::Read;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use super::access::{BufData, Buffers, Decoded};
use super::{ImportError, Imported, doc, prims};
use crate::mesh::Mesh;

/// Decoded meshopt views kept between mesh reads.
const DECODED_CACHE_BYTES: u64 = 64 << 20;

/// A scene opened lazily: everything of [`Imported`] but the geometry.
#[derive(Debug)]
pub struct Opened {
    /// The scene; its `meshes` is empty, its `meta` full.
    pub scene: Imported,
    geometry: Geometry,
    path: PathBuf,
}

/// Where an opened scene's meshes come from.
#[derive(Debug)]
enum Geometry {
    /// A glTF's document and buffers, read again per mesh.
    Gltf {
        doc: Box<doc::Doc>,
        data: Vec<BufData>,
        decoded: Decoded,
        /// [`Buffers`]' bound on accessor sizes, computed once.
        capacity: u64,
    },
    /// A mesh file's meshes, read whole ([`super::meshfile`]).
    Meshes(Vec<Option<Mesh>>),
}

impl Opened {
    /// A scene whose meshes are in memory (a PLY, OBJ or STL file).
    pub(super) fn in_memory(scene: Imported, meshes: Vec<Option<Mesh>>, path: &Path) -> Self {
        Self {
            scene,
            geometry: Geometry::Meshes(meshes),
            path: path.to_path_buf(),
        }
    }

    /// Mesh `m`'s geometry, read from the file again (`None` when it has no
    /// usable triangles; its warnings were given when the scene opened).
    pub fn mesh(&self, m: usize) -> Result<Option<Mesh>, ImportError> {
        let (doc, data, decoded, capacity) = match &self.geometry {
            Geometry::Meshes(meshes) => return Ok(meshes.get(m).cloned().flatten()),
            Geometry::Gltf {
                doc,
                data,
                decoded,
                capacity,
            } => (doc, data, decoded, *capacity),
        };
        let bufs = Buffers::with_capacity(doc.as_ref(), data, decoded, capacity);
        let mut warnings = Vec::new();
        prims::read_mesh(&bufs, m, &mut warnings)
            .map(|(mesh, ..)| mesh)
            .map_err(|what| ImportError::Invalid {
                path: self.path.clone(),
                what,
            })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The scene alone (its meshes empty).
    pub fn into_scene(self) -> Imported {
        self.scene
    }
}

const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// Opens `path` lazily: a glTF (`.glb`, or `.gltf` with external or
/// embedded buffers) by span, a PLY, OBJ or STL file (by its extension)
/// whole; the same checks and errors as [`super::load`].
pub fn open(path: &Path) -> Result<Opened, ImportError> {
    match super::Format::of(path) {
        super::Format::Gltf => open_gltf(path),
        super::Format::Ifc => open_ifc(path),
        f => super::meshfile::open(path, f),
    }
}

/// An IFC file, converted to a GLB that is opened and then removed (the
/// open file keeps its data); errors name the IFC file.
fn open_ifc(path: &Path) -> Result<Opened, ImportError> {
    let glb = super::ifc::convert(path)?;
    let mut opened = open_gltf(glb.path()).map_err(|e| e.naming(path))?;
    opened.path = path.to_path_buf();
    Ok(opened)
}

fn open_gltf(path: &Path) -> Result<Opened, ImportError> {
    let read_err = |source| ImportError::Read {
        path: path.to_path_buf(),
        source,
    };
    let parse_err = |what: String| ImportError::Parse {
        path: path.to_path_buf(),
        what,
    };
    let (file, meta) = engine::infile::open_with_meta(path).map_err(read_err)?;
    let size = meta.len();
    let mut head = [0u8; 12];
    let n = (&file).take(12).read(&mut head).map_err(read_err)?;
    let (json, bin) = if n == 12 && &head[..4] == b"glTF" {
        let (json_at, json_len, bin) = glb_chunks(&file, &head, size).map_err(parse_err)?;
        let mut json = vec![0u8; json_len as usize];
        file.read_exact_at(&mut json, json_at).map_err(read_err)?;
        (json, bin)
    } else {
        let bytes =
            engine::limits::read_bounded(path, super::max_input_bytes()).map_err(read_err)?;
        (bytes, None)
    };
    let doc = super::parse_doc(&json, path)?;
    drop(json);
    let base_dir = path.parent().unwrap_or(Path::new("."));
    let data = buffers(&doc, bin.map(|(at, len)| (&file, at, len)), base_dir).map_err(|what| {
        ImportError::Invalid {
            path: path.to_path_buf(),
            what,
        }
    })?;
    let decoded = Decoded::new(DECODED_CACHE_BYTES);
    let bufs = Buffers::new(&doc, &data, &decoded);
    let capacity = bufs.capacity();
    let scene = super::assemble(&doc, &bufs, path, false)?;
    // The hierarchy is placed; mesh reads need only meshes, accessors,
    // views, buffers and materials.
    let mut doc = doc;
    doc.nodes = Vec::new();
    doc.scenes = Vec::new();
    Ok(Opened {
        scene,
        geometry: Geometry::Gltf {
            doc: Box::new(doc),
            data,
            decoded,
            capacity,
        },
        path: path.to_path_buf(),
    })
}

/// The JSON chunk's offset and length and the BIN chunk's, from a GLB's
/// header and chunk headers, checked against the file's size.
#[allow(clippy::type_complexity)]
fn glb_chunks(
    file: &std::fs::File,
    head: &[u8; 12],
    size: u64,
) -> Result<(u64, u64, Option<(u64, u64)>), String> {
    let word = |b: &[u8]| u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let (version, length) = (word(&head[4..]), u64::from(word(&head[8..])));
    if version != 2 {
        return Err(format!("GLB container: version {version}, expected 2"));
    }
    if length < 12 {
        return Err(format!(
            "GLB header: length {length} is shorter than the 12-byte header"
        ));
    }
    if length > size {
        return Err(format!(
            "GLB container: the header says {length} bytes, the file has {size} (truncated?)"
        ));
    }
    let chunk = |at: u64| -> Result<Option<(u32, u64)>, String> {
        if at + 8 > length {
            return Ok(None);
        }
        let mut h = [0u8; 8];
        file.read_exact_at(&mut h, at)
            .map_err(|e| format!("GLB container: {e}"))?;
        let len = u64::from(word(&h[..4]));
        if at + 8 + len > length {
            return Err(format!(
                "GLB container: the chunk at byte {at} runs past the file's {length} bytes"
            ));
        }
        Ok(Some((word(&h[4..]), len)))
    };
    let (kind, json_len) = chunk(12)?.ok_or("GLB container: no JSON chunk")?;
    if kind != CHUNK_JSON {
        return Err("GLB container: the first chunk is not JSON".into());
    }
    if json_len > super::max_input_bytes() {
        return Err(format!("GLB container: a JSON chunk of {json_len} bytes"));
    }
    let bin = match chunk(20 + json_len)? {
        Some((CHUNK_BIN, len)) => Some((28 + json_len, len)),
        _ => None,
    };
    Ok((20, json_len, bin))
}

/// Every buffer as a file span where it is a file (the BIN chunk, an
/// external regular file), else in memory (a data URI, a device read up to
/// its declared length).
fn buffers(
    d: &doc::Doc,
    bin: Option<(&std::fs::File, u64, u64)>,
    base_dir: &Path,
) -> Result<Vec<BufData>, String> {
    let mut out = Vec::new();
    let mut bin = bin;
    for (i, buf) in d.buffers.iter().enumerate() {
        let data = match &buf.uri {
            None if buf.is_fallback() => BufData::Mem(Vec::new()),
            None => {
                let (f, offset, len) = bin
                    .take()
                    .ok_or_else(|| format!("buffers[{i}] refers to a missing GLB BIN chunk"))?;
                BufData::File {
                    file: f.try_clone().map_err(|e| format!("buffers[{i}]: {e}"))?,
                    offset,
                    len,
                }
            }
            Some(uri) if uri.starts_with("data:") => {
                // The in-memory loader decodes data URIs; reuse it.
                let one = doc::Doc {
                    buffers: vec![doc::Buffer {
                        uri: Some(uri.clone()),
                        byte_length: buf.byte_length,
                        extensions: Default::default(),
                    }],
                    ..Default::default()
                };
                let mut v = super::load_buffers(&one, None, base_dir)
                    .map_err(|e| e.replace("buffers[0]", &format!("buffers[{i}]")))?;
                BufData::Mem(v.pop().unwrap_or_default())
            }
            Some(uri) => {
                let path = super::resolve_uri(i, uri, base_dir)?;
                let cannot = |e: std::io::Error| {
                    format!("buffers[{i}]: cannot read {}: {e}", path.display())
                };
                let (file, m) = engine::infile::open_with_meta(&path).map_err(cannot)?;
                BufData::File {
                    file,
                    offset: 0,
                    len: m.len().min(buf.byte_length),
                }
            }
        };
        super::check_buffer_length(i, buf, data.len())?;
        out.push(data);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenegen::plant::{PlantParams, write_plant};

    fn plant(path: &Path) {
        let p = PlantParams {
            seed: 9,
            objects: 120,
            triangles: 60_000,
        };
        write_plant(&p, path).unwrap();
    }

    #[test]
    fn reads_what_the_in_memory_loader_holds() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["p.glb", "p.gltf"] {
            let path = dir.path().join(name);
            plant(&path);
            let eager = super::super::load(&path).unwrap();
            let lazy = open(&path).unwrap();
            assert!(lazy.scene.meshes.is_empty());
            assert_eq!(lazy.scene.meta, eager.meta);
            assert_eq!(lazy.scene.origin, eager.origin);
            assert_eq!(lazy.scene.instances.len(), eager.instances.len());
            for (a, b) in lazy.scene.instances.iter().zip(&eager.instances) {
                assert_eq!(
                    (a.mesh, a.transform, &a.name),
                    (b.mesh, b.transform, &b.name)
                );
            }
            for (m, want) in eager.meshes.iter().enumerate() {
                assert_eq!(&lazy.mesh(m).unwrap(), want, "{name}: meshes[{m}]");
            }
        }
    }

    #[test]
    fn truncated_containers_and_short_buffers_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let glb = dir.path().join("p.glb");
        plant(&glb);
        let bytes = std::fs::read(&glb).unwrap();
        let cut = dir.path().join("cut.glb");
        for at in [12, 30, bytes.len() / 2, bytes.len() - 4] {
            std::fs::write(&cut, &bytes[..at]).unwrap();
            let e = open(&cut).unwrap_err();
            assert!(
                matches!(e, ImportError::Parse { .. } | ImportError::Invalid { .. }),
                "cut at {at}: {e}"
            );
            assert!(e.to_string().contains("cut.glb"), "{e}");
        }
        let gltf = dir.path().join("q.gltf");
        plant(&gltf);
        let bin = dir.path().join("q.bin");
        let len = std::fs::metadata(&bin).unwrap().len();
        std::fs::File::options()
            .write(true)
            .open(&bin)
            .unwrap()
            .set_len(len / 2)
            .unwrap();
        let e = open(&gltf).unwrap_err().to_string();
        assert!(
            e.contains("q.gltf") && e.contains("buffers[0]") && e.contains("truncated"),
            "{e}"
        );
    }
}
