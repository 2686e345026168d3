//! `hlod-bench --fidelity 1,2,3`: the image of the front at each tolerance
//! against full resolution (issue 21, item 5).
//!
//! The reference is the in-core walk with every object at its finest rep
//! (a tolerance below any rep's projected error, so the front descends to
//! every visible leaf's last rep, and view-dependence trees refine fully).
//! Each tolerance is then walked in core on the same path, and every
//! sampled frame is compared with the reference's: PSNR over RGB, and the
//! share of pixels that differ beyond a one-pixel tolerance
//! ([`RgbaImage::differing_beyond_one_pixel`], colour tolerance
//! [`COLOUR_TOLERANCE`]). In core, so that only the level of detail differs
//! (no substitutes, no budget).

use engine_cli::png::PngFile as _;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use engine::camera::Pose;
use engine::image::RgbaImage;
use engine::io::ByteSource;
use engine::metrics::quantile;
use engine::runtime::{Mode, RuntimeParams, Walkthrough, run_path_each};
use engine::skeleton::Skeleton;
use engine_cli::outfile::write_bytes;
use engine_gpu::{Colouring, GpuContext, GpuRenderer, RendererConfig};

/// Largest channel difference (of 255) still counted as the same colour:
/// shading of a simplified surface moves a little with its normals.
pub const COLOUR_TOLERANCE: u8 = 16;

/// The reference's tolerance: below any rep's projected error.
const FINEST_PX: f32 = 1e-20;

/// One walk's sampled frames and median front triangles.
struct Walk {
    frames: Vec<(u32, RgbaImage)>,
    front_tris: f64,
}

/// What the fidelity run needs from `hlod-bench`.
pub struct Setup<'a> {
    pub skeleton: &'a Arc<Skeleton>,
    pub source: &'a dyn Fn() -> Result<Arc<dyn ByteSource>>,
    pub poses: &'a [Pose],
    pub params: RuntimeParams,
    pub gpu: &'a GpuContext,
    pub every: u32,
    pub data_bytes: u64,
    /// Save the sampled frames (and their differences) as PNG here.
    pub save: Option<std::path::PathBuf>,
}

fn walk(s: &Setup<'_>, tolerance_px: f32) -> Result<Walk> {
    let params = RuntimeParams {
        mode: Mode::Incore,
        tolerance_px,
        governor: None,
        occlusion_bytes: 0,
        fade_s: 0.0,
        ..s.params
    };
    let mut w = Walkthrough::start(s.skeleton.clone(), (s.source)()?, params)
        .with_context(|| format!("starting the in-core walk at ε {tolerance_px} px"))?;
    let mut r = GpuRenderer::new(
        s.gpu.clone(),
        RendererConfig {
            colouring: Colouring::Object,
            ..RendererConfig::headless(params.width_px, params.height_px, s.data_bytes)
        },
    )?;
    r.capture_every(s.every);
    let mut tris = Vec::with_capacity(s.poses.len());
    run_path_each(&mut w, s.poses, &mut r, 0.0, |f| {
        tris.push(f.drawn_tris as f64);
        Ok::<(), std::convert::Infallible>(())
    })
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    let errors = r.context().take_errors();
    if !errors.is_empty() {
        bail!("GPU errors at ε {tolerance_px} px: {}", errors.join("; "));
    }
    Ok(Walk {
        frames: r.take_captures(),
        front_tris: quantile(&tris, 0.5),
    })
}

/// Walks the reference and each tolerance; writes `fidelity.csv` and
/// returns the table.
pub fn run(s: &Setup<'_>, tolerances: &[f32], out: &Path) -> Result<String> {
    if s.every == 0 {
        bail!("--fidelity needs sampled frames: --psnr-every must be above 0");
    }
    let reference = walk(s, FINEST_PX)?;
    if let Some(dir) = &s.save {
        std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
        for (i, img) in &reference.frames {
            img.save_png(&dir.join(format!("finest-{i:05}.png")))?;
        }
    }
    eprintln!(
        "fidelity: reference (finest reps) done, median {:.0} triangles drawn",
        reference.front_tris
    );
    let mut csv = String::from("tolerance_px,frame,psnr_db,differing_share\n");
    let mut table = format!(
        "Fidelity against full resolution (every object at its finest rep: median {:.1} k triangles drawn), in core, every {} frames; differing = pixels beyond a one-pixel tolerance (colour tolerance {COLOUR_TOLERANCE}/255):\n\n| ε px | sampled | median PSNR dB | min PSNR dB | median differing % | max differing % | median triangles drawn (share of finest) |\n|---:|---:|---:|---:|---:|---:|---:|\n",
        reference.front_tris / 1e3,
        s.every
    );
    for &t in tolerances {
        let w = walk(s, t)?;
        let mut psnr = Vec::new();
        let mut share = Vec::new();
        for (i, img) in &w.frames {
            let Some((_, r)) = reference.frames.iter().find(|(j, _)| j == i) else {
                continue;
            };
            let (Some(d), Some(n)) = (
                img.diff(r, 0),
                img.differing_beyond_one_pixel(r, COLOUR_TOLERANCE),
            ) else {
                bail!("frame {i}: images of different sizes");
            };
            if let Some(dir) = &s.save {
                img.save_png(&dir.join(format!("eps{t}-{i:05}.png")))?;
                if let Some(di) = img.diff_image(r, COLOUR_TOLERANCE) {
                    di.save_png(&dir.join(format!("eps{t}-{i:05}-diff.png")))?;
                }
            }
            let sh = n as f64 / (f64::from(img.width) * f64::from(img.height));
            csv.push_str(&format!("{t},{i},{:.3},{sh:.6}\n", d.psnr_db));
            // Identical frames: PSNR is infinite; the table caps it at 99.
            psnr.push(d.psnr_db.min(99.0));
            share.push(sh * 100.0);
        }
        let min = psnr.iter().copied().fold(f64::INFINITY, f64::min);
        let max = share.iter().copied().fold(0.0, f64::max);
        table.push_str(&format!(
            "| {t} | {} | {:.1} | {min:.1} | {:.3} | {max:.3} | {:.1} k ({:.0}%) |\n",
            psnr.len(),
            quantile(&psnr, 0.5),
            quantile(&share, 0.5),
            w.front_tris / 1e3,
            100.0 * w.front_tris / reference.front_tris.max(1.0)
        ));
        eprintln!("fidelity: ε {t} px done");
    }
    write_bytes(&out.join("fidelity.csv"), csv.as_bytes())?;
    write_bytes(&out.join("fidelity.md"), table.as_bytes())?;
    Ok(table)
}
