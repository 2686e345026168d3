//! The scene-file reader: header, skeleton, `validate()`, every rep
//! decoded, the object section, and a pick through the scene. Inputs of
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
        }
    }
});
