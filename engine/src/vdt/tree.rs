//! The in-memory view-dependence forest and its checks.

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
    /// The leaf whose position this node uses: the first leaf of its subtree
    /// (leaves are numbered depth-first, left child first).
    pub leaf: u32,
    /// One past the last leaf of its subtree: the subtree's leaves are
    /// `leaf..leaf_end`.
    pub leaf_end: u32,
    /// Radius of a sphere around the node's position that holds its whole
    /// subtree's surface (0 for leaves).
    pub radius: f32,
}
const _: () = assert!(std::mem::size_of::<VdNode>() == 36);

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
    /// vertex is a leaf, leaves are numbered depth-first (every node's leaves
    /// are `leaf..leaf_end`, the roots' intervals tile all leaves), bounding
    /// radii nest, children point back to their parent, switch values
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
                let (l, r) = (
                    &self.nodes[nd.left as usize],
                    &self.nodes[nd.right as usize],
                );
                if nd.leaf != l.leaf || l.leaf_end != r.leaf || r.leaf_end != nd.leaf_end {
                    return Err(format!("node {i}: leaf interval not its children's"));
                }
                let at = |x: &VdNode| glam::Vec3::from(self.positions[x.leaf as usize]);
                for ch in [l, r] {
                    let need = at(nd).distance(at(ch)) + ch.radius;
                    if nd.radius < need * (1.0 - 1e-5) - 1e-6 {
                        return Err(format!("node {i}: radius does not hold a child's"));
                    }
                }
                if nd.max_adjacent != NONE && nd.max_adjacent >= i {
                    return Err(format!("node {i}: an adjacent vertex is newer than it"));
                }
                if nd.min_boundary_parent != NONE && nd.min_boundary_parent <= i {
                    return Err(format!("node {i}: a boundary parent is older than it"));
                }
            } else if nd.leaf != i || nd.leaf_end != i + 1 || nd.radius != 0.0 {
                return Err(format!("leaf {i}: position index or interval"));
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
        // The roots' leaf intervals tile 0..n in root order.
        let mut next = 0;
        for &r in &roots {
            let nd = &self.nodes[r as usize];
            if nd.leaf != next {
                return Err(format!("root {r}: leaves start at {}, not {next}", nd.leaf));
            }
            next = nd.leaf_end;
        }
        if next as usize != n {
            return Err("root intervals do not cover the leaves".into());
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
