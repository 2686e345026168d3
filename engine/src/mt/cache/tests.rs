//! The caching policy against a reference model that scans every resident
//! node each frame (the paper's rules read literally), on random loads and
//! cuts.

use std::collections::BTreeMap;

use proptest::prelude::*;

use super::*;

const NODES: u32 = 30;
const PER_PART: u32 = 5;

fn part(n: u32) -> u32 {
    n / PER_PART
}

fn layer(n: u32) -> u32 {
    // Layers rise with the node id, with some spread inside a partition.
    n / 3 + n % 2
}

/// The rules with a full scan: resident node → last frame on the cut.
#[derive(Default)]
struct Reference {
    nodes: BTreeMap<u32, i64>,
    tmin: BTreeMap<u32, Tuple>,
    tmax: BTreeMap<u32, Tuple>,
}

impl Reference {
    fn read_partition(&mut self, p: u32, mode: CacheMode) {
        let nodes: Vec<u32> = if mode.partitions() {
            (p * PER_PART..(p + 1) * PER_PART).collect()
        } else {
            vec![p * PER_PART]
        };
        if mode.partitions() {
            self.tmin.insert(p, (-1, -1));
            self.tmax.insert(p, (-1, -1));
        }
        for n in nodes {
            self.tmin.entry(p).or_insert((-1, -1));
            self.tmax.entry(p).or_insert((-1, -1));
            self.nodes.entry(n).or_insert(-1);
        }
    }

    fn end_frame(
        &mut self,
        f: i64,
        arcs: &[(u32, Option<u32>, Mark)],
        mode: CacheMode,
    ) -> Vec<u32> {
        for &(h, c, m) in arcs.iter().filter(|a| a.2 != Mark::Old) {
            let ends: Vec<u32> = std::iter::once(h)
                .chain(c)
                .filter(|n| self.nodes.contains_key(n))
                .collect();
            for n in ends {
                let l = i64::from(layer(n));
                let t = if m == Mark::TopDown {
                    self.tmin.get_mut(&part(n)).unwrap()
                } else {
                    self.tmax.get_mut(&part(n)).unwrap()
                };
                *t = if t.0 == f { (f, t.1.min(l)) } else { (f, l) };
            }
        }
        for &(h, c, _) in arcs.iter().filter(|a| a.2 == Mark::Old) {
            let ends: Vec<u32> = std::iter::once(h)
                .chain(c)
                .filter(|n| self.nodes.contains_key(n))
                .collect();
            for n in ends {
                self.tmin.get_mut(&part(n)).unwrap().0 = f;
                self.tmax.get_mut(&part(n)).unwrap().0 = f;
            }
        }
        let on_cut = |n: u32| arcs.iter().any(|&(h, c, _)| h == n || c == Some(n));
        let mut gone = Vec::new();
        for (&n, last) in self.nodes.iter_mut() {
            if on_cut(n) {
                *last = f;
                continue;
            }
            let (p, l) = (part(n), i64::from(layer(n)));
            let keep = match mode {
                CacheMode::NpNc | CacheMode::PNc => false,
                CacheMode::PCc => (0..NODES).any(|m| part(m) == p && on_cut(m)),
                CacheMode::PC => {
                    let (tn, tx) = (self.tmin[&p], self.tmax[&p]);
                    (tn.0 == f && l > tn.1) || (tx.0 == f && l > tx.1)
                }
            };
            if !keep {
                gone.push(n);
            }
        }
        for n in &gone {
            self.nodes.remove(n);
            let p = part(*n);
            if !self.nodes.keys().any(|&m| part(m) == p) {
                self.tmin.remove(&p);
                self.tmax.remove(&p);
            }
        }
        gone
    }
}

#[derive(Clone, Debug)]
enum Op {
    Read(u32),
    Frame(Vec<(u32, Option<u32>, u8)>),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        (0..NODES / PER_PART).prop_map(Op::Read),
        proptest::collection::vec((0..NODES, proptest::option::of(0..NODES), 0u8..3), 0..8)
            .prop_map(Op::Frame),
    ]
}

proptest! {
    #[test]
    fn the_queue_decides_as_the_full_scan(
        mode in 0usize..4,
        ops in proptest::collection::vec(op(), 1..60),
    ) {
        let mode = CacheMode::ALL[mode];
        let mut c = NodeCache::new(mode);
        let mut r = Reference::default();
        let mut f = 0i64;
        for o in ops {
            match o {
                Op::Read(p) => {
                    if mode.partitions() {
                        c.partition_read(p);
                        for n in p * PER_PART..(p + 1) * PER_PART {
                            c.loaded(n, p, layer(n));
                        }
                    } else {
                        c.loaded(p * PER_PART, p, layer(p * PER_PART));
                    }
                    r.read_partition(p, mode);
                }
                Op::Frame(arcs) => {
                    let arcs: Vec<(u32, Option<u32>, Mark)> = arcs
                        .into_iter()
                        .map(|(h, c, m)| (h, c, [Mark::Old, Mark::TopDown, Mark::BottomUp][m as usize]))
                        .collect();
                    let got = c.end_frame(f, &arcs, &part);
                    let want = r.end_frame(f, &arcs, mode);
                    prop_assert_eq!(got, want, "frame {}", f);
                    f += 1;
                }
            }
            let resident: Vec<u32> = (0..NODES).filter(|&n| c.is_resident(n)).collect();
            let want: Vec<u32> = r.nodes.keys().copied().collect();
            prop_assert_eq!(resident, want);
            for p in 0..NODES / PER_PART {
                let t = r.tmin.get(&p).copied().zip(r.tmax.get(&p).copied());
                prop_assert_eq!(c.tuples(p), t, "tuples of partition {}", p);
            }
        }
    }
}

#[test]
fn rule_3_keeps_nodes_below_the_top_down_layer_only() {
    let mut c = NodeCache::new(CacheMode::PC);
    c.partition_read(0);
    for n in 0..5 {
        c.loaded(n, 0, n);
    }
    // A top-down arc at node 2 (layer 2): nodes 3 and 4 lie below it.
    let gone = c.end_frame(0, &[(2, None, Mark::TopDown)], &|_| 0);
    assert_eq!(gone, vec![0, 1]);
    assert_eq!(c.tuples(0), Some(((0, 2), (-1, -1))));
    // Next frame the arc is old: frames move on, layers stay.
    let gone = c.end_frame(1, &[(2, None, Mark::Old)], &|_| 0);
    assert!(gone.is_empty());
    assert_eq!(c.tuples(0), Some(((1, 2), (1, -1))));
    // With no arc in the partition any more, everything off the cut goes.
    let gone = c.end_frame(2, &[], &|_| 0);
    assert_eq!(gone, vec![2, 3, 4]);
    assert_eq!(c.tuples(0), None);
}

#[test]
fn passes_the_eviction_harness() {
    crate::evict::harness::check(|_| NodeCache::new(CacheMode::PC), |k, _| (k % 3, k % 5));
}
