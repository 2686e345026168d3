//! The egui overlay: live metrics and plots, the settings the walkthrough
//! restarts with, and the viewer's actions. Returns what the user asked for;
//! the app carries it out.

use std::collections::VecDeque;

use egui_plot::{Line, Plot, PlotPoints};
use engine::metrics::FrameMetrics;
use engine::runtime::Mode;
use engine_gpu::Colouring;

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
    pub find_text: String,
    pub frozen: bool,
    /// The fraction of the window's width, from the left, that the main
    /// panel covers (as last drawn): framing keeps the model clear of it.
    pub panel_frac: f32,
    /// The main panel shows the model tree instead of the walkthrough.
    pub tree_tab: bool,
    pub tree: crate::tree_panel::TreeState,
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
    pub clear_selection: bool,
    /// Find an element by name or GlobalId and fly to it.
    pub find: Option<String>,
    /// What the model tree asks for.
    pub tree: crate::tree_panel::TreeOut,
}

/// A measurement in the view: its ends in pixels and its label.
#[derive(Clone, Debug, PartialEq)]
pub struct MeasureMark {
    pub from: (f32, f32),
    pub to: (f32, f32),
    pub label: String,
}

/// What the overlay shows besides the samples.
pub struct View<'a> {
    pub scene: Option<&'a str>,
    /// A model being built: the status line and the fraction done.
    pub building: Option<(String, f32)>,
    pub selection: Option<&'a crate::picking::Selection>,
    /// The selection's box edges, in pixels.
    pub highlight: Vec<[(f32, f32); 2]>,
    /// The measurement shown, if any.
    pub measure: Option<MeasureMark>,
    /// Whether the last frame was complete, and the reps still loading.
    pub complete: Option<(bool, u32)>,
    pub pixels_per_point: f32,
    pub error: Option<&'a str>,
    pub settings: Option<Settings>,
    pub budget_bytes: u64,
    /// The scene's rep data: what the budget slider's percentages are of.
    pub data_bytes: u64,
    pub recording: Option<usize>,
    pub playing: Option<(usize, usize)>,
    pub fly_speed: f32,
    pub orbit: bool,
    /// Walk mode's status line, while walking.
    pub walking: Option<String>,
    /// The model tree, while its tab is shown (`None`: the scene describes
    /// no elements).
    pub tree: Option<crate::tree_panel::TreeView<'a>>,
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
    notices(ctx, v, &mut act);
    let panel = egui::Window::new("hlod-view")
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
            match v.complete {
                Some((true, _)) => {
                    ui.colored_label(egui::Color32::from_rgb(120, 220, 120), "view complete: nothing missing, nothing substituted");
                }
                Some((false, n)) => {
                    ui.colored_label(egui::Color32::from_rgb(255, 200, 80), format!("loading: {n} reps still coming, coarser ones shown"));
                }
                None => {}
            }
            ui.horizontal(|ui| {
                ui.selectable_value(&mut st.tree_tab, false, "Walkthrough");
                ui.selectable_value(&mut st.tree_tab, true, "Model tree (T)");
            });
            if st.tree_tab {
                match &v.tree {
                    Some(t) => act.tree = crate::tree_panel::show(ui, &mut st.tree, t),
                    None => {
                        ui.label("This scene describes no elements: rebuild it for a model tree.");
                    }
                }
                return;
            }
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
                    "front {} reps, {:.2} M tris, {:.2} MB at ε {:.2} px; {} hidden (occlusion); fading {} in / {} out",
                    m.front_reps,
                    m.front_tris as f64 / 1e6,
                    m.front_bytes as f64 / 1e6,
                    m.tolerance_px,
                    m.occluded_reps,
                    m.fade_in,
                    m.fade_out
                ));
                ui.label(format!(
                    "resident {:.1} / {:.1} MiB, GPU {:.1} MiB",
                    m.loader.max_resident_bytes as f64 / MIB,
                    v.budget_bytes as f64 / MIB,
                    m.gpu_bytes as f64 / MIB
                ));
                ui.label(format!(
                    "Stage II {:.2} MiB, prefetched {:.2} MiB, missing {} (LOD {} / HLOD {} / new {}), substituted {}",
                    m.loader.stage2_bytes as f64 / MIB,
                    m.loader.prefetch_bytes as f64 / MIB,
                    m.loader.missing_reps,
                    m.loader.miss_lod,
                    m.loader.miss_hier,
                    m.loader.miss_new,
                    m.substituted
                ));
                ui.label(format!(
                    "P_I queues: L_O {} reps, prefetch bins {} reps",
                    m.loader.missing_reps, m.loader.prefetch_queue
                ));
            }
            live_plot("times").show(ui, |p| {
                    p.line(Line::new("loop ms", series(hist, |s| s.loop_ms)));
                    p.line(Line::new("runtime ms", series(hist, |s| s.m.frame_ms)));
                });
            live_plot("bytes").show(ui, |p| {
                    p.line(Line::new("resident MiB", series(hist, |s| s.m.loader.max_resident_bytes as f64 / MIB)));
                    p.line(Line::new("Stage II MiB", series(hist, |s| s.m.loader.stage2_bytes as f64 / MIB)));
                    p.line(Line::new("prefetch MiB", series(hist, |s| s.m.loader.prefetch_bytes as f64 / MIB)));
                });
            ui.separator();
            egui::ComboBox::from_label("mode")
                .selected_text(s.mode.name())
                .show_ui(ui, |ui| {
                    for m in [Mode::Incore, Mode::NoPre, Mode::Pre] {
                        ui.selectable_value(&mut s.mode, m, m.name());
                    }
                });
            let data = v.data_bytes.max(1) as f64;
            let mut pct = s.budget_bytes as f64 / data * 100.0;
            let slid = ui.add(egui::Slider::new(&mut pct, 0.5..=100.0).logarithmic(true).text("budget %"));
            if slid.changed() {
                s.budget_bytes = ((data * pct / 100.0) as u64).max(1);
            }
            ui.add(egui::Slider::new(&mut s.params.tolerance_px, 0.25..=32.0).logarithmic(true).text("ε px"));
            ui.checkbox(&mut s.occlusion, "occlusion culling");
            let mut governed = s.params.governor.is_some();
            ui.checkbox(&mut governed, "quality governor (raise ε to fit the budget)");
            s.params.governor = governed.then(|| s.params.governor.unwrap_or_default());
            if let Some(g) = &mut s.params.governor {
                ui.add(egui::Slider::new(&mut g.max_frame_ms, 0.0..=200.0).text("frame-time target ms (0 = none)"));
            }
            ui.add(egui::Slider::new(&mut s.params.fade_s, 0.0..=1.0).text("LOD fade s (0 = off)"));
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
            ui.label(match &v.walking {
                Some(w) => format!("{w} (G flies), WASD, shift runs, right-drag looks"),
                None => format!(
                    "{} (Tab; G walks), speed {:.2}/s (wheel), WASD/QE, shift runs, right-drag looks",
                    if v.orbit { "orbit" } else { "fly" },
                    v.fly_speed
                ),
            });
            let planes = v.settings.map_or(0, |s| s.params.section.planes().len());
            ui.label(match planes {
                0 => "no section (C cuts at eye height, B boxes the selection; H hides, I \
                      isolates, X x-rays, U shows all, T the model tree; V saves a BCF \
                      viewpoint, M measures)"
                    .to_string(),
                n => format!("section: {n} plane(s) cut the model ([ ] move them; C or B: off)"),
            });
            ui.horizontal(|ui| {
                let edit = ui.text_edit_singleline(&mut st.find_text);
                let entered = edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
                if ui.button("Find").clicked() || entered {
                    act.find = Some(st.find_text.clone());
                }
            });
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
    if let Some(r) = panel {
        let width = ctx.content_rect().width();
        if width > 0.0 {
            st.panel_frac = (r.response.rect.max.x / width).clamp(0.0, 1.0);
        }
    }
    act
}

/// What must not be missed: a build's progress and an error, centred; the
/// selected element beside, and its box drawn over the scene.
fn notices(ctx: &egui::Context, v: &View<'_>, act: &mut Actions) {
    if let Some((text, frac)) = &v.building {
        egui::Window::new("Opening the model")
            .anchor(egui::Align2::CENTER_CENTER, [0.0, 0.0])
            .collapsible(false)
            .resizable(false)
            .show(ctx, |ui| {
                ui.label(text);
                ui.add(egui::ProgressBar::new(*frac).show_percentage());
                ui.label("The scene is built once and cached; the next open is immediate.");
            });
    }
    if let Some(e) = v.error {
        egui::Window::new("Cannot show the scene")
            .anchor(egui::Align2::CENTER_BOTTOM, [0.0, -24.0])
            .collapsible(false)
            .resizable(false)
            .frame(
                egui::Frame::window(&ctx.global_style()).fill(egui::Color32::from_rgb(90, 20, 20)),
            )
            .show(ctx, |ui| {
                ui.colored_label(egui::Color32::WHITE, egui::RichText::new(e).size(16.0));
            });
    }
    let ppp = v.pixels_per_point.max(0.1);
    if let Some(m) = &v.measure {
        let painter = ctx.layer_painter(egui::LayerId::new(
            egui::Order::Background,
            egui::Id::unique("measure"),
        ));
        let (a, b) = (
            egui::pos2(m.from.0 / ppp, m.from.1 / ppp),
            egui::pos2(m.to.0 / ppp, m.to.1 / ppp),
        );
        let cyan = egui::Color32::from_rgb(0, 220, 255);
        painter.line_segment([a, b], egui::Stroke::new(2.0, cyan));
        painter.circle_filled(a, 4.0, cyan);
        painter.circle_filled(b, 4.0, cyan);
        painter.text(
            a + (b - a) * 0.5 + egui::vec2(0.0, -10.0),
            egui::Align2::CENTER_BOTTOM,
            &m.label,
            egui::FontId::proportional(16.0),
            egui::Color32::WHITE,
        );
    }
    let Some(sel) = v.selection else { return };
    let painter = ctx.layer_painter(egui::LayerId::new(
        egui::Order::Background,
        egui::Id::unique("highlight"),
    ));
    let stroke = egui::Stroke::new(2.0, egui::Color32::from_rgb(255, 230, 0));
    for [a, b] in &v.highlight {
        painter.line_segment(
            [
                egui::pos2(a.0 / ppp, a.1 / ppp),
                egui::pos2(b.0 / ppp, b.1 / ppp),
            ],
            stroke,
        );
    }
    egui::Window::new("Selected")
        .anchor(egui::Align2::RIGHT_TOP, [-8.0, 8.0])
        .default_width(300.0)
        .show(ctx, |ui| {
            ui.heading(&sel.name);
            if let Some(m) = &sel.mesh_name {
                ui.label(format!("mesh: {m}"));
            }
            if let Some(k) = sel.object {
                ui.label(format!("object {k}, leaf node {}", sel.node));
            }
            if let Some(x) = &sel.extras {
                ui.label(format!("extras: {x}"));
            }
            let f = |p: [f64; 3]| format!("{:.3}, {:.3}, {:.3}", p[0], p[1], p[2]);
            ui.label(format!("box min {}", f(sel.world_min)));
            ui.label(format!("box max {}", f(sel.world_max)));
            ui.label(format!("hit {}", f(sel.point)));
            if ui.button("Clear").clicked() {
                act.clear_selection = true;
            }
        });
}
