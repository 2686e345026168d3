//! `vdt-bench`: El-Sana & Chiang's Table 2 for one `.vdt` file. Replays a
//! camera path (approach and orbit by default) refining the tree once per
//! frame, in three stores: in core (the reference: Adapt, Tris), the
//! virtual-memory baseline (*Virt.*: 4 KiB pages, LRU, synchronous faults)
//! and the external-memory meta-node buffers (*Ext.*: place holders, I/O
//! thread, misses), both through the same disk model and footprint, at
//! each footprint. Time per frame is the navigating thread's work: the
//! refinement pass plus gathering the triangle list for the renderer; frames
//! are paced at `--fps` (the I/O thread reads meanwhile). Writes
//! `frames.csv`, `table2.md` and, with `--psnr-every`, PSNR of the refined
//! mesh against the full-resolution one (CPU rasteriser).

use engine_cli::{in_range, zero_or_in};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::Parser;
use engine::camera::{View, format_path, read_path};
use engine::disk::DiskModel;
use engine::vdt::ext::{ExtStore, Prefetch};
use engine::vdt::file::VdtFile;
use engine::vdt::raster::rasterise;
use engine::vdt::refine::{Criterion, NodeStore, Refiner};
use engine::vdt::virt::VirtStore;
use engine_cli::disk::open_scene_source;
use engine_cli::paths::{PathKind, generate_path};
use glam::Vec3;

#[derive(Parser, Debug)]
#[command(
    name = "vdt-bench",
    version,
    about = "View-dependence trees: Virt. vs Ext. on a camera path"
)]
struct Args {
    /// A `.vdt` file (`hlod-build vdt MODEL -o FILE`).
    file: PathBuf,
    /// Camera path file (default: a generated approach and orbit).
    #[arg(long)]
    path: Option<PathBuf>,
    #[arg(long, default_value_t = 600, value_parser = in_range(1usize, 1_000_000))]
    frames: usize,
    /// Footprints: bytes (KiB/MiB suffixes) or percentages of the whole
    /// meta-node tree (in-core part plus DATA), comma-separated.
    #[arg(long, default_value = "60%,80%,120%")]
    budgets: String,
    /// Error tolerance in pixels.
    #[arg(long, default_value_t = 1.0, value_parser = in_range(0.01f32, 10_000.0))]
    tolerance: f32,
    /// hdd, ssd, nvme or LATENCY_MS:MB_PER_S.
    #[arg(long, default_value = "hdd")]
    disk: String,
    #[arg(long, default_value_t = 30.0, value_parser = zero_or_in(1.0f32, 1000.0))]
    fps: f32,
    #[arg(long, default_value_t = 1280, value_parser = in_range(16u32, 8192))]
    width: u32,
    #[arg(long, default_value_t = 720, value_parser = in_range(16u32, 8192))]
    height: u32,
    /// Compare every N-th Ext. frame with the full-resolution mesh (0: off).
    #[arg(long, default_value_t = 60, value_parser = in_range(0usize, 1_000_000))]
    psnr_every: usize,
    /// Child meta-nodes kept prefetched: cut (those right below active
    /// nodes) or paper (all children of active meta-nodes).
    #[arg(long, default_value = "cut")]
    prefetch: String,
    /// Output folder.
    #[arg(long, default_value = "vdt-bench-out")]
    out: PathBuf,
}

#[derive(Clone, Copy, Default)]
struct Frame {
    ms: f64,
    adapt: u32,
    misses: u32,
    tris: usize,
    resident: u64,
    loaded: u64,
}

fn main() -> ExitCode {
    engine_cli::main_with(|| run(Args::parse()))
}

fn run(a: Args) -> Result<()> {
    if !(a.tolerance > 0.0 && a.fps >= 0.0 && a.width > 0 && a.height > 0 && a.frames > 0) {
        bail!("--tolerance, --frames and the viewport must be positive");
    }
    let disk = DiskModel::parse(&a.disk).map_err(anyhow::Error::msg)?;
    let policy = match a.prefetch.as_str() {
        "cut" => Prefetch::BelowCut,
        "paper" => Prefetch::AllChildren,
        p => bail!("--prefetch {p:?}: use cut or paper"),
    };
    let plain =
        open_scene_source(&a.file, None).with_context(|| format!("{}", a.file.display()))?;
    let file = Arc::new(VdtFile::open(plain).with_context(|| format!("{}", a.file.display()))?);
    let h = file.header;
    let tree_bytes = file.source.len() - h.virt_offset;
    let whole_ext = file.core_bytes() + h.data_len;
    let (lo, hi) = (Vec3::from(h.bounds_min), Vec3::from(h.bounds_max));
    let poses = match &a.path {
        Some(p) => read_path(p)?,
        None => generate_path(PathKind::ApproachOrbit, lo, hi, a.frames),
    };
    std::fs::create_dir_all(&a.out)?;
    engine_cli::outfile::write_bytes(&a.out.join("path.txt"), format_path(&poses).as_bytes())?;
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
    let budgets = a
        .budgets
        .split(',')
        .map(|b| engine_cli::parse_size("--budgets", b, whole_ext, 10_000.0))
        .collect::<Result<Vec<u64>>>()?;
    println!(
        "{}: {} leaves, {} nodes, {} meta-nodes (L = {}, largest {} B), DATA {:.2} MiB, tree {:.2} MiB; {} frames, ε {} px, disk {}",
        a.file.display(),
        h.leaf_count,
        h.node_count,
        h.meta_count,
        h.levels,
        h.max_meta_bytes,
        h.data_len as f64 / 1048576.0,
        tree_bytes as f64 / 1048576.0,
        views.len(),
        a.tolerance,
        a.disk
    );
    let period = if a.fps > 0.0 {
        engine::limits::duration_s(1.0 / f64::from(a.fps))
    } else {
        Duration::ZERO
    };
    let mut csv = String::from("store,budget,frame,ms,adapt,misses,tris,resident,loaded\n");
    // The in-core reference: the whole tree read up front, never waiting.
    let mut whole = file.load_tree()?;
    let full: Vec<[Vec3; 3]> = whole
        .triangles
        .iter()
        .map(|t| t.map(|l| Vec3::from(whole.positions[l as usize])))
        .collect();
    let reference = walk(
        &mut whole,
        &views,
        a.tolerance,
        Duration::ZERO,
        0,
        &mut Vec::new(),
    )?;
    log(&mut csv, "incore", 0, &reference);
    let adapt = mean(&reference, |f| f64::from(f.adapt));
    let tris = mean(&reference, |f| f.tris as f64);
    let mut table = String::from(
        "| footprint | fits | Virt. ms | Ext. ms | Virt./Ext. | Miss % | Miss % after warm-up | Ext. loads | Virt. faults | max resident |\n|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let mut psnr = String::from("budget,frame,psnr_db\n");
    for &b in &budgets {
        let src = open_scene_source(&a.file, Some(disk))?;
        let f = Arc::new(VdtFile::open(src)?);
        let mut virt = VirtStore::start(f.clone(), b)?;
        let v = walk(&mut virt, &views, a.tolerance, period, 0, &mut Vec::new())?;
        let faults = virt.pager.stats.faults;
        let mut ext = ExtStore::with_policy(f, b, policy)?;
        let mut samples = Vec::new();
        let e = walk(
            &mut ext,
            &views,
            a.tolerance,
            period,
            a.psnr_every,
            &mut samples,
        )?;
        for (k, r) in &samples {
            let full = rasterise(&views[*k], full.iter().copied());
            let got = rasterise(&views[*k], r.iter().copied());
            let d = got.diff(&full, 0).context("image sizes")?;
            let _ = writeln!(psnr, "{b},{k},{:.2}", d.psnr_db);
        }
        log(&mut csv, "virt", b, &v);
        log(&mut csv, "ext", b, &e);
        let (vm, em) = (mean(&v, |f| f.ms), mean(&e, |f| f.ms));
        let misses: u64 = e.iter().map(|f| u64::from(f.misses)).sum();
        let tried: u64 = e.iter().map(|f| u64::from(f.adapt + f.misses)).sum();
        // Warm-up: the first sixth of the path (the approach from afar).
        let warm = &e[e.len() / 6..];
        let warm_misses: u64 = warm.iter().map(|f| u64::from(f.misses)).sum();
        let warm_tried: u64 = warm.iter().map(|f| u64::from(f.adapt + f.misses)).sum();
        let max_res = v.iter().chain(&e).map(|f| f.resident).max().unwrap_or(0);
        if max_res > b {
            bail!("resident {max_res} B exceeded the footprint {b} B");
        }
        eprintln!("ext at {b} B: {:?}", ext.stats);
        let _ = writeln!(
            table,
            "| {:.2} MiB | {} | {vm:.2} | {em:.2} | {:.2} | {:.2} | {:.2} | {} | {faults} | {:.2} MiB |",
            b as f64 / 1048576.0,
            if b >= tree_bytes + file.core_bytes() {
                "yes"
            } else {
                "no"
            },
            vm / em.max(1e-9),
            100.0 * misses as f64 / tried.max(1) as f64,
            100.0 * warm_misses as f64 / warm_tried.max(1) as f64,
            ext.stats.loads,
            max_res as f64 / 1048576.0
        );
    }
    let head = format!(
        "Adapt {adapt:.0} / frame, Tris {tris:.0} / frame (in core), in-core frame {:.2} ms\n\n",
        mean(&reference, |f| f.ms)
    );
    print!("{head}{table}");
    engine_cli::outfile::write_bytes(
        &a.out.join("table2.md"),
        format!("{head}{table}").as_bytes(),
    )?;
    engine_cli::outfile::write_bytes(&a.out.join("frames.csv"), csv.as_bytes())?;
    if a.psnr_every > 0 {
        print!("PSNR (dB) of Ext. frames vs the full-resolution mesh:\n{psnr}");
        engine_cli::outfile::write_bytes(&a.out.join("psnr.csv"), psnr.as_bytes())?;
    }
    Ok(())
}

fn mean(f: &[Frame], g: impl Fn(&Frame) -> f64) -> f64 {
    f.iter().map(g).sum::<f64>() / f.len().max(1) as f64
}

fn log(csv: &mut String, store: &str, budget: u64, frames: &[Frame]) {
    for (k, f) in frames.iter().enumerate() {
        let _ = writeln!(
            csv,
            "{store},{budget},{k},{:.3},{},{},{},{},{}",
            f.ms, f.adapt, f.misses, f.tris, f.resident, f.loaded
        );
    }
}

/// What the bench reads from a store besides refining with it.
trait Benched: NodeStore {
    /// Takes in finished reads (the external-memory store).
    fn poll(&mut self) -> Result<()> {
        Ok(())
    }
    fn resident(&self) -> u64;
    /// Meta-nodes read so far.
    fn loads(&self) -> u64 {
        0
    }
}

impl Benched for engine::vdt::VdTree {
    fn resident(&self) -> u64 {
        0
    }
}

impl Benched for VirtStore {
    fn resident(&self) -> u64 {
        self.resident_bytes()
    }
}

impl Benched for ExtStore {
    fn poll(&mut self) -> Result<()> {
        Ok(ExtStore::poll(self)?)
    }
    fn resident(&self) -> u64 {
        self.resident_bytes()
    }
    fn loads(&self) -> u64 {
        self.stats.loads
    }
}

type Sample = (usize, Vec<[Vec3; 3]>);

/// One pass per frame; the frame's work is the poll, the pass and the
/// triangle list. Every `every`-th frame's triangles go to `samples`.
fn walk<S: Benched>(
    s: &mut S,
    views: &[View],
    tol: f32,
    period: Duration,
    every: usize,
    samples: &mut Vec<Sample>,
) -> Result<Vec<Frame>> {
    let mut r = Refiner::new(s)?;
    let mut out = Vec::with_capacity(views.len());
    for (k, v) in views.iter().enumerate() {
        let t0 = Instant::now();
        let before = s.loads();
        s.poll()?;
        let st = r.pass(s, &Criterion::new(*v, tol))?;
        let tris = r.triangles();
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        out.push(Frame {
            ms,
            adapt: st.adapt(),
            misses: st.misses,
            tris: tris.len(),
            resident: s.resident(),
            loaded: s.loads() - before,
        });
        if every > 0 && k % every == every - 1 {
            samples.push((k, tris.iter().map(|t| t.2).collect()));
        }
        if let Some(rest) = period.checked_sub(t0.elapsed()) {
            std::thread::sleep(rest);
        }
    }
    Ok(out)
}
