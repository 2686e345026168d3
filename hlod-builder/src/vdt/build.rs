//! Construction of the view-dependence forest: weld, then collapse edges in
//! shortest-first order (a binary heap; entries of collapsed vertices are
//! skipped when popped), refusing fold-overs and link-condition violations.
//! A vertex's position and quadric never change (a collapse makes a new
//! vertex), so an entry's cost stays right until an endpoint dies; a refused
//! collapse waits beside its endpoints and is queued again when a collapse
//! changes their neighbourhood.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

use glam::DVec3;

use super::{NONE, VdNode, VdTree};

/// What "shortest" means.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Metric {
    /// Garland–Heckbert quadric error, area-weighted, as an RMS distance.
    #[default]
    Quadric,
    /// Euclidean edge length.
    EdgeLength,
}

/// Construction parameters.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VdtParams {
    pub metric: Metric,
    /// Stop collapsing at this switch value (a tree that only refines below
    /// a static LOD of this error); `None` collapses while any collapse is valid.
    pub max_switch: Option<f32>,
}

/// A collapse may not turn a triangle more than ≈75° away from its
/// full-resolution normal (a fold-over, or a sliver standing up on edge).
const MAX_TURN_COS: f64 = 0.25;

/// `(cost, tie-break, kept vertex, removed vertex)`.
type Candidate = Reverse<(u64, u64, u32, u32)>;

struct Builder {
    pos: Vec<DVec3>,
    /// Current corners (vertex ids) of every triangle, and whether alive.
    corners: Vec<[u32; 3]>,
    alive: Vec<bool>,
    /// Alive incident triangles per vertex id.
    incident: Vec<Vec<u32>>,
    quadric: Vec<[f64; 10]>,
    /// Each triangle's full-resolution normal: no collapse may turn a
    /// triangle against it (a fold-over of the surface).
    original_normal: Vec<DVec3>,
    /// Refused collapses `(keep, gone)` filed under both endpoints, and the
    /// set of those filed (each is filed once and retried once per change).
    blocked: Vec<Vec<(u32, u32)>>,
    filed: std::collections::HashSet<(u32, u32)>,
    dead: Vec<bool>,
    nodes: Vec<VdNode>,
    adjacent: Vec<Vec<u32>>,
    boundary: Vec<Vec<u32>>,
    heap: BinaryHeap<Candidate>,
    metric: Metric,
    tick: u64,
}

/// Builds the forest for a triangle mesh. Duplicate positions are welded,
/// triangles with repeated corners or zero area are dropped.
pub fn build_tree(positions: &[[f32; 3]], indices: &[u32], p: &VdtParams) -> VdTree {
    let (pos, tris) = weld(positions, indices);
    let n = pos.len();
    let mut b = Builder {
        pos: pos.iter().map(|q| DVec3::from(q.map(f64::from))).collect(),
        corners: tris.clone(),
        alive: vec![true; tris.len()],
        incident: vec![Vec::new(); n],
        quadric: vec![[0.0; 10]; n],
        original_normal: Vec::new(),
        blocked: vec![Vec::new(); n],
        filed: Default::default(),
        dead: vec![false; n],
        nodes: (0..n as u32)
            .map(|i| VdNode {
                parent: NONE,
                left: NONE,
                right: NONE,
                switch: 0.0,
                max_adjacent: 0,
                min_boundary_parent: NONE,
                leaf: i,
                leaf_end: i + 1,
                radius: 0.0,
            })
            .collect(),
        adjacent: Vec::new(),
        boundary: Vec::new(),
        heap: BinaryHeap::new(),
        metric: p.metric,
        tick: 0,
    };
    for (t, c) in tris.iter().enumerate() {
        for &v in c {
            b.incident[v as usize].push(t as u32);
        }
    }
    b.original_normal = tris
        .iter()
        .map(|&c| b.normal(c, NONE, DVec3::ZERO))
        .collect();
    b.init_quadrics();
    for v in 0..n as u32 {
        b.push_edges(v);
    }
    // Costs are non-negative f64s, ordered by their bits.
    let stop = p.max_switch.map(|s| f64::from(s).to_bits());
    while let Some(Reverse((cost, _, keep, gone))) = b.heap.pop() {
        if stop.is_some_and(|s| cost >= s) {
            break;
        }
        if b.dead[keep as usize] || b.dead[gone as usize] {
            continue;
        }
        if b.valid(keep, gone) {
            b.collapse(keep, gone);
        } else if b.filed.insert((keep, gone)) {
            b.blocked[keep as usize].push((keep, gone));
            b.blocked[gone as usize].push((keep, gone));
        }
    }
    b.finish(pos, tris)
}

fn weld(positions: &[[f32; 3]], indices: &[u32]) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut map: HashMap<[u32; 3], u32> = HashMap::new();
    let mut pos = Vec::new();
    let mut remap = Vec::with_capacity(positions.len());
    for p in positions {
        let key = p.map(|c| if c == 0.0 { 0 } else { c.to_bits() });
        let id = *map.entry(key).or_insert_with(|| {
            pos.push(*p);
            pos.len() as u32 - 1
        });
        remap.push(id);
    }
    let mut tris = Vec::new();
    for t in indices.chunks_exact(3) {
        let Some(c) = t
            .iter()
            .map(|&i| remap.get(i as usize).copied())
            .collect::<Option<Vec<u32>>>()
        else {
            continue;
        };
        let c = [c[0], c[1], c[2]];
        if c[0] == c[1] || c[1] == c[2] || c[0] == c[2] {
            continue;
        }
        let p = c.map(|v| glam::Vec3::from(pos[v as usize]));
        if (p[1] - p[0]).cross(p[2] - p[0]).length_squared() <= 0.0 {
            continue;
        }
        tris.push(c);
    }
    (pos, tris)
}

fn plane_quadric(n: DVec3, p: DVec3, w: f64) -> [f64; 10] {
    let d = -n.dot(p);
    let (a, b, c) = (n.x, n.y, n.z);
    [
        w * a * a,
        w * a * b,
        w * a * c,
        w * a * d,
        w * b * b,
        w * b * c,
        w * b * d,
        w * c * c,
        w * c * d,
        w * d * d,
    ]
}

fn add(q: &mut [f64; 10], r: &[f64; 10]) {
    for (x, y) in q.iter_mut().zip(r) {
        *x += y;
    }
}

fn eval(q: &[f64; 10], v: DVec3) -> f64 {
    let (x, y, z) = (v.x, v.y, v.z);
    q[0] * x * x
        + 2.0 * q[1] * x * y
        + 2.0 * q[2] * x * z
        + 2.0 * q[3] * x
        + q[4] * y * y
        + 2.0 * q[5] * y * z
        + 2.0 * q[6] * y
        + q[7] * z * z
        + 2.0 * q[8] * z
        + q[9]
}

impl Builder {
    fn normal(&self, c: [u32; 3], moved: u32, to: DVec3) -> DVec3 {
        let p = c.map(|v| if v == moved { to } else { self.pos[v as usize] });
        (p[1] - p[0]).cross(p[2] - p[0])
    }

    fn init_quadrics(&mut self) {
        let mut edge_count: HashMap<(u32, u32), u32> = HashMap::new();
        for c in &self.corners {
            for k in 0..3 {
                let (a, b) = (c[k], c[(k + 1) % 3]);
                *edge_count.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        for c in self.corners.clone() {
            let n = self.normal(c, NONE, DVec3::ZERO);
            let area2 = n.length();
            if area2 <= 0.0 {
                continue;
            }
            let unit = n / area2;
            let q = plane_quadric(unit, self.pos[c[0] as usize], area2 * 0.5);
            for &v in &c {
                add(&mut self.quadric[v as usize], &q);
            }
            // Borders: a plane through each boundary edge, perpendicular to
            // the face, keeps open borders from shrinking.
            for k in 0..3 {
                let (a, b) = (c[k], c[(k + 1) % 3]);
                if edge_count[&(a.min(b), a.max(b))] == 1 {
                    let e = self.pos[b as usize] - self.pos[a as usize];
                    let bn = e.cross(unit).normalize_or_zero();
                    let q = plane_quadric(bn, self.pos[a as usize], 10.0 * e.length_squared());
                    add(&mut self.quadric[a as usize], &q);
                    add(&mut self.quadric[b as usize], &q);
                }
            }
        }
    }

    fn neighbours(&self, v: u32) -> Vec<u32> {
        let mut out: Vec<u32> = self.incident[v as usize]
            .iter()
            .flat_map(|&t| self.corners[t as usize])
            .filter(|&u| u != v)
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Cost of collapsing `gone` into `keep` (which keeps its position).
    fn cost(&self, keep: u32, gone: u32) -> f64 {
        let (pk, pg) = (self.pos[keep as usize], self.pos[gone as usize]);
        match self.metric {
            Metric::EdgeLength => pk.distance(pg),
            Metric::Quadric => {
                let mut q = self.quadric[keep as usize];
                add(&mut q, &self.quadric[gone as usize]);
                // Area-weighted planes: divide by the total weight (the
                // trace of the normal part) for an RMS distance, so the
                // switch value is an object-space length at any scale.
                let w = (q[0] + q[4] + q[7]).max(1e-300);
                (eval(&q, pk).max(0.0) / w).sqrt()
            }
        }
    }

    fn push(&mut self, keep: u32, gone: u32) {
        let c = self.cost(keep, gone);
        self.tick += 1;
        self.heap
            .push(Reverse((c.to_bits(), self.tick, keep, gone)));
    }

    fn push_edges(&mut self, v: u32) {
        for u in self.neighbours(v) {
            // Both directions; the cheaper one is popped first.
            self.push(v, u);
            self.push(u, v);
        }
    }

    /// No flipped triangle, and the link condition on a manifold edge.
    fn valid(&self, keep: u32, gone: u32) -> bool {
        let to = self.pos[keep as usize];
        let mut shared = Vec::new();
        for &t in &self.incident[gone as usize] {
            let c = self.corners[t as usize];
            if c.contains(&keep) {
                shared.push(
                    c.into_iter()
                        .find(|&x| x != keep && x != gone)
                        .unwrap_or(NONE),
                );
                continue;
            }
            let before = self.normal(c, NONE, DVec3::ZERO);
            let after = self.normal(c, gone, to);
            if before.dot(after) <= 0.0
                || self.original_normal[t as usize].dot(after)
                    <= MAX_TURN_COS * self.original_normal[t as usize].length() * after.length()
                || after.length_squared() <= 1e-12 * before.length_squared()
            {
                return false;
            }
        }
        if shared.len() <= 2 {
            shared.sort_unstable();
            let nk = self.neighbours(keep);
            let ng = self.neighbours(gone);
            let common: Vec<u32> = nk
                .into_iter()
                .filter(|x| ng.binary_search(x).is_ok())
                .collect();
            if common != shared {
                return false;
            }
        }
        true
    }

    fn collapse(&mut self, keep: u32, gone: u32) {
        let p = self.nodes.len() as u32;
        let mut removed = Vec::new();
        let mut merged = Vec::new();
        for v in [keep, gone] {
            for t in std::mem::take(&mut self.incident[v as usize]) {
                if !self.alive[t as usize] {
                    continue;
                }
                let c = &mut self.corners[t as usize];
                if c.contains(&keep) && c.contains(&gone) {
                    self.alive[t as usize] = false;
                    removed.push(t);
                } else {
                    for x in c.iter_mut() {
                        if *x == keep || *x == gone {
                            *x = p;
                        }
                    }
                    merged.push(t);
                }
            }
        }
        removed.sort_unstable();
        removed.dedup();
        merged.sort_unstable();
        merged.dedup();
        // Drop the removed triangles from the third corners' lists.
        for &t in &removed {
            for x in self.corners[t as usize] {
                if x != keep && x != gone {
                    self.incident[x as usize].retain(|&s| s != t);
                }
            }
        }
        let cost = self.cost(keep, gone) as f32;
        let switch = cost
            .max(self.nodes[keep as usize].switch)
            .max(self.nodes[gone as usize].switch);
        let mut q = self.quadric[keep as usize];
        add(&mut q, &self.quadric[gone as usize]);
        self.pos.push(self.pos[keep as usize]);
        self.quadric.push(q);
        self.incident.push(merged);
        self.blocked.push(Vec::new());
        self.dead.push(false);
        for v in [keep, gone] {
            self.dead[v as usize] = true;
            self.nodes[v as usize].parent = p;
        }
        let nb = self.neighbours(p);
        self.nodes.push(VdNode {
            parent: NONE,
            left: keep,
            right: gone,
            switch,
            max_adjacent: nb.iter().copied().max().unwrap_or(NONE),
            min_boundary_parent: NONE,
            leaf: self.nodes[keep as usize].leaf,
            leaf_end: 0,
            radius: 0.0,
        });
        self.adjacent.push(removed);
        self.boundary.push(nb.clone());
        self.push_edges(p);
        // The neighbours' surroundings changed: retry what they refused.
        for u in nb {
            for (k, g) in std::mem::take(&mut self.blocked[u as usize]) {
                // Filed under both endpoints: the first one retries it.
                if self.filed.remove(&(k, g)) && !self.dead[k as usize] && !self.dead[g as usize] {
                    self.push(k, g);
                }
            }
        }
    }

    fn finish(self, pos: Vec<[f32; 3]>, tris: Vec<[u32; 3]>) -> VdTree {
        let n = pos.len();
        let mut nodes = self.nodes;
        for (i, b) in self.boundary.iter().enumerate() {
            let m = b
                .iter()
                .map(|&v| nodes[v as usize].parent)
                .min()
                .unwrap_or(NONE);
            nodes[n + i].min_boundary_parent = m;
        }
        let permanent = (0..tris.len() as u32)
            .filter(|&t| self.alive[t as usize])
            .collect();
        let mut roots: Vec<u32> = (0..nodes.len() as u32)
            .filter(|&i| nodes[i as usize].parent == NONE)
            .collect();
        let (pos, tris) = number_leaves_depth_first(&mut nodes, &mut roots, pos, tris);
        VdTree {
            positions: pos,
            triangles: tris,
            nodes,
            adjacent: self.adjacent,
            permanent,
            roots,
        }
    }
}

/// Renumbers the leaves `0..n` in depth-first order (left child first, roots
/// ascending) so that every subtree's leaves are one interval, then sets each
/// node's interval and bounding radius (bottom-up: ids increase upward).
/// Internal ids, and so the implicit dependencies, are unchanged.
fn number_leaves_depth_first(
    nodes: &mut [VdNode],
    roots: &mut [u32],
    pos: Vec<[f32; 3]>,
    tris: Vec<[u32; 3]>,
) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let n = pos.len();
    let mut rank = vec![NONE; n];
    let mut next = 0u32;
    let mut stack = Vec::new();
    for &r in roots.iter() {
        stack.push(r);
        while let Some(v) = stack.pop() {
            let nd = nodes[v as usize];
            if nd.left == NONE {
                rank[v as usize] = next;
                next += 1;
            } else {
                stack.push(nd.right);
                stack.push(nd.left);
            }
        }
    }
    let map = |v: u32| {
        if (v as usize) < n {
            rank[v as usize]
        } else {
            v
        }
    };
    // Leaf roots were visited first, in id order: their new ids keep it.
    for r in roots.iter_mut() {
        *r = map(*r);
    }
    let mut leaves = vec![nodes[0]; n];
    for (i, nd) in nodes[..n].iter().enumerate() {
        leaves[rank[i] as usize] = *nd;
    }
    nodes[..n].copy_from_slice(&leaves);
    for (i, nd) in nodes.iter_mut().enumerate() {
        if i < n {
            nd.leaf = i as u32;
            nd.leaf_end = i as u32 + 1;
        } else {
            nd.left = map(nd.left);
            nd.right = map(nd.right);
        }
        if nd.max_adjacent != NONE {
            nd.max_adjacent = map(nd.max_adjacent);
        }
    }
    let mut new_pos = vec![[0.0; 3]; n];
    for (i, p) in pos.into_iter().enumerate() {
        new_pos[rank[i] as usize] = p;
    }
    let at = |leaf: u32| DVec3::from(new_pos[leaf as usize].map(f64::from));
    for i in n..nodes.len() {
        let (l, r) = (
            nodes[nodes[i].left as usize],
            nodes[nodes[i].right as usize],
        );
        let p = at(l.leaf);
        let radius = (f64::from(l.radius)).max(p.distance(at(r.leaf)) + f64::from(r.radius));
        let nd = &mut nodes[i];
        nd.leaf = l.leaf;
        nd.leaf_end = r.leaf_end;
        // Rounded up so the f32 radius still holds the children.
        nd.radius = (radius * (1.0 + 1e-6)) as f32;
    }
    let tris = tris.into_iter().map(|t| t.map(map)).collect();
    (new_pos, tris)
}
