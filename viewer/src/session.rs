//! A scene opened in the viewer: its skeleton, the running walkthrough
//! (P_R/P_I) and the wgpu renderer sized to the budget. Changing the mode,
//! budget, tolerance or prefetch parameters restarts the walkthrough; errors
//! are returned as text for the overlay, never panics.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, Result};

use engine::disk::DiskModel;
use engine::runtime::{Mode, RuntimeParams, Walkthrough};
use engine::tree::Look;
use engine::{SceneFile, Skeleton};
use engine_cli::SceneHandle;
use engine_gpu::{Colouring, GpuContext, GpuRenderer, RendererConfig};
use glam::Vec3;

/// What the user can change at run time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    pub mode: Mode,
    /// The footprint in bytes: `--budget` resolved when the scene opened,
    /// or what the panel's slider set.
    pub budget_bytes: u64,
    pub params: RuntimeParams,
    pub colouring: Colouring,
    pub disk: Option<DiskModel>,
    /// Occlusion culling, its occluder store a sixteenth of the budget.
    pub occlusion: bool,
}

/// An open scene with its walkthrough.
pub struct Session {
    pub path: PathBuf,
    /// The scene, held open: a walk restarted with new settings reads the
    /// same file even if its path was replaced meanwhile (a remote scene:
    /// the version pinned when it was opened).
    handle: SceneHandle,
    pub skeleton: Arc<Skeleton>,
    pub data_bytes: u64,
    walk: Option<Walkthrough>,
    pub renderer: GpuRenderer,
    pub settings: Settings,
    /// World position of the scene's origin (from its header).
    pub origin: [f64; 3],
    /// The scene file and its object section, opened at the first pick.
    picker: Option<crate::picking::Picker>,
    /// How each object is drawn (by object number; past the end: shown),
    /// and what that makes of the nodes.
    looks: Vec<Look>,
    hiding: Option<engine::hide::Hiding>,
    /// The model tree, made from the object section when first asked for.
    tree: Option<engine::tree::ModelTree>,
    /// Making it failed (said once).
    pub tree_failed: bool,
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session")
            .field("path", &self.path)
            .finish_non_exhaustive()
    }
}

impl Session {
    /// Opens `path` and starts the walkthrough; `Err` is a message to show.
    /// `budget` (bytes or a percentage, as on the command line) replaces the
    /// settings' fraction once the scene's size is known; the clip planes and
    /// viewport come from the scene's size and `size`.
    pub fn open(
        path: &Path,
        ctx: &GpuContext,
        mut settings: Settings,
        budget: Option<engine_cli::BudgetArg>,
        (size, color_format, cache): (
            (u32, u32),
            wgpu::TextureFormat,
            Option<&engine_cli::scene_handle::DiskCacheSpec>,
        ),
    ) -> Result<Self> {
        let named = || path.display().to_string();
        let handle = SceneHandle::open_cached(path, cache).with_context(named)?;
        let src = handle.raw().with_context(named)?;
        let scene = SceneFile::from_source(src).with_context(named)?;
        let skeleton = Arc::new(scene.skeleton().clone());
        let origin = scene.meta().origin;
        let data_bytes = skeleton.in_core_bytes();
        if let Some(b) = budget {
            settings.budget_bytes = b.bytes(&skeleton)?;
        }
        let root = &skeleton.nodes[0];
        let diag = (Vec3::from(root.bbox_max) - Vec3::from(root.bbox_min)).length();
        (settings.params.near, settings.params.far) = crate::controls::clip_planes(diag);
        (settings.params.width_px, settings.params.height_px) = size;
        let target = Target {
            path,
            handle: &handle,
            skel: &skeleton,
            data_bytes,
        };
        let (walk, renderer) = start(&target, ctx, &settings, size, color_format)?;
        Ok(Self {
            path: path.to_path_buf(),
            handle,
            skeleton,
            data_bytes,
            walk: Some(walk),
            renderer,
            settings,
            origin,
            picker: None,
            looks: Vec::new(),
            hiding: None,
            tree: None,
            tree_failed: false,
        })
    }

    /// The element under pixel `(x, y)` of the current view from `pose`.
    pub fn pick(
        &mut self,
        pose: &engine::camera::Pose,
        x: f32,
        y: f32,
    ) -> Result<Option<crate::picking::Selection>> {
        self.picker()?;
        let picker = self.picker.as_ref().expect("opened above");
        let cfg = *self.renderer.config();
        let cut = (self.origin, &self.settings.params.section, &self.looks[..]);
        picker.pick(pose, (cfg.width, cfg.height), x, y, cut)
    }

    /// The scene's walk section, read chunk by chunk (`None`: the file has
    /// none). Its index is in core; at most [`engine::walk::DEFAULT_CAP`]
    /// bytes of chunks are held besides.
    pub fn walk_map(&self) -> Result<Option<engine::walk::WalkMap<Arc<dyn engine::ByteSource>>>> {
        let named = || self.path.display().to_string();
        let src = self.handle.raw().with_context(named)?;
        engine::walk::WalkMap::open(src, engine::walk::DEFAULT_CAP).with_context(named)
    }

    /// The scene's object section and GlobalIds (opened once).
    pub fn picker(&mut self) -> Result<&crate::picking::Picker> {
        if self.picker.is_none() {
            let p = crate::picking::Picker::open(&self.path, &self.handle)?;
            self.picker = Some(p);
        }
        Ok(self.picker.as_ref().expect("opened above"))
    }

    /// The model tree (made once, from the object section).
    pub fn tree(&mut self) -> Result<&engine::tree::ModelTree> {
        if self.tree.is_none() {
            self.picker()?;
            let picker = self.picker.as_ref().expect("opened above");
            let table = picker.objects();
            let name = (self.path.file_name()).map_or("model".into(), |n| n.to_string_lossy());
            let t = std::time::Instant::now();
            let tree = engine::tree::ModelTree::new(table, &name, &picker.drawn());
            tracing::info!(
                "model tree: {} groups over {} elements, made in {:.1} ms",
                tree.groups().len(),
                table.len(),
                t.elapsed().as_secs_f64() * 1e3
            );
            self.tree = Some(tree);
        }
        Ok(self.tree.as_ref().expect("made above"))
    }

    /// The model tree, if made.
    pub fn tree_made(&self) -> Option<&engine::tree::ModelTree> {
        self.tree.as_ref()
    }

    /// The objects whose label, GlobalId or description holds `text`, in
    /// the tree's order; at most `limit`.
    pub fn search(&mut self, text: &str, limit: usize) -> Result<Vec<u32>> {
        self.tree()?;
        let (Some(tree), Some(p)) = (&self.tree, &self.picker) else {
            anyhow::bail!("no model tree");
        };
        Ok(tree.search(p.objects(), text, limit))
    }

    /// The objects `text` names: a tree group's by its name, else those
    /// whose description holds it; and what they are, for the log.
    pub fn resolve(&mut self, text: &str) -> Result<(Vec<u32>, String)> {
        let tree = self.tree()?;
        let groups = tree.groups_named(text);
        if let Some(&g) = groups.first() {
            let label = &tree.groups()[g as usize].label;
            let what = match groups.len() {
                1 => format!("group {label:?}"),
                n => format!("{n} groups {label:?}"),
            };
            return Ok((tree.objects_named(text), what));
        }
        Ok((self.search(text, usize::MAX)?, format!("{text:?}")))
    }

    /// Draws object `k` as `looks[k]` says (an empty list shows
    /// everything) from the next frame on: hidden objects leave the front
    /// and are not fetched, x-rayed ones are drawn translucent. Returns how
    /// many are hidden and how many x-rayed.
    pub fn set_looks(&mut self, looks: Vec<Look>) -> Result<(usize, usize)> {
        self.picker()?;
        let table = self.picker.as_ref().expect("opened above").objects();
        let h = engine::hide::Hiding::with_looks(&self.skeleton, table, |k| {
            looks.get(k as usize).copied().unwrap_or_default()
        });
        let n = (h.hidden_objects(), h.xray_objects());
        self.looks = looks;
        self.hiding = Some(h);
        self.apply_hiding();
        Ok(n)
    }

    /// How each object is drawn (empty: all shown).
    pub fn looks(&self) -> &[Look] {
        &self.looks
    }

    fn apply_hiding(&mut self) {
        if let (Some(h), Some(w)) = (&self.hiding, &mut self.walk) {
            w.set_hiding(h);
            engine::render::Renderer::set_parts(&mut self.renderer, h.parts());
        }
    }

    /// Cuts the model open (or not, with [`engine::section::Section::NONE`])
    /// from the next frame on; a restarted walk keeps the cut.
    pub fn set_section(&mut self, section: engine::section::Section) {
        self.settings.params.section = section;
        if let Some(w) = &mut self.walk {
            w.set_section(section);
        }
    }

    /// One frame: the front (and its loads) for `front_pose`, drawn from
    /// `draw_pose` into the renderer's output.
    pub fn frame(
        &mut self,
        front_pose: &engine::camera::Pose,
        draw_pose: &engine::camera::Pose,
    ) -> Result<engine::metrics::FrameMetrics> {
        let walk = self
            .walk
            .as_mut()
            .context("the walkthrough is not running (see the error above)")?;
        Ok(walk.frame_split(front_pose, draw_pose, &mut self.renderer)?)
    }

    /// `Some(bytes)` when not every rep can be drawn as itself under the
    /// footprint in force: the footprint that would take.
    pub fn full_detail_need(&self) -> Option<u64> {
        self.walk.as_ref().and_then(Walkthrough::full_detail_need)
    }

    /// The scene's bounds.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let r = &self.skeleton.nodes[0];
        (Vec3::from(r.bbox_min), Vec3::from(r.bbox_max))
    }

    /// The budget in bytes under the current settings.
    pub fn budget_bytes(&self) -> u64 {
        self.settings.budget_bytes
    }

    /// Applies new settings: a restart when the runtime's parameters change,
    /// just a new colouring otherwise.
    pub fn apply(&mut self, ctx: &GpuContext, s: Settings) -> Result<()> {
        if s == self.settings {
            return Ok(());
        }
        let restart = Settings {
            colouring: self.settings.colouring,
            ..s
        } != self.settings;
        self.renderer.set_colouring(s.colouring);
        self.settings = s;
        if restart {
            let cfg = *self.renderer.config();
            // The old P_I stops (and frees its reps) before the new one reads.
            self.walk = None;
            self.renderer.clear();
            let target = Target {
                path: &self.path,
                handle: &self.handle,
                skel: &self.skeleton,
                data_bytes: self.data_bytes,
            };
            let (walk, renderer) =
                start(&target, ctx, &s, (cfg.width, cfg.height), cfg.color_format)?;
            self.walk = Some(walk);
            self.renderer = renderer;
            self.apply_hiding();
        }
        Ok(())
    }

    /// Follows a window resize.
    pub fn resize(&mut self, width: u32, height: u32) -> Result<()> {
        self.renderer.resize(width, height)?;
        self.settings.params.width_px = width;
        self.settings.params.height_px = height;
        if let Some(w) = &mut self.walk {
            w.set_viewport(width, height)?;
        }
        Ok(())
    }
}

/// The occluders' store: a 16th of the budget, but not room that drawing
/// every rep as itself needs (`full_detail`), while the budget has it.
fn occluder_share(budget: u64, full_detail: u64) -> u64 {
    let share = budget / 16;
    if budget >= full_detail {
        share.min(budget - full_detail)
    } else {
        share
    }
}

/// The scene a walk reads: its file (held open), skeleton and data size.
struct Target<'a> {
    path: &'a Path,
    handle: &'a SceneHandle,
    skel: &'a Arc<Skeleton>,
    data_bytes: u64,
}

fn start_walk(t: &Target<'_>, s: &Settings) -> Result<Walkthrough> {
    let model = if s.mode == Mode::Incore { None } else { s.disk };
    // Over a network the network is the model: a disk model is for files.
    let model = model.filter(|_| !t.handle.is_remote());
    let source = t
        .handle
        .source(model)
        .with_context(|| t.path.display().to_string())?;
    let budget_bytes = s.budget_bytes;
    let params = RuntimeParams {
        mode: s.mode,
        budget_bytes,
        // Over a network: neighbouring reps by pages, one request each.
        page_bytes: if t.handle.is_remote() && s.params.page_bytes == 0 {
            engine::runtime::REMOTE_PAGE_BYTES
        } else {
            s.params.page_bytes
        },
        occlusion_bytes: if s.occlusion {
            occluder_share(budget_bytes, t.skel.full_detail_bytes())
        } else {
            0
        },
        ..s.params
    };
    Ok(Walkthrough::start(t.skel.clone(), source, params)?)
}

fn start(
    t: &Target<'_>,
    ctx: &GpuContext,
    s: &Settings,
    size: (u32, u32),
    color_format: wgpu::TextureFormat,
) -> Result<(Walkthrough, GpuRenderer)> {
    let walk = start_walk(t, s)?;
    let capacity = if s.mode == Mode::Incore {
        t.data_bytes
    } else {
        s.budget_bytes
    };
    let renderer = GpuRenderer::new(
        ctx.clone(),
        RendererConfig {
            width: size.0,
            height: size.1,
            capacity_bytes: capacity,
            colouring: s.colouring,
            color_format,
        },
    )?;
    Ok((walk, renderer))
}
