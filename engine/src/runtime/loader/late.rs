//! The stall deadline: Stage II reads only what it can finish in time.
//!
//! In the paper's protocol P_R waits until every missing rep of its front
//! is loaded; on a slow disk a sudden turn then stalls the frame for as
//! many seeks as it has misses. With `RuntimeParams::stall_deadline_s`,
//! Stage II starts a read only when its first block (the learnt seek and
//! transfer) ends within the deadline after the fetch command. The reps
//! left are drawn as their nearest resident ancestor — coarser, counted as
//! substituted and late — and read right after the frame, before any
//! prefetch (preemptible, as a prefetch read is; a preempted one is
//! resumed by the next Stage II if still missing), so that the next frame
//! draws them. Their bytes are demand bytes (`late_bytes`), reported with
//! Stage II's.

use super::order::ReadQueue;
use crate::skeleton::RepId;

/// The front reps past this frame's stall deadline, to read after it.
#[derive(Debug)]
pub(super) struct LateReads {
    pub(super) queue: ReadQueue,
    /// The frame a rep went late in.
    frame_of: Vec<u32>,
}

impl LateReads {
    pub(super) fn new(reps: usize) -> Self {
        Self {
            queue: ReadQueue::default(),
            frame_of: vec![u32::MAX; reps],
        }
    }

    /// A new Stage II: the late reps of the frame before are not.
    pub(super) fn clear(&mut self) {
        self.queue.clear();
    }

    /// Rep `r` of frame `frame`'s front missed its deadline.
    pub(super) fn push(&mut self, r: RepId, frame: u32) {
        self.frame_of[r as usize] = frame;
        self.queue.reps.push(r);
    }

    /// Whether rep `r` went late in frame `frame`.
    pub(super) fn is_late(&self, r: RepId, frame: u32) -> bool {
        self.frame_of[r as usize] == frame
    }
}
