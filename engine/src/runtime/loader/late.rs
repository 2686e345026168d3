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

use super::Loader;
use crate::skeleton::RepId;

impl Loader {
    /// Whether Stage II may start reading rep `r` under the stall deadline.
    pub(super) fn in_time_for_frame(&self, r: RepId) -> bool {
        let d = self.params.stall_deadline_s;
        let Some(at) = self.last_fetch_at else {
            return true;
        };
        if d <= 0.0 {
            return true;
        }
        let need = self.first_block_s(r);
        let Some(deadline) = crate::limits::after(at, f64::from(d)) else {
            return true;
        };
        crate::limits::after(self.clock.now(), need).is_some_and(|t| t <= deadline)
    }

    /// Whether rep `r` is late: in this frame's front and past its deadline.
    pub(super) fn is_late(&self, r: RepId) -> bool {
        self.late_stamp[r as usize] == self.res.frame()
    }
}
