//! Hidden elements (hide, isolate, a BCF viewpoint's invisible components):
//! which nodes of the scene graph may still be drawn, from the objects the
//! user hid.
//!
//! A node whose objects are all hidden leaves every front, P_R's and P_I's
//! ([`crate::front::FrontIndex::set_visibility`]), so it is neither drawn
//! nor fetched. A node with some hidden objects below it cannot use its own
//! reps: an HLOD, or a merged leaf's coarser levels, mixes hidden and shown
//! objects with no record of which triangle is whose, so the front goes
//! down to the leaves. A merged leaf with some objects hidden draws its
//! finest rep, the one the object section describes run by run, with only
//! the shown objects' triangles ([`Hiding::triangle_ranges`]).

use std::ops::Range;

use crate::format::NONE;
use crate::format::objects::ObjectTable;
use crate::skeleton::{RepId, Skeleton};

/// What may be drawn of a node.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(u8)]
pub enum NodeVis {
    /// Nothing below it is hidden.
    #[default]
    Shown = 0,
    /// Everything below it is hidden: it leaves the front.
    Hidden = 1,
    /// Some of it is hidden: its own reps are not used (a leaf draws its
    /// finest rep, without the hidden objects' triangles).
    Mixed = 2,
}

/// The nodes' visibility for a set of hidden objects.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Hiding {
    nodes: Vec<NodeVis>,
    /// For each merged leaf with some objects hidden: its finest rep and
    /// the triangle ranges of that rep still shown.
    ranges: Vec<(RepId, Vec<Range<u32>>)>,
    hidden_objects: usize,
}

impl Hiding {
    /// Nothing hidden in a scene of `node_count` nodes.
    pub fn none(node_count: usize) -> Self {
        Self {
            nodes: vec![NodeVis::Shown; node_count],
            ranges: Vec::new(),
            hidden_objects: 0,
        }
    }

    /// The visibility of every node when the objects `k` with
    /// `hidden(k)` are hidden. Leaves that name no object (a version-1
    /// scene) stay shown.
    pub fn new(s: &Skeleton, table: &ObjectTable, hidden: impl Fn(u32) -> bool) -> Self {
        let n = s.nodes.len();
        let mut out = Self::none(n);
        out.hidden_objects = (0..table.len() as u32).filter(|&k| hidden(k)).count();
        if out.hidden_objects == 0 {
            return out;
        }
        // Children come after their parents: a reverse sweep sees every
        // child before its parent.
        for i in (0..n).rev() {
            let node = &s.nodes[i];
            let vis = if node.child_count > 0 {
                let c = node.first_child as usize;
                let kids = &out.nodes[c..c + node.child_count as usize];
                combine(kids.iter().copied())
            } else if node.object != NONE {
                if hidden(node.object) {
                    NodeVis::Hidden
                } else {
                    NodeVis::Shown
                }
            } else {
                let runs = table.runs_of(i as u32);
                let vis = combine(runs.iter().map(|r| {
                    if hidden(r.object) {
                        NodeVis::Hidden
                    } else {
                        NodeVis::Shown
                    }
                }));
                if vis == NodeVis::Mixed && node.rep_count > 0 {
                    let finest = node.first_rep + node.rep_count - 1;
                    let mut shown: Vec<Range<u32>> = Vec::new();
                    let mut start = 0;
                    for r in runs {
                        if !hidden(r.object) && start < r.tri_end {
                            match shown.last_mut() {
                                Some(last) if last.end == start => last.end = r.tri_end,
                                _ => shown.push(start..r.tri_end),
                            }
                        }
                        start = r.tri_end;
                    }
                    out.ranges.push((finest, shown));
                }
                vis
            };
            out.nodes[i] = vis;
        }
        out.ranges.sort_by_key(|(r, _)| *r);
        out
    }

    /// Each node's visibility.
    pub fn nodes(&self) -> &[NodeVis] {
        &self.nodes
    }

    /// How many objects are hidden.
    pub fn hidden_objects(&self) -> usize {
        self.hidden_objects
    }

    /// The merged leaves' finest reps drawn in part, with the triangle
    /// ranges still shown (by rep id).
    pub fn triangle_ranges(&self) -> &[(RepId, Vec<Range<u32>>)] {
        &self.ranges
    }
}

/// A parent's visibility from its children's (or a leaf's from its runs').
fn combine(mut it: impl Iterator<Item = NodeVis>) -> NodeVis {
    let Some(first) = it.next() else {
        return NodeVis::Shown;
    };
    it.fold(first, |a, b| if a == b { a } else { NodeVis::Mixed })
}

#[cfg(test)]
mod tests;
