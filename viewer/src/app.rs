//! The event loop: input → camera → frame → overlay → present.

use engine_cli::png::PngFile as _;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result, anyhow};
use engine::camera::{Pose, read_path};
use engine::disk::DiskModel;
use engine::runtime::{Mode, RuntimeParams};
use engine_cli::report::CsvStream;
use engine_gpu::Colouring;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

mod frame;
mod tree;
mod views;
mod walking;

use crate::Args;
use crate::build::Building;
use crate::controls::{Controls, Held};
use crate::gfx::Gfx;
use crate::session::{Session, Settings};
use crate::ui::{self, Sample, UiState};

/// Frames kept for the overlay's plots.
const HISTORY: usize = 300;

/// Runs the viewer until the window closes or `--exit-after` frames.
pub fn run(args: Args) -> Result<()> {
    for dir in &args.allow_dir {
        hlod_builder::import::allow_dir(dir)
            .with_context(|| format!("--allow-dir {}", dir.display()))?;
    }
    args.check_outputs()?;
    let settings = initial_settings(&args)?;
    let budget = engine_cli::BudgetArg::parse(&args.budget)?;
    let path = match &args.path {
        Some(p) => Some(read_path(p)?),
        None => None,
    };
    let event_loop = EventLoop::new().context("no display (set DISPLAY or run under Xvfb)")?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut app = App::new(args, (settings, budget), path);
    event_loop.run_app(&mut app)?;
    app.finish()
}

fn initial_settings(a: &Args) -> Result<Settings> {
    let mode = Mode::parse(&a.mode).map_err(anyhow::Error::msg)?;
    let colouring = Colouring::parse(&a.colouring).map_err(anyhow::Error::msg)?;
    let disk = match a.disk.as_str() {
        "file" => None,
        d => Some(DiskModel::parse(d).map_err(anyhow::Error::msg)?),
    };
    let params = RuntimeParams {
        mode,
        tolerance_px: a.tolerance,
        width_px: a.width,
        height_px: a.height,
        stall_deadline_s: a.stall_deadline / 1e3,
        fade_s: a.fade,
        section: a.cut.section()?,
        ..RuntimeParams::default()
    };
    params.check()?;
    Ok(Settings {
        mode,
        // Set from `--budget` when a scene opens.
        budget_bytes: 1,
        params,
        colouring,
        disk,
        occlusion: true,
    })
}

struct App {
    args: Args,
    settings: Settings,
    /// `--budget`, resolved for each scene opened.
    budget: engine_cli::BudgetArg,
    gfx: Option<Gfx>,
    session: Option<Session>,
    error: Option<String>,
    controls: Controls,
    held: Held,
    walking: Option<walking::Walking>,
    looking: bool,
    cursor: Option<(f64, f64)>,
    frozen: Option<Pose>,
    ui: UiState,
    history: VecDeque<Sample>,
    play: Option<(Vec<Pose>, usize)>,
    recording: Option<Vec<Pose>>,
    /// The run's per-frame CSV (`--csv`), written as the frames come, and
    /// the loop times beside it.
    run_csv: Option<CsvStream>,
    loop_csv: Option<CsvStream>,
    frames: u64,
    last: Instant,
    fatal: Option<anyhow::Error>,
    /// The last scene that failed to open, while no other has opened since:
    /// the exit status says so (a script cannot read the overlay).
    open_failed: Option<String>,
    /// When the overlay is next repainted (it is cached between).
    ui_due: Instant,
    ui_dirty: bool,
    /// A model being built into the cache before it opens.
    building: Option<Building>,
    /// The selected element and where the left button went down.
    selection: Option<crate::picking::Selection>,
    press: Option<(f64, f64)>,
    /// `--pick` done; when the first complete frame was seen.
    picked: bool,
    complete_at: Option<u64>,
    started: Instant,
    /// Whether the last frame was complete, and how many reps were still loading.
    complete: Option<(bool, u32)>,
    /// The frame at which a scene first failed to open.
    failed_at: Option<u64>,
    /// The pose the selection's highlight was last drawn for.
    highlight_pose: Option<Pose>,
    shots: frame::Shots,
    measuring: views::Measuring,
}

impl App {
    fn new(
        args: Args,
        (settings, budget): (Settings, engine_cli::BudgetArg),
        path: Option<Vec<Pose>>,
    ) -> Self {
        let recording = args.record.as_ref().map(|_| Vec::new());
        Self {
            ui: UiState {
                open_text: args
                    .scene
                    .as_ref()
                    .map(|p| p.display().to_string())
                    .unwrap_or_default(),
                path_text: args
                    .path
                    .as_ref()
                    .map(|p| p.display().to_string())
                    .unwrap_or_default(),
                find_text: args.find.clone().unwrap_or_default(),
                frozen: false,
                panel_frac: 0.0,
                tree_tab: args.tree,
                tree: Default::default(),
            },
            args,
            settings,
            budget,
            gfx: None,
            session: None,
            error: None,
            controls: Controls::new(glam::Vec3::splat(-1.0), glam::Vec3::splat(1.0)),
            held: Held::default(),
            walking: None,
            looking: false,
            cursor: None,
            frozen: None,
            history: VecDeque::new(),
            play: path.map(|p| (p, 0)),
            recording,
            run_csv: None,
            loop_csv: None,
            frames: 0,
            last: Instant::now(),
            fatal: None,
            open_failed: None,
            ui_due: Instant::now(),
            ui_dirty: true,
            building: None,
            selection: None,
            press: None,
            picked: false,
            complete_at: None,
            started: Instant::now(),
            complete: None,
            failed_at: None,
            highlight_pose: None,
            shots: frame::Shots::default(),
            measuring: views::Measuring::default(),
        }
    }

    fn report(&mut self, msg: String) {
        tracing::error!("{msg}");
        self.error = Some(msg);
        // Shown at once, not at the next scheduled repaint.
        self.ui_dirty = true;
    }

    /// Opens a scene file, or starts building a model into the cache (it
    /// opens when the build is done).
    fn open(&mut self, path: &Path) {
        if crate::build::is_model(path) {
            self.session = None;
            self.selection = None;
            self.error = None;
            self.building = Some(Building::start(path, self.args.cache.as_deref()));
            self.ui_dirty = true;
            return;
        }
        self.open_scene(path, None);
    }

    /// Opens a built model when its build has finished.
    fn poll_build(&mut self) {
        let Some(b) = &self.building else { return };
        if !b.finished() {
            return;
        }
        let b = self.building.take().expect("checked above");
        let input = b.input.clone();
        match b.join() {
            Ok((cached, secs)) => {
                for line in crate::build::opened_lines(&input, &cached, secs) {
                    println!("{line}");
                }
                self.open_scene(&cached.scene, Some(&input));
            }
            Err(e) => {
                let msg = format!("cannot open {}: {e}", input.display());
                self.open_failed = Some(msg.clone());
                self.report(msg);
            }
        }
    }

    /// Opens a scene file; `model` is the glTF it was built from, which
    /// errors name first.
    fn open_scene(&mut self, path: &Path, model: Option<&Path>) {
        let Some(gfx) = &self.gfx else { return };
        self.session = None;
        self.selection = None;
        let size = (gfx.config.width, gfx.config.height);
        let budget = Some(self.budget);
        let cache = self.args.disk_cache();
        let place = (size, gfx.config.format, cache.as_ref());
        match Session::open(path, &gfx.ctx, self.settings, budget, place) {
            Ok(sess) => {
                let (min, max) = sess.bounds();
                let aspect = size.0 as f32 / size.1.max(1) as f32;
                // Before the panel is first drawn: its default place and
                // width (8 + 340 points and its frame).
                let panel = match self.ui.panel_frac {
                    0.0 => 360.0 * gfx.window.scale_factor() as f32 / size.0.max(1) as f32,
                    f => f,
                };
                self.controls.frame_all_beside(min, max, aspect, panel);
                if let Some((p, _)) = &self.play
                    && let Some(first) = p.first()
                {
                    self.controls.set_pose(first);
                }
                self.settings = sess.settings;
                let need = sess.full_detail_need();
                self.session = Some(sess);
                self.error = None;
                self.open_failed = None;
                self.after_open();
                if let Some(need) = need.filter(|_| self.args.exit_when_complete) {
                    // Waiting for a complete view would never end.
                    let msg = format!(
                        "--exit-when-complete: the view cannot complete at this budget: \
                         drawing every rep as itself needs {need} B for the reps (the budget \
                         less the occluders' share); try --budget auto"
                    );
                    self.open_failed = Some(msg.clone());
                    self.report(msg);
                }
            }
            Err(e) => {
                let msg = match model {
                    Some(m) => format!(
                        "cannot open {} (built into {}): {e:#}",
                        m.display(),
                        path.display()
                    ),
                    None => format!("cannot open {}: {e:#}", path.display()),
                };
                self.open_failed = Some(msg.clone());
                self.report(msg);
            }
        }
    }

    fn key(&mut self, code: KeyCode, down: bool) {
        let h = &mut self.held;
        match code {
            KeyCode::KeyW | KeyCode::ArrowUp => h.forward = down,
            KeyCode::KeyS | KeyCode::ArrowDown => h.back = down,
            KeyCode::KeyA | KeyCode::ArrowLeft => h.left = down,
            KeyCode::KeyD | KeyCode::ArrowRight => h.right = down,
            KeyCode::KeyE | KeyCode::PageUp => h.up = down,
            KeyCode::KeyQ | KeyCode::PageDown => h.down = down,
            KeyCode::ShiftLeft | KeyCode::ShiftRight => h.run = down,
            _ if !down => {}
            KeyCode::Tab => self.controls.toggle_mode(),
            KeyCode::Home => self.frame_all(),
            KeyCode::KeyF => self.ui.frozen = !self.ui.frozen,
            KeyCode::KeyR => self.toggle_record(),
            KeyCode::F12 => self.shots.pending = Some(self.next_shot_name()),
            KeyCode::KeyC => self.toggle_cut(),
            KeyCode::KeyB => self.toggle_box(),
            KeyCode::KeyH => self.hide_key('h'),
            KeyCode::KeyI => self.hide_key('i'),
            KeyCode::KeyU => self.hide_key('u'),
            KeyCode::KeyX => self.hide_key('x'),
            KeyCode::KeyT => self.toggle_tree(),
            KeyCode::BracketRight | KeyCode::BracketLeft => {
                self.move_section(if code == KeyCode::BracketRight {
                    0.25
                } else {
                    -0.25
                });
            }
            KeyCode::KeyM => self.toggle_measuring(),
            KeyCode::KeyG => self.toggle_walk(),
            KeyCode::KeyO => self.toggle_doors(),
            KeyCode::KeyV => self
                .save_viewpoint(None)
                .unwrap_or_else(|e| self.report(format!("{e:#}"))),
            _ => {}
        }
    }

    fn frame_all(&mut self) {
        if let (Some(s), Some(gfx)) = (&self.session, &self.gfx) {
            let (min, max) = s.bounds();
            let aspect = gfx.config.width as f32 / gfx.config.height.max(1) as f32;
            self.controls
                .frame_all_beside(min, max, aspect, self.ui.panel_frac);
        }
    }

    fn next_shot_name(&self) -> PathBuf {
        PathBuf::from(format!("hlod-view-{:06}.png", self.frames))
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) {
        self.poll_build();
        self.ensure_tree();
        let now = Instant::now();
        let dt = (now - self.last).as_secs_f32();
        self.last = now;
        let pose = match &mut self.play {
            Some((poses, i)) if *i < poses.len() => {
                let p = poses[*i];
                *i += 1;
                p
            }
            _ => {
                if self.play.take().is_some() {
                    tracing::info!("path finished");
                }
                self.move_camera(dt);
                self.controls.pose()
            }
        };
        if let Some(r) = &mut self.recording {
            r.push(pose);
        }
        if self.ui.frozen && self.frozen.is_none() {
            self.frozen = Some(pose);
        } else if !self.ui.frozen {
            self.frozen = None;
        }
        let Some(gfx) = &mut self.gfx else { return };
        let Some(frame) = gfx.acquire() else { return };
        let mut metrics = None;
        // Draw offscreen and copy when the surface allows it (see `Gfx::copy_dst`).
        let offscreen = gfx.copy_dst
            && self.session.as_ref().is_some_and(|s| {
                let t = s.renderer.target_texture();
                (t.width(), t.height()) == (gfx.config.width, gfx.config.height)
            });
        let target = match (&self.session, offscreen) {
            (Some(s), true) => s.renderer.target_view().clone(),
            _ => frame.view.clone(),
        };
        match &mut self.session {
            Some(s) => {
                s.renderer
                    .set_output((!offscreen).then(|| frame.view.clone()));
                let front_pose = self.frozen.unwrap_or(pose);
                let res = s.frame(&front_pose, &pose);
                s.renderer.set_output(None);
                match res {
                    Ok(m) => metrics = Some(m),
                    Err(e) => {
                        gfx.clear(&target);
                        self.error = Some(format!("{e:#}"));
                    }
                }
            }
            None => gfx.clear(&target),
        }
        let mut actions = ui::Actions::default();
        if self.open_failed.is_some() && self.failed_at.is_none() {
            self.failed_at = Some(self.frames);
        }
        // A failure ends `--exit-when-complete` a few frames later, once its
        // panel has been painted.
        let mut exiting = self.args.exit_after.is_some_and(|n| self.frames + 1 >= n);
        if self.args.exit_when_complete && self.failed_at.is_some_and(|f| self.frames >= f + 3) {
            // The screenshot, when one is asked for, is taken first, once
            // the error panel has faded in.
            exiting |= self.shots.ready_to_exit(self.args.screenshot.as_ref());
        }
        let refresh =
            self.ui_dirty || now >= self.ui_due || exiting || self.shots.pending.is_some();
        if !self.args.no_overlay && refresh {
            self.ui_dirty = false;
            let hz = if self.args.overlay_hz > 0.0 {
                self.args.overlay_hz
            } else {
                2.0
            };
            self.ui_due = now + engine::limits::duration_s(1.0 / hz.min(1000.0));
            let raw = gfx.egui_state.take_egui_input(&gfx.window);
            let marks = views::overlay_marks(
                self.selection.as_ref(),
                self.session.as_ref(),
                &self.measuring,
                &pose,
            );
            let view = ui::View {
                scene: self.session.as_ref().and_then(|s| s.path.to_str()),
                building: self.building.as_ref().map(Building::status),
                selection: self.selection.as_ref(),
                highlight: marks.0,
                measure: marks.1,
                complete: self.complete,
                pixels_per_point: gfx.egui_ctx.pixels_per_point(),
                error: self.error.as_deref(),
                settings: self.session.as_ref().map(|s| s.settings),
                budget_bytes: self.session.as_ref().map_or(0, |s| s.budget_bytes()),
                data_bytes: self.session.as_ref().map_or(0, |s| s.data_bytes),
                recording: self.recording.as_ref().map(Vec::len),
                playing: self.play.as_ref().map(|(p, i)| (*i, p.len())),
                fly_speed: self.controls.speed,
                orbit: self.controls.mode == crate::controls::ControlMode::Orbit,
                walking: walking::status(self.walking.as_ref()),
                tree: tree::view(self.session.as_ref(), self.selection.as_ref(), &self.ui),
            };
            let (ui_state, hist) = (&mut self.ui, &self.history);
            let out = gfx
                .egui_ctx
                .run_pass(raw, |ctx| actions = ui::draw(ctx, ui_state, &view, hist));
            // egui asks for another pass at once when a new window is sized
            // (it is invisible in its first): give it one.
            if out
                .viewport_output
                .values()
                .any(|v| v.repaint_delay.is_zero())
            {
                self.ui_dirty = true;
            }
            gfx.paint_egui(out);
        }
        if !self.args.no_overlay {
            gfx.composite(&target);
        }
        if offscreen && let Some(s) = &self.session {
            gfx.blit(s.renderer.target_texture(), &frame.texture.texture);
        }
        let mut problems: Vec<String> = Vec::new();
        let ui_dirty = self.ui_dirty && !self.args.no_overlay;
        if let Some(to) = self
            .shots
            .due(now, exiting, ui_dirty, self.args.screenshot.as_ref())
        {
            let img = match &self.session {
                Some(s) if offscreen => s.renderer.read_texture(s.renderer.target_texture()),
                _ if gfx.copy_src => engine_gpu::read_texture(&gfx.ctx, &frame.texture.texture),
                _ => None,
            };
            match img {
                Some(img) => match img.save_png(&to) {
                    Ok(()) => println!("screenshot: {}", to.display()),
                    Err(e) => problems.push(e.to_string()),
                },
                None => problems.push("this surface cannot be read back for a screenshot".into()),
            }
        }
        gfx.ctx.queue.present(frame.texture);
        for e in gfx.ctx.take_errors() {
            problems.push(format!("GPU: {e}"));
        }
        for p in problems {
            self.report(p);
        }
        let loop_ms = now.elapsed().as_secs_f64() * 1e3;
        if let Some(m) = &metrics {
            self.after_frame(m, &pose);
            if self.args.exit_when_complete
                && self.complete_at.is_some_and(|f| self.frames > f)
                && (self.args.pick.is_none() || self.picked)
            {
                // Once more, so that the screenshot shows the pick.
                exiting |= self.shots.ready_to_exit(self.args.screenshot.as_ref());
            }
        }
        if let Some(m) = metrics {
            if let Err(e) = self.log_frame(&m, loop_ms) {
                self.fatal = Some(e);
                exiting = true;
            }
            self.history.push_back(Sample { loop_ms, m });
            if self.history.len() > HISTORY {
                self.history.pop_front();
            }
        }
        self.frames += 1;
        self.apply(actions);
        if exiting {
            event_loop.exit();
        }
    }

    fn finish(mut self) -> Result<()> {
        if let Some(poses) = self.recording.take() {
            self.save_recording(&poses);
        }
        if let Some(to) = self.args.save_viewpoint.clone() {
            self.save_viewpoint(Some(to)).context("--save-viewpoint")?;
        }
        if let Some(csv) = self.run_csv.take() {
            csv.finish().context("--csv")?;
        }
        if let Some(csv) = self.loop_csv.take() {
            csv.finish().context("--csv")?;
        }
        // Drop the walkthrough (joins P_I) before the window goes.
        self.session = None;
        match (self.fatal.take(), self.open_failed.take()) {
            (Some(e), _) => Err(e),
            (None, Some(msg)) => Err(anyhow!(msg)),
            (None, None) => Ok(()),
        }
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        let attrs = Window::default_attributes()
            .with_title("hlod-view")
            .with_inner_size(winit::dpi::PhysicalSize::new(
                self.args.width,
                self.args.height,
            ));
        let gfx = event_loop
            .create_window(attrs)
            .map_err(|e| anyhow!("cannot create a window: {e}"))
            .and_then(|w| Gfx::new(Arc::new(w), self.args.vsync));
        match gfx {
            Ok(g) => {
                tracing::info!("GPU adapter: {}", g.ctx.describe());
                self.gfx = Some(g);
                if let Some(p) = self.args.scene.clone() {
                    self.open(&p);
                }
            }
            Err(e) => {
                self.fatal = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let consumed = match &mut self.gfx {
            Some(g) if !self.args.no_overlay && !matches!(event, WindowEvent::RedrawRequested) => {
                let r = g.egui_state.on_window_event(&g.window, &event);
                self.ui_dirty |= r.repaint;
                r.consumed
            }
            _ => false,
        };
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                if let Some(g) = &mut self.gfx {
                    g.resize(size.width, size.height);
                }
                if let Some(s) = &mut self.session
                    && size.width > 0
                    && size.height > 0
                    && let Err(e) = s.resize(size.width, size.height)
                {
                    self.report(format!("{e:#}"));
                }
            }
            WindowEvent::RedrawRequested => self.redraw(event_loop),
            WindowEvent::KeyboardInput { event, .. } if !consumed => {
                if let PhysicalKey::Code(c) = event.physical_key {
                    self.key(c, event.state == ElementState::Pressed);
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Right,
                ..
            } => {
                self.looking = state == ElementState::Pressed && !consumed;
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } if !consumed => match state {
                ElementState::Pressed => self.press = self.cursor,
                ElementState::Released => {
                    // A click, not a drag: pick.
                    if let (Some(p), Some(c)) = (self.press.take(), self.cursor)
                        && (p.0 - c.0).abs() + (p.1 - c.1).abs() < 5.0
                    {
                        let pose = self.frozen.unwrap_or_else(|| self.controls.pose());
                        self.click_at(&pose, c.0 as f32, c.1 as f32);
                    }
                }
            },
            WindowEvent::CursorMoved { position, .. } => {
                let p = (position.x, position.y);
                if self.looking
                    && let Some(c) = self.cursor
                {
                    self.controls.look((p.0 - c.0) as f32, (p.1 - c.1) as f32);
                }
                self.cursor = Some(p);
            }
            WindowEvent::MouseWheel { delta, .. } if !consumed => {
                let steps = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => (p.y / 40.0) as f32,
                };
                self.controls.wheel(steps);
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        // While a model builds, ten frames a second show its progress and
        // leave the cores to the build.
        if self.building.is_some() {
            let next = self.last + std::time::Duration::from_millis(100);
            if Instant::now() < next {
                event_loop.set_control_flow(ControlFlow::WaitUntil(next));
                return;
            }
            self.ui_dirty = true;
        }
        event_loop.set_control_flow(ControlFlow::Poll);
        if let Some(g) = &self.gfx {
            g.window.request_redraw();
        }
    }
}
