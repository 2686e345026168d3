//! Per frame, after drawing: whether the view is complete (and the first
//! complete frame), `--pick` and clicks, screenshots, and the `--csv` streams.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use engine::camera::{Pose, format_path};
use engine_cli::report::CsvStream;

use super::App;

/// At most this many frames, and this long, a screenshot waits for the
/// overlay to settle (egui's fades run on the wall clock, so a run of fast
/// frames alone is not enough).
const MAX_SHOT_WAITS: u32 = 120;
const MAX_SHOT_WAIT: Duration = Duration::from_secs(2);

/// Screenshots asked for (F12, the button, `--screenshot`) and how long the
/// pending one has waited.
#[derive(Default)]
pub(super) struct Shots {
    pub pending: Option<PathBuf>,
    waits: u32,
    since: Option<Instant>,
    /// Whether `--screenshot` has been taken (for `--exit-when-complete`).
    pub exit_taken: bool,
}

impl Shots {
    /// Whether a run that is done may exit now: once `--screenshot`
    /// (`exit_shot`), if asked for, has been taken; until then it is queued.
    pub fn ready_to_exit(&mut self, exit_shot: Option<&PathBuf>) -> bool {
        match exit_shot {
            Some(p) if !self.exit_taken => {
                if self.pending.is_none() {
                    self.pending = Some(p.clone());
                }
                false
            }
            _ => true,
        }
    }

    /// The screenshot to take this frame, if one is due: `--screenshot` on
    /// exit, or one asked for earlier. It waits until the overlay has
    /// settled (`ui_dirty` clear): a new window is invisible in its first
    /// pass and fades in over the next, and egui asks for another pass at
    /// once until then.
    pub fn due(
        &mut self,
        now: Instant,
        exiting: bool,
        ui_dirty: bool,
        exit_shot: Option<&PathBuf>,
    ) -> Option<PathBuf> {
        if exiting
            && !self.exit_taken
            && let Some(p) = exit_shot
        {
            self.pending = Some(p.clone());
        }
        self.pending.as_ref()?;
        if !exiting
            && ui_dirty
            && self.waits < MAX_SHOT_WAITS
            && now.duration_since(*self.since.get_or_insert(now)) < MAX_SHOT_WAIT
        {
            self.waits += 1;
            return None;
        }
        let to = self.pending.take()?;
        self.waits = 0;
        self.since = None;
        if exit_shot == Some(&to) {
            self.exit_taken = true;
        }
        Some(to)
    }
}

impl App {
    pub(super) fn toggle_record(&mut self) {
        match self.recording.take() {
            None => self.recording = Some(Vec::new()),
            Some(poses) => self.save_recording(&poses),
        }
    }

    pub(super) fn save_recording(&mut self, poses: &[Pose]) {
        let to = self
            .args
            .record
            .clone()
            .unwrap_or_else(|| PathBuf::from("hlod-view-path.txt"));
        match engine_cli::outfile::write_bytes(&to, format_path(poses).as_bytes()) {
            Ok(()) => tracing::info!("recorded {} poses to {}", poses.len(), to.display()),
            Err(e) => self.report(format!("cannot write {}: {e}", to.display())),
        }
    }

    /// Tracks completeness, the first complete frame and `--pick`.
    pub(super) fn after_frame(&mut self, m: &engine::metrics::FrameMetrics, pose: &Pose) {
        let loading = m.loader.late_reps + m.vdt_misses;
        let complete = m.substituted == 0 && loading == 0 && m.loader.read_errors == 0;
        if self.complete != Some((complete, loading)) {
            self.ui_dirty = true;
        }
        self.complete = Some((complete, loading));
        if complete && self.complete_at.is_none() {
            self.complete_at = Some(self.frames);
            println!(
                "first complete frame: frame {} at {:.2} s after start",
                self.frames,
                self.started.elapsed().as_secs_f64()
            );
        }
        if complete
            && !self.picked
            && let Some((x, y)) = self.args.pick
        {
            self.picked = true;
            self.pick_at(pose, x, y);
        }
        if complete
            && !self.measuring.cli_done
            && let Some([x0, y0, x1, y1]) = self.args.measure
        {
            self.measuring.cli_done = true;
            self.measure_at(pose, x0, y0);
            self.measure_at(pose, x1, y1);
        }
        if self.selection.is_some() && self.highlight_pose != Some(*pose) {
            // The highlight follows the camera (repainted only when it moved).
            self.highlight_pose = Some(*pose);
            self.ui_dirty = true;
        }
    }

    /// Selects the element under pixel `(x, y)`, and prints it.
    pub(super) fn pick_at(&mut self, pose: &Pose, x: f32, y: f32) {
        let Some(s) = &mut self.session else { return };
        match s.pick(pose, x, y) {
            Ok(Some(sel)) => {
                let (o, d) = pose.ray(s.renderer.config().width, s.renderer.config().height, x, y);
                println!(
                    "picked at {x},{y}: {} (mesh {}, object {:?}, node {}); extras {}; world box {:?} .. {:?}; ray {:?} {:?}",
                    sel.name,
                    sel.mesh_name.as_deref().unwrap_or("-"),
                    sel.object,
                    sel.node,
                    sel.extras.as_deref().unwrap_or("-"),
                    sel.world_min,
                    sel.world_max,
                    o.to_array(),
                    d.to_array()
                );
                self.ui.tree.reveal = sel.object;
                self.selection = Some(sel);
            }
            Ok(None) => {
                println!("picked at {x},{y}: nothing");
                self.selection = None;
            }
            Err(e) => self.report(format!("pick: {e:#}")),
        }
        self.ui_dirty = true;
    }

    /// Streams one frame to `--csv` and its `-loop.csv` (opened at the
    /// first frame).
    pub(super) fn log_frame(
        &mut self,
        m: &engine::metrics::FrameMetrics,
        loop_ms: f64,
    ) -> Result<()> {
        let Some(csv) = &self.args.csv else {
            return Ok(());
        };
        if self.run_csv.is_none() {
            let named = || csv.display().to_string();
            let loop_path = PathBuf::from(format!("{}-loop.csv", csv.with_extension("").display()));
            self.run_csv = Some(CsvStream::create(csv).with_context(named)?);
            self.loop_csv =
                Some(CsvStream::with_header(&loop_path, "frame,loop_ms").with_context(named)?);
        }
        if let (Some(c), Some(l)) = (&mut self.run_csv, &mut self.loop_csv) {
            c.push(m)?;
            l.line(&format!("{},{loop_ms:.3}", m.frame))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_screenshot_waits_for_the_overlay_but_not_forever() {
        let t0 = Instant::now();
        let mut s = Shots {
            pending: Some("a.png".into()),
            ..Shots::default()
        };
        // The overlay is still fading in: it waits, however fast the frames.
        for i in 0..10 {
            assert_eq!(
                s.due(t0 + Duration::from_millis(i), false, true, None),
                None
            );
        }
        // Settled: taken once.
        assert_eq!(s.due(t0, false, false, None), Some("a.png".into()));
        assert_eq!(s.due(t0, false, false, None), None);
        // An overlay that never settles delays it by two seconds at most.
        s.pending = Some("b.png".into());
        assert_eq!(s.due(t0, false, true, None), None);
        let late = t0 + MAX_SHOT_WAIT;
        assert_eq!(s.due(late, false, true, None), Some("b.png".into()));
        // On exit `--screenshot` is taken at once, and only once.
        let exit: PathBuf = "exit.png".into();
        assert_eq!(s.due(t0, true, true, Some(&exit)), Some(exit.clone()));
        assert!(s.exit_taken);
        assert_eq!(s.due(t0, true, true, Some(&exit)), None);
        // A finished run queues `--screenshot` and exits once it is taken.
        let mut s = Shots::default();
        assert!(!s.ready_to_exit(Some(&exit)));
        assert_eq!(s.pending, Some(exit.clone()));
        assert_eq!(s.due(t0, false, false, Some(&exit)), Some(exit.clone()));
        assert!(s.ready_to_exit(Some(&exit)));
        assert!(Shots::default().ready_to_exit(None));
    }
}
