//! The per-frame cut of a Multi-Triangulation (Holst & Schumann §3, §4.3):
//! from the last frame's cut, top-down steps refine the children of cut
//! arcs whose error projects above the tolerance (once all their fathers
//! are refined) and bottom-up steps coarsen refined nodes whose outgoing
//! arcs are all on the cut and whose error no longer does, until neither
//! applies. Errors and spheres are monotone, so the result is the cut of
//! every node whose error projects above the tolerance, wherever the
//! previous frame's cut was; a node that cannot be read stays as it is.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;

use glam::Vec3;

use super::DRAIN;
use super::cache::Mark;
use super::file::{NodeData, NodeHead};
use super::store::{MtStore, MtStoreError};
use crate::camera::{Frustum, View};
use crate::format::{PackedVertex, RepMesh};

/// Passes of top-down and bottom-up steps in one frame, at most.
const MAX_PASSES: u32 = 1024;

/// The screen-space test: a node is refined when its sphere meets the
/// frustum and its error, at the sphere's nearest point, projects above
/// `tolerance_px`.
#[derive(Clone, Copy, Debug)]
pub struct MtCriterion {
    pub view: View,
    pub frustum: Frustum,
    pub tolerance_px: f32,
    /// The view's pixels per unit of error at distance 1.
    ppr: f32,
}

impl MtCriterion {
    pub fn new(view: View, tolerance_px: f32) -> Self {
        Self {
            view,
            frustum: view.frustum(0.0),
            tolerance_px,
            ppr: view.pixels_per_radian(),
        }
    }

    pub fn wants(&self, h: &NodeHead) -> bool {
        if h.error == f32::INFINITY {
            return true;
        }
        let c = Vec3::from(h.center);
        let r = Vec3::splat(h.radius);
        if !self.frustum.intersects(c - r, c + r) {
            return false;
        }
        let d = (c.distance(self.view.pose.position) - h.radius).max(self.view.near);
        h.error * self.ppr / d > self.tolerance_px
    }
}

/// One frame's steps.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CutStats {
    pub refined: u32,
    pub coarsened: u32,
    /// Distinct nodes wanted and not in core (budget, corrupt, I/O).
    pub misses: u32,
    pub passes: u32,
}

/// An arc on the cut.
#[derive(Clone, Copy, Debug)]
struct CutArc {
    child: u32,
    tris: u32,
    mark: Mark,
}

/// The current cut of one MT.
#[derive(Debug)]
pub struct MtCut {
    refined: Vec<bool>,
    /// (father, position) → arc.
    arcs: BTreeMap<(u32, u32), CutArc>,
    /// Cut arcs per father.
    per_father: BTreeMap<u32, u32>,
    tris: u64,
    /// (father, child) of the arcs added since the last pass began: the
    /// only places the next pass can change.
    added: Vec<(u32, u32)>,
}

impl MtCut {
    /// The coarsest cut (the root refined); reads the root.
    pub fn start(store: &mut MtStore) -> Result<Self, MtStoreError> {
        let n = store.file.dir.len();
        let root = store
            .get(0)
            .map_err(|m| MtStoreError::Root(super::file::MtFileError::Corrupt(format!("{m:?}"))))?;
        let mut c = Self {
            refined: vec![false; n],
            arcs: BTreeMap::new(),
            per_father: BTreeMap::new(),
            tris: 0,
            added: Vec::new(),
        };
        c.refined[0] = true;
        c.add_out(&root, store, Mark::TopDown);
        Ok(c)
    }

    pub fn refined(&self) -> &[bool] {
        &self.refined
    }

    /// Triangles on the cut.
    pub fn triangle_count(&self) -> u64 {
        self.tris
    }

    pub fn arc_count(&self) -> usize {
        self.arcs.len()
    }

    fn add(&mut self, key: (u32, u32), child: u32, tris: u32, mark: Mark, store: &mut MtStore) {
        self.arcs.insert(key, CutArc { child, tris, mark });
        self.added.push((key.0, child));
        *self.per_father.entry(key.0).or_default() += 1;
        self.tris += u64::from(tris);
        store.pin(key.0);
        if child != DRAIN {
            store.pin(child);
        }
    }

    fn remove(&mut self, key: (u32, u32), store: &mut MtStore) {
        let Some(a) = self.arcs.remove(&key) else {
            return;
        };
        let c = self.per_father.get_mut(&key.0).expect("counted");
        *c -= 1;
        if *c == 0 {
            self.per_father.remove(&key.0);
        }
        self.tris -= u64::from(a.tris);
        store.unpin(key.0);
        if a.child != DRAIN {
            store.unpin(a.child);
        }
    }

    fn add_out(&mut self, nd: &NodeData, store: &mut MtStore, mark: Mark) {
        for k in 0..nd.arc_at.len() {
            let (h, _, _) = nd.arc(k);
            self.add((nd.id, k as u32), h.child, h.tri_count, mark, store);
        }
    }

    /// Adapts the cut to `c`: top-down and bottom-up passes until neither
    /// changes it. The first pass looks at the whole cut; each later one
    /// only at the ends of the arcs the one before added (a child can be
    /// refined only once an arc to it enters the cut, a father coarsened
    /// only once its last outgoing arc does).
    pub fn adapt(&mut self, c: &MtCriterion, store: &mut MtStore) -> CutStats {
        let mut st = CutStats::default();
        let mut missed = BTreeSet::new();
        let mut below: BTreeSet<u32> = self
            .arcs
            .values()
            .filter(|a| a.child != DRAIN && !self.refined[a.child as usize])
            .map(|a| a.child)
            .collect();
        let mut fathers: BTreeSet<u32> = self.per_father.keys().copied().collect();
        while st.passes < MAX_PASSES {
            st.passes += 1;
            self.added.clear();
            let mut changed = false;
            for g in std::mem::take(&mut below) {
                if self.refined[g as usize] {
                    continue;
                }
                if missed.contains(&g) {
                    continue;
                }
                let nd = match store.get(g) {
                    Ok(nd) => nd,
                    Err(_) => {
                        missed.insert(g);
                        continue;
                    }
                };
                if !c.wants(&nd.head) || nd.ins.iter().any(|&(h, _)| !self.refined[h as usize]) {
                    continue;
                }
                for &(h, pos) in &nd.ins {
                    self.remove((h, pos), store);
                }
                self.refined[g as usize] = true;
                self.add_out(&nd, store, Mark::TopDown);
                st.refined += 1;
                changed = true;
            }
            for g in std::mem::take(&mut fathers) {
                if g == 0 {
                    continue;
                }
                let Some(nd) = store.peek(g).cloned() else {
                    continue;
                };
                if self.per_father.get(&g).copied() != Some(nd.arc_at.len() as u32)
                    || c.wants(&nd.head)
                {
                    continue;
                }
                // The fathers are pinned while they are read, so that
                // reading one never evicts another.
                let mut fathers_in = Vec::with_capacity(nd.ins.len());
                for &(h, _) in &nd.ins {
                    store.pin(h);
                }
                for &(h, _) in &nd.ins {
                    if missed.contains(&h) {
                        continue;
                    }
                    match store.get(h) {
                        Ok(f) => fathers_in.push(f),
                        Err(_) => {
                            missed.insert(h);
                        }
                    }
                }
                let all = fathers_in.len() == nd.ins.len();
                if all {
                    for k in 0..nd.arc_at.len() {
                        self.remove((g, k as u32), store);
                    }
                    self.refined[g as usize] = false;
                    for (&(h, pos), f) in nd.ins.iter().zip(&fathers_in) {
                        let (ah, _, _) = f.arc(pos as usize);
                        self.add((h, pos), g, ah.tri_count, Mark::BottomUp, store);
                    }
                }
                for &(h, _) in &nd.ins {
                    store.unpin(h);
                }
                if !all {
                    continue;
                }
                st.coarsened += 1;
                changed = true;
            }
            if !changed {
                break;
            }
            for &(h, g) in &self.added {
                fathers.insert(h);
                if g != DRAIN && !self.refined[g as usize] {
                    below.insert(g);
                }
            }
        }
        self.added.clear();
        // A node missed is not asked for again this frame.
        st.misses = missed.len() as u32;
        st
    }

    /// The cut's arcs for the cache: (father, child or `None`, mark).
    pub fn cache_arcs(&self) -> Vec<(u32, Option<u32>, Mark)> {
        self.arcs
            .iter()
            .map(|(&(h, _), a)| (h, (a.child != DRAIN).then_some(a.child), a.mark))
            .collect()
    }

    /// Ends frame `f`: the cache keeps or deletes nodes; every arc becomes
    /// old.
    pub fn end_frame(&mut self, f: i64, store: &mut MtStore) {
        store.end_frame(f, &self.cache_arcs());
        for a in self.arcs.values_mut() {
            a.mark = Mark::Old;
        }
    }

    /// The cut's mesh as a rep payload's mesh: the arcs' vertices as
    /// stored (quantised over the MT's box, so nothing is re-quantised),
    /// coloured `color`, and their triangles.
    pub fn rep_mesh(&self, store: &MtStore, color: [u8; 4]) -> RepMesh {
        let h = store.file.header;
        let mut m = RepMesh {
            quant_min: h.quant_min,
            quant_scale: h.quant_scale,
            vertices: Vec::new(),
            indices: Vec::with_capacity(3 * self.tris as usize),
            placement: None,
        };
        for &(f, pos) in self.arcs.keys() {
            let nd: &Arc<NodeData> = store.peek(f).expect("cut fathers are pinned in core");
            let (ah, verts, idx) = nd.arc(pos as usize);
            let base = m.vertices.len() as u32;
            m.vertices.extend(verts.chunks_exact(16).map(|v| {
                let mut pv: PackedVertex = bytemuck::pod_read_unaligned(v);
                pv.color = color;
                pv
            }));
            debug_assert_eq!(idx.len(), 3 * ah.tri_count as usize);
            m.indices.extend(idx.iter().map(|&i| base + i));
        }
        m
    }
}
