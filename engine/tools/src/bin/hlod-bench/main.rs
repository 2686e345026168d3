//! `hlod-bench`: replays a camera path through a built scene in each mode
//! (`incore`, `nopre`, `pre`) and reports per-frame metrics, a summary, PNG
//! plots (`plots`) and, with the wgpu renderer, the image quality of the
//! out-of-core frames against the in-core ones (PSNR on sampled frames).

mod bounds;
mod fidelity;
mod mt_table;
mod oracle;
mod plots;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use clap::Parser;
use engine::SceneFile;
use engine::camera::{PathKind, Pose, format_path, generate_path, read_path};
use engine::disk::{DiskModel, scene_source};
use engine::image::RgbaImage;
use engine::io::FileSource;
use engine::metrics::{CsvStream, Recorder, Summary, TracePoint, summary_table, vdt_table};
use engine::outfile::write_bytes;
use engine::render::{NoneRenderer, Renderer};
use engine::runtime::{Mode, PrefetchParams, RuntimeParams, Walkthrough, run_path_each};
use engine_cli::{in_range, parse_size, size_or_off, zero_or_in};
use engine_gpu::{Colouring, GpuContext, GpuRenderer, RendererConfig};
use glam::Vec3;

#[derive(Parser, Debug)]
#[command(
    name = "hlod-bench",
    version,
    about = "Walk a camera path through a scene in-core and out-of-core"
)]
struct Args {
    scene: PathBuf,
    /// Camera path file (default: the scene's generated fly-through).
    #[arg(long)]
    path: Option<PathBuf>,
    /// Generated path when no --path: flythrough, approach, orbit,
    /// approach-orbit, random (a hostile random walk with jumps, for soak
    /// runs; see --seed) or interior (a walk at eye height through a
    /// building's storeys and rooms, found from its geometry; see --seed).
    #[arg(long, default_value = "flythrough")]
    path_kind: String,
    /// Seed of the random path.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Frames of a generated path.
    #[arg(long, default_value_t = 600, value_parser = in_range(1usize, 1_000_000))]
    frames: usize,
    #[arg(long, default_value = "incore,nopre,pre")]
    modes: String,
    /// Memory footprint: bytes, with KiB/MiB/GiB, or a percentage of the rep data (e.g. 2.5%).
    #[arg(long, default_value = "2.5%")]
    budget: String,
    /// A sweep over several footprints (comma-separated, like --budget); replaces --budget.
    #[arg(long)]
    budgets: Option<String>,
    /// Error tolerance ε in pixels.
    #[arg(long, default_value_t = 2.0, value_parser = in_range(0.01f32, 10_000.0))]
    tolerance: f32,
    /// none (no rasterisation) or wgpu (a GPU, or lavapipe without one).
    #[arg(long, default_value = "none")]
    renderer: String,
    /// Debug colouring of the wgpu renderer: object, lod, kind or substituted.
    #[arg(long, default_value = "object")]
    colouring: String,
    /// With wgpu: read back every N-th frame and compare it with the in-core
    /// frame (PSNR); 0 = off.
    #[arg(long, default_value_t = 30, value_parser = in_range(0u32, 1_000_000))]
    psnr_every: u32,
    /// With wgpu: save the sampled frames as PNG under OUT/frames.
    #[arg(long)]
    save_frames: bool,
    /// Modelled speed of the none renderer in triangles per second (0: free).
    #[arg(long, default_value_t = 0.0, value_parser = zero_or_in(1e3, 1e13))]
    render_rate: f64,
    /// file (the real file, page cache dropped), hdd, ssd, nvme, or LATENCY_MS:MB_PER_S.
    #[arg(long, default_value = "file")]
    disk: String,
    /// Frame pacing (0: as fast as possible).
    #[arg(long, default_value_t = 30.0, value_parser = zero_or_in(1.0f32, 1000.0))]
    fps: f32,
    #[arg(long, default_value_t = 1280, value_parser = in_range(16u32, 8192))]
    width: u32,
    #[arg(long, default_value_t = 720, value_parser = in_range(16u32, 8192))]
    height: u32,
    /// Bins B of the prefetcher.
    #[arg(long, default_value_t = 16, value_parser = in_range(1usize, 4096))]
    bins: usize,
    /// δ in pixels (0: 4 ε).
    #[arg(long, default_value_t = 0.0, value_parser = in_range(0.0f32, 100_000.0))]
    delta: f32,
    /// Base widening of F_I, degrees.
    #[arg(long, default_value_t = 30.0, value_parser = in_range(0.0f32, 180.0))]
    margin: f32,
    /// Widest F_I, degrees (90 or more: all around the eye).
    #[arg(long, default_value_t = 60.0, value_parser = in_range(0.0f32, 180.0))]
    max_margin: f32,
    /// Levels of PAR/CHD prefetched.
    #[arg(long, default_value_t = 1, value_parser = in_range(0u8, 16))]
    prefetch_depth: u8,
    /// Sweep: reps of F_I's front up to this size (bytes, KiB, MiB) are also
    /// read in file order, alternating with the bins; 0 = off.
    #[arg(long, default_value = "0")]
    sweep: String,
    /// Largest share of the budget for prefetched reps not yet drawn.
    #[arg(long, default_value_t = 0.6, value_parser = in_range(0.01f32, 1.0))]
    speculative_share: f32,
    /// Lookahead: P_I also prefetches the fronts of the positions the
    /// camera's motion reaches in this many frames (and a third of it); 0 = off.
    #[arg(long, default_value_t = 10, value_parser = in_range(0u32, 10_000))]
    lookahead: u32,
    /// F_I goes all around the eye whenever the all-around front takes at
    /// most this share of the reps' room (the budget less the pages'
    /// share); 0 = never.
    #[arg(long, default_value_t = 1.0, value_parser = in_range(0.0f32, 1000.0))]
    all_around: f32,
    /// Print what any fetching policy could do on this path (from the
    /// fronts alone: the first-time reps, the oracle's working set, the disk
    /// time of reading the path's reps in file order, demand fetching with
    /// optimal eviction), write it to OUT/bounds.md, and run nothing.
    #[arg(long)]
    bounds: bool,
    /// Start-up: frames rendered at the path's first pose before the path
    /// begins (P_I loads the first front and prefetches around it, as an
    /// in-core viewer loads everything before its first frame); they are
    /// reported as the start-up, not as path frames.
    #[arg(long, default_value_t = 0, value_parser = in_range(0usize, 1_000_000))]
    warmup: usize,
    /// Output directory for CSVs, the summary, plots and the path used.
    #[arg(long, default_value = "out/bench")]
    out: PathBuf,
    /// Place-holder bytes reserved per resident view-dependence tree (bytes
    /// or a percentage of the scene data), out of the footprint.
    #[arg(long, default_value = "4MiB")]
    vdt_pool: String,
    /// What a Multi-Triangulation's store keeps after a frame: p-c (the
    /// paper's caching), p-cc, p-nc or np-nc.
    #[arg(long, default_value = "p-c")]
    mt_cache: String,
    /// Longest gap P_I reads through rather than seeking over (the
    /// break-even gap is learnt; this caps it); 0 turns coalescing off.
    #[arg(long, default_value = "1MiB")]
    coalesce_gap: String,
    /// Reads by pages of this size (e.g. 128KiB) where a seek costs at
    /// least a page's transfer (learnt; a fast disk never does); 0 (the
    /// default) turns pages off.
    #[arg(long, default_value = "0")]
    page: String,
    /// The share of the budget that pages may take from prefetching.
    #[arg(long, default_value_t = 0.25, value_parser = in_range(0.0f32, 0.9))]
    page_share: f32,
    /// Stall deadline in ms (0: off, the paper's protocol, P_R waits for
    /// every missing rep): Stage II reads only what it can finish this long
    /// after the fetch command; the rest is drawn as its nearest resident
    /// ancestor (counted as substituted and late) and read after the frame.
    #[arg(long, default_value_t = 0.0, value_parser = in_range(0.0f32, 60_000.0))]
    stall_deadline: f32,
    /// Occlusion culling (0: off): the share of the budget that P_R's
    /// occluder store takes (P_I's reps get the rest), e.g. 0.05.
    #[arg(long, default_value_t = 0.0, value_parser = in_range(0.0f32, 0.5))]
    occlusion: f32,
    /// The quality governor: raise ε for the whole frame when the front
    /// does not fit the footprint (or --max-tris), instead of substituting.
    #[arg(long)]
    governor: bool,
    /// The governor's triangle target for the front (0: none).
    #[arg(long, default_value_t = 0)]
    max_tris: u64,
    /// The governor's frame-time target in ms (0: none): the front's
    /// triangles are held to what the measured drawing rate fits in it.
    #[arg(long, default_value_t = 0.0, value_parser = in_range(0.0f32, 60_000.0))]
    max_frame_ms: f32,
    /// Smooth LOD switches (0: off): a rep that replaces another fades in
    /// over this many seconds while the other fades out, both resident.
    #[arg(long, default_value_t = 0.0, value_parser = in_range(0.0f32, 10.0))]
    fade: f32,
    /// Fidelity against full resolution (needs --renderer wgpu): walk the
    /// path in core with every object at its finest rep, then at each of
    /// these tolerances (comma-separated, px), and compare the sampled
    /// frames (PSNR, pixels differing beyond one pixel); runs nothing else.
    #[arg(long)]
    fidelity: Option<String>,
}

fn main() -> ExitCode {
    engine_cli::main_with(|| run(Args::parse()))
}

fn run(a: Args) -> Result<()> {
    let colouring = Colouring::parse(&a.colouring).map_err(anyhow::Error::msg)?;
    let gpu = match a.renderer.as_str() {
        "none" => None,
        "wgpu" => {
            let ctx = GpuContext::new()?;
            println!("GPU adapter: {}", ctx.describe());
            Some(ctx)
        }
        r => bail!("--renderer {r:?}: use none or wgpu"),
    };
    let mut modes: Vec<Mode> = a
        .modes
        .split(',')
        .map(|m| Mode::parse(m.trim()))
        .collect::<Result<_, _>>()
        .map_err(anyhow::Error::msg)?;
    if modes.is_empty() {
        bail!("--modes is empty");
    }
    // In-core first: its frames are the reference for image quality.
    modes.sort_by_key(|&m| m != Mode::Incore);
    modes.dedup();
    let disk = if a.disk == "file" {
        None
    } else {
        Some(DiskModel::parse(&a.disk).map_err(anyhow::Error::msg)?)
    };
    // The scene is opened once and held for the whole run: every mode
    // reads the same file even if its path is replaced meanwhile.
    let scene_name = a.scene.display().to_string();
    let file = engine::infile::open(&a.scene).with_context(|| scene_name.clone())?;
    let scene = SceneFile::from_source(FileSource::from_file(file.try_clone()?)?)
        .with_context(|| scene_name.clone())?;
    let skel = Arc::new(scene.skeleton().clone());
    let interior = if a.path.is_none() && a.path_kind == "interior" {
        // Openings' voids, spaces and doors are walked through.
        let (tris, passable) =
            engine::interior::obstacle_triangles(&scene).with_context(|| scene_name.clone())?;
        let p = engine::interior::InteriorParams {
            seed: a.seed,
            ..Default::default()
        };
        let path = engine::interior::interior_path(&tris, a.frames, &p)
            .with_context(|| format!("{scene_name}: interior path"))?;
        println!(
            "interior path: storeys at {:?}, walkable cells {:?}, {} climbs up stairs, {} jumps between storeys ({passable} openings, spaces and doors walked through)",
            path.storeys, path.cells, path.climbs, path.jumps
        );
        Some(path.poses)
    } else {
        None
    };
    drop(scene);
    // Percentages are of the scene in core (compressed reps expanded, and
    // room to load the largest): at 100% every rep can be resident.
    let data_bytes = skel.in_core_bytes();
    let vdt_pool = parse_size("--vdt-pool", &a.vdt_pool, data_bytes, 100.0)?;
    let coalesce_gap = size_or_off("--coalesce-gap", &a.coalesce_gap, data_bytes)?;
    let page_bytes = size_or_off("--page", &a.page, data_bytes)?;
    let sweep_bytes = u32::try_from(size_or_off("--sweep", &a.sweep, data_bytes)?)
        .context("--sweep: at most 4 GiB")?;
    let budgets: Vec<u64> = match &a.budgets {
        Some(list) => list
            .split(',')
            .map(|b| engine_cli::parse_budget(b, data_bytes))
            .collect::<Result<_>>()?,
        None => vec![engine_cli::parse_budget(&a.budget, data_bytes)?],
    };
    let mut seen = std::collections::BTreeSet::new();
    let budgets: Vec<u64> = budgets
        .into_iter()
        .filter(|b| {
            let new = seen.insert(*b);
            if !new {
                eprintln!("--budgets: {b} bytes given twice, run once");
            }
            new
        })
        .collect();
    let budget = budgets[0];
    let root = &skel.nodes[0];
    let (min, max) = (Vec3::from(root.bbox_min), Vec3::from(root.bbox_max));
    let poses: Vec<Pose> = match (&a.path, interior) {
        (Some(p), _) => read_path(p)?,
        (None, Some(walk)) => walk,
        (None, None) => {
            let kind = match a.path_kind.as_str() {
                "flythrough" => PathKind::Flythrough,
                "approach" => PathKind::Approach,
                "orbit" => PathKind::Orbit,
                "approach-orbit" => PathKind::ApproachOrbit,
                "random" => PathKind::Random { seed: a.seed },
                k => bail!(
                    "--path-kind {k:?}: use flythrough, approach, orbit, approach-orbit, random or interior"
                ),
            };
            generate_path(kind, min, max, a.frames)
        }
    };
    std::fs::create_dir_all(&a.out).with_context(|| a.out.display().to_string())?;
    write_bytes(&a.out.join("path.txt"), format_path(&poses).as_bytes())?;
    let diag = (max - min).length().max(1.0);
    let params = RuntimeParams {
        mode: Mode::Pre,
        budget_bytes: budget,
        tolerance_px: a.tolerance,
        width_px: a.width,
        height_px: a.height,
        near: (diag * 1e-5).max(0.01),
        far: diag * 10.0,
        prefetch: PrefetchParams {
            delta_px: a.delta,
            bins: a.bins,
            margin_deg: a.margin,
            max_margin_deg: a.max_margin,
            depth: a.prefetch_depth,
            speculative_share: a.speculative_share,
            sweep_bytes,
            lookahead_frames: a.lookahead,
            all_around_fit: a.all_around,
            ..PrefetchParams::default()
        },
        frame_period_s: if a.fps > 0.0 { 1.0 / a.fps } else { 0.0 },
        vdt_pool_bytes: vdt_pool,
        mt_cache: engine::mt::cache::CacheMode::parse(&a.mt_cache).with_context(|| {
            format!("--mt-cache {:?}: use p-c, p-cc, p-nc or np-nc", a.mt_cache)
        })?,
        coalesce_max_gap: coalesce_gap,
        page_bytes,
        page_share: a.page_share,
        stall_deadline_s: a.stall_deadline / 1e3,
        governor: (a.governor || a.max_tris > 0 || a.max_frame_ms > 0.0).then_some(
            engine::governor::GovernorParams {
                max_tris: a.max_tris,
                max_frame_ms: a.max_frame_ms,
                ..Default::default()
            },
        ),
        fade_s: a.fade,
        ..RuntimeParams::default()
    };
    println!(
        "scene {}: {} nodes, {} reps, {:.1} MiB of rep data; budget {:.2} MiB ({:.2}%); {} frames at {} fps; disk {}; tolerance {} px",
        a.scene.display(),
        skel.nodes.len(),
        skel.reps.len(),
        data_bytes as f64 / 1048576.0,
        budget as f64 / 1048576.0,
        100.0 * budget as f64 / data_bytes as f64,
        poses.len(),
        a.fps,
        a.disk,
        a.tolerance
    );
    if a.bounds {
        let io = bounds::Io {
            page_bytes,
            render_rate: a.render_rate,
        };
        let text = bounds::bounds(&skel, &poses, &params, &budgets, disk, a.fps, io);
        write_bytes(&a.out.join("bounds.md"), text.as_bytes())?;
        println!("{text}");
        return Ok(());
    }
    if let Some(list) = &a.fidelity {
        let Some(ctx) = &gpu else {
            bail!("--fidelity needs --renderer wgpu");
        };
        let tolerances: Vec<f32> = list
            .split(',')
            .map(|t| in_range(0.01f32, 10_000.0)(t.trim()).map_err(anyhow::Error::msg))
            .collect::<Result<_>>()
            .context("--fidelity")?;
        let source = || -> Result<Arc<dyn engine::io::ByteSource>> {
            scene_source(file.try_clone()?, None).with_context(|| scene_name.clone())
        };
        let setup = fidelity::Setup {
            skeleton: &skel,
            source: &source,
            poses: &poses,
            params,
            gpu: ctx,
            every: a.psnr_every,
            data_bytes,
            save: a.save_frames.then(|| a.out.join("frames")),
        };
        let table = fidelity::run(&setup, &tolerances, &a.out)?;
        println!(
            "\n{table}\nfidelity.csv and fidelity.md in {}",
            a.out.display()
        );
        return Ok(());
    }
    let period_ms = if a.fps > 0.0 {
        1000.0 / f64::from(a.fps)
    } else {
        f64::INFINITY
    };
    let mut rows: Vec<Summary> = Vec::new();
    let mut done: Vec<(Mode, u64, Vec<TracePoint>)> = Vec::new();
    let mut tags: std::collections::BTreeSet<String> = std::collections::BTreeSet::new();
    let mut reference: Vec<(u32, RgbaImage)> = Vec::new();
    let mut quality = String::from("mode,budget_bytes,frame,psnr_db,substituted\n");
    let mut quality_rows: Vec<String> = Vec::new();
    let mut startup =
        String::from("\n| run | start-up ms | start-up MiB read |\n|---|---:|---:|\n");
    let runs = budgets
        .iter()
        .enumerate()
        .flat_map(|(k, &b)| modes.iter().map(move |&m| (k, b, m)));
    for (k, budget, mode) in runs {
        if mode == Mode::Incore && k > 0 {
            continue; // independent of the footprint
        }
        // Every sweep point's files have a name of their own (two budgets
        // that round to the same MiB get their bytes in the name).
        let mut tag = if budgets.len() > 1 && mode != Mode::Incore {
            format!("{}-{:.2}MiB", mode.name(), budget as f64 / 1048576.0)
        } else {
            mode.name().to_string()
        };
        if tags.contains(&tag) {
            tag = format!("{}-{budget}B", mode.name());
        }
        tags.insert(tag.clone());
        let model = if mode == Mode::Incore { None } else { disk };
        let source = scene_source(file.try_clone()?, model).with_context(|| scene_name.clone())?;
        let params = RuntimeParams {
            mode,
            budget_bytes: budget,
            occlusion_bytes: (f64::from(a.occlusion) * budget as f64) as u64,
            ..params
        };
        let t0 = std::time::Instant::now();
        let mut walk = Walkthrough::start(skel.clone(), source, params)
            .with_context(|| format!("starting mode {}", mode.name()))?;
        let mut gpu_r = match &gpu {
            Some(ctx) => {
                let mut r = GpuRenderer::new(
                    ctx.clone(),
                    RendererConfig {
                        colouring,
                        ..RendererConfig::headless(
                            a.width,
                            a.height,
                            if mode == Mode::Incore {
                                data_bytes
                            } else {
                                budget
                            },
                        )
                    },
                )?;
                r.capture_every(a.psnr_every);
                Some(r)
            }
            None => None,
        };
        let mut none_r = NoneRenderer::new(a.render_rate);
        let renderer: &mut dyn Renderer = match &mut gpu_r {
            Some(r) => r,
            None => &mut none_r,
        };
        let over_budget = |f: &engine::metrics::FrameMetrics| {
            mode != Mode::Incore
                && (f.loader.max_resident_bytes + f.occluder_bytes > budget || f.gpu_bytes > budget)
        };
        // The first frame loads the first front; the others come a frame
        // period apart after it.
        let mut warm_read = 0u64;
        let mut over = 0usize;
        let mut warm_each = |f: engine::metrics::FrameMetrics| {
            warm_read += f.loader.stage2_bytes + f.loader.prefetch_bytes;
            over += usize::from(over_budget(&f));
            Ok::<(), std::io::Error>(())
        };
        run_path_each(
            &mut walk,
            &poses[..a.warmup.min(1)],
            renderer,
            a.fps,
            &mut warm_each,
        )?;
        let rest = vec![poses[0]; a.warmup.saturating_sub(1)];
        run_path_each(&mut walk, &rest, renderer, a.fps, &mut warm_each)?;
        let start_ms = t0.elapsed().as_secs_f64() * 1e3;
        let mut csv = CsvStream::create(&a.out.join(format!("{tag}.csv")))?;
        let mut rec = Recorder::default();
        let mut i = 0u32;
        run_path_each(&mut walk, &poses, renderer, a.fps, |mut f| {
            f.frame = i; // path frames, after the start-up
            i += 1;
            over += usize::from(over_budget(&f));
            rec.push(&f);
            csv.push(&f)
        })?;
        drop(walk);
        csv.finish()?;
        startup.push_str(&format!(
            "| {tag} | {start_ms:.0} | {:.2} |\n",
            warm_read as f64 / 1048576.0
        ));
        if over > 0 {
            bail!(
                "mode {}: the footprint exceeded the budget on {over} frames",
                mode.name()
            );
        }
        if let Some(r) = &mut gpu_r {
            let errors = r.context().take_errors();
            if !errors.is_empty() {
                bail!("GPU errors in mode {}: {}", mode.name(), errors.join("; "));
            }
            // Path frame indices (the start-up frames come first).
            let w = a.warmup as u32;
            let caps: Vec<(u32, RgbaImage)> = r
                .take_captures()
                .into_iter()
                .filter(|(i, _)| *i >= w)
                .map(|(i, img)| (i - w, img))
                .collect();
            if a.save_frames {
                let dir = a.out.join("frames");
                std::fs::create_dir_all(&dir)?;
                for (i, img) in &caps {
                    img.save_png(&dir.join(format!("{tag}-{i:05}.png")))?;
                }
            }
            if mode == Mode::Incore {
                reference = caps;
            } else if !reference.is_empty() {
                let q = compare(&caps, &reference, rec.trace());
                for (i, psnr, sub) in &q {
                    quality.push_str(&format!("{},{budget},{i},{psnr:.3},{sub}\n", mode.name()));
                }
                quality_rows.push(quality_row(&tag, &q));
            }
        }
        rows.push(rec.summary(period_ms));
        eprintln!("{tag}: done ({})", memory_note());
        done.push((mode, budget, rec.into_trace()));
    }
    let mut table = summary_table(&rows);
    if skel.reps.iter().any(|r| r.is_vdt()) {
        table.push_str(&format!("\nView-dependence trees:\n\n{}", vdt_table(&rows)));
    }
    if skel.reps.iter().any(|r| r.is_mt()) {
        table.push_str(&format!(
            "\nMulti-Triangulations:\n\n{}",
            mt_table::mt_table(&rows)
        ));
    }
    if a.stall_deadline > 0.0 {
        table.push_str(&format!(
            "\nStall deadline {} ms: Stage II MiB include the bytes read after it; late reps (of substituted): {}\n",
            a.stall_deadline,
            rows.iter()
                .map(|r| format!("{} {}", r.mode, r.late_reps))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    if a.warmup > 0 {
        table.push_str(&format!(
            "\nStart-up ({} frames at the first pose before the path; in-core: loading every rep):\n{startup}",
            a.warmup
        ));
    }
    println!("\n{table}");
    let mut report = table.clone();
    if !quality_rows.is_empty() {
        let q = format!(
            "\nImage quality against in-core (every {} frames):\n\n| run | sampled | identical | min PSNR dB | mean PSNR dB (differing frames) |\n|---|---:|---:|---:|---:|\n{}",
            a.psnr_every,
            quality_rows.concat()
        );
        println!("{q}");
        report.push_str(&q);
        write_bytes(&a.out.join("psnr.csv"), quality.as_bytes())?;
    }
    write_bytes(&a.out.join("summary.md"), report.as_bytes())?;
    write_plots(&a.out, &done, budget, period_ms)?;
    println!(
        "per-frame CSVs, summary.md, plots (*.png) and path.txt in {}",
        a.out.display()
    );
    Ok(())
}

/// (frame, PSNR against the in-core frame, substituted reps) per sample.
fn compare(
    caps: &[(u32, RgbaImage)],
    reference: &[(u32, RgbaImage)],
    frames: &[TracePoint],
) -> Vec<(u32, f64, u32)> {
    caps.iter()
        .filter_map(|(i, img)| {
            let (_, r) = reference.iter().find(|(j, _)| j == i)?;
            let d = img.diff(r, 0)?;
            Some((*i, d.psnr_db, frames.get(*i as usize)?.substituted))
        })
        .collect()
}

/// This process's resident memory now and at its peak (Linux), for the
/// log of long runs.
fn memory_note() -> String {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(name))
            .map(|v| v.trim().to_string())
    };
    match (field("VmRSS:"), field("VmHWM:")) {
        (Some(rss), Some(peak)) => format!("RSS {rss}, peak {peak}"),
        _ => "RSS unknown".into(),
    }
}

fn quality_row(tag: &str, q: &[(u32, f64, u32)]) -> String {
    let identical = q.iter().filter(|x| x.1.is_infinite()).count();
    let finite: Vec<f64> = q.iter().map(|x| x.1).filter(|v| v.is_finite()).collect();
    let min = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let mean = finite.iter().sum::<f64>() / finite.len().max(1) as f64;
    let show = |v: f64, ok: bool| if ok { format!("{v:.1}") } else { "∞".into() };
    format!(
        "| {tag} | {} | {identical} | {} | {} |\n",
        q.len(),
        show(min, !finite.is_empty()),
        show(mean, !finite.is_empty())
    )
}

fn write_plots(
    out: &Path,
    done: &[(Mode, u64, Vec<TracePoint>)],
    budget: u64,
    period_ms: f64,
) -> Result<()> {
    let label = |m: Mode, b: u64| {
        if m == Mode::Incore {
            m.name().to_string()
        } else {
            format!("{} {:.1} MiB", m.name(), b as f64 / 1048576.0)
        }
    };
    let first: Vec<plots::Run<'_>> = done
        .iter()
        .filter(|(m, b, _)| *m == Mode::Incore || *b == budget)
        .map(|(m, b, f)| plots::Run {
            label: label(*m, *b),
            frames: f,
        })
        .collect();
    plots::frame_times(&out.join("frame_time.png"), &first, period_ms)?;
    let ooc: Vec<plots::Run<'_>> = done
        .iter()
        .filter(|(m, b, _)| *m != Mode::Incore && *b == budget)
        .map(|(m, b, f)| plots::Run {
            label: label(*m, *b),
            frames: f,
        })
        .collect();
    if !ooc.is_empty() {
        plots::fetch_vs_front(&out.join("stage2_vs_front.png"), &ooc)?;
        plots::resident(&out.join("resident.png"), &ooc, budget)?;
    }
    let points: Vec<plots::SweepPoint> = done
        .iter()
        .filter(|(m, _, _)| *m != Mode::Incore)
        .map(|(m, b, f)| plots::SweepPoint {
            mode: m.name(),
            budget_mib: *b as f64 / 1048576.0,
            stage2_mib: f.iter().map(|x| x.stage2_bytes).sum::<u64>() as f64 / 1048576.0,
            p99_ms: engine::metrics::quantile(
                &f.iter().map(|x| x.frame_ms).collect::<Vec<_>>(),
                0.99,
            ),
        })
        .collect();
    let sweep_budgets: std::collections::BTreeSet<u64> = done
        .iter()
        .filter(|d| d.0 != Mode::Incore)
        .map(|d| d.1)
        .collect();
    if sweep_budgets.len() > 1 {
        let mut pts = points;
        pts.sort_by(|x, y| {
            x.mode
                .cmp(y.mode)
                .then(x.budget_mib.total_cmp(&y.budget_mib))
        });
        plots::sweep(&out.join("sweep.png"), &pts)?;
    }
    Ok(())
}
