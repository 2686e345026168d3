//! View-dependence trees built from the shipped scanned models.

use hlod_builder::import::load;
use hlod_builder::vdt::{VdtParams, build_tree};

#[test]
fn bunny_tree_validates_and_refines_back_to_the_input() {
    let imp = load(&e2e_tests::data_dir().join("bunny.glb")).unwrap();
    let mesh = imp.meshes.iter().flatten().next().unwrap();
    let t0 = std::time::Instant::now();
    let t = build_tree(&mesh.positions, &mesh.indices, &VdtParams::default());
    let secs = t0.elapsed().as_secs_f64();
    t.validate().unwrap();
    let leaves: Vec<bool> = (0..t.nodes.len()).map(|i| i < t.leaf_count()).collect();
    assert_eq!(t.cut_triangles(&leaves).len(), t.triangles.len());
    assert!(t.triangles.len() > 60_000);
    assert!(
        t.roots.len() < t.leaf_count() / 100,
        "{} roots for {} vertices",
        t.roots.len(),
        t.leaf_count()
    );
    eprintln!(
        "bunny: {} vertices, {} triangles, {} nodes, {} roots, {:.2} s",
        t.leaf_count(),
        t.triangles.len(),
        t.nodes.len(),
        t.roots.len(),
        secs
    );
}
