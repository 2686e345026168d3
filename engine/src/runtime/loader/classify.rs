//! CLASSIFY (Varadhan & Manocha §4.2): the front of the enlarged frustum
//! F_I — all around the eye when that front fits the footprint — binned
//! by `Priority(O)`, and the PAR/CHD of each rep PREFETCH serves.

use super::plan::Plan;
use crate::camera::{Frustum, View};
use crate::prefetch::{Bins, ang_pr, priority};
use crate::runtime::resident::ResidentSet;
use crate::skeleton::RepId;

/// Front reps binned between two checks for a waiting command.
const STOP_EVERY: usize = 512;

/// The binned prefetch candidates of the last classified view.
#[derive(Debug)]
pub(super) struct Classifier {
    pub(super) bins: Bins,
    /// A rep is classified (binned at most once) in this classification
    /// when its stamp is `generation`.
    classified: Vec<u32>,
    /// A rep is a prefetch candidate when its stamp is `generation`.
    queued: Vec<u32>,
    generation: u32,
    view: Option<View>,
    /// F_R of the classified view (for the angle of each rep), and the
    /// angles θ0 (its half angle) and θ1 (F_I's margin) of AngPr.
    own: Option<Frustum>,
    theta0: f32,
    theta1: f32,
    /// The last F_I front, and the all-around front (scratch).
    front: Vec<RepId>,
    all: Vec<RepId>,
    /// A rep is hidden from the view (occlusion culling left it out of
    /// P_R's front) when its stamp is `hidden_stamp`: it is binned as a
    /// rep at the edge of F_I.
    hidden: Vec<u32>,
    hidden_stamp: u32,
    /// Whether each rep was hidden (rather than drawn) the last time P_R's
    /// front held it: one not in the view's front now that was hidden then
    /// is served after every bin.
    was_hidden: Vec<bool>,
}

impl Classifier {
    pub(super) fn new(reps: usize, bins: Bins) -> Self {
        Self {
            bins,
            classified: vec![0; reps],
            queued: vec![0; reps],
            // Stamps of 0 never match: nothing is classified or queued yet.
            generation: 1,
            view: None,
            own: None,
            theta0: 0.0,
            theta1: 1.0,
            front: Vec::new(),
            all: Vec::new(),
            hidden: vec![0; reps],
            hidden_stamp: 1,
            was_hidden: vec![false; reps],
        }
    }

    /// New bins (another tolerance): the next view is classified afresh.
    pub(super) fn rebin(&mut self, bins: Bins) {
        self.bins = bins;
        self.view = None;
        self.generation += 1;
    }

    /// Whether occlusion culling left rep `r` out of this fetch's front,
    /// or out of the last front that held it.
    pub(super) fn is_hidden(&self, r: RepId) -> bool {
        self.was_hidden[r as usize]
    }

    /// This fetch's front (`front`) and the reps occlusion culling left out
    /// of it (`hidden`).
    pub(super) fn set_hidden(&mut self, front: &[RepId], hidden: &[RepId]) {
        self.hidden_stamp += 1;
        for &r in hidden {
            self.hidden[r as usize] = self.hidden_stamp;
            self.was_hidden[r as usize] = true;
        }
        for &r in front {
            self.was_hidden[r as usize] = false;
        }
    }

    /// Flushes the bins and classifies the front under the enlarged frustum
    /// F_I, when the viewpoint changed. Returns F_I's front and its margin
    /// (rad) when it did. When `stop` says a command is waiting, the
    /// all-around front is not computed and the binning stops where it is
    /// (the candidates binned so far stay; the same view is classified
    /// again next time).
    pub(super) fn classify_front(
        &mut self,
        plan: &Plan,
        res: &ResidentSet,
        view: &View,
        turn_rad: f32,
        stop: &mut dyn FnMut() -> bool,
    ) -> Option<(&[RepId], f32)> {
        if self.view.as_ref() == Some(view) {
            return None;
        }
        self.view = Some(*view);
        self.bins.clear();
        self.generation += 1;
        let p = &plan.params.prefetch;
        let mut margin = (p.margin_deg + p.margin_per_deg_turn * turn_rad.to_degrees())
            .min(p.max_margin_deg)
            .to_radians();
        let mut front = std::mem::take(&mut self.front);
        let enlarged = view.frustum(margin);
        plan.index
            .compute(view, &enlarged, plan.params.tolerance_px, &mut front);
        // All around when the all-around front fits the reps' room (the
        // footprint less the pages' share); if it does not, F_I's front is
        // its part in F_I. The all-around front holds F_I's (the same cut,
        // less culling): when F_I's does not fit, the all-around one is not
        // computed. (Measured against the whole footprint while pages took
        // a quarter of it, F_I's fronts ahead were protected past the
        // reps' room and P_I stood idle, every candidate refused for room.)
        let fit = f64::from(p.all_around_fit) * plan.room as f64;
        let bytes = |f: &[RepId]| f.iter().map(|&r| res.cost(r)).sum::<u64>() as f64;
        let mut cut = false;
        if fit > 0.0 && margin < std::f32::consts::FRAC_PI_2 && bytes(&front) <= fit && {
            cut = stop();
            !cut
        } {
            let all = view.frustum(std::f32::consts::PI);
            plan.index
                .compute(view, &all, plan.params.tolerance_px, &mut self.all);
            if bytes(&self.all) <= fit {
                margin = std::f32::consts::PI;
                std::mem::swap(&mut front, &mut self.all);
            }
        }
        let own = view.frustum(0.0);
        self.theta0 = own.half_angle;
        self.own = Some(own);
        self.theta1 = margin.max(1e-3);
        for (i, &r) in front.iter().enumerate() {
            if i % STOP_EVERY == STOP_EVERY - 1 && stop() {
                cut = true;
                break;
            }
            self.classify(plan, r, 0, r);
        }
        if cut {
            // Classified in part: the same view is classified again.
            self.view = None;
        }
        self.front = front;
        Some((&self.front, margin))
    }

    /// Bins rep `r`, found `depth` PAR/CHD steps from the F_I front, by the
    /// projected error of `by`: `r` itself for front reps and coarser
    /// candidates, the front rep it refines for a finer one (a child is
    /// needed when its parent's error reaches ε, and its own error, often
    /// 0 for a finest LOD, says nothing about when).
    fn classify(&mut self, plan: &Plan, r: RepId, depth: u8, by: RepId) {
        if self.classified[r as usize] == self.generation {
            return;
        }
        self.classified[r as usize] = self.generation;
        let (Some(view), Some(own)) = (self.view, self.own) else {
            return;
        };
        let hidden_now = self.hidden[r as usize] == self.hidden_stamp;
        if self.was_hidden[r as usize] && !hidden_now {
            self.bins.push_hidden(r, depth);
            self.queued[r as usize] = self.generation;
            return;
        }
        // A rep hidden in the view ranks as one at the edge of F_I: a door
        // ahead may show it, as a turn may show what lies beside the view.
        let theta = if hidden_now {
            self.theta0 + self.theta1
        } else {
            let (mn, mx) = plan.index.node_box(plan.skeleton.reps[r as usize].node);
            own.angle_to_box(mn, mx)
        };
        let tol = plan.params.tolerance_px;
        let eps = if depth == 0 && plan.skeleton.reps[r as usize].error <= 0.0 {
            // A finest rep of error 0 in F_I's front is needed as long as
            // it is in view, at any distance: it counts as a rep at ε,
            // ranked by its angle. By its own projected error, 0, it would
            // rank last wherever it lay, in the order F_I's front lists it.
            tol
        } else {
            let by_node = plan.skeleton.reps[by as usize].node;
            plan.index.projected_error(&view, by_node, by)
        };
        let mut prio = priority(eps, tol, ang_pr(theta, self.theta0, self.theta1));
        if depth == 0 {
            // Reps of the F_I front are visibility-prefetched whatever their
            // error (a leaf's finest rep may project above δ); δ bounds only
            // how far PAR/CHD classification reaches.
            prio = prio.min(plan.params.delta());
        }
        if self.bins.push(r, prio, depth) {
            self.queued[r as usize] = self.generation;
        }
    }

    /// Classifies the parent and children of rep `o` (found `depth` steps
    /// from the front), up to the prefetch depth.
    pub(super) fn classify_neighbours(&mut self, plan: &Plan, o: RepId, depth: u8) {
        if depth < plan.params.prefetch.depth {
            if let Some(p) = plan.skeleton.par(o) {
                self.classify(plan, p, depth + 1, p);
            }
            for c in plan.skeleton.chd(o) {
                self.classify(plan, c, depth + 1, o);
            }
        }
    }

    /// F_R of the classified view.
    pub(super) fn own_frustum(&self) -> Option<Frustum> {
        self.own
    }

    /// Makes rep `r` a candidate of this classification (the lookahead's).
    pub(super) fn queue(&mut self, r: RepId) {
        self.queued[r as usize] = self.generation;
    }

    /// Whether rep `r` is a candidate of this classification.
    pub(super) fn is_queued(&self, r: RepId) -> bool {
        self.queued[r as usize] == self.generation
    }

    /// Whether rep `r` is a candidate of this classification or of the one
    /// before (a child is binned again only when its parent comes up).
    pub(super) fn is_recent(&self, r: RepId) -> bool {
        self.generation.wrapping_sub(self.queued[r as usize]) <= 1
    }
}
