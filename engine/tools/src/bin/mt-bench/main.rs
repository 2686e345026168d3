//! `mt-bench`: Holst & Schumann's Figs 4–5 for MT files. Replays a
//! far-to-near path and a rotating path (and any other given) cutting the
//! MT once per frame by the screen-space error, in the paper's four modes
//! (NP,NC / P,NC / P,CC / P,C) through the same disk model and footprint,
//! and records per frame the cumulative read operations and bytes, the
//! memory held (the frame's peak: in-core part plus node records), the
//! cut's size and the misses. Writes `frames.csv`, `summary.md` and, per
//! model and path, `io-MODEL-PATH.png` and `memory-MODEL-PATH.png`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Parser;
use engine::camera::{Pose, View, format_path, read_path};
use engine::disk::DiskModel;
use engine::mt::cache::CacheMode;
use engine::mt::cut::{MtCriterion, MtCut};
use engine::mt::file::MtFile;
use engine::mt::store::{MtStore, node_bytes};
use engine_cli::disk::open_scene_source;
use engine_cli::in_range;
use glam::Vec3;

#[allow(dead_code)]
#[path = "../hlod-bench/plots.rs"]
mod plots;

#[derive(Parser, Debug)]
#[command(
    name = "mt-bench",
    version,
    about = "Multi-Triangulations: I/O and memory of the four caching modes on camera paths"
)]
struct Args {
    /// MT files (`hlod-build mt MODEL -o FILE`).
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// Paths: far-near, rotate, approach-orbit, or files of poses.
    #[arg(long, default_value = "far-near,rotate")]
    paths: String,
    /// Modes: np-nc, p-nc, p-cc, p-c (default: all four).
    #[arg(long, default_value = "np-nc,p-nc,p-cc,p-c")]
    modes: String,
    #[arg(long, default_value_t = 600, value_parser = in_range(2usize, 1_000_000))]
    frames: usize,
    /// Error tolerance in pixels.
    #[arg(long, default_value_t = 1.0, value_parser = in_range(0.01f32, 10_000.0))]
    tolerance: f32,
    /// Footprint: bytes (KiB/MiB suffixes) or a percentage of the file
    /// (a node in core takes up to twice its record).
    #[arg(long, default_value = "400%")]
    budget: String,
    /// none, hdd, ssd, nvme or LATENCY_MS:MB_PER_S.
    #[arg(long, default_value = "none")]
    disk: String,
    #[arg(long, default_value_t = 1280, value_parser = in_range(16u32, 8192))]
    width: u32,
    #[arg(long, default_value_t = 720, value_parser = in_range(16u32, 8192))]
    height: u32,
    /// Output folder.
    #[arg(long, default_value = "mt-bench-out")]
    out: PathBuf,
}

#[derive(Clone, Copy, Default)]
struct Frame {
    reads: u64,
    bytes_read: u64,
    peak: u64,
    resident_end: u64,
    nodes: usize,
    arcs: usize,
    tris: u64,
    misses: u32,
    steps: u32,
    ms: f64,
    /// Bytes of every refined node: what a traversal from the root each
    /// frame would hold.
    refined_bytes: u64,
}

fn main() -> ExitCode {
    engine_cli::main_with(|| run(Args::parse()))
}

fn run(a: Args) -> Result<()> {
    let disk = match a.disk.as_str() {
        "none" => None,
        d => Some(DiskModel::parse(d).map_err(anyhow::Error::msg)?),
    };
    let modes = a
        .modes
        .split(',')
        .map(|m| CacheMode::parse(m.trim()).with_context(|| format!("--modes: unknown mode {m:?}")))
        .collect::<Result<Vec<_>>>()?;
    // Every file opens and fits the footprint before anything is written.
    for file in &a.files {
        let f = MtFile::open(
            open_scene_source(file, None).with_context(|| format!("{}", file.display()))?,
        )
        .with_context(|| format!("{}", file.display()))?;
        let budget = engine_cli::parse_size("--budget", &a.budget, f.source.len(), 10_000.0)?;
        MtStore::new(Arc::new(f), CacheMode::PC, budget)
            .with_context(|| format!("{}", file.display()))?;
    }
    std::fs::create_dir_all(&a.out)?;
    let mut csv = String::from(
        "model,path,mode,frame,reads_total,bytes_read_total,peak_bytes,resident_bytes,nodes,cut_arcs,cut_tris,misses,steps,ms,refined_bytes\n",
    );
    let mut summary = String::from(
        "| model | path | mode | reads | MiB read | mean memory KiB | max memory KiB | mean cut tris | misses | mean ms | mean refined-node KiB |\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for file in &a.files {
        let name = file
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "mt".into());
        let f = MtFile::open(open_scene_source(file, None)?)?;
        let h = f.header;
        let budget = engine_cli::parse_size("--budget", &a.budget, f.source.len(), 10_000.0)?;
        println!(
            "{}: {} input tris, {} nodes, {} arcs, {} layers, {} partitions (θ = {}), {:.2} MiB, footprint {:.2} MiB",
            file.display(),
            h.input_triangles,
            h.node_count,
            h.arc_count,
            h.layers,
            h.partition_count,
            h.theta,
            f.source.len() as f64 / 1048576.0,
            budget as f64 / 1048576.0
        );
        let (lo, hi) = (Vec3::from(h.bounds_min), Vec3::from(h.bounds_max));
        for p in a.paths.split(',').map(str::trim) {
            let poses = poses(p, lo, hi, a.frames)?;
            let pname = Path::new(p)
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| p.into());
            engine_cli::outfile::write_bytes(
                &a.out.join(format!("path-{pname}.txt")),
                format_path(&poses).as_bytes(),
            )?;
            let diag = (hi - lo).length().max(1e-6);
            let views: Vec<View> = poses
                .iter()
                .map(|&pose| View {
                    pose,
                    width_px: a.width,
                    height_px: a.height,
                    near: diag * 1e-4,
                    far: diag * 100.0,
                    section: engine::section::Section::NONE,
                })
                .collect();
            let mut io_series = Vec::new();
            let mut mem_series = Vec::new();
            for &m in &modes {
                let src = open_scene_source(file, disk)?;
                let file = Arc::new(MtFile::open(src)?);
                let frames = walk(file, m, budget, &views, a.tolerance)?;
                if let Some(over) = frames.iter().find(|f| f.peak > budget) {
                    bail!(
                        "{name} {pname} {}: {} B held, over the footprint {budget} B",
                        m.label(),
                        over.peak
                    );
                }
                for (k, fr) in frames.iter().enumerate() {
                    let _ = writeln!(
                        csv,
                        "{name},{pname},{},{k},{},{},{},{},{},{},{},{},{},{:.3},{}",
                        m.name(),
                        fr.reads,
                        fr.bytes_read,
                        fr.peak,
                        fr.resident_end,
                        fr.nodes,
                        fr.arcs,
                        fr.tris,
                        fr.misses,
                        fr.steps,
                        fr.ms,
                        fr.refined_bytes
                    );
                }
                let last = frames.last().copied().unwrap_or_default();
                let n = frames.len().max(1) as f64;
                let mean = |g: &dyn Fn(&Frame) -> f64| frames.iter().map(g).sum::<f64>() / n;
                let _ = writeln!(
                    summary,
                    "| {name} | {pname} | {} | {} | {:.2} | {:.0} | {:.0} | {:.0} | {} | {:.3} | {:.0} |",
                    m.label(),
                    last.reads,
                    last.bytes_read as f64 / 1048576.0,
                    mean(&|f| f.peak as f64) / 1024.0,
                    frames.iter().map(|f| f.peak).max().unwrap_or(0) as f64 / 1024.0,
                    mean(&|f| f.tris as f64),
                    frames.iter().map(|f| u64::from(f.misses)).sum::<u64>(),
                    mean(&|f| f.ms),
                    mean(&|f| f.refined_bytes as f64) / 1024.0,
                );
                io_series.push((
                    m.label().to_string(),
                    frames.iter().map(|f| f.reads as f64).collect(),
                ));
                mem_series.push((
                    m.label().to_string(),
                    frames.iter().map(|f| f.peak as f64 / 1024.0).collect(),
                ));
            }
            plots::per_frame(
                &a.out.join(format!("io-{name}-{pname}.png")),
                &format!("{name}, {pname}: read operations since the start"),
                "reads",
                &io_series,
                None,
            )?;
            plots::per_frame(
                &a.out.join(format!("memory-{name}-{pname}.png")),
                &format!("{name}, {pname}: memory held (peak of each frame)"),
                "KiB",
                &mem_series,
                None,
            )?;
        }
    }
    print!("{summary}");
    engine_cli::outfile::write_bytes(&a.out.join("summary.md"), summary.as_bytes())?;
    engine_cli::outfile::write_bytes(&a.out.join("frames.csv"), csv.as_bytes())?;
    Ok(())
}

/// The paths: `far-near` moves from 8 to 1.2 bounding radii towards the
/// centre along one direction; `rotate` keeps 1.5 radii and turns once
/// around the vertical axis (the object rotating in view space);
/// `approach-orbit` is the view-dependence-tree benchmark's path.
fn poses(p: &str, lo: Vec3, hi: Vec3, frames: usize) -> Result<Vec<Pose>> {
    let c = (lo + hi) * 0.5;
    let r = ((hi - lo).length() * 0.5).max(1e-6);
    let n = frames.max(2);
    Ok(match p {
        "far-near" => (0..n)
            .map(|i| {
                let t = i as f32 / (n - 1) as f32;
                let d = 8.0 + (1.2 - 8.0) * t;
                let dir = Vec3::new(0.3, 0.2, 1.0).normalize();
                Pose::look_at(c + dir * r * d, c, 60.0)
            })
            .collect(),
        "rotate" => (0..n)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / n as f32;
                let dir = Vec3::new(a.sin(), 0.15, a.cos()).normalize();
                Pose::look_at(c + dir * r * 1.5, c, 60.0)
            })
            .collect(),
        "approach-orbit" => {
            engine_cli::paths::generate_path(engine_cli::paths::PathKind::ApproachOrbit, lo, hi, n)
        }
        file => read_path(Path::new(file)).with_context(|| format!("--paths {file:?}"))?,
    })
}

fn walk(
    file: Arc<MtFile>,
    mode: CacheMode,
    budget: u64,
    views: &[View],
    tol: f32,
) -> Result<Vec<Frame>> {
    let mut store = MtStore::new(file, mode, budget)?;
    let mut cut = MtCut::start(&mut store)?;
    let mut out = Vec::with_capacity(views.len());
    for (k, v) in views.iter().enumerate() {
        let t0 = Instant::now();
        let st = cut.adapt(&MtCriterion::new(*v, tol), &mut store);
        cut.end_frame(k as i64, &mut store);
        let peak = store.take_peak();
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        out.push(Frame {
            reads: store.stats.reads,
            bytes_read: store.stats.bytes_read,
            peak,
            resident_end: store.resident_bytes(),
            nodes: store.resident_nodes(),
            arcs: cut.arc_count(),
            tris: cut.triangle_count(),
            misses: st.misses,
            steps: st.refined + st.coarsened,
            ms,
            refined_bytes: cut
                .refined()
                .iter()
                .enumerate()
                .filter(|(_, r)| **r)
                .map(|(n, _)| node_bytes(store.file.dir[n].len))
                .sum(),
        });
    }
    Ok(out)
}
