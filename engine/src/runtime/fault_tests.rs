//! Fault injection through the I/O trait: the scene file truncated,
//! overwritten or replaced under a running walk, a disk that starts
//! failing (EIO), reads slower than the stall deadline. Each walk goes on
//! to its end without a panic or a hang, reports the failed reads, draws
//! every front rep as itself or a resident ancestor, and keeps the
//! footprint within the budget on every frame.

use std::sync::Arc;
use std::time::Duration;

use super::tests::{check_frames, params, pose, start, start_throttled, wide};
use super::*;
use crate::disk::{FaultySource, SwitchingSource};
use crate::io::MemSource;
use crate::render::NoneRenderer;

/// A walk forward through the wide scene and back, turning.
fn poses() -> Vec<Pose> {
    (0..160)
        .map(|i| {
            let t = i as f32 / 160.0;
            pose(
                2.0 + 40.0 * t,
                0.5,
                0.5 + 3.0 * (t * 9.0).sin(),
                (i % 40) as f32 * 0.08,
            )
        })
        .collect()
}

fn bytes_of(src: &Arc<dyn ByteSource>) -> Vec<u8> {
    let mut b = vec![0u8; src.len() as usize];
    src.read_at(0, &mut b).unwrap();
    b
}

/// Walks `src` in each out-of-core mode under a budget a fifth of the
/// data; returns the frames of each walk, checked frame by frame.
fn walk_all(skel: &Arc<Skeleton>, src: impl Fn() -> Arc<dyn ByteSource>) -> Vec<Vec<FrameMetrics>> {
    let total: u64 = skel.reps.iter().map(|r| u64::from(r.len)).sum();
    let budget = total / 5;
    [Mode::NoPre, Mode::Pre]
        .into_iter()
        .map(|mode| {
            let mut walk = start(skel.clone(), src(), params(mode, budget)).unwrap();
            let frames = run_path(&mut walk, &poses(), &mut NoneRenderer::new(0.0), 0.0).unwrap();
            check_frames(&frames, budget);
            frames
        })
        .collect()
}

fn errors(frames: &[FrameMetrics]) -> u32 {
    frames.iter().map(|f| f.loader.read_errors).sum()
}

#[test]
fn a_scene_truncated_mid_run_degrades_to_what_is_resident() {
    let (skel, mem) = wide(64);
    let bytes = bytes_of(&mem);
    let cut = bytes.len() / 3;
    for frames in walk_all(&skel, || {
        Arc::new(SwitchingSource::new(
            MemSource::new(bytes.clone()),
            MemSource::new(bytes[..cut].to_vec()),
            12,
        ))
    }) {
        assert!(errors(&frames) > 0, "reads past the new end fail");
        assert!(frames.iter().any(|f| f.substituted > 0));
    }
}

#[test]
fn a_scene_overwritten_mid_run_is_caught_by_the_rep_checksums() {
    let (skel, mem) = wide(64);
    let bytes = bytes_of(&mem);
    // The same length, every rep byte changed (the header and skeleton stay).
    let mut other = bytes.clone();
    for b in &mut other[4096..] {
        *b ^= 0x5a;
    }
    for frames in walk_all(&skel, || {
        Arc::new(SwitchingSource::new(
            MemSource::new(bytes.clone()),
            MemSource::new(other.clone()),
            12,
        ))
    }) {
        assert!(errors(&frames) > 0, "checksum failures are read errors");
    }
}

#[test]
fn a_scene_replaced_by_another_mid_run_never_mixes_them() {
    let (skel, mem) = wide(64);
    let (_, other) = wide(32);
    let bytes = bytes_of(&mem);
    let other = bytes_of(&other);
    for frames in walk_all(&skel, || {
        Arc::new(SwitchingSource::new(
            MemSource::new(bytes.clone()),
            MemSource::new(other.clone()),
            12,
        ))
    }) {
        // Every rep read after the switch is the other scene's and fails
        // its record's checksum: it is drawn as a resident ancestor (of
        // the first scene), never as the other scene's bytes.
        assert!(errors(&frames) > 0);
        assert!(frames[40..].iter().any(|f| f.substituted > 0));
    }
}

#[test]
fn eio_on_every_read_from_some_point_on_is_reported_and_the_walk_goes_on() {
    let (skel, mem) = wide(64);
    let bytes = bytes_of(&mem);
    let n = bytes.len() as u64;
    for frames in walk_all(&skel, || {
        Arc::new(SwitchingSource::new(
            MemSource::new(bytes.clone()),
            FaultySource::new(MemSource::new(bytes.clone()), vec![(0, n)]),
            20,
        ))
    }) {
        assert!(errors(&frames) > 0);
        assert_eq!(frames.len(), poses().len(), "every frame was drawn");
    }
}

#[test]
fn reads_far_slower_than_the_stall_deadline_hold_no_frame_past_one_read() {
    let (skel, mem) = wide(64);
    let total: u64 = skel.reps.iter().map(|r| u64::from(r.len)).sum();
    // 30 ms a seek against a 2 ms deadline.
    let p = RuntimeParams {
        frame_period_s: 0.04,
        stall_deadline_s: 0.002,
        ..params(Mode::Pre, total / 5)
    };
    let disk = (Duration::from_millis(30), 20e6);
    let mut walk = start_throttled(skel, &mem, disk, p).unwrap();
    let path = poses();
    let frames = run_path(&mut walk, &path[..60], &mut NoneRenderer::new(0.0), 25.0).unwrap();
    check_frames(&frames, total / 5);
    assert!(frames.iter().map(|f| f.loader.late_reps).sum::<u32>() > 0);
    // A frame waits at most for a read already under way (one seek and a
    // rep), never for the reps that are late.
    let worst = frames[1..].iter().map(|f| f.wait_ms).fold(0.0, f64::max);
    assert!(worst < 150.0, "a frame waited {worst} ms");
}
