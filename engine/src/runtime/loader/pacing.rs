//! When P_I expects the next fetch command, and whether a read ends in
//! time: before it (a prefetch read), or within the stall deadline after
//! the last one (a Stage II read). Plain values: the time is passed in.

use std::time::Instant;

use crate::limits::after;

/// The fetch commands' rhythm as P_I sees it.
#[derive(Clone, Debug, Default)]
pub(super) struct Pacing {
    /// When the next fetch command is expected (paced runs only).
    next_fetch: Option<Instant>,
    /// When the last fetch command came.
    last_fetch_at: Option<Instant>,
    /// A moving average of the time between fetch commands (frames slower
    /// than the period leave P_I more time to prefetch).
    interval_s: f64,
}

impl Pacing {
    /// A fetch command came at `now`; frames are `period_s` apart (0:
    /// unpaced, so that no prefetch read waits for the next command).
    pub(super) fn on_fetch(&mut self, now: Instant, period_s: f64) {
        if let Some(t) = self.last_fetch_at {
            // A stalled frame must not promise P_I a long window.
            let dt = now
                .saturating_duration_since(t)
                .as_secs_f64()
                .min(4.0 * period_s);
            self.interval_s += 0.25 * (dt - self.interval_s);
        }
        self.last_fetch_at = Some(now);
        let expect = period_s.max(self.interval_s);
        // 1 % early: frame pacing wakes P_R a little late, not early (reads
        // are timed per read, with their own margin).
        self.next_fetch = (period_s > 0.0)
            .then(|| after(now, expect * 0.99))
            .flatten();
    }

    /// Whether work of `need_s` seconds started at `now` ends before the
    /// next fetch command is due (always, unpaced).
    pub(super) fn ends_in_time(&self, now: Instant, need_s: f64) -> bool {
        let Some(due) = self.next_fetch else {
            return true;
        };
        after(now, need_s).is_some_and(|t| t <= due)
    }

    /// Whether a Stage II read of `need_s` seconds started at `now` ends
    /// within `deadline_s` of the fetch command (always without one).
    pub(super) fn in_time_for_frame(&self, now: Instant, need_s: f64, deadline_s: f64) -> bool {
        let Some(at) = self.last_fetch_at else {
            return true;
        };
        if deadline_s <= 0.0 {
            return true;
        }
        let Some(deadline) = after(at, deadline_s) else {
            return true;
        };
        after(now, need_s).is_some_and(|t| t <= deadline)
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    fn ms(x: f64) -> Duration {
        Duration::from_secs_f64(x / 1e3)
    }

    #[test]
    fn a_prefetch_read_must_end_before_the_next_fetch_command() {
        let t0 = Instant::now();
        let mut p = Pacing::default();
        assert!(p.ends_in_time(t0, 10.0), "nothing expected yet");
        p.on_fetch(t0, 0.1);
        // Due at 99 ms.
        assert!(p.ends_in_time(t0 + ms(50.0), 0.049));
        assert!(!p.ends_in_time(t0 + ms(50.0), 0.050));
        // Unpaced: never waits.
        let mut u = Pacing::default();
        u.on_fetch(t0, 0.0);
        assert!(u.ends_in_time(t0, 1e6));
    }

    #[test]
    fn slow_frames_widen_the_window_but_a_stall_is_capped() {
        let t0 = Instant::now();
        let mut p = Pacing::default();
        // Frames come every 200 ms against a 100 ms period.
        for k in 0..40 {
            p.on_fetch(t0 + ms(200.0 * k as f64), 0.1);
        }
        let last = t0 + ms(200.0 * 39.0);
        assert!((p.interval_s - 0.2).abs() < 1e-3, "{}", p.interval_s);
        assert!(p.ends_in_time(last, 0.19));
        assert!(!p.ends_in_time(last, 0.2));
        // One 10 s stall counts as 4 periods, not 10 s.
        let mut q = Pacing::default();
        q.on_fetch(t0, 0.1);
        q.on_fetch(t0 + Duration::from_secs(10), 0.1);
        assert!((q.interval_s - 0.25 * 0.4).abs() < 1e-9, "{}", q.interval_s);
    }

    #[test]
    fn the_stall_deadline_counts_from_the_fetch_command() {
        let t0 = Instant::now();
        let mut p = Pacing::default();
        assert!(p.in_time_for_frame(t0, 1.0, 0.01), "no command yet");
        p.on_fetch(t0, 0.1);
        assert!(p.in_time_for_frame(t0 + ms(2.0), 0.007, 0.01));
        assert!(!p.in_time_for_frame(t0 + ms(2.0), 0.009, 0.01));
        assert!(p.in_time_for_frame(t0 + ms(2.0), 9.0, 0.0), "no deadline");
    }
}
