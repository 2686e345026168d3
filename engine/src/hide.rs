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
//! the shown objects' triangles ([`Hiding::parts`]).
//!
//! X-rayed objects ([`Look::XRay`]) stay in the front as if shown, since
//! they are drawn; a node all of whose objects are x-rayed draws its reps
//! translucent and is no occluder, and a node mixing looks goes down to the
//! leaves as a node with hidden objects does.

use std::ops::Range;

use crate::format::NONE;
use crate::format::objects::ObjectTable;
use crate::skeleton::{RepId, Skeleton};
use crate::tree::Look;

/// What may be drawn of a node.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(u8)]
pub enum NodeVis {
    /// Nothing below it is hidden or x-rayed.
    #[default]
    Shown = 0,
    /// Everything below it is hidden: it leaves the front.
    Hidden = 1,
    /// Some of it is hidden or x-rayed: its own reps are not used (a leaf
    /// draws its finest rep, each object's triangles as it looks).
    Mixed = 2,
    /// Everything below it is x-rayed: in the front as if shown, drawn
    /// translucent, no occluder.
    XRay = 3,
}

/// A whole rep's triangles, as a range of [`DrawParts`].
pub const WHOLE: Range<u32> = 0..u32::MAX / 3;

/// How the renderer draws reps that are not simply opaque: per rep (sorted
/// by rep id), the triangle ranges drawn opaque and those drawn x-rayed.
/// A rep in neither list is drawn whole and opaque; a rep in `opaque` only
/// draws those ranges (an empty list: nothing opaque).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DrawParts {
    pub opaque: Vec<(RepId, Vec<Range<u32>>)>,
    pub xray: Vec<(RepId, Vec<Range<u32>>)>,
}

/// The nodes' visibility for a set of hidden or x-rayed objects.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Hiding {
    nodes: Vec<NodeVis>,
    parts: DrawParts,
    hidden_objects: usize,
    xray_objects: usize,
}

impl Hiding {
    /// Nothing hidden in a scene of `node_count` nodes.
    pub fn none(node_count: usize) -> Self {
        Self {
            nodes: vec![NodeVis::Shown; node_count],
            ..Self::default()
        }
    }

    /// The visibility of every node when the objects `k` with
    /// `hidden(k)` are hidden.
    pub fn new(s: &Skeleton, table: &ObjectTable, hidden: impl Fn(u32) -> bool) -> Self {
        Self::with_looks(
            s,
            table,
            |k| {
                if hidden(k) { Look::Hidden } else { Look::Shown }
            },
        )
    }

    /// The visibility of every node when object `k` looks `look(k)`.
    /// Leaves that name no object (a version-1 scene) stay shown.
    pub fn with_looks(s: &Skeleton, table: &ObjectTable, look: impl Fn(u32) -> Look) -> Self {
        let n = s.nodes.len();
        let mut out = Self::none(n);
        for k in 0..table.len() as u32 {
            match look(k) {
                Look::Hidden => out.hidden_objects += 1,
                Look::XRay => out.xray_objects += 1,
                Look::Shown => {}
            }
        }
        if out.hidden_objects + out.xray_objects == 0 {
            return out;
        }
        let vis_of = |k: u32| match look(k) {
            Look::Shown => NodeVis::Shown,
            Look::Hidden => NodeVis::Hidden,
            Look::XRay => NodeVis::XRay,
        };
        // Children come after their parents: a reverse sweep sees every
        // child before its parent.
        for i in (0..n).rev() {
            let node = &s.nodes[i];
            let vis = if node.child_count > 0 {
                let c = node.first_child as usize;
                let kids = &out.nodes[c..c + node.child_count as usize];
                combine(kids.iter().copied())
            } else if node.object != NONE {
                vis_of(node.object)
            } else {
                let runs = table.runs_of(i as u32);
                let vis = combine(runs.iter().map(|r| vis_of(r.object)));
                if vis == NodeVis::Mixed && node.rep_count > 0 {
                    let finest = node.first_rep + node.rep_count - 1;
                    let ranges = |want: NodeVis| {
                        let mut out: Vec<Range<u32>> = Vec::new();
                        let mut start = 0;
                        for r in runs {
                            if vis_of(r.object) == want && start < r.tri_end {
                                match out.last_mut() {
                                    Some(last) if last.end == start => last.end = r.tri_end,
                                    _ => out.push(start..r.tri_end),
                                }
                            }
                            start = r.tri_end;
                        }
                        out
                    };
                    out.parts.opaque.push((finest, ranges(NodeVis::Shown)));
                    let xray = ranges(NodeVis::XRay);
                    if !xray.is_empty() {
                        out.parts.xray.push((finest, xray));
                    }
                }
                vis
            };
            if vis == NodeVis::XRay {
                for r in node.first_rep..node.first_rep + node.rep_count {
                    out.parts.opaque.push((r, Vec::new()));
                    out.parts.xray.push((r, vec![WHOLE]));
                }
            }
            out.nodes[i] = vis;
        }
        out.parts.opaque.sort_by_key(|(r, _)| *r);
        out.parts.xray.sort_by_key(|(r, _)| *r);
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

    /// How many objects are x-rayed.
    pub fn xray_objects(&self) -> usize {
        self.xray_objects
    }

    /// How the renderer draws the reps of x-rayed nodes and of merged
    /// leaves drawn in part.
    pub fn parts(&self) -> &DrawParts {
        &self.parts
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
