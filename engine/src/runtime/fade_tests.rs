//! Smooth LOD switches in the runtime: both reps of a switch drawn with
//! complementary dithers, the footprint counting both, every fade ending.

use std::sync::Arc;
use std::time::Duration;

use super::tests::{check_frames, params, pose, wide};
use super::*;
use crate::clock::ManualClock;
use crate::format::RepRecord;
use crate::render::{DrawStyle, Fade};

/// Records each frame's draws.
#[derive(Default)]
struct Recorder {
    frames: Vec<Vec<(RepId, DrawStyle)>>,
}

impl Renderer for Recorder {
    fn begin_frame(&mut self, _view: &View) {
        self.frames.push(Vec::new());
    }
    fn draw(&mut self, rep: RepId, _rec: &RepRecord, _payload: &Arc<[u8]>, style: DrawStyle) {
        if let Some(f) = self.frames.last_mut() {
            f.push((rep, style));
        }
    }
    fn end_frame(&mut self) {}
    fn name(&self) -> &'static str {
        "recorder"
    }
}

/// An approach along the row of leaves and back (LOD and HLOD switches
/// both ways), then a still camera; the clock moves a 30 Hz period a frame.
fn walk(mode: Mode, budget: u64, fade_s: f32) -> (Vec<FrameMetrics>, Recorder) {
    let (skel, src) = wide(64);
    let clock = Arc::new(ManualClock::new());
    let p = RuntimeParams {
        fade_s,
        ..params(mode, budget)
    };
    let mut w = Walkthrough::start_with_clock(skel, src, p, clock.clone()).unwrap();
    // Along the row at one leaf a frame: leaves refine as the camera comes
    // within 16 and then 8 leaves of them, and coarsen behind it.
    let along = std::f32::consts::FRAC_PI_2;
    let mut poses: Vec<Pose> = (0..60)
        .map(|i| pose(70.0 - i as f32, 0.5, 0.5, along))
        .collect();
    let back: Vec<Pose> = poses.iter().rev().copied().collect();
    poses.extend(back);
    let still = *poses.last().unwrap();
    poses.extend(std::iter::repeat_n(still, 20));
    let mut rec = Recorder::default();
    let mut frames = Vec::new();
    for p in &poses {
        frames.push(w.frame(p, &mut rec).unwrap());
        clock.advance(Duration::from_secs_f64(1.0 / 30.0));
    }
    (frames, rec)
}

#[test]
fn a_switch_draws_both_reps_with_complementary_dithers_and_every_fade_ends() {
    let (skel, _) = wide(64);
    let total: u64 = skel.reps.iter().map(|r| r.resident_len()).sum();
    for (mode, budget) in [
        (Mode::Incore, total),
        (Mode::NoPre, total / 3),
        (Mode::Pre, total / 3),
    ] {
        let (frames, rec) = walk(mode, budget, 0.2);
        if mode != Mode::Incore {
            check_frames(&frames, budget);
        }
        let (ins, outs): (u32, u32) = frames
            .iter()
            .fold((0, 0), |(a, b), f| (a + f.fade_in, b + f.fade_out));
        assert!(ins > 20 && outs > 20, "{mode:?}: {ins} in, {outs} out");
        for (k, draws) in rec.frames.iter().enumerate() {
            for (r, s) in draws {
                // A rep fading in has a partner fading out by the same t.
                if let Fade::In(t) = s.fade {
                    assert!(
                        draws.iter().any(|(_, o)| o.fade == Fade::Out(t)),
                        "{mode:?} frame {k}: rep {r} fades in by {t} alone"
                    );
                }
                // What fades out is resident and not the front's.
                assert!(!(s.substitute && s.fade != Fade::Opaque));
            }
            assert_eq!(
                draws.iter().filter(|(_, s)| s.fade != Fade::Opaque).count() as u32,
                frames[k].fade_in + frames[k].fade_out
            );
        }
        // Still camera: 0.2 s is six frames; the last frames are opaque.
        for f in &frames[frames.len() - 10..] {
            assert_eq!(
                (f.fade_in, f.fade_out),
                (0, 0),
                "{mode:?} frame {}",
                f.frame
            );
        }
    }
}

#[test]
fn fades_change_no_front_and_off_draws_nothing_faded() {
    let (skel, _) = wide(64);
    let total: u64 = skel.reps.iter().map(|r| r.resident_len()).sum();
    let (on, rec_on) = walk(Mode::Incore, total, 0.2);
    let (off, rec_off) = walk(Mode::Incore, total, 0.0);
    for (k, (a, b)) in on.iter().zip(&off).enumerate() {
        assert_eq!(a.front_reps, b.front_reps);
        assert_eq!(a.drawn_reps, b.drawn_reps);
        // The reps drawn not fading out are the ones drawn without fades.
        let shown = |d: &Vec<(RepId, DrawStyle)>| {
            let mut v: Vec<RepId> = d
                .iter()
                .filter(|(_, s)| !matches!(s.fade, Fade::Out(_)))
                .map(|(r, _)| *r)
                .collect();
            v.sort_unstable();
            v
        };
        assert_eq!(shown(&rec_on.frames[k]), shown(&rec_off.frames[k]));
        assert_eq!((b.fade_in, b.fade_out), (0, 0));
    }
}

#[test]
fn a_fade_takes_no_room_the_front_needs() {
    // A footprint the fronts of the walk just fit: fades may only use what
    // the front leaves, so they add no substitute.
    let (skel, _) = wide(64);
    let root = skel.reps[0].resident_len();
    let (frames, _) = walk(Mode::Incore, u64::MAX, 0.0);
    let widest = frames.iter().map(|f| f.front_bytes).max().unwrap();
    let budget = widest + root;
    let subs = |fade_s| {
        let (frames, _) = walk(Mode::NoPre, budget, fade_s);
        check_frames(&frames, budget);
        let fades: u32 = frames.iter().map(|f| f.fade_in + f.fade_out).sum();
        (frames.iter().filter(|f| f.substituted > 0).count(), fades)
    };
    let (without, _) = subs(0.0);
    let (with, fades) = subs(0.2);
    assert!(fades > 0, "no fade at all");
    assert!(
        with <= without,
        "{with} frames with substitutes with fades, {without} without"
    );
}
