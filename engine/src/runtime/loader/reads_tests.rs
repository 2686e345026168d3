//! P_I's reads without a thread: an in-memory scene, a manual clock, and
//! a [`Turn`] the test sets.

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::*;
use crate::clock::ManualClock;
use crate::runtime::tests::{clocked, params, wide_compressed};

/// The command loop as a test sets it.
#[derive(Default)]
struct TestTurn {
    /// Preemption checks so far; a fetch command arrives at check
    /// `preempt_at` (counting from 1).
    checks: u32,
    preempt_at: Option<u32>,
    /// The prefetch candidates.
    queued: Vec<RepId>,
}

impl Turn for TestTurn {
    fn preempted(&mut self) -> bool {
        self.checks += 1;
        self.preempt_at.is_some_and(|n| self.checks >= n)
    }

    fn queued(&self, r: RepId, _frame: u32) -> bool {
        self.queued.contains(&r)
    }

    fn is_late(&self, _r: RepId, _frame: u32) -> bool {
        false
    }

    fn is_recent(&self, r: RepId) -> bool {
        self.queued.contains(&r)
    }

    fn ends_in_time(&mut self, _now: Instant, _need_s: f64) -> bool {
        true
    }
}

/// Reads of the 64-leaf test scene from `source` under a budget of the
/// whole scene, with `page_bytes` pages and blocks of `block_bytes`.
fn reads_of(source: Arc<dyn crate::ByteSource>, page_bytes: u64, block_bytes: usize) -> Reads {
    let (skel, _) = wide_compressed(64);
    let total: u64 = skel.reps.iter().map(|r| r.resident_len()).sum();
    let p = RuntimeParams {
        page_bytes,
        coalesce_max_gap: 1 << 20,
        ..params(Mode::Pre, 2 * total)
    };
    let fp = Footprint::new(&p).unwrap();
    // Blocks below the parameters' 512-byte floor: the test scene's reps
    // are a few hundred bytes, and a preemption needs several blocks.
    let rp = ReadParams {
        block_bytes,
        ..ReadParams::of(&p)
    };
    let pools = vec![Some(0); skel.reps.len()];
    let clock = Arc::new(ManualClock::new());
    Reads::new(skel, source, &pools, (rp, fp), clock)
}

/// The reps in file order, the root's left out.
fn in_file_order(reads: &Reads) -> Vec<RepId> {
    let root = reads.skeleton.nodes[0].first_rep;
    let order = reads.skeleton.reps_in_file_order();
    order.into_iter().filter(|&r| r != root).collect()
}

#[test]
fn a_preempted_prefetch_read_stays_reserved_and_goes_on_where_it_stopped() {
    let (_, mem) = wide_compressed(64);
    let mut reads = reads_of(mem, 0, 16);
    let r = in_file_order(&reads)
        .into_iter()
        .find(|&r| reads.skeleton.reps[r as usize].len > 3 * 16)
        .expect("a rep of several blocks");
    let rec = reads.skeleton.reps[r as usize];
    let held = reads.cost(r) + rec.load_scratch();
    let mut turn = TestTurn {
        preempt_at: Some(1),
        ..TestTurn::default()
    };
    assert_eq!(
        reads.load(r, Purpose::Prefetch, &mut turn),
        Err(LoadError::Preempted)
    );
    let p = reads.partial.as_ref().expect("kept");
    assert_eq!((p.rep, p.done), (r, 16), "one block read");
    assert_eq!(reads.res.reserved(), held, "its footprint stays reserved");
    assert_eq!(reads.stats.prefetch_bytes, 16);
    // The next read of it goes on from the second block and completes.
    let mut idle = TestTurn::default();
    reads.load(r, Purpose::Prefetch, &mut idle).unwrap();
    assert!(reads.partial.is_none() && reads.res.contains(r));
    assert_eq!(reads.stats.resumed, 1);
    assert_eq!(reads.stats.prefetch_bytes, u64::from(rec.len));
    assert_eq!(reads.res.reserved(), 0);
    assert_eq!(reads.res.bytes(), reads.cost(r));
    // A preempted read given up releases what it held.
    let s = in_file_order(&reads)
        .into_iter()
        .find(|&s| s != r && reads.skeleton.reps[s as usize].len > 3 * 16)
        .unwrap();
    let mut turn = TestTurn {
        preempt_at: Some(1),
        ..TestTurn::default()
    };
    assert!(reads.load(s, Purpose::Prefetch, &mut turn).is_err());
    assert!(reads.res.reserved() > 0);
    assert!(reads.cancel_partial() && !reads.cancel_partial());
    assert_eq!(reads.res.reserved(), 0);
}

#[test]
fn a_read_through_a_gap_keeps_the_candidates_on_it_and_discards_the_rest() {
    let (_, mem) = wide_compressed(64);
    let mut reads = reads_of(mem, 0, 512);
    let order = in_file_order(&reads);
    let (a, b, c, d) = (order[0], order[1], order[2], order[3]);
    let skel = reads.skeleton.clone();
    let rec = |r: RepId| skel.reps[r as usize];
    let mut turn = TestTurn {
        queued: vec![c],
        ..TestTurn::default()
    };
    reads.load(a, Purpose::Demand, &mut turn).unwrap();
    let from = rec(a).offset + u64::from(rec(a).len);
    assert_eq!(reads.costs.last_end(), Some(from));
    let to = rec(d).offset;
    assert!(reads.bridge(from, to, Purpose::Demand, &mut turn));
    assert!(reads.res.contains(c), "the candidate on the way is kept");
    assert!(!reads.res.contains(b), "the rest is discarded");
    assert_eq!(reads.costs.last_end(), Some(to), "the next read seeks not");
    assert_eq!(
        reads.stats.skipped_bytes,
        to - from - u64::from(rec(c).len),
        "every byte between is read once"
    );
    // A gap longer than the learnt break-even is not read through.
    reads.costs.seek_s = 1e-6;
    reads.costs.per_byte_s = 1e-6;
    let far = rec(order[20]).offset;
    assert!(!reads.bridge(to, far, Purpose::Demand, &mut turn));
    assert_eq!(reads.costs.last_end(), Some(to));
}

/// Reads of the test scene by 4 KiB pages from a disk of 10 ms seeks and
/// 30 MB/s (a seek costs 300 KB of transfer), its costs learnt; and the
/// scene's bytes.
fn paged_on_a_seek_bound_disk() -> (Reads, Arc<dyn crate::ByteSource>) {
    let (_, mem) = wide_compressed(64);
    let clock = Arc::new(ManualClock::new());
    let hdd = clocked(&mem, Duration::from_millis(10), 30e6, &clock);
    let mut reads = reads_of(hdd, 4096, 512);
    reads.clock = clock;
    reads.costs.seek_s = 0.010;
    reads.costs.per_byte_s = 1.0 / 30e6;
    reads.plan_pages();
    assert!(reads.pages_on(), "a seek costs more than a page");
    (reads, mem)
}

#[test]
fn on_a_seek_bound_disk_a_page_read_once_serves_its_neighbours() {
    let (mut reads, _) = paged_on_a_seek_bound_disk();
    let order = in_file_order(&reads);
    let skel = reads.skeleton.clone();
    let rec = |r: RepId| skel.reps[r as usize];
    let (a, b) = (order[0], order[1]);
    assert_eq!(
        rec(a).offset / 4096,
        rec(b).offset / 4096,
        "neighbours in one page"
    );
    let mut turn = TestTurn::default();
    reads.load(a, Purpose::Demand, &mut turn).unwrap();
    assert_eq!(reads.stats.stage2_seeks, 1);
    let page_read = reads.stats.stage2_bytes;
    assert!(page_read > u64::from(rec(a).len), "the whole page is read");
    assert_eq!(reads.pages.bytes(), page_read, "and held");
    // Its neighbour is a copy out of the page: no read, no seek.
    let expected_s = reads.first_block_s(b);
    assert_eq!(expected_s, reads.costs.overhead_s);
    reads.load(b, Purpose::Demand, &mut turn).unwrap();
    assert_eq!(reads.stats.page_hits, 1);
    assert_eq!(reads.stats.stage2_seeks, 1);
    assert_eq!(reads.stats.stage2_bytes, page_read);
    // The pages count in the footprint beside the reps (and the frame's
    // maximum also counts the compressed copy of a rep being expanded).
    let now = reads.res.bytes() + reads.pages.bytes();
    assert!(reads.stats.max_resident_bytes >= now + u64::from(rec(b).len));
    // A demand read that finds no other room takes the pages'.
    assert!(reads.yield_pages() && reads.pages.bytes() == 0);
}

#[test]
fn a_rep_straddling_two_pages_where_one_fits_is_read_as_it_is() {
    let (mut reads, mem) = paged_on_a_seek_bound_disk();
    // The test scene's reps each lie in one page; a record across the
    // boundary of pages 1 and 2 stands for one that does not.
    let mut rec = reads.skeleton.reps[1];
    (rec.offset, rec.len) = (2 * 4096 - 64, 128);
    // Beside what is held, one page fits: room for its second page could
    // only be made by evicting its first (which read them in turn for ever).
    let room = reads.rep_room(Purpose::Demand).unwrap();
    reads.res.reserve(room - 4096);
    let mut buf = vec![0u8; 128];
    let turn = TestTurn::default();
    assert_eq!(
        reads.read_by_pages(&rec, &mut buf, Purpose::Demand, &turn),
        0
    );
    assert!(reads.pages.bytes() <= 4096, "at most the page that fits");
    // A record within one page is still read through it.
    (rec.offset, rec.len) = (3 * 4096, 128);
    assert_eq!(
        reads.read_by_pages(&rec, &mut buf, Purpose::Demand, &turn),
        128
    );
    let mut want = vec![0u8; 128];
    mem.read_at(3 * 4096, &mut want).unwrap();
    assert_eq!(buf, want);
}

#[test]
fn pages_stay_on_until_a_request_is_worth_under_half_a_page() {
    let (mut reads, _) = paged_on_a_seek_bound_disk();
    // A request worth 3 KB against 4 KiB pages: on already, they stay on.
    let worth = |reads: &mut Reads, bytes: f64| {
        reads.costs.seek_s = bytes / 30e6;
        reads.plan_pages();
        reads.pages_on()
    };
    assert!(worth(&mut reads, 3000.0));
    // 1.5 KB: off, and the same 3 KB does not turn them on again; a page's
    // worth does.
    assert!(!worth(&mut reads, 1500.0));
    assert!(!worth(&mut reads, 3000.0));
    assert!(worth(&mut reads, 4200.0));
}
