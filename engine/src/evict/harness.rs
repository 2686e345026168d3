//! The test harness every eviction policy passes: random inserts, uses and
//! removals against a model of the resident set, and [`choose`] on the
//! policy's order under random budgets and refusals.

use std::collections::BTreeSet;

use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};

use super::{Eviction, Verdict, Victim, choose};

/// Keys the harness uses: `0..KEYS`.
const KEYS: u32 = 24;

/// Runs the harness on the policies `make(KEYS)` makes; `hint(key, step)`
/// is what the policy is told with an insert or a use at step `step`.
pub(crate) fn check<P: Eviction<Key = u32>>(
    make: impl Fn(u32) -> P,
    hint: impl Fn(u32, u32) -> P::Hint,
) {
    let ops = prop::collection::vec((0u8..3, 0..KEYS, 0u64..200, 0u32..4), 0..200);
    let mut runner = TestRunner::new(Config {
        cases: 64,
        ..Config::default()
    });
    runner
        .run(&ops, |ops| {
            let mut p = make(KEYS);
            let mut model = BTreeSet::new();
            for (step, &(op, k, over, refuse)) in ops.iter().enumerate() {
                let step = step as u32;
                match op {
                    0 if !model.contains(&k) => {
                        p.insert(k, hint(k, step));
                        model.insert(k);
                    }
                    0 | 1 if model.contains(&k) => p.access(k, hint(k, step)),
                    _ => {
                        p.remove(k);
                        model.remove(&k);
                    }
                }
                // The order lists every resident item once, and nothing else.
                let order: Vec<Victim<u32>> = p.victims().collect();
                let keys: BTreeSet<u32> = order.iter().map(|v| v.key).collect();
                prop_assert_eq!(keys.len(), order.len(), "an item listed twice");
                prop_assert_eq!(&keys, &model);
                prop_assert_eq!(p.len(), model.len());
                prop_assert_eq!(p.is_empty(), model.is_empty());
                for x in 0..KEYS {
                    prop_assert_eq!(p.contains(x), model.contains(&x));
                }
                // `choose`: the shortest run of allowed items, in order, that
                // frees `over` bytes, or none when they cannot.
                let cost = |x: u32| u64::from(x % 5) * 10 + 1;
                let allowed = |v: Victim<u32>| v.key % 4 != refuse;
                let verdict = |v: Victim<u32>| {
                    if allowed(v) {
                        Verdict::Take
                    } else {
                        Verdict::Skip
                    }
                };
                let take: Vec<u32> = order
                    .iter()
                    .filter(|&&v| allowed(v))
                    .map(|v| v.key)
                    .collect();
                match choose(order.iter().copied(), over, cost, verdict) {
                    Some(v) => {
                        prop_assert_eq!(&v[..], &take[..v.len()]);
                        let freed: u64 = v.iter().map(|&x| cost(x)).sum();
                        prop_assert!(freed >= over);
                        if let Some(&last) = v.last() {
                            prop_assert!(freed - cost(last) < over, "more than needed");
                        }
                    }
                    None => {
                        let all: u64 = take.iter().map(|&x| cost(x)).sum();
                        prop_assert!(all < over);
                    }
                }
            }
            Ok(())
        })
        .unwrap();
}

#[test]
fn choose_stops_where_the_store_says_stop() {
    let order = [3u32, 1, 4, 1, 5].map(|key| Victim {
        key,
        recent: key == 4,
    });
    let verdict = |v: Victim<u32>| {
        if v.recent {
            Verdict::Stop
        } else {
            Verdict::Take
        }
    };
    assert_eq!(choose(order, 2, |_| 1, verdict), Some(vec![3, 1]));
    assert_eq!(choose(order, 3, |_| 1, verdict), None);
    assert_eq!(choose(order, 0, |_| 1, verdict), Some(vec![]));
}
