//! `hlod-build build` and `hlod-build merge`: the options, and running a
//! build, a shard job or a merge.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;
use hlod_builder::build::BuildParams;
use hlod_builder::lod::LodParams;
use hlod_builder::summary::{TABLE_HEADER, human_bytes, table_row};

#[derive(Args, Debug)]
pub(crate) struct BuildArgs {
    input: PathBuf,
    #[arg(short, long)]
    output: PathBuf,
    /// Children per interior node (at most).
    #[arg(long, default_value_t = 8)]
    branching: usize,
    /// Merge clusters of small objects into one leaf up to this many triangles (0: never).
    #[arg(long, default_value_t = 1024)]
    leaf_tris: usize,
    /// Split objects larger than this many triangles into spatial chunks.
    #[arg(long, default_value_t = 65536)]
    chunk_tris: usize,
    /// Triangle budget of each HLOD.
    #[arg(long, default_value_t = 8192)]
    hlod_tris: usize,
    /// HLOD target as a fraction of the merged children's coarsest reps.
    #[arg(long, default_value_t = 0.5)]
    hlod_ratio: f32,
    /// Triangle ratio between successive LODs.
    #[arg(long, default_value_t = 0.25)]
    lod_ratio: f32,
    /// Most LODs per object, the original included.
    #[arg(long, default_value_t = 6)]
    max_lods: usize,
    /// Objects of at least this many triangles get a view-dependence tree as
    /// their finest rep (paged by meta-nodes, refined per frame) instead of
    /// being split into chunks (0: none).
    #[arg(long, default_value_t = 0)]
    vdt_tris: usize,
    /// How many of the coarsest static LODs such an object keeps below its
    /// tree or MT.
    #[arg(long, default_value_t = 2)]
    vdt_keep: usize,
    /// Objects of at least this many triangles get a Multi-Triangulation
    /// (Holst & Schumann: patches paged by partitions, cut per frame) as
    /// their finest rep (0: none; takes precedence over --vdt-tris).
    #[arg(long, default_value_t = 0)]
    mt_tris: usize,
    /// MT nodes per partition, at most (the paper: 50-100 in scenes of many
    /// objects).
    #[arg(long, default_value_t = 64)]
    mt_theta: u32,
    /// Largest MT patch cluster in triangles.
    #[arg(long, default_value_t = 16)]
    mt_cluster_tris: usize,
    /// Order of the reps on disk: `spatial` (selection band, then Morton
    /// order: one frame's misses lie close together) or `build` (the order
    /// they are made: each leaf's chain, then the HLODs level by level).
    #[arg(long, default_value = "spatial")]
    layout: String,
    /// Store mesh rep payloads raw instead of through meshopt's vertex and
    /// index codecs (larger files; for comparison).
    #[arg(long)]
    raw_reps: bool,
    /// Store an instanced mesh's levels once per placement, in scene
    /// coordinates, instead of once for all its placements (larger files
    /// and footprints; for comparison).
    #[arg(long)]
    copy_instances: bool,
    /// The most heap the build may use, e.g. 4G or 512M (default: half of
    /// this machine's memory). The scene graph is built in cells sized to
    /// it; the output does not depend on it.
    #[arg(long, value_parser = parse_memory)]
    memory_limit: Option<u64>,
    /// Make only share I of N of the scene graph into a shard file (an
    /// independent job; `hlod-build merge` joins the N files).
    #[arg(long)]
    shard: Option<hlod_builder::build::shard::ShardSpec>,
    /// Keep the objects of IFC exports that stand for no visible part
    /// (openings' voids, spaces' volumes: `IfcOpeningElement*`,
    /// `IfcSpace*` by name), which are left out by default.
    #[arg(long)]
    ifc_voids: bool,
    /// Cell side of the walk section in metres: solid space by columns,
    /// which walk mode collides with (0: none; a site too large for 32M
    /// cells gets a coarser grid).
    #[arg(long, default_value_t = 0.1)]
    walk_cell: f32,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

fn parse_memory(s: &str) -> Result<u64, String> {
    hlod_builder::build::memory::parse_size(s)
}

fn params_of(a: &BuildArgs) -> Result<BuildParams> {
    Ok(BuildParams {
        lod: LodParams {
            ratio: a.lod_ratio,
            max_levels: a.max_lods,
            ..LodParams::default()
        },
        branching: a.branching,
        leaf_tris: a.leaf_tris,
        chunk_tris: a.chunk_tris,
        hlod_tris: a.hlod_tris,
        hlod_ratio: a.hlod_ratio,
        vdt_tris: a.vdt_tris,
        vdt_keep: a.vdt_keep,
        mt_tris: a.mt_tris,
        mt: hlod_builder::mt::MtRepParams {
            mt: hlod_builder::mt::MtParams {
                cluster_tris: a.mt_cluster_tris,
                ..Default::default()
            },
            theta: a.mt_theta,
        },
        spatial_layout: match a.layout.as_str() {
            "spatial" => true,
            "build" => false,
            l => anyhow::bail!("--layout {l:?}: use spatial or build"),
        },
        compress_reps: !a.raw_reps,
        ifc_voids: a.ifc_voids,
        walk_cell: a.walk_cell,
        share_instances: !a.copy_instances,
    })
}

/// How the build reports: a progress bar on a terminal unless `-q`.
fn run_options(a: &BuildArgs) -> hlod_builder::build::RunOptions<'static> {
    hlod_builder::build::RunOptions {
        progress: !a.quiet && std::io::IsTerminal::is_terminal(&std::io::stderr()),
        report: &|_, _, _| {},
        memory_limit: a.memory_limit,
    }
}

/// The summary table's header and the row of `input`'s build.
fn print_table(input: &std::path::Path, stats: &hlod_builder::build::BuildStats) {
    let name = input
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    println!("{TABLE_HEADER}\n{}", table_row(&name, stats));
}

pub(crate) fn merge(a: BuildArgs, shards: &[PathBuf]) -> Result<()> {
    if a.shard.is_some() {
        bail!("merge takes the shard files, not --shard");
    }
    let params = params_of(&a)?;
    let opts = run_options(&a);
    let stats =
        hlod_builder::build::shard::merge_files(&a.input, shards, &a.output, &params, &opts)?;
    print_table(&a.input, &stats);
    println!(
        "merged {} shards into {}; peak heap {}",
        stats.cells,
        a.output.display(),
        stats
            .peak_heap
            .map_or_else(|| "not counted".into(), human_bytes)
    );
    Ok(())
}

pub(crate) fn build(a: BuildArgs) -> Result<()> {
    let params = params_of(&a)?;
    let opts = run_options(&a);
    if let Some(spec) = a.shard {
        let s = hlod_builder::build::shard::build_shard_file(
            &a.input, &a.output, &params, &opts, spec,
        )?;
        println!(
            "wrote shard {}/{} to {}: {} nodes in {} cell(s), {}; peak heap {}",
            spec.index,
            spec.count,
            a.output.display(),
            s.nodes,
            s.cells,
            human_bytes(s.file_bytes),
            s.peak_heap
                .map_or_else(|| "not counted".into(), human_bytes)
        );
        return Ok(());
    }
    // Import warnings are printed by the build as soon as they are known.
    let stats = hlod_builder::build::build_file_with(&a.input, &a.output, &params, &opts)?;
    print_table(&a.input, &stats);
    println!(
        "wrote {} ({} objects split into chunks, {} with a view-dependence tree, {} with a Multi-Triangulation, {} degenerate triangles dropped)",
        a.output.display(),
        stats.chunked_objects,
        stats.vdt_objects,
        stats.mt_objects,
        stats.input_triangles - stats.usable_triangles - stats.hidden_triangles
    );
    if stats.hidden_objects > 0 {
        println!(
            "left out {} IFC opening voids and spaces ({} triangles; --ifc-voids keeps them)",
            stats.hidden_objects, stats.hidden_triangles
        );
    }
    println!("{}", hlod_builder::walkmap::walk_line(&stats.walk));
    if let Some(p) = stats.memory_plan {
        println!(
            "memory: limit {}, {} for the objects and graph, {} cell(s) of at most {} input triangles, leaves {} at a time; peak heap {}",
            human_bytes(p.limit),
            human_bytes(p.fixed),
            stats.cells,
            p.cell_tris,
            p.batch,
            stats
                .peak_heap
                .map_or_else(|| "not counted".into(), human_bytes)
        );
    }
    Ok(())
}
