//! Front computation (Varadhan & Manocha §3.2): view-frustum culling against the
//! node boxes and simplification culling.
//!
//! From the root down, a node outside the frustum is culled; otherwise the
//! coarsest rep `N[i]` whose projected screen-space error `ε_N[i]` is below the
//! tolerance `ε` (pixels) joins the front and the traversal stops there. If no
//! rep qualifies, the traversal descends to the children; a leaf falls back to
//! its finest rep. Distances are taken to the node's box (rep boxes lie inside
//! it), so the projected error is conservative.

use std::sync::atomic::{AtomicU8, Ordering};

use glam::Vec3;

use crate::camera::{Frustum, View, box_distance};
use crate::hide::NodeVis;
use crate::skeleton::{RepId, Skeleton};

/// Per-node data laid out for a fast traversal.
#[derive(Clone, Debug)]
pub struct FrontIndex {
    /// Each node's [`NodeVis`] as a byte: shared by P_R and P_I through
    /// the index's `Arc`, set by [`FrontIndex::set_visibility`].
    vis: VisMask,
    min: Vec<Vec3>,
    max: Vec<Vec3>,
    first_child: Vec<u32>,
    child_count: Vec<u32>,
    first_rep: Vec<u32>,
    rep_count: Vec<u32>,
    /// Rep errors, indexed by rep id.
    errors: Vec<f32>,
}

/// What one front computation did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrontStats {
    pub nodes_visited: u32,
}

impl FrontIndex {
    /// Prepares the skeleton for traversal.
    pub fn new(s: &Skeleton) -> Self {
        Self {
            vis: VisMask(s.nodes.iter().map(|_| AtomicU8::new(0)).collect()),
            min: s.nodes.iter().map(|n| Vec3::from(n.bbox_min)).collect(),
            max: s.nodes.iter().map(|n| Vec3::from(n.bbox_max)).collect(),
            first_child: s.nodes.iter().map(|n| n.first_child).collect(),
            child_count: s.nodes.iter().map(|n| n.child_count).collect(),
            first_rep: s.nodes.iter().map(|n| n.first_rep).collect(),
            rep_count: s.nodes.iter().map(|n| n.rep_count).collect(),
            errors: s.reps.iter().map(|r| r.error).collect(),
        }
    }

    /// Computes the front for `view` and tolerance `tol_px` into `out` (cleared
    /// first), using `frustum` for culling (the view's own, or an enlarged one).
    pub fn compute(
        &self,
        view: &View,
        frustum: &Frustum,
        tol_px: f32,
        out: &mut Vec<RepId>,
    ) -> FrontStats {
        out.clear();
        let mut stats = FrontStats::default();
        if self.min.is_empty() {
            return stats;
        }
        let eye = view.pose.position;
        let k = view.pixels_per_radian();
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        stack.push(0);
        while let Some(n) = stack.pop() {
            let i = n as usize;
            stats.nodes_visited += 1;
            let (mn, mx) = (self.min[i], self.max[i]);
            if !frustum.intersects(mn, mx) {
                continue;
            }
            let vis = self.vis.0[i].load(Ordering::Relaxed);
            if vis == NodeVis::Hidden as u8 {
                continue;
            }
            let dist = box_distance(eye, mn, mx).max(view.near);
            // ε_N[i] = E_i * k / dist < tol  <=>  E_i < tol * dist / k
            let limit = tol_px * dist / k;
            let (fr, rc) = (self.first_rep[i], self.rep_count[i]);
            // A node with hidden or x-rayed objects below it draws none of
            // its own reps (a leaf: its finest, drawn in part); an x-rayed
            // one is chosen as a shown one is.
            let chosen = (vis == NodeVis::Shown as u8 || vis == NodeVis::XRay as u8)
                .then(|| (fr..fr + rc).find(|&r| self.errors[r as usize] < limit))
                .flatten();
            match chosen {
                Some(r) => out.push(r),
                None if self.child_count[i] == 0 => out.push(fr + rc - 1),
                None => {
                    let c = self.first_child[i];
                    stack.extend((c..c + self.child_count[i]).rev());
                }
            }
        }
        stats
    }

    /// Keeps the reps of `front`, computed with no culling (all around the
    /// eye), that [`compute`](Self::compute) with `frustum` would return,
    /// in the same order: those whose node box meets `frustum`. (The
    /// traversals choose alike where both go; a box inside its parent's
    /// never passes the plane test where the parent's fails, so a node
    /// that meets the frustum has no culled ancestor.)
    pub fn restrict(&self, s: &Skeleton, frustum: &Frustum, front: &mut Vec<RepId>) {
        front.retain(|&r| {
            let n = s.reps[r as usize].node as usize;
            frustum.intersects(self.min[n], self.max[n])
        });
    }

    /// Projected error of rep `r` (of node `node`) in pixels.
    pub fn projected_error(&self, view: &View, node: u32, r: RepId) -> f32 {
        let i = node as usize;
        let dist = box_distance(view.pose.position, self.min[i], self.max[i]);
        view.projected(self.errors[r as usize], dist)
    }

    /// The node's box.
    pub fn node_box(&self, node: u32) -> (Vec3, Vec3) {
        (self.min[node as usize], self.max[node as usize])
    }

    /// Whether every object under `node` is shown (neither hidden nor
    /// x-rayed): only such reps hide what is behind them.
    pub fn all_shown(&self, node: u32) -> bool {
        (self.vis.0.get(node as usize))
            .is_none_or(|v| v.load(Ordering::Relaxed) == NodeVis::Shown as u8)
    }

    /// What may be drawn of each node from now on, for every front
    /// computed through this index (P_R's and P_I's: they share it).
    /// `vis` has one entry per node; a shorter one leaves the rest shown.
    pub fn set_visibility(&self, vis: &[NodeVis]) {
        for (i, a) in self.vis.0.iter().enumerate() {
            let v = vis.get(i).copied().unwrap_or_default();
            a.store(v as u8, Ordering::Relaxed);
        }
    }
}

/// Per-node visibility bytes (a clone copies the current values).
#[derive(Debug)]
struct VisMask(Vec<AtomicU8>);

impl Clone for VisMask {
    fn clone(&self) -> Self {
        Self(
            self.0
                .iter()
                .map(|a| AtomicU8::new(a.load(Ordering::Relaxed)))
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests;
