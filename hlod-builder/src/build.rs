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

use engine::format::objects::{ObjectTable, Run};
use engine::format::{NONE, NodeRecord, RepKind, RepMesh, RepRecord, SceneMeta, SceneWriter};
use engine::{FormatError, Skeleton};

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

mod leaf;

use crate::cluster::{ClusterItem, cluster};
use crate::import::{self, ImportError, Imported};
use crate::lod::{LodParams, hlod, lod_chain, strictly_above};
use crate::mesh::{Aabb, Mesh};
use leaf::{Item, LeafGeometry, item_object, leaf_levels, object_infos, transformed_bounds};

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
    Output(#[from] engine::outfile::OutputError),
}

/// Table-1 figures of a finished build.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildStats {
    pub objects: u64,
    pub nodes: u64,
    pub leaves: u64,
    pub chunked_objects: u64,
    /// Objects whose finest rep is a view-dependence tree.
    pub vdt_objects: u64,
    /// Objects whose finest rep is a Multi-Triangulation.
    pub mt_objects: u64,
    pub height: u32,
    pub reps: u64,
    /// Source triangles after instancing.
    pub input_triangles: u64,
    /// Of those, the non-degenerate ones (what the finest reps hold).
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
}

/// A finished node's coarsest rep, kept for its parent's HLOD.
struct Coarse {
    mesh: Mesh,
    error: f32,
}

/// Where a build is: a stage name, nodes done and nodes in all (0 while
/// the total is not known yet).
pub type Report<'a> = &'a (dyn Fn(&str, u64, u64) + Sync);

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
    params.check()?;
    report("importing", 0, 0);
    let t0 = Instant::now();
    // The output policy first: a device, a directory or the input itself
    // is refused before any work.
    let out = engine::outfile::OutputFile::create(output, &[input])?;
    let imported = import::load(input)?;
    // Every import warning is shown now, whatever becomes of the build.
    for w in &imported.warnings {
        tracing::warn!("{}: {w}", input.display());
    }
    let io_err = |source| BuildError::Io {
        path: output.to_path_buf(),
        source,
    };
    let dir = engine::outfile::parent_dir(out.target()).to_path_buf();
    let sink = BufWriter::with_capacity(1 << 20, out.file().try_clone().map_err(io_err)?);
    let mut stats = build_scene_staged(&imported, sink, params, (progress, report), Some(&dir))
        .map_err(|source| BuildError::Write {
            path: output.to_path_buf(),
            source,
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
    build_scene_staged(imported, sink, params, (progress, &|_, _, _| {}), None)
}

/// [`build_scene`]; for the spatial layout the reps are first written in the
/// order they are made to a temporary file in `staging` (the system's
/// temporary directory if `None`), then copied into `sink` in layout order.
fn build_scene_staged<W: Write + std::io::Seek>(
    imported: &Imported,
    sink: W,
    params: &BuildParams,
    progress: (bool, Report<'_>),
    staging: Option<&Path>,
) -> Result<BuildStats, FormatError> {
    if !params.spatial_layout {
        return build_in_make_order(imported, sink, params, progress);
    }
    let file = match staging {
        Some(dir) => tempfile::tempfile_in(dir)?,
        None => tempfile::tempfile()?,
    };
    let stats = build_in_make_order(
        imported,
        BufWriter::with_capacity(1 << 20, file.try_clone()?),
        params,
        progress,
    )?;
    let staged = engine::format::SceneFile::from_source(engine::io::FileSource::from_file(file)?)?;
    // The copy in layout order needs as much room again as the staged file.
    if let Some(dir) = staging {
        let need = engine::ByteSource::len(staged.source());
        engine::outfile::ensure_free(dir, need).map_err(|e| {
            FormatError::Io(std::io::Error::new(
                std::io::ErrorKind::StorageFull,
                format!("{e}: the spatial layout writes the scene twice (use --layout build to need half)"),
            ))
        })?;
    }
    progress.1("writing the spatial layout", stats.nodes, stats.nodes);
    crate::layout::relayout(&staged, sink, crate::layout::Payloads::Keep)?;
    Ok(stats)
}

fn build_in_make_order<W: Write + std::io::Seek>(
    imported: &Imported,
    sink: W,
    params: &BuildParams,
    (progress, report): (bool, Report<'_>),
) -> Result<BuildStats, FormatError> {
    let mut stats = BuildStats {
        objects: imported.instances.len() as u64,
        input_triangles: imported.instanced_source_triangles(),
        usable_triangles: imported.instanced_triangles(),
        warnings: imported.warnings.clone(),
        origin: imported.origin,
        ..Default::default()
    };
    let mut leaf_runs: Vec<(u32, Vec<Run>)> = Vec::new();
    // 1. Items.
    let mut items = Vec::new();
    let mut cluster_items = Vec::new();
    for (obj, inst) in imported.instances.iter().enumerate() {
        let mesh = imported.meshes[inst.mesh]
            .as_ref()
            .expect("instances refer to usable meshes");
        let mt = params.mt_tris > 0 && mesh.tri_count() >= params.mt_tris;
        if mt || (params.vdt_tris > 0 && mesh.tri_count() >= params.vdt_tris) {
            let world = mesh.transformed(&inst.transform);
            cluster_items.push(ClusterItem {
                bounds: world.bounds(),
                tris: world.tri_count(),
            });
            items.push(Item::Tree {
                mesh: world,
                object: obj as u32,
                mt,
            });
        } else if mesh.tri_count() > params.chunk_tris {
            stats.chunked_objects += 1;
            for chunk in mesh
                .transformed(&inst.transform)
                .split_spatial(params.chunk_tris)
            {
                cluster_items.push(ClusterItem {
                    bounds: chunk.bounds(),
                    tris: chunk.tri_count(),
                });
                items.push(Item::Chunk {
                    mesh: chunk,
                    object: obj as u32,
                });
            }
        } else {
            cluster_items.push(ClusterItem {
                bounds: transformed_bounds(mesh.bounds(), &inst.transform),
                tris: mesh.tri_count(),
            });
            items.push(Item::Instance {
                mesh: inst.mesh,
                transform: inst.transform,
                object: obj as u32,
            });
        }
    }
    // 2. Topology.
    report("clustering", 0, 0);
    let tree = cluster(&cluster_items, params.branching, params.leaf_tris);
    let total = tree.len() as u64;
    let mut done = 0u64;
    let bar = if progress {
        ProgressBar::new(tree.len() as u64).with_style(
            ProgressStyle::with_template(
                "{spinner} {msg:12} [{bar:40}] {pos}/{len} nodes  {elapsed}",
            )
            .expect("static template")
            .progress_chars("=> "),
        )
    } else {
        ProgressBar::hidden()
    };
    // 3. Chains of meshes placed by several single-instance leaves, computed
    // once in local space; other leaves compute theirs in their batch.
    bar.set_message("mesh LODs");
    report("mesh LODs", 0, total);
    let mut placed: Vec<usize> = tree
        .iter()
        .filter(|n| n.items.len() == 1)
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
    let chains: Vec<(usize, Vec<crate::lod::Level>)> = shared
        .par_iter()
        .map(|&m| {
            (
                m,
                lod_chain(imported.meshes[m].as_ref().expect("usable"), &params.lod),
            )
        })
        .collect();
    let chain_of = |m: usize| {
        chains
            .binary_search_by_key(&m, |(k, _)| *k)
            .ok()
            .map(|k| &chains[k].1)
    };

    let mut writer = SceneWriter::new(sink)?;
    let mut nodes = vec![NodeRecord::default(); tree.len()];
    let mut node_reps: Vec<Vec<RepRecord>> = vec![Vec::new(); tree.len()];
    let mut coarse: Vec<Option<Coarse>> = (0..tree.len()).map(|_| None).collect();
    for (i, t) in tree.iter().enumerate() {
        let n = &mut nodes[i];
        n.parent = t.parent.unwrap_or(NONE);
        n.depth = t.depth;
        n.first_child = t.children.first().copied().unwrap_or(0);
        n.child_count = t.children.len() as u32;
        n.object = NONE;
    }
    // 4. Leaves, in batches, written in breadth-first order.
    bar.set_message("leaf LODs");
    report("leaf LODs", 0, total);
    let leaves: Vec<usize> = (0..tree.len())
        .filter(|&i| !tree[i].items.is_empty())
        .collect();
    stats.leaves = leaves.len() as u64;
    for batch in leaves.chunks(64) {
        let made: Vec<LeafGeometry> = batch
            .par_iter()
            .map(|&i| leaf_levels(&tree[i].items, &items, imported, params, &chain_of))
            .collect();
        for (&i, (levels, vdt, runs)) in batch.iter().zip(made) {
            if let Some(r) = runs {
                leaf_runs.push((i as u32, r));
            }
            let objects: Vec<u32> = tree[i]
                .items
                .iter()
                .map(|&k| item_object(&items[k as usize]))
                .collect();
            let n = &mut nodes[i];
            n.object_count = objects.len() as u32;
            if objects.len() == 1 {
                n.object = objects[0];
                if matches!(items[tree[i].items[0] as usize], Item::Chunk { .. }) {
                    n.flags |= NodeRecord::FLAG_CHUNK;
                }
            } else {
                n.flags |= NodeRecord::FLAG_MERGED;
            }
            let (mut recs, c) = write_chain(
                &mut writer,
                i as u32,
                levels,
                (RepKind::Lod, params.compress_reps),
                0.0,
            )?;
            if let Some(t) = vdt {
                if t.kind == RepKind::Mt {
                    stats.mt_objects += 1;
                } else {
                    stats.vdt_objects += 1;
                }
                recs.push(crate::vdt::write_rep(&mut writer, i as u32, &recs, &t)?);
            }
            finish_node(&mut nodes[i], &recs, &c.mesh, &[]);
            node_reps[i] = recs;
            coarse[i] = Some(c);
            bar.inc(1);
            done += 1;
        }
        report("leaf LODs", done, total);
    }
    // 5. Interior nodes, deepest level first.
    bar.set_message("HLODs");
    let max_depth = tree.iter().map(|t| t.depth).max().unwrap_or(0);
    for depth in (0..=max_depth).rev() {
        let level: Vec<usize> = (0..tree.len())
            .filter(|&i| tree[i].depth == depth && !tree[i].children.is_empty())
            .collect();
        for batch in level.chunks(32) {
            let inputs: Vec<(Mesh, f32)> = batch
                .iter()
                .map(|&i| {
                    let kids: Vec<&Coarse> = tree[i]
                        .children
                        .iter()
                        .map(|&c| coarse[c as usize].as_ref().expect("children done first"))
                        .collect();
                    let merged = Mesh::merge(kids.iter().map(|k| &k.mesh));
                    let floor = kids.iter().map(|k| k.error).fold(0.0, f32::max);
                    (merged, floor)
                })
                .collect();
            let made: Vec<(Mesh, f32, f32)> = inputs
                .into_par_iter()
                .map(|(merged, floor)| {
                    let budget = ((merged.tri_count() as f32 * params.hlod_ratio) as usize).clamp(
                        params.lod.min_tris.min(merged.tri_count()),
                        params.hlod_tris,
                    );
                    let (m, e) = hlod(&merged, budget);
                    (m, floor, e)
                })
                .collect();
            for (&i, (mesh, floor, e)) in batch.iter().zip(made) {
                let level = crate::lod::Level {
                    mesh,
                    error: floor + e,
                };
                let (recs, c) = write_chain(
                    &mut writer,
                    i as u32,
                    vec![level],
                    (RepKind::Hlod, params.compress_reps),
                    floor,
                )?;
                let child_boxes: Vec<([f32; 3], [f32; 3])> = tree[i]
                    .children
                    .iter()
                    .map(|&ch| (nodes[ch as usize].bbox_min, nodes[ch as usize].bbox_max))
                    .collect();
                nodes[i].object_count = tree[i]
                    .children
                    .iter()
                    .map(|&ch| nodes[ch as usize].object_count)
                    .sum();
                finish_node(&mut nodes[i], &recs, &c.mesh, &child_boxes);
                node_reps[i] = recs;
                coarse[i] = Some(c);
                for &ch in &tree[i].children {
                    coarse[ch as usize] = None;
                }
                bar.inc(1);
                done += 1;
            }
            report("HLODs", done, total);
        }
    }
    bar.finish_and_clear();
    // 6. Skeleton.
    let mut reps = Vec::new();
    for (i, recs) in node_reps.into_iter().enumerate() {
        nodes[i].first_rep = reps.len() as u32;
        nodes[i].rep_count = recs.len() as u32;
        reps.extend(recs);
    }
    let skeleton = Skeleton { nodes, reps };
    let meta = SceneMeta {
        object_count: stats.objects as u32,
        input_triangles: stats.input_triangles,
        origin: imported.origin,
    };
    let objects = ObjectTable::encode(&object_infos(imported), &leaf_runs);
    stats.object_bytes = objects.len() as u64;
    let mut sink = writer.finish_with_objects(&skeleton, &meta, &objects)?;
    sink.flush()?;
    stats.nodes = skeleton.nodes.len() as u64;
    stats.height = skeleton.height();
    stats.reps = skeleton.reps.len() as u64;
    stats.output_triangles = skeleton.total_triangles();
    stats.skeleton_bytes = (std::mem::size_of_val(skeleton.nodes.as_slice())
        + std::mem::size_of_val(skeleton.reps.as_slice())) as u64;
    stats.data_bytes = skeleton.reps.iter().map(RepRecord::extent).sum();
    Ok(stats)
}

/// Writes a node's levels (coarsest first), compressed or not; `floor` is an
/// error every rep must exceed (the children's for an HLOD). Returns the
/// records and the coarsest level.
fn write_chain<W: Write + std::io::Seek>(
    writer: &mut SceneWriter<W>,
    node: u32,
    levels: Vec<crate::lod::Level>,
    (kind, compress): (RepKind, bool),
    floor: f32,
) -> Result<(Vec<RepRecord>, Coarse), FormatError> {
    let n = levels.len();
    let mut recs = vec![RepRecord::default(); n];
    let mut below = if kind == RepKind::Hlod {
        Some(floor)
    } else {
        None
    };
    // Finest first, so each coarser error is made strictly larger.
    for (i, level) in levels.iter().enumerate().rev() {
        let m = &level.mesh;
        let packed = RepMesh::quantize(&m.positions, &m.normals, &m.colors, m.indices.clone());
        let raw = level.error + packed.quantization_error();
        let error = match below {
            Some(b) => strictly_above(b, raw),
            None => raw,
        };
        below = Some(error);
        let payload = if compress {
            packed.encode_compressed(node, i as u32)
        } else {
            packed.encode(node, i as u32)
        };
        let loc = writer.write_rep(&payload)?;
        let (bbox_min, bbox_max) = m.bounds().to_arrays();
        recs[i] = RepRecord {
            bbox_min,
            bbox_max,
            node,
            index: i as u16,
            kind: kind as u16,
            error,
            checksum: loc.checksum,
            offset: loc.offset,
            len: loc.len,
            tri_count: m.tri_count() as u32,
            vertex_count: m.vertex_count() as u32,
            aux: 0,
        };
    }
    let first = levels.into_iter().next().expect("at least one level");
    Ok((
        recs.clone(),
        Coarse {
            mesh: first.mesh,
            error: recs[0].error,
        },
    ))
}

/// Box and colour of a node from its reps and children.
fn finish_node(
    n: &mut NodeRecord,
    reps: &[RepRecord],
    color_mesh: &Mesh,
    child_boxes: &[([f32; 3], [f32; 3])],
) {
    let mut b = Aabb::EMPTY;
    for r in reps {
        b.add(r.bbox_min.into());
        b.add(r.bbox_max.into());
    }
    for (mn, mx) in child_boxes {
        b.add((*mn).into());
        b.add((*mx).into());
    }
    (n.bbox_min, n.bbox_max) = b.to_arrays();
    n.color = u32::from_le_bytes(color_mesh.dominant_color());
}
