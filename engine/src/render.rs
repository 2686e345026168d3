//! The renderer interface P_R draws through, and the `none` renderer used for
//! I/O and footprint experiments.
//!
//! A renderer receives every rep of the frame as P_R gets it (resident reps
//! first, then each missing one as P_I hands it over). The `none` renderer
//! rasterises nothing; it can charge a modelled cost per triangle so that
//! rendering takes time and overlaps with loading as on a real GPU.

use std::sync::Arc;
use std::time::Duration;

use crate::camera::View;
use crate::clock::{Clock, SystemClock};
use crate::format::RepRecord;
use crate::skeleton::RepId;

/// What P_R draws through.
pub trait Renderer {
    /// Starts a frame.
    fn begin_frame(&mut self, view: &View);
    /// Draws one rep (its payload as P_I holds it), as `style` says: a
    /// substitute for a missing front rep, or fading in or out (a rep
    /// drawn fading out may be drawn again opaque in the same frame).
    fn draw(&mut self, rep: RepId, record: &RepRecord, payload: &Arc<[u8]>, style: DrawStyle);
    /// P_I evicted `rep`: drop any copy of it (GPU memory follows the budget).
    fn evict(&mut self, _rep: RepId) {}
    /// From now on draw these reps as `parts` says (x-rayed elements
    /// translucent, merged leaves with hidden elements in part:
    /// [`crate::hide::Hiding::parts`]), every other one whole and opaque.
    fn set_parts(&mut self, _parts: &crate::hide::DrawParts) {}
    /// Finishes the frame (presents, or waits for the GPU).
    fn end_frame(&mut self);
    /// Rep geometry bytes held on the GPU.
    fn gpu_bytes(&self) -> u64 {
        0
    }
    /// Short name for reports.
    fn name(&self) -> &'static str;
}

/// A screen-door fade (see [`crate::fade`]): of a 4×4 ordered-dither
/// pattern, a rep fading in by `t` covers the pixels whose threshold is
/// below `t`, a rep fading out by `t` exactly the others, so the two reps
/// of a switch together cover every pixel once.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Fade {
    #[default]
    Opaque,
    In(f32),
    Out(f32),
}

impl Fade {
    /// Whether the pixel of dither threshold `threshold` (in (0, 1)) is
    /// drawn: the CPU statement of the shader's test.
    pub fn covers(self, threshold: f32) -> bool {
        match self {
            Fade::Opaque => true,
            Fade::In(t) => threshold < t,
            Fade::Out(t) => threshold >= t,
        }
    }
}

/// The 4×4 ordered-dither (Bayer) threshold of pixel `(x, y)`, in (0, 1):
/// the shader's `dither_threshold`.
pub fn dither_threshold(x: u32, y: u32) -> f32 {
    const BAYER: [u32; 16] = [0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5];
    (BAYER[((y & 3) * 4 + (x & 3)) as usize] as f32 + 0.5) / 16.0
}

/// How one rep is drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DrawStyle {
    /// It stands in for a missing front rep (an ancestor).
    pub substitute: bool,
    pub fade: Fade,
    /// Where a shared payload is placed: the payload is its `source` rep's
    /// (a renderer keeps one copy of it, under that id, for every rep
    /// that places it; P_I's evictions name it), drawn with `transform`.
    pub placement: Option<crate::records::RepPlacement>,
}

impl DrawStyle {
    /// Opaque; a substitute when `substitute`.
    pub fn opaque(substitute: bool) -> Self {
        Self {
            substitute,
            fade: Fade::Opaque,
            placement: None,
        }
    }

    /// The id under which the payload drawn as `rep` is held.
    pub fn payload_rep(&self, rep: RepId) -> RepId {
        self.placement.map_or(rep, |p| p.source)
    }
}

/// Draws nothing; optionally takes `1 / tris_per_sec` seconds per triangle
/// on its clock (slept on the system's, advanced on a manual one).
#[derive(Debug)]
pub struct NoneRenderer {
    tris_per_sec: f64,
    debt: Duration,
    frame_tris: u64,
    clock: Arc<dyn Clock>,
}

impl Default for NoneRenderer {
    fn default() -> Self {
        Self::new(0.0)
    }
}

impl NoneRenderer {
    /// A renderer of modelled speed (`0` = free) on the system's clock.
    pub fn new(tris_per_sec: f64) -> Self {
        Self::with_clock(tris_per_sec, Arc::new(SystemClock))
    }

    /// A renderer of modelled speed on `clock` (the walk's, for a walk on
    /// a manual clock: [`crate::runtime::Walkthrough::clock`]).
    pub fn with_clock(tris_per_sec: f64, clock: Arc<dyn Clock>) -> Self {
        Self {
            tris_per_sec: tris_per_sec.max(0.0),
            debt: Duration::ZERO,
            frame_tris: 0,
            clock,
        }
    }

    fn pay(&mut self, threshold: Duration) {
        if self.debt >= threshold {
            let t = self.clock.now();
            self.clock.sleep(self.debt);
            self.debt = self
                .debt
                .saturating_sub(self.clock.now().saturating_duration_since(t));
        }
    }
}

impl Renderer for NoneRenderer {
    fn begin_frame(&mut self, _view: &View) {
        self.frame_tris = 0;
        self.debt = Duration::ZERO;
    }

    fn draw(&mut self, _rep: RepId, record: &RepRecord, _payload: &Arc<[u8]>, _style: DrawStyle) {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fade_in_and_its_fade_out_cover_every_pixel_once() {
        let mut seen = [false; 16];
        for y in 0..4 {
            for x in 0..4 {
                let t = dither_threshold(x, y);
                let k = (t * 16.0 - 0.5).round() as usize;
                assert!(!seen[k], "threshold {t} twice");
                seen[k] = true;
                // The pattern repeats every four pixels.
                assert_eq!(t, dither_threshold(x + 4, y + 8));
            }
        }
        for step in 0..=16 {
            let t = step as f32 / 16.0;
            let mut covered_in = 0;
            for y in 0..4 {
                for x in 0..4 {
                    let th = dither_threshold(x, y);
                    assert_ne!(Fade::In(t).covers(th), Fade::Out(t).covers(th));
                    covered_in += usize::from(Fade::In(t).covers(th));
                }
            }
            // A fade in by t covers t of the pixels.
            assert_eq!(covered_in, step);
        }
        assert!(Fade::Opaque.covers(0.99));
    }
}
