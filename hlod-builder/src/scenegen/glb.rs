//! A minimal GLB (binary glTF 2.0) writer for generated scenes.
//!
//! Each mesh becomes a glTF mesh with one primitive per distinct vertex colour
//! (a material with that base colour); each object a node referring to a mesh,
//! so meshes placed many times are instanced.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

use glam::Mat4;
use serde_json::{Value, json};

use crate::mesh::Mesh;

/// A node of the written scene.
#[derive(Clone, Debug)]
pub struct GlbObject {
    pub name: String,
    pub mesh: usize,
    pub transform: Mat4,
}

/// Triangles of `mesh` grouped by colour (first vertex), in order of first
/// appearance; `None` when the mesh has one colour and is written whole.
fn colour_groups(mesh: &Mesh) -> Option<Vec<([u8; 4], Vec<usize>)>> {
    let mut groups: Vec<([u8; 4], Vec<usize>)> = Vec::new();
    for t in 0..mesh.tri_count() {
        let c = mesh.colors[mesh.indices[3 * t] as usize];
        match groups.iter_mut().find(|(k, _)| *k == c) {
            Some((_, v)) => v.push(t),
            None => groups.push((c, vec![t])),
        }
    }
    (groups.len() > 1).then_some(groups)
}

/// Calls `f` with each primitive of `mesh`: its colour and geometry.
fn for_each_part(mesh: &Mesh, mut f: impl FnMut([u8; 4], &Mesh)) {
    match colour_groups(mesh) {
        None => f(mesh.dominant_color(), mesh),
        Some(groups) => {
            for (color, tris) in groups {
                f(color, &mesh.subset(tris));
            }
        }
    }
}

fn pad4(n: usize) -> usize {
    n.next_multiple_of(4)
}

/// The JSON chunk and the BIN chunk's length (first pass: layout only).
fn layout(meshes: &[Mesh], objects: &[GlbObject]) -> (Vec<u8>, usize) {
    let mut bin_len = 0usize;
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut materials: BTreeMap<[u8; 4], usize> = BTreeMap::new();
    let mut gltf_meshes = Vec::new();
    let mut view = |len: usize, target: u32| {
        views
            .push(json!({"buffer": 0, "byteOffset": bin_len, "byteLength": len, "target": target}));
        bin_len += pad4(len);
        views.len() - 1
    };
    for mesh in meshes {
        let mut prims = Vec::new();
        for_each_part(mesh, |color, part| {
            let b = Mesh::bounds_of_all(part);
            let n_mat = materials.len();
            let material = *materials.entry(color).or_insert(n_mat);
            let vc = part.vertex_count();
            let pv = view(vc * 12, 34962);
            let nv = view(vc * 12, 34962);
            let iv = view(part.indices.len() * 4, 34963);
            let a = accessors.len();
            accessors.push(json!({"bufferView": pv, "componentType": 5126, "count": vc,
                "type": "VEC3", "min": b.min.to_array(), "max": b.max.to_array()}));
            accessors.push(
                json!({"bufferView": nv, "componentType": 5126, "count": vc, "type": "VEC3"}),
            );
            accessors.push(json!({"bufferView": iv, "componentType": 5125, "count": part.indices.len(), "type": "SCALAR"}));
            prims.push(json!({"attributes": {"POSITION": a, "NORMAL": a + 1}, "indices": a + 2, "material": material}));
        });
        gltf_meshes.push(json!({ "primitives": prims }));
    }
    let mut mats: Vec<(usize, [u8; 4])> = materials.into_iter().map(|(c, i)| (i, c)).collect();
    mats.sort_unstable();
    let materials: Vec<Value> = mats
        .iter()
        .map(|(_, c)| {
            let f = c.map(|x| f64::from(x) / 255.0);
            json!({"pbrMetallicRoughness": {"baseColorFactor": f, "metallicFactor": 0.0, "roughnessFactor": 0.8}})
        })
        .collect();
    let nodes: Vec<Value> = objects
        .iter()
        .map(|o| {
            let mut n = json!({"name": o.name, "mesh": o.mesh});
            if o.transform != Mat4::IDENTITY {
                n["matrix"] = json!(o.transform.to_cols_array());
            }
            n
        })
        .collect();
    let doc = json!({
        "asset": {"version": "2.0", "generator": "hlod-build gen"},
        "scene": 0,
        "scenes": [{"nodes": (0..objects.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": gltf_meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin_len}],
    });
    let mut js = serde_json::to_vec(&doc).expect("JSON values serialise");
    js.resize(pad4(js.len()), b' ');
    (js, bin_len)
}

/// Streams meshes and objects as GLB into `w`; returns the bytes written.
/// Memory stays at the JSON plus one primitive, whatever the scene's size.
pub fn write_glb_to<W: Write>(
    w: &mut W,
    meshes: &[Mesh],
    objects: &[GlbObject],
) -> std::io::Result<u64> {
    let (js, bin_len) = layout(meshes, objects);
    let total = 12 + 8 + js.len() + 8 + bin_len;
    let too_big = || {
        std::io::Error::other(format!(
            "scene of {total} bytes exceeds the GLB limit of 4 GiB"
        ))
    };
    let total32 = u32::try_from(total).map_err(|_| too_big())?;
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&total32.to_le_bytes())?;
    w.write_all(&(js.len() as u32).to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(&js)?;
    w.write_all(&(bin_len as u32).to_le_bytes())?;
    w.write_all(b"BIN\0")?;
    let mut result = Ok(());
    let mut put = |w: &mut W, bytes: &[u8]| {
        if result.is_ok() {
            result = w
                .write_all(bytes)
                .and_then(|()| w.write_all(&[0u8; 3][..pad4(bytes.len()) - bytes.len()]));
        }
    };
    for mesh in meshes {
        for_each_part(mesh, |_, part| {
            put(w, bytemuck::cast_slice(&part.positions));
            put(w, bytemuck::cast_slice(&part.normals));
            put(w, bytemuck::cast_slice(&part.indices));
        });
    }
    result?;
    Ok(total as u64)
}

/// Serialises meshes and objects to GLB bytes in memory.
pub fn to_glb(meshes: &[Mesh], objects: &[GlbObject]) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::new();
    write_glb_to(&mut out, meshes, objects)?;
    Ok(out)
}

/// Writes a GLB atomically (temporary file in the same directory, then rename).
pub fn write_glb(
    path: &Path,
    inputs: &[&Path],
    meshes: &[Mesh],
    objects: &[GlbObject],
) -> std::io::Result<u64> {
    engine::outfile::write_with(path, inputs, |w| write_glb_to(w, meshes, objects))
}
