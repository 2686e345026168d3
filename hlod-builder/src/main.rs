//! `hlod-build`: build, inspect and generate out-of-core scenes.

mod build_cmd;
mod mt_cmd;
#[cfg(feature = "publish")]
mod publish_cmd;
mod tree_cmd;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use hlod_builder::scenegen::{lattice, plant, tile};
use hlod_builder::summary::{TABLE_HEADER, human_bytes, stats_of, table_row};

#[derive(Parser, Debug)]
#[command(
    name = "hlod-build",
    version,
    about = "Build out-of-core HLOD scenes from glTF 2.0"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
    /// A folder a glTF's buffer and image `uri`s may name besides the
    /// model's own (repeatable); a `uri` that leaves both is refused.
    #[arg(long, global = true, value_name = "DIR")]
    allow_dir: Vec<PathBuf>,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Build a glTF/GLB scene into a scene file.
    Build(build_cmd::BuildArgs),
    /// Print a scene file's summary and validate it.
    Info {
        /// Scene file, or its URL (http://, https://, s3://BUCKET/KEY; S3
        /// credentials from the AWS_* variables).
        file: PathBuf,
        /// Skip reading and checking every rep payload (header and skeleton only).
        #[arg(long)]
        no_verify_data: bool,
        /// Print the model tree (site, building, storey, type; or the glTF
        /// node hierarchy) down to this many levels of groups.
        #[arg(long, value_name = "DEPTH", num_args = 0..=1, default_missing_value = "3")]
        tree: Option<usize>,
    },
    /// Rewrite a scene file with its reps in the spatial layout (selection
    /// band, then Morton order; see `hlod_builder::layout`), atomically.
    Relayout {
        input: PathBuf,
        #[arg(short, long)]
        output: PathBuf,
        /// Mesh rep payloads: `compressed` (meshopt codecs, the default of
        /// format version 3), `raw`, or `keep` (copied as they are).
        #[arg(long, default_value = "compressed")]
        reps: String,
    },
    /// Upload a scene file to S3-compatible object storage (s3://BUCKET/KEY)
    /// as one multipart upload, every part checked by MD5 before the object
    /// appears; credentials and endpoint from the AWS_* environment variables.
    #[cfg(feature = "publish")]
    Publish(publish_cmd::PublishArgs),
    /// Merge the shard files of a sharded build (`build --shard I/N`, one
    /// file per shard, all N) into the scene file, with the same build options.
    Merge {
        #[command(flatten)]
        build: build_cmd::BuildArgs,
        /// The shard files, in any order.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
    },
    /// Export a scene file as an OGC 3D Tiles 1.1 tileset (tileset.json,
    /// one .glb per rep), for CesiumJS, 3DTilesRendererJS and other 3D Tiles
    /// viewers; a viewer's screen-space error target means what ε means
    /// here. Written atomically: OUTPUT is replaced only when complete.
    #[command(name = "export-3dtiles")]
    Export3dTiles {
        /// Scene file.
        scene: PathBuf,
        /// Output folder (absent, empty, or an earlier export).
        #[arg(short, long)]
        output: PathBuf,
        /// Most tiles in one JSON file; larger subtrees become external
        /// tilesets.
        #[arg(long, default_value_t = 10_000)]
        max_tiles_per_json: usize,
        /// Merge each subtree storing at most SIZE (e.g. 256K) into one chain
        /// of larger tiles, for browsers; 0: a tile per rep.
        #[arg(long, default_value = "0", value_parser = hlod_builder::tiles3d::parse_bundle)]
        bundle: u64,
    },
    /// Generate a glTF scene.
    #[command(subcommand)]
    Gen(GenCmd),
    /// Build the view-dependence tree of each mesh of a model and report it
    /// (El-Sana & Chiang Table 1: input size, construction time, tree size).
    /// Build the Multi-Triangulation of a model's largest mesh (Holst &
    /// Schumann), check it, partition it and report it.
    Mt {
        input: PathBuf,
        /// Nodes per partition, at most (the paper: up to 20 for one
        /// object, 50-100 for scenes of many).
        #[arg(long, default_value_t = 20)]
        theta: u32,
        /// Largest cluster (patch) in triangles.
        #[arg(long, default_value_t = 16)]
        cluster_tris: usize,
        /// Clusters simplified together in one node.
        #[arg(long, default_value_t = 8)]
        group_clusters: usize,
        /// Write the MT file, atomically.
        #[arg(short, long)]
        output: Option<PathBuf>,
    },
    Vdt {
        input: PathBuf,
        /// quadric or length.
        #[arg(long, default_value = "quadric")]
        metric: String,
        /// Disk block the meta-nodes are sized to (chooses L).
        #[arg(long, default_value_t = 4096)]
        block: usize,
        /// Write the largest mesh's tree as a `.vdt` file (meta-node trees
        /// and the flat layout), atomically.
        #[arg(short, long)]
        output: Option<PathBuf>,
    },
}

#[derive(Subcommand, Debug)]
enum GenCmd {
    /// A procedural CAD plant (pipes, elbows, tanks, girders, stairs, walkways, equipment).
    Plant {
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[arg(long, default_value_t = 1200)]
        objects: usize,
        #[arg(long, default_value_t = 2_000_000)]
        triangles: u64,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Thin members: lattice towers, pipe racks and railings on a grid of
    /// UNITS x UNITS (members of 2-9 cm; for checking that simplification
    /// keeps them).
    Lattice {
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[arg(long, default_value_t = 6)]
        units: u32,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// A closed scan-like surface of about TRIS triangles (a displaced
    /// sphere; one mesh), for Multi-Triangulations and trees at any size.
    Rock {
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[arg(long, default_value_t = 1_000_000, value_parser = engine_cli::in_range(32usize, 200_000_000))]
        tris: usize,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Lay a model out on an N x M grid.
    Tile {
        input: PathBuf,
        /// Grid size, e.g. 8x8.
        #[arg(long)]
        grid: String,
        /// Share the meshes between tiles (default).
        #[arg(long, conflicts_with = "baked")]
        instanced: bool,
        /// Copy the geometry into every tile.
        #[arg(long)]
        baked: bool,
        /// Gap between tiles as a fraction of the model's footprint.
        #[arg(long, default_value_t = 0.1)]
        gap: f32,
        #[arg(short, long)]
        output: PathBuf,
    },
}

/// The heap is counted, so that a build can be sized to `--memory-limit`
/// and report its peak.
#[global_allocator]
static HEAP: hlod_builder::heap::Counting = hlod_builder::heap::Counting;

fn main() -> ExitCode {
    hlod_builder::heap::mark_installed();
    engine_cli::main_with(|| run(Cli::parse()))
}

fn run(cli: Cli) -> Result<()> {
    for dir in &cli.allow_dir {
        hlod_builder::import::allow_dir(dir)
            .with_context(|| format!("--allow-dir {}", dir.display()))?;
    }
    match cli.cmd {
        Cmd::Build(a) => build_cmd::build(a),
        Cmd::Merge { build, shards } => build_cmd::merge(build, &shards),
        #[cfg(feature = "publish")]
        Cmd::Publish(a) => publish_cmd::publish(&a),
        Cmd::Info {
            file,
            no_verify_data,
            tree,
        } => info(&file, !no_verify_data, tree),
        Cmd::Relayout {
            input,
            output,
            reps,
        } => {
            use hlod_builder::layout::Payloads;
            let payloads = match reps.as_str() {
                "compressed" => Payloads::Compressed,
                "raw" => Payloads::Raw,
                "keep" => Payloads::Keep,
                r => anyhow::bail!("--reps {r:?}: use compressed, raw or keep"),
            };
            hlod_builder::layout::relayout_file(&input, &output, payloads)?;
            println!("{} -> {}", input.display(), output.display());
            Ok(())
        }
        Cmd::Export3dTiles {
            scene,
            output,
            max_tiles_per_json,
            bundle,
        } => {
            let t = std::time::Instant::now();
            let opts = hlod_builder::tiles3d::ExportOptions {
                max_tiles_per_json,
                bundle_bytes: bundle,
            };
            let r = hlod_builder::tiles3d::export(&scene, &output, opts)?;
            let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
            println!(
                "{} -> {}: {} tiles, {} .glb ({:.1} MiB; {} name their elements), {} JSON files ({:.2} MiB, largest {:.2} MiB) in {:.1} s",
                scene.display(),
                output.display(),
                r.tiles,
                r.contents,
                mib(r.content_bytes),
                r.contents_with_elements,
                r.json_files,
                mib(r.json_bytes),
                mib(r.largest_json_bytes),
                t.elapsed().as_secs_f64()
            );
            if r.bundles > 0 {
                println!("{} bundles merge {} reps", r.bundles, r.bundled_reps);
            }
            if r.paged_reps_skipped > 0 {
                eprintln!(
                    "warning: {} view-dependence trees and Multi-Triangulations are not exported; those leaves end at their finest static rep",
                    r.paged_reps_skipped
                );
            }
            Ok(())
        }
        Cmd::Gen(GenCmd::Plant {
            seed,
            objects,
            triangles,
            output,
        }) => {
            let p = plant::PlantParams {
                seed,
                objects,
                triangles,
            };
            let t = std::time::Instant::now();
            let s = plant::write_plant(&p, &output)?;
            println!(
                "{}: {} objects, {} triangles ({} after instancing), {} meshes, {} in {:.1} s",
                output.display(),
                s.objects,
                s.unique_triangles,
                s.triangles,
                s.meshes,
                human_bytes(s.bytes),
                t.elapsed().as_secs_f64()
            );
            Ok(())
        }
        Cmd::Gen(GenCmd::Rock { seed, tris, output }) => {
            let (positions, normals, indices) = hlod_builder::scenegen::rock::rock(tris, seed);
            let (n, t) = (positions.len(), indices.len() / 3);
            let mesh = hlod_builder::mesh::Mesh {
                positions,
                normals,
                colors: vec![[176, 164, 150, 255]; n],
                indices,
            };
            let obj = hlod_builder::scenegen::glb::GlbObject {
                name: "rock".into(),
                mesh: 0,
                transform: glam::Mat4::IDENTITY,
            };
            let bytes = hlod_builder::scenegen::glb::write_glb(&output, &[], &[mesh], &[obj])
                .with_context(|| format!("cannot write {}", output.display()))?;
            println!(
                "{}: {t} triangles, {}",
                output.display(),
                human_bytes(bytes)
            );
            Ok(())
        }
        Cmd::Gen(GenCmd::Lattice {
            seed,
            units,
            output,
        }) => {
            let p = lattice::LatticeParams { seed, units };
            let s = lattice::write_lattice(&p, &output)?;
            println!(
                "{}: {} objects, {} triangles, {}",
                output.display(),
                s.objects,
                s.triangles,
                human_bytes(s.bytes)
            );
            Ok(())
        }
        Cmd::Mt {
            input,
            theta,
            cluster_tris,
            group_clusters,
            output,
        } => mt_cmd::mt_report(
            &input,
            theta,
            cluster_tris,
            group_clusters,
            output.as_deref(),
        ),
        Cmd::Vdt {
            input,
            metric,
            block,
            output,
        } => vdt_report(&input, &metric, block, output.as_deref()),
        Cmd::Gen(GenCmd::Tile {
            input,
            grid,
            instanced: _,
            baked,
            gap,
            output,
        }) => {
            let (n, m) = parse_grid(&grid)?;
            let s = tile::write_tiled(&input, n, m, baked, gap, &output)?;
            println!(
                "{}: {n}x{m} tiles, {} objects, {} triangles after instancing, {}",
                output.display(),
                s.objects,
                s.triangles,
                human_bytes(s.bytes)
            );
            Ok(())
        }
    }
}

fn parse_grid(s: &str) -> Result<(usize, usize)> {
    let (a, b) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("--grid {s:?}: expected NxM, e.g. 8x8"))?;
    let n: usize = a
        .trim()
        .parse()
        .with_context(|| format!("--grid {s:?}: bad N"))?;
    let m: usize = b
        .trim()
        .parse()
        .with_context(|| format!("--grid {s:?}: bad M"))?;
    if n == 0 || m == 0 || n * m > 1_000_000 {
        bail!("--grid {s:?}: N and M must be positive and N*M at most 1,000,000");
    }
    Ok((n, m))
}

fn info(file: &std::path::Path, verify: bool, tree: Option<usize>) -> Result<()> {
    // A local file, or a URL (http(s)://, s3://) read with ranged requests.
    let handle =
        engine_cli::SceneHandle::open(file).with_context(|| format!("{}", file.display()))?;
    let scene = engine::SceneFile::from_source(handle.raw()?)
        .with_context(|| format!("{}", file.display()))?;
    let stats = stats_of(&scene);
    let name = file
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    println!("{TABLE_HEADER}\n{}", table_row(&name, &stats));
    #[cfg(feature = "remote")]
    if let engine_cli::SceneHandle::Remote(r, _) = &handle {
        println!(
            "read from a server with ranged requests: {} bytes, {} (pinned: every read asks for this version)",
            engine::ByteSource::len(r),
            r.version()
        );
    }
    let s = scene.skeleton();
    let lods = s
        .reps
        .iter()
        .filter(|r| r.kind == engine::RepKind::Lod as u16)
        .count();
    let trees: Vec<u32> = (0..s.reps.len() as u32)
        .filter(|&r| s.reps[r as usize].is_vdt())
        .collect();
    let mts: Vec<u32> = (0..s.reps.len() as u32)
        .filter(|&r| s.reps[r as usize].is_mt())
        .collect();
    let root = s.root().expect("validated scenes have a root");
    println!(
        "format v{}, {} LODs + {} HLODs + {} view-dependence trees + {} Multi-Triangulations, bounds {:?} .. {:?}, root error {:.4}",
        scene.header().version,
        lods,
        s.reps.len() - lods - trees.len() - mts.len(),
        trees.len(),
        mts.len(),
        root.bbox_min,
        root.bbox_max,
        s.reps
            .get(root.first_rep as usize)
            .map_or(f32::NAN, |r| r.error)
    );
    println!("{}", input_line(&scene.meta()));
    println!(
        "{}",
        hlod_builder::walkmap::walk_line(&hlod_builder::summary::stats_of(&scene).walk)
    );
    let o = scene.meta().origin;
    println!(
        "origin {} {} {} (world position of the scene's coordinates; {} in the object section)",
        o[0],
        o[1],
        o[2],
        match scene.read_objects() {
            Ok(t) if t.is_empty() => "no objects described".to_string(),
            Ok(t) => format!("{} objects described", t.len()),
            Err(e) => format!("unreadable: {e}"),
        }
    );
    println!(
        "validate(): ok (structure, error monotonicity, boxes, byte ranges, checksums of header and skeleton)"
    );
    for &r in &trees {
        let rec = &s.reps[r as usize];
        let core = scene
            .read_rep_bytes(r)
            .with_context(|| format!("{}: rep {r}", file.display()))?;
        let Some(head) = core.get(..std::mem::size_of::<engine::vdt::file::VdtHeader>()) else {
            bail!(
                "{}: rep {r}: a view-dependence tree shorter than its header",
                file.display()
            );
        };
        let h: engine::vdt::file::VdtHeader = bytemuck::pod_read_unaligned(head);
        println!(
            "  tree rep {r} (node {}): {} vertices, {} triangles, error {:.5}; L = {}, {} meta-nodes ({} roots, largest {}), MNT {}, permanent {}, DATA {}, flat tree {}",
            rec.node,
            h.leaf_count,
            h.triangle_count,
            rec.error,
            h.levels,
            h.meta_count,
            h.root_count,
            human_bytes(u64::from(h.max_meta_bytes)),
            human_bytes(u64::from(h.meta_count) * 32),
            human_bytes(u64::from(h.permanent_count) * 16),
            human_bytes(h.data_len),
            human_bytes(rec.extent() - h.virt_offset),
        );
    }
    for &r in &mts {
        println!(
            "{}",
            mt_cmd::info_line(&scene, r).with_context(|| format!("{}: rep {r}", file.display()))?
        );
    }
    // A shared payload is stored and resident once.
    let mesh_reps = (s.reps.iter().enumerate())
        .filter(|&(r, rec)| !rec.is_paged() && s.owns_payload(r as u32))
        .map(|(_, rec)| rec);
    let stored: u64 = mesh_reps.clone().map(|r| u64::from(r.len)).sum();
    let resident: u64 = mesh_reps.clone().map(|r| r.resident_len()).sum();
    if !s.placements.is_empty() {
        let owners = (0..s.reps.len() as u32)
            .filter(|&r| s.placement(r).is_some_and(|p| p.source == r))
            .count();
        println!(
            "instancing: {} reps place {owners} shared payloads (stored once each)",
            s.placements.len()
        );
    }
    println!(
        "mesh reps: {} stored ({:.2} B per input triangle with the skeleton and the object section: {} file), {} resident when expanded ({:.2}x)",
        human_bytes(stored),
        scene.header().file_len as f64 / (scene.header().input_triangles.max(1)) as f64,
        human_bytes(scene.header().file_len),
        human_bytes(resident),
        resident as f64 / stored.max(1) as f64,
    );
    if let Some(depth) = tree {
        tree_cmd::print_tree(&scene, &name, depth).with_context(|| file.display().to_string())?;
    }
    if verify {
        let v = verify_data(&scene).with_context(|| format!("{}: rep data", file.display()))?;
        if v.compressed == 0 {
            println!(
                "data: all {} reps read back and match their checksums; no mesh rep is compressed",
                s.reps.len()
            );
            return Ok(());
        }
        println!(
            "data: all {} reps read back and match their checksums; {} of {} mesh payloads compressed, expanded at {:.0} MB/s ({} in {:.2} s on one core)",
            s.reps.len(),
            v.compressed,
            (0..s.reps.len() as u32)
                .filter(|&r| s.owns_payload(r) && !s.reps[r as usize].is_paged())
                .count(),
            v.expanded_bytes as f64 / v.expand_s.max(1e-9) / 1e6,
            human_bytes(v.expanded_bytes),
            v.expand_s,
        );
    }
    Ok(())
}

/// What [`verify_data`] found.
#[derive(Default)]
struct DataCheck {
    compressed: usize,
    expanded_bytes: u64,
    expand_s: f64,
}

/// Reads every rep back (checksums, decoding, every meta-node of a tree),
/// timing the expansion of the compressed ones.
fn verify_data<S: engine::ByteSource>(scene: &engine::SceneFile<S>) -> Result<DataCheck> {
    let s = scene.skeleton();
    let mut v = DataCheck::default();
    // A shared payload is checked once, as its owner's.
    for r in (0..s.reps.len() as u32).filter(|&r| s.owns_payload(r)) {
        let rec = &s.reps[r as usize];
        if rec.is_vdt() {
            scene.verify_tree(r)?;
            continue;
        }
        if rec.is_mt() {
            scene.verify_mt(r)?;
            continue;
        }
        let stored = scene.read_rep_bytes(r)?;
        let t = std::time::Instant::now();
        let raw = engine::format::expand_payload(&stored, r, rec)?;
        if engine::format::is_compressed(&stored) {
            v.expand_s += t.elapsed().as_secs_f64();
            v.expanded_bytes += raw.len() as u64;
            v.compressed += 1;
        }
        engine::format::RepMesh::decode(&raw, r, rec)?;
    }
    Ok(v)
}

/// Writes `bytes` to `out` under the output-file policy (never over `input`).
fn write_vdt(out: &std::path::Path, input: &std::path::Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let inputs = hlod_builder::import::model_files(input);
    let inputs: Vec<&std::path::Path> = inputs.iter().map(PathBuf::as_path).collect();
    engine_cli::outfile::write_with(out, &inputs, |w| w.write_all(bytes))
        .with_context(|| format!("cannot write {}", out.display()))
}

fn vdt_report(
    input: &std::path::Path,
    metric: &str,
    block: usize,
    output: Option<&std::path::Path>,
) -> Result<()> {
    use hlod_builder::vdt::meta;
    use hlod_builder::vdt::{Metric, VdtParams, build_tree};
    if !(64..=1 << 24).contains(&block) {
        anyhow::bail!("--block must be in 64..=16777216 bytes");
    }
    if let Some(out) = output {
        let inputs = hlod_builder::import::model_files(input);
        let inputs: Vec<&std::path::Path> = inputs.iter().map(PathBuf::as_path).collect();
        engine_cli::outfile::check_output(out, &inputs)?;
    }
    let levels = meta::levels_for_block(block);
    let metric = match metric {
        "quadric" => Metric::Quadric,
        "length" => Metric::EdgeLength,
        m => anyhow::bail!("--metric {m:?}: use quadric or length"),
    };
    let t = std::time::Instant::now();
    let imp = hlod_builder::import::load(input)?;
    let load_s = t.elapsed().as_secs_f64();
    let input_bytes = std::fs::metadata(input).map(|m| m.len()).unwrap_or(0);
    println!(
        "{}: {}, meta-nodes of L = {levels} levels for {block}-byte blocks",
        input.display(),
        human_bytes(input_bytes)
    );
    println!(
        "| mesh | input tris | input verts (welded) | nodes | roots | VDT s | MNT s | tree | meta-nodes | DATA | MNT |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let largest = imp
        .meshes
        .iter()
        .enumerate()
        .filter_map(|(i, m)| m.as_ref().map(|m| (m.indices.len(), i)))
        .max()
        .map(|x| x.1);
    for (i, m) in imp.meshes.iter().enumerate() {
        let Some(m) = m else { continue };
        let t = std::time::Instant::now();
        let tree = build_tree(
            &m.positions,
            &m.indices,
            &VdtParams {
                metric,
                max_switch: None,
            },
        );
        let secs = t.elapsed().as_secs_f64();
        tree.validate()
            .map_err(|e| anyhow::anyhow!("mesh {i}: invalid tree: {e}"))?;
        let t = std::time::Instant::now();
        let m = meta::block(&tree, levels);
        let files = meta::encode(&tree, &m);
        let mnt_secs = t.elapsed().as_secs_f64();
        m.validate(&tree)
            .map_err(|e| anyhow::anyhow!("mesh {i}: invalid meta-nodes: {e}"))?;
        // The binary tree as a flat file: the `.vdt` file's flat layout
        // (nodes, leaf positions, adjacency offsets and entries, roots).
        let tree_bytes = engine::vdt::file::flat_len(
            tree.leaf_count() as u64,
            tree.nodes.len() as u64,
            tree.adjacent.iter().map(Vec::len).sum::<usize>() as u64,
            tree.roots.len() as u64,
        );
        println!(
            "| {i} | {} | {} | {} | {} | {secs:.2} | {mnt_secs:.2} | {} | {} | {} | {} |",
            tree.triangles.len(),
            tree.leaf_count(),
            tree.nodes.len(),
            tree.roots.len(),
            human_bytes(tree_bytes),
            m.metas.len(),
            human_bytes(files.data.len() as u64),
            human_bytes((files.mnt.len() * std::mem::size_of::<meta::MntRecord>()) as u64)
        );
        if let (Some(out), true) = (output, Some(i) == largest) {
            write_vdt(
                out,
                input,
                &engine::vdt::file::encode_blocked(&tree, &m, &files),
            )?;
            println!("wrote {} (mesh {i})", out.display());
        }
    }
    if output.is_some() && largest.is_none() {
        anyhow::bail!("{}: no mesh to write", input.display());
    }
    println!("(import {load_s:.2} s)");
    Ok(())
}

/// What the source held and what the finest reps draw of it: input
/// triangles after instancing, degenerate ones and hidden objects' included,
/// and each part said.
fn input_line(m: &engine::SceneMeta) -> String {
    if m.drawn_triangles == 0 {
        return format!(
            "input: {} triangles after instancing (what the finest reps draw of them is not \
             recorded in files of earlier builds)",
            m.input_triangles
        );
    }
    let dropped = m
        .input_triangles
        .saturating_sub(m.drawn_triangles + m.hidden_triangles);
    format!(
        "input: {} triangles after instancing: {} drawn by the finest reps, {} degenerate dropped, \
         {} of hidden objects (IFC voids and spaces)",
        m.input_triangles, m.drawn_triangles, dropped, m.hidden_triangles
    )
}
