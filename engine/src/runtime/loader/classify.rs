//! CLASSIFY (Varadhan & Manocha §4.2): the front of the enlarged frustum
//! F_I — all around the eye when that front fits the footprint — binned
//! by `Priority(O)`, and the PAR/CHD of each rep PREFETCH serves.

use super::Loader;
use crate::camera::View;
use crate::prefetch::{ang_pr, priority};
use crate::skeleton::RepId;

impl Loader {
    /// Flushes the bins and classifies the front under the enlarged frustum
    /// F_I, when the viewpoint changed.
    pub(super) fn classify_front(&mut self, view: &View, turn_rad: f32) {
        if self.class_view.as_ref() == Some(view) {
            return;
        }
        self.class_view = Some(*view);
        self.bins.clear();
        self.class_gen += 1;
        let p = &self.params.prefetch;
        let mut margin = (p.margin_deg + p.margin_per_deg_turn * turn_rad.to_degrees())
            .min(p.max_margin_deg)
            .to_radians();
        let mut front = std::mem::take(&mut self.scratch);
        // All around when the all-around front fits the footprint; if it
        // does not, F_I's front is its part in F_I.
        let fit = f64::from(p.all_around_fit) * self.params.budget_bytes as f64;
        let have_all_around = fit > 0.0 && margin < std::f32::consts::FRAC_PI_2;
        if have_all_around {
            let f = view.frustum(std::f32::consts::PI);
            self.index
                .compute(view, &f, self.params.tolerance_px, &mut front);
            let bytes: u64 = front.iter().map(|&r| self.cost(r)).sum();
            if bytes as f64 <= fit {
                margin = std::f32::consts::PI;
            }
        }
        let enlarged = view.frustum(margin);
        let own = view.frustum(0.0);
        self.theta0 = own.half_angle;
        self.class_frustum = Some(own);
        self.theta1 = margin.max(1e-3);
        if !have_all_around {
            self.index
                .compute(view, &enlarged, self.params.tolerance_px, &mut front);
        } else if margin < std::f32::consts::FRAC_PI_2 {
            self.index.restrict(&self.skeleton, &enlarged, &mut front);
        }
        for &r in &front {
            self.classify(r, 0, r);
        }
        self.plan_sweep(&front);
        self.scratch = front;
        self.plan_ahead(view, margin);
    }

    /// Bins rep `r`, found `depth` PAR/CHD steps from the F_I front, by the
    /// projected error of `by`: `r` itself for front reps and coarser
    /// candidates, the front rep it refines for a finer one (a child is
    /// needed when its parent's error reaches ε, and its own error, often
    /// 0 for a finest LOD, says nothing about when).
    pub(super) fn classify(&mut self, r: RepId, depth: u8, by: RepId) {
        if self.classified[r as usize] == self.class_gen {
            return;
        }
        self.classified[r as usize] = self.class_gen;
        let (Some(view), Some(own)) = (self.class_view, self.class_frustum) else {
            return;
        };
        let node = self.skeleton.reps[r as usize].node;
        let by_node = self.skeleton.reps[by as usize].node;
        let eps = self.index.projected_error(&view, by_node, by);
        let (mn, mx) = self.index.node_box(node);
        let theta = own.angle_to_box(mn, mx);
        let mut prio = priority(
            eps,
            self.params.tolerance_px,
            ang_pr(theta, self.theta0, self.theta1),
        );
        if depth == 0 {
            // Reps of the F_I front are visibility-prefetched whatever their
            // error (a leaf's finest rep may project above δ); δ bounds only
            // how far PAR/CHD classification reaches.
            prio = prio.min(self.params.delta());
        }
        if self.bins.push(r, prio, depth) {
            self.queued[r as usize] = self.class_gen;
        }
    }

    /// Classifies the parent and children of rep `o` (found `depth` steps
    /// from the front), up to the prefetch depth.
    pub(super) fn classify_neighbours(&mut self, o: RepId, depth: u8) {
        if depth < self.params.prefetch.depth {
            if let Some(p) = self.skeleton.par(o) {
                self.classify(p, depth + 1, p);
            }
            for c in self.skeleton.chd(o) {
                self.classify(c, depth + 1, o);
            }
        }
    }
}
