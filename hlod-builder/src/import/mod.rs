//! Model import: glTF 2.0 (`.gltf` + external or embedded buffers, `.glb`),
//! and PLY, OBJ and STL ([`meshfile`], by the file's extension).
//!
//! - [`doc`]: the document as permissive serde types; a required extension
//!   that cannot be honoured (Draco) is refused before anything else.
//! - [`access`]: bounds-checked accessors of every component type,
//!   normalized (`KHR_mesh_quantization`), sparse, and meshopt-decoded
//!   buffer views ([`meshopt_view`], `EXT_meshopt_compression`).
//! - [`prims`]: primitives merged into one mesh per glTF mesh, with base
//!   colours from `pbrMetallicRoughness` or `KHR_materials_pbrSpecularGlossiness`.
//! - [`nodes`]: the hierarchy in `f64`, `EXT_mesh_gpu_instancing` (each
//!   instance an object), cycles, overflowing transforms.
//!
//! Transforms are composed in `f64` and stored relative to an origin
//! ([`Imported::origin`], kept in the scene file's header), so a model at
//! survey coordinates keeps millimetres. Structural corruption is an error
//! naming the glTF part; a part that cannot be drawn is skipped with a
//! warning, and every warning is kept for the caller to print.

mod access;
mod doc;
mod draco;
mod draco_ffi;
mod files;
mod ifc;
mod lazy;
mod meshfile;
mod meshopt_view;
mod nodes;
mod obj;
mod ply;
mod prims;
mod stl;

use std::path::{Path, PathBuf};

use base64::Engine as _;
use glam::{DMat4, DVec3, Mat4};
use serde_json::Value;

use crate::mesh::{Aabb, Mesh};

use files::resolve_uri;
pub use files::{allow_dir, external_buffers, external_files, json_part, model_files, read_files};
pub use lazy::{Opened, open};
pub use meshfile::{Format, parse_bytes as parse_mesh_bytes};

/// Why a glTF file could not be imported.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not a valid glTF 2.0 file: {what}")]
    Parse { path: PathBuf, what: String },
    #[error("{path}: {what}")]
    Unsupported { path: PathBuf, what: String },
    #[error("{path}: {what}")]
    Invalid { path: PathBuf, what: String },
    #[error("{path}: the scene has no renderable triangles: {why}")]
    NoTriangles { path: PathBuf, why: String },
}

impl ImportError {
    /// The same error, naming `path` (an IFC file for its converted GLB).
    pub fn naming(self, path: &Path) -> Self {
        let path = path.to_path_buf();
        match self {
            ImportError::Read { source, .. } => ImportError::Read { path, source },
            ImportError::Parse { what, .. } => ImportError::Parse { path, what },
            ImportError::Unsupported { what, .. } => ImportError::Unsupported { path, what },
            ImportError::Invalid { what, .. } => ImportError::Invalid { path, what },
            ImportError::NoTriangles { why, .. } => ImportError::NoTriangles { path, why },
        }
    }
}

/// Whether an object, by the IFC class its name starts with (as IFC
/// exporters name nodes), stands for no visible part: an opening's void
/// (`IfcOpeningElement`, written as a solid box in every door and window
/// hole by some exporters) or a room's volume (`IfcSpace`, a translucent
/// box filling the room). Viewers of BIM hide both.
pub fn ifc_void(name: &str) -> bool {
    engine::interior::ifc_class_in(name, &["IfcOpeningElement", "IfcSpace"])
}

/// One placement of a mesh: an *object*.
#[derive(Clone, Debug)]
pub struct Instance {
    pub mesh: usize,
    /// Local-to-scene transform: world relative to [`Imported::origin`].
    pub transform: Mat4,
    pub name: String,
    /// The glTF node that places it (`None` when the file has no nodes).
    pub node: Option<usize>,
    /// Its index among the node's `EXT_mesh_gpu_instancing` instances.
    pub instance: Option<u32>,
    /// The glTF nodes above `node`, outermost first (the model tree's
    /// groups where the file carries no IFC structure).
    pub parents: std::sync::Arc<[usize]>,
}

/// The imported scene: meshes in their local space and their placements.
#[derive(Debug, Default)]
pub struct Imported {
    /// One entry per glTF mesh; `None` when it has no usable triangles.
    /// Empty for a scene [`open`]ed lazily ([`Opened::mesh`] reads them).
    pub meshes: Vec<Option<Mesh>>,
    /// Size and box of each usable mesh (`None` as in `meshes`).
    pub meta: Vec<Option<MeshMeta>>,
    pub instances: Vec<Instance>,
    /// Triangles of each mesh as read, before degenerate ones were dropped.
    pub source_tris: Vec<u64>,
    /// Parts skipped, with the reason.
    pub warnings: Vec<String>,
    /// World position of the scene's coordinate origin.
    pub origin: [f64; 3],
    /// Name and `extras` of each glTF mesh, and `extras` of each node (its
    /// name is its instances').
    pub mesh_info: Vec<(Option<String>, Option<Value>)>,
    pub node_extras: Vec<Option<Value>>,
    /// Each glTF node's name.
    pub node_names: Vec<Option<String>>,
    /// What a build of it records as its source ([`crate::cache::key`];
    /// zero unless the builder sets it).
    pub source_key: [u8; 16],
}

/// What is known of a usable mesh without its geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshMeta {
    pub tris: usize,
    pub vertices: usize,
    /// Box of its referenced vertices, in its local space.
    pub bounds: Aabb,
    /// What [`prims::recentre`] took off the file's positions (its
    /// placements add it back): zero for most meshes.
    pub offset: [f32; 3],
}

impl MeshMeta {
    pub fn of(m: &Mesh) -> Self {
        Self {
            tris: m.tri_count(),
            vertices: m.vertex_count(),
            bounds: m.bounds(),
            offset: [0.0; 3],
        }
    }
}

impl Imported {
    /// Usable triangles after instancing (degenerate ones dropped).
    pub fn instanced_triangles(&self) -> u64 {
        self.instances
            .iter()
            .filter_map(|i| self.meta[i.mesh].as_ref())
            .map(|m| m.tris as u64)
            .sum()
    }

    /// Source triangles after instancing, as the file has them.
    pub fn instanced_source_triangles(&self) -> u64 {
        self.instances
            .iter()
            .map(|i| self.source_tris[i.mesh])
            .sum()
    }

    /// What the viewer shows for object `k`: its names, `extras` and glTF
    /// indices, as one JSON object.
    pub fn object_info(&self, k: usize) -> Value {
        let inst = &self.instances[k];
        let mut o = serde_json::Map::new();
        o.insert("name".into(), inst.name.clone().into());
        if let Some(n) = inst.node {
            o.insert("node".into(), n.into());
            if let Some(Some(x)) = self.node_extras.get(n) {
                o.insert("extras".into(), x.clone());
            }
        }
        if let Some(k) = inst.instance {
            o.insert("instance".into(), k.into());
        }
        if !inst.parents.is_empty() {
            let names: Vec<Value> = (inst.parents.iter())
                .map(|&p| match self.node_names.get(p) {
                    Some(Some(n)) => n.clone().into(),
                    _ => format!("nodes[{p}]").into(),
                })
                .collect();
            o.insert("parents".into(), names.into());
        }
        o.insert("mesh".into(), inst.mesh.into());
        if let Some((name, extras)) = self.mesh_info.get(inst.mesh) {
            if let Some(n) = name {
                o.insert("mesh_name".into(), n.clone().into());
            }
            if let Some(x) = extras {
                o.insert("mesh_extras".into(), x.clone());
            }
        }
        Value::Object(o)
    }
}

/// The largest glTF/GLB file (or external buffer) read: half the machine's
/// memory (the build needs several times its input besides).
pub fn max_input_bytes() -> u64 {
    engine::limits::memory_total() / 2
}

/// Scenes whose coordinates all lie within this keep the world origin (f32
/// then holds them to better than 0.25 mm); others get their box centre.
pub const ORIGIN_FREE_EXTENT: f64 = 4096.0;

/// Loads `path` with its geometry in memory. It is [`open`]ed first, so
/// only the byte ranges its accessors use are read from its buffers (a
/// model whose `.bin` is mostly unused costs what it uses, not the file).
pub fn load(path: &Path) -> Result<Imported, ImportError> {
    let opened = open(path)?;
    let meshes = (0..opened.scene.meta.len())
        .map(|m| opened.mesh(m))
        .collect::<Result<Vec<_>, _>>()?;
    let mut scene = opened.into_scene();
    scene.meshes = meshes;
    Ok(scene)
}

/// Loads glTF or GLB bytes; external buffers are resolved against `base_dir`,
/// errors name `path`.
pub fn load_slice(bytes: &[u8], base_dir: &Path, path: &Path) -> Result<Imported, ImportError> {
    let (json, bin) = doc::split(bytes).map_err(|what| ImportError::Parse {
        path: path.to_path_buf(),
        what,
    })?;
    let doc = parse_doc(json, path)?;
    let data: Vec<access::BufData> = load_buffers(&doc, bin, base_dir)
        .map_err(|what| ImportError::Invalid {
            path: path.to_path_buf(),
            what,
        })?
        .into_iter()
        .map(access::BufData::Mem)
        .collect();
    let decoded = access::Decoded::new(u64::MAX);
    assemble(
        &doc,
        &access::Buffers::new(&doc, &data, &decoded),
        path,
        true,
    )
}

/// The document, a required extension it cannot honour refused first.
fn parse_doc(json: &[u8], path: &Path) -> Result<doc::Doc, ImportError> {
    doc::parse(json).map_err(|what| {
        if what.starts_with("requires the extension") {
            ImportError::Unsupported {
                path: path.to_path_buf(),
                what,
            }
        } else {
            ImportError::Parse {
                path: path.to_path_buf(),
                what,
            }
        }
    })
}

/// Reads every mesh (kept when `keep`, else only its [`MeshMeta`]) and
/// places them.
fn assemble(
    doc: &doc::Doc,
    bufs: &access::Buffers<'_>,
    path: &Path,
    keep: bool,
) -> Result<Imported, ImportError> {
    let invalid = |what: String| ImportError::Invalid {
        path: path.to_path_buf(),
        what,
    };
    let mut out = Imported {
        mesh_info: doc
            .meshes
            .iter()
            .map(|m| (m.name.clone(), m.extras.clone()))
            .collect(),
        node_extras: doc.nodes.iter().map(|n| n.extras.clone()).collect(),
        node_names: doc.nodes.iter().map(|n| n.name.clone()).collect(),
        ..Imported::default()
    };
    for m in 0..doc.meshes.len() {
        let (mesh, source, offset) =
            prims::read_mesh(bufs, m, &mut out.warnings).map_err(&invalid)?;
        out.meta.push(mesh.as_ref().map(|mesh| MeshMeta {
            offset,
            ..MeshMeta::of(mesh)
        }));
        if keep {
            out.meshes.push(mesh);
        }
        out.source_tris.push(source);
    }
    // Placed as the file places them (boxes where the file has them), then
    // each placement moved by its mesh's offset, composed in f64.
    let boxes: Vec<Option<Aabb>> = out
        .meta
        .iter()
        .map(|m| {
            m.map(|m| {
                let o = glam::Vec3::from(m.offset);
                Aabb {
                    min: m.bounds.min + o,
                    max: m.bounds.max + o,
                }
            })
        })
        .collect();
    let mut placed = nodes::place(doc, bufs, &boxes, &mut out.warnings).map_err(&invalid)?;
    let boxes: Vec<Option<Aabb>> = out.meta.iter().map(|m| m.map(|m| m.bounds)).collect();
    for p in &mut placed {
        if let Some(meta) = &out.meta[p.mesh] {
            p.world *= DMat4::from_translation(glam::Vec3::from(meta.offset).as_dvec3());
        }
    }
    if placed.is_empty() {
        return Err(ImportError::NoTriangles {
            path: path.to_path_buf(),
            why: no_triangles_why(doc, &out.warnings),
        });
    }
    out.origin = choose_origin(&placed, &boxes);
    let to_scene = DMat4::from_translation(-DVec3::from(out.origin));
    out.instances = placed
        .into_iter()
        .map(|p| {
            let base = p
                .node
                .and_then(|n| doc.nodes[n].name.clone())
                .unwrap_or_else(|| match p.node {
                    Some(n) => format!("nodes[{n}]"),
                    None => format!("meshes[{}]", p.mesh),
                });
            Instance {
                mesh: p.mesh,
                transform: (to_scene * p.world).as_mat4(),
                name: match p.instance {
                    Some(k) => format!("{base} #{k}"),
                    None => base,
                },
                node: p.node,
                instance: p.instance,
                parents: p.parents,
            }
        })
        .collect();
    Ok(out)
}

/// Zero when every placed box lies within [`ORIGIN_FREE_EXTENT`], else the
/// world box's centre rounded to whole units (deterministic, readable).
fn choose_origin(placed: &[nodes::Placement], boxes: &[Option<Aabb>]) -> [f64; 3] {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in placed {
        let Some(b) = &boxes[p.mesh] else { continue };
        for c in b.corners() {
            let w = p.world.transform_point3(c.as_dvec3());
            lo = lo.min(w);
            hi = hi.max(w);
        }
    }
    if lo.abs().max(hi.abs()).max_element() <= ORIGIN_FREE_EXTENT {
        return [0.0; 3];
    }
    ((lo + hi) * 0.5).round().to_array()
}

/// Why nothing could be placed, from the warnings and the document.
fn no_triangles_why(doc: &doc::Doc, warnings: &[String]) -> String {
    if doc.meshes.is_empty() {
        return "the file has no meshes".into();
    }
    if warnings.is_empty() {
        return "no node of the scene places a mesh".into();
    }
    let shown: Vec<&str> = warnings.iter().take(8).map(String::as_str).collect();
    let more = warnings.len().saturating_sub(shown.len());
    let tail = if more > 0 {
        format!("; and {more} more")
    } else {
        String::new()
    };
    format!("{}{tail}", shown.join("; "))
}

/// The bytes of every buffer: the GLB BIN chunk, a data URI or an external
/// file (read up to its declared length); a meshopt fallback buffer
/// without a source is empty.
pub(super) fn load_buffers(
    doc: &doc::Doc,
    bin: Option<&[u8]>,
    base_dir: &Path,
) -> Result<Vec<Vec<u8>>, String> {
    let mut out = Vec::new();
    let mut bin = bin;
    for (i, buf) in doc.buffers.iter().enumerate() {
        let data = match &buf.uri {
            None if buf.is_fallback() => Vec::new(),
            None => bin
                .take()
                .ok_or_else(|| format!("buffers[{i}] refers to a missing GLB BIN chunk"))?
                .to_vec(),
            Some(uri) => {
                if let Some(rest) = uri.strip_prefix("data:") {
                    let b64 = rest
                        .split_once(";base64,")
                        .map(|(_, d)| d)
                        .ok_or_else(|| format!("buffers[{i}]: unsupported data URI"))?;
                    base64::engine::general_purpose::STANDARD
                        .decode(b64)
                        .map_err(|e| format!("buffers[{i}]: bad base64: {e}"))?
                } else {
                    let file = resolve_uri(i, uri, base_dir)?;
                    read_buffer_file(&file, buf.byte_length)
                        .map_err(|e| format!("buffers[{i}]: cannot read {}: {e}", file.display()))?
                }
            }
        };
        check_buffer_length(i, buf, data.len() as u64)?;
        out.push(data);
    }
    Ok(out)
}

/// Buffer `i` holds at least the bytes it declares (a fallback buffer of
/// EXT_meshopt_compression may hold none).
pub(super) fn check_buffer_length(i: usize, buf: &doc::Buffer, len: u64) -> Result<(), String> {
    if len < buf.byte_length && !(buf.is_fallback() && len == 0) {
        return Err(format!(
            "buffers[{i}] has {len} bytes, declares {} (truncated file?)",
            buf.byte_length
        ));
    }
    Ok(())
}

/// The first `len` bytes of an external buffer file (what the buffer
/// declares; a longer file is fine, a shorter one an error), never more:
/// a buffer naming `/dev/zero` reads `len` bytes.
pub(super) fn read_buffer_file(file: &Path, len: u64) -> std::io::Result<Vec<u8>> {
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
    let f = engine::infile::open(file)?;
    let mut out = Vec::new();
    out.try_reserve_exact(len as usize)
        .map_err(|_| std::io::Error::from(std::io::ErrorKind::OutOfMemory))?;
    f.take(len).read_to_end(&mut out)?;
    Ok(out)
}
