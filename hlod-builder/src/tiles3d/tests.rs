use std::collections::BTreeMap;
use std::path::Path;

use engine::format::{PackedVertex, RepMesh, SceneFile};
use serde_json::Value;

use super::glb::{self, Element, Features};
use super::*;

pub(super) fn plant_scene(dir: &Path, objects: usize) -> PathBuf {
    let model = dir.join("p.glb");
    crate::scenegen::plant::write_plant(
        &crate::scenegen::plant::PlantParams {
            seed: 5,
            objects,
            triangles: objects as u64 * 400,
        },
        &model,
    )
    .unwrap();
    let scene = dir.join("p.hlod");
    crate::build_file(&model, &scene, &crate::BuildParams::default(), false).unwrap();
    scene
}

/// Decodes a GLB's primitive back: vertices, indices, feature IDs.
pub(super) fn decode(bytes: &[u8]) -> (Value, Vec<PackedVertex>, Vec<u32>, Vec<f32>) {
    // Read back through the gltf crate's GLB reader, not ours.
    let glb = gltf::binary::Glb::from_slice(bytes).expect("a GLB");
    let doc: Value = serde_json::from_slice(&glb.json).expect("JSON");
    let bin = glb.bin.expect("a BIN chunk");
    let view = |a: usize| {
        let v = &doc["bufferViews"][doc["accessors"][a]["bufferView"].as_u64().unwrap() as usize];
        let e = &v["extensions"]["EXT_meshopt_compression"];
        let (o, l) = (
            e["byteOffset"].as_u64().unwrap() as usize,
            e["byteLength"].as_u64().unwrap() as usize,
        );
        (
            &bin[o..o + l],
            e["count"].as_u64().unwrap() as usize,
            e["byteStride"].as_u64().unwrap(),
        )
    };
    let (vs, vc, _) = view(0);
    let verts: Vec<PackedVertex> = meshopt::decode_vertex_buffer(vs, vc).unwrap();
    let (is, ic, stride) = view(3);
    let indices: Vec<u32> = if stride == 2 {
        meshopt::decode_index_buffer::<u16>(is, ic)
            .unwrap()
            .into_iter()
            .map(u32::from)
            .collect()
    } else {
        meshopt::decode_index_buffer::<u32>(is, ic).unwrap()
    };
    let ids = if doc["accessors"].as_array().unwrap().len() > 4 {
        let (fs, fc, _) = view(4);
        meshopt::decode_vertex_buffer::<f32>(fs, fc).unwrap()
    } else {
        Vec::new()
    };
    (doc, verts, indices, ids)
}

/// Triangles each rotated to start at their smallest index (the index codec
/// may rotate them; it keeps their winding).
fn rotated(ix: &[u32]) -> Vec<[u32; 3]> {
    ix.chunks(3)
        .map(|t| {
            let k = (0..3).min_by_key(|&k| t[k]).unwrap();
            [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
        })
        .collect()
}

fn mesh() -> RepMesh {
    // A flat, anisotropic quad pair (box 10 x 0.5 x 0) and a slanted triangle.
    let p = [
        [0.0, 0.0, 0.0],
        [10.0, 0.0, 0.0],
        [10.0, 0.5, 0.0],
        [0.0, 0.5, 0.0],
        [5.0, 0.2, 0.0],
    ];
    let n = [
        [0.0, 0.0, 1.0],
        [0.6, 0.0, 0.8],
        [0.0, 0.6, 0.8],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, 1.0],
    ];
    let c = [[200, 10, 10, 255]; 5];
    RepMesh::quantize(&p, &n, &c, vec![0, 1, 2, 0, 2, 3, 1, 4, 2])
}

#[test]
fn a_glb_holds_the_rep_as_quantised_and_its_normals_come_out_as_they_were() {
    let m = mesh();
    let (doc, verts, indices, ids) = decode(&glb::encode(&m, None));
    assert_eq!(
        rotated(&indices),
        rotated(&m.indices),
        "the same triangles, the same winding"
    );
    assert!(ids.is_empty());
    let s = glb::node_scale(&m);
    assert_eq!(doc["nodes"][0]["scale"], serde_json::json!(s));
    assert!(
        s.iter().all(|&v| v > 0.0),
        "the flat axis gets a scale: {s:?}"
    );
    for (a, b) in verts.iter().zip(&m.vertices) {
        assert_eq!(a.position, b.position, "positions are stored as quantised");
        assert_eq!(a.color, b.color);
        // What a renderer does: the normal matrix (S^-1), then normalise.
        let r = [0, 1, 2].map(|k| f32::from(a.normal[k]) / 127.0 / s[k]);
        let want = [0, 1, 2].map(|k| f32::from(b.normal[k]) / 127.0);
        let len = r.iter().map(|x| x * x).sum::<f32>().sqrt();
        let dot: f32 = (0..3).map(|k| r[k] / len * want[k]).sum();
        assert!(dot > 0.995, "normal {want:?} comes out as {r:?}");
    }
    let pos = &doc["accessors"][0];
    assert_eq!(pos["componentType"], 5123);
    assert!(pos.get("normalized").is_none());
    assert_eq!(doc["extensionsRequired"].as_array().unwrap().len(), 2);
}

#[test]
fn features_split_shared_vertices_and_name_each_triangle() {
    let m = mesh();
    let el = |k: u32| Element {
        object: k,
        name: format!("obj{k}"),
        ..Element::default()
    };
    let f = Features {
        triangle: vec![0, 1, 1],
        elements: vec![el(7), el(9)],
    };
    let (doc, verts, indices, ids) = decode(&glb::encode(&m, Some(&f)));
    assert_eq!(indices.len(), 9);
    for (t, tri) in indices.chunks(3).enumerate() {
        let mut got: Vec<[u16; 4]> = tri.iter().map(|&i| verts[i as usize].position).collect();
        let mut want: Vec<[u16; 4]> = m.indices[t * 3..t * 3 + 3]
            .iter()
            .map(|&i| m.vertices[i as usize].position)
            .collect();
        got.sort();
        want.sort();
        assert_eq!(got, want, "triangle {t}");
        for &i in tri {
            assert_eq!(ids[i as usize], f.triangle[t] as f32);
        }
    }
    // Vertices 0, 1 and 2 are used by both elements: split.
    assert_eq!(verts.len(), m.vertices.len() + 3);
    let table = &doc["extensions"]["EXT_structural_metadata"]["propertyTables"][0];
    assert_eq!(table["count"], 2);
    let fid =
        &doc["meshes"][0]["primitives"][0]["extensions"]["EXT_mesh_features"]["featureIds"][0];
    assert_eq!(fid["featureCount"], 2);
    // Every metadata view is 8-aligned, as EXT_structural_metadata asks.
    for v in doc["bufferViews"].as_array().unwrap() {
        if v["buffer"] == 0 {
            assert_eq!(v["byteOffset"].as_u64().unwrap() % 8, 0);
        }
    }
}

#[test]
fn ifc_type_and_global_id_come_from_extras_or_the_name() {
    let e = element(
        3,
        r#"{"name":"w","extras":{"GlobalId":"2O2Fr$t4X7Zf8NOew3FLOH","type":"IfcWall"}}"#,
    );
    assert_eq!(
        (e.ifc_type.as_str(), e.global_id.as_str()),
        ("IfcWall", "2O2Fr$t4X7Zf8NOew3FLOH")
    );
    let e = element(
        4,
        r#"{"name":"IfcSlab:Floor:0BTBFw6f90Nfh9rP1dlXr2","mesh":1}"#,
    );
    assert_eq!(
        (e.ifc_type.as_str(), e.global_id.as_str()),
        ("IfcSlab", "0BTBFw6f90Nfh9rP1dlXr2")
    );
    let e = element(5, "not json");
    assert_eq!((e.name.as_str(), e.info.as_str()), ("", ""));
}

/// Every tile of a tileset folder, by JSON file: (tile, parent's error).
pub(super) fn tiles(dir: &Path) -> (Vec<(Value, f64)>, usize) {
    let mut out = Vec::new();
    let mut files = vec![("tileset.json".to_string(), f64::INFINITY)];
    let mut n = 0;
    while let Some((name, bound)) = files.pop() {
        n += 1;
        let doc: Value = serde_json::from_slice(&fs::read(dir.join(&name)).unwrap()).unwrap();
        assert_eq!(doc["asset"]["version"], "1.1");
        let mut stack = vec![(doc["root"].clone(), bound)];
        while let Some((t, b)) = stack.pop() {
            let e = t["geometricError"].as_f64().unwrap();
            assert!(e <= b, "a tile's error {e} exceeds its parent's {b}");
            if let Some(u) = t["content"]["uri"].as_str()
                && u.ends_with(".json")
            {
                files.push((u.to_string(), e));
            }
            for c in t["children"].as_array().into_iter().flatten() {
                stack.push((c.clone(), e));
            }
            out.push((t, b));
        }
    }
    (out, n)
}

#[test]
fn the_tileset_has_a_tile_per_rep_with_its_error_and_splits_into_files() {
    let dir = tempfile::tempdir().unwrap();
    let scene = plant_scene(dir.path(), 60);
    let out = dir.path().join("tiles");
    let r = export(&scene, &out, ExportOptions::default()).unwrap();
    let file = SceneFile::open(&scene).unwrap();
    let s = file.skeleton();
    let with_tris = s.reps.iter().filter(|r| r.tri_count > 0).count() as u64;
    assert_eq!(r.contents, with_tris);
    assert_eq!(r.json_files, 1);
    let (all, _) = tiles(&out);
    assert_eq!(all.len() as u64, r.tiles);
    // Each content tile has its rep's error and its node's box.
    let mut seen = BTreeMap::new();
    for (t, _) in &all {
        if let Some(u) = t["content"]["uri"].as_str() {
            let rep: u32 = u
                .rsplit('/')
                .next()
                .unwrap()
                .trim_end_matches(".glb")
                .parse()
                .unwrap();
            let rec = &s.reps[rep as usize];
            assert_eq!(t["geometricError"].as_f64().unwrap() as f32, rec.error);
            let n = &s.nodes[rec.node as usize];
            let b = t["boundingVolume"]["box"].as_array().unwrap();
            let cy = 0.5 * (f64::from(n.bbox_min[1]) + f64::from(n.bbox_max[1]));
            assert!(
                (b[2].as_f64().unwrap() - cy).abs() < 1e-9,
                "z-up: the box's z is y"
            );
            assert!(out.join(u).is_file());
            seen.insert(rep, ());
        }
    }
    assert_eq!(seen.len() as u64, with_tris);
    // Split into files of at most 16 tiles: the same tiles.
    let small = dir.path().join("small");
    let r2 = export(
        &scene,
        &small,
        ExportOptions {
            max_tiles_per_json: 16,
            ..ExportOptions::default()
        },
    )
    .unwrap();
    let (all2, files) = tiles(&small);
    assert!(files > 3, "{files} files");
    assert_eq!(r2.json_files as usize, files);
    let content = |v: &[(Value, f64)]| {
        let mut c: Vec<String> = v
            .iter()
            .filter_map(|(t, _)| t["content"]["uri"].as_str().map(String::from))
            .filter(|u| u.ends_with(".glb"))
            .collect();
        c.sort();
        c
    };
    assert_eq!(content(&all), content(&all2));
    assert_eq!(r2.contents, r.contents);
}

#[test]
fn the_export_is_deterministic_atomic_and_refuses_a_foreign_folder() {
    let dir = tempfile::tempdir().unwrap();
    let scene = plant_scene(dir.path(), 30);
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    export(&scene, &a, ExportOptions::default()).unwrap();
    export(&scene, &b, ExportOptions::default()).unwrap();
    assert_eq!(files(&a), files(&b), "byte-identical");
    // An earlier export is replaced; a stale file in it goes.
    fs::write(a.join("stale.txt"), b"x").unwrap();
    export(&scene, &a, ExportOptions::default()).unwrap();
    assert!(!a.join("stale.txt").exists());
    assert_eq!(files(&a), files(&b));
    // Nothing else is left beside it.
    let names: Vec<String> = fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.starts_with('.')), "{names:?}");
    // A folder that is not an export is refused, untouched.
    let other = dir.path().join("other");
    fs::create_dir(&other).unwrap();
    fs::write(other.join("notes.txt"), b"mine").unwrap();
    let e = export(&scene, &other, ExportOptions::default()).unwrap_err();
    assert!(e.to_string().contains("not an earlier export"), "{e}");
    assert_eq!(fs::read(other.join("notes.txt")).unwrap(), b"mine");
    // A missing scene names the file.
    let e = export(
        &dir.path().join("nope.hlod"),
        &other,
        ExportOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("nope.hlod"), "{e}");
}

/// Every file under `d`: its path relative to `d` and its bytes, sorted.
pub(super) fn files(d: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = walk(d)
        .into_iter()
        .map(|p| {
            let name = p.strip_prefix(d).unwrap().display().to_string();
            (name, fs::read(&p).unwrap())
        })
        .collect();
    v.sort();
    v
}

fn walk(d: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in fs::read_dir(d).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}
