//! Time, injected: everything in the runtime that reads or spends time —
//! P_R's frame timings and pacing, the `none` renderer's modelled draw
//! time, P_I's timing policy (when the next frame's fetch is due, whether a
//! read ends in time, the learnt read costs) and the modelled disk
//! ([`crate::disk::ThrottledSource`]) — goes through one [`Clock`]. Tests
//! drive it with a [`ManualClock`] that waits move on instead of sleeping:
//! timing is tested without depending on the machine's speed or load.

use std::fmt::Debug;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// A source of the current instant, and a way to wait for a later one.
pub trait Clock: Send + Sync + Debug {
    fn now(&self) -> Instant;

    /// Returns at `t` or later (at once when `t` has passed).
    fn sleep_until(&self, t: Instant);

    /// Whether time passes only as the program's reads and waits say (a
    /// [`ManualClock`]): waiting on it gives other threads no time, so a
    /// paced walk lets P_I finish its work instead
    /// ([`crate::runtime::Walkthrough::settle`]).
    fn is_simulated(&self) -> bool {
        false
    }

    /// Milliseconds since `t` (0 for an instant still to come).
    fn ms_since(&self, t: Instant) -> f64 {
        self.now().saturating_duration_since(t).as_secs_f64() * 1e3
    }

    /// [`Self::sleep_until`] `d` from now.
    fn sleep(&self, d: Duration) {
        self.sleep_until(self.now() + d);
    }
}

/// The system's monotonic clock; its sleeps are the thread's, which
/// oversleep by the timer slack (50–80 µs on Linux). A program that models
/// sub-millisecond reads brings a finer clock (`engine_cli::disk::SpinClock`).
#[derive(Clone, Copy, Debug, Default)]
pub struct SystemClock;

impl Clock for SystemClock {
    fn now(&self) -> Instant {
        Instant::now()
    }

    fn sleep_until(&self, t: Instant) {
        let now = Instant::now();
        if t > now {
            std::thread::sleep(t - now);
        }
    }
}

/// A clock that moves only when told ([`ManualClock::advance`]) or when
/// something waits on it (a wait moves it to its end at once).
#[derive(Debug)]
pub struct ManualClock {
    base: Instant,
    nanos: AtomicU64,
}

impl Default for ManualClock {
    fn default() -> Self {
        Self::new()
    }
}

impl ManualClock {
    pub fn new() -> Self {
        Self {
            base: Instant::now(),
            nanos: AtomicU64::new(0),
        }
    }

    /// Moves the clock on by `d`.
    pub fn advance(&self, d: Duration) {
        let n = u64::try_from(d.as_nanos()).unwrap_or(u64::MAX);
        self.nanos.fetch_add(n, Ordering::Relaxed);
    }

    /// Time since the clock was made.
    pub fn elapsed(&self) -> Duration {
        Duration::from_nanos(self.nanos.load(Ordering::Relaxed))
    }
}

impl Clock for ManualClock {
    fn now(&self) -> Instant {
        self.base + self.elapsed()
    }

    fn sleep_until(&self, t: Instant) {
        let target =
            u64::try_from(t.saturating_duration_since(self.base).as_nanos()).unwrap_or(u64::MAX);
        self.nanos.fetch_max(target, Ordering::Relaxed);
    }

    fn is_simulated(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_manual_clock_moves_only_when_advanced_or_waited_on() {
        let c = ManualClock::new();
        let t0 = c.now();
        std::thread::sleep(Duration::from_millis(2));
        assert_eq!(c.now(), t0);
        c.advance(Duration::from_millis(7));
        assert_eq!(c.now() - t0, Duration::from_millis(7));
        c.sleep(Duration::from_millis(3));
        assert_eq!(c.now() - t0, Duration::from_millis(10));
        // A wait for a past instant returns at once and moves nothing.
        c.sleep_until(t0 + Duration::from_millis(4));
        assert_eq!(c.now() - t0, Duration::from_millis(10));
        assert!(SystemClock.now() >= t0);
    }

    #[test]
    fn the_system_clock_sleeps_at_least_as_asked() {
        let t0 = SystemClock.now();
        SystemClock.sleep(Duration::from_millis(3));
        assert!(SystemClock.now() - t0 >= Duration::from_millis(3));
        SystemClock.sleep_until(t0); // passed: returns at once
    }
}
