//! StartTail LRU replacement (Varadhan & Manocha §4.3).
//!
//! The *InMemoryList* holds the resident reps. At the start of Stage II the
//! current tail is remembered (*StartTail*); every access during fetching and
//! prefetching moves (or inserts) the rep right after StartTail, so the reps
//! accessed this frame lie beyond StartTail in reverse order of access, and
//! replacement candidates are taken from the head.
//!
//! StartTail is a marker element of the list itself, moved to the tail by
//! [`InMemoryList::start_stage2`]: inserting after it is O(1) and stays well
//! defined when the rep that was the tail is later moved or evicted. The list
//! is an index-linked slab over rep ids (the `lru` crate cannot insert at an
//! arbitrary position).

use super::{Eviction, Victim};
use crate::skeleton::RepId;

const NIL: u32 = u32::MAX;

/// The InMemoryList over rep ids `0..capacity`.
#[derive(Clone, Debug)]
pub struct InMemoryList {
    prev: Vec<u32>,
    next: Vec<u32>,
    linked: Vec<bool>,
    len: usize,
}

impl InMemoryList {
    /// An empty list for rep ids below `capacity`.
    pub fn new(capacity: usize) -> Self {
        let n = capacity + 2;
        let mut l = Self {
            prev: vec![NIL; n],
            next: vec![NIL; n],
            linked: vec![false; n],
            len: 0,
        };
        let (root, mark) = (l.root(), l.mark());
        // root <-> mark, circular.
        l.next[root] = mark as u32;
        l.prev[root] = mark as u32;
        l.next[mark] = root as u32;
        l.prev[mark] = root as u32;
        l.linked[mark] = true;
        l
    }

    fn root(&self) -> usize {
        self.prev.len() - 2
    }

    fn mark(&self) -> usize {
        self.prev.len() - 1
    }

    /// Reps in the list.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no rep is in the list.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whether `rep` is in the list.
    pub fn contains(&self, rep: RepId) -> bool {
        self.linked[rep as usize]
    }

    fn unlink(&mut self, i: usize) {
        let (p, n) = (self.prev[i] as usize, self.next[i] as usize);
        self.next[p] = n as u32;
        self.prev[n] = p as u32;
        self.linked[i] = false;
    }

    fn link_after(&mut self, i: usize, after: usize) {
        let n = self.next[after] as usize;
        self.prev[i] = after as u32;
        self.next[i] = n as u32;
        self.next[after] = i as u32;
        self.prev[n] = i as u32;
        self.linked[i] = true;
    }

    /// Start of Stage II: StartTail becomes the current tail.
    pub fn start_stage2(&mut self) {
        let (mark, root) = (self.mark(), self.root());
        self.unlink(mark);
        let tail = self.prev[root] as usize;
        self.link_after(mark, tail);
    }

    /// An access: moves or inserts `rep` right after StartTail.
    pub fn access(&mut self, rep: RepId) {
        let i = rep as usize;
        if self.linked[i] {
            self.unlink(i);
        } else {
            self.len += 1;
        }
        let mark = self.mark();
        self.link_after(i, mark);
    }

    /// Removes `rep` (evicted); no-op when absent.
    pub fn remove(&mut self, rep: RepId) {
        let i = rep as usize;
        if self.linked[i] {
            self.unlink(i);
            self.len -= 1;
        }
    }

    /// Reps from the head (replacement order), with `true` for those before
    /// StartTail (not accessed since the current Stage II began).
    pub fn iter_from_head(&self) -> impl Iterator<Item = (RepId, bool)> + '_ {
        let (root, mark) = (self.root(), self.mark());
        let mut cur = self.next[root] as usize;
        let mut before_mark = true;
        std::iter::from_fn(move || {
            loop {
                if cur == root {
                    return None;
                }
                let i = cur;
                cur = self.next[i] as usize;
                if i == mark {
                    before_mark = false;
                    continue;
                }
                return Some((i as RepId, before_mark));
            }
        })
    }
}

/// StartTail LRU as an [`Eviction`] policy: from the head, and `recent`
/// past StartTail (accessed in this Stage II).
impl Eviction for InMemoryList {
    type Key = RepId;
    type Hint = ();

    fn insert(&mut self, key: RepId, (): ()) {
        InMemoryList::access(self, key);
    }

    fn access(&mut self, key: RepId, (): ()) {
        InMemoryList::access(self, key);
    }

    fn remove(&mut self, key: RepId) {
        InMemoryList::remove(self, key);
    }

    fn victims(&self) -> Box<dyn Iterator<Item = Victim<RepId>> + '_> {
        Box::new(self.iter_from_head().map(|(key, before_mark)| Victim {
            key,
            recent: !before_mark,
        }))
    }

    fn contains(&self, key: RepId) -> bool {
        InMemoryList::contains(self, key)
    }

    fn len(&self) -> usize {
        InMemoryList::len(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The obvious model: a vector with a marker value.
    #[derive(Default)]
    struct Model {
        items: Vec<Option<RepId>>, // None = StartTail
    }

    impl Model {
        fn new() -> Self {
            Self { items: vec![None] }
        }
        fn start(&mut self) {
            self.items.retain(Option::is_some);
            self.items.push(None);
        }
        fn access(&mut self, r: RepId) {
            self.items.retain(|x| *x != Some(r));
            let m = self.items.iter().position(Option::is_none).unwrap();
            self.items.insert(m + 1, Some(r));
        }
        fn remove(&mut self, r: RepId) {
            self.items.retain(|x| *x != Some(r));
        }
        fn order(&self) -> Vec<(RepId, bool)> {
            let m = self.items.iter().position(Option::is_none).unwrap();
            self.items
                .iter()
                .enumerate()
                .filter_map(|(k, x)| x.map(|r| (r, k < m)))
                .collect()
        }
    }

    #[test]
    fn paper_figure_7_order() {
        let mut l = InMemoryList::new(10);
        // Frame 1 accesses 0, 1, 2: they lie in reverse order of access.
        for r in [0, 1, 2] {
            l.access(r);
        }
        let order: Vec<_> = l.iter_from_head().map(|x| x.0).collect();
        assert_eq!(order, vec![2, 1, 0]);
        l.start_stage2();
        // Front reps 3, 1 fetched in Stage II, then 4 prefetched.
        for r in [3, 1, 4] {
            l.access(r);
        }
        let order: Vec<_> = l.iter_from_head().collect();
        assert_eq!(
            order,
            vec![(2, true), (0, true), (4, false), (1, false), (3, false)]
        );
        assert_eq!(l.len(), 5);
        l.remove(0);
        l.remove(0);
        assert_eq!(l.len(), 4);
    }

    #[test]
    fn passes_the_shared_harness() {
        crate::evict::harness::check(|n| InMemoryList::new(n as usize), |_, _| ());
    }

    proptest! {
        #[test]
        fn matches_the_reference_model(ops in prop::collection::vec((0u8..4, 0u32..12), 0..300)) {
            let mut l = InMemoryList::new(12);
            let mut m = Model::new();
            for (op, r) in ops {
                match op {
                    0 => { l.start_stage2(); m.start(); }
                    1 | 2 => { l.access(r); m.access(r); }
                    _ => { l.remove(r); m.remove(r); }
                }
                prop_assert_eq!(l.iter_from_head().collect::<Vec<_>>(), m.order());
                prop_assert_eq!(l.len(), m.order().len());
                for r in 0..12 {
                    prop_assert_eq!(l.contains(r), m.order().iter().any(|x| x.0 == r));
                }
            }
        }
    }
}
