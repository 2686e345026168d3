//! When a rep that could not be loaded is tried again.
//!
//! A rep whose bytes are wrong (a checksum, a payload that does not decode,
//! a file cut short, a scene changed on its server) stays failed: reading it
//! again gives the same bytes. A rep whose read failed for a cause that may
//! pass (a network or device error after the source's own retries) is tried
//! again after a backoff that doubles with each failure in a row. While
//! failures go on, one rep at a time is released as a probe, so that a
//! server that is down costs one failed read per backoff period, not one per
//! rep; once a read succeeds, every rep due is released. Time is passed in.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::io::ErrorKind;
use std::time::{Duration, Instant};

use crate::skeleton::RepId;

/// The first backoff; it doubles with each failure in a row.
const BASE: Duration = Duration::from_millis(250);
/// The longest backoff.
const MAX: Duration = Duration::from_secs(4);

/// Whether a read error may pass (then the rep is tried again).
pub(super) fn transient(kind: ErrorKind) -> bool {
    !matches!(
        kind,
        ErrorKind::UnexpectedEof
            | ErrorKind::InvalidData
            | ErrorKind::InvalidInput
            | ErrorKind::NotFound
            | ErrorKind::StaleNetworkFileHandle
    )
}

/// The failed reps to try again, and the failures so far.
#[derive(Debug, Default)]
pub(super) struct Retry {
    /// Failures in this walk (for the pace of the warnings).
    total: u32,
    /// Failures since the last successful read.
    streak: u32,
    due: BinaryHeap<Reverse<(Instant, RepId)>>,
}

impl Retry {
    /// Records a failure of rep `r` at `now`; returns the failures so far.
    pub(super) fn failed(&mut self, r: RepId, now: Instant, transient: bool) -> u32 {
        self.total = self.total.saturating_add(1);
        self.streak = self.streak.saturating_add(1);
        if transient {
            let wait = BASE.saturating_mul(1 << (self.streak - 1).min(8)).min(MAX);
            self.due.push(Reverse((now + wait, r)));
        }
        self.total
    }

    /// A read succeeded: the cause passed, if there was one.
    pub(super) fn succeeded(&mut self) {
        self.streak = 0;
    }

    /// The reps to try again at `now`: every one due, or a single probe
    /// while failures go on.
    pub(super) fn release(&mut self, now: Instant) -> Vec<RepId> {
        let mut out = Vec::new();
        while let Some(&Reverse((t, r))) = self.due.peek() {
            if t > now || (self.streak > 0 && !out.is_empty()) {
                break;
            }
            self.due.pop();
            out.push(r);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lasting_errors_are_not_retried() {
        for k in [
            ErrorKind::UnexpectedEof,
            ErrorKind::InvalidData,
            ErrorKind::StaleNetworkFileHandle,
        ] {
            assert!(!transient(k), "{k:?}");
        }
        for k in [
            ErrorKind::Other,
            ErrorKind::TimedOut,
            ErrorKind::ConnectionReset,
        ] {
            assert!(transient(k), "{k:?}");
        }
        let t0 = Instant::now();
        let mut r = Retry::default();
        assert_eq!(r.failed(3, t0, false), 1);
        assert!(r.release(t0 + Duration::from_secs(3600)).is_empty());
    }

    #[test]
    fn backoff_doubles_one_probe_while_failing_then_all_due() {
        let t0 = Instant::now();
        let mut r = Retry::default();
        r.failed(1, t0, true); // due at 250 ms
        r.failed(2, t0, true); // 500 ms
        r.failed(3, t0, true); // 1 s
        assert!(r.release(t0 + Duration::from_millis(200)).is_empty());
        // Still failing: one probe at a time.
        assert_eq!(r.release(t0 + Duration::from_secs(2)), vec![1]);
        // The probe failed again: a streak of 4, 2 s.
        r.failed(1, t0 + Duration::from_secs(2), true);
        assert_eq!(r.release(t0 + Duration::from_secs(2)), vec![2]);
        // It was read: every rep due goes at once.
        r.succeeded();
        assert_eq!(r.release(t0 + Duration::from_secs(2)), vec![3]);
        assert!(r.release(t0 + Duration::from_millis(3900)).is_empty());
        assert_eq!(r.release(t0 + Duration::from_secs(4)), vec![1]);
        // Capped.
        for i in 0..40 {
            r.failed(9, t0, true);
            let _ = i;
        }
        assert!(r.due.iter().all(|Reverse((t, _))| *t <= t0 + MAX));
    }
}
