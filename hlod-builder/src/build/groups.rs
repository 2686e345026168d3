//! Leaves that repeat (format version 6): two leaves whose instances place
//! the same meshes the same way relative to each other (one instance of a
//! mesh placed several times, or a merged leaf of a tiled or repeated
//! assembly) share one LOD chain, computed once in the frame of one of the
//! leaf's instances and placed by each leaf with that instance's transform.
//!
//! A leaf's **signature** is its instances' meshes and their transforms
//! relative to its frame instance (the one of the smallest mesh id, then
//! the lowest position), rounded to a grid (2⁻¹⁴ of the scene's diagonal
//! for translations, 2⁻¹² for the linear part), sorted. Leaves of equal
//! signatures share the chain of the first of them in node order, the
//! group's **representative**, whose geometry it is exactly. Another leaf's
//! instances may sit up to the grid's rounding away from where the chain
//! puts them: that distance, measured on each mesh's box, is added to the
//! errors of its reps ([`LeafPlace::deviation`]).

use std::collections::BTreeMap;

use glam::{DMat4, Mat4, Vec3};

use super::leaf::Item;
use crate::cluster::TreeNode;
use crate::import::Imported;
use crate::mesh::Aabb;

/// An instance of a mesh placed more than once and of at least this many
/// triangles is a leaf of its own (not merged with its neighbours), so that
/// its levels are shared by every placement; smaller ones cost more in
/// records (a rep and a placement: 120 B in core) than their copies.
pub(super) const ALONE_MIN_TRIS: usize = 256;
// (64 was measured too: 3.1× less rep data on the tiled Schependomlaan, but a
// skeleton 4× larger than 256's and a larger file; docs/results.md.)

/// The clustering's items with every instance of a shared mesh of at least
/// [`ALONE_MIN_TRIS`] triangles counted as too large to merge: the graph
/// then gives each a leaf of its own, which [`plan`] groups by mesh.
pub(super) fn alone(
    cluster: &[crate::cluster::ClusterItem],
    items: &[Item],
    leaf_tris: usize,
) -> Vec<crate::cluster::ClusterItem> {
    let mut placed: BTreeMap<usize, usize> = BTreeMap::new();
    for it in items {
        if let Item::Instance { mesh, .. } = it {
            *placed.entry(*mesh).or_default() += 1;
        }
    }
    cluster
        .iter()
        .zip(items)
        .map(|(c, it)| {
            let mut c = *c;
            if let Item::Instance { mesh, .. } = it
                && placed[mesh] > 1
                && c.tris >= ALONE_MIN_TRIS
            {
                c.tris = c.tris.max(leaf_tris + 1);
            }
            c
        })
        .collect()
}

/// One instance of a signature: its mesh and its rounded relative transform.
type Key = (usize, [i64; 12]);

/// A leaf of a signature: its node, frame transform, items in signature
/// order and their exact transforms relative to the frame.
type Keyed = (usize, Mat4, Vec<u32>, Vec<Mat4>);

/// Leaves of one signature: the representative's instances in signature
/// order, each with its mesh and exact transform relative to the frame.
#[derive(Clone, Debug)]
pub(super) struct GroupPlan {
    pub parts: Vec<(usize, Mat4)>,
    /// The representative's node: its reps own the chain's payloads
    /// (whichever leaf is made first writes them), so the output does not
    /// depend on the order the cells are made in.
    pub owner: u32,
}

/// How a leaf places its group's chain.
#[derive(Clone, Debug)]
pub(super) struct LeafPlace {
    pub group: u32,
    /// The frame instance's transform: the chain's coordinates to the scene's.
    pub frame: Mat4,
    /// The leaf's items in signature order (the order of the chain's runs).
    pub order: Vec<u32>,
    /// How far, in the frame's units, this leaf's instances may lie from
    /// where the chain puts them (0 for the representative).
    pub deviation: f32,
}

/// Every repeated leaf's group, and the groups.
#[derive(Debug, Default)]
pub(super) struct Plan {
    pub groups: Vec<GroupPlan>,
    pub leaves: BTreeMap<usize, LeafPlace>,
}

/// The repeated leaves' groups ([`groups::plan`]) and each group's chain,
/// in its frame: a single instance's as its mesh's, a merged leaf's with
/// each instance optimised on its own (its triangles one run, as
/// [`super::leaf::leaf_levels`] makes them), with the per-instance triangle counts.
pub(super) fn chains<S: super::SceneSource>(
    src: &S,
    tree: &[crate::cluster::TreeNode],
    items: &[Item],
    params: &super::BuildParams,
) -> Result<super::assemble::Groups, engine::FormatError> {
    use rayon::prelude::*;
    let plan = plan(src.scene(), tree, items);
    let chains = plan
        .groups
        .par_iter()
        .map(|g| {
            if let [(m, _)] = g.parts.as_slice() {
                return Ok((
                    crate::lod::lod_chain(&*src.mesh(*m)?, &params.lod),
                    Vec::new(),
                ));
            }
            let mut parts = Vec::with_capacity(g.parts.len());
            for (m, rel) in &g.parts {
                parts.push(crate::lod::optimize(&src.mesh(*m)?.transformed(rel)));
            }
            let tris = parts.iter().map(|p| p.tri_count() as u32).collect();
            Ok((
                crate::lod::lod_chain_from(crate::mesh::Mesh::merge(&parts), &params.lod),
                tris,
            ))
        })
        .collect::<Result<Vec<_>, engine::FormatError>>()?;
    Ok(super::assemble::Groups {
        places: plan.leaves,
        owners: plan.groups.iter().map(|g| g.owner).collect(),
        chains,
    })
}

/// The groups of `tree`'s leaves made only of instances, of two leaves or more.
pub(super) fn plan(scene: &Imported, tree: &[TreeNode], items: &[Item]) -> Plan {
    let mut world = Aabb::EMPTY;
    for inst in &scene.instances {
        if let Some(m) = scene.meta[inst.mesh] {
            let b = super::leaf::transformed_bounds(m.bounds, &inst.transform);
            world.add(b.min);
            world.add(b.max);
        }
    }
    let diag = (world.max - world.min).length();
    let grid = if diag.is_finite() && diag > 0.0 {
        diag / 16384.0
    } else {
        1.0
    };
    // Each eligible leaf's signature, frame and order, in node order.
    let mut by_key: BTreeMap<Vec<Key>, Vec<Keyed>> = BTreeMap::new();
    for (i, node) in tree.iter().enumerate() {
        if node.items.is_empty() {
            continue;
        }
        let mut inst: Vec<(u32, usize, Mat4)> = Vec::with_capacity(node.items.len());
        for &k in &node.items {
            match &items[k as usize] {
                Item::Instance {
                    mesh, transform, ..
                } => inst.push((k, *mesh, *transform)),
                _ => break,
            }
        }
        if inst.len() != node.items.len() {
            continue;
        }
        let frame_at = (0..inst.len())
            .min_by_key(|&j| (inst[j].1, round3(inst[j].2.w_axis.truncate(), grid)))
            .expect("a leaf has items");
        let frame = inst[frame_at].2;
        let inv = frame.as_dmat4().inverse();
        let mut keyed: Vec<(Key, u32, Mat4)> = inst
            .iter()
            .map(|&(k, m, t)| {
                let rel = (inv * t.as_dmat4()).as_mat4();
                ((m, round_affine(&rel, grid)), k, rel)
            })
            .collect();
        keyed.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.cmp(&b.1)));
        let key: Vec<Key> = keyed.iter().map(|x| x.0).collect();
        let order = keyed.iter().map(|x| x.1).collect();
        let rels = keyed.iter().map(|x| x.2).collect();
        by_key.entry(key).or_default().push((i, frame, order, rels));
    }
    // Groups by their representative's node, so the output is in node order.
    let mut repeated: Vec<_> = by_key.into_values().filter(|v| v.len() > 1).collect();
    repeated.sort_by_key(|v| v[0].0);
    let mut out = Plan::default();
    for (g, leaves) in repeated.into_iter().enumerate() {
        let (_, _, ref rep_order, ref rep_rels) = leaves[0];
        let parts: Vec<(usize, Mat4)> = rep_order
            .iter()
            .zip(rep_rels)
            .map(|(&k, &rel)| match &items[k as usize] {
                Item::Instance { mesh, .. } => (*mesh, rel),
                _ => unreachable!("groups hold instances only"),
            })
            .collect();
        for (i, frame, order, rels) in &leaves {
            let deviation = parts
                .iter()
                .zip(rels)
                .map(|(&(m, a), b)| {
                    let bounds = scene.meta[m].map_or(Aabb::EMPTY, |x| x.bounds);
                    distance_on_box(&a, b, &bounds)
                })
                .fold(0f32, f32::max);
            out.leaves.insert(
                *i,
                LeafPlace {
                    group: g as u32,
                    frame: *frame,
                    order: order.clone(),
                    deviation,
                },
            );
        }
        out.groups.push(GroupPlan {
            parts,
            owner: leaves[0].0 as u32,
        });
    }
    out
}

fn round3(v: Vec3, grid: f32) -> [i64; 3] {
    v.to_array()
        .map(|x| (f64::from(x) / f64::from(grid)).round() as i64)
}

fn round_affine(m: &Mat4, grid: f32) -> [i64; 12] {
    let lin = |x: f32| (f64::from(x) * 4096.0).round() as i64;
    let t = round3(m.w_axis.truncate(), grid);
    [
        lin(m.x_axis.x),
        lin(m.x_axis.y),
        lin(m.x_axis.z),
        lin(m.y_axis.x),
        lin(m.y_axis.y),
        lin(m.y_axis.z),
        lin(m.z_axis.x),
        lin(m.z_axis.y),
        lin(m.z_axis.z),
        t[0],
        t[1],
        t[2],
    ]
}

/// The largest distance between where `a` and `b` put a corner of `bounds`
/// (an affine map's difference is largest at a corner of a box).
fn distance_on_box(a: &Mat4, b: &Mat4, bounds: &Aabb) -> f32 {
    if bounds.min.x > bounds.max.x {
        return 0.0;
    }
    let d: DMat4 = a.as_dmat4() - b.as_dmat4();
    bounds
        .corners()
        .iter()
        .map(|c| (d * c.as_dvec3().extend(1.0)).truncate().length() as f32)
        .fold(0f32, f32::max)
}
