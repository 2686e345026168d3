use proptest::prelude::*;

use super::*;

/// Size of meta-node `m` in the tests: they differ, as real ones do.
fn size(m: u32) -> u32 {
    40 + (m * 37) % 100
}

/// The reference model: the rules written as plainly as possible (vectors,
/// linear scans, recomputed sums).
struct Model {
    holders: Vec<Holder>,
    spare: Vec<u32>,
    free: Vec<u32>,
    capacity: u64,
}

impl Model {
    fn used(&self) -> u64 {
        self.holders.iter().map(|x| u64::from(x.bytes)).sum()
    }
    fn find(&self, m: u32) -> Option<u32> {
        self.holders
            .iter()
            .position(|x| x.meta == m)
            .map(|h| h as u32)
    }
    fn release(&mut self, h: u32) {
        self.free.retain(|&f| f != h);
        self.holders[h as usize] = EMPTY;
        self.spare.push(h);
    }
    fn request(&mut self, m: u32, u: Urgency) -> Request {
        if let Some(h) = self.find(m) {
            if let Some(i) = self.free.iter().position(|&f| f == h) {
                self.free.remove(i);
                return Request::SecondChance(h);
            }
            return Request::Present(h);
        }
        let need = u64::from(size(m));
        if need > self.capacity {
            return Request::GiveUp;
        }
        let mut room = self.capacity - self.used();
        let mut victims = Vec::new();
        for &h in &self.free {
            if room >= need {
                break;
            }
            room += u64::from(self.holders[h as usize].bytes);
            victims.push(h);
        }
        if room < need {
            let unused = (0..self.holders.len() as u32)
                .filter(|h| {
                    let x = self.holders[*h as usize];
                    x.meta != NONE && x.usage == 0 && !self.free.contains(h)
                })
                .count();
            let ok = match u {
                Urgency::Prefetch => false,
                Urgency::Up => true,
                Urgency::Down => unused >= 3,
            };
            if !ok {
                return Request::GiveUp;
            }
            for h in 0..self.holders.len() as u32 {
                let x = self.holders[h as usize];
                if room < need
                    && x.meta != NONE
                    && x.usage == 0
                    && x.content == Content::Ready
                    && !self.free.contains(&h)
                {
                    room += u64::from(x.bytes);
                    victims.push(h);
                }
            }
            if room < need {
                return Request::GiveUp;
            }
        }
        let mut evicted = Vec::new();
        for h in victims {
            evicted.push((self.holders[h as usize].meta, h));
            self.release(h);
        }
        let h = self.spare.pop().unwrap_or_else(|| {
            self.holders.push(EMPTY);
            self.holders.len() as u32 - 1
        });
        self.holders[h as usize] = Holder {
            meta: m,
            bytes: size(m),
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
    fn buffer_manager_matches_the_reference_model(cap in 100u64..700, ops in prop::collection::vec(op(), 1..200)) {
        let mut b = BufferManager::new(cap);
        let mut m = Model { holders: Vec::new(), spare: Vec::new(), free: Vec::new(), capacity: cap };
        for o in ops {
            match o {
                Op::Request(x, u) => {
                    let u = [Urgency::Prefetch, Urgency::Up, Urgency::Down][u as usize];
                    prop_assert_eq!(b.request(x, size(x), u), m.request(x, u));
                }
                Op::Finish(x, ok) => {
                    if let Some(h) = m.find(x).filter(|&h| m.holders[h as usize].content == Content::Loading) {
                        prop_assert!(b.loaded(h, x, ok));
                        if ok {
                            m.holders[h as usize].content = Content::Ready;
                            m.flush(h);
                        } else {
                            m.release(h);
                        }
                    }
                }
                Op::RefInc(x) => {
                    let r = b.ref_inc(x, size(x));
                    prop_assert_eq!(&r, &m.request(x, Urgency::Prefetch));
                    if let Some(h) = r.holder() {
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
            prop_assert!(b.used() <= cap, "budget exceeded");
            prop_assert_eq!(b.used(), m.used());
            prop_assert_eq!(b.free_list(), m.free.clone());
            for h in 0..m.holders.len() as u32 {
                prop_assert_eq!(*b.holder(h), m.holders[h as usize]);
            }
        }
    }
}

fn load(b: &mut BufferManager, m: u32, bytes: u32, u: Urgency) -> u32 {
    match b.request(m, bytes, u) {
        Request::Load { holder, .. } => {
            assert!(b.loaded(holder, m, true));
            holder
        }
        r => panic!("meta {m}: {r:?}"),
    }
}

#[test]
fn a_flushed_meta_node_gets_a_second_chance_until_its_space_is_taken() {
    let mut b = BufferManager::new(200);
    let h0 = load(&mut b, 10, 100, Urgency::Prefetch);
    b.use_inc(h0);
    b.use_dec(h0); // flushed: end of the free list, still in the table
    assert!(!b.in_real(10) && b.find(10) == Some(h0));
    assert_eq!(
        b.request(10, 100, Urgency::Prefetch),
        Request::SecondChance(h0)
    );
    b.maybe_flush(h0);
    // Free bytes are used first; 10 keeps its place.
    let h1 = load(&mut b, 11, 100, Urgency::Prefetch);
    assert_eq!(b.find(10), Some(h0));
    b.maybe_flush(h1);
    assert_eq!(b.free_list(), vec![h0, h1]);
    // A bigger one takes both, front first.
    assert_eq!(
        b.request(12, 150, Urgency::Prefetch),
        Request::Load {
            holder: h1,
            evicted: vec![(10, h0), (11, h1)]
        }
    );
    assert_eq!(b.find(10), None);
    assert_eq!(b.used(), 150);
}

#[test]
fn urgent_switch_down_needs_three_unused_holders_switch_up_does_not() {
    let fill = || {
        let mut b = BufferManager::new(400);
        // Four prefetched (referenced, unused) meta-nodes fill the buffer.
        for m in 0..4 {
            let Request::Load { holder, .. } = b.ref_inc(m, 100) else {
                panic!()
            };
            assert!(b.loaded(holder, m, true));
        }
        b
    };
    let mut b = fill();
    assert_eq!(b.request(9, 100, Urgency::Prefetch), Request::GiveUp);
    // Two in use: two unused left, a switch down may not take one.
    b.use_inc(b.find(0).unwrap());
    b.use_inc(b.find(1).unwrap());
    assert_eq!(b.unused_in_real(), 2);
    assert_eq!(b.request(9, 100, Urgency::Down), Request::GiveUp);
    // A switch up always may: the first prefetched-only holder goes.
    let h2 = b.find(2).unwrap();
    assert_eq!(
        b.request(9, 100, Urgency::Up),
        Request::Load {
            holder: h2,
            evicted: vec![(2, h2)]
        }
    );
    // With three unused a switch down may too.
    let mut b = fill();
    b.use_inc(b.find(0).unwrap());
    assert!(
        matches!(b.request(9, 100, Urgency::Down), Request::Load { ref evicted, .. } if evicted[0].0 == 1)
    );
    // Nothing bigger than the whole buffer.
    assert_eq!(b.request(99, 401, Urgency::Up), Request::GiveUp);
}
