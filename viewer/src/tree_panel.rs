//! The model tree in the main panel (T, or its tab): site, building,
//! storey, type and element as [`engine::tree::ModelTree`] groups them,
//! each row with hide/show, isolate, x-ray and fly-to; a search by name,
//! type or GlobalId. Returns what the user asked for; the app does it.

use egui::collapsing_header::CollapsingState;
use engine::tree::{Counts, Look, ModelTree, Op};

/// Elements listed under one group before the rest is left to the search.
const MAX_ROWS: usize = 200;

/// What a row stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    Group(u32),
    Object(u32),
}

/// What a row's buttons ask for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum What {
    Op(Op),
    FlyTo,
    Select,
}

/// One click in the tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TreeAction {
    pub target: Target,
    pub what: What,
}

/// The tree panel's state that outlives a frame.
#[derive(Debug, Default)]
pub struct TreeState {
    pub search: String,
    /// The last search's objects.
    pub results: Vec<u32>,
    /// Open the groups above this object and scroll to it (once).
    pub reveal: Option<u32>,
}

/// What the tree panel shows.
pub struct TreeView<'a> {
    pub tree: &'a ModelTree,
    pub looks: &'a [Look],
    pub selected: Option<u32>,
}

/// What the panel asks for this frame.
#[derive(Debug, Default)]
pub struct TreeOut {
    pub action: Option<TreeAction>,
    pub search: Option<String>,
}

/// Draws the tree into `ui`.
pub fn show(ui: &mut egui::Ui, st: &mut TreeState, v: &TreeView<'_>) -> TreeOut {
    let mut out = TreeOut::default();
    ui.horizontal(|ui| {
        let edit = ui.text_edit_singleline(&mut st.search);
        let entered = edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
        if ui.button("Search").clicked() || entered {
            out.search = Some(st.search.clone());
        }
    });
    ui.horizontal(|ui| {
        let all = ModelTree::counts(v.tree.objects(0), v.looks);
        ui.label(format!(
            "{} elements: {} shown, {} hidden, {} x-rayed",
            v.tree.objects(0).len(),
            all.shown,
            all.hidden,
            all.xray
        ));
        if ui.small_button("show all").clicked() {
            out.action = Some(TreeAction {
                target: Target::Group(0),
                what: What::Op(Op::Show),
            });
        }
    });
    if let Some(k) = st.reveal.take() {
        for g in v.tree.ancestry(v.tree.group_of(k)) {
            let mut s = CollapsingState::load_with_default_open(ui.ctx(), row_id(g), true);
            s.set_open(true);
            s.store(ui.ctx());
        }
    }
    egui::ScrollArea::vertical()
        .max_height(ui.available_height().max(200.0))
        .auto_shrink([false, true])
        .show(ui, |ui| {
            if !st.results.is_empty() {
                ui.label(format!("{} found:", st.results.len()));
                for &k in &st.results {
                    object_row(ui, v, k, &mut out);
                }
                if ui.small_button("clear the search").clicked() {
                    st.results.clear();
                }
                ui.separator();
            }
            group(ui, v, 0, 0, &mut out);
        });
    out
}

/// A group row's id (the same wherever the row is drawn).
fn row_id(g: u32) -> egui::Id {
    egui::Id::unique(("hlod-view model tree", g))
}

/// Groups this deep (the model, a site, a building) are open at first.
const OPEN_DEPTH: usize = 2;

/// A group's row and, when open, its subgroups and elements.
fn group(ui: &mut egui::Ui, v: &TreeView<'_>, g: u32, depth: usize, out: &mut TreeOut) {
    let grp = &v.tree.groups()[g as usize];
    CollapsingState::load_with_default_open(ui.ctx(), row_id(g), depth <= OPEN_DEPTH)
        .show_header(ui, |ui| {
            let c = ModelTree::counts(v.tree.objects(g), v.looks);
            let text = format!("{} ({})", grp.label, v.tree.objects(g).len());
            buttons(ui, Target::Group(g), c, out);
            let r = ui.label(styled(text, c, false));
            r.on_hover_text(format!("{:?}", grp.level));
        })
        .body(|ui| {
            for &c in &grp.children {
                group(ui, v, c, depth + 1, out);
            }
            let direct = v.tree.direct(g);
            for &k in direct.iter().take(MAX_ROWS) {
                object_row(ui, v, k, out);
            }
            if direct.len() > MAX_ROWS {
                ui.label(format!(
                    "… {} more: search to find one",
                    direct.len() - MAX_ROWS
                ));
            }
        });
}

/// An element's row: its buttons and its label (a click selects it).
fn object_row(ui: &mut egui::Ui, v: &TreeView<'_>, k: u32, out: &mut TreeOut) {
    ui.horizontal(|ui| {
        let c = ModelTree::counts(&[k], v.looks);
        buttons(ui, Target::Object(k), c, out);
        let selected = v.selected == Some(k);
        let label = match v.tree.label(k) {
            "" => format!("object {k}"),
            l => l.to_string(),
        };
        let r = ui.selectable_label(selected, styled(label, c, selected));
        let r = match v.tree.global_id(k) {
            "" => r,
            id => r.on_hover_text(format!("GlobalId {id}")),
        };
        if selected {
            r.scroll_to_me(None);
        }
        if r.clicked() {
            out.action = Some(TreeAction {
                target: Target::Object(k),
                what: What::Select,
            });
        }
    });
}

/// Hide (or show), isolate, x-ray (or solid) and fly-to for a row.
fn buttons(ui: &mut egui::Ui, target: Target, c: Counts, out: &mut TreeOut) {
    let mut ask = |what| out.action = Some(TreeAction { target, what });
    let all_hidden = c.shown == 0 && c.xray == 0;
    if ui
        .small_button(if all_hidden { "show" } else { "hide" })
        .on_hover_text("hide these elements (they leave the front and are not fetched)")
        .clicked()
    {
        ask(What::Op(if all_hidden { Op::Show } else { Op::Hide }));
    }
    if ui
        .small_button("iso")
        .on_hover_text("isolate: show these, hide every other element")
        .clicked()
    {
        ask(What::Op(Op::Isolate));
    }
    let all_xray = c.xray > 0 && c.shown == 0;
    if ui
        .small_button(if all_xray { "solid" } else { "x-ray" })
        .on_hover_text("x-ray: draw translucent, hiding nothing behind")
        .clicked()
    {
        ask(What::Op(if all_xray { Op::Show } else { Op::XRay }));
    }
    if ui
        .small_button("go")
        .on_hover_text("fly to these elements")
        .clicked()
    {
        ask(What::FlyTo);
    }
}

/// A row's text: dim when all hidden, blue when all x-rayed.
fn styled(text: String, c: Counts, strong: bool) -> egui::RichText {
    let t = egui::RichText::new(text);
    let t = if c.shown == 0 && c.xray == 0 && c.hidden > 0 {
        t.color(egui::Color32::from_gray(110)).strikethrough()
    } else if c.shown == 0 && c.xray > 0 {
        t.color(egui::Color32::from_rgb(140, 190, 255))
    } else {
        t
    };
    if strong { t.strong() } else { t }
}
