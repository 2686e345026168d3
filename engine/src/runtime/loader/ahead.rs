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
//! counts. P_I computes the view fronts (F_R, no margin) of viewpoints up
//! to `lookahead_frames` ahead (each of the first three frames, then ever
//! sparser: 1, 2, 3, 5, 8, 10 for 10) and serves their reps by the frame
//! that first draws them, nearest first, each front's in file order (the
//! fewest seeks: a sudden turn reveals a thousand reps a frame); then the
//! F_I fronts of the viewpoints `lookahead_frames / 3` and
//! `lookahead_frames` ahead, in the order of the angle to the line of
//! sight, all before the bins. A fetch command waiting after P_I has
//! computed these fronts for a millisecond stops it there (on a 250K-node
//! skeleton they take several).
//! (Served by angle alone, a large object beside the path, whose box
//! centre is far off the line of sight, came after hundreds of F_I reps
//! that the view would not reach for seconds, and was missed.) The resident
//! reps are touched so that no prefetch evicts them, except, with
//! occlusion culling on, those only in F_I's fronts ahead. Those fronts are
//! not culled (outside the view nothing can test them), so on an interior
//! walk they hold the rooms all around, 10-30 times the reps a culled front
//! draws; protected, they filled the footprint and a door's newly visible
//! reps found no room. Left untouched they keep their place in the list,
//! and a prefetch may take their room. (Without culling, F_I's fronts are
//! what a turn draws: left untouched there, they churned, and Stage II
//! grew on the DE-size plant. Figures in docs/results.md.) What is touched
//! never exceeds the reps' room for prefetching: the view fronts ahead
//! count first, resident or not, and F_I's resident reps are touched only
//! while they fit beside them. (Touched past the room — F_I's all-around
//! fronts of a dense stretch — they left no rep a prefetch could evict,
//! and the view fronts' reps were refused for room.)

use glam::{Quat, Vec3};

use super::classify::Classifier;
use super::order::ReadQueue;
use super::plan::Plan;
use crate::camera::{Pose, View};
use crate::clock::Clock;
use crate::runtime::resident::ResidentSet;
use crate::skeleton::RepId;

/// How long P_I plans the lookahead before a waiting fetch command stops it.
const PLAN_BUDGET_S: f64 = 1e-3;

/// The camera's motion, and the reps of the fronts it reaches next.
#[derive(Debug)]
pub(super) struct Lookahead {
    /// The camera's motion per frame, and its last position.
    motion: Vec3,
    last_pos: Option<Vec3>,
    /// The camera's rotation per frame, and its last rotation.
    spin: Quat,
    last_rot: Option<Quat>,
    /// The reps of the fronts ahead, in service order.
    pub(super) queue: ReadQueue,
    front: Vec<RepId>,
    /// The plan that last counted each rep's bytes (a rep in several fronts
    /// counts once), and this plan's stamp.
    counted: Vec<u32>,
    stamp: u32,
}

impl Default for Lookahead {
    fn default() -> Self {
        Self {
            motion: Vec3::ZERO,
            last_pos: None,
            spin: Quat::IDENTITY,
            last_rot: None,
            queue: ReadQueue::default(),
            front: Vec::new(),
            counted: Vec::new(),
            stamp: 0,
        }
    }
}

impl Lookahead {
    /// A fetch command's pose: the motion and rotation per frame since the
    /// last one.
    pub(super) fn observe(&mut self, pose: &Pose) {
        self.motion = motion(self.last_pos, pose.position);
        self.last_pos = Some(pose.position);
        self.spin = spin(self.last_rot, pose.rotation);
        self.last_rot = Some(pose.rotation);
    }

    /// Plans the lookahead reads for `view` (F_I widened by `margin` rad):
    /// the reps not resident become candidates of `classes`, the resident
    /// ones are touched. Once the plan has taken
    /// [`PLAN_BUDGET_S`], `stop` says whether a fetch command waits.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn plan(
        &mut self,
        plan: &Plan,
        res: &mut ResidentSet,
        failed: &[bool],
        classes: &mut Classifier,
        view: &View,
        margin: f32,
        clock: &dyn Clock,
        stop: &mut dyn FnMut() -> bool,
    ) {
        self.queue.clear();
        let k = plan.params.prefetch.lookahead_frames;
        let v = if self.motion.is_finite() {
            self.motion
        } else {
            Vec3::ZERO
        };
        if k == 0 || (v.length_squared() == 0.0 && self.spin.to_axis_angle().1 == 0.0) {
            return;
        }
        let Some(own) = classes.own_frustum() else {
            return;
        };
        let started = clock.now();
        // With occlusion culling, F_I's fronts ahead (not culled: outside
        // the view nothing tests them) overstate what turning would draw.
        let protect_f_i = plan.params.occlusion_bytes == 0;
        let mut front = std::mem::take(&mut self.front);
        let mut keyed: Vec<(u32, u64, RepId)> = Vec::new();
        // The bytes the fronts ahead keep (touched) or want (queued view
        // front reps), each rep once.
        self.counted.resize(plan.skeleton.reps.len(), 0);
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.counted.fill(0);
            self.stamp = 1;
        }
        let mut kept = 0u64;
        // First the view fronts (F_R) of each frame ahead, nearest first:
        // what the motion will draw next; then F_I's fronts at two horizons.
        let mut passes: Vec<(u32, f32)> = view_horizons(k).map(|f| (f, 0.0)).collect();
        passes.push(((k / 3).max(1), margin));
        if k > (k / 3).max(1) {
            passes.push((k, margin));
        }
        for (stage, &(frames, m)) in passes.iter().enumerate() {
            // A waiting fetch command comes first once the plan has taken
            // a millisecond: the fronts computed so far do.
            if stage > 0
                && clock.now().saturating_duration_since(started).as_secs_f64() > PLAN_BUDGET_S
                && stop()
            {
                break;
            }
            let mut ahead = *view;
            ahead.pose.position += v * frames as f32;
            ahead.pose.rotation = spin_ahead(self.spin, frames) * view.pose.rotation;
            let f = ahead.frustum(m);
            plan.index
                .compute(&ahead, &f, plan.params.tolerance_px, &mut front);
            for &r in &front {
                if failed[r as usize] {
                    continue;
                }
                let new = self.counted[r as usize] != self.stamp;
                if res.contains(r) {
                    if new && (m == 0.0 || (protect_f_i && kept + res.cost(r) <= plan.room)) {
                        self.counted[r as usize] = self.stamp;
                        kept += res.cost(r);
                        res.access(r);
                    }
                    continue;
                }
                if m == 0.0 && new {
                    self.counted[r as usize] = self.stamp;
                    kept += res.cost(r);
                }
                // Hidden now, or when last in the view (behind a wall): after
                // every rep the motion will see, in the same horizon order,
                // since a door ahead may show it.
                let stage = if classes.is_hidden(r) {
                    stage + passes.len()
                } else {
                    stage
                };
                classes.queue(r);
                let rec = &plan.skeleton.reps[r as usize];
                let key = if m == 0.0 {
                    // A view front's reps are all drawn by its frame: in
                    // file order they are read with the fewest seeks.
                    rec.offset
                } else {
                    let (mn, mx) = plan.index.node_box(rec.node);
                    u64::from(own.angle_to_box(mn, mx).to_bits())
                };
                keyed.push((stage as u32, key, r));
            }
        }
        // Angles are non-negative: their bits order as the values do. A rep
        // in both fronts keeps its place in the nearer one.
        keyed.sort_unstable_by_key(|&(h, a, r)| (r, h, a));
        keyed.dedup_by_key(|x| x.2);
        keyed.sort_unstable();
        self.queue.reps.extend(keyed.into_iter().map(|(_, _, r)| r));
        self.front = front;
    }
}

/// The frames ahead whose view fronts are computed, up to `k`: every one
/// of the first three, then each half as far again as the last (1, 2, 3,
/// 5, 8, 12, …), and `k`. A rep first drawn between two of them is in the
/// later one's front (a front changes little from one frame to the next),
/// and the fronts far ahead cost as much as the near ones.
fn view_horizons(k: u32) -> impl Iterator<Item = u32> {
    let mut next = 1;
    std::iter::from_fn(move || {
        if next > k {
            return None;
        }
        let f = next;
        next = if f == k {
            k + 1
        } else {
            (f + f.div_ceil(2)).min(k)
        };
        Some(f)
    })
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
fn spin(prev: Option<Quat>, now: Quat) -> Quat {
    let q = prev.map_or(Quat::IDENTITY, |p| (now * p.inverse()).normalize());
    // The short way round.
    if q.w < 0.0 { -q } else { q }
}

/// The camera's motion per frame: from the previous position to `now`.
fn motion(prev: Option<Vec3>, now: Vec3) -> Vec3 {
    prev.map_or(Vec3::ZERO, |p| now - p)
}

#[cfg(test)]
mod tests {
    use super::view_horizons;

    #[test]
    fn view_horizons_thin_out_with_distance_and_end_at_k() {
        let h = |k| view_horizons(k).collect::<Vec<_>>();
        assert_eq!(h(10), [1, 2, 3, 5, 8, 10]);
        assert_eq!(h(3), [1, 2, 3]);
        assert_eq!(h(1), [1]);
        assert!(h(0).is_empty());
        assert_eq!(h(40), [1, 2, 3, 5, 8, 12, 18, 27, 40]);
    }
}
