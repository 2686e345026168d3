//! Plain values of P_I's reads: the reps in file order, a queue of reps to
//! read, and the [`Partial`] read a preemption leaves to be resumed.

use crate::skeleton::{RepId, Skeleton};

/// A prefetch read that a fetch command preempted: the bytes read so far.
/// Its rep's footprint stays reserved until it completes or is given up.
#[derive(Debug)]
pub(super) struct Partial {
    pub(super) rep: RepId,
    pub(super) buf: Vec<u8>,
    pub(super) done: usize,
}

/// Reps to read in order (the lookahead's, the late ones) and the next one.
#[derive(Debug, Default)]
pub(super) struct ReadQueue {
    pub(super) reps: Vec<RepId>,
    at: usize,
}

impl ReadQueue {
    /// The reps not served yet, in order.
    pub(super) fn rest(&self) -> &[RepId] {
        self.reps.get(self.at..).unwrap_or_default()
    }

    pub(super) fn clear(&mut self) {
        self.reps.clear();
        self.at = 0;
    }

    /// The next rep to read.
    pub(super) fn next(&self) -> Option<RepId> {
        self.reps.get(self.at).copied()
    }

    /// Goes past the next rep.
    pub(super) fn advance(&mut self) {
        self.at += 1;
    }

    /// Whether reps wait to be read.
    pub(super) fn pending(&self) -> bool {
        self.at < self.reps.len()
    }
}

/// The payloads in file order (a shared one once, by the rep that owns it).
#[derive(Clone, Debug, Default)]
pub(super) struct FileOrder {
    by_offset: Vec<RepId>,
    pos: Vec<u32>,
}

impl FileOrder {
    pub(super) fn new(skeleton: &Skeleton) -> Self {
        let by_offset = skeleton.payloads_in_file_order();
        let mut pos = vec![0u32; skeleton.reps.len()];
        for (i, &r) in by_offset.iter().enumerate() {
            pos[r as usize] = i as u32;
        }
        // A second placement of a payload is where its owner is.
        for p in &skeleton.placements {
            pos[p.rep as usize] = pos[p.source as usize];
        }
        Self { by_offset, pos }
    }

    /// The reps stored after `r`, nearest first.
    pub(super) fn after(&self, r: RepId) -> &[RepId] {
        &self.by_offset[self.pos[r as usize] as usize + 1..]
    }

    /// The reps stored at or after byte `offset`, nearest first.
    pub(super) fn starting_at(&self, skeleton: &Skeleton, offset: u64) -> &[RepId] {
        let i = self
            .by_offset
            .partition_point(|&r| skeleton.reps[r as usize].offset < offset);
        &self.by_offset[i..]
    }
}
