//! Scenes at the edges: one node, one triangle, the smallest budget.

use super::tests::{check_frames, params, pose, scene, start};
use super::*;
use crate::render::NoneRenderer;

/// Frames from close up until the front is drawn without substitutes (at
/// most `max` frames); how many it took.
fn frames_to_complete(walk: &mut Walkthrough, budget: u64, max: usize) -> Option<usize> {
    let mut r = NoneRenderer::new(0.0);
    for i in 0..max {
        let f = walk.frame(&pose(0.5, 0.5, 0.3, 0.0), &mut r).unwrap();
        check_frames(std::slice::from_ref(&f), budget);
        if f.substituted == 0 && i > 0 {
            return Some(i);
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    None
}

#[test]
fn a_one_node_scene_completes_in_every_mode() {
    let (skel, src) = scene(&[3], &[0]);
    let total: u64 = skel.reps.iter().map(|r| r.resident_len()).sum();
    for mode in [Mode::NoPre, Mode::Pre] {
        for budget in [total, 10 * total] {
            let mut walk = start(skel.clone(), src.clone(), params(mode, budget)).unwrap();
            let n = frames_to_complete(&mut walk, budget, 500);
            assert!(n.is_some(), "{mode:?} at {budget} B never completes");
        }
    }
}

#[test]
fn the_full_detail_footprint_is_enough_and_one_byte_less_is_said() {
    use crate::SceneFile;
    use crate::io::MemSource;
    let built = [
        crate::testutil::build(&[1], &[0]),
        crate::testutil::build_compressed(&[1], &[0]),
        crate::testutil::build(&[3], &[0]),
        crate::testutil::build_compressed(&[3], &[0]),
        crate::testutil::build_compressed(&[2, 3, 3], &[2, 0, 0]),
    ];
    for (k, (bytes, _)) in built.into_iter().enumerate() {
        let file = SceneFile::from_source(MemSource::new(bytes.clone())).unwrap();
        let skel = Arc::new(file.skeleton().clone());
        let src: Arc<dyn ByteSource> = Arc::new(MemSource::new(bytes));
        let need = skel.full_detail_bytes();
        assert!(need <= skel.in_core_bytes(), "scene {k}: 100% is enough");
        if skel.reps.len() == 1 {
            // One rep: the root's own load, nothing beside it.
            let r = &skel.reps[0];
            assert_eq!(need, r.expanded_extent() + r.load_scratch(), "scene {k}");
        }
        for mode in [Mode::NoPre, Mode::Pre] {
            let mut walk = start(skel.clone(), src.clone(), params(mode, need)).unwrap();
            assert_eq!(walk.full_detail_need(), None);
            assert!(
                frames_to_complete(&mut walk, need, 500).is_some(),
                "scene {k}, {mode:?}: completes at {need} B"
            );
            // One byte less: said, before any frame (the walk still runs
            // when the root fits).
            let root = &skel.reps[0];
            if need > root.expanded_extent() + root.load_scratch() {
                let walk = start(skel.clone(), src.clone(), params(mode, need - 1)).unwrap();
                assert_eq!(walk.full_detail_need(), Some(need), "scene {k}");
            }
        }
    }
}
