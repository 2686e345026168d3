//! Belady's rule: the item used again last goes first. It needs the future
//! — the frames that use each item — so it is the reference a clairvoyant
//! P_I is measured with (`hlod-bench --bounds`), not a runtime policy.

use std::collections::BTreeSet;

use super::{Eviction, Victim};

/// Resident items keyed by their next use; an item whose next use is
/// [`Belady::NOW`] (used this frame) is resident and not a victim.
#[derive(Debug)]
pub struct Belady {
    by_next: BTreeSet<(u32, u32)>,
    next: Vec<Option<u32>>,
    len: usize,
}

impl Belady {
    /// The next use of an item used now: pinned, never a victim.
    pub const NOW: u32 = u32::MAX;

    /// Nothing resident, over keys `0..n`.
    pub fn new(n: usize) -> Self {
        Self {
            by_next: BTreeSet::new(),
            next: vec![None; n],
            len: 0,
        }
    }

    /// The next use of resident `key`.
    pub fn next_use(&self, key: u32) -> Option<u32> {
        self.next[key as usize]
    }
}

impl Eviction for Belady {
    type Key = u32;
    /// The frame `key` is used next (`u32::MAX - 1`: never again;
    /// [`Belady::NOW`]: now).
    type Hint = u32;

    fn insert(&mut self, key: u32, next: u32) {
        if self.next[key as usize].is_none() {
            self.len += 1;
        }
        self.access(key, next);
    }

    fn access(&mut self, key: u32, next: u32) {
        if let Some(old) = self.next[key as usize].replace(next) {
            self.by_next.remove(&(old, key));
        }
        if next != Self::NOW {
            self.by_next.insert((next, key));
        }
    }

    fn remove(&mut self, key: u32) {
        if let Some(old) = self.next[key as usize].take() {
            self.by_next.remove(&(old, key));
            self.len -= 1;
        }
    }

    /// Used again last first; the items used now are not listed.
    fn victims(&self) -> Box<dyn Iterator<Item = Victim<u32>> + '_> {
        Box::new(
            self.by_next
                .iter()
                .rev()
                .map(|&(_, key)| Victim { key, recent: false }),
        )
    }

    fn contains(&self, key: u32) -> bool {
        self.next[key as usize].is_some()
    }

    fn len(&self) -> usize {
        self.len
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_the_shared_harness() {
        // Hints below NOW: the harness checks that every item is a victim.
        crate::evict::harness::check(|n| Belady::new(n as usize), |k, step| (k * 7 + step) % 50);
    }

    #[test]
    fn the_item_used_again_last_goes_first_and_one_used_now_stays() {
        let mut b = Belady::new(4);
        b.insert(0, 5);
        b.insert(1, 9);
        b.insert(2, Belady::NOW);
        b.insert(3, 2);
        let order: Vec<u32> = b.victims().map(|v| v.key).collect();
        assert_eq!(order, vec![1, 0, 3]);
        assert_eq!(b.len(), 4);
        b.access(2, 7);
        assert_eq!(b.victims().next().map(|v| v.key), Some(1));
        assert_eq!(b.next_use(2), Some(7));
    }
}
