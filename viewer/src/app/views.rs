//! The BIM tools in the window: section planes and BCF viewpoints
//! (`--viewpoint` applied when a scene opens, `--save-viewpoint` at exit,
//! `V` to save one, `C` to cut the model horizontally at the eye's height
//! and back, `B` to box the selected element, `[` and `]` to move the
//! planes), measuring (`M`, then two clicks; `--measure`), and the marks
//! the overlay draws for them.

use std::path::PathBuf;

use anyhow::{Context, Result};
use engine::camera::Pose;
use engine::measure::{Measurement, SnapKind, snap};
use engine::section::Section;
use engine::tree::{Look, Op};
use glam::Vec3;

use super::App;
use crate::viewpoint::Viewpoint;

/// A pick snaps to a corner or an edge this close on screen (pixels).
const SNAP_PX: f32 = 8.0;

/// Measuring: on or off (M), the first point of a measurement under way,
/// and the last measurement.
#[derive(Debug, Default)]
pub(super) struct Measuring {
    pub on: bool,
    first: Option<(Vec3, SnapKind)>,
    pub last: Option<Measurement>,
    /// `--measure` done.
    pub cli_done: bool,
}

impl App {
    /// What follows a scene's opening: `--viewpoint`, `--isolate`, `--xray`
    /// and `--hide`, then `--find`.
    pub(super) fn after_open(&mut self) {
        self.walking = None;
        // The last scene's search results name its objects.
        self.ui.tree = Default::default();
        self.apply_viewpoint();
        self.tree_cli();
        if let Some(t) = self.args.find.clone() {
            self.find(&t);
        }
        if self.args.walk {
            self.toggle_walk();
        }
    }

    /// Finds the elements whose name, mesh name or `extras` (IFC type,
    /// GlobalId) hold `text`, selects the first and flies to it (frames
    /// its box beside the panel).
    pub(super) fn find(&mut self, text: &str) {
        let Some(sess) = &mut self.session else {
            return;
        };
        let origin = sess.origin;
        let found = match sess.picker() {
            Ok(p) => p.find(text, origin),
            Err(e) => {
                self.report(format!("find: {e:#}"));
                return;
            }
        };
        let Some(first) = found.first().cloned() else {
            self.report(format!("find {text:?}: no element matches"));
            return;
        };
        self.fly_to(first.scene_min, first.scene_max);
        println!(
            "find {text:?}: {} element(s); selected {} and flew to it",
            found.len(),
            first.name
        );
        self.ui.tree.reveal = first.object;
        self.selection = Some(first);
    }

    /// `M`: clicks measure instead of selecting (and back).
    pub(super) fn toggle_measuring(&mut self) {
        let m = &mut self.measuring;
        m.on = !m.on;
        m.first = None;
        self.ui_dirty = true;
    }

    /// A click at pixel `(x, y)`: a measured point while measuring, else
    /// a selection.
    pub(super) fn click_at(&mut self, pose: &Pose, x: f32, y: f32) {
        if self.measuring.on {
            self.measure_at(pose, x, y);
        } else {
            self.pick_at(pose, x, y);
        }
    }

    /// Picks the point under `(x, y)`, snapped to the hit triangle's corner
    /// or edge within [`SNAP_PX`]; the second point of a pair ends a
    /// measurement, printed with its distance in metres.
    pub(super) fn measure_at(&mut self, pose: &Pose, x: f32, y: f32) {
        let Some(s) = &mut self.session else { return };
        let cfg = *s.renderer.config();
        let origin = s.origin;
        let world = |p: Vec3| {
            let d = p.as_dvec3();
            [d.x + origin[0], d.y + origin[1], d.z + origin[2]]
        };
        match s.pick(pose, x, y) {
            Ok(Some(sel)) => {
                let size = (cfg.width, cfg.height);
                let (p, kind) = snap(pose, size, (x, y), sel.scene_point, sel.corners, SNAP_PX);
                match self.measuring.first.take() {
                    None => {
                        println!(
                            "measure: from {:?} ({}) on {}",
                            world(p),
                            kind.name(),
                            sel.name
                        );
                        self.measuring.first = Some((p, kind));
                        self.measuring.last = None;
                    }
                    Some((a, ka)) => {
                        let m = Measurement {
                            a,
                            b: p,
                            snapped: [ka, kind],
                        };
                        println!(
                            "measured {:.3} m from {:?} ({}) to {:?} ({}) on {}",
                            m.distance(),
                            world(a),
                            ka.name(),
                            world(p),
                            kind.name(),
                            sel.name
                        );
                        self.measuring.last = Some(m);
                    }
                }
            }
            Ok(None) => println!("measure at {x},{y}: nothing there"),
            Err(e) => self.report(format!("measure: {e:#}")),
        }
        self.ui_dirty = true;
    }

    /// Applies `--viewpoint` to the scene just opened: its camera and its
    /// clipping planes (with those given on the command line). A viewpoint that cannot be read ends the run with
    /// an error that names it.
    pub(super) fn apply_viewpoint(&mut self) {
        let (Some(path), Some(sess)) = (self.args.viewpoint.clone(), &mut self.session) else {
            return;
        };
        let read = read_text(&path)
            .and_then(|xml| Viewpoint::parse(&xml, sess.origin))
            .with_context(|| format!("--viewpoint {}", path.display()));
        // The viewpoint's planes, and those of --section / --section-box.
        let cli = sess.settings.params.section;
        let read = read.and_then(|v| {
            let mut planes = v.section.as_location_direction();
            planes.extend(cli.as_location_direction());
            let section = Section::from_planes(&planes)
                .context("its clipping planes with --section / --section-box")?;
            Ok(Viewpoint { section, ..v })
        });
        let v = match read {
            Ok(v) => v,
            Err(e) => {
                let msg = format!("{e:#}");
                self.open_failed = Some(msg.clone());
                self.report(msg);
                return;
            }
        };
        sess.set_section(v.section);
        self.settings = sess.settings;
        self.controls.set_pose(&v.pose);
        self.play = None;
        println!(
            "{}: camera and {} clipping plane(s) applied; {} component(s) selected",
            path.display(),
            v.section.planes().len(),
            v.selected.len()
        );
        // The first selected component, selected (the camera stays).
        if let Some(id) = v.selected.first() {
            let origin = sess.origin;
            let found = sess.picker().map(|p| {
                p.find(id, origin)
                    .into_iter()
                    .find(|s| s.object.and_then(|k| p.global_id(k)).as_deref() == Some(id))
            });
            match found {
                Ok(Some(sel)) => {
                    println!("{}: selected {}", path.display(), sel.name);
                    self.selection = Some(sel);
                }
                Ok(None) => tracing::warn!(
                    "{}: the selected component {id} is not in the scene",
                    path.display()
                ),
                Err(e) => tracing::warn!("{}: {e:#}", path.display()),
            }
        }
        if !v.default_visible || !v.exceptions.is_empty() {
            let shown = |id: &Option<String>| {
                let listed = id.as_ref().is_some_and(|g| v.exceptions.contains(g));
                listed != v.default_visible
            };
            let done = sess.picker().map(|p| {
                let ids: Vec<Option<String>> = (0..p.objects().len() as u32)
                    .map(|k| p.global_id(k))
                    .collect();
                let found = v
                    .exceptions
                    .iter()
                    .filter(|g| ids.iter().any(|i| i.as_ref() == Some(g)))
                    .count();
                let looks = ids
                    .iter()
                    .map(|i| if shown(i) { Look::Shown } else { Look::Hidden });
                (looks.collect::<Vec<Look>>(), found)
            });
            match done.and_then(|(looks, found)| Ok((sess.set_looks(looks)?.0, found))) {
                Ok((n, found)) => println!(
                    "{}: {n} element(s) hidden ({} of its {} listed component(s) found in the scene)",
                    path.display(),
                    found,
                    v.exceptions.len()
                ),
                Err(e) => self.report(format!("--viewpoint {}: {e:#}", path.display())),
            }
        }
    }

    /// `H` hides the selected element, `I` isolates it (hides every other
    /// one), `X` x-rays it, `U` shows everything again.
    pub(super) fn hide_key(&mut self, key: char) {
        let selected = self.selection.as_ref().and_then(|s| s.object);
        let op = match (key, selected) {
            ('u', _) => None,
            ('h', Some(k)) => Some((Op::Hide, k)),
            ('i', Some(k)) => Some((Op::Isolate, k)),
            ('x', Some(k)) => Some((Op::XRay, k)),
            _ => {
                self.report(
                    "H hides, I isolates and X x-rays the selected element: select one first"
                        .into(),
                );
                return;
            }
        };
        match op {
            Some((op, k)) => self.apply_op(op, &[k], "the selected element"),
            None => self.set_looks(Vec::new()),
        }
        if key == 'h' || key == 'x' {
            self.selection = None;
        }
    }

    /// The view as a BCF viewpoint, written to `to` (or to the next
    /// `hlod-view-N.bcfv`).
    pub(super) fn save_viewpoint(&mut self, to: Option<PathBuf>) -> Result<()> {
        let Some(sess) = &mut self.session else {
            anyhow::bail!("no scene is open");
        };
        let to = to.unwrap_or_else(|| PathBuf::from(format!("hlod-view-{:06}.bcfv", self.frames)));
        // Hidden elements: listed as exceptions to a visible default, or
        // the shown ones to a hidden default when most are hidden.
        let hidden: Vec<bool> = sess.looks().iter().map(|l| *l == Look::Hidden).collect();
        let n_hidden = hidden.iter().filter(|h| **h).count();
        let default_visible = 2 * n_hidden <= hidden.len();
        let exceptions = if n_hidden == 0 {
            Vec::new()
        } else {
            let p = sess.picker()?;
            (0..hidden.len() as u32)
                .filter(|&k| hidden[k as usize] == default_visible)
                .filter_map(|k| p.global_id(k))
                .collect()
        };
        let v = Viewpoint {
            pose: self.frozen.unwrap_or_else(|| self.controls.pose()),
            section: sess.settings.params.section,
            selected: match self.selection.as_ref().and_then(|s| s.object) {
                Some(k) => sess.picker()?.global_id(k).into_iter().collect(),
                None => Vec::new(),
            },
            default_visible,
            exceptions,
        };
        engine_cli::outfile::write_bytes(&to, v.to_xml(sess.origin).as_bytes())
            .with_context(|| format!("cannot write {}", to.display()))?;
        println!("viewpoint saved to {}", to.display());
        Ok(())
    }

    /// `C`: a horizontal cut at the eye's height (at the model's mid-height
    /// when the eye is above or below it), removing what lies above; again:
    /// no cut.
    pub(super) fn toggle_cut(&mut self) {
        let Some(sess) = &mut self.session else {
            return;
        };
        let section = if sess.settings.params.section.is_empty() {
            let (min, max) = sess.bounds();
            let eye = self.controls.pose().position;
            let y = if eye.y > min.y && eye.y < max.y {
                eye.y
            } else {
                0.5 * (min.y + max.y)
            };
            Section::from_planes(&[(Vec3::new(eye.x, y, eye.z), Vec3::Y)]).unwrap_or_default()
        } else {
            Section::NONE
        };
        sess.set_section(section);
        self.settings = sess.settings;
    }

    /// `B`: a section box around the selected element (half a metre
    /// around its box); again: no section.
    pub(super) fn toggle_box(&mut self) {
        let Some(sess) = &mut self.session else {
            return;
        };
        let section = match (&self.selection, sess.settings.params.section.is_empty()) {
            (Some(sel), true) => Section::boxed(sel.scene_min, sel.scene_max)
                .or_else(|_| Section::boxed(sel.scene_min - 0.01, sel.scene_max + 0.01))
                .map(|b| b.grown(0.5))
                .unwrap_or_default(),
            (None, true) => {
                self.report("B boxes the selected element: select one first (left click)".into());
                return;
            }
            (_, false) => Section::NONE,
        };
        sess.set_section(section);
        self.settings = sess.settings;
    }

    /// `]` and `[`: every section plane a quarter metre outwards (keeping
    /// more) or inwards.
    pub(super) fn move_section(&mut self, by: f32) {
        if let Some(sess) = &mut self.session {
            let s = sess.settings.params.section;
            if !s.is_empty() {
                sess.set_section(s.grown(by));
                self.settings = sess.settings;
            }
        }
    }
}

/// A viewpoint file's text (at most 16 MiB: viewpoints are a few KiB).
fn read_text(path: &std::path::Path) -> Result<String> {
    use std::io::Read as _;
    let f = engine::infile::open(path)?;
    let mut s = String::new();
    f.take(16 << 20)
        .read_to_string(&mut s)
        .context("not UTF-8 text")?;
    Ok(s)
}

/// What the overlay marks in the view from `pose`, in pixels: the
/// selection's box edges, and the last measurement (or the first point of
/// one under way) with its label. Taken field by field, so that it can be
/// called while the window is borrowed.
pub(super) fn overlay_marks(
    selection: Option<&crate::picking::Selection>,
    session: Option<&crate::session::Session>,
    measuring: &Measuring,
    pose: &Pose,
) -> (Vec<[(f32, f32); 2]>, Option<crate::ui::MeasureMark>) {
    let Some(s) = session else {
        return (Vec::new(), None);
    };
    let c = s.renderer.config();
    let edges = selection.map_or_else(Vec::new, |sel| {
        crate::picking::box_edges(pose, (c.width, c.height), sel.scene_min, sel.scene_max)
    });
    let px = |p: Vec3| pose.project(c.width, c.height, p).map(|(x, y, _)| (x, y));
    let mark = match (&measuring.last, measuring.first) {
        (Some(m), _) => px(m.a)
            .zip(px(m.b))
            .map(|(from, to)| crate::ui::MeasureMark {
                from,
                to,
                label: format!("{:.3} m", m.distance()),
            }),
        (None, Some((a, _))) => px(a).map(|p| crate::ui::MeasureMark {
            from: p,
            to: p,
            label: "click the second point".into(),
        }),
        (None, None) => None,
    };
    (edges, mark)
}
