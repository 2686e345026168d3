//! What the read planners (CLASSIFY, the lookahead, the sweep) consult.

use crate::front::FrontIndex;
use crate::runtime::params::RuntimeParams;
use crate::skeleton::Skeleton;

/// What the read planners consult: the skeleton, its front index, the
/// parameters and the reps' room for prefetching.
pub(super) struct Plan<'a> {
    pub(super) skeleton: &'a Skeleton,
    pub(super) index: &'a FrontIndex,
    pub(super) params: &'a RuntimeParams,
    /// The bytes prefetched reps may take: the budget less the pages'
    /// share (all of it when reads go by rep).
    pub(super) room: u64,
}

impl<'a> Plan<'a> {
    pub(super) fn of(
        skeleton: &'a Skeleton,
        index: &'a FrontIndex,
        params: &'a RuntimeParams,
    ) -> Self {
        Self {
            skeleton,
            index,
            params,
            room: params.budget_bytes,
        }
    }

    /// The same with the reps' room for prefetching `room`.
    pub(super) fn with_room(self, room: u64) -> Self {
        Self { room, ..self }
    }
}
