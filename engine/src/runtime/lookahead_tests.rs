//! The lookahead on P_I: what the camera's motion foresees, walked on a
//! clock that moves on as it is read (so that P_I's classification is timed).

use std::sync::Arc;

use super::tests::{check_frames, params, pose, wide};
use super::*;
use crate::camera::Pose;
use crate::render::NoneRenderer;

/// A manual clock that also moves on 1 µs each time it is read.
#[derive(Debug, Default)]
struct Ticking(crate::clock::ManualClock);

impl crate::clock::Clock for Ticking {
    fn now(&self) -> std::time::Instant {
        self.0.advance(std::time::Duration::from_micros(1));
        self.0.now()
    }

    fn sleep_until(&self, t: std::time::Instant) {
        self.0.sleep_until(t);
    }

    fn is_simulated(&self) -> bool {
        true
    }
}

/// Walks `poses` through `wide(64)` with F_I as F_R and no PAR/CHD, so
/// that only the lookahead (over `lookahead_frames`) foresees what a frame
/// will draw; checks the budget and returns the frames.
fn lookahead_walk(poses: &[Pose], lookahead_frames: u32) -> Vec<FrameMetrics> {
    let (skel, src) = wide(64);
    let total: u64 = skel.reps.iter().map(|r| u64::from(r.len)).sum();
    let p = RuntimeParams {
        frame_period_s: 0.05,
        prefetch: PrefetchParams {
            depth: 0,
            margin_deg: 0.0,
            max_margin_deg: 0.0,
            all_around_fit: 0.0,
            lookahead_frames,
            ..PrefetchParams::default()
        },
        ..params(Mode::Pre, total)
    };
    // Work that reads the clock takes time on it: P_I's classification is
    // timed.
    let mut walk =
        Walkthrough::start_with_clock(skel, src, p, Arc::new(Ticking::default())).unwrap();
    let frames = run_path(&mut walk, poses, &mut NoneRenderer::new(0.0), 20.0).unwrap();
    check_frames(&frames, total);
    frames
}

#[test]
fn the_lookahead_prefetches_the_lod_switches_of_an_approach() {
    // Along the row of leaves at one leaf a frame: each leaf switches to a
    // finer LOD as the camera comes within 16 and then 8 leaves of it.
    let along = std::f32::consts::FRAC_PI_2;
    let poses: Vec<Pose> = (0..50)
        .map(|i| pose(100.0 - i as f32, 0.5, 0.5, along))
        .collect();
    // The motion is known from the second fetch command on.
    let run = |k| -> u32 {
        lookahead_walk(&poses, k)[3..]
            .iter()
            .map(|f| f.loader.miss_lod)
            .sum()
    };
    let without = run(0);
    assert!(
        without > 10,
        "{without} LOD switches missed without lookahead"
    );
    assert_eq!(run(10), 0, "the lookahead missed a switch");
}

#[test]
fn the_lookahead_follows_a_pan_and_prefetches_what_turns_into_view() {
    // In the middle of the row, turning round at 6° a frame: each frame
    // brings leaves into view that were behind the camera.
    let poses: Vec<Pose> = (0..40)
        .map(|i| pose(32.0, 0.5, 0.5, (i as f32 * 6.0).to_radians()))
        .collect();
    let run = |k| -> u32 {
        let frames = lookahead_walk(&poses, k);
        // P_I's classification is timed.
        assert!(frames.iter().any(|f| f.loader.classify_ms > 0.0));
        // The rotation is known from the second fetch command on.
        frames[3..].iter().map(|f| f.loader.miss_new).sum()
    };
    let without = run(0);
    assert!(without > 10, "{without} reps turned into view unprefetched");
    assert_eq!(run(10), 0, "the lookahead missed what the turn showed");
}
