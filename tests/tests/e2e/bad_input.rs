//! Bad input gives typed errors naming the file, never a panic or partial output.

use std::path::Path;

use e2e_tests::{data_dir, grid, tiny_gltf};
use hlod_builder::build::{BuildError, BuildParams, build_file};
use hlod_builder::import::ImportError;

fn try_build(input: &Path, dir: &Path) -> Result<(), BuildError> {
    build_file(input, &dir.join("out.hlod"), &BuildParams::default(), false).map(|_| ())
}

/// Runs a build expected to fail; checks the directory holds nothing but the input.
fn fails(name: &str, contents: &[u8]) -> BuildError {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join(name);
    std::fs::write(&input, contents).unwrap();
    let err = try_build(&input, dir.path()).unwrap_err();
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(
        left,
        vec![std::ffi::OsString::from(name)],
        "partial output left behind"
    );
    assert!(
        err.to_string().contains(name),
        "error does not name the file: {err}"
    );
    err
}

#[test]
fn missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let err = try_build(&dir.path().join("nope.glb"), dir.path()).unwrap_err();
    assert!(matches!(err, BuildError::Import(ImportError::Read { .. })));
    assert!(err.to_string().contains("nope.glb"));
}

#[test]
fn not_gltf_and_truncated_glb() {
    assert!(matches!(
        fails("x.glb", b"hello world"),
        BuildError::Import(ImportError::Parse { .. })
    ));
    let bunny = std::fs::read(data_dir().join("bunny.glb")).unwrap();
    for cut in [12, 100, bunny.len() / 2, bunny.len() - 4] {
        let e = fails("cut.glb", &bunny[..cut]);
        assert!(matches!(e, BuildError::Import(_)), "cut at {cut}: {e}");
    }
}

#[test]
fn accessor_out_of_range() {
    let (p, i) = grid(2);
    let e = fails(
        "oob.gltf",
        tiny_gltf(&p, &i, 4, Some(p.len() + 50)).as_bytes(),
    );
    let msg = e.to_string();
    assert!(msg.contains("out of range"), "{e}");
    // The file and the glTF part, once.
    assert!(
        msg.contains("oob.gltf")
            && msg.contains("meshes[0].primitives[0]")
            && msg.contains("accessors[0]"),
        "{e}"
    );
}

#[test]
fn non_triangle_primitives_are_skipped_and_nothing_left_is_an_error() {
    let (p, i) = grid(2);
    let e = fails("lines.gltf", tiny_gltf(&p, &i, 1, None).as_bytes());
    assert!(
        matches!(e, BuildError::Import(ImportError::NoTriangles { .. })),
        "{e}"
    );
}

#[test]
fn nan_positions_degenerate_and_empty_meshes() {
    let (mut p, i) = grid(2);
    p[3][1] = f32::NAN;
    let e = fails("nan.gltf", tiny_gltf(&p, &i, 4, None).as_bytes());
    assert!(
        matches!(e, BuildError::Import(ImportError::NoTriangles { .. })),
        "{e}"
    );
    let flat = vec![[0.0, 0.0, 0.0]; 3];
    let e = fails(
        "degenerate.gltf",
        tiny_gltf(&flat, &[0, 1, 2, 0, 0, 1], 4, None).as_bytes(),
    );
    assert!(
        matches!(e, BuildError::Import(ImportError::NoTriangles { .. })),
        "{e}"
    );
    let e = fails("empty.gltf", tiny_gltf(&[], &[], 4, None).as_bytes());
    assert!(matches!(e, BuildError::Import(_)), "{e}");
}

#[test]
fn bad_index_skips_the_primitive_with_a_warning_and_strips_fans_work() {
    let dir = tempfile::tempdir().unwrap();
    let (p, mut i) = grid(3);
    i[5] = 999;
    let input = dir.path().join("badindex.gltf");
    std::fs::write(&input, tiny_gltf(&p, &i, 4, None)).unwrap();
    assert!(try_build(&input, dir.path()).is_err());
    // A strip of the same vertices builds.
    let strip: Vec<u32> = (0..p.len() as u32).collect();
    std::fs::write(&input, tiny_gltf(&p, &strip, 5, None)).unwrap();
    let stats = build_file(
        &input,
        &dir.path().join("ok.hlod"),
        &BuildParams::default(),
        false,
    )
    .unwrap();
    assert!(stats.input_triangles > 0);
}

#[test]
fn absurd_parameters_are_rejected_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let input = data_dir().join("dragon_res4.glb");
    let bad = [
        BuildParams {
            branching: 1,
            ..Default::default()
        },
        BuildParams {
            hlod_ratio: f32::NAN,
            ..Default::default()
        },
        BuildParams {
            chunk_tris: 0,
            ..Default::default()
        },
        BuildParams {
            lod: hlod_builder::lod::LodParams {
                ratio: 1.5,
                ..Default::default()
            },
            ..Default::default()
        },
    ];
    for p in bad {
        let r = build_file(&input, &dir.path().join("o.hlod"), &p, false);
        assert!(matches!(r, Err(BuildError::Params(_))), "{p:?}");
    }
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn missing_external_buffer_names_the_buffer_file() {
    let dir = tempfile::tempdir().unwrap();
    let gltf = dir.path().join("engine.gltf");
    std::fs::copy(
        data_dir().join("2CylinderEngine/2CylinderEngine.gltf"),
        &gltf,
    )
    .unwrap();
    let err = try_build(&gltf, dir.path()).unwrap_err().to_string();
    assert!(
        err.contains("engine.gltf") && err.contains("2CylinderEngine0.bin"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "no output left"
    );
}

/// The fuzz targets' calls (`tests/fuzz/fuzz_targets`) on their seeds and on
/// every input a campaign found (`tests/fuzz/regressions/TARGET/`), on the
/// stable toolchain: each ends in `Ok` or a typed error, never a panic.
#[test]
fn fuzz_seeds_and_regressions_run_clean() {
    use std::sync::Arc;
    let fuzz = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let inputs = |target: &str| -> Vec<(String, Vec<u8>)> {
        ["seeds", "regressions"]
            .iter()
            .filter_map(|d| std::fs::read_dir(fuzz.join(d).join(target)).ok())
            .flatten()
            .map(|e| {
                let p = e.unwrap().path();
                (p.display().to_string(), std::fs::read(&p).unwrap())
            })
            .collect()
    };
    let mut ran = 0;
    for (name, bytes) in inputs("scene_reader") {
        if let Ok(s) = engine::SceneFile::from_source(engine::MemSource::new(bytes)) {
            s.verify_all_reps()
                .unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        ran += 1;
    }
    for (_, bytes) in inputs("vdt_reader") {
        if let Ok(f) = engine::vdt::file::VdtFile::open(Arc::new(engine::MemSource::new(bytes))) {
            for m in 0..f.header.meta_count.min(64) {
                let _ = f.read_meta(m);
            }
        }
        ran += 1;
    }
    for (_, bytes) in inputs("gltf_import") {
        let _ = hlod_builder::import::load_slice(
            &bytes,
            Path::new("/nonexistent-fuzz-dir"),
            Path::new("fuzz.glb"),
        );
        ran += 1;
    }
    for (_, bytes) in inputs("path_parser") {
        if let Ok(text) = std::str::from_utf8(&bytes) {
            let _ = engine::camera::parse_path(text, "fuzz.txt");
        }
        ran += 1;
    }
    for (name, mut bytes) in inputs("shard_reader") {
        let key = hlod_builder::build::shard::reseal(&mut bytes).unwrap_or_default();
        let r = hlod_builder::build::shard::check_shard(&bytes, &key, 4096);
        if name.contains("/seeds/") {
            assert!(r.is_ok(), "{name}: a seed reads whole: {r:?}");
        }
        ran += 1;
    }
    for (name, bytes) in inputs("cache_entry") {
        let head = &bytes[..std::mem::size_of::<engine::FileHeader>().min(bytes.len())];
        let key = bytemuck::try_pod_read_unaligned::<engine::FileHeader>(head)
            .map_or([0; 16], |h| h.source_key);
        let r = hlod_builder::cache::check_entry_source(engine::MemSource::new(bytes), &key);
        if name.contains("/seeds/") {
            assert!(
                r.is_ok() && key != [0; 16],
                "{name}: a seed is a valid entry: {r:?}"
            );
        }
        ran += 1;
    }
    for (name, bytes) in inputs("mesh_import") {
        use hlod_builder::import::{Format, parse_mesh_bytes};
        let Some((&pick, file)) = bytes.split_first() else {
            continue;
        };
        let format = [Format::Ply, Format::Obj, Format::Stl][usize::from(pick % 3)];
        let r = parse_mesh_bytes(file, format, Path::new("/nonexistent-fuzz-dir"));
        if name.contains("/seeds/") {
            assert!(
                r.as_ref().is_ok_and(|&t| t > 0),
                "{name}: a seed reads: {r:?}"
            );
        }
        ran += 1;
    }
    assert!(ran >= 12, "the seeds are there ({ran})");
}

#[test]
fn an_unsupported_required_extension_is_refused_first_in_one_short_line() {
    // Splats required, and the rest broken too: that line comes first.
    let json = br#"{"asset":{"version":"2.0"},"extensionsRequired":["KHR_gaussian_splatting"],
        "extensionsUsed":["KHR_gaussian_splatting"],"accessors":5,"meshes":[{"primitives":[]}]}"#;
    let e = fails("splats.gltf", json).to_string();
    assert!(
        e.contains("KHR_gaussian_splatting") && e.contains("re-export"),
        "{e}"
    );
    assert!(!e.contains('\n') && e.len() < 400, "one short line: {e}");
    assert_eq!(
        e.matches("splats.gltf").count(),
        1,
        "the file named once: {e}"
    );
    let other = br#"{"asset":{"version":"2.0"},"extensionsRequired":["ACME_teleport"]}"#;
    let e = fails("acme.gltf", other).to_string();
    assert!(e.contains("ACME_teleport"), "{e}");
}

#[test]
fn no_renderable_triangles_says_why() {
    let (p, i) = grid(2);
    let e = fails("lines.gltf", tiny_gltf(&p, &i, 1, None).as_bytes()).to_string();
    assert!(
        e.contains("meshes[0].primitives[0]") && e.contains("LINES"),
        "{e}"
    );
    let (mut p, i) = grid(2);
    p[0][0] = f32::NAN;
    let e = fails("nan.gltf", tiny_gltf(&p, &i, 4, None).as_bytes()).to_string();
    assert!(e.contains("non-finite positions"), "{e}");
    let (p, mut i) = grid(2);
    i[4] = 999;
    let e = fails("oor.gltf", tiny_gltf(&p, &i, 4, None).as_bytes()).to_string();
    assert!(e.contains("index 999 out of range"), "{e}");
}

#[test]
fn an_overflowing_transform_is_caught_at_import_naming_the_node() {
    let (p, i) = grid(2);
    let json = tiny_gltf(&p, &i, 4, None).replace(
        r#""nodes":[{"mesh":0}]"#,
        r#""nodes":[{"mesh":0,"scale":[1e30,1e30,1e30]}]"#,
    );
    let e = fails("huge.gltf", json.as_bytes()).to_string();
    assert!(e.contains("nodes[0]") && e.contains("beyond"), "{e}");
    assert!(!e.contains("invariant") && !e.contains("huge.hlod"), "{e}");
}

#[test]
fn valid_files_the_old_importer_refused_now_build() {
    let dir = tempfile::tempdir().unwrap();
    let (p, i) = grid(3);
    let base = tiny_gltf(&p, &i, 4, None);
    // No min/max on POSITION; a scene without nodes; no scenes at all; a
    // 400-deep node chain; a NORMAL of unsigned bytes (recomputed).
    let no_minmax = {
        let a = base.find(r#","min":"#).unwrap();
        let m = base.find(r#""max":"#).unwrap();
        let b = m + base[m..].find(']').unwrap() + 1;
        format!("{}{}", &base[..a], &base[b..])
    };
    assert!(!no_minmax.contains("\"min\""));
    let no_scene_nodes = base.replace(r#""scenes":[{"nodes":[0]}]"#, r#""scenes":[{}]"#);
    let no_scenes = base.replace(r#""scene":0,"scenes":[{"nodes":[0]}],"#, "");
    let chain: Vec<String> = (0..400)
        .map(|k| {
            if k == 399 {
                r#"{"mesh":0}"#.to_string()
            } else {
                format!(r#"{{"children":[{}]}}"#, k + 1)
            }
        })
        .collect();
    let deep = base.replace(
        r#""nodes":[{"mesh":0}]"#,
        &format!(r#""nodes":[{}]"#, chain.join(",")),
    );
    let byte_normals = base
        .replace(
            r#""attributes":{"POSITION":0}"#,
            r#""attributes":{"POSITION":0,"NORMAL":2}"#,
        )
        .replace(
            r#""type":"SCALAR"}],"#,
            &format!(
                r#""type":"SCALAR"}},{{"bufferView":0,"componentType":5121,"count":{},"type":"VEC3"}}],"#,
                p.len()
            ),
        );
    for (name, json) in [
        ("no-minmax.gltf", no_minmax),
        ("no-scene-nodes.gltf", no_scene_nodes),
        ("no-scenes.gltf", no_scenes),
        ("deep.gltf", deep),
        ("byte-normals.gltf", byte_normals),
    ] {
        let input = dir.path().join(name);
        std::fs::write(&input, &json).unwrap();
        let out = dir.path().join(format!("{name}.hlod"));
        let stats = build_file(&input, &out, &BuildParams::default(), false)
            .unwrap_or_else(|e| panic!("{name}: {e}\n{json}"));
        assert_eq!(stats.input_triangles, 18, "{name}");
        if name == "byte-normals.gltf" {
            assert!(
                stats
                    .warnings
                    .iter()
                    .any(|w| w.contains("normals recomputed")),
                "{:?}",
                stats.warnings
            );
        }
    }
}

/// A GLB of one triangle whose POSITION has component type `ct`
/// (`normalized` as given) and `stride`-byte elements from `bin`, placed by
/// `nodes`; with `KHR_mesh_quantization` declared or not.
fn one_triangle(
    ct: u32,
    normalized: bool,
    bin: &[u8],
    stride: usize,
    ext: bool,
    nodes: serde_json::Value,
) -> Vec<u8> {
    let mut doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": (0..nodes.as_array().unwrap().len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 4}]}],
        "accessors": [{"bufferView": 0, "componentType": ct, "normalized": normalized, "count": 3, "type": "VEC3"}],
        "bufferViews": [{"buffer": 0, "byteLength": bin.len(), "byteStride": stride}],
        "buffers": [{"byteLength": bin.len()}],
    });
    if ext {
        doc["extensionsUsed"] = serde_json::json!(["KHR_mesh_quantization"]);
    }
    e2e_tests::conformance::glb(&doc, bin)
}

/// Import warnings of a GLB, with the triangles kept.
fn import_warnings(bytes: &[u8]) -> (Vec<String>, u64) {
    let imp = hlod_builder::import::load_slice(bytes, Path::new("."), Path::new("q.glb")).unwrap();
    let tris = imp
        .meshes
        .iter()
        .flatten()
        .map(|m| m.tri_count() as u64)
        .sum();
    (imp.warnings, tris)
}

#[test]
fn spec_invalid_quantization_and_degenerate_transforms_are_said() {
    let one = serde_json::json!([{"mesh": 0}]);
    let u16s: Vec<u8> = [[0u16, 0, 0, 0], [100, 0, 0, 0], [0, 100, 0, 0]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let u32s: Vec<u8> = [[0u32, 0, 0], [100, 0, 0], [0, 100, 0]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let f32s: Vec<u8> = [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    // Valid: quantized with the extension declared; plain floats.
    for (ct, bin, stride) in [(5123, &u16s, 8), (5126, &f32s, 12)] {
        let (w, tris) = import_warnings(&one_triangle(
            ct,
            false,
            bin,
            stride,
            ct != 5126,
            one.clone(),
        ));
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(tris, 1);
    }
    // Invalid: each said once, naming the primitive and the accessor; the
    // triangle is kept as its type reads.
    for (ct, norm, bin, stride, ext, needle) in [
        (
            5123,
            false,
            &u16s,
            8,
            false,
            "without KHR_mesh_quantization in extensionsUsed",
        ),
        (5126, true, &f32s, 12, false, "normalized FLOAT"),
        (5125, false, &u32s, 12, true, "UNSIGNED_INT components"),
    ] {
        let (w, tris) = import_warnings(&one_triangle(ct, norm, bin, stride, ext, one.clone()));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains(needle)
                && w[0].contains("meshes[0].primitives[0].attributes.POSITION: accessors[0]"),
            "{w:?}"
        );
        assert_eq!(tris, 1, "{needle}");
    }
    // A zero scale and a zero matrix collapse the mesh: said, and skipped.
    let nodes = serde_json::json!([
        {"mesh": 0},
        {"mesh": 0, "scale": [0.0, 0.0, 0.0]},
        {"mesh": 0, "matrix": vec![0.0; 16]},
    ]);
    let imp = hlod_builder::import::load_slice(
        &one_triangle(5126, false, &f32s, 12, false, nodes),
        Path::new("."),
        Path::new("q.glb"),
    )
    .unwrap();
    assert_eq!(imp.instances.len(), 1, "{:?}", imp.warnings);
    for n in ["nodes[1]", "nodes[2]"] {
        assert!(
            imp.warnings
                .iter()
                .any(|w| w.starts_with(n) && w.contains("degenerate")),
            "{n}: {:?}",
            imp.warnings
        );
    }
}
