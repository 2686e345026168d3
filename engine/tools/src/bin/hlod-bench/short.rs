//! The warning for a footprint smaller than the path's fronts: out of core,
//! such a run draws coarser ancestors in place of reps that do not fit, so
//! its frame times look better than in-core's for the wrong reason. The
//! viewer shows the substitutions on screen; `hlod-bench` says it in words,
//! on stderr and in `summary.md`.

use engine::metrics::TracePoint;

fn mib(b: u64) -> f64 {
    b as f64 / 1048576.0
}

/// A warning when some of a run's fronts (its `trace`) exceeded `budget`
/// and reps were drawn as ancestors; `None` when the footprint held every
/// front. `max_tolerance_px` is the run's largest ε (the quality
/// governor's, when it raised it).
pub fn warning(
    tag: &str,
    budget: u64,
    tolerance_px: f32,
    trace: &[TracePoint],
    max_tolerance_px: f64,
) -> Option<String> {
    let n = trace.len();
    let over = trace.iter().filter(|p| p.front_bytes > budget).count();
    let substituted_frames = trace.iter().filter(|p| p.substituted > 0).count();
    if n == 0 || over == 0 || substituted_frames == 0 {
        return None;
    }
    let mut sorted: Vec<u64> = trace.iter().map(|p| p.front_bytes).collect();
    sorted.sort_unstable();
    let (median, largest) = (sorted[n / 2], sorted[n - 1]);
    let raised = max_tolerance_px > f64::from(tolerance_px) * 1.001;
    let (at, advice) = if raised {
        (
            format!(
                "even at the quality governor's raised ε (up to {:.0} px)",
                max_tolerance_px
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
        substituted_frames,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(front: u64, substituted: u32) -> TracePoint {
        TracePoint {
            frame_ms: 1.0,
            front_bytes: front,
            stage2_bytes: 0,
            max_resident_bytes: 0,
            substituted,
        }
    }

    #[test]
    fn warns_only_when_fronts_exceed_the_footprint_and_reps_were_substituted() {
        let mut t: Vec<TracePoint> = [10 << 20, 30 << 20, 50 << 20]
            .into_iter()
            .map(|b| point(b, 0))
            .collect();
        assert!(
            warning("pre", 40 << 20, 2.0, &t, 2.0).is_none(),
            "nothing substituted"
        );
        t.push(point(60 << 20, 3));
        let w = warning("pre", 40 << 20, 2.0, &t, 8.0).unwrap();
        assert!(w.contains("on 2 of 4 frames"), "{w}");
        assert!(w.contains("largest 60.00 MiB"), "{w}");
        assert!(w.contains("1 frames drew coarser ancestors"), "{w}");
        assert!(w.contains("governor's raised ε (up to 8 px)"), "{w}");
        assert!(w.contains("larger still"), "{w}");
        let plain = [point(60 << 20, 3)];
        let w = warning("nopre", 40 << 20, 2.0, &plain, 2.0).unwrap();
        assert!(w.contains("fronts at ε 2 px on 1 of 1 frames"), "{w}");
        assert!(w.contains("at least 60.00 MiB draws every front"), "{w}");
        assert!(
            warning("pre", 100 << 20, 2.0, &t, 8.0).is_none(),
            "every front fits"
        );
    }
}
