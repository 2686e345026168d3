//! The in-core scene-graph skeleton and the paper's relations over object-reps.
//!
//! Reps are numbered globally ([`RepId`]); node `N`'s reps are
//! `N.first_rep .. N.first_rep + N.rep_count`, coarsest first, so `N[i]` is
//! `first_rep + i`. The relations follow Varadhan & Manocha §3.1:
//!
//! - `PAR(N[i]) = N[i-1]` for `i > 0`, else the finest rep of `N`'s parent;
//! - `CHD(N[i]) = {N[i+1]}` for `i < Num(N)-1`, else the coarsest reps of `N`'s children;
//! - `ASC(O, k)` / `DSC(O, k)` by recursion.
//!
//! A node without reps (allowed for interior nodes only) is transparent: PAR and
//! CHD pass through it.

use crate::records::{
    NONE, NodeRecord, REP_ALIGN, REP_HEADER_BYTES, RepKind, RepPlacement, RepRecord,
    rep_payload_len,
};

/// Global index of an object-rep in the skeleton's rep table.
pub type RepId = u32;

/// The scene graph without its geometry: nodes, boxes, errors, rep ranges.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Skeleton {
    pub nodes: Vec<NodeRecord>,
    pub reps: Vec<RepRecord>,
    /// The placed reps, sorted by rep (format version 6): an instanced
    /// mesh's levels stored once and drawn by every instance with its
    /// transform. Empty when nothing is shared.
    pub placements: Vec<RepPlacement>,
}

/// Why a hierarchy is not well formed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ValidationError {
    #[error("the scene has no nodes")]
    Empty,
    #[error("node {node}: {reason}")]
    Node { node: u32, reason: String },
    #[error("rep {rep}: {reason}")]
    Rep { rep: u32, reason: String },
    #[error("errors do not decrease from rep {coarse} to rep {fine} ({coarse_err} <= {fine_err})")]
    ErrorOrder {
        coarse: u32,
        fine: u32,
        coarse_err: f32,
        fine_err: f32,
    },
    #[error("box of {what} {id} is not inside the box of node {parent}")]
    BoxNotContained {
        what: &'static str,
        id: u32,
        parent: u32,
    },
    #[error("reps {a} and {b} overlap on disk")]
    Overlap { a: u32, b: u32 },
    #[error("placement {index}: {reason}")]
    Placement { index: usize, reason: String },
}

impl Skeleton {
    /// Rep `r`'s placement, when its payload is shared.
    pub fn placement(&self, r: RepId) -> Option<&RepPlacement> {
        if self.placements.is_empty() {
            return None;
        }
        let i = self.placements.binary_search_by_key(&r, |p| p.rep).ok()?;
        Some(&self.placements[i])
    }

    /// The rep whose record and header describe `r`'s payload: `r` itself,
    /// or the first rep that places the same shared payload. P_I loads,
    /// holds and evicts payloads under this id, so a payload placed N
    /// times is read, resident and counted once.
    pub fn payload_rep(&self, r: RepId) -> RepId {
        self.placement(r).map_or(r, |p| p.source)
    }

    /// Whether `r` is where its payload is stored and counted (not a
    /// second placement of another rep's).
    pub fn owns_payload(&self, r: RepId) -> bool {
        self.payload_rep(r) == r
    }

    /// The root node (node 0).
    pub fn root(&self) -> Option<&NodeRecord> {
        self.nodes.first()
    }

    /// Bytes the whole scene takes in core (every rep as it is resident,
    /// compressed reps expanded) with room to load its largest compressed
    /// rep (the compressed copy it needs while it is expanded): what a
    /// footprint of 100% means, so that a walk at 100% can load everything.
    pub fn in_core_bytes(&self) -> u64 {
        let data: u64 = (self.reps.iter().enumerate())
            .filter(|&(i, _)| self.owns_payload(i as RepId))
            .map(|(_, r)| r.expanded_extent())
            .sum();
        let scratch = self.reps.iter().map(RepRecord::load_scratch).max();
        data.saturating_add(scratch.unwrap_or(0))
    }

    /// The smallest footprint under which every rep can be drawn as itself:
    /// the root's coarsest rep (always resident) beside the largest other
    /// rep while it loads (or the root's own load, if larger). Below it,
    /// the reps that do not fit are drawn as coarser ancestors on every
    /// frame. Never more than [`Self::in_core_bytes`].
    pub fn full_detail_bytes(&self) -> u64 {
        let loading = |r: &RepRecord| r.expanded_extent() + r.load_scratch();
        let root_id = self.root().map(|n| n.first_rep as usize);
        let root = root_id.and_then(|i| self.reps.get(i));
        let root_resident = root.map_or(0, RepRecord::expanded_extent);
        let root_loading = root.map_or(0, loading);
        let largest_other = (self.reps.iter().enumerate())
            .filter(|&(i, _)| Some(i) != root_id)
            .map(|(_, r)| loading(r))
            .max()
            .unwrap_or(0);
        root_loading.max(root_resident.saturating_add(largest_other))
    }

    /// Children node ids of `node`.
    pub fn children(&self, node: u32) -> std::ops::Range<u32> {
        let n = &self.nodes[node as usize];
        n.first_child..n.first_child + n.child_count
    }

    /// `PAR(O)`: the next coarser rep on the path to the root, if any.
    pub fn par(&self, rep: RepId) -> Option<RepId> {
        let r = &self.reps[rep as usize];
        if r.index > 0 {
            return Some(rep - 1);
        }
        let mut p = self.nodes[r.node as usize].parent;
        while p != NONE {
            let pn = &self.nodes[p as usize];
            if pn.rep_count > 0 {
                return Some(pn.first_rep + pn.rep_count - 1);
            }
            p = pn.parent;
        }
        None
    }

    /// `CHD(O)`: the next finer reps (one, or the children's coarsest reps).
    pub fn chd(&self, rep: RepId) -> Vec<RepId> {
        let r = &self.reps[rep as usize];
        let n = &self.nodes[r.node as usize];
        if u32::from(r.index) + 1 < n.rep_count {
            return vec![rep + 1];
        }
        let mut out = Vec::new();
        self.coarsest_below(r.node, &mut out);
        out
    }

    /// Coarsest reps of `node`'s children, passing through rep-less nodes.
    fn coarsest_below(&self, node: u32, out: &mut Vec<RepId>) {
        for c in self.children(node) {
            let cn = &self.nodes[c as usize];
            if cn.rep_count > 0 {
                out.push(cn.first_rep);
            } else {
                self.coarsest_below(c, out);
            }
        }
    }

    /// `ASC(O, k)`: the k-th coarser ancestor rep (`k >= 1`).
    pub fn asc(&self, rep: RepId, k: u32) -> Option<RepId> {
        let mut cur = rep;
        for _ in 0..k {
            cur = self.par(cur)?;
        }
        Some(cur)
    }

    /// `DSC(O, k)`: the reps k CHD-steps finer (`k >= 1`), sorted.
    pub fn dsc(&self, rep: RepId, k: u32) -> Vec<RepId> {
        let mut level = vec![rep];
        for _ in 0..k {
            level = level.iter().flat_map(|&r| self.chd(r)).collect();
        }
        level.sort_unstable();
        level.dedup();
        level
    }

    /// Height of the graph: nodes on the longest root-to-leaf path.
    pub fn height(&self) -> u32 {
        self.nodes.iter().map(|n| n.depth + 1).max().unwrap_or(0)
    }

    /// Triangles over all reps.
    pub fn total_triangles(&self) -> u64 {
        self.reps.iter().map(|r| u64::from(r.tri_count)).sum()
    }

    /// Checks the whole hierarchy: structure, rep tables, strictly decreasing
    /// errors along PAR/CHD, boxes nested, payload ranges inside
    /// `data_start..data_end`, block-aligned and disjoint.
    pub fn validate(&self, data_start: u64, data_end: u64) -> Result<(), ValidationError> {
        if self.nodes.is_empty() {
            return Err(ValidationError::Empty);
        }
        self.validate_structure()?;
        self.validate_placements()?;
        self.validate_reps(data_start, data_end)?;
        self.validate_errors_and_boxes()
    }

    /// Placements: sorted by rep, each of a mesh rep whose source places
    /// itself, precedes it, and has the same payload range, checksum,
    /// counts and kind; finite transforms.
    fn validate_placements(&self) -> Result<(), ValidationError> {
        let n = self.reps.len() as u64;
        for (index, p) in self.placements.iter().enumerate() {
            let bad = |reason: String| Err(ValidationError::Placement { index, reason });
            if u64::from(p.rep) >= n || p.source > p.rep {
                return bad(format!(
                    "rep {} from source {} out of range",
                    p.rep, p.source
                ));
            }
            if index > 0 && self.placements[index - 1].rep >= p.rep {
                return bad("not sorted by rep".into());
            }
            if !p.transform.iter().flatten().all(|x| x.is_finite()) {
                return bad("transform not finite".into());
            }
            let (r, s) = (&self.reps[p.rep as usize], &self.reps[p.source as usize]);
            if r.is_paged() {
                return bad("a view-dependence tree or MT cannot be shared".into());
            }
            let same = (
                r.offset,
                r.len,
                r.checksum,
                r.tri_count,
                r.vertex_count,
                r.kind,
            ) == (
                s.offset,
                s.len,
                s.checksum,
                s.tri_count,
                s.vertex_count,
                s.kind,
            );
            if !same {
                return bad(format!("rep {} and its source {} differ", p.rep, p.source));
            }
            if p.source != p.rep
                && self
                    .placement(p.source)
                    .is_none_or(|q| q.source != p.source)
            {
                return bad(format!(
                    "source {} is not placed as its own source",
                    p.source
                ));
            }
        }
        Ok(())
    }

    fn validate_structure(&self) -> Result<(), ValidationError> {
        let n_nodes = self.nodes.len() as u64;
        let node_err = |node: usize, reason: String| ValidationError::Node {
            node: node as u32,
            reason,
        };
        let mut next_child = 1u64;
        let mut next_rep = 0u64;
        for (i, n) in self.nodes.iter().enumerate() {
            if i == 0 {
                if n.parent != NONE || n.depth != 0 {
                    return Err(node_err(i, "root has a parent or non-zero depth".into()));
                }
            } else {
                let p = n.parent as usize;
                if p >= i {
                    return Err(node_err(i, format!("parent {p} does not precede it")));
                }
                let pn = &self.nodes[p];
                if !(pn.first_child as usize..(pn.first_child + pn.child_count) as usize)
                    .contains(&i)
                {
                    return Err(node_err(i, format!("not among the children of parent {p}")));
                }
                if n.depth != pn.depth + 1 {
                    return Err(node_err(i, "depth is not parent depth + 1".into()));
                }
            }
            if n.child_count > 0 {
                if u64::from(n.first_child) != next_child {
                    return Err(node_err(i, "children not stored breadth-first".into()));
                }
                next_child += u64::from(n.child_count);
                if next_child > n_nodes {
                    return Err(node_err(i, "child range past the node table".into()));
                }
            }
            if u64::from(n.first_rep) != next_rep && n.rep_count > 0 {
                return Err(node_err(
                    i,
                    "rep range not contiguous with the previous node".into(),
                ));
            }
            next_rep += u64::from(n.rep_count);
            if next_rep > self.reps.len() as u64 {
                return Err(node_err(i, "rep range past the rep table".into()));
            }
            if n.is_leaf() && n.rep_count == 0 {
                return Err(node_err(i, "leaf without object-reps".into()));
            }
            if !finite_box(n.bbox_min, n.bbox_max) {
                return Err(node_err(i, "box not finite or inverted".into()));
            }
        }
        if next_child != n_nodes {
            return Err(node_err(
                0,
                format!("{} nodes unreachable", n_nodes - next_child),
            ));
        }
        if next_rep != self.reps.len() as u64 {
            return Err(ValidationError::Rep {
                rep: next_rep as u32,
                reason: "rep owned by no node".into(),
            });
        }
        Ok(())
    }

    fn validate_reps(&self, data_start: u64, data_end: u64) -> Result<(), ValidationError> {
        for (ni, n) in self.nodes.iter().enumerate() {
            for i in 0..n.rep_count {
                let id = n.first_rep + i;
                let r = &self.reps[id as usize];
                let rep_err = |reason: String| ValidationError::Rep { rep: id, reason };
                if r.node as usize != ni || u32::from(r.index) != i {
                    return Err(rep_err(format!("says node {} index {}", r.node, r.index)));
                }
                match r.rep_kind() {
                    Some(RepKind::Lod) if !n.is_leaf() => {
                        return Err(rep_err("static LOD on an interior node".into()));
                    }
                    Some(RepKind::Hlod) if n.is_leaf() => {
                        return Err(rep_err("HLOD on a leaf".into()));
                    }
                    Some(RepKind::Vdt) if !n.is_leaf() || i + 1 != n.rep_count || i == 0 => {
                        return Err(rep_err(
                            "a view-dependence tree must be a leaf's finest rep after a static LOD"
                                .into(),
                        ));
                    }
                    None => return Err(rep_err(format!("unknown kind {}", r.kind))),
                    _ => {}
                }
                if !(r.error.is_finite() && r.error >= 0.0) {
                    return Err(rep_err(format!("error {} is not finite and >= 0", r.error)));
                }
                if r.tri_count == 0 || r.vertex_count == 0 {
                    return Err(rep_err("empty rep".into()));
                }
                if r.is_vdt() {
                    if r.len < 112 || r.aux == 0 {
                        return Err(rep_err(format!(
                            "view-dependence tree of {}+{} bytes is too short",
                            r.len, r.aux
                        )));
                    }
                } else if r.is_mt() {
                    if r.len < 136 || r.aux == 0 {
                        return Err(rep_err(format!(
                            "Multi-Triangulation of {}+{} bytes is too short",
                            r.len, r.aux
                        )));
                    }
                } else {
                    // Stored raw (exactly `expect`) or compressed (shorter).
                    let expect = rep_payload_len(r.vertex_count as usize, r.tri_count as usize * 3);
                    if (r.len as usize) < REP_HEADER_BYTES || r.len as usize > expect || r.aux != 0
                    {
                        return Err(rep_err(format!(
                            "length {}+{} but counts need {expect} (or less, compressed)",
                            r.len, r.aux
                        )));
                    }
                }
                let end = r.offset.checked_add(r.extent());
                if !r.offset.is_multiple_of(REP_ALIGN)
                    || r.offset < data_start
                    || end.is_none_or(|e| e > data_end)
                {
                    return Err(rep_err(format!(
                        "byte range {}+{} not {REP_ALIGN}-byte aligned inside {data_start}..{data_end}",
                        r.offset,
                        r.extent()
                    )));
                }
                if !finite_box(r.bbox_min, r.bbox_max) {
                    return Err(rep_err("box not finite or inverted".into()));
                }
            }
        }
        for w in self.payloads_in_file_order().windows(2) {
            let (a, b) = (&self.reps[w[0] as usize], &self.reps[w[1] as usize]);
            if a.offset + a.extent() > b.offset {
                return Err(ValidationError::Overlap { a: w[0], b: w[1] });
            }
        }
        Ok(())
    }

    /// The reps in the order their payloads are stored (ties by id).
    pub fn reps_in_file_order(&self) -> Vec<RepId> {
        let mut by_offset: Vec<RepId> = (0..self.reps.len() as RepId).collect();
        by_offset.sort_by_key(|&r| (self.reps[r as usize].offset, r));
        by_offset
    }

    /// The payloads in the order they are stored: each by the rep that
    /// owns it ([`Skeleton::payload_rep`]), a shared one once.
    pub fn payloads_in_file_order(&self) -> Vec<RepId> {
        let mut v = self.reps_in_file_order();
        if !self.placements.is_empty() {
            v.retain(|&r| self.owns_payload(r));
        }
        v
    }

    fn validate_errors_and_boxes(&self) -> Result<(), ValidationError> {
        let root = &self.nodes[0];
        let extent = (0..3)
            .map(|a| root.bbox_max[a] - root.bbox_min[a])
            .fold(0f32, f32::max);
        let tol = extent * 1e-5;
        for id in 0..self.reps.len() as u32 {
            let r = &self.reps[id as usize];
            for c in self.chd(id) {
                let cr = &self.reps[c as usize];
                if cr.error >= r.error {
                    return Err(ValidationError::ErrorOrder {
                        coarse: id,
                        fine: c,
                        coarse_err: r.error,
                        fine_err: cr.error,
                    });
                }
            }
            if !contains(&self.nodes[r.node as usize], r.bbox_min, r.bbox_max, tol) {
                return Err(ValidationError::BoxNotContained {
                    what: "rep",
                    id,
                    parent: r.node,
                });
            }
        }
        for (i, n) in self.nodes.iter().enumerate().skip(1) {
            if !contains(&self.nodes[n.parent as usize], n.bbox_min, n.bbox_max, tol) {
                return Err(ValidationError::BoxNotContained {
                    what: "node",
                    id: i as u32,
                    parent: n.parent,
                });
            }
        }
        Ok(())
    }
}

fn finite_box(min: [f32; 3], max: [f32; 3]) -> bool {
    (0..3).all(|a| min[a].is_finite() && max[a].is_finite() && min[a] <= max[a])
}

fn contains(outer: &NodeRecord, min: [f32; 3], max: [f32; 3], tol: f32) -> bool {
    (0..3).all(|a| min[a] >= outer.bbox_min[a] - tol && max[a] <= outer.bbox_max[a] + tol)
}

#[cfg(test)]
mod tests;
