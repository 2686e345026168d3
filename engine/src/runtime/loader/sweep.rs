//! The sweep: P_I reads the small reps of the F_I front in file order.
//!
//! On a seek-bound disk most of a frame's misses after a pan or a turn are
//! small reps (the coarse LODs of everything newly in view: most of the reps
//! a fly-through draws, holding a small share of its bytes), each costing a
//! seek. Served by priority they are
//! read one seek each; in file order (the spatial layout stores them by
//! band and along a Morton curve) a run of them costs one seek and their
//! transfer, and the gaps between them are read through. The sweep is an
//! elevator: it goes on from where it stopped, also across frames, and
//! wraps round at the end of the file. Prefetch steps alternate between
//! the sweep and the bins (the paper's priority order).

use super::{LoadError, Loader, Purpose};
use crate::skeleton::RepId;

impl Loader {
    /// Collects the small reps of the (enlarged-frustum) front not resident.
    pub(super) fn plan_sweep(&mut self, front: &[RepId]) {
        self.sweep.clear();
        let small = u64::from(self.params.prefetch.sweep_bytes);
        if small == 0 {
            return;
        }
        for &r in front {
            if !self.res.contains(r) && !self.failed[r as usize] && self.cost(r) <= small {
                self.sweep.push(r);
            }
        }
        self.sweep
            .sort_unstable_by_key(|&r| self.skeleton.reps[r as usize].offset);
    }

    /// One sweep read: the next small candidate at or after the cursor
    /// (wrapping round), and on through the file while cheap. Returns
    /// whether it read (or tried to).
    pub(super) fn sweep_step(&mut self) -> bool {
        let n = self.sweep.len();
        if n == 0 {
            return false;
        }
        let at = self.sweep_at;
        let i = self
            .sweep
            .partition_point(|&r| self.skeleton.reps[r as usize].offset < at);
        let next = (0..n)
            .map(|k| self.sweep[(i + k) % n])
            .find(|&r| self.wanted(r));
        let Some(r) = next else {
            self.sweep.clear();
            return false;
        };
        let rec = self.skeleton.reps[r as usize];
        let bridged = self
            .costs
            .last_end()
            .is_some_and(|end| self.bridge(end, rec.offset, Purpose::Prefetch));
        if self.pending.is_some() {
            return true;
        }
        if !bridged && !self.first_block_in_time(r) {
            return false;
        }
        match self.prefetch_read(r) {
            Ok(()) | Err(LoadError::Failed) | Err(LoadError::Preempted) => {}
            Err(LoadError::NoRoom) => self.sweep.clear(),
        }
        self.sweep_at = self.costs.last_end().unwrap_or(rec.offset);
        true
    }
}
