//! Stage I on P_R: the front for a view — frustum and simplification
//! culling (`front.rs`), then occlusion culling (`occlusion`), at the
//! tolerance the quality governor (`governor.rs`) chooses.

use std::sync::Arc;

use crate::camera::View;
use crate::clock::Clock;
use crate::format::RepRecord;
use crate::front::FrontIndex;
use crate::governor::{FrontCost, Governor, GovernorParams};
use crate::metrics::FrameMetrics;
use crate::occlusion::OcclusionCuller;
use crate::skeleton::{RepId, Skeleton};

/// One frame's front.
#[derive(Debug, Default)]
pub(super) struct Selected {
    pub(super) front: Vec<RepId>,
    /// Front reps occlusion culling left out.
    pub(super) hidden: Vec<RepId>,
    /// The tolerance the front was computed for.
    pub(super) tolerance_px: f32,
    pub(super) nodes_visited: u32,
    pub(super) front_ms: f64,
    pub(super) occlusion_ms: f64,
    /// Fronts computed (more than one when the governor searched).
    pub(super) tries: u32,
    /// What the front's reps take (the last front computed).
    pub(super) cost: FrontCost,
}

/// Computes fronts; owns the occlusion culler and the governor.
#[derive(Debug)]
pub(super) struct FrontSelect {
    index: Arc<FrontIndex>,
    occlusion: Option<OcclusionCuller>,
    governor: Option<Governor>,
    tolerance_px: f32,
    /// Bytes the front's reps may take (P_I's footprint; `None` in core).
    capacity: Option<u64>,
    /// The section of the frame being drawn: a rep it cuts is no occluder
    /// (what hides others may be cut away).
    section: crate::section::Section,
    /// P_R's clock: what the front and the culling took.
    clock: Arc<dyn Clock>,
}

impl FrontSelect {
    pub(super) fn new(
        index: Arc<FrontIndex>,
        reps: usize,
        occlusion_bytes: u64,
        governor: Option<GovernorParams>,
        tolerance_px: f32,
        capacity: Option<u64>,
        clock: Arc<dyn Clock>,
    ) -> Self {
        Self {
            index,
            occlusion: (occlusion_bytes > 0).then(|| OcclusionCuller::new(reps, occlusion_bytes)),
            governor: governor.map(|g| Governor::new(g, tolerance_px)),
            tolerance_px,
            capacity,
            section: crate::section::Section::NONE,
            clock,
        }
    }

    /// The front index (shared with P_I).
    pub(super) fn index(&self) -> &FrontIndex {
        &self.index
    }

    /// The front at `tol`, occlusion-culled, into `out`.
    fn compute(&mut self, s: &Skeleton, view: &View, tol: f32, out: &mut Selected) -> FrontCost {
        out.front.clear();
        out.hidden.clear();
        out.tolerance_px = tol;
        out.tries += 1;
        let t = self.clock.now();
        let fs = self
            .index
            .compute(view, &view.frustum(0.0), tol, &mut out.front);
        out.nodes_visited += fs.nodes_visited;
        out.front_ms += self.clock.ms_since(t);
        if let Some(c) = &mut self.occlusion {
            let t = self.clock.now();
            c.cull(view, s, &self.index, tol, &mut out.front, &mut out.hidden);
            out.occlusion_ms += self.clock.ms_since(t);
        }
        let mut cost = FrontCost::default();
        // A payload placed several times in the front is resident once.
        let mut placed = std::collections::HashSet::new();
        for &r in &out.front {
            let rec = &s.reps[r as usize];
            if s.placement(r).is_none_or(|p| placed.insert(p.source)) {
                cost.bytes += rec.resident_len();
            }
            if !rec.is_paged() {
                cost.tris += u64::from(rec.tri_count);
            }
        }
        out.cost = cost;
        cost
    }

    /// Stage I for `view`.
    pub(super) fn select(&mut self, s: &Skeleton, view: &View) -> Selected {
        self.section = view.section;
        if let Some(c) = &mut self.occlusion {
            c.begin_frame(view);
        }
        let mut out = Selected::default();
        let Some(mut g) = self.governor.take() else {
            let tol = self.tolerance_px;
            self.compute(s, view, tol, &mut out);
            return out;
        };
        let capacity = self.capacity;
        let eps = g.choose(capacity, |eps| self.compute(s, view, eps, &mut out));
        if out.tolerance_px != eps {
            // The last front tried was not the one chosen.
            self.compute(s, view, eps, &mut out);
        }
        self.governor = Some(g);
        out
    }

    /// A frame ended (the governor's frame-time target).
    pub(super) fn observe_frame(&mut self, frame_ms: f64, draw_ms: f64, tris: u64) {
        if let Some(g) = &mut self.governor {
            g.observe_frame(frame_ms, draw_ms, tris);
        }
    }

    /// A rep drawn as itself this frame (for the occluders: not one the
    /// section cuts, nor one drawn x-rayed or in part).
    pub(super) fn drawn(
        &mut self,
        r: RepId,
        rec: (&RepRecord, Option<&crate::records::RepPlacement>),
        payload: &Arc<[u8]>,
    ) {
        if let Some(c) = &mut self.occlusion {
            let (mn, mx) = self.index.node_box(rec.0.node);
            if self.section.keeps_whole_box(mn, mx) && self.index.all_shown(rec.0.node) {
                c.drawn(r, rec, payload, (mn, mx));
            }
        }
    }

    /// After the frame: the visibility of `front`, and the frame's
    /// occlusion counts into `m`.
    pub(super) fn end_frame(&mut self, s: &Skeleton, front: &[RepId], m: &mut FrameMetrics) {
        let Some(c) = &mut self.occlusion else {
            return;
        };
        let t = self.clock.now();
        c.end_frame(s, &self.index, front);
        m.occlusion_ms += self.clock.ms_since(t);
        let cs = c.stats();
        m.occluders = cs.occluders;
        m.occluded_reps = cs.occluded;
        m.occluder_tris = cs.triangles;
        m.occluder_bytes = c.store_bytes();
    }
}

#[cfg(test)]
mod tests;
