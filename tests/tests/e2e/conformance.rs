//! The importer over a conformance set assembled here: six real models, each
//! written in every variant of `e2e_tests::conformance` (instancing,
//! quantization, meshopt compression, sparse accessors, material
//! extensions, scene structure, survey coordinates, hostile transforms,
//! unsupported extensions). Every case is OK (the triangle count the
//! importer reports equals the independent count, and the box agrees) or a
//! clean refusal; none is wrong, none panics.

use std::path::Path;

use e2e_tests::conformance::{self, Expect, VARIANTS, Variant};
use e2e_tests::data_dir;
use glam::Vec3;
use hlod_builder::import;

const MODELS: &[&str] = &[
    "2CylinderEngine/2CylinderEngine.gltf",
    "AC14-FZK-Haus.glb",
    "Ifc2x3_Duplex_Architecture.glb",
    "schependomlaan_subcontractors.glb",
    "bunny.glb",
    "dragon_res4.glb",
];

#[derive(Debug, PartialEq)]
enum Outcome {
    Ok,
    Refused,
    Wrong(String),
    Panic,
}

/// The scene box of an import, in world coordinates.
pub(crate) fn world_box(imp: &import::Imported) -> (Vec3, Vec3) {
    let o = Vec3::from(imp.origin.map(|c| c as f32));
    let mut b = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for inst in &imp.instances {
        let Some(m) = &imp.meshes[inst.mesh] else {
            continue;
        };
        for p in &m.positions {
            let w = inst.transform.transform_point3(Vec3::from(*p)) + o;
            b.0 = b.0.min(w);
            b.1 = b.1.max(w);
        }
    }
    b
}

fn check(model: &str, v: Variant) -> (Outcome, u64, u64, String) {
    let flat = conformance::read_flat(&data_dir().join(model));
    let (bytes, expect) = conformance::write(&flat, v);
    let path = Path::new("conformance.glb");
    let got = std::panic::catch_unwind(|| import::load_slice(&bytes, Path::new("."), path));
    let Ok(got) = got else {
        return (Outcome::Panic, 0, 0, String::new());
    };
    match (expect, got) {
        (Expect::Triangles(n), Ok(imp)) => {
            let have = imp.instanced_source_triangles();
            if have != n {
                return (
                    Outcome::Wrong(format!("{have} triangles, expected {n}")),
                    n,
                    have,
                    String::new(),
                );
            }
            // Geometry: the box agrees with the model's (quantisation to
            // 1/65535 of a mesh; survey and hostile variants are moved or
            // partly skipped, so only their counts are compared).
            if !matches!(v, Variant::Survey | Variant::HostileTransforms) {
                let (a, b) = (conformance::world_box(&flat), world_box(&imp));
                let tol = (a.1 - a.0).max_element() * 1e-3 + 1e-4;
                if (a.0 - b.0).abs().max_element() > tol || (a.1 - b.1).abs().max_element() > tol {
                    return (
                        Outcome::Wrong(format!("box {b:?}, expected {a:?}")),
                        n,
                        have,
                        String::new(),
                    );
                }
            }
            (Outcome::Ok, n, have, imp.warnings.len().to_string())
        }
        (Expect::Refusal(word), Err(e)) => {
            let msg = e.to_string();
            if msg.contains(word) && msg.contains("conformance.glb") && !msg.contains('\n') {
                (Outcome::Refused, 0, 0, msg)
            } else {
                (
                    Outcome::Wrong(format!("refusal without {word:?}: {msg}")),
                    0,
                    0,
                    msg,
                )
            }
        }
        (Expect::Triangles(n), Err(e)) => {
            (Outcome::Wrong(format!("refused: {e}")), n, 0, String::new())
        }
        (Expect::Refusal(_), Ok(_)) => (Outcome::Wrong("accepted".into()), 0, 0, String::new()),
    }
}

#[test]
fn every_variant_of_every_model_is_ok_or_a_clean_refusal() {
    let mut rows = Vec::new();
    let mut bad = Vec::new();
    for model in MODELS {
        for &v in VARIANTS {
            let (outcome, expected, got, note) = check(model, v);
            rows.push(format!(
                "| {model} | {v:?} | {outcome:?} | {expected} | {got} | {note} |"
            ));
            if !matches!(outcome, Outcome::Ok | Outcome::Refused) {
                bad.push(format!("{model} {v:?}: {outcome:?}"));
            }
        }
    }
    println!("| model | variant | outcome | expected tris | reported tris | warnings / message |");
    println!("|---|---|---|---:|---:|---|");
    for r in &rows {
        println!("{r}");
    }
    assert!(bad.is_empty(), "wrong or panicked:\n{}", bad.join("\n"));
}

#[test]
fn instanced_quantized_and_compressed_variants_count_what_the_plain_one_does() {
    let flat = conformance::read_flat(&data_dir().join("2CylinderEngine/2CylinderEngine.gltf"));
    let count = |v| {
        let (bytes, _) = conformance::write(&flat, v);
        import::load_slice(&bytes, Path::new("."), Path::new("x.glb"))
            .unwrap()
            .instanced_source_triangles()
    };
    let plain = count(Variant::Plain);
    assert_eq!(plain, 121_496);
    for v in [
        Variant::Instanced { required: false },
        Variant::Instanced { required: true },
        Variant::Quantized,
        Variant::Meshopt,
        Variant::Sparse,
    ] {
        assert_eq!(count(v), plain, "{v:?}");
    }
}

#[test]
fn a_survey_coordinate_model_keeps_millimetres() {
    // A 0.1 m box at (5,000 km, 3,000 km): every vertex must come back to
    // within 1 mm in world coordinates.
    let cube: Vec<[f32; 3]> = (0..8)
        .map(|k| {
            [
                (k & 1) as f32 * 0.1,
                ((k >> 1) & 1) as f32 * 0.1,
                ((k >> 2) & 1) as f32 * 0.1,
            ]
        })
        .collect();
    let idx: Vec<u32> = vec![
        0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1, 2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4,
        1, 5, 7, 1, 7, 3,
    ];
    let flat = conformance::Flat {
        meshes: vec![vec![conformance::Prim {
            positions: cube.clone(),
            normals: None,
            indices: idx,
        }]],
        placements: vec![
            (0, glam::Mat4::IDENTITY),
            (0, glam::Mat4::from_translation(Vec3::new(0.25, 0.0, 0.0))),
        ],
    };
    let (bytes, _) = conformance::write(&flat, Variant::Survey);
    let imp = import::load_slice(&bytes, Path::new("."), Path::new("survey.glb")).unwrap();
    assert_ne!(imp.origin, [0.0; 3], "a far model gets an origin");
    let o = glam::DVec3::from(imp.origin);
    for (k, inst) in imp.instances.iter().enumerate() {
        let m = imp.meshes[inst.mesh].as_ref().unwrap();
        let at = glam::DVec3::new(5.0e6 + 0.25 * k as f64, 3.0e6, 100.0);
        assert_eq!(m.positions.len(), cube.len());
        for p in &m.positions {
            let got = inst.transform.transform_point3(Vec3::from(*p)).as_dvec3() + o;
            let err = cube
                .iter()
                .map(|q| (got - (at + Vec3::from(*q).as_dvec3())).abs().max_element())
                .fold(f64::INFINITY, f64::min);
            assert!(
                err < 1e-3,
                "vertex {got} is {err} m from the nearest true vertex"
            );
        }
    }
    // And through a built scene file: the origin is in the header.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("survey.glb");
    std::fs::write(&input, &bytes).unwrap();
    let out = dir.path().join("survey.hlod");
    hlod_builder::build_file(&input, &out, &hlod_builder::BuildParams::default(), false).unwrap();
    let scene = engine::SceneFile::open(&out).unwrap();
    assert_eq!(scene.meta().origin, imp.origin);
    let root = scene.skeleton().root().unwrap();
    let width = root.bbox_max[0] - root.bbox_min[0];
    assert!(
        (width - 0.35).abs() < 1e-3,
        "scene width {width}, expected 0.35 m"
    );
}

/// A quantized mesh (unsigned shorts near 35,000) under a node scale of
/// 100.0037 and a translation that cancels the product (about 3.5e6) down
/// to a 2 m part near the origin: composed in f32 the two would lose a
/// quarter of a metre; the importer keeps every vertex to the millimetre.
#[test]
fn a_quantized_mesh_whose_placement_cancels_a_large_product_keeps_millimetres() {
    let q: Vec<[u16; 3]> = (0..8u16)
        .map(|k| {
            [
                35_000 + (k & 1) * 20,
                35_000 + ((k >> 1) & 1) * 20,
                35_000 + (k >> 2) * 20,
            ]
        })
        .collect();
    let idx: [u16; 36] = [
        0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1, 2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4,
        1, 5, 7, 1, 7, 3,
    ];
    let mut bin: Vec<u8> = Vec::new();
    for p in &q {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
        bin.extend_from_slice(&[0, 0]); // each vertex padded to 8 bytes
    }
    let pos_len = bin.len();
    for i in idx {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let (s, t) = (100.003_7_f64, -3_500_129.012_3_f64);
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_mesh_quantization"],
        "extensionsRequired": ["KHR_mesh_quantization"],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteLength": pos_len, "byteStride": 8},
            {"buffer": 0, "byteOffset": pos_len, "byteLength": 72}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5123, "count": 8, "type": "VEC3",
             "min": [35000, 35000, 35000], "max": [35020, 35020, 35020]},
            {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "nodes": [{"mesh": 0, "scale": [s, s, s], "translation": [t, t, t]}],
        "scenes": [{"nodes": [0]}], "scene": 0
    });
    let bytes = conformance::glb(&doc, &bin);
    let imp = import::load_slice(&bytes, Path::new("."), Path::new("quantized.glb")).unwrap();
    let o = glam::DVec3::from(imp.origin);
    let inst = &imp.instances[0];
    let m = imp.meshes[inst.mesh].as_ref().unwrap();
    let truth: Vec<glam::DVec3> = q
        .iter()
        .map(|p| glam::DVec3::from(p.map(f64::from)) * s + glam::DVec3::splat(t))
        .collect();
    assert!(
        truth[0].abs().max_element() < 10.0,
        "a part near the origin"
    );
    for p in &m.positions {
        let got = inst.transform.transform_point3(Vec3::from(*p)).as_dvec3() + o;
        let err = truth
            .iter()
            .map(|w| (got - *w).abs().max_element())
            .fold(f64::INFINITY, f64::min);
        assert!(
            err < 1e-3,
            "vertex {got} is {err} from the nearest true vertex"
        );
    }
}

/// Files that gltfpack and gltf-transform wrote (`tests/data/real/`): the
/// count matches gltf-transform's own, and the box the plain model's
/// (Draco included: `draco.rs` checks those files closer).
#[test]
fn real_tool_exports_import_with_the_independent_count_and_box() {
    let dir = data_dir().join("real");
    let list = std::fs::read_to_string(dir.join("expected.tsv")).unwrap();
    let mut checked = 0;
    for line in list.lines() {
        let (name, count) = line.split_once('\t').unwrap();
        let count: u64 = count.parse().unwrap();
        let path = dir.join(name);
        let got = import::load(&path);
        let imp = got.unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(imp.instanced_source_triangles(), count, "{name}");
        let plain = match name.split('.').next().unwrap() {
            "2CylinderEngine" => "2CylinderEngine/2CylinderEngine.gltf".to_string(),
            stem => format!("{stem}.glb"),
        };
        let (a, b) = (
            conformance::world_box(&conformance::read_flat(&data_dir().join(&plain))),
            world_box(&imp),
        );
        let tol = (a.1 - a.0).max_element() * 2e-3;
        assert!(
            (a.0 - b.0).abs().max_element() < tol && (a.1 - b.1).abs().max_element() < tol,
            "{name}: box {b:?}, the plain model's {a:?}"
        );
        checked += 1;
    }
    assert_eq!(checked, 15);
}
