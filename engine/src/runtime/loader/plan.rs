//! What the read planners (CLASSIFY, the lookahead, the sweep) consult.

use crate::front::FrontIndex;
use crate::runtime::RuntimeParams;
use crate::skeleton::Skeleton;

/// What the read planners consult: the skeleton, its front index, the
/// parameters and the reps' room for prefetching.
pub(in crate::runtime) struct Plan<'a> {
    pub(in crate::runtime) skeleton: &'a Skeleton,
    pub(in crate::runtime) index: &'a FrontIndex,
    pub(in crate::runtime) params: &'a RuntimeParams,
    /// The bytes prefetched reps may take: the budget less the pages'
    /// share (all of it when reads go by rep).
    pub(in crate::runtime) room: u64,
}

impl<'a> Plan<'a> {
    pub(in crate::runtime) fn of(
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
    pub(in crate::runtime) fn with_room(self, room: u64) -> Self {
        Self { room, ..self }
    }
}
