//! The renderer interface P_R draws through, and the `none` renderer used for
//! I/O and footprint experiments.
//!
//! A renderer receives every rep of the frame as P_R gets it (resident reps
//! first, then each missing one as P_I hands it over). The `none` renderer
//! rasterises nothing; it can charge a modelled cost per triangle so that
//! rendering takes time and overlaps with loading as on a real GPU.

use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::camera::View;
use crate::format::RepRecord;
use crate::skeleton::RepId;

/// What P_R draws through.
pub trait Renderer {
    /// Starts a frame.
    fn begin_frame(&mut self, view: &View);
    /// Draws one rep (its raw payload as stored in the scene file);
    /// `substitute` when it stands in for a missing front rep.
    fn draw(&mut self, rep: RepId, record: &RepRecord, payload: &Arc<[u8]>, substitute: bool);
    /// P_I evicted `rep`: drop any copy of it (GPU memory follows the budget).
    fn evict(&mut self, _rep: RepId) {}
    /// Finishes the frame (presents, or waits for the GPU).
    fn end_frame(&mut self);
    /// Rep geometry bytes held on the GPU.
    fn gpu_bytes(&self) -> u64 {
        0
    }
    /// Short name for reports.
    fn name(&self) -> &'static str;
}

/// Draws nothing; optionally takes `1 / tris_per_sec` seconds per triangle.
#[derive(Debug, Default)]
pub struct NoneRenderer {
    tris_per_sec: f64,
    debt: Duration,
    frame_tris: u64,
}

impl NoneRenderer {
    /// A renderer of modelled speed (`0` = free).
    pub fn new(tris_per_sec: f64) -> Self {
        Self {
            tris_per_sec: tris_per_sec.max(0.0),
            ..Self::default()
        }
    }

    fn pay(&mut self, threshold: Duration) {
        if self.debt >= threshold {
            let t = Instant::now();
            std::thread::sleep(self.debt);
            self.debt = self.debt.saturating_sub(t.elapsed());
        }
    }
}

impl Renderer for NoneRenderer {
    fn begin_frame(&mut self, _view: &View) {
        self.frame_tris = 0;
        self.debt = Duration::ZERO;
    }

    fn draw(&mut self, _rep: RepId, record: &RepRecord, _payload: &Arc<[u8]>, _sub: bool) {
        self.frame_tris += u64::from(record.tri_count);
        if self.tris_per_sec > 0.0 {
            self.debt += crate::limits::duration_s(f64::from(record.tri_count) / self.tris_per_sec);
            self.pay(Duration::from_micros(500));
        }
    }

    fn end_frame(&mut self) {
        self.pay(Duration::ZERO);
        self.debt = Duration::ZERO;
    }

    fn name(&self) -> &'static str {
        "none"
    }
}
