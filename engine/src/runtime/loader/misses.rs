//! Miss accounting: each rep a front misses is an LOD switch (its node was
//! in the previous front), an HLOD switch (an ancestor or a descendant
//! was) or a newly visible part of the scene.

use crate::format::NONE;
use crate::skeleton::{RepId, Skeleton};

/// The kinds of this frame's misses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Misses {
    pub(super) lod: u32,
    pub(super) hier: u32,
    pub(super) new: u32,
}

/// The nodes of the previous front and those above it.
#[derive(Clone, Debug)]
pub(super) struct MissAccount {
    /// `front[n]` / `above[n]` equal the previous frame's number when node
    /// n was in its front / above a node that was.
    front: Vec<u32>,
    above: Vec<u32>,
}

impl MissAccount {
    pub(super) fn new(nodes: usize) -> Self {
        Self {
            front: vec![0; nodes],
            above: vec![0; nodes],
        }
    }

    /// Classifies the misses of frame `frame` (numbered from 2) against the
    /// previous front, then records this front for the next frame.
    pub(super) fn account(
        &mut self,
        skeleton: &Skeleton,
        frame: u32,
        front: &[RepId],
        missing: &[RepId],
    ) -> Misses {
        let prev = frame.wrapping_sub(1);
        let mut m = Misses::default();
        for &r in missing {
            let n = skeleton.reps[r as usize].node;
            if self.front[n as usize] == prev {
                m.lod += 1;
                continue;
            }
            let mut up = skeleton.nodes[n as usize].parent;
            let mut below_prev = false;
            while up != NONE {
                if self.front[up as usize] == prev {
                    below_prev = true;
                    break;
                }
                up = skeleton.nodes[up as usize].parent;
            }
            if below_prev || self.above[n as usize] == prev {
                m.hier += 1;
            } else {
                m.new += 1;
            }
        }
        for &r in front {
            let n = skeleton.reps[r as usize].node;
            self.front[n as usize] = frame;
            let mut up = skeleton.nodes[n as usize].parent;
            while up != NONE && self.above[up as usize] != frame {
                self.above[up as usize] = frame;
                up = skeleton.nodes[up as usize].parent;
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::build;

    #[test]
    fn misses_are_lod_hlod_or_new_against_the_previous_front() {
        // root A (1 rep) with children B (2 LODs) and C (2 LODs), and D
        // (1 rep) under C: reps A=0, B=1,2, C=3,4, D=5.
        let s = build(&[1, 2, 2, 1], &[2, 0, 1, 0]).1;
        let mut a = MissAccount::new(s.nodes.len());
        // Frame 2: everything is new.
        let m = a.account(&s, 2, &[1], &[1]);
        assert_eq!(
            m,
            Misses {
                lod: 0,
                hier: 0,
                new: 1
            }
        );
        // Frame 3 after a front of B's coarse rep: B's finer rep is an LOD
        // switch; A (above B) an HLOD switch; C new.
        let m = a.account(&s, 3, &[2, 0, 3], &[2, 0, 3]);
        assert_eq!(
            m,
            Misses {
                lod: 1,
                hier: 1,
                new: 1
            }
        );
        // Frame 4: D is below C, which was in the front.
        let m = a.account(&s, 4, &[5], &[5]);
        assert_eq!(
            m,
            Misses {
                lod: 0,
                hier: 1,
                new: 0
            }
        );
        // Frame 5: nothing missing, nothing counted.
        assert_eq!(a.account(&s, 5, &[5], &[]), Misses::default());
    }
}
