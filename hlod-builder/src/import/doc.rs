//! The part of a glTF 2.0 document the importer reads, as permissive serde
//! types, and the GLB container.
//!
//! The `gltf` crate's own JSON model (gltf-json 1.4) refuses valid files: a
//! scene without `nodes`, a POSITION accessor without `min`/`max`, and every
//! extension it does not know when listed as required; and it has no types
//! for `EXT_mesh_gpu_instancing` or `EXT_meshopt_compression`. So the
//! document is read into these types, which default every optional property
//! and ignore what the importer does not use; the GLB container is split by
//! the `gltf` crate.

use std::collections::BTreeMap;

use serde::Deserialize;
use serde_json::Value;

/// Extensions the importer reads or may safely ignore when a file requires
/// them (a texture format when textures are not used, lights, material
/// models of which only the base colour is taken).
const SUPPORTED: &[&str] = &[
    "KHR_mesh_quantization",
    "KHR_draco_mesh_compression",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
    "EXT_mesh_gpu_instancing",
    "KHR_texture_transform",
    "KHR_texture_basisu",
    "EXT_texture_webp",
    "EXT_texture_avif",
    "MSFT_texture_dds",
    "KHR_lights_punctual",
    "KHR_xmp_json_ld",
    "EXT_lights_image_based",
    "CESIUM_primitive_outline",
    "EXT_mesh_features",
    "EXT_structural_metadata",
];

/// Whether a required extension can be honoured: the supported list and
/// every `KHR_materials_*` (the base colour of each is what is drawn).
pub fn supported(ext: &str) -> bool {
    SUPPORTED.contains(&ext) || ext.starts_with("KHR_materials_")
}

/// Only `extensionsRequired`, read before anything else so that a file this
/// importer cannot decode gets that one message first.
#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
pub struct Required {
    pub extensions_required: Vec<String>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
pub struct Doc {
    pub asset: Asset,
    pub extensions_used: Vec<String>,
    pub extensions_required: Vec<String>,
    pub accessors: Vec<Accessor>,
    pub buffer_views: Vec<BufferView>,
    pub buffers: Vec<Buffer>,
    pub meshes: Vec<Mesh>,
    pub nodes: Vec<Node>,
    pub scenes: Vec<Scene>,
    pub scene: Option<usize>,
    pub materials: Vec<Material>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(default)]
pub struct Asset {
    pub version: String,
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
pub struct Accessor {
    pub buffer_view: Option<usize>,
    pub byte_offset: u64,
    pub component_type: u32,
    pub normalized: bool,
    pub count: u64,
    #[serde(rename = "type")]
    pub kind: String,
    pub sparse: Option<Box<Sparse>>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
pub struct Sparse {
    pub count: u64,
    pub indices: SparseIndices,
    pub values: SparseValues,
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
pub struct SparseIndices {
    pub buffer_view: usize,
    pub byte_offset: u64,
    pub component_type: u32,
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
pub struct SparseValues {
    pub buffer_view: usize,
    pub byte_offset: u64,
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
pub struct BufferView {
    pub buffer: usize,
    pub byte_offset: u64,
    pub byte_length: u64,
    pub byte_stride: Option<u64>,
    pub extensions: ViewExtensions,
}

#[derive(Debug, Default, Deserialize)]
#[serde(default)]
pub struct ViewExtensions {
    // Boxed: most views have neither, and a large scene has millions.
    #[serde(rename = "EXT_meshopt_compression")]
    pub ext_meshopt: Option<Box<Meshopt>>,
    #[serde(rename = "KHR_meshopt_compression")]
    pub khr_meshopt: Option<Box<Meshopt>>,
}

impl ViewExtensions {
    /// The meshopt-compressed source of the view, if any.
    pub fn meshopt(&self) -> Option<&Meshopt> {
        self.khr_meshopt.as_deref().or(self.ext_meshopt.as_deref())
    }
}

/// `EXT_meshopt_compression` on a buffer view.
#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
pub struct Meshopt {
    pub buffer: usize,
    pub byte_offset: u64,
    pub byte_length: u64,
    pub byte_stride: u64,
    pub count: u64,
    pub mode: String,
    pub filter: Option<String>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
pub struct Buffer {
    pub uri: Option<String>,
    pub byte_length: u64,
    pub extensions: BufferExtensions,
}

#[derive(Debug, Default, Deserialize)]
#[serde(default)]
pub struct BufferExtensions {
    #[serde(rename = "EXT_meshopt_compression")]
    pub ext_meshopt: Option<Fallback>,
    #[serde(rename = "KHR_meshopt_compression")]
    pub khr_meshopt: Option<Fallback>,
}

impl Buffer {
    /// A placeholder for meshopt-compressed views (no data needed when
    /// every view on it is decoded from elsewhere).
    pub fn is_fallback(&self) -> bool {
        let e = &self.extensions;
        e.ext_meshopt
            .iter()
            .chain(&e.khr_meshopt)
            .any(|f| f.fallback)
    }
}

#[derive(Debug, Default, Deserialize)]
#[serde(default)]
pub struct Fallback {
    pub fallback: bool,
}

#[derive(Debug, Default, Deserialize)]
#[serde(default)]
pub struct Mesh {
    pub name: Option<String>,
    pub primitives: Vec<Primitive>,
    pub extras: Option<Value>,
}

#[derive(Debug, Deserialize)]
#[serde(default)]
pub struct Primitive {
    pub attributes: BTreeMap<String, usize>,
    pub indices: Option<usize>,
    pub material: Option<usize>,
    pub mode: u32,
    pub extensions: BTreeMap<String, Value>,
}

impl Default for Primitive {
    fn default() -> Self {
        Self {
            attributes: BTreeMap::new(),
            indices: None,
            material: None,
            mode: 4,
            extensions: BTreeMap::new(),
        }
    }
}

#[derive(Debug, Default, Deserialize)]
#[serde(default)]
pub struct Node {
    pub name: Option<String>,
    pub mesh: Option<usize>,
    pub children: Vec<usize>,
    pub matrix: Option<[f64; 16]>,
    pub translation: Option<[f64; 3]>,
    pub rotation: Option<[f64; 4]>,
    pub scale: Option<[f64; 3]>,
    pub extras: Option<Value>,
    pub extensions: NodeExtensions,
}

#[derive(Debug, Default, Deserialize)]
#[serde(default)]
pub struct NodeExtensions {
    #[serde(rename = "EXT_mesh_gpu_instancing")]
    pub instancing: Option<Instancing>,
}

/// `EXT_mesh_gpu_instancing`: per-instance TRS accessors.
#[derive(Debug, Default, Deserialize)]
#[serde(default)]
pub struct Instancing {
    pub attributes: BTreeMap<String, usize>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(default)]
pub struct Scene {
    pub nodes: Vec<usize>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
pub struct Material {
    pub pbr_metallic_roughness: Option<PbrMetallicRoughness>,
    pub extensions: MaterialExtensions,
    /// `OPAQUE` (the default), `MASK` or `BLEND`.
    pub alpha_mode: Option<String>,
    pub alpha_cutoff: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
pub struct PbrMetallicRoughness {
    pub base_color_factor: Option<[f64; 4]>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(default)]
pub struct MaterialExtensions {
    #[serde(rename = "KHR_materials_pbrSpecularGlossiness")]
    pub spec_gloss: Option<SpecGloss>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "camelCase", default)]
pub struct SpecGloss {
    pub diffuse_factor: Option<[f64; 4]>,
}

impl Material {
    /// The alpha a surface of this material is drawn with, from the
    /// alpha of its colour (`a`, in [0, 1]): as it is under `BLEND`, 0 or 1
    /// by the cutoff (0.5 unless given) under `MASK`, and 1 under `OPAQUE`
    /// (glTF ignores the alpha then).
    pub fn alpha(&self, a: f64) -> f64 {
        match self.alpha_mode.as_deref() {
            Some("BLEND") => a,
            Some("MASK") => {
                if a >= self.alpha_cutoff.unwrap_or(0.5) {
                    1.0
                } else {
                    0.0
                }
            }
            _ => 1.0,
        }
    }

    /// The colour a flat-shaded viewer draws: the specular-glossiness
    /// diffuse factor where that model is given (its `pbrMetallicRoughness`
    /// is then a fallback), else the base colour factor; unlit and the
    /// other `KHR_materials_*` extensions keep the base colour.
    pub fn base_color(&self) -> [f64; 4] {
        self.extensions
            .spec_gloss
            .as_ref()
            .and_then(|s| s.diffuse_factor)
            .or_else(|| {
                self.pbr_metallic_roughness
                    .as_ref()
                    .and_then(|p| p.base_color_factor)
            })
            .unwrap_or([1.0; 4])
    }
}

/// The JSON and the binary chunk of a `.glb`, or the whole of a `.gltf`.
pub fn split(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), String> {
    if bytes.get(..4) != Some(b"glTF") {
        return Ok((bytes, None));
    }
    // gltf 1.4.1 subtracts the header's size from the length field
    // unchecked (a panic with overflow checks, found by fuzzing).
    if let Some(h) = bytes.get(..12) {
        let len = u32::from_le_bytes([h[8], h[9], h[10], h[11]]);
        if len < 12 {
            return Err(format!(
                "GLB header: length {len} is shorter than the 12-byte header"
            ));
        }
    }
    let glb = gltf::binary::Glb::from_slice(bytes).map_err(|e| format!("GLB container: {e}"))?;
    let json: &[u8] = match glb.json {
        std::borrow::Cow::Borrowed(j) => j,
        std::borrow::Cow::Owned(_) => return Err("GLB container: JSON chunk not in place".into()),
    };
    let bin = match glb.bin {
        Some(std::borrow::Cow::Borrowed(b)) => Some(b),
        Some(std::borrow::Cow::Owned(_)) => {
            return Err("GLB container: BIN chunk not in place".into());
        }
        None => None,
    };
    Ok((json, bin))
}

/// Parses the document: `extensionsRequired` first, then the rest, with the
/// JSON path of a malformed property in the message.
pub fn parse(json: &[u8]) -> Result<Doc, String> {
    let json = json.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(json);
    let required: Required = serde_json::from_slice(json).map_err(|e| format!("JSON: {e}"))?;
    for ext in &required.extensions_required {
        if !supported(ext) {
            return Err(format!(
                "requires the extension {ext}, which this importer does not support: re-export \
                 the model without this extension"
            ));
        }
    }
    let de = &mut serde_json::Deserializer::from_slice(json);
    let doc: Doc = serde_path_to_error::deserialize(de).map_err(|e| {
        let at = e.path().to_string();
        format!("{at}: {}", e.into_inner())
    })?;
    if !doc.asset.version.is_empty() && !doc.asset.version.starts_with("2.") {
        return Err(format!(
            "asset.version is {:?}: only glTF 2.x is read",
            doc.asset.version
        ));
    }
    Ok(doc)
}

/// Only the images' `uri`s (what a model names besides its buffers; the
/// importer does not read images, but no output may replace one).
#[derive(Debug, Default, Deserialize)]
#[serde(default)]
struct Images {
    images: Vec<ImageUri>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(default)]
struct ImageUri {
    uri: Option<String>,
}

/// The `uri`s of a document's images (none where it does not parse).
pub fn parse_images(json: &[u8]) -> Result<Vec<String>, String> {
    let json = json.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(json);
    let i: Images = serde_json::from_slice(json).map_err(|e| format!("JSON: {e}"))?;
    Ok(i.images.into_iter().filter_map(|i| i.uri).collect())
}
