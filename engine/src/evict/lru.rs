//! Least recently used, with demotion: an item used longest ago goes
//! first, and an item demoted goes before every other (P_I's pages: a page
//! whose reps are all read is spent). Over the `lru` crate's list.
//! [`LruMap`] keeps values beside the order, for the stores that evict by
//! it alone: P_I's pages, the occluder store, the walk section's chunks,
//! a tree's virtual-memory pages and its buffer's free list; outside the
//! engine, the disk cache of a remote scene's blocks and the builder's
//! decoded meshopt views.

use std::collections::HashMap;
use std::hash::Hash;

use lru::LruCache;

use super::{Eviction, Victim};

/// The LRU order over keys `K`.
#[derive(Debug)]
pub struct Lru<K: Hash + Eq> {
    list: LruCache<K, ()>,
}

impl<K: Hash + Eq + Copy> Default for Lru<K> {
    fn default() -> Self {
        Self {
            list: LruCache::unbounded(),
        }
    }
}

impl<K: Hash + Eq + Copy> Lru<K> {
    /// Makes `key` the first to go (no use recorded); no-op when absent.
    pub fn demote(&mut self, key: K) {
        self.list.demote(&key);
    }

    /// Forgets every item.
    pub fn clear(&mut self) {
        self.list.clear();
    }
}

impl<K: Hash + Eq + Copy + std::fmt::Debug> Eviction for Lru<K> {
    type Key = K;
    type Hint = ();

    fn insert(&mut self, key: K, (): ()) {
        self.list.put(key, ());
    }

    fn access(&mut self, key: K, (): ()) {
        self.list.promote(&key);
    }

    fn remove(&mut self, key: K) {
        self.list.pop(&key);
    }

    fn victims(&self) -> Box<dyn Iterator<Item = Victim<K>> + '_> {
        Box::new(
            self.list
                .iter()
                .rev()
                .map(|(&key, ())| Victim { key, recent: false }),
        )
    }

    fn contains(&self, key: K) -> bool {
        self.list.contains(&key)
    }

    fn len(&self) -> usize {
        self.list.len()
    }
}

/// Values by key, evicted least recently used first: a map beside an
/// [`Lru`] order, which every eviction goes through.
#[derive(Debug)]
pub struct LruMap<K: Hash + Eq, V> {
    map: HashMap<K, V>,
    order: Lru<K>,
}

impl<K: Hash + Eq + Copy + std::fmt::Debug, V> Default for LruMap<K, V> {
    fn default() -> Self {
        Self {
            map: HashMap::new(),
            order: Lru::default(),
        }
    }
}

impl<K: Hash + Eq + Copy + std::fmt::Debug, V> LruMap<K, V> {
    /// The value of `key`, used now.
    pub fn get(&mut self, key: K) -> Option<&V> {
        self.get_mut(key).map(|v| &*v)
    }

    /// The value of `key`, used now.
    pub fn get_mut(&mut self, key: K) -> Option<&mut V> {
        let v = self.map.get_mut(&key)?;
        self.order.access(key, ());
        Some(v)
    }

    /// Whether `key` is held (no use recorded).
    pub fn contains(&self, key: K) -> bool {
        self.map.contains_key(&key)
    }

    /// Holds `value` for `key`, used now; the value it replaces.
    pub fn put(&mut self, key: K, value: V) -> Option<V> {
        self.order.insert(key, ());
        self.map.insert(key, value)
    }

    /// Removes and returns the first victim ([`Eviction::victims`]).
    pub fn pop_victim(&mut self) -> Option<(K, V)> {
        let key = self.order.victims().next()?.key;
        self.order.remove(key);
        let v = self.map.remove(&key).expect("an ordered key is held");
        Some((key, v))
    }

    /// Makes `key` the first to go (no use recorded).
    pub fn demote(&mut self, key: K) {
        self.order.demote(key);
    }

    /// Removes `key` (not by eviction); its value, when it was held.
    pub fn remove(&mut self, key: K) -> Option<V> {
        self.order.remove(key);
        self.map.remove(&key)
    }

    pub fn len(&self) -> usize {
        self.map.len()
    }

    pub fn is_empty(&self) -> bool {
        self.map.is_empty()
    }

    pub fn clear(&mut self) {
        self.map.clear();
        self.order.clear();
    }

    /// The values held, in no particular order.
    pub fn values(&self) -> impl Iterator<Item = (&K, &V)> {
        self.map.iter()
    }

    /// Whether the order holds exactly the keys held.
    pub fn validate(&self) -> Result<(), String> {
        if self.order.len() != self.map.len() || self.map.keys().any(|&k| !self.order.contains(k)) {
            return Err("the eviction order and the values held differ".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_the_shared_harness() {
        crate::evict::harness::check(|_| Lru::<u32>::default(), |_, _| ());
    }

    #[test]
    fn the_least_recently_used_goes_first_and_a_demoted_one_before_it() {
        let mut l = Lru::default();
        for k in [1u64, 2, 3] {
            l.insert(k, ());
        }
        l.access(1, ());
        let order = |l: &Lru<u64>| l.victims().map(|v| v.key).collect::<Vec<_>>();
        assert_eq!(order(&l), vec![2, 3, 1]);
        l.demote(1);
        assert_eq!(order(&l), vec![1, 2, 3]);
        l.remove(2);
        assert_eq!(order(&l), vec![1, 3]);
    }

    #[test]
    fn a_map_evicts_in_its_order_and_a_get_is_a_use() {
        let mut m = LruMap::default();
        for k in [1u32, 2, 3] {
            m.put(k, k * 10);
        }
        assert_eq!(m.get(1), Some(&10));
        assert!(m.contains(2) && m.validate().is_ok());
        assert_eq!(m.pop_victim(), Some((2, 20)));
        m.demote(1);
        assert_eq!(m.pop_victim(), Some((1, 10)));
        assert_eq!(m.put(3, 31), Some(30));
        m.put(4, 40);
        assert_eq!(m.remove(4), Some(40));
        assert_eq!(m.remove(4), None);
        assert_eq!(m.len(), 1);
        assert_eq!(m.pop_victim(), Some((3, 31)));
        assert!(m.pop_victim().is_none() && m.is_empty());
    }
}
