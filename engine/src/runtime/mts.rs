//! Multi-Triangulations on P_R (Holst & Schumann inside the Varadhan &
//! Manocha front), beside the view-dependence trees of [`super::trees`].
//!
//! An MT rep's payload is the MT file's in-core part (header, node
//! directory, partition table). When the front selects the rep, P_R opens
//! the MT over that payload and the scene file behind it, and every frame
//! the rep is drawn it adapts the cut to the view (top-down and bottom-up
//! from the last cut), reading partitions through the scene's source (so
//! through the disk model) into a store capped at the rep's reserve, lets
//! the node cache keep what rule (3) predicts, and draws the cut's arcs as
//! one mesh rebuilt whenever the cut changed. Reads are synchronous, as in
//! the paper: their time is P_R's. A node failing its checksum keeps its
//! region at the level it has.

use std::sync::Arc;

use super::paged::{TreeError, TreeFrame};
use crate::camera::View;
use crate::format::RepRecord;
use crate::io::{ByteSource, WindowSource};
use crate::mt::cache::CacheMode;
use crate::mt::cut::{MtCriterion, MtCut};
use crate::mt::file::{MtFile, MtHeader};
use crate::mt::store::{MtStore, node_bytes};

/// Bytes P_I reserves for an MT rep's store besides its payload: the open
/// file's and the store's tables plus `max(need, min(wanted, all nodes))`, `need` being
/// four of the largest node records (the root and a few to refine with).
pub(super) fn plan(
    source: &dyn ByteSource,
    rec: &RepRecord,
    wanted: u64,
) -> Result<u64, TreeError> {
    const H: usize = std::mem::size_of::<MtHeader>();
    if (rec.len as usize) < H {
        return Err(TreeError::Header);
    }
    let mut b = [0u8; H];
    source.read_at(rec.offset, &mut b)?;
    let h: MtHeader = bytemuck::pod_read_unaligned(&b);
    if h.data_offset != u64::from(rec.len) || h.data_len != u64::from(rec.aux) || h.node_count == 0
    {
        return Err(TreeError::Roots);
    }
    let n = u64::from(h.node_count);
    let core = H as u64
        + (20 + crate::mt::store::TABLE_BYTES_PER_NODE) * n
        + 8 * u64::from(h.partition_count);
    let all = 2 * h.data_len + 64 * n;
    let need = 4 * node_bytes(h.max_record);
    Ok(core + need.max(wanted.min(all)))
}

/// One live MT.
pub(super) struct MtLive {
    store: MtStore,
    cut: MtCut,
    frame: i64,
    /// The cut as drawn, rebuilt on change.
    pub(super) mesh: Option<(RepRecord, Arc<[u8]>)>,
    reads: u64,
    partitions: u64,
    read_bytes: u64,
}

impl MtLive {
    /// Opens rep `rec`'s MT over `payload` (its in-core part; in core, the
    /// whole file) with a store of `pool` bytes.
    pub(super) fn open(
        source: Arc<dyn ByteSource>,
        rec: &RepRecord,
        payload: &Arc<[u8]>,
        pool: u64,
        mode: CacheMode,
    ) -> Result<Self, TreeError> {
        let src = WindowSource::new(source, rec.offset, rec.extent(), payload.clone())?;
        let file = Arc::new(MtFile::open(Arc::new(src))?);
        let h = file.header;
        if h.input_triangles != u64::from(rec.tri_count) || file.source.len() != rec.extent() {
            return Err(TreeError::Roots);
        }
        let mut store = MtStore::new(file, mode, pool)?;
        let cut = MtCut::start(&mut store)?;
        Ok(Self {
            store,
            cut,
            frame: 0,
            mesh: None,
            reads: 0,
            partitions: 0,
            read_bytes: 0,
        })
    }

    /// Bytes the store holds (tables and nodes; within its reserve).
    pub(super) fn bytes(&self) -> u64 {
        self.store.resident_bytes()
    }

    /// Adapts the cut to `view` and returns the mesh to draw.
    pub(super) fn frame(
        &mut self,
        rec: &RepRecord,
        color: [u8; 4],
        view: &View,
        tolerance_px: f32,
        out: &mut TreeFrame,
    ) -> &(RepRecord, Arc<[u8]>) {
        let st = self
            .cut
            .adapt(&MtCriterion::new(*view, tolerance_px), &mut self.store);
        self.cut.end_frame(self.frame, &mut self.store);
        self.frame += 1;
        let s = self.store.stats;
        out.mt_trees += 1;
        out.mt_arcs += self.cut.arc_count() as u32;
        out.mt_tris += self.cut.triangle_count();
        out.mt_reads += (s.reads - self.reads) as u32;
        out.mt_partitions += (s.partitions_read - self.partitions) as u32;
        out.mt_misses += st.misses;
        out.mt_adapt += st.refined + st.coarsened;
        out.mt_nodes += self.store.resident_nodes() as u32;
        out.mt_read_bytes += s.bytes_read - self.read_bytes;
        self.read_bytes = s.bytes_read;
        self.reads = s.reads;
        self.partitions = s.partitions_read;
        if st.refined + st.coarsened > 0 || self.mesh.is_none() {
            self.mesh = Some(self.cut_mesh(rec, color));
        }
        self.mesh.as_ref().expect("built above")
    }

    fn cut_mesh(&self, rec: &RepRecord, color: [u8; 4]) -> (RepRecord, Arc<[u8]>) {
        let mesh = self.cut.rep_mesh(&self.store, color);
        let bytes = mesh.encode(rec.node, u32::from(rec.index));
        let out = RepRecord {
            len: bytes.len() as u32,
            tri_count: (mesh.indices.len() / 3) as u32,
            vertex_count: mesh.vertices.len() as u32,
            aux: 0,
            ..*rec
        };
        (out, bytes.into())
    }
}
