//! Builds every shipped test model and a generated plant, then reads them back.

use std::path::Path;

use e2e_tests::data_dir;
use engine::{SceneFile, Skeleton};
use hlod_builder::build::{BuildParams, BuildStats, build_file};
use hlod_builder::scenegen::plant::{PlantParams, write_plant};

fn build(input: &Path, dir: &Path, name: &str) -> (BuildStats, SceneFile) {
    let out = dir.join(name);
    let stats = build_file(input, &out, &BuildParams::default(), false).unwrap();
    let scene = SceneFile::open(&out).unwrap();
    scene.verify_all_reps().unwrap();
    (stats, scene)
}

/// Errors strictly increase along PAR up to the root, from every rep.
fn assert_monotone(s: &Skeleton) {
    for id in 0..s.reps.len() as u32 {
        let mut cur = id;
        while let Some(p) = s.par(cur) {
            assert!(
                s.reps[p as usize].error > s.reps[cur as usize].error,
                "PAR({cur}) = {p}"
            );
            cur = p;
        }
        assert_eq!(cur, 0, "every PAR chain ends at the root's coarsest rep");
    }
}

#[test]
fn every_test_model_builds_validates_and_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("bunny.glb", 1, 69_451),
        ("dragon_res4.glb", 1, 11_102),
        ("2CylinderEngine/2CylinderEngine.gltf", 0, 0),
        ("schependomlaan_subcontractors.glb", 0, 0),
    ];
    for (file, objects, tris) in cases {
        let (stats, scene) = build(&data_dir().join(file), dir.path(), "out.hlod");
        let s = scene.skeleton();
        if objects > 0 {
            assert_eq!(stats.objects, objects, "{file}");
            assert_eq!(stats.input_triangles, tris, "{file}");
        }
        assert_eq!(scene.meta().input_triangles, stats.input_triangles);
        // One small object is one leaf; larger inputs are chunked or clustered.
        let expect_hierarchy = stats.input_triangles > 65_536 || stats.objects > 1;
        assert_eq!(s.nodes.len() > 1, expect_hierarchy, "{file}");
        assert!(
            s.reps.len() >= s.nodes.len() + 2,
            "{file}: expected several LODs per leaf"
        );
        assert_monotone(s);
        // The finest reps of the leaves hold the whole input.
        let finest: u64 = s
            .nodes
            .iter()
            .filter(|n| n.is_leaf())
            .map(|n| u64::from(s.reps[(n.first_rep + n.rep_count - 1) as usize].tri_count))
            .sum();
        assert_eq!(finest, stats.usable_triangles, "{file}");
        assert!(stats.usable_triangles <= stats.input_triangles, "{file}");
        // The root's coarsest rep is a drastic approximation.
        assert!(
            u64::from(s.reps[0].tri_count) * 4 < stats.input_triangles,
            "{file}"
        );
    }
}

#[test]
fn known_object_counts_of_the_cad_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let (engine, _) = build(
        &data_dir().join("2CylinderEngine/2CylinderEngine.gltf"),
        dir.path(),
        "e.hlod",
    );
    assert_eq!(engine.objects, 67);
    assert_eq!(engine.input_triangles, 121_496);
    let (school, _) = build(
        &data_dir().join("schependomlaan_subcontractors.glb"),
        dir.path(),
        "s.hlod",
    );
    assert_eq!(school.objects, 2_274);
}

#[test]
fn same_input_and_parameters_give_identical_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let input = data_dir().join("2CylinderEngine/2CylinderEngine.gltf");
    for name in ["a.hlod", "b.hlod"] {
        build_file(
            &input,
            &dir.path().join(name),
            &BuildParams::default(),
            false,
        )
        .unwrap();
    }
    let a = std::fs::read(dir.path().join("a.hlod")).unwrap();
    let b = std::fs::read(dir.path().join("b.hlod")).unwrap();
    assert!(a == b, "two builds differ");
    let c_params = BuildParams {
        branching: 4,
        ..BuildParams::default()
    };
    build_file(&input, &dir.path().join("c.hlod"), &c_params, false).unwrap();
    assert_ne!(a, std::fs::read(dir.path().join("c.hlod")).unwrap());
    // The thread count does not show in the output either.
    let single = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    single
        .install(|| {
            build_file(
                &input,
                &dir.path().join("d.hlod"),
                &BuildParams::default(),
                false,
            )
        })
        .unwrap();
    assert!(
        a == std::fs::read(dir.path().join("d.hlod")).unwrap(),
        "1-thread build differs"
    );
}

#[test]
fn generated_plant_and_tiles_build() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("plant.glb");
    let p = PlantParams {
        seed: 3,
        objects: 120,
        triangles: 60_000,
    };
    let gs = write_plant(&p, &glb).unwrap();
    assert_eq!(gs.objects, 120);
    let (stats, scene) = build(&glb, dir.path(), "plant.hlod");
    assert_eq!(stats.objects, 120);
    assert_eq!(stats.input_triangles, gs.triangles);
    assert!(scene.skeleton().height() >= 3);
    // Deterministic generator: same seed, same bytes.
    let glb2 = dir.path().join("plant2.glb");
    write_plant(&p, &glb2).unwrap();
    assert_eq!(std::fs::read(&glb).unwrap(), std::fs::read(&glb2).unwrap());

    let tiled = dir.path().join("tiled.glb");
    for baked in [false, true] {
        let t = hlod_builder::scenegen::tile::write_tiled(
            &data_dir().join("dragon_res4.glb"),
            3,
            2,
            baked,
            0.1,
            &tiled,
        )
        .unwrap();
        assert_eq!(t.objects, 6);
        let (stats, _) = build(&tiled, dir.path(), "tiled.hlod");
        assert_eq!(stats.input_triangles, 6 * 11_102);
        assert_eq!(stats.objects, 6);
    }
}
