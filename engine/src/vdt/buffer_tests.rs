use proptest::prelude::*;

use super::*;

/// The reference model: the paper's rules written as plainly as possible
/// (vectors, linear scans).
#[derive(Default)]
struct Model {
    holders: Vec<Holder>,
    free: Vec<u32>,
}

impl Model {
    fn new(k: usize) -> Self {
        Self {
            holders: vec![
                Holder {
                    meta: NONE,
                    usage: 0,
                    refs: 0,
                    content: Content::Empty
                };
                k
            ],
            free: (0..k as u32).collect(),
        }
    }
    fn find(&self, m: u32) -> Option<u32> {
        self.holders.iter().position(|x| x.meta == m).map(|h| h as u32)
    }
    fn request(&mut self, m: u32, u: Urgency) -> Request {
        if let Some(h) = self.find(m) {
            if let Some(i) = self.free.iter().position(|&f| f == h) {
                self.free.remove(i);
                return Request::SecondChance(h);
            }
            return Request::Present(h);
        }
        let h = if !self.free.is_empty() {
            self.free.remove(0)
        } else {
            let unused = self
                .holders
                .iter()
                .filter(|x| x.meta != NONE && x.usage == 0)
                .count();
            let ok = match u {
                Urgency::Prefetch => false,
                Urgency::Up => true,
                Urgency::Down => unused >= 3,
            };
            match self
                .holders
                .iter()
                .position(|x| x.meta != NONE && x.usage == 0 && x.content == Content::Ready)
            {
                Some(v) if ok => v as u32,
                _ => return Request::GiveUp,
            }
        };
        let evicted = self.holders[h as usize].meta;
        self.holders[h as usize] = Holder {
            meta: m,
            usage: 0,
            refs: 0,
            content: Content::Loading,
        };
        Request::Load { holder: h, evicted }
    }
    fn flush(&mut self, h: u32) {
        let x = self.holders[h as usize];
        if x.usage == 0 && x.refs == 0 && x.content == Content::Ready && !self.free.contains(&h) {
            self.free.push(h);
        }
    }
}

#[derive(Clone, Debug)]
enum Op {
    Request(u32, u8),
    Finish(u32, bool),
    RefInc(u32),
    RefDec(u32),
    UseInc(u32),
    UseDec(u32),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        (0..12u32, 0..3u8).prop_map(|(m, u)| Op::Request(m, u)),
        (0..12u32, proptest::bool::weighted(0.9)).prop_map(|(m, ok)| Op::Finish(m, ok)),
        (0..12u32).prop_map(Op::RefInc),
        (0..12u32).prop_map(Op::RefDec),
        (0..12u32).prop_map(Op::UseInc),
        (0..12u32).prop_map(Op::UseDec),
    ]
}

proptest! {
    #[test]
    fn buffer_manager_matches_the_reference_model(k in 1usize..7, ops in prop::collection::vec(op(), 1..200)) {
        let mut b = BufferManager::new(k);
        let mut m = Model::new(k);
        for o in ops {
            match o {
                Op::Request(x, u) => {
                    let u = [Urgency::Prefetch, Urgency::Up, Urgency::Down][u as usize];
                    prop_assert_eq!(b.request(x, u), m.request(x, u));
                }
                Op::Finish(x, ok) => {
                    if let Some(h) = m.find(x).filter(|&h| m.holders[h as usize].content == Content::Loading) {
                        prop_assert!(b.loaded(h, x, ok));
                        if ok {
                            m.holders[h as usize].content = Content::Ready;
                            m.flush(h);
                        } else {
                            m.holders[h as usize] = Holder { meta: NONE, usage: 0, refs: 0, content: Content::Empty };
                            m.free.retain(|&f| f != h);
                            m.free.insert(0, h);
                        }
                    }
                }
                Op::RefInc(x) => {
                    let r = b.ref_inc(x);
                    prop_assert_eq!(r, m.request(x, Urgency::Prefetch));
                    if let Request::Present(h) | Request::SecondChance(h) | Request::Load { holder: h, .. } = r {
                        m.holders[h as usize].refs += 1;
                    }
                }
                Op::RefDec(x) => {
                    b.ref_dec(x);
                    if let Some(h) = m.find(x).filter(|h| !m.free.contains(h)) {
                        let r = &mut m.holders[h as usize].refs;
                        *r = r.saturating_sub(1);
                        m.flush(h);
                    }
                }
                // Only the navigating side uses ready meta-nodes in real memory.
                Op::UseInc(x) | Op::UseDec(x) => {
                    if let Some(h) = b.ready(x) {
                        if matches!(o, Op::UseInc(_)) {
                            b.use_inc(h);
                            m.holders[h as usize].usage += 1;
                        } else {
                            b.use_dec(h);
                            let u = &mut m.holders[h as usize].usage;
                            *u = u.saturating_sub(1);
                            m.flush(h);
                        }
                    }
                }
            }
            b.validate().map_err(TestCaseError::fail)?;
            prop_assert_eq!(b.free_list(), m.free.clone());
            for h in 0..k as u32 {
                prop_assert_eq!(*b.holder(h), m.holders[h as usize]);
            }
        }
    }
}

fn load(b: &mut BufferManager, m: u32, u: Urgency) -> u32 {
    match b.request(m, u) {
        Request::Load { holder, .. } => {
            assert!(b.loaded(holder, m, true));
            holder
        }
        r => panic!("meta {m}: {r:?}"),
    }
}

#[test]
fn a_flushed_meta_node_gets_a_second_chance_until_its_holder_is_reused() {
    let mut b = BufferManager::new(2);
    let h0 = load(&mut b, 10, Urgency::Prefetch);
    b.use_inc(h0);
    b.use_dec(h0); // flushed: end of the free list, still in the table
    assert!(!b.in_real(10) && b.find(10) == Some(h0));
    assert_eq!(b.request(10, Urgency::Prefetch), Request::SecondChance(h0));
    b.maybe_flush(h0);
    // The other (never used) holder is taken first; then 10's.
    let h1 = load(&mut b, 11, Urgency::Prefetch);
    assert_ne!(h1, h0);
    assert_eq!(b.find(10), Some(h0));
    b.maybe_flush(h1);
    assert_eq!(b.free_list(), vec![h0, h1]);
    assert_eq!(
        b.request(12, Urgency::Prefetch),
        Request::Load {
            holder: h0,
            evicted: 10
        }
    );
    assert_eq!(b.find(10), None);
}

#[test]
fn urgent_switch_down_needs_three_unused_holders_switch_up_does_not() {
    let mut b = BufferManager::new(4);
    // Four prefetched (referenced, unused) meta-nodes fill every holder.
    for m in 0..4 {
        let r = b.ref_inc(m);
        let Request::Load { holder, .. } = r else {
            panic!("{r:?}")
        };
        assert!(b.loaded(holder, m, true));
    }
    assert_eq!(b.request(9, Urgency::Prefetch), Request::GiveUp);
    // Two in use: two unused left, a switch down may not take one.
    b.use_inc(b.find(0).unwrap());
    b.use_inc(b.find(1).unwrap());
    assert_eq!(b.unused_in_real(), 2);
    assert_eq!(b.request(9, Urgency::Down), Request::GiveUp);
    // A switch up always may: the first prefetched-only holder goes.
    let h2 = b.find(2).unwrap();
    assert_eq!(
        b.request(9, Urgency::Up),
        Request::Load {
            holder: h2,
            evicted: 2
        }
    );
    // With three unused a switch down may too.
    let mut b = BufferManager::new(4);
    for m in 0..4 {
        let Request::Load { holder, .. } = b.ref_inc(m) else {
            panic!()
        };
        b.loaded(holder, m, true);
    }
    b.use_inc(b.find(0).unwrap());
    assert!(matches!(b.request(9, Urgency::Down), Request::Load { evicted: 1, .. }));
}
