//! Thin members do not vanish from coarse reps and HLODs (issue 21,
//! item 5): on a generated scene of lattice towers, pipe racks and
//! railings, every point of the full-resolution geometry under a node lies
//! within each of the node's reps' errors of that rep's triangles, so a rep
//! drawn at ε px leaves no member more than ε px from where it is drawn.

use hlod_builder::build::{BuildParams, build_file};
use hlod_builder::deviation::distance_from;
use hlod_builder::mesh::Mesh;
use hlod_builder::scenegen::lattice::{LatticeParams, write_lattice};

fn mesh_of(scene: &engine::SceneFile, r: u32) -> Mesh {
    let m = scene.read_rep(r).unwrap();
    Mesh {
        positions: m.vertices.iter().map(|v| m.position(v)).collect(),
        indices: m.indices.clone(),
        ..Mesh::default()
    }
}

#[test]
fn every_rep_keeps_the_members_under_it_within_its_error() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("lattice.glb");
    write_lattice(&LatticeParams { seed: 5, units: 2 }, &glb).unwrap();
    let out = dir.path().join("lattice.hlod");
    build_file(&glb, &out, &BuildParams::default(), false).unwrap();
    let scene = engine::SceneFile::open(&out).unwrap();
    let s = scene.skeleton().clone();
    // Full resolution under each node: its leaves' finest reps.
    let n = s.nodes.len();
    let mut full: Vec<Mesh> = vec![Mesh::default(); n];
    for i in (0..n as u32).rev() {
        let node = &s.nodes[i as usize];
        if node.is_leaf() {
            full[i as usize] = mesh_of(&scene, node.first_rep + node.rep_count - 1);
        } else {
            let mut m = Mesh::default();
            for c in s.children(i) {
                let cm = &full[c as usize];
                let base = m.positions.len() as u32;
                m.positions.extend_from_slice(&cm.positions);
                m.indices.extend(cm.indices.iter().map(|x| x + base));
            }
            full[i as usize] = m;
        }
    }
    let mut checked = 0;
    let mut worst: f32 = 0.0;
    for (i, node) in s.nodes.iter().enumerate() {
        for r in node.first_rep..node.first_rep + node.rep_count {
            let rec = &s.reps[r as usize];
            if rec.is_vdt() || full[i].indices.is_empty() {
                continue;
            }
            let d = distance_from(&full[i], &mesh_of(&scene, r));
            // A rep's error bounds how far the geometry it stands for lies
            // from it (up to the quantisation of the two reps compared).
            let slack = 1e-3 + 0.01 * rec.error;
            assert!(
                d <= rec.error + slack,
                "node {i} rep {r} (level {} of {}): members {d} m away, error {}",
                rec.index,
                node.rep_count,
                rec.error
            );
            worst = worst.max(d / rec.error.max(1e-6));
            checked += 1;
        }
    }
    assert!(checked > 100, "{checked} reps checked");
    eprintln!("{checked} reps checked; largest distance / error {worst:.3}");
}
