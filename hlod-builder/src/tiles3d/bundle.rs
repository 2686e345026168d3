//! Bundles: a small subtree exported as one chain of tiles, each tile's
//! content one primitive merging a cut of the subtree's reps.
//!
//! A 3D Tiles viewer pays per tile: a request, a parse, a draw call and a
//! place in its queues. Our reps are small (about 1.7 KB stored on the
//! DE-size plant, 80 triangles where a front meets them), so one tile per rep
//! gives a browser tens of thousands of tiles to load before a view is
//! complete. A bundle trades that for coarser refinement:
//!
//! - **Which subtrees.** A node whose subtree stores at most the bundle's
//!   bytes (every static rep of every node under it), whose parent's does
//!   not, and which has children, is a bundle's root.
//! - **Cuts.** The cut at a threshold `t` is the front our selection would
//!   pick if every node asked for error `t`: at each node the coarsest static
//!   rep whose error is at most `t`, else its children's cuts (a leaf: its
//!   finest rep). The chain starts at `t = ∞` (the root's coarsest rep, or
//!   its children's) and halves the largest error of a rep that can still be
//!   refined, until every rep of the cut is its leaf's finest. Equal cuts
//!   are one tile.
//! - **A tile's error** is the largest error of its cut plus what the
//!   merged content's 16-bit quantisation adds, never above the tile before
//!   it; its box is the bundle root's node box. So a viewer refines the
//!   whole bundle where its worst rep, seen from the box's nearest point,
//!   exceeds the target: it draws at least what our front draws there.

use std::collections::HashMap;

use engine::format::{NONE, RepMesh};
use engine::skeleton::Skeleton;

use super::chain;
use super::glb::{Element, Features};

/// Which nodes root a bundle, and which lie inside one.
#[derive(Clone, Debug, Default)]
pub struct Bundles {
    pub root: Vec<bool>,
    /// Node lies in a bundle (its root included).
    pub inside: Vec<bool>,
    /// Bundle roots, in node order.
    pub roots: Vec<u32>,
}

impl Bundles {
    /// The bundles of at most `bytes` stored bytes each (0: none).
    pub fn new(s: &Skeleton, bytes: u64) -> Self {
        let n = s.nodes.len();
        let mut b = Self {
            root: vec![false; n],
            inside: vec![false; n],
            roots: Vec::new(),
        };
        if bytes == 0 {
            return b;
        }
        // Children come after their parent in node order.
        let mut stored = vec![0u64; n];
        for i in (0..n).rev() {
            let node = &s.nodes[i];
            let own: u64 = chain(s, node)
                .iter()
                .map(|&r| u64::from(s.reps[r as usize].len))
                .sum();
            let kids = node.first_child as usize..(node.first_child + node.child_count) as usize;
            stored[i] = own + kids.map(|c| stored[c]).sum::<u64>();
        }
        for (i, (node, &bytes_under)) in s.nodes.iter().zip(&stored).enumerate() {
            if !b.inside[i] && bytes_under <= bytes && node.child_count > 0 {
                b.root[i] = true;
                b.inside[i] = true;
                b.roots.push(i as u32);
            }
            if b.inside[i] {
                let kids =
                    node.first_child as usize..(node.first_child + node.child_count) as usize;
                for c in kids {
                    b.inside[c] = true;
                }
            }
        }
        b
    }

    /// Whether node `i` roots a bundle.
    pub fn is_root(&self, i: u32) -> bool {
        self.root.get(i as usize).copied().unwrap_or(false)
    }

    /// Whether node `i` is a bundle's root or lies under one.
    pub fn is_inside(&self, i: u32) -> bool {
        self.inside.get(i as usize).copied().unwrap_or(false)
    }
}

/// The cut of node `i`'s subtree at error `t`, appended to `out`.
fn cut(s: &Skeleton, i: u32, t: f64, out: &mut Vec<u32>) {
    let node = &s.nodes[i as usize];
    let reps = chain(s, node);
    if let Some(&r) = reps
        .iter()
        .find(|&&r| f64::from(s.reps[r as usize].error) <= t)
    {
        out.push(r);
        return;
    }
    if node.child_count == 0 {
        if let Some(&r) = reps.last() {
            out.push(r);
        }
        return;
    }
    for c in node.first_child..node.first_child + node.child_count {
        cut(s, c, t, out);
    }
}

/// Whether rep `r` is its node's finest static rep on a leaf (a cut never
/// refines it).
fn is_final(s: &Skeleton, r: u32) -> bool {
    let rec = &s.reps[r as usize];
    let node = &s.nodes[rec.node as usize];
    node.child_count == 0 && chain(s, node).last() == Some(&r)
}

/// The cuts of bundle `root`, coarsest first: each a list of reps and the
/// largest error among them.
pub fn cuts(s: &Skeleton, root: u32) -> Vec<(Vec<u32>, f64)> {
    let mut out: Vec<(Vec<u32>, f64)> = Vec::new();
    let mut t = f64::INFINITY;
    loop {
        let mut c = Vec::new();
        cut(s, root, t, &mut c);
        let err = |r: &u32| f64::from(s.reps[*r as usize].error);
        let max = c.iter().map(err).fold(0.0, f64::max);
        if out.last().map(|(p, _)| p) != Some(&c) {
            out.push((c.clone(), max));
        }
        let refinable = c
            .iter()
            .filter(|&&r| !is_final(s, r))
            .map(err)
            .fold(f64::NEG_INFINITY, f64::max);
        if refinable == f64::NEG_INFINITY {
            return out;
        }
        // The worst refinable rep is refined at the next step; one at error
        // 0 sends every rep of the cut to its finest.
        t = if refinable > 0.0 {
            refinable / 2.0
        } else {
            -1.0
        };
    }
}

/// One primitive holding the reps `meshes` (in scene coordinates), with
/// each rep's features merged: elements by object, a triangle of a rep
/// without features given the null id (`elements.len()`). `None` features
/// when no rep names an element.
pub fn merge(meshes: &[(&RepMesh, Option<&Features>)]) -> (RepMesh, Option<Features>) {
    let total: usize = meshes.iter().map(|(m, _)| m.vertices.len()).sum();
    let (mut pos, mut nrm, mut col) = (
        Vec::with_capacity(total),
        Vec::with_capacity(total),
        Vec::with_capacity(total),
    );
    let mut indices = Vec::new();
    let mut elements: Vec<Element> = Vec::new();
    let mut by_object: HashMap<u32, u32> = HashMap::new();
    // Per triangle: Some(element) or None (no element).
    let mut tri: Vec<Option<u32>> = Vec::new();
    let mut named = false;
    for (m, f) in meshes {
        let base = pos.len() as u32;
        for v in &m.vertices {
            pos.push(m.position(v));
            nrm.push(m.normal(v));
            col.push(v.color);
        }
        indices.extend(m.indices.iter().map(|&i| base + i));
        let n = m.indices.len() / 3;
        match f {
            Some(f) => {
                named = true;
                let local: Vec<u32> = f
                    .elements
                    .iter()
                    .map(|e| {
                        let key = if e.object == NONE { u32::MAX } else { e.object };
                        *by_object.entry(key).or_insert_with(|| {
                            elements.push(e.clone());
                            (elements.len() - 1) as u32
                        })
                    })
                    .collect();
                tri.extend((0..n).map(|t| f.triangle.get(t).map(|&k| local[k as usize])));
            }
            None => tri.extend(std::iter::repeat_n(None, n)),
        }
    }
    let mesh = RepMesh::quantize(&pos, &nrm, &col, indices);
    let features = named.then(|| {
        let null = elements.len() as u32;
        Features {
            triangle: tri.into_iter().map(|k| k.unwrap_or(null)).collect(),
            elements,
        }
    });
    (mesh, features)
}

/// The content path of bundle `root`'s tile `k`.
pub fn content_uri(root: u32, k: usize) -> String {
    format!("content/b{}/{root}-{k}.glb", root / 1000)
}
