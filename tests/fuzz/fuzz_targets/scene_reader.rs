//! The scene-file reader: header, skeleton, `validate()`, every rep
//! decoded, the object section, a pick through the scene, and a walk
//! across the walk section. Inputs of
//! even length get their header, skeleton and object-section CRCs
//! recomputed first (version 2), so that mutations reach the checks behind
//! the checksums.
#![no_main]

use engine::{MemSource, SceneFile};
use libfuzzer_sys::fuzz_target;

#[path = "fix.rs"]
mod fix;

fuzz_target!(|data: &[u8]| {
    let bytes = fix::prepared(data);
    if let Ok(scene) = SceneFile::from_source(MemSource::new(bytes)) {
        let _ = scene.verify_all_reps();
        if let Ok(objects) = scene.read_objects() {
            let root = &scene.skeleton().nodes[0];
            let (lo, hi) = (glam::Vec3::from(root.bbox_min), glam::Vec3::from(root.bbox_max));
            let eye = hi + (hi - lo);
            let _ = engine::pick::pick(&scene, &objects, eye, (lo + hi) * 0.5 - eye);
            for k in 0..objects.len() as u32 {
                let _ = objects.info(k);
            }
            // The model tree of whatever the descriptions say, and the
            // hiding and x-ray of its first group.
            let drawn = engine::tree::drawn_objects(scene.skeleton(), &objects);
            let tree = engine::tree::ModelTree::new(&objects, "fuzz", &drawn);
            assert_eq!(tree.validate(), Ok(()));
            let mut looks = Vec::new();
            if let Some(&g) = tree.groups()[0].children.first() {
                tree.apply(&mut looks, tree.objects(g), engine::tree::Op::XRayOthers);
            }
            let hiding = engine::hide::Hiding::with_looks(scene.skeleton(), &objects, |k| {
                looks.get(k as usize).copied().unwrap_or_default()
            });
            assert_eq!(hiding.nodes().len(), scene.skeleton().nodes.len());
        }
        let _ = scene.read_walk_bytes();
        let source = scene.source().clone();
        if let Ok(Some(mut map)) = engine::walk::WalkMap::open(source, 1 << 16) {
            walk_across(&scene, &mut map);
        }
    }
});

/// A walker dropped at the scene's centre walks across it.
fn walk_across(scene: &SceneFile<MemSource>, map: &mut engine::walk::WalkMap<MemSource>) {
    let root = &scene.skeleton().nodes[0];
    let (lo, hi) = (glam::Vec3::from(root.bbox_min), glam::Vec3::from(root.bbox_max));
    let body = engine::walk::Body::default();
    let Ok(mut w) = engine::walk::Walker::from_eye(body, map, (lo + hi) * 0.5) else {
        return;
    };
    let d = glam::Vec2::new(hi.x - lo.x, hi.z - lo.z).clamp_length_max(20.0) / 60.0;
    for _ in 0..60 {
        if w.step(map, d, 1.0 / 30.0).is_err() {
            return;
        }
    }
}
