//! The egui overlay: live metrics and plots, the settings the walkthrough
//! restarts with, and the viewer's actions. Returns what the user asked for;
//! the app carries it out.

use std::collections::VecDeque;

use egui_plot::{Line, Plot, PlotPoints};
use engine::gpu::Colouring;
use engine::metrics::FrameMetrics;
use engine::runtime::Mode;

use crate::session::Settings;

const MIB: f64 = 1048576.0;

/// One frame as the overlay plots it.
#[derive(Clone, Debug)]
pub struct Sample {
    /// Whole loop: front, loads, scene, overlay, present.
    pub loop_ms: f64,
    pub m: FrameMetrics,
}

/// Overlay state that outlives a frame.
#[derive(Debug, Default)]
pub struct UiState {
    pub open_text: String,
    pub path_text: String,
    pub frozen: bool,
}

/// What the user asked for this frame.
#[derive(Debug, Default)]
pub struct Actions {
    pub settings: Option<Settings>,
    pub open: Option<String>,
    pub play: Option<String>,
    pub toggle_record: bool,
    pub screenshot: bool,
    pub frame_all: bool,
}

/// What the overlay shows besides the samples.
pub struct View<'a> {
    pub scene: Option<&'a str>,
    pub error: Option<&'a str>,
    pub settings: Option<Settings>,
    pub budget_bytes: u64,
    pub recording: Option<usize>,
    pub playing: Option<(usize, usize)>,
    pub fly_speed: f32,
    pub orbit: bool,
}

fn series(h: &VecDeque<Sample>, f: impl Fn(&Sample) -> f64) -> PlotPoints<'static> {
    PlotPoints::from(
        h.iter()
            .enumerate()
            .map(|(i, s)| [i as f64, f(s)])
            .collect::<Vec<_>>(),
    )
}

/// A small fixed plot of the last frames.
fn live_plot(id: &str) -> Plot<'_> {
    Plot::new(id)
        .height(90.0)
        .legend(egui_plot::Legend::default())
        .include_y(0.0)
        .allow_drag(false)
        .allow_zoom(false)
        .allow_scroll(false)
}

/// Draws the overlay.
pub fn draw(
    ctx: &egui::Context,
    st: &mut UiState,
    v: &View<'_>,
    hist: &VecDeque<Sample>,
) -> Actions {
    let mut act = Actions::default();
    egui::Window::new("hlod-view")
        .default_pos([8.0, 8.0])
        .default_width(340.0)
        .show(ctx, |ui| {
            if let Some(e) = v.error {
                ui.colored_label(egui::Color32::from_rgb(255, 110, 90), e);
            }
            ui.horizontal(|ui| {
                ui.text_edit_singleline(&mut st.open_text);
                if ui.button("Open").clicked() {
                    act.open = Some(st.open_text.clone());
                }
            });
            let Some(mut s) = v.settings else {
                ui.label("No scene open.");
                return;
            };
            ui.label(v.scene.unwrap_or(""));
            if let Some(last) = hist.back() {
                let n = hist.len().max(1) as f64;
                let mean = hist.iter().map(|x| x.loop_ms).sum::<f64>() / n;
                let m = &last.m;
                ui.label(format!(
                    "frame {:.1} ms ({:.0} fps), runtime {:.1} ms, wait {:.1} ms",
                    mean,
                    1000.0 / mean.max(1e-3),
                    m.frame_ms,
                    m.wait_ms
                ));
                ui.label(format!(
                    "front {} reps, {:.2} M tris, {:.2} MB",
                    m.front_reps,
                    m.front_tris as f64 / 1e6,
                    m.front_bytes as f64 / 1e6
                ));
                ui.label(format!(
                    "resident {:.1} / {:.1} MiB, GPU {:.1} MiB",
                    m.max_resident_bytes as f64 / MIB,
                    v.budget_bytes as f64 / MIB,
                    m.gpu_bytes as f64 / MIB
                ));
                ui.label(format!(
                    "Stage II {:.2} MiB, prefetched {:.2} MiB, missing {} (LOD {} / HLOD {} / new {}), substituted {}",
                    m.stage2_bytes as f64 / MIB,
                    m.prefetch_bytes as f64 / MIB,
                    m.missing_reps,
                    m.miss_lod,
                    m.miss_hier,
                    m.miss_new,
                    m.substituted
                ));
                ui.label(format!(
                    "P_I queues: L_O {} reps, prefetch bins {} reps",
                    m.missing_reps, m.prefetch_queue
                ));
            }
            live_plot("times").show(ui, |p| {
                    p.line(Line::new("loop ms", series(hist, |s| s.loop_ms)));
                    p.line(Line::new("runtime ms", series(hist, |s| s.m.frame_ms)));
                });
            live_plot("bytes").show(ui, |p| {
                    p.line(Line::new("resident MiB", series(hist, |s| s.m.max_resident_bytes as f64 / MIB)));
                    p.line(Line::new("Stage II MiB", series(hist, |s| s.m.stage2_bytes as f64 / MIB)));
                    p.line(Line::new("prefetch MiB", series(hist, |s| s.m.prefetch_bytes as f64 / MIB)));
                });
            ui.separator();
            egui::ComboBox::from_label("mode")
                .selected_text(s.mode.name())
                .show_ui(ui, |ui| {
                    for m in [Mode::Incore, Mode::NoPre, Mode::Pre] {
                        ui.selectable_value(&mut s.mode, m, m.name());
                    }
                });
            let mut pct = s.budget_fraction * 100.0;
            ui.add(egui::Slider::new(&mut pct, 0.5..=100.0).logarithmic(true).text("budget %"));
            s.budget_fraction = pct / 100.0;
            ui.add(egui::Slider::new(&mut s.params.tolerance_px, 0.25..=32.0).logarithmic(true).text("ε px"));
            let p = &mut s.params.prefetch;
            ui.add(egui::Slider::new(&mut p.margin_deg, 0.0..=60.0).text("F_I margin °"));
            ui.add(egui::Slider::new(&mut p.delta_px, 0.0..=128.0).text("δ px (0 = 4ε)"));
            ui.add(egui::Slider::new(&mut p.bins, 1..=64).text("bins B"));
            egui::ComboBox::from_label("colouring")
                .selected_text(format!("{:?}", s.colouring))
                .show_ui(ui, |ui| {
                    for c in [Colouring::Object, Colouring::LodLevel, Colouring::Kind, Colouring::Substituted] {
                        ui.selectable_value(&mut s.colouring, c, format!("{c:?}"));
                    }
                });
            ui.checkbox(&mut st.frozen, "freeze front (F)");
            if Some(s) != v.settings {
                act.settings = Some(s);
            }
            ui.separator();
            ui.label(format!(
                "{} (Tab), speed {:.2}/s (wheel), WASD/QE, shift runs, right-drag looks",
                if v.orbit { "orbit" } else { "fly" },
                v.fly_speed
            ));
            ui.horizontal(|ui| {
                if ui.button("Frame all (Home)").clicked() {
                    act.frame_all = true;
                }
                if ui.button("Screenshot (F12)").clicked() {
                    act.screenshot = true;
                }
            });
            let rec = match v.recording {
                Some(n) => format!("Stop recording ({n} poses) (R)"),
                None => "Record path (R)".into(),
            };
            if ui.button(rec).clicked() {
                act.toggle_record = true;
            }
            ui.horizontal(|ui| {
                ui.text_edit_singleline(&mut st.path_text);
                if ui.button("Play path").clicked() {
                    act.play = Some(st.path_text.clone());
                }
            });
            if let Some((i, n)) = v.playing {
                ui.label(format!("playing frame {i} of {n}"));
            }
        });
    act
}
