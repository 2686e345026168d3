use super::*;
use crate::runtime::resident::ResidentSet;
use proptest::prelude::*;

fn bounded(total: u64, occluders: u64) -> Footprint {
    Footprint::new(&RuntimeParams {
        mode: Mode::Pre,
        budget_bytes: total,
        occlusion_bytes: occluders,
        page_share: 0.25,
        ..RuntimeParams::default()
    })
    .unwrap()
}

#[test]
fn the_shares_are_derived_from_the_budget_once() {
    let f = bounded(1000, 200);
    assert_eq!(
        (f.total(), f.occluders(), f.reps()),
        (Some(1000), 200, Some(800))
    );
    // Pages: a quarter of P_I's side, when it holds two pages.
    assert_eq!(f.pages_cap(100, true), 200);
    assert_eq!(f.pages_cap(101, true), 0, "two pages do not fit the share");
    assert_eq!(f.pages_cap(100, false), 0);
    // A prefetch leaves the pages' whole cap; a demand read only what they hold.
    assert_eq!(f.rep_room(50, 200, Purpose::Prefetch), Some(600));
    assert_eq!(f.rep_room(50, 200, Purpose::Demand), Some(750));
    assert_eq!(f.speculative_cap(), 480, "0.6 of P_I's side");
    assert!(f.check_root(800).is_ok());
    assert!(matches!(
        f.check_root(801),
        Err(RuntimeError::BudgetTooSmall {
            budget: 800,
            need: 801
        })
    ));
    assert_eq!(f.unfit(800), None);
    assert_eq!(f.unfit(900), Some(900));
}

#[test]
fn requests_started_ahead_get_at_most_an_eighth_of_p_is_side() {
    let f = bounded(1000, 200).with_read_ahead(1 << 20);
    assert_eq!((f.in_flight(), f.reps()), (100, Some(700)));
    assert_eq!(bounded(1000, 200).with_read_ahead(40).in_flight(), 40);
    assert_eq!(bounded(1000, 0).with_read_ahead(0), bounded(1000, 0));
    let core = Footprint::InCore { occluders: 0 };
    assert_eq!(
        core.with_read_ahead(1 << 20).in_flight(),
        0,
        "in core: read at start"
    );
}

#[test]
fn in_core_is_a_variant_that_bounds_nothing() {
    let p = RuntimeParams {
        mode: Mode::Incore,
        budget_bytes: 10,
        occlusion_bytes: 4096,
        ..RuntimeParams::default()
    };
    let f = Footprint::new(&p).unwrap();
    assert_eq!(f, Footprint::InCore { occluders: 4096 });
    assert_eq!((f.total(), f.reps()), (None, None));
    assert_eq!(f.rep_room(0, 0, Purpose::Demand), None);
    assert_eq!(f.pages_cap(4096, true), 0, "no pages in core");
    assert!(f.holds(Held {
        reps: u64::MAX / 2,
        pages: 0
    }));
    assert!(f.check_root(u64::MAX).is_ok());
    assert_eq!(f.unfit(u64::MAX), None);
}

#[test]
fn nonsense_shares_are_refused_where_they_are_derived() {
    let ok = RuntimeParams {
        mode: Mode::Pre,
        budget_bytes: 1000,
        ..RuntimeParams::default()
    };
    for bad in [
        RuntimeParams {
            occlusion_bytes: 501,
            ..ok
        },
        RuntimeParams {
            page_share: 0.95,
            ..ok
        },
        RuntimeParams {
            page_share: f32::NAN,
            ..ok
        },
        RuntimeParams {
            prefetch: crate::runtime::PrefetchParams {
                speculative_share: 0.0,
                ..ok.prefetch
            },
            ..ok
        },
    ] {
        assert!(
            matches!(Footprint::new(&bad), Err(RuntimeError::Params(_))),
            "{bad:?}"
        );
        assert!(bad.check().is_err());
    }
    assert!(
        Footprint::new(&RuntimeParams {
            occlusion_bytes: 500,
            ..ok
        })
        .is_ok()
    );
}

/// What P_I does to its side of the footprint, as the loader does it.
#[derive(Clone, Debug)]
enum Op {
    /// Read rep `r` for Stage II or a prefetch: room made, bytes reserved
    /// while in flight, then the rep resident (or the read given up).
    Read { r: u32, prefetch: bool, fails: bool },
    /// A page of `n` bytes read on a seek-bound disk.
    Page { n: u64 },
    /// A new frame: Stage II starts and the pages' cap is planned again.
    Frame { paging: bool },
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        (0u32..40, any::<bool>(), prop::bool::weighted(0.1))
            .prop_map(|(r, prefetch, fails)| Op::Read { r, prefetch, fails }),
        (1u64..300).prop_map(|n| Op::Page { n }),
        any::<bool>().prop_map(|paging| Op::Frame { paging }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]
    /// Random reps, pages and reservations under the footprint's rules:
    /// what P_I holds, with the occluders, never exceeds the user's budget,
    /// after every step.
    #[test]
    fn reps_pages_and_reservations_never_exceed_the_budget(
        total in 2000u64..20_000,
        occ_share in 0.0f64..0.5,
        // What a network source would hold for requests started ahead.
        ahead in prop_oneof![Just(0u64), 0u64..10_000],
        costs in prop::collection::vec(1u64..900, 40),
        scratch in prop::collection::vec(prop_oneof![Just(0u64), 1u64..300], 40),
        ops in prop::collection::vec(op(), 1..200),
    ) {
        let f = bounded(total, (total as f64 * occ_share) as u64).with_read_ahead(ahead);
        let side = f.reps().unwrap();
        let mut res = ResidentSet::new(costs.clone());
        // The pages held, least recently used first.
        let mut pages: Vec<u64> = Vec::new();
        let mut cap = 0;
        let page_bytes: u64 = 300;
        let check = |res: &ResidentSet, pages: &[u64]| {
            let held = Held { reps: res.bytes(), pages: pages.iter().sum() };
            prop_assert!(f.holds(held), "{held:?} over {side}");
            prop_assert!(held.sum() + f.occluders() + f.in_flight() <= total);
            prop_assert!(res.validate().is_ok());
            Ok(())
        };
        for o in ops {
            match o {
                Op::Frame { paging } => {
                    res.start_stage2(&[]);
                    cap = f.pages_cap(page_bytes, paging);
                    while pages.iter().sum::<u64>() > cap {
                        pages.remove(0);
                    }
                }
                Op::Page { n } => {
                    let n = n.min(page_bytes);
                    let held = |res: &ResidentSet, pages: &[u64]| Held {
                        reps: res.bytes(),
                        pages: pages.iter().sum(),
                    };
                    while !f.page_fits(held(&res, &pages), cap, n) && !pages.is_empty() {
                        pages.remove(0);
                    }
                    if f.page_fits(held(&res, &pages), cap, n) {
                        pages.push(n);
                    }
                }
                Op::Read { r, prefetch, fails } => {
                    if res.contains(r) {
                        continue;
                    }
                    let purpose = if prefetch { Purpose::Prefetch } else { Purpose::Demand };
                    // Its footprint, and the stored copy held while it expands.
                    let need = costs[r as usize] + scratch[r as usize];
                    let p: u64 = pages.iter().sum();
                    let room = f.rep_room(p, cap, purpose).unwrap();
                    let mut ok = res.make_room(need, room, purpose, f.speculative_cap(), |_| 0);
                    if !ok && purpose == Purpose::Demand && !pages.is_empty() {
                        // A demand read takes the pages' room back.
                        pages.clear();
                        let room = f.rep_room(0, cap, purpose).unwrap();
                        ok = res.make_room(need, room, purpose, f.speculative_cap(), |_| 0);
                    }
                    if !ok {
                        continue;
                    }
                    res.reserve(need);
                    check(&res, &pages)?;
                    if fails {
                        res.release(need);
                    } else {
                        res.release(scratch[r as usize]);
                        res.insert(r, vec![0u8; 1].into(), prefetch);
                    }
                }
            }
            check(&res, &pages)?;
        }
    }
}
