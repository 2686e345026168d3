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

use super::plan::Plan;
use crate::runtime::resident::ResidentSet;
use crate::skeleton::RepId;

/// The elevator through the small reps of F_I's front.
#[derive(Debug, Default)]
pub(super) struct Sweep {
    /// The candidates, in file order.
    reps: Vec<RepId>,
    /// The offset where the sweep goes on.
    at: u64,
    /// Whether this prefetch step is the sweep's (they alternate with the
    /// bins').
    turn: bool,
}

impl Sweep {
    /// Collects the small reps (`PrefetchParams::sweep_bytes`) of the
    /// F_I `front` that are not resident.
    pub(super) fn plan(
        &mut self,
        plan: &Plan,
        res: &ResidentSet,
        failed: &[bool],
        front: &[RepId],
    ) {
        self.reps.clear();
        let small = u64::from(plan.params.prefetch.sweep_bytes);
        if small == 0 {
            return;
        }
        for &r in front {
            if !res.contains(r) && !failed[r as usize] && res.cost(r) <= small {
                self.reps.push(r);
            }
        }
        let reps = &plan.skeleton.reps;
        self.reps.sort_unstable_by_key(|&r| reps[r as usize].offset);
    }

    /// Whether this prefetch step is the sweep's: every other one.
    pub(super) fn take_turn(&mut self) -> bool {
        self.turn = !self.turn;
        self.turn
    }

    /// The next candidate still `wanted` at or after the cursor, wrapping
    /// round.
    pub(super) fn next(&self, plan: &Plan, wanted: impl Fn(RepId) -> bool) -> Option<RepId> {
        let n = self.reps.len();
        let reps = &plan.skeleton.reps;
        let i = self
            .reps
            .partition_point(|&r| reps[r as usize].offset < self.at);
        (0..n).map(|k| self.reps[(i + k) % n]).find(|&r| wanted(r))
    }

    /// The sweep goes on from byte `offset`.
    pub(super) fn moved_to(&mut self, offset: u64) {
        self.at = offset;
    }

    /// Ends the sweep (nothing left to read, or no room left for it).
    pub(super) fn clear(&mut self) {
        self.reps.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::build;

    #[test]
    fn the_sweep_goes_on_from_its_cursor_and_wraps_round() {
        let (_, s) = build(&[1, 1, 1, 1, 1], &[4, 0, 0, 0, 0]);
        let mut params = crate::runtime::params::RuntimeParams::default();
        params.prefetch.sweep_bytes = 1 << 20;
        let index = crate::front::FrontIndex::new(&s);
        let plan = Plan::of(&s, &index, &params);
        let res = ResidentSet::new(s.reps.iter().map(|r| r.resident_len()).collect());
        let failed = vec![false; s.reps.len()];
        let mut w = Sweep::default();
        // Given out of file order; the root rep (0) is not in this front.
        w.plan(&plan, &res, &failed, &[4, 2, 1, 3]);
        assert_eq!(w.reps, vec![1, 2, 3, 4]);
        w.moved_to(s.reps[3].offset);
        assert_eq!(w.next(&plan, |_| true), Some(3));
        // Past the last candidate: round to the first still wanted.
        w.moved_to(s.reps[4].offset + 1);
        assert_eq!(w.next(&plan, |r| r != 1), Some(2));
        assert_eq!(w.next(&plan, |_| false), None);
        assert!(w.take_turn() && !w.take_turn(), "every other step");
    }
}
