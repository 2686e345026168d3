//! glTF variants for the importer's conformance test, written independently
//! of the importer: a model is read with the `gltf` crate's own validating
//! reader into a flat list of placed meshes, then written back out plain,
//! with `EXT_mesh_gpu_instancing`, `KHR_mesh_quantization`,
//! `EXT_meshopt_compression` (the `meshopt` crate's encoders and filters),
//! sparse accessors, material extensions, unusual scene structure and
//! hostile transforms. Each variant carries the triangle count an importer
//! must report, counted here.

use std::path::Path;

use glam::{DMat4, Mat4, Vec3};
use serde_json::{Value, json};

/// One triangle-list primitive.
#[derive(Clone, Debug)]
pub struct Prim {
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub indices: Vec<u32>,
}

/// A model as meshes and their world placements.
#[derive(Clone, Debug, Default)]
pub struct Flat {
    pub meshes: Vec<Vec<Prim>>,
    pub placements: Vec<(usize, Mat4)>,
}

impl Flat {
    /// Triangles after instancing: the independent count.
    pub fn triangles(&self) -> u64 {
        self.placements
            .iter()
            .map(|(m, _)| self.mesh_tris(*m))
            .sum()
    }

    pub fn mesh_tris(&self, m: usize) -> u64 {
        self.meshes[m]
            .iter()
            .map(|p| p.indices.len() as u64 / 3)
            .sum()
    }
}

/// Reads `path` (`.glb`, or `.gltf` with external buffers) with the `gltf`
/// crate: triangle-list primitives, node transforms composed from the
/// default scene.
pub fn read_flat(path: &Path) -> Flat {
    let bytes = std::fs::read(path).unwrap();
    let g = gltf::Gltf::from_slice(&bytes).unwrap();
    let mut blob = g.blob.clone();
    let buffers: Vec<Vec<u8>> = g
        .buffers()
        .map(|b| match b.source() {
            gltf::buffer::Source::Bin => blob.take().unwrap(),
            gltf::buffer::Source::Uri(u) => match u.split_once(";base64,") {
                Some((_, b64)) => {
                    use base64::Engine as _;
                    base64::engine::general_purpose::STANDARD
                        .decode(b64)
                        .unwrap()
                }
                None => std::fs::read(path.parent().unwrap().join(u)).unwrap(),
            },
        })
        .collect();
    let mut flat = Flat::default();
    for mesh in g.meshes() {
        let mut prims = Vec::new();
        for p in mesh.primitives() {
            if p.mode() != gltf::mesh::Mode::Triangles {
                continue;
            }
            let r = p.reader(|b| Some(&buffers[b.index()]));
            let positions: Vec<[f32; 3]> = r.read_positions().unwrap().collect();
            let normals = r.read_normals().map(|n| n.collect());
            let indices = match r.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..positions.len() as u32).collect(),
            };
            prims.push(Prim {
                positions,
                normals,
                indices,
            });
        }
        flat.meshes.push(prims);
    }
    let scene = g.default_scene().or_else(|| g.scenes().next()).unwrap();
    let mut stack: Vec<(gltf::Node, Mat4)> = scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
    while let Some((n, parent)) = stack.pop() {
        let world = parent * Mat4::from_cols_array_2d(&n.transform().matrix());
        if let Some(m) = n.mesh() {
            flat.placements.push((m.index(), world));
        }
        stack.extend(n.children().map(|c| (c, world)));
    }
    flat.placements.sort_by_key(|(m, _)| *m);
    flat
}

/// How a variant encodes the model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    Plain,
    /// `EXT_mesh_gpu_instancing` in `extensionsUsed` (or required).
    Instanced {
        required: bool,
    },
    /// `KHR_mesh_quantization`: u16 positions, i8 normals, u16 indices where they fit.
    Quantized,
    /// Quantized, then every view `EXT_meshopt_compression`-encoded, with a fallback buffer.
    Meshopt,
    /// Positions in a sparse accessor over a base view with wrong values.
    Sparse,
    /// Materials with `KHR_materials_pbrSpecularGlossiness`, `KHR_materials_unlit`
    /// and `KHR_texture_transform` required.
    MaterialExtensions,
    /// No `scene`, no `scenes`.
    NoScenes,
    /// A scene without `nodes`.
    EmptyScene,
    /// Every placement under a 300-deep chain of identity nodes.
    DeepChain,
    /// Everything moved to survey coordinates (5,000 km, 3,000 km).
    Survey,
    /// An extension no importer here knows is required: must be refused.
    UnknownRequired,
    /// One placement scaled by 1e30 and one NaN: those two skipped.
    HostileTransforms,
    /// A node that is its own ancestor: must be refused.
    Cycle,
}

pub const VARIANTS: &[Variant] = &[
    Variant::Plain,
    Variant::Instanced { required: false },
    Variant::Instanced { required: true },
    Variant::Quantized,
    Variant::Meshopt,
    Variant::Sparse,
    Variant::MaterialExtensions,
    Variant::NoScenes,
    Variant::EmptyScene,
    Variant::DeepChain,
    Variant::Survey,
    Variant::UnknownRequired,
    Variant::HostileTransforms,
    Variant::Cycle,
];

/// What an importer must do with a variant.
#[derive(Clone, Debug, PartialEq)]
pub enum Expect {
    /// Import with this many triangles after instancing, within this world box.
    Triangles(u64),
    /// Refuse, with a message containing this.
    Refusal(&'static str),
}

/// The GLB of `flat` written as `v`, and what an importer must report.
pub fn write(flat: &Flat, v: Variant) -> (Vec<u8>, Expect) {
    let mut w = Writer::default();
    let mut expect = Expect::Triangles(flat.triangles());
    let quant = matches!(v, Variant::Quantized | Variant::Meshopt);
    // Meshes (with their dequantisation matrix when quantised).
    let mut dequant = Vec::new();
    for prims in &flat.meshes {
        let mut ps = Vec::new();
        let mut bounds = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for p in prims {
            for q in &p.positions {
                bounds.0 = bounds.0.min(Vec3::from(*q));
                bounds.1 = bounds.1.max(Vec3::from(*q));
            }
        }
        let (lo, scale) = (
            bounds.0,
            ((bounds.1 - bounds.0) / 65535.0).max(Vec3::splat(1e-12)),
        );
        for p in prims {
            ps.push(if quant {
                w.quantized_prim(p, lo, scale, v == Variant::Meshopt)
            } else {
                w.plain_prim(p, v == Variant::Sparse)
            });
        }
        if v == Variant::MaterialExtensions {
            for p in ps.iter_mut() {
                p["material"] = json!(w.materials.len() % 2);
            }
        }
        w.meshes
            .push(json!({ "primitives": ps, "name": format!("mesh{}", w.meshes.len()) }));
        dequant.push(if quant {
            Mat4::from_translation(lo) * Mat4::from_scale(scale)
        } else {
            Mat4::IDENTITY
        });
    }
    // Nodes.
    let mut roots = Vec::new();
    match v {
        Variant::Instanced { .. } => {
            let mut m = 0;
            while m < flat.meshes.len() {
                let list: Vec<Mat4> = flat
                    .placements
                    .iter()
                    .filter(|(k, _)| *k == m)
                    .map(|(_, t)| *t)
                    .collect();
                if !list.is_empty() {
                    let (t, r, s) = w.instance_accessors(&list);
                    roots.push(w.nodes.len());
                    w.nodes
                        .push(json!({ "mesh": m, "name": format!("instances of {m}"),
                        "extensions": { "EXT_mesh_gpu_instancing": { "attributes": {
                            "TRANSLATION": t, "ROTATION": r, "SCALE": s } } } }));
                }
                m += 1;
            }
        }
        _ => {
            for (k, (m, t)) in flat.placements.iter().enumerate() {
                let mut t = *t * dequant[*m];
                let mut skipped = false;
                if v == Variant::HostileTransforms && k < 2 {
                    t = if k == 0 {
                        t * Mat4::from_scale(Vec3::splat(1e30))
                    } else {
                        Mat4::from_cols_array(&[f32::NAN; 16])
                    };
                    skipped = true;
                }
                if skipped && let Expect::Triangles(n) = &mut expect {
                    *n -= flat.mesh_tris(*m);
                }
                let mut matrix: Vec<Value> = t.to_cols_array().iter().map(|&c| json!(c)).collect();
                if v == Variant::Survey {
                    let o = DMat4::from_translation(glam::DVec3::new(5.0e6, 3.0e6, 100.0))
                        * t.as_dmat4();
                    matrix = o.to_cols_array().iter().map(|&c| json!(c)).collect();
                }
                if t.to_cols_array().iter().any(|c| !c.is_finite()) {
                    // JSON has no NaN: a matrix of strings would not parse, so
                    // a huge finite value stands for it.
                    matrix = (0..16).map(|_| json!(1e300)).collect();
                }
                roots.push(w.nodes.len());
                w.nodes.push(
                    json!({ "mesh": m, "matrix": matrix, "name": format!("part {k}"),
                    "extras": { "GlobalId": format!("id-{k}"), "type": "IfcWall" } }),
                );
            }
        }
    }
    if v == Variant::DeepChain {
        let mut top = roots.clone();
        for _ in 0..300 {
            let id = w.nodes.len();
            w.nodes.push(json!({ "children": top }));
            top = vec![id];
        }
        roots = top;
    }
    if v == Variant::Cycle {
        let a = w.nodes.len();
        w.nodes.push(json!({ "children": [a + 1] }));
        w.nodes.push(json!({ "children": [a] }));
        roots.push(a);
        expect = Expect::Refusal("cycle");
    }
    if expect == Expect::Triangles(0) {
        // Every placement was hostile: nothing renderable, and the node named.
        expect = Expect::Refusal("nodes[0]");
    }
    let mut used = Vec::new();
    let mut required = Vec::new();
    match v {
        Variant::Instanced { required: r } => {
            used.push("EXT_mesh_gpu_instancing");
            if r {
                required.push("EXT_mesh_gpu_instancing");
            }
        }
        Variant::Quantized => {
            used.push("KHR_mesh_quantization");
            required.push("KHR_mesh_quantization");
        }
        Variant::Meshopt => {
            used.extend(["KHR_mesh_quantization", "EXT_meshopt_compression"]);
            required.extend(["KHR_mesh_quantization", "EXT_meshopt_compression"]);
        }
        Variant::MaterialExtensions => {
            let e = [
                "KHR_materials_pbrSpecularGlossiness",
                "KHR_materials_unlit",
                "KHR_texture_transform",
            ];
            used.extend(e);
            required.extend(e);
            w.materials = vec![
                json!({ "extensions": { "KHR_materials_pbrSpecularGlossiness": {
                    "diffuseFactor": [0.8, 0.2, 0.1, 1.0] } } }),
                json!({ "pbrMetallicRoughness": { "baseColorFactor": [0.1, 0.5, 0.9, 1.0] },
                    "extensions": { "KHR_materials_unlit": {} } }),
            ];
        }
        Variant::UnknownRequired => {
            used.push("EXT_acme_teleport");
            required.push("EXT_acme_teleport");
            expect = Expect::Refusal("EXT_acme_teleport");
        }
        _ => {}
    }
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": "e2e-tests conformance" },
        "meshes": w.meshes,
        "nodes": w.nodes,
        "accessors": w.accessors,
        "bufferViews": w.views,
    });
    if !w.materials.is_empty() {
        doc["materials"] = json!(w.materials);
    }
    if !used.is_empty() {
        doc["extensionsUsed"] = json!(used);
    }
    if !required.is_empty() {
        doc["extensionsRequired"] = json!(required);
    }
    match v {
        Variant::NoScenes => {}
        Variant::EmptyScene => doc["scenes"] = json!([{}]),
        _ => {
            doc["scene"] = json!(0);
            doc["scenes"] = json!([{ "nodes": roots }]);
        }
    }
    let bin = w.bin;
    if v == Variant::Meshopt {
        doc["buffers"] = json!([
            { "byteLength": w.fallback_len,
              "extensions": { "EXT_meshopt_compression": { "fallback": true } } },
            { "byteLength": bin.len() },
        ]);
    } else {
        doc["buffers"] = json!([{ "byteLength": bin.len() }]);
    }
    (glb(&doc, &bin), expect)
}

/// The world box of a flat model's placements (finite ones).
pub fn world_box(flat: &Flat) -> (Vec3, Vec3) {
    let mut b = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for (m, t) in &flat.placements {
        for p in &flat.meshes[*m] {
            for q in &p.positions {
                let w = t.transform_point3(Vec3::from(*q));
                b.0 = b.0.min(w);
                b.1 = b.1.max(w);
            }
        }
    }
    b
}

#[derive(Default)]
struct Writer {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    meshes: Vec<Value>,
    nodes: Vec<Value>,
    materials: Vec<Value>,
    /// Bytes the meshopt fallback buffer stands for.
    fallback_len: u64,
}

impl Writer {
    fn view(&mut self, bytes: &[u8], stride: Option<usize>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut v = json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() });
        if let Some(s) = stride {
            v["byteStride"] = json!(s);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }

    /// A view of `count` elements of `stride` bytes compressed with meshopt
    /// into buffer 1; buffer 0 is the fallback.
    fn meshopt_view(
        &mut self,
        raw: &[u8],
        count: usize,
        stride: usize,
        mode: &str,
        filter: &str,
        vertices: usize,
    ) -> usize {
        let enc = match (mode, stride) {
            ("TRIANGLES", 4) => {
                let idx: Vec<u32> = bytemuck::pod_collect_to_vec(raw);
                meshopt::encode_index_buffer(&idx, vertices).unwrap()
            }
            ("TRIANGLES", 2) => {
                let idx: Vec<u32> = raw
                    .chunks_exact(2)
                    .map(|c| u32::from(u16::from_le_bytes([c[0], c[1]])))
                    .collect();
                meshopt::encode_index_buffer(&idx, vertices).unwrap()
            }
            (_, 4) => {
                meshopt::encode_vertex_buffer(&bytemuck::pod_collect_to_vec::<u8, [u8; 4]>(raw))
                    .unwrap()
            }
            (_, 8) => {
                meshopt::encode_vertex_buffer(&bytemuck::pod_collect_to_vec::<u8, [u8; 8]>(raw))
                    .unwrap()
            }
            _ => panic!("stride {stride}"),
        };
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(&enc);
        let fb = self.fallback_len;
        self.fallback_len += raw.len().next_multiple_of(4) as u64;
        let mut ext = json!({ "buffer": 1, "byteOffset": offset, "byteLength": enc.len(),
            "byteStride": stride, "count": count, "mode": mode });
        if filter != "NONE" {
            ext["filter"] = json!(filter);
        }
        let mut v = json!({ "buffer": 0, "byteOffset": fb, "byteLength": raw.len(),
            "extensions": { "EXT_meshopt_compression": ext } });
        if mode == "ATTRIBUTES" {
            v["byteStride"] = json!(stride);
        }
        self.views.push(v);
        self.views.len() - 1
    }

    fn accessor(
        &mut self,
        view: usize,
        ctype: u32,
        normalized: bool,
        count: usize,
        kind: &str,
    ) -> usize {
        let mut a =
            json!({ "bufferView": view, "componentType": ctype, "count": count, "type": kind });
        if normalized {
            a["normalized"] = json!(true);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn plain_prim(&mut self, p: &Prim, sparse: bool) -> Value {
        let n = p.positions.len();
        let mut pos: Vec<[f32; 3]> = p.positions.clone();
        let k = n.min(8);
        if sparse {
            for q in pos.iter_mut().take(k) {
                *q = [1e4, -1e4, 1e4];
            }
        }
        let pv = self.view(bytemuck::cast_slice(&pos), None);
        let pa = self.accessor(pv, 5126, false, n, "VEC3");
        if sparse {
            let idx: Vec<u32> = (0..k as u32).collect();
            let iv = self.view(bytemuck::cast_slice(&idx), None);
            let vv = self.view(bytemuck::cast_slice(&p.positions[..k]), None);
            self.accessors[pa]["sparse"] = json!({ "count": k,
                "indices": { "bufferView": iv, "componentType": 5125 },
                "values": { "bufferView": vv } });
        }
        let mut attrs = json!({ "POSITION": pa });
        if let Some(nr) = &p.normals {
            let nv = self.view(bytemuck::cast_slice(nr), None);
            attrs["NORMAL"] = json!(self.accessor(nv, 5126, false, n, "VEC3"));
        }
        let iv = self.view(bytemuck::cast_slice(&p.indices), None);
        let ia = self.accessor(iv, 5125, false, p.indices.len(), "SCALAR");
        json!({ "attributes": attrs, "indices": ia })
    }

    fn quantized_prim(&mut self, p: &Prim, lo: Vec3, scale: Vec3, meshopt: bool) -> Value {
        let n = p.positions.len();
        let q: Vec<[u16; 4]> = p
            .positions
            .iter()
            .map(|v| {
                let c = (Vec3::from(*v) - lo) / scale;
                let f = |x: f32| x.round().clamp(0.0, 65535.0) as u16;
                [f(c.x), f(c.y), f(c.z), 0]
            })
            .collect();
        let raw: &[u8] = bytemuck::cast_slice(&q);
        let pv = if meshopt {
            self.meshopt_view(raw, n, 8, "ATTRIBUTES", "NONE", n)
        } else {
            self.view(raw, Some(8))
        };
        let mut attrs = json!({ "POSITION": self.accessor(pv, 5123, false, n, "VEC3") });
        if let Some(nr) = &p.normals {
            let nv = if meshopt {
                let f: Vec<[f32; 4]> = nr.iter().map(|v| [v[0], v[1], v[2], 0.0]).collect();
                let enc: Vec<[i8; 4]> = meshopt::encode_filter_oct(&f, 8);
                self.meshopt_view(
                    bytemuck::cast_slice(&enc),
                    n,
                    4,
                    "ATTRIBUTES",
                    "OCTAHEDRAL",
                    n,
                )
            } else {
                let b: Vec<[i8; 4]> = nr
                    .iter()
                    .map(|v| {
                        let s = |c: f32| (c * 127.0).round().clamp(-127.0, 127.0) as i8;
                        [s(v[0]), s(v[1]), s(v[2]), 0]
                    })
                    .collect();
                self.view(bytemuck::cast_slice(&b), Some(4))
            };
            attrs["NORMAL"] = json!(self.accessor(nv, 5120, true, n, "VEC3"));
        }
        let small = n <= 65536;
        let ibytes: Vec<u8> = if small {
            p.indices
                .iter()
                .flat_map(|&i| (i as u16).to_le_bytes())
                .collect()
        } else {
            p.indices.iter().flat_map(|&i| i.to_le_bytes()).collect()
        };
        let stride = if small { 2 } else { 4 };
        let iv = if meshopt && p.indices.len().is_multiple_of(3) {
            self.meshopt_view(&ibytes, p.indices.len(), stride, "TRIANGLES", "NONE", n)
        } else {
            self.view(&ibytes, None)
        };
        let ctype = if small { 5123 } else { 5125 };
        let ia = self.accessor(iv, ctype, false, p.indices.len(), "SCALAR");
        json!({ "attributes": attrs, "indices": ia })
    }

    fn instance_accessors(&mut self, list: &[Mat4]) -> (usize, usize, usize) {
        let (mut t, mut r, mut s) = (Vec::new(), Vec::new(), Vec::new());
        for m in list {
            let (sc, rot, tr) = m.to_scale_rotation_translation();
            t.push(tr.to_array());
            r.push(rot.to_array());
            s.push(sc.to_array());
        }
        let n = list.len();
        let tv = self.view(bytemuck::cast_slice(&t), None);
        let ta = self.accessor(tv, 5126, false, n, "VEC3");
        let rv = self.view(bytemuck::cast_slice(&r), None);
        let ra = self.accessor(rv, 5126, false, n, "VEC4");
        let sv = self.view(bytemuck::cast_slice(&s), None);
        let sa = self.accessor(sv, 5126, false, n, "VEC3");
        (ta, ra, sa)
    }
}

/// The JSON and the BIN chunk of a GLB (the inverse of [`glb`]).
pub fn split_glb(b: &[u8]) -> (Value, Vec<u8>) {
    let jl = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
    let json = serde_json::from_slice(&b[20..20 + jl]).unwrap();
    let at = 20 + jl;
    let bin = match b.get(at..at + 4) {
        Some(l) => {
            let bl = u32::from_le_bytes(l.try_into().unwrap()) as usize;
            b[at + 8..at + 8 + bl].to_vec()
        }
        None => Vec::new(),
    };
    (json, bin)
}

/// A GLB container around `doc` and `bin`.
pub fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
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
