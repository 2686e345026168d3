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

/// Serialises meshes and objects to GLB bytes.
pub fn to_glb(meshes: &[Mesh], objects: &[GlbObject]) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut materials: BTreeMap<[u8; 4], usize> = BTreeMap::new();
    let mut gltf_meshes = Vec::new();
    let mut push_view = |bin: &mut Vec<u8>, bytes: &[u8], target: u32| {
        bin.resize(bin.len().next_multiple_of(4), 0);
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len(), "target": target}));
        bin.extend_from_slice(bytes);
        views.len() - 1
    };
    for mesh in meshes {
        // Triangles grouped by colour, in order of first appearance.
        let mut groups: Vec<([u8; 4], Vec<usize>)> = Vec::new();
        for t in 0..mesh.tri_count() {
            let c = mesh.colors[mesh.indices[3 * t] as usize];
            match groups.iter_mut().find(|(k, _)| *k == c) {
                Some((_, v)) => v.push(t),
                None => groups.push((c, vec![t])),
            }
        }
        let mut prims = Vec::new();
        for (color, tris) in groups {
            let part = mesh.subset(tris);
            let b = part.bounds();
            let n_mat = materials.len();
            let material = *materials.entry(color).or_insert(n_mat);
            let pv = push_view(&mut bin, bytemuck::cast_slice(&part.positions), 34962);
            let nv = push_view(&mut bin, bytemuck::cast_slice(&part.normals), 34962);
            let iv = push_view(&mut bin, bytemuck::cast_slice(&part.indices), 34963);
            let a = accessors.len();
            accessors.push(
                json!({"bufferView": pv, "componentType": 5126, "count": part.vertex_count(),
                "type": "VEC3", "min": b.min.to_array(), "max": b.max.to_array()}),
            );
            accessors.push(json!({"bufferView": nv, "componentType": 5126, "count": part.vertex_count(), "type": "VEC3"}));
            accessors.push(json!({"bufferView": iv, "componentType": 5125, "count": part.indices.len(), "type": "SCALAR"}));
            prims.push(json!({"attributes": {"POSITION": a, "NORMAL": a + 1}, "indices": a + 2, "material": material}));
        }
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
    bin.resize(bin.len().next_multiple_of(4), 0);
    let doc = json!({
        "asset": {"version": "2.0", "generator": "hlod-build gen"},
        "scene": 0,
        "scenes": [{"nodes": (0..objects.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": gltf_meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
    });
    let mut js = serde_json::to_vec(&doc).expect("JSON values serialise");
    js.resize(js.len().next_multiple_of(4), b' ');
    let total = 12 + 8 + js.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(js.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&js);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// Writes a GLB atomically (temporary file in the same directory, then rename).
pub fn write_glb(path: &Path, meshes: &[Mesh], objects: &[GlbObject]) -> std::io::Result<u64> {
    let bytes = to_glb(meshes, objects);
    if bytes.len() > u32::MAX as usize {
        return Err(std::io::Error::other(format!(
            "scene of {} bytes exceeds the GLB limit of 4 GiB",
            bytes.len()
        )));
    }
    write_atomically(path, &bytes)?;
    Ok(bytes.len() as u64)
}

/// Writes `bytes` to `path` through a temporary file and a rename.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut tmp = tempfile::Builder::new()
        .prefix(".hlod-gen-")
        .suffix(".tmp")
        .tempfile_in(dir)?;
    tmp.write_all(bytes)?;
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}
