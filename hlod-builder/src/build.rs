//! The build pipeline: glTF scene → scene graph with LODs and HLODs → scene file.
//!
//! 1. import objects (mesh instances); split very large ones into chunks;
//! 2. cluster objects/chunks into the scene graph ([`crate::cluster`]);
//! 3. leaves: LOD chains (a mesh placed by several one-instance leaves once,
//!    in its local space), written to disk batch by batch as they are made;
//! 4. interior nodes, deepest first: HLODs from the children's coarsest reps;
//! 5. the skeleton and header, then an atomic rename into place.
//!
//! Rep errors are the simplification error plus the quantisation error, made
//! strictly monotone along PAR/CHD. Output is byte-identical for the same input
//! and parameters (ordered parallel maps, no hash-ordered iteration).

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use engine::format::objects::ObjectTable;
use engine::format::{NONE, NodeRecord, RepRecord, SceneMeta, SceneWriter};
use engine::{FormatError, Skeleton};

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

mod assemble;
mod cells;
mod groups;
mod leaf;
pub mod memory;
mod placed;
pub mod shard;
mod source;

use crate::cluster::cluster;
use crate::import::{self, ImportError, Imported};
use crate::lod::{LodParams, lod_chain};
pub(crate) use leaf::transformed_bounds;
use leaf::{Item, object_infos};
pub use source::SceneSource;

/// Parameters of a build.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildParams {
    pub lod: LodParams,
    /// Children per interior node (at most).
    pub branching: usize,
    /// BVH subtrees with at most this many triangles become one merged leaf.
    pub leaf_tris: usize,
    /// Objects above this many triangles are split into chunks of at most this size.
    pub chunk_tris: usize,
    /// Triangle budget of an HLOD.
    pub hlod_tris: usize,
    /// HLOD target as a fraction of the merged children's coarsest reps.
    pub hlod_ratio: f32,
    /// Objects of at least this many triangles get a view-dependence tree as
    /// their finest rep instead of being chunked (0: none).
    pub vdt_tris: usize,
    /// How many of the coarsest static LODs such an object keeps; the tree
    /// replaces the finer ones (a deep tree pages well: its root meta-nodes
    /// stay small).
    pub vdt_keep: usize,
    /// Objects of at least this many triangles get a Multi-Triangulation as
    /// their finest rep (0: none; checked before `vdt_tris`), keeping
    /// `vdt_keep` static LODs too.
    pub mt_tris: usize,
    pub mt: crate::mt::MtRepParams,
    /// Reps on disk in the spatial layout (`layout`: selection band, then
    /// Morton order) rather than in the order they are made.
    pub spatial_layout: bool,
    /// Mesh rep payloads through meshopt's vertex and index codecs (format
    /// version 3), or raw (for comparison).
    pub compress_reps: bool,
    /// Keep the objects of IFC exports that stand for no visible part:
    /// openings' voids and spaces' volumes ([`crate::import::ifc_void`]).
    /// Left out by default (counted in [`BuildStats::hidden_objects`]).
    pub ifc_voids: bool,
    /// Cell side of the walk section, metres ([`crate::walkmap`]; 0: none).
    pub walk_cell: f32,
    /// A mesh placed by several single-instance leaves has its levels
    /// stored once, in its own coordinates, and placed by each leaf's reps
    /// (format version 6); `false` stores every placement's levels in
    /// scene coordinates (as before version 6; sharded builds always do).
    pub share_instances: bool,
}

impl Default for BuildParams {
    fn default() -> Self {
        Self {
            lod: LodParams::default(),
            branching: 8,
            leaf_tris: 1024,
            chunk_tris: 65536,
            hlod_tris: 8192,
            hlod_ratio: 0.5,
            vdt_tris: 0,
            vdt_keep: 2,
            mt_tris: 0,
            mt: crate::mt::MtRepParams::default(),
            spatial_layout: true,
            compress_reps: true,
            ifc_voids: false,
            walk_cell: 0.1,
            share_instances: true,
        }
    }
}

impl BuildParams {
    /// Rejects nonsense values.
    pub fn check(&self) -> Result<(), BuildError> {
        let bad = |s: &str| Err(BuildError::Params(s.to_string()));
        let l = &self.lod;
        if !(l.ratio > 0.0 && l.ratio < 1.0) {
            return bad("--lod-ratio must be in (0, 1)");
        }
        if !(l.max_keep > 0.0 && l.max_keep <= 1.0) {
            return bad("LOD max_keep must be in (0, 1]");
        }
        if l.max_levels == 0 || l.max_levels > 32 {
            return bad("--max-lods must be in 1..=32");
        }
        if self.branching < 2 || self.branching > 1024 {
            return bad("--branching must be in 2..=1024");
        }
        if self.chunk_tris < 64 {
            return bad("--chunk-tris must be at least 64");
        }
        if self.hlod_tris < 4 || l.min_tris < 1 {
            return bad("--hlod-tris must be at least 4");
        }
        if !(self.walk_cell == 0.0 || (0.02..=10.0).contains(&self.walk_cell)) {
            return bad("--walk-cell must be 0 (no walk section) or in [0.02, 10] metres");
        }
        if !(self.hlod_ratio > 0.0 && self.hlod_ratio <= 1.0) {
            return bad("--hlod-ratio must be in (0, 1]");
        }
        if self.vdt_tris != 0 && self.vdt_tris <= self.leaf_tris {
            return bad(
                "--vdt-tris must exceed --leaf-tris (a tree's object is a leaf of its own)",
            );
        }
        if self.mt_tris != 0 && self.mt_tris <= self.leaf_tris {
            return bad("--mt-tris must exceed --leaf-tris (an MT's object is a leaf of its own)");
        }
        if !(1..=engine::mt::partition::MAX_THETA).contains(&self.mt.theta) {
            return bad("--mt-theta must be in 1..=4096 nodes per partition");
        }
        if !(8..=256).contains(&self.mt.mt.cluster_tris) {
            return bad("--mt-cluster-tris must be in 8..=256");
        }
        if self.vdt_keep == 0 || self.vdt_keep >= l.max_levels {
            return bad("--vdt-keep must be in 1..--max-lods");
        }
        Ok(())
    }
}

/// Why a build failed.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error(transparent)]
    Import(#[from] ImportError),
    #[error("invalid parameters: {0}")]
    Params(String),
    #[error("{path}: {source}")]
    Write { path: PathBuf, source: FormatError },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Output(#[from] engine_cli::outfile::OutputError),
    #[error("{0}")]
    Memory(String),
    #[error("{0}")]
    Shard(String),
}

/// Table-1 figures of a finished build.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildStats {
    pub objects: u64,
    pub nodes: u64,
    pub leaves: u64,
    pub chunked_objects: u64,
    /// Objects left out as IFC voids and spaces (see
    /// [`BuildParams::ifc_voids`]), and their triangles.
    pub hidden_objects: u64,
    pub hidden_triangles: u64,
    /// Objects whose finest rep is a view-dependence tree.
    pub vdt_objects: u64,
    /// Objects whose finest rep is a Multi-Triangulation.
    pub mt_objects: u64,
    pub height: u32,
    pub reps: u64,
    /// Source triangles after instancing.
    pub input_triangles: u64,
    /// Of those, the non-degenerate ones of the objects kept (what the
    /// finest reps hold).
    pub usable_triangles: u64,
    pub output_triangles: u64,
    pub skeleton_bytes: u64,
    pub data_bytes: u64,
    pub file_bytes: u64,
    pub seconds: f64,
    pub warnings: Vec<String>,
    /// World position of the scene's origin.
    pub origin: [f64; 3],
    /// Bytes of the object section (names, extras, merged leaves' runs).
    pub object_bytes: u64,
    /// Cells the scene graph was built in, and the plan that sized them.
    pub cells: u64,
    pub memory_plan: Option<memory::MemoryPlan>,
    /// The most heap in use at once, where the heap is counted.
    pub peak_heap: Option<u64>,
    /// The walk section.
    pub walk: crate::walkmap::WalkStats,
}

/// Where a build is: a stage name, nodes done and nodes in all (0 while
/// the total is not known yet).
pub type Report<'a> = &'a (dyn Fn(&str, u64, u64) + Sync);

/// How a build runs; none of it changes the output.
#[derive(Clone, Copy)]
pub struct RunOptions<'a> {
    /// A progress bar on the terminal.
    pub progress: bool,
    pub report: Report<'a>,
    /// The most heap the build may use ([`memory::default_limit`] if `None`).
    pub memory_limit: Option<u64>,
}

impl std::fmt::Debug for RunOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunOptions")
            .field("progress", &self.progress)
            .field("memory_limit", &self.memory_limit)
            .finish_non_exhaustive()
    }
}

/// Builds `input` into the scene file `output` (written atomically).
pub fn build_file(
    input: &Path,
    output: &Path,
    params: &BuildParams,
    progress: bool,
) -> Result<BuildStats, BuildError> {
    build_file_reporting(input, output, params, progress, &|_, _, _| {})
}

/// [`build_file`], telling `report` how far it is (the viewer's progress).
pub fn build_file_reporting(
    input: &Path,
    output: &Path,
    params: &BuildParams,
    progress: bool,
    report: Report<'_>,
) -> Result<BuildStats, BuildError> {
    let opts = RunOptions {
        progress,
        report,
        memory_limit: None,
    };
    build_file_with(input, output, params, &opts)
}

/// [`build_file`] under `opts`: the input is opened lazily (its geometry
/// read mesh by mesh as cells need it), so the heap stays within the limit.
pub fn build_file_with(
    input: &Path,
    output: &Path,
    params: &BuildParams,
    opts: &RunOptions<'_>,
) -> Result<BuildStats, BuildError> {
    params.check()?;
    (opts.report)("importing", 0, 0);
    let t0 = Instant::now();
    // The output policy first: a device, a directory or the input itself
    // is refused before any work.
    let inputs = import::model_files(input);
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let out = engine_cli::outfile::OutputFile::create(output, &inputs)?;
    let mut opened = import::open(input)?;
    opened.scene.source_key = crate::cache::key_bytes(input, params)?;
    // Every import warning is shown now, whatever becomes of the build.
    for w in &opened.scene.warnings {
        tracing::warn!("{}: {w}", input.display());
    }
    let io_err = |source| BuildError::Io {
        path: output.to_path_buf(),
        source,
    };
    let dir = engine_cli::outfile::parent_dir(out.target()).to_path_buf();
    let sink = BufWriter::with_capacity(1 << 20, out.file().try_clone().map_err(io_err)?);
    let mut stats =
        build_scene_staged(&opened, sink, params, opts, Some(&dir)).map_err(|e| match e {
            Staged::Format(source) => BuildError::Write {
                path: output.to_path_buf(),
                source,
            },
            Staged::Memory(what) => BuildError::Memory(what),
        })?;
    out.commit()?;
    stats.file_bytes = std::fs::metadata(output).map_err(io_err)?.len();
    stats.seconds = t0.elapsed().as_secs_f64();
    Ok(stats)
}

/// Builds an imported scene into `sink`.
pub fn build_scene<W: Write + std::io::Seek>(
    imported: &Imported,
    sink: W,
    params: &BuildParams,
    progress: bool,
) -> Result<BuildStats, FormatError> {
    let opts = RunOptions {
        progress,
        report: &|_, _, _| {},
        memory_limit: None,
    };
    build_scene_staged(imported, sink, params, &opts, None).map_err(|e| match e {
        Staged::Format(f) => f,
        Staged::Memory(m) => FormatError::Io(std::io::Error::other(m)),
    })
}

/// Why a staged build stopped.
enum Staged {
    Format(FormatError),
    Memory(String),
}

impl From<FormatError> for Staged {
    fn from(e: FormatError) -> Self {
        Staged::Format(e)
    }
}

impl From<std::io::Error> for Staged {
    fn from(e: std::io::Error) -> Self {
        Staged::Format(e.into())
    }
}

/// [`build_scene`]; for the spatial layout the reps are first written in the
/// order they are made to a temporary file in `staging` (the system's
/// temporary directory if `None`), then copied into `sink` in layout order.
fn build_scene_staged<S: SceneSource, W: Write + std::io::Seek>(
    src: &S,
    sink: W,
    params: &BuildParams,
    opts: &RunOptions<'_>,
    staging: Option<&Path>,
) -> Result<BuildStats, Staged> {
    if !params.spatial_layout {
        return build_in_make_order(src, sink, params, opts);
    }
    let file = match staging {
        Some(dir) => tempfile::tempfile_in(dir)?,
        None => tempfile::tempfile()?,
    };
    let stats = build_in_make_order(
        src,
        BufWriter::with_capacity(1 << 20, file.try_clone()?),
        params,
        opts,
    )?;
    let staged = engine::format::SceneFile::from_source(engine::io::FileSource::from_file(file)?)?;
    // The copy in layout order needs as much room again as the staged file.
    if let Some(dir) = staging {
        let need = engine::ByteSource::len(staged.source());
        engine_cli::outfile::ensure_free(dir, need).map_err(|e| {
            FormatError::Io(std::io::Error::new(
                std::io::ErrorKind::StorageFull,
                format!("{e}: the spatial layout writes the scene twice (use --layout build to need half)"),
            ))
        })?;
    }
    (opts.report)("writing the spatial layout", stats.nodes, stats.nodes);
    crate::layout::relayout(&staged, sink, crate::layout::Payloads::Keep)?;
    Ok(stats)
}

fn progress_bar(show: bool, len: u64) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    ProgressBar::new(len).with_style(
        ProgressStyle::with_template("{spinner} {msg:12} [{bar:40}] {pos}/{len} nodes  {elapsed}")
            .expect("static template")
            .progress_chars("=> "),
    )
}

/// What every kind of build computes first, from sizes and boxes: the
/// items, the graph, the shared meshes' chains and the memory plan.
struct Prepared {
    items: Vec<Item>,
    tree: Vec<crate::cluster::TreeNode>,
    item_tris: Vec<usize>,
    chains: assemble::Chains,
    /// Repeated leaves' groups and their chains (with sharing on).
    groups: assemble::Groups,
    mplan: memory::MemoryPlan,
}

fn prepare<S: SceneSource>(
    src: &S,
    params: &BuildParams,
    opts: &RunOptions<'_>,
    stats: &mut BuildStats,
) -> Result<Prepared, Staged> {
    let scene = src.scene();
    *stats = BuildStats {
        objects: scene.instances.len() as u64,
        input_triangles: scene.instanced_source_triangles(),
        usable_triangles: scene.instanced_triangles(),
        warnings: scene.warnings.clone(),
        origin: scene.origin,
        ..Default::default()
    };
    // 1. Items, from sizes and boxes (split and tree objects loaded once).
    let made = source::make_items(src, params)?;
    stats.chunked_objects = made.chunked_objects;
    stats.hidden_objects = made.hidden_objects;
    stats.hidden_triangles = made.hidden_triangles;
    stats.usable_triangles -= made.hidden_triangles;
    // 2. Topology.
    (opts.report)("clustering", 0, 0);
    let tree = if params.share_instances {
        cluster(
            &groups::alone(&made.cluster, &made.items, params.leaf_tris),
            params.branching,
            params.leaf_tris,
        )
    } else {
        cluster(&made.cluster, params.branching, params.leaf_tris)
    };
    let item_tris: Vec<usize> = made.cluster.iter().map(|c| c.tris).collect();
    drop(made.cluster);
    let items = made.items;
    let total = tree.len() as u64;
    // 3. Chains of meshes placed by several single-instance leaves, computed
    // once in local space; other leaves compute theirs in their batch.
    (opts.report)("mesh LODs", 0, total);
    // With sharing on, repeated leaves (a mesh's single-instance leaves
    // among them) share one chain each instead.
    let groups = if params.share_instances {
        groups::chains(src, &tree, &items, params)?
    } else {
        assemble::Groups::default()
    };
    let mut placed: Vec<usize> = tree
        .iter()
        .filter(|n| n.items.len() == 1 && !params.share_instances)
        .filter_map(|n| match &items[n.items[0] as usize] {
            Item::Instance { mesh, .. } => Some(*mesh),
            Item::Chunk { .. } | Item::Tree { .. } => None,
        })
        .collect();
    placed.sort_unstable();
    let shared: Vec<usize> = placed
        .chunk_by(|a, b| a == b)
        .filter(|run| run.len() > 1)
        .map(|run| run[0])
        .collect();
    let chains: assemble::Chains = shared
        .par_iter()
        .map(|&m| Ok((m, lod_chain(&*src.mesh(m)?, &params.lod))))
        .collect::<Result<_, FormatError>>()?;
    // 4. The memory plan.
    let mut leaf_tris: Vec<u64> = tree
        .iter()
        .filter(|n| !n.items.is_empty())
        .map(|n| n.items.iter().map(|&k| item_tris[k as usize] as u64).sum())
        .collect();
    leaf_tris.sort_unstable_by(|a, b| b.cmp(a));
    stats.leaves = leaf_tris.len() as u64;
    let chain_bytes: u64 = (chains.iter().map(|(_, c)| c))
        .chain(groups.chains.iter().map(|(c, _)| c))
        .flatten()
        .map(|l| l.mesh.heap_bytes())
        .sum();
    let demand = memory::Demand {
        fixed_now: crate::heap::in_use()
            .unwrap_or(stats.objects * memory::ESTIMATED_BYTES_PER_OBJECT),
        nodes: total,
        objects: stats.objects,
        leaf_tris_desc: leaf_tris,
        interior_batch: memory::interior_batch(
            (params.branching * params.hlod_tris) as u64,
            stats.usable_triangles,
            rayon::current_num_threads(),
        ),
        chains: chain_bytes,
    };
    let limit = opts.memory_limit.unwrap_or_else(memory::default_limit);
    let mplan =
        memory::plan(limit, &demand, rayon::current_num_threads()).map_err(Staged::Memory)?;
    stats.memory_plan = Some(mplan);
    Ok(Prepared {
        items,
        tree,
        item_tris,
        chains,
        groups,
        mplan,
    })
}

/// An assembly over `prep` writing to `sink`, every node still to make.
fn assembly<'a, W: Write + std::io::Seek>(
    prep: &'a Prepared,
    sink: W,
    params: &'a BuildParams,
    opts: &RunOptions<'a>,
    stats: &'a mut BuildStats,
) -> Result<assemble::Assembly<'a, W>, FormatError> {
    let tree = &prep.tree;
    let mut nodes = vec![NodeRecord::default(); tree.len()];
    for (i, t) in tree.iter().enumerate() {
        let n = &mut nodes[i];
        n.parent = t.parent.unwrap_or(NONE);
        n.depth = t.depth;
        n.first_child = t.children.first().copied().unwrap_or(0);
        n.child_count = t.children.len() as u32;
        n.object = NONE;
    }
    Ok(assemble::Assembly {
        writer: SceneWriter::new(sink)?,
        tree,
        items: &prep.items,
        params,
        chains: &prep.chains,
        groups: &prep.groups,
        nodes,
        node_reps: vec![Vec::new(); tree.len()],
        coarse: (0..tree.len()).map(|_| None).collect(),
        leaf_runs: Vec::new(),
        stats,
        bar: progress_bar(opts.progress, tree.len() as u64),
        report: opts.report,
        done: 0,
        batch: prep.mplan.batch,
        written: Default::default(),
        pending: Vec::new(),
    })
}

/// Makes the nodes of `plan`: cell by cell, its leaves and then its
/// interior nodes deepest first; then the nodes above the cells.
fn make_nodes<S: SceneSource, W: Write + std::io::Seek>(
    asm: &mut assemble::Assembly<'_, W>,
    src: &S,
    plan: &cells::Plan,
) -> Result<(), FormatError> {
    for cell in &plan.cells {
        asm.bar.set_message("leaf LODs");
        asm.leaves(src, &cell.leaves)?;
        asm.bar.set_message("HLODs");
        asm.interior(&cell.interior)?;
    }
    asm.interior(&plan.upper)?;
    asm.bar.finish_and_clear();
    Ok(())
}

/// The skeleton of every node's records (first reps numbered in node order).
fn skeleton_of(mut nodes: Vec<NodeRecord>, node_reps: Vec<Vec<RepRecord>>) -> Skeleton {
    let mut reps = Vec::new();
    for (i, recs) in node_reps.into_iter().enumerate() {
        nodes[i].first_rep = reps.len() as u32;
        nodes[i].rep_count = recs.len() as u32;
        reps.extend(recs);
    }
    Skeleton {
        nodes,
        reps,
        ..Skeleton::default()
    }
}

/// The object section and the header's figures.
fn scene_tail(
    scene: &Imported,
    stats: &BuildStats,
    leaf_runs: &[(u32, Vec<engine::format::objects::Run>)],
) -> (SceneMeta, Vec<u8>) {
    let meta = SceneMeta {
        object_count: stats.objects as u32,
        input_triangles: stats.input_triangles,
        origin: scene.origin,
        source_key: scene.source_key,
        drawn_triangles: stats.usable_triangles,
        hidden_triangles: stats.hidden_triangles,
    };
    (meta, ObjectTable::encode(&object_infos(scene), leaf_runs))
}

/// The walk section of the drawn objects.
pub(crate) fn walk_tail<S: SceneSource>(
    src: &S,
    params: &BuildParams,
    opts: &RunOptions<'_>,
    stats: &mut BuildStats,
) -> Result<Vec<u8>, FormatError> {
    (opts.report)("walk section", 0, 0);
    let draws = source::drawn(src.scene(), params);
    // What the cells and batches used is free again.
    let heap = stats
        .memory_plan
        .map_or(u64::MAX, |p| p.limit.saturating_sub(p.fixed) / 2)
        .max(1 << 20);
    let (bytes, walk) = crate::walkmap::walk_section(src, params.walk_cell, &draws, heap)?;
    stats.walk = walk;
    Ok(bytes)
}

/// The figures of a finished skeleton.
fn skeleton_stats(stats: &mut BuildStats, skeleton: &Skeleton, object_bytes: usize) {
    stats.object_bytes = object_bytes as u64;
    stats.nodes = skeleton.nodes.len() as u64;
    stats.height = skeleton.height();
    stats.reps = skeleton.reps.len() as u64;
    stats.output_triangles = skeleton.total_triangles();
    stats.skeleton_bytes = (std::mem::size_of_val(skeleton.nodes.as_slice())
        + std::mem::size_of_val(skeleton.reps.as_slice())
        + std::mem::size_of_val(skeleton.placements.as_slice())) as u64;
    stats.data_bytes = (skeleton.reps.iter().enumerate())
        .filter(|&(r, _)| skeleton.owns_payload(r as u32))
        .map(|(_, r)| r.extent())
        .sum();
    stats.peak_heap = crate::heap::peak();
}

fn build_in_make_order<S: SceneSource, W: Write + std::io::Seek>(
    src: &S,
    sink: W,
    params: &BuildParams,
    opts: &RunOptions<'_>,
) -> Result<BuildStats, Staged> {
    let mut stats = BuildStats::default();
    let prep = prepare(src, params, opts, &mut stats)?;
    let plan = cells::plan(&prep.tree, &prep.item_tris, prep.mplan.cell_tris, &[0]);
    stats.cells = plan.cells.len() as u64;
    let mut asm = assembly(&prep, sink, params, opts, &mut stats)?;
    make_nodes(&mut asm, src, &plan)?;
    let assemble::Assembly {
        writer,
        nodes,
        node_reps,
        leaf_runs,
        pending,
        ..
    } = asm;
    let mut skeleton = skeleton_of(nodes, node_reps);
    placed::resolve(&mut skeleton, &pending);
    let (meta, objects) = scene_tail(src.scene(), &stats, &leaf_runs);
    let walk = walk_tail(src, params, opts, &mut stats)?;
    let mut sink = writer.finish_with_sections(&skeleton, &meta, &objects, &walk)?;
    sink.flush()?;
    skeleton_stats(&mut stats, &skeleton, objects.len());
    Ok(stats)
}
