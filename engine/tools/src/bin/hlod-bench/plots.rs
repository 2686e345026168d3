//! PNG plots like the paper's figures, drawn with plotters into a bitmap and
//! written with the engine's PNG writer. Text uses the Ubuntu Light face
//! bundled by `epaint_default_fonts` (no system fonts needed).

use engine_cli::png::PngFile as _;
use std::path::Path;
use std::sync::Once;

use anyhow::{Result, anyhow};
use engine::image::RgbaImage;
use engine::metrics::TracePoint;
use plotters::prelude::*;

const SIZE: (u32, u32) = (1200, 600);
const MIB: f64 = 1048576.0;

/// One run's frames and its legend label.
pub struct Run<'a> {
    pub label: String,
    pub frames: &'a [TracePoint],
}

/// A point of the footprint sweep.
pub struct SweepPoint {
    pub mode: &'static str,
    pub budget_mib: f64,
    pub stage2_mib: f64,
    pub p99_ms: f64,
}

fn fonts() -> Result<()> {
    static ONCE: Once = Once::new();
    let mut res = Ok(());
    ONCE.call_once(|| {
        res = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        )
        .map_err(|_| anyhow!("bundled font rejected"));
    });
    res
}

fn colour(i: usize) -> RGBColor {
    const C: [RGBColor; 6] = [
        RGBColor(40, 40, 40),
        RGBColor(220, 50, 47),
        RGBColor(38, 139, 210),
        RGBColor(133, 153, 0),
        RGBColor(211, 54, 130),
        RGBColor(181, 137, 0),
    ];
    C[i % C.len()]
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

/// Draws into an RGB buffer with `f`, then saves it as PNG.
fn save(path: &Path, f: impl FnOnce(&Area<'_>) -> Result<()>) -> Result<()> {
    fonts()?;
    let mut buf = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        f(&root)?;
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    let img = RgbaImage {
        width: SIZE.0,
        height: SIZE.1,
        data: buf
            .chunks_exact(3)
            .flat_map(|c| [c[0], c[1], c[2], 255])
            .collect(),
    };
    img.save_png(path)?;
    Ok(())
}

/// Line series per run of `value(frame)` over the frame index.
pub fn per_frame(
    path: &Path,
    title: &str,
    y_label: &str,
    runs: &[(String, Vec<f64>)],
    hline: Option<(String, f64)>,
) -> Result<()> {
    let n = runs.iter().map(|r| r.1.len()).max().unwrap_or(1).max(1);
    let mut y_max = runs
        .iter()
        .flat_map(|r| r.1.iter().copied())
        .fold(0.0f64, f64::max);
    if let Some((_, h)) = &hline {
        y_max = y_max.max(*h);
    }
    let y_max = if y_max > 0.0 { y_max * 1.08 } else { 1.0 };
    save(path, |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 26))
            .margin(16)
            .x_label_area_size(44)
            .y_label_area_size(72)
            .build_cartesian_2d(0..n, 0.0..y_max)
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .configure_mesh()
            .x_desc("frame")
            .y_desc(y_label)
            .label_style(("sans-serif", 16))
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        for (i, (label, ys)) in runs.iter().enumerate() {
            let c = colour(i);
            chart
                .draw_series(LineSeries::new(
                    ys.iter().enumerate().map(|(x, &y)| (x, y)),
                    c.stroke_width(1),
                ))
                .map_err(|e| anyhow!("{e}"))?
                .label(label.clone())
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], c.stroke_width(3)));
        }
        if let Some((label, h)) = hline {
            let c = RGBColor(120, 120, 120);
            chart
                .draw_series(LineSeries::new([(0, h), (n, h)], c.stroke_width(2)))
                .map_err(|e| anyhow!("{e}"))?
                .label(label)
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], c.stroke_width(3)));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 18))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        Ok(())
    })
}

/// Fig. 9: frame time per frame, one line per run, the frame period marked.
pub fn frame_times(path: &Path, runs: &[Run<'_>], period_ms: f64) -> Result<()> {
    let series: Vec<(String, Vec<f64>)> = runs
        .iter()
        .map(|r| {
            (
                r.label.clone(),
                r.frames.iter().map(|f| f.frame_ms).collect(),
            )
        })
        .collect();
    let hline = period_ms
        .is_finite()
        .then(|| ("frame period".to_string(), period_ms));
    per_frame(path, "Frame time", "ms", &series, hline)
}

/// Fig. 10: bytes fetched in Stage II per frame against the front's size.
pub fn fetch_vs_front(path: &Path, runs: &[Run<'_>]) -> Result<()> {
    let mut series = Vec::new();
    if let Some(r) = runs.first() {
        series.push((
            "front size".to_string(),
            r.frames
                .iter()
                .map(|f| f.front_bytes as f64 / MIB)
                .collect(),
        ));
    }
    for r in runs {
        series.push((
            format!("{}: Stage II fetch", r.label),
            r.frames
                .iter()
                .map(|f| f.stage2_bytes as f64 / MIB)
                .collect(),
        ));
    }
    per_frame(path, "Stage II fetch vs front size", "MiB", &series, None)
}

/// Resident rep bytes (the largest per frame) against the budget.
pub fn resident(path: &Path, runs: &[Run<'_>], budget: u64) -> Result<()> {
    let series: Vec<(String, Vec<f64>)> = runs
        .iter()
        .map(|r| {
            (
                r.label.clone(),
                r.frames
                    .iter()
                    .map(|f| f.max_resident_bytes as f64 / MIB)
                    .collect(),
            )
        })
        .collect();
    per_frame(
        path,
        "Resident memory",
        "MiB",
        &series,
        Some(("budget".into(), budget as f64 / MIB)),
    )
}

/// Fig. 11: Stage II MiB (left) and p99 frame time (right) over footprints.
pub fn sweep(path: &Path, points: &[SweepPoint]) -> Result<()> {
    let modes: Vec<&str> = {
        let mut m: Vec<&str> = points.iter().map(|p| p.mode).collect();
        m.dedup();
        m
    };
    let x_max = points.iter().map(|p| p.budget_mib).fold(0.0, f64::max) * 1.1 + 1e-9;
    save(path, |root| {
        let halves = root.split_evenly((1, 2));
        for (h, (title, pick)) in halves.iter().zip([
            ("Stage II fetch over the walk", 0usize),
            ("p99 frame time", 1),
        ]) {
            let val = |p: &SweepPoint| if pick == 0 { p.stage2_mib } else { p.p99_ms };
            let y_max = points.iter().map(val).fold(0.0, f64::max) * 1.1 + 1e-9;
            let mut chart = ChartBuilder::on(h)
                .caption(title, ("sans-serif", 24))
                .margin(16)
                .x_label_area_size(44)
                .y_label_area_size(72)
                .build_cartesian_2d(0.0..x_max, 0.0..y_max)
                .map_err(|e| anyhow!("{e}"))?;
            chart
                .configure_mesh()
                .x_desc("footprint (MiB)")
                .y_desc(if pick == 0 { "MiB" } else { "ms" })
                .label_style(("sans-serif", 16))
                .draw()
                .map_err(|e| anyhow!("{e}"))?;
            for (i, m) in modes.iter().enumerate() {
                let c = colour(i + 1);
                let pts: Vec<(f64, f64)> = points
                    .iter()
                    .filter(|p| p.mode == *m)
                    .map(|p| (p.budget_mib, val(p)))
                    .collect();
                chart
                    .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
                    .map_err(|e| anyhow!("{e}"))?
                    .label(m.to_string())
                    .legend(move |(x, y)| {
                        PathElement::new([(x, y), (x + 20, y)], c.stroke_width(3))
                    });
                chart
                    .draw_series(pts.iter().map(|&p| Circle::new(p, 4, c.filled())))
                    .map_err(|e| anyhow!("{e}"))?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 18))
                .draw()
                .map_err(|e| anyhow!("{e}"))?;
        }
        Ok(())
    })
}
