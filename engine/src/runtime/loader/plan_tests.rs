//! The read planners without a thread, a channel or a byte source: CLASSIFY
//! and the lookahead on a row of parts, with the time from a test clock.

use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use glam::Vec3;

use super::Plan;
use super::ahead::Lookahead;
use super::classify::Classifier;
use crate::camera::Pose;
use crate::clock::{Clock, ManualClock};
use crate::front::FrontIndex;
use crate::prefetch::Bins;
use crate::runtime::RuntimeParams;
use crate::runtime::resident::{Purpose, ResidentSet};
use crate::skeleton::{RepId, Skeleton};
use crate::testutil::build;

/// A root over 24 unit parts in a row along x (reps 1..=24; rep k spans
/// x in [k-1, k]).
fn row() -> Skeleton {
    let mut reps = vec![1u32; 25];
    reps[0] = 1;
    let mut children = vec![0u32; 25];
    children[0] = 24;
    build(&reps, &children).1
}

/// A narrow view of the row from above, at `x`.
fn pose_at(x: f32) -> Pose {
    Pose::look_at(Vec3::new(x, 0.5, 3.0), Vec3::new(x, 0.5, 0.0), 20.0)
}

fn params() -> RuntimeParams {
    let mut p = RuntimeParams::default();
    // No all-around front: F_I is the view widened by the margin.
    p.prefetch.all_around_fit = 0.0;
    p.prefetch.margin_deg = 10.0;
    p.prefetch.lookahead_frames = 6;
    p
}

fn setup(s: &Skeleton, p: &RuntimeParams) -> (FrontIndex, ResidentSet, Classifier) {
    let index = FrontIndex::new(s);
    let res = ResidentSet::new(s.reps.iter().map(|r| u64::from(r.len)).collect());
    let bins = Bins::new(p.prefetch.bins, 4.0 * p.tolerance_px, p.tolerance_px);
    (index, res, Classifier::new(s.reps.len(), bins))
}

/// The x the parts of `reps` start at.
fn xs(s: &Skeleton, reps: &[RepId]) -> Vec<i32> {
    reps.iter()
        .map(|&r| s.reps[r as usize].bbox_min[0] as i32)
        .collect()
}

/// A lookahead that saw the camera move along +x by one part a frame, up
/// to x = 5; the view there, classified by `c`, and F_I's margin.
fn moving_to_5(
    plan: &Plan,
    res: &ResidentSet,
    c: &mut Classifier,
) -> (Lookahead, crate::camera::View, f32) {
    let mut ahead = Lookahead::default();
    ahead.observe(&pose_at(4.0));
    ahead.observe(&pose_at(5.0));
    let view = plan.params.view(&pose_at(5.0));
    let (_, margin) = c
        .classify_front(plan, res, &view, 0.0, &mut || false)
        .unwrap();
    (ahead, view, margin)
}

/// Rep `r` of `s` loaded into `res` (reserved, then inserted).
fn make_resident(s: &Skeleton, res: &mut ResidentSet, r: RepId) {
    res.reserve(res.cost(r));
    res.insert(r, vec![0u8; s.reps[r as usize].len as usize].into(), false);
}

#[test]
fn classify_bins_the_enlarged_front_once_per_viewpoint() {
    let (s, p) = (row(), params());
    let (index, res, mut c) = setup(&s, &p);
    let plan = Plan::of(&s, &index, &p);
    let view = p.view(&pose_at(12.0));
    let (front, margin) = c
        .classify_front(&plan, &res, &view, 0.0, &mut || false)
        .unwrap();
    let front = front.to_vec();
    assert!((margin - 10f32.to_radians()).abs() < 1e-6);
    let x = xs(&s, &front);
    assert!(
        x.contains(&12) && !x.contains(&0) && !x.contains(&23),
        "{x:?}"
    );
    assert_eq!(c.bins.len(), front.len());
    assert!(front.iter().all(|&r| c.is_queued(r)));
    // The same viewpoint again: nothing is reclassified.
    assert!(
        c.classify_front(&plan, &res, &view, 0.0, &mut || false)
            .is_none()
    );
    // Front reps come out first (their priority is capped at δ).
    let (first, depth) = c.bins.pop().unwrap();
    assert!(front.contains(&first) && depth == 0);
    // Its parent (the root) is classified when it is served, but its error
    // projects far above δ here: not a candidate.
    let before = c.bins.len();
    c.classify_neighbours(&plan, first, depth);
    assert!(!c.is_queued(0) && c.bins.len() == before);
    // A new viewpoint: a new generation; the old candidates are recent.
    let moved = p.view(&pose_at(4.0));
    assert!(
        c.classify_front(&plan, &res, &moved, 0.0, &mut || false)
            .is_some()
    );
    assert!(!c.is_queued(first) && c.is_recent(first));
}

#[test]
fn a_waiting_command_cuts_the_classification_short_and_it_is_redone() {
    let s = row();
    let mut p = params();
    p.prefetch.all_around_fit = 1.0;
    p.budget_bytes = u64::MAX / 4; // the all-around front fits
    let (index, res, mut c) = setup(&s, &p);
    let plan = Plan::of(&s, &index, &p);
    let view = p.view(&pose_at(12.0));
    let (_, margin) = c
        .classify_front(&plan, &res, &view, 0.0, &mut || true)
        .unwrap();
    assert!(margin < 1.0, "no all-around front while a command waits");
    // The same view again: classified in full this time.
    let (front, margin) = c
        .classify_front(&plan, &res, &view, 0.0, &mut || false)
        .unwrap();
    assert_eq!(margin, std::f32::consts::PI);
    let x = xs(&s, front);
    assert!(x.contains(&0) && x.contains(&23), "{x:?}");
    assert!(
        c.classify_front(&plan, &res, &view, 0.0, &mut || false)
            .is_none()
    );
}

/// A clock that moves by `step` each time it is read.
#[derive(Debug)]
struct Ticking {
    base: Instant,
    reads: AtomicU32,
    step: Duration,
}

impl Clock for Ticking {
    fn now(&self) -> Instant {
        self.base + self.step * self.reads.fetch_add(1, Ordering::Relaxed)
    }

    fn sleep_until(&self, _: Instant) {}
}

#[test]
fn the_lookahead_serves_the_parts_the_motion_reaches_first() {
    let (s, p) = (row(), params());
    let (index, mut res, mut c) = setup(&s, &p);
    let plan = Plan::of(&s, &index, &p);
    let failed = vec![false; s.reps.len()];
    let (mut ahead, view, margin) = moving_to_5(&plan, &res, &mut c);
    let clock = ManualClock::new();
    // Plans `a` for `view` on `clock`; `stop` says a fetch command waits.
    let mut plan_with = |a: &mut Lookahead,
                         res: &mut ResidentSet,
                         clock: &dyn Clock,
                         stop: &mut dyn FnMut() -> bool| {
        a.plan(&plan, res, &failed, &mut c, &view, margin, clock, stop)
    };
    let mut stops = 0;
    plan_with(&mut ahead, &mut res, &clock, &mut || {
        stops += 1;
        true
    });
    assert_eq!(stops, 0, "the clock did not move: the whole plan is made");
    let queued = ahead.queue.reps.clone();
    let x = xs(&s, &queued);
    // Ahead (x > 5) before anything behind, the next frame's first.
    assert!(x.iter().any(|&v| v >= 9), "{x:?}");
    let first_behind = x.iter().position(|&v| v < 4).unwrap_or(x.len());
    assert!(x[..first_behind].iter().all(|&v| v >= 4), "{x:?}");
    // At rest there is nothing ahead.
    let mut still = Lookahead::default();
    still.observe(&pose_at(5.0));
    still.observe(&pose_at(5.0));
    plan_with(&mut still, &mut res, &clock, &mut || true);
    assert!(still.queue.reps.is_empty());
    // A resident part is touched, not queued.
    make_resident(&s, &mut res, queued[0]);
    plan_with(&mut ahead, &mut res, &clock, &mut || true);
    assert!(!ahead.queue.reps.contains(&queued[0]));
    // A clock past the planning budget and a waiting fetch command stop the
    // plan after the first frame ahead.
    let ticking = Ticking {
        base: Instant::now(),
        reads: AtomicU32::new(0),
        step: Duration::from_millis(2),
    };
    plan_with(&mut ahead, &mut res, &ticking, &mut || true);
    let short = ahead.queue.reps.len();
    assert!(
        short > 0 && short < queued.len() - 1,
        "{short} of {}",
        queued.len()
    ); // What the plans queued are candidates of the classification.
    assert!(queued.iter().all(|&r| c.is_queued(r)));
}

#[test]
fn f_i_is_all_around_only_when_the_all_around_front_fits() {
    let s = row();
    let view = |p: &RuntimeParams| p.view(&pose_at(12.0));
    let bytes: u64 = s.reps[1..].iter().map(|r| u64::from(r.len)).sum();
    // A footprint that holds every part: all around the eye.
    let mut p = params();
    p.prefetch.all_around_fit = 1.0;
    p.budget_bytes = bytes * 2;
    let (index, res, mut c) = setup(&s, &p);
    let plan = Plan::of(&s, &index, &p);
    let (front, margin) = c
        .classify_front(&plan, &res, &view(&p), 0.0, &mut || false)
        .unwrap();
    assert_eq!(margin, std::f32::consts::PI);
    assert_eq!(front.len(), 24, "every part");
    // One that holds a few parts: F_I, the view widened by the margin,
    // which is the all-around front restricted to F_I.
    p.budget_bytes = u64::from(s.reps[1].len) * 8;
    let (index, res, mut c) = setup(&s, &p);
    let plan = Plan::of(&s, &index, &p);
    let (front, margin) = c
        .classify_front(&plan, &res, &view(&p), 0.0, &mut || false)
        .unwrap();
    let front = front.to_vec();
    assert!(margin < 1.0 && front.len() < 24, "{margin} {}", front.len());
    let mut all = Vec::new();
    let v = view(&p);
    index.compute(
        &v,
        &v.frustum(std::f32::consts::PI),
        p.tolerance_px,
        &mut all,
    );
    index.restrict(&s, &v.frustum(margin), &mut all);
    assert_eq!(front, all);
}

#[test]
fn f_i_front_reps_are_served_by_angle_whatever_their_error() {
    // Finest reps of error 0 all around the eye, which stands above part
    // 12 and looks along the row towards part 20. By ε(O)·AngPr(O) each
    // would rank 0, last, in the order F_I's front lists them: the parts
    // behind the eye (0..12) first. A finest rep is needed at any distance
    // while in view, so it ranks as a rep at ε, by its angle: the parts
    // ahead come first.
    let mut s = row();
    for r in &mut s.reps[1..] {
        r.error = 0.0;
    }
    let mut p = params();
    p.prefetch.all_around_fit = 1.0;
    p.budget_bytes = s.reps.iter().map(|r| u64::from(r.len)).sum::<u64>() * 2;
    let (index, res, mut c) = setup(&s, &p);
    let plan = Plan::of(&s, &index, &p);
    let pose = Pose::look_at(Vec3::new(12.5, 0.5, 3.0), Vec3::new(20.0, 0.5, 0.0), 20.0);
    let view = p.view(&pose);
    let (front, margin) = c
        .classify_front(&plan, &res, &view, 0.0, &mut || false)
        .unwrap();
    assert_eq!((front.len(), margin), (24, std::f32::consts::PI));
    let mut order = Vec::new();
    while let Some((r, _)) = c.bins.pop() {
        order.push(r);
    }
    let x = xs(&s, &order);
    assert_eq!(x.len(), 24);
    let at = |k: i32| x.iter().position(|&v| v == k).unwrap();
    for ahead in 14..24 {
        for behind in 0..=10 {
            assert!(at(ahead) < at(behind), "{ahead} before {behind}: {x:?}");
        }
    }
}

/// Moving along +x with an all-around F_I (classified with the whole
/// footprint as the reps' room): the part at x = 7 is in the view fronts
/// ahead, the part at x = 1 (behind the eye) only in F_I's fronts ahead.
/// Both are resident, last used before this Stage II; the lookahead plans
/// with occlusion culling on or off and the reps' room `room` (of the
/// resident set), then a prefetch asks for the room of the part behind.
/// Whether it got it, and whether the parts ahead and behind stay.
fn lookahead_then_prefetch(culling: bool, room: impl Fn(&ResidentSet) -> u64) -> [bool; 3] {
    let s = row();
    let (ahead_rep, behind_rep) = (8, 2);
    assert_eq!(xs(&s, &[ahead_rep, behind_rep]), [7, 1]);
    let mut p = params();
    p.prefetch.all_around_fit = 1.0;
    p.budget_bytes = u64::MAX / 4;
    p.occlusion_bytes = if culling { 1 << 20 } else { 0 };
    let (index, mut res, mut c) = setup(&s, &p);
    let plan = Plan::of(&s, &index, &p).with_room(room(&res));
    for r in [ahead_rep, behind_rep] {
        make_resident(&s, &mut res, r);
    }
    res.start_stage2(&[]);
    let (mut ahead, view, margin) = moving_to_5(&Plan::of(&s, &index, &p), &res, &mut c);
    assert_eq!(margin, std::f32::consts::PI);
    let failed = vec![false; s.reps.len()];
    ahead.plan(
        &plan,
        &mut res,
        &failed,
        &mut c,
        &view,
        margin,
        &ManualClock::new(),
        &mut || false,
    );
    let need = res.cost(behind_rep);
    let made = res.make_room(need, res.bytes(), Purpose::Prefetch, u64::MAX, |_| 0);
    [made, res.contains(ahead_rep), res.contains(behind_rep)]
}

#[test]
fn with_occlusion_culling_the_lookahead_protects_only_what_the_motion_draws() {
    let whole = |_: &ResidentSet| u64::MAX / 4;
    // With culling, F_I's part behind the eye is not protected: its room is
    // taken.
    assert_eq!(lookahead_then_prefetch(true, whole), [true, true, false]);
    // Without culling, F_I's fronts are what a turn draws: both stay.
    assert_eq!(lookahead_then_prefetch(false, whole), [false, true, true]);
}

#[test]
fn the_lookahead_protects_f_i_fronts_only_within_the_reps_room() {
    // Without culling, the part behind the eye (only in F_I's fronts
    // ahead) is protected while the reps' room holds it beside the view
    // fronts ahead (above); with a room that the view fronts already fill
    // (pages taking the rest of the footprint), a prefetch may take it, and
    // the view fronts' part stays.
    let ahead_only = |res: &ResidentSet| res.cost(8);
    assert_eq!(
        lookahead_then_prefetch(false, ahead_only),
        [true, true, false]
    );
}

#[test]
fn f_i_is_all_around_only_when_it_fits_the_reps_room_beside_the_pages() {
    // A footprint that holds every part twice, but pages take all of it but
    // eight parts: F_I is the view widened by the margin.
    let s = row();
    let mut p = params();
    p.prefetch.all_around_fit = 1.0;
    p.budget_bytes = s.reps.iter().map(|r| u64::from(r.len)).sum::<u64>() * 2;
    let (index, res, mut c) = setup(&s, &p);
    let plan = Plan::of(&s, &index, &p).with_room(u64::from(s.reps[1].len) * 8);
    let (front, margin) = c
        .classify_front(&plan, &res, &p.view(&pose_at(12.0)), 0.0, &mut || false)
        .unwrap();
    assert!(margin < 1.0 && front.len() < 24, "{margin} {}", front.len());
}
