//! Per frame, after drawing: whether the view is complete (and the first
//! complete frame), `--pick` and clicks, and the `--csv` streams.

use std::path::PathBuf;

use anyhow::{Context, Result};
use engine::camera::Pose;
use engine::metrics::CsvStream;

use super::App;

impl App {
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
