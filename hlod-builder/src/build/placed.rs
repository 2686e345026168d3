//! Leaves that place a shared chain (format version 6): the leaves of a
//! group ([`super::groups`]) have one LOD chain, computed once in the
//! group's frame, its payloads written once (by the first of its leaves to
//! be made, in the name of its first leaf in node order, whose reps own
//! them: the output does not depend on the order of the cells), and every
//! leaf's reps name those
//! payloads with the leaf's transform ([`RepPlacement`]). A rep keeps its
//! own box in scene coordinates (its level's vertices placed), and its own
//! error: the level's error in the frame's units, quantisation included,
//! plus how far the leaf's instances may lie from the chain's, times the
//! transform's largest stretch. HLODs above are made from the placed
//! coarsest level, as from any leaf's.

use glam::{Mat4, Vec3};

use engine::format::{RepPlacement, RepRecord};
use engine::skeleton::Skeleton;

use super::leaf::max_scale;
use crate::lod::{Level, strictly_above};
use crate::mesh::{Aabb, Mesh};

/// What a leaf placing a shared chain computes in the parallel part.
pub(super) struct PlacedLeaf {
    /// The group whose chain it places.
    pub group: usize,
    pub transform: Mat4,
    /// Added to every level's error, in the frame's units.
    pub deviation: f32,
    /// Each level's box in scene coordinates, coarsest first.
    pub boxes: Vec<Aabb>,
    /// The coarsest level placed: its parent's HLOD input.
    pub coarse: Mesh,
}

impl PlacedLeaf {
    /// The leaf that places `chain` (in the mesh's coordinates) by `transform`.
    pub fn new(group: usize, chain: &[Level], transform: Mat4, deviation: f32) -> Self {
        let boxes = chain
            .iter()
            .map(|l| {
                let mut b = Aabb::EMPTY;
                for &i in &l.mesh.indices {
                    b.add(transform.transform_point3(Vec3::from(l.mesh.positions[i as usize])));
                }
                b
            })
            .collect();
        Self {
            group,
            transform,
            deviation,
            boxes,
            coarse: chain[0].mesh.transformed(&transform),
        }
    }

    /// The leaf's records, coarsest first: `owned`'s payload ranges and
    /// counts (the chain as written, errors in the mesh's units), this
    /// leaf's node, index, box and scaled errors, strictly decreasing.
    pub fn records(&self, node: u32, owned: &[RepRecord]) -> Vec<RepRecord> {
        let scale = max_scale(&self.transform);
        let mut recs: Vec<RepRecord> = owned.to_vec();
        let mut below: Option<f32> = None;
        for (i, r) in recs.iter_mut().enumerate().rev() {
            let e = (r.error + self.deviation) * scale;
            r.error = below.map_or(e, |b| strictly_above(b, e));
            below = Some(r.error);
            (r.bbox_min, r.bbox_max) = self.boxes[i].to_arrays();
            r.node = node;
            r.index = i as u16;
        }
        recs
    }

    /// The rows of the leaf's transform, as a placement stores them.
    pub fn rows(&self) -> [[f32; 4]; 3] {
        let m = self.transform;
        std::array::from_fn(|i| {
            let r = m.row(i);
            [r.x, r.y, r.z, r.w]
        })
    }
}

/// A shared chain once written: the node whose reps own its payloads and
/// its records in the mesh's units.
pub(super) struct Written {
    pub owner: u32,
    pub recs: Vec<RepRecord>,
}

/// A placement named by nodes, resolved to reps once they are numbered.
#[derive(Clone, Copy, Debug)]
pub(super) struct Pending {
    pub node: u32,
    pub index: u16,
    pub owner: u32,
    pub rows: [[f32; 4]; 3],
}

/// `pending` as the skeleton's placements (sorted by rep), now that its
/// nodes' reps are numbered.
pub(super) fn resolve(skeleton: &mut Skeleton, pending: &[Pending]) {
    let rep = |node: u32, index: u16| skeleton.nodes[node as usize].first_rep + u32::from(index);
    let mut out: Vec<RepPlacement> = pending
        .iter()
        .map(|p| RepPlacement {
            rep: rep(p.node, p.index),
            source: rep(p.owner, p.index),
            transform: p.rows,
        })
        .collect();
    out.sort_unstable_by_key(|p| p.rep);
    skeleton.placements = out;
}
