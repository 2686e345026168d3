//! View-dependence trees on P_R (El-Sana & Chiang §3.3 inside the
//! Varadhan & Manocha front).
//!
//! A tree rep's payload (the `.vdt` file's in-core part and root meta-nodes)
//! comes from P_I like any rep. When the front selects it, P_R opens the tree
//! over that payload and the scene file behind it ([`WindowSource`]), starts
//! its external-memory store (its own I/O thread reads the other meta-nodes
//! through the same disk model) and, every frame the rep is drawn, runs one
//! refinement pass for the view and draws the active triangles as a mesh
//! rebuilt whenever the cut changed. In `incore` mode P_I loads the whole
//! file and the tree is refined fully in memory.
//!
//! One footprint: P_I reserves, for every resident tree rep, its payload
//! plus the store's bytes (in-core part and place holders), planned once at
//! start-up ([`plan_pools`]); the store never holds more than its reserve, so
//! resident bytes stay within the budget. A tree whose store cannot start is
//! reported to P_I, which substitutes its finest static LOD from then on.

use std::collections::BTreeMap;
use std::sync::Arc;

use glam::Vec3;

use super::paged::{TreeError, TreeFrame};
use crate::camera::View;
use crate::format::{RepMesh, RepRecord};
use crate::io::{ByteSource, WindowSource};
use crate::render::Renderer;
use crate::skeleton::{RepId, Skeleton};
use crate::vdt::VdTree;
use crate::vdt::ext::ExtStore;
use crate::vdt::file::{VdtFile, VdtHeader};
use crate::vdt::refine::{Criterion, NodeStore, Refiner};

/// Bytes P_I reserves for each tree rep's store, besides its payload: the
/// tree's in-core part plus `max(need, min(wanted, DATA))` holder bytes,
/// where `need` is the root meta-nodes and three of the largest. Reads each
/// tree's header and root records (one small read per tree); 0 for other
/// reps, `None` for a tree or MT whose header cannot be read (the rep is
/// not usable: P_I never loads it).
pub(super) fn plan_pools(
    skeleton: &Skeleton,
    source: &dyn ByteSource,
    wanted: u64,
) -> Vec<Option<u64>> {
    skeleton
        .reps
        .iter()
        .enumerate()
        .map(|(r, rec)| {
            let plan = if rec.is_vdt() {
                plan_one(source, rec, wanted)
            } else if rec.is_mt() {
                super::mts::plan(source, rec, wanted)
            } else {
                return Some(0);
            };
            plan.map_err(|why| {
                tracing::warn!("paged rep {r}: {why}; its finest static LOD is drawn instead");
            })
            .ok()
        })
        .collect()
}

fn plan_one(source: &dyn ByteSource, rec: &RepRecord, wanted: u64) -> Result<u64, TreeError> {
    let read = |len: u64| -> Result<Vec<u8>, TreeError> {
        if len > u64::from(rec.len) {
            return Err(TreeError::Header);
        }
        let mut b = vec![0u8; len as usize];
        source.read_at(rec.offset, &mut b)?;
        Ok(b)
    };
    let head = read(112)?;
    let roots = u64::from(bytemuck::pod_read_unaligned::<VdtHeader>(&head).root_count);
    let prefix = read(112 + roots * 32)?;
    let (h, root_bytes) = VdtHeader::with_root_bytes(&prefix)
        .filter(|(h, _)| h.root_count > 0 && h.data_offset <= u64::from(rec.len))
        .ok_or(TreeError::Roots)?;
    Ok(h.data_offset + h.holder_need(root_bytes).max(wanted.min(h.data_len)))
}

enum Store {
    Ext(Box<ExtStore>),
    /// The whole tree, and the size of its flat layout (what it holds).
    Core(Box<VdTree>, u64),
}

impl Store {
    fn nodes(&mut self) -> &mut dyn NodeStore {
        match self {
            Store::Ext(s) => s.as_mut(),
            Store::Core(t, _) => t.as_mut(),
        }
    }
}

struct Tree {
    store: Store,
    refiner: Refiner,
    /// The cut as drawn (synthetic record and payload), rebuilt on change.
    mesh: Option<(RepRecord, Arc<[u8]>)>,
    loads: u64,
}

/// P_R's live trees.
pub(super) struct Trees {
    source: Arc<dyn ByteSource>,
    skeleton: Arc<Skeleton>,
    pools: Arc<Vec<Option<u64>>>,
    incore: bool,
    live: BTreeMap<RepId, Tree>,
    mts: BTreeMap<RepId, super::mts::MtLive>,
    mt_mode: crate::mt::cache::CacheMode,
    /// P_R's clock: what refining and drawing the trees took.
    clock: Arc<dyn crate::clock::Clock>,
}

impl Trees {
    pub(super) fn new(
        source: Arc<dyn ByteSource>,
        skeleton: Arc<Skeleton>,
        pools: Arc<Vec<Option<u64>>>,
        incore: bool,
        mt_mode: crate::mt::cache::CacheMode,
        clock: Arc<dyn crate::clock::Clock>,
    ) -> Self {
        Self {
            source,
            skeleton,
            pools,
            incore,
            live: BTreeMap::new(),
            mts: BTreeMap::new(),
            mt_mode,
            clock,
        }
    }

    /// Bytes held by the live trees' stores.
    pub(super) fn bytes(&self) -> u64 {
        self.live
            .values()
            .map(|t| match &t.store {
                Store::Ext(s) => s.resident_bytes(),
                Store::Core(_, bytes) => *bytes,
            })
            .sum::<u64>()
            + self.mts.values().map(|m| m.bytes()).sum::<u64>()
    }

    /// P_I evicted rep `r`: its store goes with it.
    pub(super) fn evict(&mut self, r: RepId) {
        self.live.remove(&r);
        self.mts.remove(&r);
    }

    /// Rep `r`'s store reserve. A rep whose store could not be planned
    /// (`None`) is never handed to P_R: P_I does not load it.
    fn pool(&self, r: RepId) -> u64 {
        self.pools[r as usize].unwrap_or(0)
    }

    fn open(&self, r: RepId, payload: &Arc<[u8]>) -> Result<Tree, TreeError> {
        let rec = &self.skeleton.reps[r as usize];
        // In core the payload is the whole file: the window never reads
        // through to the scene source.
        let src = WindowSource::new(
            self.source.clone(),
            rec.offset,
            rec.extent(),
            payload.clone(),
        )?;
        let file = VdtFile::open(Arc::new(src))?;
        crate::format::check_vdt_record(r, rec, &file)?;
        let flat = file.source.len() - file.header.virt_offset;
        let mut store = if self.incore {
            let tree = file.load_tree()?;
            Store::Core(Box::new(tree), flat)
        } else {
            let s = ExtStore::start(Arc::new(file), self.pool(r))?;
            Store::Ext(Box::new(s))
        };
        let refiner = Refiner::new(store.nodes())?;
        Ok(Tree {
            store,
            refiner,
            mesh: None,
            loads: 0,
        })
    }

    /// Refines rep `r`'s tree for `view` and draws its cut; `false` when
    /// the tree cannot be used (logged and dropped here; the caller tells
    /// P_I, which never hands the rep over again).
    pub(super) fn draw(
        &mut self,
        r: RepId,
        payload: &Arc<[u8]>,
        view: &View,
        tolerance_px: f32,
        renderer: &mut dyn Renderer,
        out: &mut TreeFrame,
    ) -> bool {
        let t0 = self.clock.now();
        let done = if self.skeleton.reps[r as usize].is_mt() {
            self.cut_and_draw(r, payload, view, tolerance_px, renderer, out)
        } else {
            self.refine_and_draw(r, payload, view, tolerance_px, renderer, out)
        };
        out.ms += self.clock.ms_since(t0);
        if let Err(why) = &done {
            tracing::warn!("paged rep {r}: {why}; its finest static LOD is drawn instead");
            self.live.remove(&r);
            self.mts.remove(&r);
        }
        done.is_ok()
    }

    fn cut_and_draw(
        &mut self,
        r: RepId,
        payload: &Arc<[u8]>,
        view: &View,
        tolerance_px: f32,
        renderer: &mut dyn Renderer,
        out: &mut TreeFrame,
    ) -> Result<(), TreeError> {
        let rec = self.skeleton.reps[r as usize];
        if !self.mts.contains_key(&r) {
            // In core the payload is the whole file and nothing limits the
            // store but the file itself.
            let pool = if self.incore { u64::MAX } else { self.pool(r) };
            let m =
                super::mts::MtLive::open(self.source.clone(), &rec, payload, pool, self.mt_mode)?;
            self.mts.insert(r, m);
        }
        let color = self.skeleton.nodes[rec.node as usize].color.to_le_bytes();
        let m = self.mts.get_mut(&r).expect("inserted above");
        let had = m.mesh.as_ref().map(|x| x.1.clone());
        let (mrec, mesh) = m.frame(&rec, color, view, tolerance_px, out);
        if had.is_some_and(|h| !Arc::ptr_eq(&h, mesh)) {
            renderer.evict(r);
        }
        renderer.draw(r, mrec, mesh, crate::render::DrawStyle::opaque(false));
        Ok(())
    }

    fn refine_and_draw(
        &mut self,
        r: RepId,
        payload: &Arc<[u8]>,
        view: &View,
        tolerance_px: f32,
        renderer: &mut dyn Renderer,
        out: &mut TreeFrame,
    ) -> Result<(), TreeError> {
        if !self.live.contains_key(&r) {
            let t = self.open(r, payload)?;
            self.live.insert(r, t);
        }
        let rec = self.skeleton.reps[r as usize];
        let color = self.skeleton.nodes[rec.node as usize].color.to_le_bytes();
        let tree = self.live.get_mut(&r).expect("inserted above");
        if let Store::Ext(s) = &mut tree.store {
            s.poll()?;
            out.metas_loaded += (s.stats.loads - tree.loads) as u32;
            tree.loads = s.stats.loads;
        }
        let c = Criterion::new(*view, tolerance_px);
        let st = tree.refiner.pass(tree.store.nodes(), &c)?;
        out.trees += 1;
        out.adapt += st.adapt();
        out.misses += st.misses;
        out.tris += tree.refiner.triangle_count() as u64;
        if st.adapt() > 0 || tree.mesh.is_none() {
            if tree.mesh.is_some() {
                renderer.evict(r);
            }
            tree.mesh = Some(cut_mesh(&tree.refiner, &rec, color));
        }
        let (mrec, mesh) = tree.mesh.as_ref().expect("built above");
        renderer.draw(r, mrec, mesh, crate::render::DrawStyle::opaque(false));
        Ok(())
    }
}

/// The active triangles as a rep payload (vertex normals area-weighted from
/// the active faces) with a record that matches it.
fn cut_mesh(refiner: &Refiner, rec: &RepRecord, color: [u8; 4]) -> (RepRecord, Arc<[u8]>) {
    let (positions, indices) = refiner.indexed_mesh();
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let p = [0, 1, 2].map(|k| positions[t[k] as usize]);
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        for &v in t {
            normals[v as usize] += n;
        }
    }
    let normals: Vec<[f32; 3]> = normals.iter().map(|n| n.to_array()).collect();
    let positions: Vec<[f32; 3]> = positions.iter().map(|p| p.to_array()).collect();
    let colors = vec![color; positions.len()];
    let tri_count = (indices.len() / 3) as u32;
    let mesh = RepMesh::quantize(&positions, &normals, &colors, indices);
    let bytes = mesh.encode(rec.node, u32::from(rec.index));
    let out = RepRecord {
        len: bytes.len() as u32,
        tri_count,
        vertex_count: positions.len() as u32,
        aux: 0,
        ..*rec
    };
    (out, bytes.into())
}
