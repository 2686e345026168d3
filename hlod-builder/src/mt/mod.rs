//! Construction of Multi-Triangulations (Holst & Schumann §3) as a cluster
//! DAG ([`dag`]): the mesh is split into clusters, neighbouring clusters
//! are grouped, each group is simplified with its border locked and the
//! result split into new clusters, level after level. Each
//! simplified group is one MT node (a local simplification), each cluster
//! one patch of triangles between the group that made it and the group it
//! is in, so every arc holds a whole cluster or more and the hierarchy is
//! born *reduced* (§3.1: the paper collapses arcs of an edge-collapse MT
//! until patches average 10 triangles; here they average about half of the
//! cluster size). Groups the simplifier cannot reduce are always refined:
//! they join the root. Errors and spheres are made monotone bottom-up, so
//! the screen-space test of a father is never below a child's.
//!
//! The input's border is locked too, so no level closes a hole, and every
//! cut is crack-free ([`Mt::validate`], [`Mt::check_cut`]).

use std::collections::{BTreeMap, HashMap};

use engine::mt::{DRAIN, Mt, MtArc, MtNode};

mod dag;
mod rep;

pub use rep::{MtRepParams, mt_levels};

use dag::{Clusters, Group, enclose as enclose_spheres};

/// Parameters of [`build_mt`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MtParams {
    /// Largest cluster, in triangles (8..=256).
    pub cluster_tris: usize,
    /// Clusters simplified together in one node (the builder's target;
    /// groups may be up to a third larger), 2..=64.
    pub group_clusters: usize,
}

impl Default for MtParams {
    fn default() -> Self {
        Self {
            cluster_tris: 16,
            group_clusters: 8,
        }
    }
}

/// Why no Multi-Triangulation was built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MtBuildError {
    #[error("the mesh has no triangle")]
    Empty,
    #[error("cluster size {0} is outside 8..=256 triangles")]
    ClusterSize(usize),
    #[error("group size {0} is outside 2..=64 clusters")]
    GroupSize(usize),
    #[error("triangle {0} indexes past the {1} vertices")]
    Index(usize, usize),
    #[error("vertex {0} is not finite")]
    NotFinite(usize),
    #[error("the mesh is too large for a Multi-Triangulation ({0})")]
    TooLarge(String),
}

/// Builds the Multi-Triangulation of an indexed mesh (deterministic).
/// Degenerate triangles are dropped first; a mesh with no valid
/// simplification gives an MT of one node whose arcs hold the whole input.
pub fn build_mt(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    indices: &[u32],
    p: &MtParams,
) -> Result<Mt, MtBuildError> {
    if !(8..=256).contains(&p.cluster_tris) {
        return Err(MtBuildError::ClusterSize(p.cluster_tris));
    }
    if !(2..=64).contains(&p.group_clusters) {
        return Err(MtBuildError::GroupSize(p.group_clusters));
    }
    if let Some(v) = positions
        .iter()
        .position(|v| v.iter().any(|c| !c.is_finite()))
    {
        return Err(MtBuildError::NotFinite(v));
    }
    if positions.len() >= u32::MAX as usize / 2 {
        return Err(MtBuildError::TooLarge(format!(
            "{} vertices",
            positions.len()
        )));
    }
    let mut tris: Vec<u32> = Vec::with_capacity(indices.len());
    for (t, c) in indices.chunks_exact(3).enumerate() {
        if c.iter().any(|&v| v as usize >= positions.len()) {
            return Err(MtBuildError::Index(t, positions.len()));
        }
        if c[0] != c[1] && c[1] != c[2] && c[0] != c[2] {
            tris.extend_from_slice(c);
        }
    }
    if tris.is_empty() {
        return Err(MtBuildError::Empty);
    }
    let weld = weld_by_position(positions);
    let locks = border_locks(&weld, &tris);
    let (groups, clusters) = dag::build(
        positions,
        &tris,
        &weld,
        &locks,
        p.cluster_tris,
        p.group_clusters,
    );
    Ok(assemble(
        positions,
        normals,
        &groups,
        &clusters,
        (tris.len() / 3) as u64,
    ))
}

fn weld_by_position(positions: &[[f32; 3]]) -> Vec<u32> {
    let mut weld: HashMap<[u32; 3], u32> = HashMap::new();
    positions
        .iter()
        .map(|p| {
            let next = weld.len() as u32;
            *weld.entry(p.map(f32::to_bits)).or_insert(next)
        })
        .collect()
}

/// Locks the vertices on the input's border (edges of one triangle, by
/// position), so that no level closes a hole: every cut keeps the input's
/// topology.
fn border_locks(w: &[u32], tris: &[u32]) -> Vec<bool> {
    let mut uses: HashMap<(u32, u32), u32> = HashMap::new();
    for t in tris.chunks_exact(3) {
        for k in 0..3 {
            let (a, b) = (w[t[k] as usize], w[t[(k + 1) % 3] as usize]);
            *uses.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut border = vec![false; w.len()];
    for (&(a, b), &c) in &uses {
        if c == 1 {
            border[a as usize] = true;
            border[b as usize] = true;
        }
    }
    w.iter().map(|&x| border[x as usize]).collect()
}

/// Turns groups and clusters into the node-and-arc graph.
fn assemble(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    groups: &[Group],
    clusters: &Clusters,
    input_triangles: u64,
) -> Mt {
    // Node of a group: terminal groups are the root (usize::MAX marks it).
    const ROOT: usize = usize::MAX;
    let node_of = |g: u32| {
        if groups[g as usize].terminal {
            ROOT
        } else {
            g as usize
        }
    };
    // Arcs keyed by (father group, child group or -1).
    let mut arcs: BTreeMap<(usize, i64), Vec<[u32; 3]>> = BTreeMap::new();
    for (g, refined, idx) in clusters {
        let key = (node_of(*g), i64::from(*refined));
        let e = arcs.entry(key).or_default();
        e.extend(idx.chunks_exact(3).map(|t| [t[0], t[1], t[2]]));
    }
    // Layers top-down: fathers have larger group ids (or are the root).
    let mut layer = vec![0u32; groups.len()];
    let mut fathers_of: Vec<Vec<usize>> = vec![Vec::new(); groups.len()];
    for &(f, c) in arcs.keys() {
        if c >= 0 {
            fathers_of[c as usize].push(f);
        }
    }
    for g in (0..groups.len()).rev() {
        if groups[g].terminal {
            continue;
        }
        layer[g] = fathers_of[g]
            .iter()
            .map(|&f| if f == ROOT { 1 } else { layer[f] + 1 })
            .max()
            .unwrap_or(1);
    }
    // Monotone bounds bottom-up: children have smaller group ids.
    let node = |g: usize| MtNode {
        layer: layer[g],
        error: groups[g].error,
        center: groups[g].center,
        radius: groups[g].radius,
    };
    let mut nodes: Vec<MtNode> = (0..groups.len()).map(node).collect();
    let mut root = MtNode {
        layer: 0,
        error: f32::INFINITY,
        center: [0.0; 3],
        radius: -1.0,
    };
    for &(f, c) in arcs.keys() {
        if c < 0 {
            continue;
        }
        let child = nodes[c as usize];
        let father = if f == ROOT { &mut root } else { &mut nodes[f] };
        enclose(father, &child);
    }
    // Node ids: the root, then groups by (layer, group id).
    let mut order: Vec<usize> = (0..groups.len()).filter(|&g| !groups[g].terminal).collect();
    order.sort_by_key(|&g| (layer[g], g));
    let mut id = vec![u32::MAX; groups.len()];
    for (k, &g) in order.iter().enumerate() {
        id[g] = k as u32 + 1;
    }
    let to_id = |g: usize| if g == ROOT { 0 } else { id[g] };
    let mut out_nodes = Vec::with_capacity(order.len() + 1);
    if root.radius < 0.0 {
        root.radius = 0.0;
    }
    // The root's sphere also holds its drain arcs' triangles.
    let mut all: Vec<(u32, u32, Vec<[u32; 3]>)> = arcs
        .into_iter()
        .map(|((f, c), t)| (to_id(f), if c < 0 { DRAIN } else { id[c as usize] }, t))
        .collect();
    all.sort_by_key(|a| (a.0, a.1));
    for a in all.iter().filter(|a| a.0 == 0) {
        for t in &a.2 {
            for &v in t {
                let p = MtNode {
                    layer: 0,
                    error: 0.0,
                    center: positions[v as usize],
                    radius: 0.0,
                };
                enclose(&mut root, &p);
            }
        }
    }
    out_nodes.push(root);
    out_nodes.extend(order.iter().map(|&g| nodes[g]));
    let mut out_start = vec![0u32; out_nodes.len() + 1];
    for a in &all {
        out_start[a.0 as usize + 1] += 1;
    }
    for k in 1..out_start.len() {
        out_start[k] += out_start[k - 1];
    }
    Mt {
        positions: positions.to_vec(),
        normals: normals.to_vec(),
        nodes: out_nodes,
        arcs: all
            .into_iter()
            .map(|(father, child, triangles)| MtArc {
                father,
                child,
                triangles,
            })
            .collect(),
        out_start,
        input_triangles,
    }
}

/// Grows `f`'s sphere to hold `c`'s and its error to `c`'s.
fn enclose(f: &mut MtNode, c: &MtNode) {
    f.error = f.error.max(c.error);
    if f.radius < 0.0 {
        f.center = c.center;
        f.radius = c.radius;
        return;
    }
    (f.center, f.radius) = enclose_spheres((f.center, f.radius), (c.center, c.radius));
}
