//! `hlod-bench`: replays a camera path through a built scene in each mode
//! (`incore`, `nopre`, `pre`) and reports per-frame metrics, a summary, PNG
//! plots (`plots`) and, with the wgpu renderer, the image quality of the
//! out-of-core frames against the in-core ones (PSNR on sampled frames).

mod anatomy;
mod args;
mod bounds;
mod fidelity;
mod mt_table;
mod oracle;
mod plots;
mod raster;
mod short;
mod walking;

use engine_cli::png::PngFile as _;
use std::path::Path;
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use args::Args;
use clap::Parser;
use engine::SceneFile;
use engine::camera::{Pose, format_path, read_path};
use engine::disk::DiskModel;
use engine::image::RgbaImage;
use engine::metrics::{Recorder, Summary, TracePoint};
use engine::render::{NoneRenderer, Renderer};
use engine::runtime::{Mode, PrefetchParams, RuntimeParams, Walkthrough, run_path_each};
use engine_cli::SceneHandle;
use engine_cli::outfile::write_bytes;
use engine_cli::paths::{PathKind, generate_path};
use engine_cli::report::{CsvStream, summary_table, vdt_table};
use engine_cli::{in_range, parse_size, size_or_off};
use engine_gpu::{Colouring, GpuContext, GpuRenderer, RendererConfig};
use glam::Vec3;

/// A comma-separated list of tolerances in pixels.
fn tolerance_list(list: &str) -> Result<Vec<f32>> {
    list.split(',')
        .map(|t| in_range(0.01f32, 10_000.0)(t.trim()).map_err(anyhow::Error::msg))
        .collect()
}

fn main() -> ExitCode {
    engine_cli::main_with(|| run(Args::parse()))
}

fn run(a: Args) -> Result<()> {
    let colouring = Colouring::parse(&a.colouring).map_err(anyhow::Error::msg)?;
    let anatomy_tolerances = a
        .anatomy
        .as_deref()
        .map(tolerance_list)
        .transpose()
        .context("--anatomy")?;
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
    let cache = match &a.disk_cache {
        Some(dir) => Some(engine_cli::scene_handle::DiskCacheSpec {
            dir: dir.clone(),
            max_bytes: engine_cli::parse_disk_size("--disk-cache-size", &a.disk_cache_size)?,
        }),
        None => None,
    };
    let requests = engine_cli::scene_handle::Requests {
        max: a.requests,
        ahead_bytes: engine_cli::parse_disk_size("--read-ahead", &a.read_ahead)?,
    };
    let handle = SceneHandle::open_with(&a.scene, cache.as_ref(), requests)
        .with_context(|| scene_name.clone())?;
    let scene = SceneFile::from_source(handle.raw()?).with_context(|| scene_name.clone())?;
    let skel = Arc::new(scene.skeleton().clone());
    let hiding = if a.hide.is_empty() && a.xray.is_empty() {
        None
    } else {
        let table = scene.read_objects().with_context(|| scene_name.clone())?;
        let has = |k: u32, texts: &[String]| {
            (table.info(k)).is_some_and(|t| texts.iter().any(|x| t.contains(x.as_str())))
        };
        let h = engine::hide::Hiding::with_looks(&skel, &table, |k| {
            if has(k, &a.hide) {
                engine::tree::Look::Hidden
            } else if has(k, &a.xray) {
                engine::tree::Look::XRay
            } else {
                engine::tree::Look::Shown
            }
        });
        println!(
            "--hide/--xray: {} of {} elements hidden, {} x-rayed",
            h.hidden_objects(),
            table.len(),
            h.xray_objects()
        );
        Some(h)
    };
    // `interior` is walked on the walk section where the scene has one
    // (never through geometry, every storey it reports reached); `rooms`,
    // and `interior` on a scene built without one, find storeys and rooms
    // from the geometry.
    let has_walk = || {
        (scene.read_walk_index())
            .map(|w| w.is_some())
            .with_context(|| scene_name.clone())
    };
    let kind = match a.path_kind.as_str() {
        "interior" if a.path.is_none() && !has_walk()? => {
            println!(
                "{scene_name}: no walk section (built before format version 5): the interior \
                 path is found from the geometry (--path-kind rooms); rebuild the scene to walk it"
            );
            "rooms"
        }
        "interior" => "walk",
        k => k,
    };
    let interior = if a.path.is_none() && kind == "rooms" {
        // Openings' voids, spaces and doors are walked through.
        let (tris, passable) =
            engine::interior::obstacle_triangles(&scene).with_context(|| scene_name.clone())?;
        let p = engine::interior::InteriorParams {
            seed: a.seed,
            ..Default::default()
        };
        let path = engine::interior::interior_path(&tris, a.frames, &p)
            .with_context(|| format!("{scene_name}: rooms path"))?;
        println!(
            "rooms path: storeys at {:?}, walkable cells {:?}, {} climbs up stairs, {} jumps between storeys ({passable} openings, spaces and doors walked through)",
            path.storeys, path.cells, path.climbs, path.jumps
        );
        Some(path.poses)
    } else if a.path.is_none() && kind == "walk" {
        Some(walking::tour_path(
            handle.raw()?,
            &scene_name,
            &skel.nodes[0],
            a.frames,
            a.seed,
        )?)
    } else {
        None
    };
    // Only the anatomy reads reps through it; otherwise the runs open
    // their own sources and the skeleton is held once.
    let scene = anatomy_tolerances.is_some().then_some(scene);
    // Percentages are of the scene in core (compressed reps expanded, and
    // room to load the largest): at 100% every rep can be resident.
    let data_bytes = skel.in_core_bytes();
    let vdt_pool = parse_size("--vdt-pool", &a.vdt_pool, data_bytes, 100.0)?;
    let coalesce_gap = size_or_off("--coalesce-gap", &a.coalesce_gap, data_bytes)?;
    let page_bytes = match a.page.trim() {
        // Over a network every request pays the round trip: pages of
        // neighbouring reps in one request (P_I turns them on when the
        // learnt request cost is worth a page's transfer).
        "auto" if handle.is_remote() => engine::runtime::REMOTE_PAGE_BYTES,
        "auto" => 0,
        p => size_or_off("--page", p, data_bytes)?,
    };
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
                    "--path-kind {k:?}: use flythrough, approach, orbit, approach-orbit, random, interior, walk or rooms"
                ),
            };
            generate_path(kind, min, max, a.frames)
        }
    };
    let poses = if a.walk {
        walking::walked(handle.raw()?, &scene_name, &poses, f64::from(a.fps))?
    } else {
        poses
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
        section: a.cut.section()?,
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
    if let Some(tolerances) = anatomy_tolerances {
        let scene = scene.as_ref().expect("kept for the anatomy");
        let setup = anatomy::Setup {
            skeleton: &skel,
            scene,
            poses: &poses,
            params,
            every: a.anatomy_every,
            data_bytes,
        };
        let (table, csv) = anatomy::run(&setup, &tolerances).with_context(|| scene_name.clone())?;
        write_bytes(&a.out.join("anatomy.md"), table.as_bytes())?;
        write_bytes(&a.out.join("anatomy.csv"), csv.as_bytes())?;
        println!("{table}");
        return Ok(());
    }
    if let Some(list) = &a.fidelity {
        let Some(ctx) = &gpu else {
            bail!("--fidelity needs --renderer wgpu");
        };
        let tolerances = tolerance_list(list).context("--fidelity")?;
        let source = || -> Result<Arc<dyn engine::io::ByteSource>> {
            handle.source(None).with_context(|| scene_name.clone())
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
    let mut warnings = String::new();
    let mut network = String::from(
        "\n| run | requests | MiB fetched | KiB per request | failed reads | MiB from the disk cache | reads served ahead | MiB ahead dropped unread | most in flight |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
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
        let source = handle.source(model).with_context(|| scene_name.clone())?;
        let params = RuntimeParams {
            mode,
            budget_bytes: budget,
            occlusion_bytes: (f64::from(a.occlusion) * budget as f64) as u64,
            ..params
        };
        let net0 = handle.network();
        let t0 = std::time::Instant::now();
        let mut walk = Walkthrough::start(skel.clone(), source, params)
            .with_context(|| format!("starting mode {}", mode.name()))?;
        if let Some(h) = &hiding {
            walk.set_hiding(h);
        }
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
                if let Some(h) = &hiding {
                    engine::render::Renderer::set_parts(&mut r, h.parts());
                }
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
        let net = handle.network() - net0;
        network.push_str(&format!(
            "| {tag} | {} | {:.2} | {:.1} | {} | {:.2} | {} | {:.2} | {} |\n",
            net.requests,
            net.bytes as f64 / 1048576.0,
            net.bytes as f64 / 1024.0 / net.requests.max(1) as f64,
            net.failures,
            net.cache_hit_bytes as f64 / 1048576.0,
            net.ahead_hits,
            net.ahead_dropped_bytes as f64 / 1048576.0,
            net.peak_in_flight
        ));
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
        let summary = rec.summary(period_ms);
        if mode != Mode::Incore
            && let Some(w) = short::warning(
                &tag,
                budget,
                a.tolerance,
                rec.trace(),
                summary.totals.tolerance_px,
            )
        {
            eprintln!("warning: {w}");
            warnings.push_str(&format!("\n**Warning:** {w}\n"));
        }
        rows.push(summary);
        eprintln!("{tag}: done ({})", memory_note());
        done.push((mode, budget, rec.into_trace()));
    }
    let mut table = summary_table(&rows);
    table.push_str(&warnings);
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
    if handle.is_remote() {
        table.push_str(&format!(
            "\nOver the network ({}; each run's requests, start-up included):\n{network}",
            a.scene.display()
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
