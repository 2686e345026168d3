//! Lookahead: P_I also classifies the fronts of the viewpoints the camera's
//! motion reaches in a few frames.
//!
//! Most of the bytes a walkthrough fetches for the first time are LOD
//! switches of approaching objects, mostly reps that were not even in the
//! previous frame's all-around front (`hlod-bench --bounds` measures it;
//! figures in docs/results.md). The binned priority serves the children of
//! every front rep whose projected error is near ε, approaching or not; the
//! position extrapolated from the last two fetch commands says which ones
//! the motion will switch: the all-around fronts of the positions a few
//! frames ahead hold most of them. The viewpoint is extrapolated from the
//! last two fetch commands, in position and in rotation (a pan goes on
//! turning).
//!
//! On a slow disk P_I reads only a few reps a frame, so the order is what
//! counts. P_I computes the view fronts (F_R, no margin) of each of the
//! `lookahead_frames` viewpoints ahead and serves their reps by the frame
//! that first draws them, nearest first; then the F_I fronts of the
//! viewpoints `lookahead_frames / 3` and `lookahead_frames` ahead; each
//! group in the order of the angle to the line of sight, all before the
//! bins. A fetch command waiting after P_I has computed these fronts for a
//! millisecond stops it there (on a 250K-node skeleton they take several).
//! (Served by angle alone, a large object beside the path, whose box
//! centre is far off the line of sight, came after hundreds of F_I reps
//! that the view would not reach for seconds, and was missed.) The resident
//! reps are touched so that no prefetch evicts them.

use glam::{Quat, Vec3};

use super::Loader;
use crate::camera::View;
use crate::skeleton::RepId;

/// How long P_I plans the lookahead before a waiting fetch command stops it.
const PLAN_BUDGET_S: f64 = 1e-3;

impl Loader {
    /// Plans the lookahead reads for `view` (F_I widened by `margin` rad).
    pub(super) fn plan_ahead(&mut self, view: &View, margin: f32) {
        self.ahead.clear();
        let k = self.params.prefetch.lookahead_frames;
        let v = if self.motion.is_finite() {
            self.motion
        } else {
            Vec3::ZERO
        };
        if k == 0 || (v.length_squared() == 0.0 && self.spin.to_axis_angle().1 == 0.0) {
            return;
        }
        let Some(own) = self.class_frustum else {
            return;
        };
        let started = self.clock.now();
        let mut front = std::mem::take(&mut self.scratch_ahead);
        let mut keyed: Vec<(u32, u32, RepId)> = Vec::new();
        // First the view fronts (F_R) of each frame ahead, nearest first:
        // what the motion will draw next; then F_I's fronts at two horizons.
        let mut passes: Vec<(u32, f32)> = (1..=k).map(|f| (f, 0.0)).collect();
        passes.push(((k / 3).max(1), margin));
        if k > (k / 3).max(1) {
            passes.push((k, margin));
        }
        for (stage, &(frames, m)) in passes.iter().enumerate() {
            // A waiting fetch command comes first once the plan has taken
            // a millisecond: the fronts computed so far do.
            if stage > 0
                && (self.clock.now() - started).as_secs_f64() > PLAN_BUDGET_S
                && (self.pending.is_some() || self.preempted())
            {
                break;
            }
            let mut ahead = *view;
            ahead.pose.position += v * frames as f32;
            ahead.pose.rotation = spin_ahead(self.spin, frames) * view.pose.rotation;
            let f = ahead.frustum(m);
            self.index
                .compute(&ahead, &f, self.params.tolerance_px, &mut front);
            for &r in &front {
                if self.failed[r as usize] {
                    continue;
                }
                if self.res.contains(r) {
                    self.res.access(r);
                    continue;
                }
                self.queued[r as usize] = self.class_gen;
                let (mn, mx) = self.index.node_box(self.skeleton.reps[r as usize].node);
                let angle = own.angle_to_box(mn, mx);
                keyed.push((stage as u32, angle.to_bits(), r));
            }
        }
        // Angles are non-negative: their bits order as the values do. A rep
        // in both fronts keeps its place in the nearer one.
        keyed.sort_unstable_by_key(|&(h, a, r)| (r, h, a));
        keyed.dedup_by_key(|x| x.2);
        keyed.sort_unstable();
        self.ahead.reps.extend(keyed.into_iter().map(|(_, _, r)| r));
        self.scratch_ahead = front;
    }
}

/// The rotation `spin` (per frame) continued for `frames` frames, at most
/// half a turn.
fn spin_ahead(spin: Quat, frames: u32) -> Quat {
    let (axis, angle) = spin.to_axis_angle();
    if !angle.is_finite() || angle == 0.0 {
        return Quat::IDENTITY;
    }
    Quat::from_axis_angle(axis, (angle * frames as f32).min(std::f32::consts::PI))
}

/// The camera's rotation per frame: from the previous rotation to `now`
/// (world frame: `spin * prev = now`).
pub(super) fn spin(prev: Option<Quat>, now: Quat) -> Quat {
    let q = prev.map_or(Quat::IDENTITY, |p| (now * p.inverse()).normalize());
    // The short way round.
    if q.w < 0.0 { -q } else { q }
}

/// The camera's motion per frame: from the previous position to `now`.
pub(super) fn motion(prev: Option<Vec3>, now: Vec3) -> Vec3 {
    prev.map_or(Vec3::ZERO, |p| now - p)
}
