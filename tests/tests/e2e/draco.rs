//! `KHR_draco_mesh_compression` against the files' uncompressed sources:
//! gltf-transform's Draco exports of two IFC houses, a scan and a coloured
//! grid (edgebreaker and sequential connectivity) import with the source's
//! triangles, every position within the stream's quantisation step of a
//! source position, and the colours and normals of the source; a damaged
//! stream is one error naming the file, the primitive and the stream.
//! The quantisation step is read from the streams by another decoder,
//! `draco-oxide` (pure Rust), than the importer's (libdraco).

use std::collections::HashMap;
use std::path::Path;

use draco_oxide_decoder::AttributeTransform;
use e2e_tests::conformance::{self, Flat};
use e2e_tests::data_dir;
use glam::Vec3;
use hlod_builder::import::{self, Imported};
use serde_json::Value;

/// Each Draco file of `tests/data/real` and its uncompressed source.
const PAIRS: &[(&str, &str)] = &[
    ("AC14-FZK-Haus.gt-draco.glb", "AC14-FZK-Haus.glb"),
    (
        "Ifc2x3_Duplex_Architecture.gt-draco.glb",
        "Ifc2x3_Duplex_Architecture.glb",
    ),
    ("dragon_res4.gt-draco.glb", "dragon_res4.glb"),
    ("grid-colours.gt-draco.glb", "grid-colours.glb"),
    ("grid-colours.gt-draco-seq.glb", "grid-colours.glb"),
];

/// The byte range in BIN of every Draco stream, with its POSITION id.
fn streams(doc: &Value) -> Vec<(usize, usize, u64)> {
    let mut out = Vec::new();
    for m in doc["meshes"].as_array().unwrap() {
        for p in m["primitives"].as_array().unwrap() {
            let e = &p["extensions"]["KHR_draco_mesh_compression"];
            let v = &doc["bufferViews"][e["bufferView"].as_u64().unwrap() as usize];
            let o = v["byteOffset"].as_u64().unwrap_or(0) as usize;
            let len = v["byteLength"].as_u64().unwrap() as usize;
            out.push((o, o + len, e["attributes"]["POSITION"].as_u64().unwrap()));
        }
    }
    out
}

/// The largest position quantisation step of any stream of the file, read
/// from the streams themselves (the decoder's portable form keeps it).
fn position_step(bytes: &[u8]) -> f32 {
    let (doc, bin) = conformance::split_glb(bytes);
    let mut step = 0f32;
    for (a, b, uid) in streams(&doc) {
        let p = draco_oxide_decoder::decode_mesh_portable(&bin[a..b]).unwrap();
        let i = p
            .mesh
            .attributes
            .iter()
            .position(|att| att.get_id().as_usize() as u64 == uid)
            .unwrap();
        match &p.transforms[i] {
            AttributeTransform::Quantized {
                delta_max, bits, ..
            } => step = step.max(delta_max / ((1u32 << bits) - 1) as f32),
            _ => panic!("POSITION is not quantised"),
        }
    }
    step
}

/// World positions of an import, with each vertex's colour and normal.
fn world(imp: &Imported) -> Vec<(Vec3, [u8; 4], Vec3)> {
    let o = Vec3::from(imp.origin.map(|c| c as f32));
    let mut out = Vec::new();
    for inst in &imp.instances {
        let Some(m) = &imp.meshes[inst.mesh] else {
            continue;
        };
        for (i, p) in m.positions.iter().enumerate() {
            let w = inst.transform.transform_point3(Vec3::from(*p)) + o;
            let n = inst.transform.transform_vector3(Vec3::from(m.normals[i]));
            out.push((w, m.colors[i], n.normalize_or_zero()));
        }
    }
    out
}

/// A grid of `flat`'s world positions with cells of `cell`, to find
/// the source positions near a point.
fn grid(flat: &Flat, cell: f32) -> HashMap<[i64; 3], Vec<Vec3>> {
    let mut g: HashMap<[i64; 3], Vec<Vec3>> = HashMap::new();
    for (m, t) in &flat.placements {
        for p in &flat.meshes[*m] {
            for q in &p.positions {
                let w = t.transform_point3(Vec3::from(*q));
                g.entry(key(w, cell)).or_default().push(w);
            }
        }
    }
    g
}

fn key(p: Vec3, cell: f32) -> [i64; 3] {
    (p / cell).floor().as_i64vec3().to_array()
}

/// The distance (largest axis) from `p` to the nearest position in `g`.
fn nearest(g: &HashMap<[i64; 3], Vec<Vec3>>, p: Vec3, cell: f32) -> f32 {
    let k = key(p, cell);
    let mut best = f32::INFINITY;
    for dx in -1..=1 {
        for dy in -1..=1 {
            for dz in -1..=1 {
                for q in g
                    .get(&[k[0] + dx, k[1] + dy, k[2] + dz])
                    .into_iter()
                    .flatten()
                {
                    best = best.min((*q - p).abs().max_element());
                }
            }
        }
    }
    best
}

#[test]
fn draco_files_import_with_the_sources_triangles_and_positions_within_one_step() {
    for (draco, plain) in PAIRS {
        let path = data_dir().join("real").join(draco);
        let bytes = std::fs::read(&path).unwrap();
        let imp = import::load(&path).unwrap_or_else(|e| panic!("{draco}: {e}"));
        let src = conformance::read_flat(&data_dir().join(plain));
        assert_eq!(imp.instanced_source_triangles(), src.triangles(), "{draco}");
        // Placements are rigid here (IFC exports, the scans): a local step
        // is a world step. Half a step is the rounding; f32 adds a little.
        let step = position_step(&bytes);
        let extent = {
            let (a, b) = conformance::world_box(&src);
            (b - a).max_element()
        };
        let tol = 0.5 * step + 8.0 * f32::EPSILON * extent.max(1.0);
        let g = grid(&src, tol.max(1e-6));
        let mut worst = 0f32;
        for (p, ..) in world(&imp) {
            worst = worst.max(nearest(&g, p, tol.max(1e-6)));
        }
        assert!(
            worst <= tol,
            "{draco}: a position {worst} from the nearest source position, step {step}"
        );
    }
}

#[test]
fn draco_colours_and_normals_are_the_sources() {
    for draco in ["grid-colours.gt-draco.glb", "grid-colours.gt-draco-seq.glb"] {
        let imp = import::load(&data_dir().join("real").join(draco)).unwrap();
        let src = import::load(&data_dir().join("grid-colours.glb")).unwrap();
        // Grid points are 0.1 apart in x and y: a centimetre key finds the
        // source point whatever the quantisation did.
        let key = |p: Vec3| (p.truncate() * 100.0).round().as_ivec2().to_array();
        let by_pos: HashMap<_, _> = world(&src)
            .into_iter()
            .map(|(p, c, n)| (key(p), (c, n)))
            .collect();
        let got = world(&imp);
        assert_eq!(
            got.len(),
            by_pos.len(),
            "{draco}: one vertex per grid point"
        );
        for (p, c, n) in got {
            let (sc, sn) = by_pos[&key(p)];
            // Bytes are coded losslessly; float colours with 8 bits or more.
            let dc = c.iter().zip(sc).map(|(a, b)| a.abs_diff(b)).max().unwrap();
            assert!(dc <= 1, "{draco}: colour {c:?}, source {sc:?} at {p}");
            assert!(n.dot(sn) > 0.999, "{draco}: normal {n}, source {sn}");
        }
    }
}

/// `doc` and `bin` changed by `f`, imported from memory.
fn damaged(mut f: impl FnMut(&mut Value, &mut Vec<u8>)) -> String {
    let bytes = std::fs::read(data_dir().join("real/AC14-FZK-Haus.gt-draco.glb")).unwrap();
    let (mut doc, mut bin) = conformance::split_glb(&bytes);
    f(&mut doc, &mut bin);
    let out = conformance::glb(&doc, &bin);
    match import::load_slice(&out, Path::new("."), Path::new("haus.glb")) {
        Ok(_) => String::new(),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_damaged_draco_stream_is_one_error_naming_the_file_and_the_primitive() {
    let first = |doc: &Value| streams(doc)[0];
    let said = |e: &str, what: &str| {
        assert!(e.starts_with("haus.glb: meshes["), "{e}");
        assert!(e.contains("KHR_draco_mesh_compression"), "{e}");
        assert!(e.contains(what), "expected {what:?} in: {e}");
        assert_eq!(e.lines().count(), 1, "{e}");
    };
    // Not a Draco stream at all.
    let e = damaged(|doc, bin| {
        let (a, ..) = first(doc);
        bin[a..a + 5].copy_from_slice(b"XXXXX");
    });
    said(&e, "Draco stream: Not a Draco file");
    // Cut short: the view is a quarter of the stream.
    let e = damaged(|doc, _| {
        let v = doc["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]
            ["bufferView"]
            .as_u64()
            .unwrap() as usize;
        let len = doc["bufferViews"][v]["byteLength"].as_u64().unwrap();
        doc["bufferViews"][v]["byteLength"] = (len / 4).into();
    });
    said(&e, "Draco stream");
    // The extension names an attribute the stream does not have.
    let e = damaged(|doc, _| {
        doc["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"]
            ["POSITION"] = 99.into();
    });
    said(&e, "unique id 99");
    // No buffer view.
    let e = damaged(|doc, _| {
        let ext =
            &mut doc["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"];
        ext.as_object_mut().unwrap().remove("bufferView");
    });
    said(&e, "no bufferView");
    // Bytes changed anywhere in a stream: a mesh or the error above, never
    // a crash or a hang (the reference decoder has no checksum: some
    // changes decode to another mesh).
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    let mut errors = 0;
    for _ in 0..300 {
        let e = damaged(|doc, bin| {
            for (a, b, _) in streams(doc).into_iter().take(3) {
                for _ in 0..4 {
                    rng ^= rng << 13;
                    rng ^= rng >> 7;
                    rng ^= rng << 17;
                    bin[a + (rng as usize % (b - a))] = (rng >> 32) as u8;
                }
            }
        });
        if !e.is_empty() {
            said(&e, "bytes): ");
            errors += 1;
        }
    }
    assert!(errors > 100, "{errors} of 300 damaged files refused");
}
