//! The warning for a footprint smaller than the path's fronts: out of core,
//! such a run draws coarser ancestors in place of reps that do not fit, so
//! its frame times look better than in-core's for the wrong reason. The
//! viewer shows the substitutions on screen; `hlod-bench` says it in words,
//! on stderr and in `summary.md`.

use engine::metrics::FrameMetrics;

/// Per-run counts of the fronts against the footprint.
#[derive(Default)]
pub struct ShortFootprint {
    fronts: Vec<u64>,
    substituted_frames: usize,
    max_tolerance_px: f64,
}

fn mib(b: u64) -> f64 {
    b as f64 / 1048576.0
}

impl ShortFootprint {
    pub fn push(&mut self, f: &FrameMetrics) {
        self.fronts.push(f.front_bytes);
        self.substituted_frames += usize::from(f.substituted > 0);
        self.max_tolerance_px = self.max_tolerance_px.max(f.tolerance_px);
    }

    /// A warning when some frames' fronts exceeded `budget` and reps were
    /// drawn as ancestors; `None` when the footprint held every front.
    pub fn warning(&self, tag: &str, budget: u64, tolerance_px: f32) -> Option<String> {
        let n = self.fronts.len();
        let over = self.fronts.iter().filter(|&&b| b > budget).count();
        if n == 0 || over == 0 || self.substituted_frames == 0 {
            return None;
        }
        let mut sorted = self.fronts.clone();
        sorted.sort_unstable();
        let (median, largest) = (sorted[n / 2], sorted[n - 1]);
        let raised = self.max_tolerance_px > f64::from(tolerance_px) * 1.001;
        let (at, advice) = if raised {
            (
                format!(
                    "even at the quality governor's raised ε (up to {:.0} px)",
                    self.max_tolerance_px
                ),
                format!(
                    "Its fronts at ε {tolerance_px} px are larger still (run without --governor to measure them)."
                ),
            )
        } else {
            (
                format!("at ε {tolerance_px} px"),
                format!(
                    "A footprint of at least {:.2} MiB draws every front as itself.",
                    mib(largest)
                ),
            )
        };
        Some(format!(
            "{tag}: the footprint of {:.2} MiB is smaller than this path's fronts {at} on {over} \
             of {n} frames (median front {:.2} MiB, largest {:.2} MiB): {} frames drew coarser \
             ancestors in place of reps that did not fit, so this run's frame times are not \
             comparable with in-core's. {advice}",
            mib(budget),
            mib(median),
            mib(largest),
            self.substituted_frames,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(front: u64, substituted: u32, tol: f64) -> FrameMetrics {
        FrameMetrics {
            front_bytes: front,
            substituted,
            tolerance_px: tol,
            ..FrameMetrics::default()
        }
    }

    #[test]
    fn warns_only_when_fronts_exceed_the_footprint_and_reps_were_substituted() {
        let mut s = ShortFootprint::default();
        for b in [10 << 20, 30 << 20, 50 << 20] {
            s.push(&frame(b, 0, 2.0));
        }
        assert!(
            s.warning("pre", 40 << 20, 2.0).is_none(),
            "nothing substituted"
        );
        s.push(&frame(60 << 20, 3, 8.0));
        let w = s.warning("pre", 40 << 20, 2.0).unwrap();
        assert!(w.contains("on 2 of 4 frames"), "{w}");
        assert!(w.contains("largest 60.00 MiB"), "{w}");
        assert!(w.contains("1 frames drew coarser ancestors"), "{w}");
        assert!(w.contains("governor's raised ε (up to 8 px)"), "{w}");
        assert!(w.contains("larger still"), "{w}");
        let mut plain = ShortFootprint::default();
        plain.push(&frame(60 << 20, 3, 2.0));
        let w = plain.warning("nopre", 40 << 20, 2.0).unwrap();
        assert!(w.contains("fronts at ε 2 px on 1 of 1 frames"), "{w}");
        assert!(w.contains("at least 60.00 MiB draws every front"), "{w}");
        assert!(
            s.warning("pre", 100 << 20, 2.0).is_none(),
            "every front fits"
        );
    }
}
