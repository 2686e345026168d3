//! The object section of a built BIM model: every object described by its
//! glTF names and world box, and every triangle of a merged leaf's finest
//! rep attributed to the object whose geometry it is.

use e2e_tests::data_dir;
use engine::format::{NONE, RepKind};
use hlod_builder::build::{BuildParams, build_file};

#[test]
fn every_finest_triangle_lies_in_the_box_of_the_object_it_is_attributed_to() {
    let dir = tempfile::tempdir().unwrap();
    let input = data_dir().join("Ifc2x3_Duplex_Architecture.glb");
    assert!(
        check_attribution(&input, dir.path(), true) > 10,
        "the Duplex has merged leaves"
    );
    // Tiled with instancing, most leaves are repeated and share their
    // chains (format version 6): the runs of a shared merged leaf's finest
    // level name this leaf's objects, placed where they are.
    let tiled = dir.path().join("tiled.glb");
    hlod_builder::scenegen::tile::write_tiled(&input, 2, 2, false, 0.1, &tiled).unwrap();
    let merged = check_attribution(&tiled, dir.path(), false);
    let scene = engine::SceneFile::open(&dir.path().join("scene.hlod")).unwrap();
    let s = scene.skeleton();
    let leaves: Vec<&engine::format::NodeRecord> = s.nodes.iter().filter(|n| n.is_leaf()).collect();
    let shared_leaves = leaves
        .iter()
        .filter(|n| s.placement(n.first_rep).is_some())
        .count();
    let shared_merged = (leaves.iter())
        .filter(|n| n.object == NONE && s.placement(n.first_rep).is_some())
        .count();
    assert!(
        // (Measured: 178 of 273, 38 of 120 merged.)
        shared_leaves * 2 > leaves.len() && shared_merged > 0,
        "{shared_leaves} of {} leaves share their chains ({shared_merged} of {merged} merged)",
        leaves.len()
    );
}

/// Builds `input` into `dir/scene.hlod` and checks that every triangle of
/// every leaf's finest level lies in the box of the object the object
/// section attributes it to; returns the merged leaves. `mesh_names`: the
/// objects' meshes have names (the tiler's copies do not).
fn check_attribution(input: &std::path::Path, dir: &std::path::Path, mesh_names: bool) -> usize {
    let out = dir.join("scene.hlod");
    let stats = build_file(input, &out, &BuildParams::default(), false).unwrap();
    let scene = engine::SceneFile::open(&out).unwrap();
    let table = scene.read_objects().unwrap();
    assert_eq!(table.len() as u64, stats.objects);
    let s = scene.skeleton();
    let origin = glam::DVec3::from(scene.meta().origin);
    let boxes: Vec<(glam::Vec3, glam::Vec3)> = (0..table.len() as u32)
        .map(|k| {
            let v: serde_json::Value = serde_json::from_str(table.info(k).unwrap()).unwrap();
            assert!(v["name"].as_str().is_some_and(|n| !n.is_empty()), "{v}");
            assert!(v["mesh_name"].is_string() || !mesh_names, "{v}");
            let b = |key: &str| {
                let a: Vec<f64> = v[key]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_f64().unwrap())
                    .collect();
                (glam::DVec3::new(a[0], a[1], a[2]) - origin).as_vec3()
            };
            (b("box_min"), b("box_max"))
        })
        .collect();
    let (mut merged, mut tris) = (0, 0u64);
    for (i, n) in s.nodes.iter().enumerate() {
        if !n.is_leaf() {
            continue;
        }
        let rep = (n.first_rep..n.first_rep + n.rep_count)
            .rev()
            .find(|&r| s.reps[r as usize].rep_kind() == Some(RepKind::Lod))
            .unwrap();
        let mesh = scene.read_rep(rep).unwrap();
        let tol = 2.0 * mesh.quantization_error() + 1e-4;
        merged += usize::from(n.object == NONE);
        for (t, tri) in mesh.indices.chunks_exact(3).enumerate() {
            let k = table
                .object_at(s, i as u32, t as u32)
                .expect("every triangle has an object");
            let (lo, hi) = boxes[k as usize];
            for &v in tri {
                let p = glam::Vec3::from(mesh.position(&mesh.vertices[v as usize]));
                assert!(
                    p.cmpge(lo - tol).all() && p.cmple(hi + tol).all(),
                    "leaf {i} triangle {t}: {p} outside object {k}'s box {lo}..{hi}"
                );
            }
            tris += 1;
        }
    }
    assert_eq!(tris, stats.usable_triangles);
    merged
}

/// The objects of a built scene whose finest reps hold a triangle.
fn drawn_objects(scene: &engine::SceneFile) -> std::collections::BTreeSet<u32> {
    let table = scene.read_objects().unwrap();
    let s = scene.skeleton();
    let mut out = std::collections::BTreeSet::new();
    for (i, n) in s.nodes.iter().enumerate().filter(|(_, n)| n.is_leaf()) {
        let rep = n.first_rep + n.rep_count - 1;
        for t in 0..s.reps[rep as usize].tri_count {
            out.extend(table.object_at(s, i as u32, t));
        }
    }
    out
}

#[test]
fn ifc_opening_voids_and_spaces_are_left_out_unless_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let input = data_dir().join("Ifc2x3_Duplex_Architecture.glb");
    let (a, b) = (dir.path().join("a.hlod"), dir.path().join("b.hlod"));
    let hidden = build_file(&input, &a, &BuildParams::default(), false).unwrap();
    let kept = BuildParams {
        ifc_voids: true,
        ..BuildParams::default()
    };
    let all = build_file(&input, &b, &kept, false).unwrap();
    // The Duplex has 50 IfcOpeningElement and 21 IfcSpace objects.
    assert_eq!((hidden.hidden_objects, all.hidden_objects), (71, 0));
    assert_eq!(hidden.objects, all.objects, "both list every object");
    assert_eq!(
        hidden.usable_triangles + hidden.hidden_triangles,
        all.usable_triangles
    );
    let (sa, sb) = (
        engine::SceneFile::open(&a).unwrap(),
        engine::SceneFile::open(&b).unwrap(),
    );
    let table = sa.read_objects().unwrap();
    let (da, db) = (drawn_objects(&sa), drawn_objects(&sb));
    assert_eq!(db.len() as u64, all.objects, "every object is drawn");
    for k in 0..table.len() as u32 {
        let v: serde_json::Value = serde_json::from_str(table.info(k).unwrap()).unwrap();
        let name = v["name"].as_str().unwrap();
        let void = name.starts_with("IfcOpeningElement") || name.starts_with("IfcSpace");
        assert_eq!(da.contains(&k), !void, "{name}");
    }
}
