//! The quality governor: when the front at the tolerance ε does not fit
//! the footprint (or a triangle or frame-time target), the whole frame is drawn at the
//! smallest larger tolerance that fits, instead of substituting whatever
//! ancestors happen to be resident for the reps that cannot be loaded.
//!
//! The tolerance moves in steps of `step` (a factor). A frame whose front
//! does not fit goes coarser, step by step, until it fits. A frame whose
//! front fits tries one step finer, and takes it only when the finer front
//! fits with room to spare (`lower_share` of what fits): that band is the
//! hysteresis that keeps a still or slowly moving camera from switching
//! between two tolerances every frame. A still camera converges: after a
//! step finer the front still fits (it is within the band), so the next
//! frame does not go coarser again, and it goes finer only while the band
//! allows.
//!
//! A frame-time target becomes a triangle target: the governor is told each
//! frame's time, the part of it spent drawing and the triangles drawn
//! ([`Governor::observe_frame`]), keeps moving averages of the cost of a
//! triangle and of the rest of the frame, and allows the triangles that fit
//! the target after the rest.
//!
//! Plain policy: the caller measures a front for a tolerance and the
//! frames' times, the governor decides; no clock, no thread.

/// Parameters of [`Governor`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GovernorParams {
    /// Share of the footprint the front may take (the rest is for reps in
    /// flight and their compressed copies).
    pub fit_share: f32,
    /// A finer tolerance is taken when its front takes at most this share
    /// of what fits (and of `max_tris`).
    pub lower_share: f32,
    /// Front triangles allowed (0: no target).
    pub max_tris: u64,
    /// Frame time to keep within, in milliseconds (0: no target).
    pub max_frame_ms: f32,
    /// Factor between two tolerances tried (> 1).
    pub step: f32,
    /// The largest tolerance, in pixels.
    pub max_tolerance_px: f32,
}

impl Default for GovernorParams {
    fn default() -> Self {
        Self {
            fit_share: 0.8,
            lower_share: 0.85,
            max_tris: 0,
            max_frame_ms: 0.0,
            step: 1.25,
            max_tolerance_px: 4096.0,
        }
    }
}

impl GovernorParams {
    /// Rejects nonsense values.
    pub fn check(&self) -> Result<(), String> {
        if !(self.fit_share > 0.0 && self.fit_share <= 1.0) {
            return Err("the governor's fit share must be in (0, 1]".into());
        }
        if !(self.lower_share > 0.0 && self.lower_share < 1.0) {
            return Err("the governor's lower share must be in (0, 1)".into());
        }
        if !(self.step > 1.0 && self.step <= 4.0) {
            return Err("the governor's step must be in (1, 4]".into());
        }
        if !(self.max_frame_ms.is_finite() && self.max_frame_ms >= 0.0 && self.max_frame_ms <= 60e3)
        {
            return Err("the governor's frame-time target must be in [0, 60000] ms".into());
        }
        if !(self.max_tolerance_px.is_finite() && self.max_tolerance_px >= 1.0) {
            return Err("the governor's largest tolerance must be at least 1 pixel".into());
        }
        Ok(())
    }
}

/// What a front at some tolerance costs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrontCost {
    pub bytes: u64,
    pub tris: u64,
}

/// The governor of one walkthrough: the tolerance it holds.
#[derive(Clone, Debug)]
pub struct Governor {
    params: GovernorParams,
    base: f32,
    current: f32,
    /// Moving averages: drawing time per triangle, and the rest of a
    /// frame (front, waiting for P_I), in ms.
    ms_per_tri: Option<f64>,
    other_ms: Option<f64>,
}

/// Weight of a new frame in the moving averages.
const SMOOTHING: f64 = 0.1;

/// Frames drawing fewer triangles say little about a triangle's cost.
const MIN_TRIS_OBSERVED: u64 = 1000;

fn average(avg: &mut Option<f64>, v: f64) {
    *avg = Some(avg.map_or(v, |a| a + SMOOTHING * (v - a)));
}

impl Governor {
    /// A governor that never goes finer than `base_px`, the user's ε.
    pub fn new(params: GovernorParams, base_px: f32) -> Self {
        Self {
            params,
            base: base_px,
            current: base_px,
            ms_per_tri: None,
            other_ms: None,
        }
    }

    /// A frame ended: it took `frame_ms`, of which `draw_ms` drawing `tris`
    /// triangles (only a frame-time target uses it).
    pub fn observe_frame(&mut self, frame_ms: f64, draw_ms: f64, tris: u64) {
        if self.params.max_frame_ms <= 0.0 || !(frame_ms.is_finite() && draw_ms.is_finite()) {
            return;
        }
        average(&mut self.other_ms, (frame_ms - draw_ms).max(0.0));
        if tris >= MIN_TRIS_OBSERVED && draw_ms > 0.0 {
            average(&mut self.ms_per_tri, draw_ms / tris as f64);
        }
    }

    /// The triangles a front may have (0: any): `max_tris`, and what the
    /// frame-time target leaves after the rest of the frame (at least a
    /// tenth of the target, so one slow frame does not blank the view).
    pub fn tri_target(&self) -> u64 {
        let p = self.params;
        let mut t = p.max_tris;
        if p.max_frame_ms > 0.0
            && let Some(c) = self.ms_per_tri
        {
            let target = f64::from(p.max_frame_ms);
            let room = (target - self.other_ms.unwrap_or(0.0)).max(0.1 * target);
            let timed = ((room / c.max(1e-12)) as u64).max(1);
            t = if t == 0 { timed } else { t.min(timed) };
        }
        t
    }

    /// The tolerance of the last frame.
    pub fn tolerance(&self) -> f32 {
        self.current
    }

    fn fits(&self, c: FrontCost, capacity: Option<u64>, share: f64) -> bool {
        let bytes_ok = capacity
            .is_none_or(|b| c.bytes as f64 <= b as f64 * f64::from(self.params.fit_share) * share);
        let max_tris = self.tri_target();
        let tris_ok = max_tris == 0 || c.tris as f64 <= max_tris as f64 * share;
        bytes_ok && tris_ok
    }

    /// This frame's tolerance, for fronts that may take `capacity` bytes
    /// (`None`: no byte bound, in core);
    /// `measure(ε)` computes the front at ε and says what it costs (the
    /// caller keeps the fronts it computed).
    pub fn choose(
        &mut self,
        capacity: Option<u64>,
        mut measure: impl FnMut(f32) -> FrontCost,
    ) -> f32 {
        let p = self.params;
        let mut eps = self
            .current
            .clamp(self.base, p.max_tolerance_px.max(self.base));
        if self.fits(measure(eps), capacity, 1.0) {
            if eps > self.base {
                let finer = (eps / p.step).max(self.base);
                if self.fits(measure(finer), capacity, f64::from(p.lower_share)) {
                    eps = finer;
                }
            }
        } else {
            while eps < p.max_tolerance_px {
                eps = (eps * p.step).min(p.max_tolerance_px);
                if self.fits(measure(eps), capacity, 1.0) {
                    break;
                }
            }
        }
        self.current = eps;
        eps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A front whose bytes fall as the tolerance rises: `k / ε`.
    fn front(k: f64) -> impl FnMut(f32) -> FrontCost {
        move |eps| FrontCost {
            bytes: (k / f64::from(eps)) as u64,
            tris: 0,
        }
    }

    #[test]
    fn a_front_that_fits_keeps_the_tolerance() {
        let mut g = Governor::new(GovernorParams::default(), 2.0);
        assert_eq!(g.choose(Some(1000), front(1000.0)), 2.0);
    }

    #[test]
    fn too_large_a_front_raises_the_tolerance_until_it_fits_then_settles() {
        let p = GovernorParams::default();
        let mut g = Governor::new(p, 1.0);
        // Fits at ε with 8000 / ε <= 800: ε >= 10.
        let eps = g.choose(Some(1000), front(8000.0));
        assert!(eps >= 10.0 && eps < 10.0 * p.step, "{eps}");
        // A still camera: the same tolerance on every later frame.
        let mut seen = vec![eps];
        for _ in 0..20 {
            seen.push(g.choose(Some(1000), front(8000.0)));
        }
        assert!(seen.windows(2).all(|w| w[0] == w[1]), "{seen:?}");
    }

    #[test]
    fn the_tolerance_comes_back_down_when_the_front_shrinks_without_oscillating() {
        let mut g = Governor::new(GovernorParams::default(), 1.0);
        g.choose(Some(1000), front(8000.0));
        // The view shrinks the front: back down step by step to ε.
        let mut last = g.tolerance();
        let mut steps = 0;
        while g.tolerance() > 1.0 {
            let e = g.choose(Some(1000), front(100.0));
            assert!(e <= last);
            last = e;
            steps += 1;
            assert!(steps < 50);
        }
        // Near the limit: no frame-to-frame flip between two tolerances.
        let mut g = Governor::new(GovernorParams::default(), 1.0);
        let k = 800.0 * 5.0;
        let mut seen = Vec::new();
        for _ in 0..30 {
            seen.push(g.choose(Some(1000), front(k)));
        }
        let flips = seen
            .windows(3)
            .filter(|w| w[0] == w[2] && w[0] != w[1])
            .count();
        assert_eq!(flips, 0, "{seen:?}");
    }

    #[test]
    fn the_triangle_target_counts_too_and_the_cap_holds() {
        let p = GovernorParams {
            max_tris: 100,
            max_tolerance_px: 50.0,
            ..GovernorParams::default()
        };
        let mut g = Governor::new(p, 1.0);
        let e = g.choose(None, |eps| FrontCost {
            bytes: 0,
            tris: (1000.0 / eps) as u64,
        });
        assert!((10.0..12.5).contains(&e), "{e}");
        // Nothing fits: the largest tolerance, no further.
        let e = g.choose(Some(10), |_| FrontCost {
            bytes: 1000,
            tris: 0,
        });
        assert_eq!(e, 50.0);
    }

    #[test]
    fn a_frame_time_target_settles_within_the_target_without_oscillating() {
        let p = GovernorParams {
            max_frame_ms: 20.0,
            ..GovernorParams::default()
        };
        let mut g = Governor::new(p, 1.0);
        // A renderer of 3 ms a frame plus 0.1 ms per 1000 triangles; the
        // front holds 1M / ε triangles (100 ms at ε 1).
        let mut seen = Vec::new();
        let mut last_ms = 0.0;
        for _ in 0..120 {
            let e = g.choose(None, |eps| FrontCost {
                bytes: 0,
                tris: (1e6 / f64::from(eps)) as u64,
            });
            let tris = (1e6 / f64::from(e)) as u64;
            let draw = tris as f64 * 1e-4;
            last_ms = 3.0 + draw;
            g.observe_frame(last_ms, draw, tris);
            seen.push(e);
        }
        assert!(last_ms <= 20.0, "{last_ms} ms at ε {}", g.tolerance());
        // Not far coarser than needed (170k triangles: ε 5.9).
        assert!(g.tolerance() < 5.9 * p.step * p.step, "ε {}", g.tolerance());
        let tail = &seen[60..];
        assert!(tail.windows(2).all(|w| w[0] == w[1]), "{tail:?}");
        // A cheap scene stays at ε.
        let mut g = Governor::new(p, 1.0);
        for _ in 0..30 {
            let e = g.choose(None, |_| FrontCost {
                bytes: 0,
                tris: 10_000,
            });
            g.observe_frame(4.0, 1.0, 10_000);
            assert_eq!(e, 1.0);
        }
    }

    #[test]
    fn nonsense_parameters_are_refused() {
        let bad = GovernorParams {
            step: 1.0,
            ..GovernorParams::default()
        };
        assert!(bad.check().is_err());
        assert!(GovernorParams::default().check().is_ok());
    }
}
