//! One tile's content: a rep as a binary glTF 2.0 (`.glb`).
//!
//! - Positions keep the rep's 16-bit quantisation as they are
//!   (`KHR_mesh_quantization`, unnormalised `u16`), dequantised by the
//!   node's translation (`quant_min`) and scale (`quant_scale`).
//! - Normals are `i8` snorm. A node scale that differs per axis turns a
//!   normal by its inverse (the renderer's normal matrix), so each normal is
//!   stored multiplied by the scale first, and comes out as it was.
//! - Colours are RGBA8, as in the rep.
//! - The vertex, index and feature-ID streams go through meshoptimizer's
//!   codecs (`EXT_meshopt_compression`: vertex codec version 0, index codec
//!   version 1), with a fallback buffer that holds no bytes.
//! - Element identity: a `_FEATURE_ID_0` attribute (`EXT_mesh_features`) into
//!   a property table (`EXT_structural_metadata`) of the elements the tile
//!   holds.

use std::collections::HashMap;

use engine::format::{PackedVertex, RepMesh};
use serde_json::{Value, json};

/// One element of a tile's property table.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Element {
    /// The scene's object index.
    pub object: u32,
    pub name: String,
    pub mesh_name: String,
    pub ifc_type: String,
    pub global_id: String,
    /// The object's whole description, as the scene file holds it (JSON).
    pub info: String,
}

/// Which element each triangle of a rep belongs to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Features {
    /// Per triangle, an index into `elements`, or `elements.len()` for a
    /// triangle of no element (written as the `nullFeatureId`).
    pub triangle: Vec<u32>,
    /// Every element appears in `triangle`.
    pub elements: Vec<Element>,
}

/// One string property of an element: its name and how to read it.
type StringProperty = (&'static str, fn(&Element) -> &str);

/// The string properties of the element class, in table order.
const STRINGS: [StringProperty; 5] = [
    ("name", |e| &e.name),
    ("mesh_name", |e| &e.mesh_name),
    ("ifc_type", |e| &e.ifc_type),
    ("global_id", |e| &e.global_id),
    ("info", |e| &e.info),
];

/// A glTF's buffer data and views, built up as streams are added.
#[derive(Default)]
struct Bin {
    bytes: Vec<u8>,
    /// Uncompressed bytes the fallback buffer stands for.
    fallback_len: usize,
    views: Vec<Value>,
}

impl Bin {
    fn align(&mut self) {
        while !self.bytes.len().is_multiple_of(8) {
            self.bytes.push(0);
        }
    }

    /// A plain view of `data` in buffer 0.
    fn plain(&mut self, data: &[u8]) -> usize {
        self.align();
        self.views.push(json!({
            "buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len(),
        }));
        self.bytes.extend_from_slice(data);
        self.views.len() - 1
    }

    /// A compressed view: `data` (already encoded) in buffer 0, standing for
    /// `count` elements of `stride` bytes in the fallback buffer.
    fn compressed(&mut self, data: &[u8], count: usize, stride: usize, mode: &str) -> usize {
        self.align();
        while !self.fallback_len.is_multiple_of(8) {
            self.fallback_len += 1;
        }
        let target = if mode == "TRIANGLES" { 34963 } else { 34962 };
        let mut view = json!({
            "buffer": 1, "byteOffset": self.fallback_len, "byteLength": count * stride,
            "target": target,
            "extensions": {"EXT_meshopt_compression": {
                "buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len(),
                "byteStride": stride, "count": count, "mode": mode,
            }},
        });
        if mode == "ATTRIBUTES" {
            view["byteStride"] = json!(stride);
        }
        self.views.push(view);
        self.bytes.extend_from_slice(data);
        self.fallback_len += count * stride;
        self.views.len() - 1
    }
}

/// The node scale that dequantises positions: the rep's `quant_scale`, with
/// a flat axis (all positions 0 on it) given the largest axis' scale, so
/// that the matrix stays invertible.
pub fn node_scale(mesh: &RepMesh) -> [f32; 3] {
    let s = mesh.quant_scale;
    let big = s.iter().copied().fold(0f32, f32::max);
    let fill = if big > 0.0 { big } else { 1.0 };
    s.map(|v| if v > 0.0 { v } else { fill })
}

/// Vertices and indices as the glTF stores them: normals pre-multiplied by
/// the node scale; with features, vertices shared by triangles of two
/// elements split, and each vertex's feature index.
fn vertices(
    mesh: &RepMesh,
    features: Option<&Features>,
) -> (Vec<PackedVertex>, Vec<u32>, Vec<f32>) {
    let s = node_scale(mesh);
    let fix = |v: &PackedVertex| {
        let n = [0, 1, 2].map(|a| f32::from(v.normal[a]) / 127.0 * s[a]);
        PackedVertex {
            position: v.position,
            normal: engine::format::quantize_unit_normal(n),
            color: v.color,
        }
    };
    let Some(f) = features else {
        return (
            mesh.vertices.iter().map(fix).collect(),
            mesh.indices.clone(),
            Vec::new(),
        );
    };
    let mut map: HashMap<(u32, u32), u32> = HashMap::new();
    let (mut verts, mut ids) = (Vec::new(), Vec::new());
    let mut indices = Vec::with_capacity(mesh.indices.len());
    for (t, tri) in mesh.indices.chunks_exact(3).enumerate() {
        let feature = f.triangle[t];
        for &i in tri {
            let k = *map.entry((i, feature)).or_insert_with(|| {
                verts.push(fix(&mesh.vertices[i as usize]));
                ids.push(feature as f32);
                (verts.len() - 1) as u32
            });
            indices.push(k);
        }
    }
    (verts, indices, ids)
}

/// The string property's values and offsets (UINT32), as bytes.
fn string_column<'a>(rows: impl Iterator<Item = &'a str>) -> (Vec<u8>, Vec<u8>) {
    let (mut values, mut offsets) = (Vec::new(), vec![0u8; 4]);
    for r in rows {
        values.extend_from_slice(r.as_bytes());
        offsets.extend_from_slice(&(values.len() as u32).to_le_bytes());
    }
    (values, offsets)
}

/// The `EXT_structural_metadata` extension of a tile with these elements.
fn metadata(bin: &mut Bin, elements: &[Element]) -> Value {
    let objects: Vec<u8> = elements
        .iter()
        .flat_map(|e| e.object.to_le_bytes())
        .collect();
    let mut props = serde_json::Map::new();
    props.insert("object".into(), json!({"values": bin.plain(&objects)}));
    for (name, field) in STRINGS {
        let (values, offsets) = string_column(elements.iter().map(field));
        if values.is_empty() {
            // No element has it: left out (a zero-length view is invalid).
            continue;
        }
        let v = bin.plain(&values);
        let o = bin.plain(&offsets);
        props.insert(
            (*name).into(),
            json!({"values": v, "stringOffsets": o, "stringOffsetType": "UINT32"}),
        );
    }
    let mut class_props = serde_json::Map::new();
    class_props.insert(
        "object".into(),
        json!({"type": "SCALAR", "componentType": "UINT32",
               "description": "index of the object in the scene file"}),
    );
    for (name, _) in STRINGS {
        class_props.insert(name.into(), json!({"type": "STRING"}));
    }
    json!({
        "schema": {"id": "hlod", "classes": {"element": {
            "name": "Element",
            "description": "a source object (glTF node or IFC product) of the scene",
            "properties": class_props,
        }}},
        "propertyTables": [{
            "name": "elements", "class": "element", "count": elements.len(),
            "properties": props,
        }],
    })
}

/// Encodes `mesh` (at least one triangle) as a GLB, with its elements when
/// `features` is given.
pub fn encode(mesh: &RepMesh, features: Option<&Features>) -> Vec<u8> {
    let (verts, indices, ids) = vertices(mesh, features);
    let vc = verts.len();
    let mut bin = Bin::default();
    let vs = meshopt::encode_vertex_buffer_level(&verts, 2, Some(0))
        .expect("meshopt's vertex encoder sizes its own output");
    let vertex_view = bin.compressed(&vs, vc, 16, "ATTRIBUTES");
    let is = meshopt::encode_index_buffer(&indices, vc)
        .expect("indices are in range, a multiple of three");
    let index_size = if vc <= 1 << 16 { 2 } else { 4 };
    let index_view = bin.compressed(&is, indices.len(), index_size, "TRIANGLES");
    let (mut lo, mut hi) = ([u16::MAX; 3], [0u16; 3]);
    for v in &verts {
        for a in 0..3 {
            lo[a] = lo[a].min(v.position[a]);
            hi[a] = hi[a].max(v.position[a]);
        }
    }
    let mut accessors = vec![
        json!({"bufferView": vertex_view, "byteOffset": 0, "componentType": 5123,
               "count": vc, "type": "VEC3", "min": lo, "max": hi}),
        json!({"bufferView": vertex_view, "byteOffset": 8, "componentType": 5120,
               "normalized": true, "count": vc, "type": "VEC3"}),
        json!({"bufferView": vertex_view, "byteOffset": 12, "componentType": 5121,
               "normalized": true, "count": vc, "type": "VEC4"}),
        json!({"bufferView": index_view, "componentType": if index_size == 2 { 5123 } else { 5125 },
               "count": indices.len(), "type": "SCALAR"}),
    ];
    let mut attributes = json!({"POSITION": 0, "NORMAL": 1, "COLOR_0": 2});
    let mut primitive = json!({"indices": 3, "material": 0, "mode": 4});
    let mut used = vec!["EXT_meshopt_compression", "KHR_mesh_quantization"];
    let mut root_ext = serde_json::Map::new();
    if let Some(f) = features {
        let fs = meshopt::encode_vertex_buffer_level(&ids, 2, Some(0))
            .expect("meshopt's vertex encoder sizes its own output");
        let feature_view = bin.compressed(&fs, vc, 4, "ATTRIBUTES");
        accessors.push(json!({"bufferView": feature_view, "componentType": 5126,
                              "count": vc, "type": "SCALAR"}));
        attributes["_FEATURE_ID_0"] = json!(4);
        let mut id = json!({
            "featureCount": f.elements.len(), "attribute": 0, "propertyTable": 0,
        });
        // A merged tile's triangles of reps without elements (HLODs).
        if f.triangle.iter().any(|&k| k as usize >= f.elements.len()) {
            id["nullFeatureId"] = json!(f.elements.len());
        }
        primitive["extensions"] = json!({"EXT_mesh_features": {"featureIds": [id]}});
        root_ext.insert(
            "EXT_structural_metadata".into(),
            metadata(&mut bin, &f.elements),
        );
        used.extend(["EXT_mesh_features", "EXT_structural_metadata"]);
    }
    primitive["attributes"] = attributes;
    let s = node_scale(mesh);
    // A shared payload (format version 6) is placed by its rep's transform:
    // the node's matrix is that transform after the dequantisation.
    let node = match &mesh.placement {
        None => json!({"mesh": 0, "translation": mesh.quant_min, "scale": s}),
        Some(p) => {
            let m = &p.transform;
            let q = mesh.quant_min;
            // Column-major: the linear part's columns scaled by s, then the
            // translation M · quant_min + t.
            let mut cols = Vec::with_capacity(16);
            for (j, sj) in s.iter().enumerate() {
                cols.extend([m[0][j] * sj, m[1][j] * sj, m[2][j] * sj, 0.0]);
            }
            let t = p.point(q);
            cols.extend([t[0], t[1], t[2], 1.0]);
            json!({"mesh": 0, "matrix": cols})
        }
    };
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": "hlod-build export-3dtiles"},
        "extensionsUsed": used,
        "extensionsRequired": ["EXT_meshopt_compression", "KHR_mesh_quantization"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [node],
        "meshes": [{"primitives": [primitive]}],
        "materials": [{"pbrMetallicRoughness": {
            "baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0,
            "roughnessFactor": 1.0,
        }, "doubleSided": true}],
        "accessors": accessors,
        "bufferViews": bin.views,
        "buffers": [
            {"byteLength": bin.bytes.len()},
            {"byteLength": bin.fallback_len,
             "extensions": {"EXT_meshopt_compression": {"fallback": true}}},
        ],
    });
    if !root_ext.is_empty() {
        doc["extensions"] = Value::Object(root_ext);
    }
    glb(&doc, bin.bytes)
}

/// The GLB container: header, JSON chunk (space-padded), BIN chunk.
fn glb(doc: &Value, mut bin: Vec<u8>) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).expect("a JSON value serialises");
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}
