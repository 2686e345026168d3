//! The stall deadline: Stage II reads only what it can finish in time.
//!
//! In the paper's protocol P_R waits until every missing rep of its front
//! is loaded; on a slow disk a sudden turn then stalls the frame for as
//! many seeks as it has misses. With `RuntimeParams::stall_deadline_s`,
//! Stage II starts a read only when its first block (the learnt seek and
//! transfer) ends within the deadline after the fetch command. The reps
//! left are drawn as their nearest resident ancestor — coarser, counted as
//! substituted and late — and read right after the frame, before any
//! prefetch, so that the next frame draws them. Their bytes are demand
//! bytes (`late_bytes`), reported with Stage II's.

use std::time::{Duration, Instant};

use super::{LoadError, Loader};
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
        Instant::now() + Duration::from_secs_f64(need) <= at + Duration::from_secs_f32(d)
    }

    /// Whether late reps wait to be read.
    pub(super) fn late_pending(&self) -> bool {
        self.late_at < self.late.len()
    }

    /// Reads the next late rep, and on through the file to the next
    /// candidates while cheap (preemptible, as a prefetch read is; a
    /// preempted one is resumed by the next Stage II if still missing).
    /// Returns whether it read or decided to wait for the fetch command.
    pub(super) fn late_step(&mut self) -> bool {
        while self.late_at < self.late.len() {
            let r = self.late[self.late_at];
            self.late_at += 1;
            if self.data[r as usize].is_some() || self.failed[r as usize] {
                continue;
            }
            if !self.first_block_in_time(r) {
                self.late_at -= 1;
                self.wait_fetch = true;
                return true;
            }
            if let Err(LoadError::NoRoom) = self.prefetch_read(r) {
                self.late.clear();
            }
            return true;
        }
        false
    }

    /// Whether rep `r` is late: in this frame's front and past its deadline.
    pub(super) fn is_late(&self, r: RepId) -> bool {
        self.late_stamp[r as usize] == self.pin_gen
    }
}
