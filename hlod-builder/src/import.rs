//! glTF 2.0 import (`.gltf` + external or embedded buffers, `.glb`).
//!
//! Buffers are loaded here (the `gltf` crate's `import` feature is not used, it
//! pulls in image decoders), and every accessor is read with explicit bounds
//! checks so that a corrupt file gives an error naming the accessor instead of a
//! panic. Structural corruption (bad JSON, buffers or accessors out of range) is
//! an error; a bad part (non-triangle primitive, NaN positions, out-of-range
//! indices, empty mesh) is skipped with a warning.

use std::path::{Path, PathBuf};

use base64::Engine as _;
use glam::Mat4;
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

use crate::mesh::Mesh;

/// Why a glTF file could not be imported.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not a valid glTF 2.0 file: {source}")]
    Parse { path: PathBuf, source: gltf::Error },
    #[error("{path}: {what}")]
    Invalid { path: PathBuf, what: String },
    #[error("{path}: the scene has no renderable triangles")]
    NoTriangles { path: PathBuf },
}

/// One placement of a mesh: an *object*.
#[derive(Clone, Debug)]
pub struct Instance {
    pub mesh: usize,
    /// Local-to-world transform.
    pub transform: Mat4,
    pub name: String,
}

/// The imported scene: meshes in their local space and their placements.
#[derive(Debug, Default)]
pub struct Imported {
    /// One entry per glTF mesh; `None` when it has no usable triangles.
    pub meshes: Vec<Option<Mesh>>,
    pub instances: Vec<Instance>,
    /// Triangles of each mesh as read, before degenerate ones were dropped.
    pub source_tris: Vec<u64>,
    /// Parts skipped, with the reason.
    pub warnings: Vec<String>,
}

impl Imported {
    /// Usable triangles after instancing (degenerate ones dropped).
    pub fn instanced_triangles(&self) -> u64 {
        self.instances
            .iter()
            .filter_map(|i| self.meshes[i.mesh].as_ref())
            .map(|m| m.tri_count() as u64)
            .sum()
    }

    /// Source triangles after instancing, as the file has them.
    pub fn instanced_source_triangles(&self) -> u64 {
        self.instances
            .iter()
            .map(|i| self.source_tris[i.mesh])
            .sum()
    }
}

const MAX_NODE_DEPTH: usize = 256;

/// The largest glTF/GLB file (or external buffer) read: half the machine's
/// memory (the build needs several times its input besides).
pub fn max_input_bytes() -> u64 {
    engine::limits::memory_total() / 2
}

/// Loads `path`.
pub fn load(path: &Path) -> Result<Imported, ImportError> {
    let read_err = |source| ImportError::Read {
        path: path.to_path_buf(),
        source,
    };
    // A pipe or a device (`/dev/zero`) has no length to bound the read by.
    let meta = std::fs::metadata(path).map_err(read_err)?;
    if !meta.is_file() {
        return Err(read_err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a regular file (a directory, pipe or device): save the model to a file first",
        )));
    }
    let gltf = {
        let bytes = engine::limits::read_bounded(path, max_input_bytes()).map_err(|source| {
            ImportError::Read {
                path: path.to_path_buf(),
                source,
            }
        })?;
        parse(&bytes, path)?
    };
    from_gltf(gltf, path.parent().unwrap_or(Path::new(".")), path)
}

/// Parses and validates glTF or GLB bytes.
///
/// `gltf-json` 1.4.1's validation indexes a primitive's POSITION accessor
/// before checking that it exists (a panic on a dangling index), so accessor
/// references of primitives are checked here first.
fn parse(bytes: &[u8], path: &Path) -> Result<gltf::Gltf, ImportError> {
    let parse_err = |source| ImportError::Parse {
        path: path.to_path_buf(),
        source,
    };
    // gltf 1.4.1 subtracts the header's size from a GLB's length field
    // unchecked (a panic with overflow checks, found by fuzzing).
    if let Some(h) = bytes.get(..12)
        && &h[..4] == b"glTF"
    {
        let len = u32::from_le_bytes([h[8], h[9], h[10], h[11]]);
        if len < 12 {
            return Err(ImportError::Invalid {
                path: path.to_path_buf(),
                what: format!("GLB header: length {len} is shorter than the 12-byte header"),
            });
        }
    }
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(parse_err)?;
    let root = document.into_json();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let refs = prim.attributes.values().chain(prim.indices.as_ref());
            if let Some(bad) = refs.map(|a| a.value()).find(|&a| a >= root.accessors.len()) {
                return Err(ImportError::Invalid {
                    path: path.to_path_buf(),
                    what: format!(
                        "mesh {m} primitive {p} refers to accessor {bad}, but there are {}",
                        root.accessors.len()
                    ),
                });
            }
        }
    }
    let document = gltf::Document::from_json(root).map_err(parse_err)?;
    Ok(gltf::Gltf { document, blob })
}

/// Loads glTF or GLB bytes; external buffers are resolved against `base_dir`,
/// errors name `path`.
pub fn load_slice(bytes: &[u8], base_dir: &Path, path: &Path) -> Result<Imported, ImportError> {
    from_gltf(parse(bytes, path)?, base_dir, path)
}

fn from_gltf(mut gltf: gltf::Gltf, base_dir: &Path, path: &Path) -> Result<Imported, ImportError> {
    let invalid = |what: String| ImportError::Invalid {
        path: path.to_path_buf(),
        what,
    };
    let buffers = load_buffers(&mut gltf, base_dir, path)?;
    let doc = &gltf.document;
    let mut out = Imported::default();
    for mesh in doc.meshes() {
        let (m, source) = read_mesh(&mesh, &buffers, &mut out.warnings).map_err(&invalid)?;
        out.meshes.push(m);
        out.source_tris.push(source);
    }
    // Walk the default scene (or the first, or every root node).
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut is_child = vec![false; doc.nodes().len()];
            for n in doc.nodes() {
                for c in n.children() {
                    is_child[c.index()] = true;
                }
            }
            doc.nodes().filter(|n| !is_child[n.index()]).collect()
        }
    };
    let mut stack: Vec<(gltf::Node, Mat4, usize)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, Mat4::IDENTITY, 0))
        .collect();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > MAX_NODE_DEPTH {
            return Err(invalid(format!(
                "node hierarchy deeper than {MAX_NODE_DEPTH} (cyclic?) at node {}",
                node.index()
            )));
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        let world = parent * local;
        if let Some(mesh) = node.mesh() {
            let name = node
                .name()
                .map_or_else(|| format!("node{}", node.index()), str::to_string);
            if !world.is_finite() {
                out.warnings.push(format!(
                    "node {}: non-finite transform, skipped",
                    node.index()
                ));
            } else if out.meshes[mesh.index()].is_some() {
                out.instances.push(Instance {
                    mesh: mesh.index(),
                    transform: world,
                    name,
                });
            }
        }
        let children: Vec<_> = node.children().collect();
        for c in children.into_iter().rev() {
            stack.push((c, world, depth + 1));
        }
    }
    if out.instances.is_empty() {
        return Err(ImportError::NoTriangles {
            path: path.to_path_buf(),
        });
    }
    Ok(out)
}

fn load_buffers(
    gltf: &mut gltf::Gltf,
    base_dir: &Path,
    path: &Path,
) -> Result<Vec<Vec<u8>>, ImportError> {
    let invalid = |what: String| ImportError::Invalid {
        path: path.to_path_buf(),
        what,
    };
    let mut out = Vec::new();
    let mut blob = gltf.blob.take();
    for buf in gltf.document.buffers() {
        let data = match buf.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                invalid(format!(
                    "buffer {} refers to a missing GLB BIN chunk",
                    buf.index()
                ))
            })?,
            gltf::buffer::Source::Uri(uri) => {
                if let Some(rest) = uri.strip_prefix("data:") {
                    let b64 = rest.split_once(";base64,").map(|(_, d)| d).ok_or_else(|| {
                        invalid(format!("buffer {}: unsupported data URI", buf.index()))
                    })?;
                    base64::engine::general_purpose::STANDARD
                        .decode(b64)
                        .map_err(|e| invalid(format!("buffer {}: bad base64: {e}", buf.index())))?
                } else {
                    let file = base_dir.join(percent_decode(uri));
                    read_buffer_file(&file, buf.length() as u64).map_err(|e| {
                        invalid(format!(
                            "buffer {}: cannot read {}: {e}",
                            buf.index(),
                            file.display()
                        ))
                    })?
                }
            }
        };
        if data.len() < buf.length() {
            return Err(invalid(format!(
                "buffer {} has {} bytes, declares {} (truncated file?)",
                buf.index(),
                data.len(),
                buf.length()
            )));
        }
        out.push(data);
    }
    Ok(out)
}

/// The first `len` bytes of an external buffer file (what the buffer
/// declares; a longer file is fine, a shorter one an error), never more:
/// a buffer naming `/dev/zero` reads `len` bytes.
fn read_buffer_file(file: &Path, len: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    if len > max_input_bytes() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::FileTooLarge,
            format!(
                "declares {}, more than the {} this importer reads",
                engine::limits::human(len),
                engine::limits::human(max_input_bytes())
            ),
        ));
    }
    let f = std::fs::File::open(file)?;
    if f.metadata()?.is_dir() {
        return Err(std::io::ErrorKind::IsADirectory.into());
    }
    let mut out = Vec::new();
    out.try_reserve_exact(len as usize)
        .map_err(|_| std::io::Error::from(std::io::ErrorKind::OutOfMemory))?;
    f.take(len).read_to_end(&mut out)?;
    Ok(out)
}

fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            let hex = std::str::from_utf8(&b[i + 1..i + 3]).ok();
            if let Some(v) = hex.and_then(|h| u8::from_str_radix(h, 16).ok()) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// All primitives of a mesh merged, each vertex coloured by its material's
/// base colour; with the triangle count read (degenerate ones included).
fn read_mesh(
    mesh: &gltf::Mesh,
    buffers: &[Vec<u8>],
    warnings: &mut Vec<String>,
) -> Result<(Option<Mesh>, u64), String> {
    let mut out = Mesh::default();
    let mut source = 0u64;
    for prim in mesh.primitives() {
        let what = format!("mesh {} primitive {}", mesh.index(), prim.index());
        let Some(pos_acc) = prim.get(&gltf::Semantic::Positions) else {
            warnings.push(format!("{what}: no POSITION, skipped"));
            continue;
        };
        if !matches!(
            prim.mode(),
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            warnings.push(format!(
                "{what}: mode {:?} is not triangles, skipped",
                prim.mode()
            ));
            continue;
        }
        let positions =
            read_vec3(&pos_acc, buffers).map_err(|e| format!("{what} POSITION: {e}"))?;
        if positions.iter().flatten().any(|c| !c.is_finite()) {
            warnings.push(format!("{what}: non-finite positions, skipped"));
            continue;
        }
        let normals = match prim.get(&gltf::Semantic::Normals) {
            Some(acc) => {
                let n = read_vec3(&acc, buffers).map_err(|e| format!("{what} NORMAL: {e}"))?;
                (n.len() == positions.len() && n.iter().flatten().all(|c| c.is_finite()))
                    .then_some(n)
            }
            None => None,
        };
        let raw = match prim.indices() {
            Some(acc) => read_indices(&acc, buffers).map_err(|e| format!("{what} indices: {e}"))?,
            None => (0..positions.len() as u32).collect(),
        };
        if let Some(&bad) = raw.iter().find(|&&i| i as usize >= positions.len()) {
            warnings.push(format!(
                "{what}: index {bad} out of range of {} vertices, skipped",
                positions.len()
            ));
            continue;
        }
        let indices = triangulate(prim.mode(), &raw);
        let c = prim.material().pbr_metallic_roughness().base_color_factor();
        let color = c.map(|x| (x.clamp(0.0, 1.0) * 255.0).round() as u8);
        let mut part = Mesh {
            colors: vec![color; positions.len()],
            normals: normals.clone().unwrap_or_default(),
            positions,
            indices,
        };
        if normals.is_none() {
            part.compute_normals();
        }
        source += part.tri_count() as u64;
        let dropped = part.remove_degenerate();
        if dropped > 0 {
            warnings.push(format!("{what}: {dropped} degenerate triangles dropped"));
        }
        out.append(&part);
    }
    if out.tri_count() == 0 {
        warnings.push(format!(
            "mesh {}: no usable triangles, its instances skipped",
            mesh.index()
        ));
        return Ok((None, source));
    }
    Ok((Some(out), source))
}

fn triangulate(mode: Mode, idx: &[u32]) -> Vec<u32> {
    match mode {
        Mode::TriangleStrip => (2..idx.len())
            .flat_map(|i| {
                if i % 2 == 0 {
                    [idx[i - 2], idx[i - 1], idx[i]]
                } else {
                    [idx[i - 1], idx[i - 2], idx[i]]
                }
            })
            .collect(),
        Mode::TriangleFan => (2..idx.len())
            .flat_map(|i| [idx[0], idx[i - 1], idx[i]])
            .collect(),
        _ => idx[..idx.len() - idx.len() % 3].to_vec(),
    }
}

/// The bytes of each element of `acc`, bounds-checked against its view and buffer.
fn elements<'a>(
    acc: &gltf::Accessor,
    buffers: &'a [Vec<u8>],
) -> Result<impl Iterator<Item = &'a [u8]> + 'a, String> {
    if acc.sparse().is_some() {
        return Err(format!(
            "accessor {}: sparse accessors are not supported",
            acc.index()
        ));
    }
    let view = acc
        .view()
        .ok_or_else(|| format!("accessor {} has no buffer view", acc.index()))?;
    let buffer = &buffers[view.buffer().index()];
    let elem = acc.size();
    let stride = view.stride().unwrap_or(elem);
    let count = acc.count();
    let view_end = view.offset().checked_add(view.length());
    if view_end.is_none_or(|e| e > buffer.len()) {
        return Err(format!(
            "buffer view {} ({}+{}) out of range of buffer {} ({} bytes)",
            view.index(),
            view.offset(),
            view.length(),
            view.buffer().index(),
            buffer.len()
        ));
    }
    let need = if count == 0 {
        Some(0)
    } else {
        stride
            .checked_mul(count - 1)
            .and_then(|x| x.checked_add(elem))
            .and_then(|x| x.checked_add(acc.offset()))
    };
    if stride < elem || need.is_none_or(|n| n > view.length()) {
        return Err(format!(
            "accessor {} ({count} x {elem} bytes, stride {stride}, offset {}) out of range of buffer view {} ({} bytes)",
            acc.index(),
            acc.offset(),
            view.index(),
            view.length()
        ));
    }
    let start = view.offset() + acc.offset();
    Ok((0..count).map(move |i| &buffer[start + i * stride..start + i * stride + elem]))
}

fn read_vec3(acc: &gltf::Accessor, buffers: &[Vec<u8>]) -> Result<Vec<[f32; 3]>, String> {
    if acc.data_type() != DataType::F32 || acc.dimensions() != Dimensions::Vec3 {
        return Err(format!(
            "accessor {} is {:?} {:?}, expected float VEC3",
            acc.index(),
            acc.data_type(),
            acc.dimensions()
        ));
    }
    Ok(elements(acc, buffers)?
        .map(|e| {
            let f =
                |k: usize| f32::from_le_bytes([e[4 * k], e[4 * k + 1], e[4 * k + 2], e[4 * k + 3]]);
            [f(0), f(1), f(2)]
        })
        .collect())
}

fn read_indices(acc: &gltf::Accessor, buffers: &[Vec<u8>]) -> Result<Vec<u32>, String> {
    if acc.dimensions() != Dimensions::Scalar {
        return Err(format!("accessor {} is not SCALAR", acc.index()));
    }
    let it = elements(acc, buffers)?;
    Ok(match acc.data_type() {
        DataType::U8 => it.map(|e| u32::from(e[0])).collect(),
        DataType::U16 => it
            .map(|e| u32::from(u16::from_le_bytes([e[0], e[1]])))
            .collect(),
        DataType::U32 => it
            .map(|e| u32::from_le_bytes([e[0], e[1], e[2], e[3]]))
            .collect(),
        t => {
            return Err(format!(
                "accessor {}: index type {t:?} is not unsigned",
                acc.index()
            ));
        }
    })
}
