//! The in-memory Multi-Triangulation and its checks.
//!
//! Nodes are local simplification steps, numbered top-down: node 0 is the
//! root (it creates the coarsest mesh), every arc goes from a father to a
//! child of a deeper layer, and the arcs into [`DRAIN`] hold the input
//! triangles. An arc `(h, g)` carries the patch of triangles that refining
//! `h` creates and refining `g` removes. A *cut* is a set `S` of refined
//! nodes that holds the root and every father of each of its nodes; its mesh
//! is the triangles of the arcs leaving `S`.

use std::collections::HashMap;

/// The child of the arcs that hold input triangles.
pub const DRAIN: u32 = u32::MAX;

/// One node: a local simplification, and the bounds of the region it
/// changes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MtNode {
    /// Longest path from the root (the root is layer 0).
    pub layer: u32,
    /// Object-space error of the mesh while this node is not refined (the
    /// root's is infinite); never smaller than any child's.
    pub error: f32,
    /// A sphere holding the node's region and every child's sphere.
    pub center: [f32; 3],
    pub radius: f32,
}

/// One arc: a patch of triangles (indices into [`Mt::positions`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MtArc {
    pub father: u32,
    /// A node or [`DRAIN`].
    pub child: u32,
    pub triangles: Vec<[u32; 3]>,
}

/// A Multi-Triangulation over one mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mt {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub nodes: Vec<MtNode>,
    /// Sorted by father, then child; a node's outgoing arcs are
    /// `arcs[out_start[n]..out_start[n + 1]]`.
    pub arcs: Vec<MtArc>,
    pub out_start: Vec<u32>,
    /// Triangles of the input mesh (the arcs into [`DRAIN`]).
    pub input_triangles: u64,
}

/// Why a Multi-Triangulation is not valid.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MtError {
    #[error("the Multi-Triangulation has no nodes")]
    Empty,
    #[error("arc {0}: {1}")]
    Arc(usize, String),
    #[error("node {0}: {1}")]
    Node(u32, String),
    #[error("cut {what}: {why}")]
    Cut { what: String, why: String },
}

impl Mt {
    /// The outgoing arcs of node `n` (ids into [`Mt::arcs`]).
    pub fn out_arcs(&self, n: u32) -> std::ops::Range<usize> {
        self.out_start[n as usize] as usize..self.out_start[n as usize + 1] as usize
    }

    /// For every node, the ids of its ingoing arcs, ascending.
    pub fn in_arcs(&self) -> Vec<Vec<u32>> {
        let mut ins = vec![Vec::new(); self.nodes.len()];
        for (i, a) in self.arcs.iter().enumerate() {
            if a.child != DRAIN {
                ins[a.child as usize].push(i as u32);
            }
        }
        ins
    }

    /// Triangles held by all arcs.
    pub fn arc_triangles(&self) -> u64 {
        self.arcs.iter().map(|a| a.triangles.len() as u64).sum()
    }

    /// Average triangles per arc (the paper reduces its MT until this is
    /// at least 10).
    pub fn mean_patch(&self) -> f64 {
        self.arc_triangles() as f64 / self.arcs.len().max(1) as f64
    }

    /// Number of layers.
    pub fn layers(&self) -> u32 {
        self.nodes.iter().map(|n| n.layer + 1).max().unwrap_or(0)
    }

    /// The mesh of cut `refined` (one flag per node): the triangles of the
    /// arcs from a refined node to an unrefined one or the drain.
    pub fn cut_triangles(&self, refined: &[bool]) -> Vec<[u32; 3]> {
        let mut out = Vec::new();
        for a in &self.arcs {
            let below = a.child == DRAIN || !refined[a.child as usize];
            if refined[a.father as usize] && below {
                out.extend_from_slice(&a.triangles);
            }
        }
        out
    }

    /// Whether `refined` is a cut: the root is refined and so is every
    /// father of a refined node.
    pub fn is_cut(&self, refined: &[bool]) -> bool {
        refined.len() == self.nodes.len()
            && refined.first() == Some(&true)
            && self.arcs.iter().all(|a| {
                a.child == DRAIN || !refined[a.child as usize] || refined[a.father as usize]
            })
    }

    /// Checks the structure: node 0 is the only node without fathers, every
    /// arc goes from a father to a child of a deeper layer (so the graph is
    /// a DAG), layers are longest paths, errors and spheres never grow from
    /// father to child, the arcs into the drain hold every input triangle,
    /// and the coarsest and the finest cut are crack-free
    /// ([`Mt::check_cut`]).
    pub fn validate(&self) -> Result<(), MtError> {
        let n = self.nodes.len();
        if n == 0 {
            return Err(MtError::Empty);
        }
        if self.out_start.len() != n + 1
            || self.out_start[n] as usize != self.arcs.len()
            || self.out_start.windows(2).any(|w| w[0] > w[1])
        {
            return Err(MtError::Node(
                0,
                "outgoing arc ranges do not tile the arcs".into(),
            ));
        }
        let mut fathers = vec![0u32; n];
        let mut children = vec![0u32; n];
        let mut layer_from_fathers = vec![0u32; n];
        for (i, a) in self.arcs.iter().enumerate() {
            let bad = |why: String| Err(MtError::Arc(i, why));
            if a.father as usize >= n || (a.child != DRAIN && a.child as usize >= n) {
                return bad(format!("nodes {} -> {} out of range", a.father, a.child));
            }
            if !self.out_arcs(a.father).contains(&i) {
                return bad(format!("not in father {}'s outgoing range", a.father));
            }
            if a.triangles.is_empty() {
                return bad("holds no triangle".into());
            }
            if let Some(t) = a
                .triangles
                .iter()
                .find(|t| t.iter().any(|&v| v as usize >= self.positions.len()))
            {
                return bad(format!("triangle {t:?} indexes past the vertices"));
            }
            children[a.father as usize] += 1;
            if a.child == DRAIN {
                continue;
            }
            let (f, c) = (
                &self.nodes[a.father as usize],
                &self.nodes[a.child as usize],
            );
            if c.layer <= f.layer {
                return bad(format!(
                    "child layer {} not below father's {}",
                    c.layer, f.layer
                ));
            }
            if c.error > f.error {
                return bad(format!(
                    "child error {} above father's {}",
                    c.error, f.error
                ));
            }
            let d = glam::Vec3::from(f.center).distance(glam::Vec3::from(c.center));
            if d + c.radius > f.radius * (1.0 + 1e-5) + 1e-6 {
                return bad("child sphere not inside father's".into());
            }
            fathers[a.child as usize] += 1;
            let l = &mut layer_from_fathers[a.child as usize];
            *l = (*l).max(f.layer + 1);
            if i > 0 && self.arcs[i - 1].father == a.father && self.arcs[i - 1].child >= a.child {
                return bad("arcs of a father not sorted by child (or repeated)".into());
            }
        }
        for (k, node) in self.nodes.iter().enumerate() {
            let k32 = k as u32;
            if (k == 0) != (fathers[k] == 0) {
                return Err(MtError::Node(k32, format!("{} fathers", fathers[k])));
            }
            if children[k] == 0 {
                return Err(MtError::Node(k32, "no outgoing arc".into()));
            }
            if node.layer != layer_from_fathers[k] {
                return Err(MtError::Node(
                    k32,
                    format!(
                        "layer {} but longest path {}",
                        node.layer, layer_from_fathers[k]
                    ),
                ));
            }
            let sane = |x: f32| x >= 0.0;
            if !sane(node.error) || !sane(node.radius) {
                return Err(MtError::Node(k32, "negative or NaN error or radius".into()));
            }
        }
        let drained: u64 = self
            .arcs
            .iter()
            .filter(|a| a.child == DRAIN)
            .map(|a| a.triangles.len() as u64)
            .sum();
        if drained != self.input_triangles {
            return Err(MtError::Arc(
                0,
                format!(
                    "arcs into the drain hold {drained} triangles, the input {}",
                    self.input_triangles
                ),
            ));
        }
        let topo = self.topology(&vec![true; n]);
        let mut coarse = vec![false; n];
        coarse[0] = true;
        self.check_cut(&coarse, &topo, "coarsest")?;
        self.check_cut(&vec![true; n], &topo, "finest")?;
        Ok(())
    }

    /// Vertex welding by position and the input's border vertices and
    /// Euler characteristic (of the finest cut), for [`Mt::check_cut`].
    pub fn topology(&self, finest: &[bool]) -> Topology {
        let mut weld = Vec::with_capacity(self.positions.len());
        let mut seen: HashMap<[u32; 3], u32> = HashMap::new();
        for p in &self.positions {
            let key = p.map(f32::to_bits);
            let next = seen.len() as u32;
            weld.push(*seen.entry(key).or_insert(next));
        }
        let tris = self.cut_triangles(finest);
        let edges = edge_uses(&tris, &weld);
        let mut border = vec![false; seen.len()];
        let mut non_manifold = 0;
        for (&(a, b), &c) in &edges {
            if c.0 + c.1 > 2 {
                non_manifold += 1;
            }
            if c.0 != c.1 {
                border[a as usize] = true;
                border[b as usize] = true;
            }
        }
        let euler = euler(&tris, &weld, &edges);
        Topology {
            weld,
            border,
            euler,
            non_manifold,
        }
    }

    /// Checks that the mesh of cut `refined` is crack-free: every edge
    /// whose uses do not pair up (as many a→b as b→a) joins two vertices
    /// on the input's border, where the input's uses do not pair up either.
    /// Returns what else the cut changed: see [`CutReport`].
    pub fn check_cut(
        &self,
        refined: &[bool],
        topo: &Topology,
        what: &str,
    ) -> Result<CutReport, MtError> {
        let bad = |why: String| MtError::Cut {
            what: what.to_string(),
            why,
        };
        if !self.is_cut(refined) {
            return Err(bad("not closed under fathers".into()));
        }
        let tris = self.cut_triangles(refined);
        let edges = edge_uses(&tris, &topo.weld);
        let mut r = CutReport {
            triangles: tris.len() as u64,
            euler: euler(&tris, &topo.weld, &edges),
            non_manifold: 0,
        };
        for (&(a, b), &(fwd, back)) in &edges {
            if fwd != back && !(topo.border[a as usize] && topo.border[b as usize]) {
                return Err(bad(format!(
                    "open edge {a}-{b} inside the surface (a crack)"
                )));
            }
            if fwd + back > 2 {
                r.non_manifold += 1;
            }
        }
        Ok(r)
    }
}

/// What a cut changed besides being crack-free: the simplifier keeps
/// cracks out by locking patch borders, but may join two sheets along an
/// edge or let a tiny component vanish.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CutReport {
    pub triangles: u64,
    /// Compare with [`Topology::euler`].
    pub euler: i64,
    /// Edges used by more than two triangles.
    pub non_manifold: u64,
}

/// What [`Mt::check_cut`] compares a cut with.
#[derive(Clone, Debug)]
pub struct Topology {
    /// Vertex id to welded vertex id.
    pub weld: Vec<u32>,
    /// Welded vertices on the input's border.
    pub border: Vec<bool>,
    pub euler: i64,
    /// Edges of the input used by more than two triangles.
    pub non_manifold: u64,
}

/// Uses of each undirected edge (smaller welded id first): (as a→b, as b→a).
fn edge_uses(tris: &[[u32; 3]], weld: &[u32]) -> HashMap<(u32, u32), (u32, u32)> {
    let mut m: HashMap<(u32, u32), (u32, u32)> = HashMap::with_capacity(tris.len() * 2);
    for t in tris {
        let w = t.map(|v| weld[v as usize]);
        for k in 0..3 {
            let (a, b) = (w[k], w[(k + 1) % 3]);
            if a == b {
                continue;
            }
            let e = m.entry((a.min(b), a.max(b))).or_default();
            if a < b {
                e.0 += 1;
            } else {
                e.1 += 1;
            }
        }
    }
    m
}

fn euler(tris: &[[u32; 3]], weld: &[u32], edges: &HashMap<(u32, u32), (u32, u32)>) -> i64 {
    let mut verts: Vec<u32> = tris.iter().flatten().map(|&v| weld[v as usize]).collect();
    verts.sort_unstable();
    verts.dedup();
    verts.len() as i64 - edges.len() as i64 + tris.len() as i64
}
