//! Scenes at the edges: one node, one triangle, the smallest budget.

use super::tests::{check_frames, params, pose, scene};
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
            let mut walk =
                Walkthrough::start(skel.clone(), src.clone(), params(mode, budget)).unwrap();
            let n = frames_to_complete(&mut walk, budget, 500);
            assert!(n.is_some(), "{mode:?} at {budget} B never completes");
        }
    }
}
