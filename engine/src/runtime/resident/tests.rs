//! The resident set against a plain model: a `Vec` in LRU order with the
//! StartTail position as an index, and the eviction rule written as a scan
//! over it.

use super::*;
use proptest::prelude::*;

#[derive(Clone, Debug)]
enum Op {
    /// Load rep (reserve after making room, then insert), as Stage II or a prefetch.
    Load(usize, bool),
    Access(usize),
    StartStage2(Vec<usize>),
    Remove(usize),
    /// Make room for this many bytes, as Stage II or a prefetch.
    Room(u64, bool),
}

fn op(n: usize) -> impl Strategy<Value = Op> {
    prop_oneof![
        4 => (0..n, any::<bool>()).prop_map(|(r, p)| Op::Load(r, p)),
        2 => (0..n).prop_map(Op::Access),
        1 => prop::collection::vec(0..n, 0..4).prop_map(Op::StartStage2),
        1 => (0..n).prop_map(Op::Remove),
        1 => (0u64..120, any::<bool>()).prop_map(|(b, p)| Op::Room(b, p)),
    ]
}

/// The plain model: LRU order, StartTail as an index into it.
#[derive(Default)]
struct Model {
    order: Vec<RepId>,
    mark: usize,
    pinned: Vec<RepId>,
    speculative: Vec<RepId>,
    bytes: u64,
}

impl Model {
    fn remove(&mut self, r: RepId, cost: &[u64]) {
        if let Some(i) = self.order.iter().position(|&x| x == r) {
            self.order.remove(i);
            if i < self.mark {
                self.mark -= 1;
            }
        }
        self.speculative.retain(|&y| y != r);
        self.bytes -= cost[r as usize];
    }

    fn access(&mut self, r: RepId) {
        if let Some(i) = self.order.iter().position(|&x| x == r) {
            self.order.remove(i);
            if i < self.mark {
                self.mark -= 1;
            }
        }
        self.order.insert(self.mark, r);
    }

    /// The reps the rule evicts, or `None` when room cannot be made.
    fn victims(
        &self,
        need: u64,
        budget: u64,
        prefetch: bool,
        cap: u64,
        cost: &[u64],
    ) -> Option<Vec<RepId>> {
        if self.bytes + need <= budget {
            return Some(Vec::new());
        }
        if need > budget {
            return None;
        }
        let spec_bytes: u64 = self.speculative.iter().map(|&r| cost[r as usize]).sum();
        let only_spec = prefetch && spec_bytes + need > cap;
        let mut after = self.bytes;
        let mut out = Vec::new();
        for (i, &r) in self.order.iter().enumerate() {
            if prefetch && i >= self.mark {
                break;
            }
            if self.pinned.contains(&r) || (only_spec && !self.speculative.contains(&r)) {
                continue;
            }
            out.push(r);
            after -= cost[r as usize];
            if after + need <= budget {
                return Some(out);
            }
        }
        None
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]
    #[test]
    fn make_room_evicts_what_the_plain_model_does_and_the_counts_stay_exact(
        costs in prop::collection::vec(1u64..40, 1..12),
        budget in 20u64..200,
        share in 0.0f64..1.0,
        ops in prop::collection::vec(op(12), 1..80),
    ) {
        let n = costs.len();
        let cap = (budget as f64 * share) as u64;
        let mut set = ResidentSet::new(costs.clone());
        let mut m = Model { pinned: vec![0], ..Model::default() };
        set.keep(0);
        let payload: Arc<[u8]> = Arc::from(vec![0u8; 1]);
        for o in ops {
            match o {
                Op::Load(r, prefetch) => {
                    let r = (r % n) as RepId;
                    if set.contains(r) {
                        continue;
                    }
                    let purpose = if prefetch { Purpose::Prefetch } else { Purpose::Demand };
                    let need = costs[r as usize];
                    let want = m.victims(need, budget, prefetch, cap, &costs);
                    let ok = set.make_room(need, budget, purpose, cap, |_| 1);
                    prop_assert_eq!(ok, want.is_some());
                    if let Some(v) = want {
                        let mut got = set.take_evicted();
                        let mut v2 = v.clone();
                        got.sort_unstable();
                        v2.sort_unstable();
                        prop_assert_eq!(got, v2);
                        for x in v {
                            m.remove(x, &costs);
                        }
                        set.reserve(need);
                        m.bytes += need;
                        prop_assert!(set.bytes() <= budget, "over the budget");
                        set.insert(r, payload.clone(), prefetch);
                        m.access(r);
                        if prefetch {
                            m.speculative.push(r);
                        }
                    } else {
                        prop_assert!(set.take_evicted().is_empty(), "evicted without making room");
                    }
                }
                Op::Access(r) => {
                    let r = (r % n) as RepId;
                    if set.contains(r) {
                        set.access(r);
                        m.access(r);
                    }
                }
                Op::StartStage2(front) => {
                    let front: Vec<RepId> = front.into_iter().map(|r| (r % n) as RepId).collect();
                    set.start_stage2(&front);
                    m.mark = m.order.len();
                    m.pinned = front.clone();
                    m.pinned.push(0);
                    m.speculative.retain(|r| !front.contains(r));
                }
                Op::Remove(r) => {
                    let r = (r % n) as RepId;
                    if set.contains(r) && r != 0 {
                        set.remove(r, 1);
                        let _ = set.take_evicted();
                        m.remove(r, &costs);
                    }
                }
                Op::Room(need, prefetch) => {
                    let purpose = if prefetch { Purpose::Prefetch } else { Purpose::Demand };
                    let want = m.victims(need, budget, prefetch, cap, &costs);
                    let ok = set.make_room(need, budget, purpose, cap, |_| 1);
                    prop_assert_eq!(ok, want.is_some());
                    let mut got = set.take_evicted();
                    got.sort_unstable();
                    let mut v = want.unwrap_or_default();
                    for &x in &v {
                        m.remove(x, &costs);
                    }
                    v.sort_unstable();
                    prop_assert_eq!(got, v);
                }
            }
            set.validate().map_err(TestCaseError::fail)?;
            prop_assert_eq!(set.bytes(), m.bytes);
        }
    }
}

#[test]
fn validate_catches_a_count_that_drifted() {
    let mut s = ResidentSet::new(vec![10, 20]);
    s.reserve(10);
    s.insert(0, Arc::from(vec![0u8; 1]), true);
    s.validate().unwrap();
    s.resident += 1;
    assert!(s.validate().is_err());
    s.resident -= 1;
    s.speculative_bytes = 0;
    assert!(s.validate().is_err());
}
