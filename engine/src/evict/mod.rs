//! Eviction as one interface: which resident item goes first.
//!
//! Every store that holds items under a byte budget — P_I's resident reps
//! ([`crate::runtime::resident::ResidentSet`]), its pages, an MT's nodes
//! ([`crate::mt::store::MtStore`]) and the clairvoyant reference of
//! `hlod-bench --bounds` — keeps its own bytes, pins and admission rules
//! and asks an [`Eviction`] policy for the order its items go in, then
//! [`choose`]s victims from that order. As in foyer's `Eviction` trait, a
//! policy owns only the order and is told, with a policy-specific
//! [`Eviction::Hint`], what became resident, what was used and what left.
//!
//! One file per policy:
//! - [`start_tail`]: StartTail LRU (Varadhan & Manocha §4.3), P_I's reps;
//! - [`lru`]: least recently used, with demotion (P_I's pages);
//! - [`belady`]: the item used again last goes first (the clairvoyant
//!   reference);
//! - the MT node cache ([`crate::mt::cache::NodeCache`], Holst & Schumann
//!   §4.3): the node longest off the cut goes first.
//!
//! Every policy passes the same test harness (`harness.rs`): random
//! inserts, uses and removals against a model of the resident set, and
//! [`choose`] on its order under random budgets.

pub mod belady;
#[cfg(test)]
pub(crate) mod harness;
pub mod lru;
pub mod start_tail;

/// One item in eviction order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Victim<K> {
    pub key: K,
    /// Used since the policy's current epoch began (StartTail: accessed in
    /// this Stage II). A store may refuse to evict such items; policies
    /// without epochs never set it.
    pub recent: bool,
}

/// An eviction policy: the order in which resident items go.
pub trait Eviction {
    type Key: Copy + Eq + std::fmt::Debug;
    /// What the policy is told with an insert or a use: nothing for LRU,
    /// the next use for Belady, the partition and layer for the MT cache.
    type Hint;

    /// `key` became resident.
    fn insert(&mut self, key: Self::Key, hint: Self::Hint);
    /// `key`, resident, was used.
    fn access(&mut self, key: Self::Key, hint: Self::Hint);
    /// `key` is no longer resident (evicted or dropped); no-op when absent.
    fn remove(&mut self, key: Self::Key);
    /// The resident items, the first to go first.
    fn victims(&self) -> Box<dyn Iterator<Item = Victim<Self::Key>> + '_>;
    /// Whether `key` is resident.
    fn contains(&self, key: Self::Key) -> bool;
    /// How many items are resident.
    fn len(&self) -> usize;
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// What a store says of the next item in eviction order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// It may go.
    Take,
    /// It stays (pinned, kept); look further.
    Skip,
    /// It and everything after it stay (a prefetch reaching StartTail).
    Stop,
}

/// The victims that free at least `over` bytes, taken in `order` where
/// `verdict` allows; `cost(k)` is an item's bytes. `None` when the allowed
/// items do not free enough: then nothing should be evicted (an eviction
/// that cannot make the room only loses data). `over` 0 needs none.
pub fn choose<K: Copy>(
    order: impl IntoIterator<Item = Victim<K>>,
    over: u64,
    mut cost: impl FnMut(K) -> u64,
    mut verdict: impl FnMut(Victim<K>) -> Verdict,
) -> Option<Vec<K>> {
    let mut victims = Vec::new();
    let mut freed = 0u64;
    if over == 0 {
        return Some(victims);
    }
    for v in order {
        match verdict(v) {
            Verdict::Take => {}
            Verdict::Skip => continue,
            Verdict::Stop => break,
        }
        victims.push(v.key);
        freed += cost(v.key);
        if freed >= over {
            return Some(victims);
        }
    }
    None
}
