//! The model tree in the window: the panel's clicks (hide, isolate,
//! x-ray, fly to, select), its search, key T, `--tree`, `--isolate`,
//! `--xray` and `--hide`; and the overlay's actions.

use std::path::Path;

use engine::camera::read_path;
use engine::tree::{Look, Op};
use glam::Vec3;

use super::App;
use crate::session::Session;
use crate::tree_panel::{Target, TreeAction, TreeView, What};
use crate::ui::{self, UiState};

/// Search results listed at most.
const MAX_FOUND: usize = 500;

/// The tree panel's view of the open scene, while its tab is shown and
/// the tree is made.
pub(super) fn view<'a>(
    session: Option<&'a Session>,
    selection: Option<&crate::picking::Selection>,
    ui: &UiState,
) -> Option<TreeView<'a>> {
    let s = session.filter(|_| ui.tree_tab)?;
    Some(TreeView {
        tree: s.tree_made()?,
        looks: s.looks(),
        selected: selection.and_then(|x| x.object),
    })
}

impl App {
    pub(super) fn apply(&mut self, a: ui::Actions) {
        if let Some(p) = a.open {
            self.open(Path::new(p.trim()));
        }
        if a.clear_selection {
            self.selection = None;
        }
        if let (Some(s), Some(sess), Some(gfx)) = (a.settings, &mut self.session, &self.gfx) {
            if let Err(e) = sess.apply(&gfx.ctx, s) {
                self.report(format!("{e:#}"));
            } else {
                self.settings = s;
            }
        }
        if let Some(p) = a.play {
            match read_path(Path::new(p.trim())) {
                Ok(poses) => self.play = Some((poses, 0)),
                Err(e) => self.report(e.to_string()),
            }
        }
        if a.toggle_record {
            self.toggle_record();
        }
        if a.screenshot {
            self.shots.pending = Some(self.next_shot_name());
        }
        if a.frame_all {
            self.frame_all();
        }
        if let Some(t) = a.find {
            self.find(&t);
        }
        if let Some(t) = a.tree.search {
            self.tree_search(&t);
        }
        if let Some(t) = a.tree.action {
            self.tree_action(t);
        }
    }

    /// T: the main panel shows the model tree, or the walkthrough again.
    pub(super) fn toggle_tree(&mut self) {
        self.ui.tree_tab = !self.ui.tree_tab;
        self.ui_dirty = true;
    }

    /// Makes the model tree when its tab is first shown (an error once).
    pub(super) fn ensure_tree(&mut self) {
        let Some(s) = &mut self.session else { return };
        if self.ui.tree_tab
            && s.tree_made().is_none()
            && !s.tree_failed
            && let Err(e) = s.tree()
        {
            s.tree_failed = true;
            self.report(format!("model tree: {e:#}"));
        }
    }

    /// `--isolate`, `--xray` and `--hide`, in that order, once a scene opens.
    pub(super) fn tree_cli(&mut self) {
        let steps: Vec<(Op, String)> = (self.args.isolate.iter().map(|t| (Op::Isolate, t.clone())))
            .chain(self.args.xray.iter().map(|t| (Op::XRay, t.clone())))
            .chain(self.args.hide.iter().map(|t| (Op::Hide, t.clone())))
            .collect();
        let mut looks = match &self.session {
            Some(s) if !steps.is_empty() => s.looks().to_vec(),
            _ => return,
        };
        for (op, text) in steps {
            let Some(s) = &mut self.session else { return };
            let (objects, what) = match s.resolve(&text) {
                Ok(found) => found,
                Err(e) => return self.report(format!("{op:?} {text:?}: {e:#}")),
            };
            if objects.is_empty() {
                self.report(format!("{op:?} {text:?}: no group or element matches"));
                continue;
            }
            if let Ok(tree) = s.tree() {
                tree.apply(&mut looks, &objects, op);
            }
            println!("{op:?} {what}: {} element(s)", objects.len());
        }
        self.set_looks(looks);
    }

    /// The panel's search: the objects found, the first selected.
    fn tree_search(&mut self, text: &str) {
        let Some(s) = &mut self.session else { return };
        let found = match s.search(text, MAX_FOUND) {
            Ok(found) => found,
            Err(e) => return self.report(format!("search: {e:#}")),
        };
        println!("search {text:?}: {} element(s)", found.len());
        if found.is_empty() {
            self.report(format!("search {text:?}: no element matches"));
        }
        self.ui.tree.results = found;
        self.ui_dirty = true;
    }

    /// A click in the tree.
    fn tree_action(&mut self, a: TreeAction) {
        let Some(s) = &mut self.session else { return };
        let origin = s.origin;
        let Ok(tree) = s.tree() else { return };
        let (objects, what) = match a.target {
            Target::Group(g) => (
                tree.objects(g).to_vec(),
                tree.groups()[g as usize].label.clone(),
            ),
            Target::Object(k) => (vec![k], tree.label(k).to_string()),
        };
        let bounds = tree.bounds_of(&objects);
        match (a.what, a.target) {
            (What::Op(op), _) => self.apply_op(op, &objects, &format!("{what:?}")),
            (What::FlyTo, _) => {
                let Some((min, max)) = bounds else {
                    return self.report(format!("{what}: no box to fly to"));
                };
                let scene = |w: [f64; 3]| {
                    Vec3::new(
                        (w[0] - origin[0]) as f32,
                        (w[1] - origin[1]) as f32,
                        (w[2] - origin[2]) as f32,
                    )
                };
                self.fly_to(scene(min), scene(max));
                println!("flew to {what:?}");
            }
            (What::Select, Target::Object(k)) => {
                self.selection = s.picker().ok().and_then(|p| p.select(k, origin));
                self.ui_dirty = true;
            }
            (What::Select, Target::Group(_)) => {}
        }
    }

    /// Frames the box `[min, max]` (scene coordinates) beside the panel.
    pub(super) fn fly_to(&mut self, min: Vec3, max: Vec3) {
        let Some(s) = &self.session else { return };
        let c = *s.renderer.config();
        let aspect = c.width as f32 / c.height.max(1) as f32;
        let pad = (max - min).max_element().max(0.5) * 0.5;
        (self.controls).frame_all_beside(min - pad, max + pad, aspect, self.ui.panel_frac);
        self.play = None;
        self.ui_dirty = true;
    }

    /// Draws the objects as `looks` says from the next frame on.
    pub(super) fn set_looks(&mut self, looks: Vec<Look>) {
        let Some(s) = &mut self.session else { return };
        match s.set_looks(looks) {
            Ok((hidden, xray)) => println!("{hidden} element(s) hidden, {xray} x-rayed"),
            Err(e) => self.report(format!("hide: {e:#}")),
        }
        self.ui_dirty = true;
    }

    /// Applies `op` to `objects` (`what` names them in the log).
    pub(super) fn apply_op(&mut self, op: Op, objects: &[u32], what: &str) {
        let Some(s) = &mut self.session else { return };
        let mut looks = s.looks().to_vec();
        match s.tree() {
            Ok(tree) => tree.apply(&mut looks, objects, op),
            Err(e) => return self.report(format!("{op:?} {what}: {e:#}")),
        }
        println!("{op:?} {what}: {} element(s)", objects.len());
        self.set_looks(looks);
    }
}
