//! View-dependence trees (El-Sana & Varshney; El-Sana & Chiang §2.1.1,
//! §3.3.5): a vertex hierarchy built bottom-up by half-edge collapses in
//! shortest-first order under a metric.
//!
//! - Vertex ids: the welded input vertices are `0..n`; every collapse makes a
//!   parent whose id is one more than the largest so far, so ids increase
//!   toward the roots. The parent takes its **left** child's position, so only
//!   leaves carry coordinates.
//! - A node's **switch value** is its collapse error (quadric error, or the
//!   edge length), made monotone: never below its children's.
//! - **Implicit dependencies** (§3.3.5), two integers per node: the largest id
//!   of the vertices adjacent to the parent right after the collapse (a split
//!   of p is safe when p's id exceeds its active neighbours'), and the smallest
//!   parent id of those collapse-boundary vertices (a collapse is safe when the
//!   parent's id is below it).
//! - Triangles are kept as triples of leaf ids; at run time a triangle is
//!   shown when its three leaves have three distinct active ancestors. Each
//!   node lists the triangles its collapse removed (its *adjacent* triangles,
//!   added back on a split), so refining every node gives back the input mesh.
//! - Collapses that would flip a triangle's normal or break the link condition
//!   of a manifold edge are refused; when no valid collapse remains, the rest
//!   are roots: the result is a forest. Non-manifold edges and fans are
//!   allowed (no link condition is asked of them).

mod build;
pub mod meta;
#[cfg(test)]
mod tests;

pub use build::{Metric, VdtParams, build_tree};

/// No node.
pub const NONE: u32 = u32::MAX;

/// One node of the vertex hierarchy. Nodes `0..leaf_count` are the leaves.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct VdNode {
    pub parent: u32,
    /// Children (`NONE` for leaves); the left child's position is the node's.
    pub left: u32,
    pub right: u32,
    /// Metric value at which the node is split (monotone toward the roots).
    pub switch: f32,
    /// Largest id adjacent to this node right after it was created (leaves: 0).
    pub max_adjacent: u32,
    /// Smallest parent id of the collapse-boundary vertices (`NONE` if they
    /// are all roots).
    pub min_boundary_parent: u32,
    /// The leaf whose position this node uses.
    pub leaf: u32,
}
const _: () = assert!(std::mem::size_of::<VdNode>() == 28);

/// A forest of view-dependence trees over one mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct VdTree {
    /// Welded leaf positions.
    pub positions: Vec<[f32; 3]>,
    /// Triangles as leaf ids.
    pub triangles: Vec<[u32; 3]>,
    pub nodes: Vec<VdNode>,
    /// `adjacent[i]` lists the triangles removed by the collapse that made
    /// node `leaf_count + i`.
    pub adjacent: Vec<Vec<u32>>,
    /// Triangles that no collapse removed (shown even at the roots).
    pub permanent: Vec<u32>,
    /// The roots, ascending.
    pub roots: Vec<u32>,
}

impl VdTree {
    /// Number of input (welded) vertices.
    pub fn leaf_count(&self) -> usize {
        self.positions.len()
    }

    /// Checks the hierarchy: ids increase toward the roots, every input
    /// vertex is a leaf, children point back to their parent, switch values
    /// never decrease upward, every triangle is removed by exactly one
    /// collapse or is permanent, and the dependency data is consistent.
    pub fn validate(&self) -> Result<(), String> {
        let n = self.leaf_count();
        if self.nodes.len() < n || self.adjacent.len() != self.nodes.len() - n {
            return Err("node or adjacency count inconsistent".into());
        }
        let mut roots = Vec::new();
        for (i, nd) in self.nodes.iter().enumerate() {
            let i = i as u32;
            let leaf = (i as usize) < n;
            if leaf != (nd.left == NONE && nd.right == NONE) {
                return Err(format!("node {i}: leaves are exactly the input vertices"));
            }
            if !leaf {
                for c in [nd.left, nd.right] {
                    let Some(ch) = self.nodes.get(c as usize) else {
                        return Err(format!("node {i}: child {c} out of range"));
                    };
                    if c >= i || ch.parent != i {
                        return Err(format!("node {i}: child {c} not below it"));
                    }
                    if ch.switch > nd.switch {
                        return Err(format!("node {i}: switch below child {c}'s"));
                    }
                }
                if nd.leaf != self.nodes[nd.left as usize].leaf {
                    return Err(format!("node {i}: does not use its left child's position"));
                }
                if nd.max_adjacent != NONE && nd.max_adjacent >= i {
                    return Err(format!("node {i}: an adjacent vertex is newer than it"));
                }
                if nd.min_boundary_parent != NONE && nd.min_boundary_parent <= i {
                    return Err(format!("node {i}: a boundary parent is older than it"));
                }
            } else if nd.leaf != i {
                return Err(format!("leaf {i}: position index {}", nd.leaf));
            }
            if nd.parent == NONE {
                roots.push(i);
            } else if nd.parent <= i || nd.parent as usize >= self.nodes.len() {
                return Err(format!("node {i}: parent {} not above it", nd.parent));
            }
            if !nd.switch.is_finite() || nd.switch < 0.0 {
                return Err(format!("node {i}: switch value {}", nd.switch));
            }
        }
        if roots != self.roots {
            return Err("root list does not match the parent links".into());
        }
        let mut seen = vec![0u8; self.triangles.len()];
        for &t in self.adjacent.iter().flatten().chain(&self.permanent) {
            match seen.get_mut(t as usize) {
                Some(s) => *s += 1,
                None => return Err(format!("triangle {t} out of range")),
            }
        }
        if let Some(t) = seen.iter().position(|&s| s != 1) {
            return Err(format!("triangle {t} listed {} times", seen[t]));
        }
        if self.triangles.iter().flatten().any(|&v| v as usize >= n) {
            return Err("a triangle corner is not a leaf".into());
        }
        Ok(())
    }

    /// The active node above `leaf` when `active` marks the active nodes.
    pub fn active_ancestor(&self, leaf: u32, active: &[bool]) -> u32 {
        let mut v = leaf;
        while !active[v as usize] {
            v = self.nodes[v as usize].parent;
        }
        v
    }

    /// Triangles shown when the nodes marked in `active` form a cut (every
    /// leaf has exactly one active ancestor-or-self): those whose corners
    /// have three distinct active ancestors, as active node ids.
    pub fn cut_triangles(&self, active: &[bool]) -> Vec<[u32; 3]> {
        self.triangles
            .iter()
            .filter_map(|t| {
                let a = t.map(|v| self.active_ancestor(v, active));
                (a[0] != a[1] && a[1] != a[2] && a[0] != a[2]).then_some(a)
            })
            .collect()
    }
}
