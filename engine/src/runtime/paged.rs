//! What P_R's paged reps — view-dependence trees (`trees.rs`) and
//! Multi-Triangulations (`mts.rs`) — share: why one cannot be used, and
//! the work of one frame.

/// Why a view-dependence tree cannot be used (its finest static LOD is
/// drawn instead).
#[derive(Debug, thiserror::Error)]
pub(super) enum TreeError {
    #[error("its header is longer than its rep record")]
    Header,
    #[error("its header and root records disagree with the rep record")]
    Roots,
    #[error(transparent)]
    Io(#[from] std::io::Error),
    #[error(transparent)]
    Vdt(#[from] crate::vdt::file::VdtError),
    #[error(transparent)]
    Format(#[from] crate::format::FormatError),
    #[error(transparent)]
    Mt(#[from] crate::mt::file::MtFileError),
    #[error(transparent)]
    MtStore(#[from] crate::mt::store::MtStoreError),
}

/// One frame's tree work, for the metrics.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct TreeFrame {
    pub trees: u32,
    pub adapt: u32,
    pub tris: u64,
    pub misses: u32,
    pub metas_loaded: u32,
    pub ms: f64,
    /// Multi-Triangulations drawn, their cut arcs and triangles, reads and
    /// partitions read this frame, misses and nodes in core.
    pub mt_trees: u32,
    pub mt_arcs: u32,
    pub mt_tris: u64,
    pub mt_adapt: u32,
    pub mt_reads: u32,
    pub mt_partitions: u32,
    pub mt_read_bytes: u64,
    pub mt_misses: u32,
    pub mt_nodes: u32,
}
