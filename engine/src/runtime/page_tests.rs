//! Reads by pages on a simulated seek-bound disk (`loader::pages`).

use std::sync::Arc;
use std::time::Duration;

use super::tests::{SeekCounter, check_frames, clocked, params, pose, wide_compressed};
use super::*;
use crate::camera::Pose;
use crate::metrics::FrameMetrics;
use crate::render::NoneRenderer;

/// The path: along the row of leaves, turning.
fn poses() -> Vec<Pose> {
    (0..40)
        .map(|i| pose(i as f32 * 1.2, 0.5, 2.0, 1.2 + (i as f32 * 0.3).sin()))
        .collect()
}

/// Walks `poses` on a simulated disk of `latency` seeks and `rate` bytes/s;
/// the frames and the seeks.
fn walk(
    mode: Mode,
    page_bytes: u64,
    latency: Duration,
    rate: f64,
    budget: u64,
) -> (Vec<FrameMetrics>, u64) {
    let (skel, mem) = wide_compressed(64);
    let clock = Arc::new(crate::clock::ManualClock::new());
    let counter = Arc::new(SeekCounter {
        inner: clocked(&mem, latency, rate, &clock),
        state: Default::default(),
    });
    let p = RuntimeParams {
        coalesce_max_gap: 0,
        page_bytes,
        block_bytes: 16 << 10,
        ..params(mode, budget)
    };
    let mut w = Walkthrough::start_with_clock(skel, counter.clone(), p, clock).unwrap();
    let frames = run_path(&mut w, &poses(), &mut NoneRenderer::new(0.0), 0.0).unwrap();
    drop(w);
    check_frames(&frames, budget);
    let seeks = counter.state.lock().unwrap().1;
    (frames, seeks)
}

/// Half the reps' footprint, and room for the pages' share to hold four
/// pages of 4 KiB.
fn budget() -> u64 {
    let (skel, _) = wide_compressed(64);
    skel.reps.iter().map(|r| r.resident_len()).sum::<u64>() / 2 + (64 << 10)
}

fn total(f: &[FrameMetrics], k: fn(&FrameMetrics) -> u64) -> u64 {
    f.iter().map(k).sum()
}

#[test]
fn pages_on_a_seek_bound_disk_save_seeks_within_the_budget() {
    let budget = budget();
    // 10 ms seeks, 30 MB/s: a seek costs 300 KB of transfer, a 4 KiB page
    // far less.
    let hdd = (Duration::from_millis(10), 30e6);
    let (off, off_seeks) = walk(Mode::NoPre, 0, hdd.0, hdd.1, budget);
    let (on, on_seeks) = walk(Mode::NoPre, 4096, hdd.0, hdd.1, budget);
    assert_eq!(total(&off, |f| u64::from(f.loader.page_hits)), 0);
    assert!(off.iter().all(|f| f.loader.page_bytes == 0));
    assert!(total(&on, |f| u64::from(f.loader.page_hits)) > 0);
    assert!(on.iter().any(|f| f.loader.page_bytes > 0));
    // On demand only, P_R waits for every rep: nothing substituted.
    for f in off.iter().chain(&on) {
        assert_eq!(f.substituted, 0, "frame {}", f.frame);
    }
    assert!(
        on_seeks * 10 < off_seeks * 8,
        "seeks: {on_seeks} by pages, {off_seeks} without"
    );
    // Prefetching by pages keeps the budget too (timing-dependent beyond
    // the invariants `walk` checks).
    let (pre, _) = walk(Mode::Pre, 4096, hdd.0, hdd.1, budget);
    assert!(total(&pre, |f| u64::from(f.loader.page_hits)) > 0);
}

#[test]
fn pages_stay_off_where_a_seek_costs_less_than_a_page() {
    let budget = budget();
    // 0.1 ms seeks, 500 MB/s: a seek is worth 50 KB, under a 128 KiB page.
    for mode in [Mode::NoPre, Mode::Pre] {
        let (frames, _) = walk(mode, 128 << 10, Duration::from_micros(100), 500e6, budget);
        assert_eq!(total(&frames, |f| u64::from(f.loader.page_hits)), 0);
        assert!(frames.iter().all(|f| f.loader.page_bytes == 0));
    }
}

#[test]
fn a_share_under_two_pages_reads_by_rep() {
    let budget = budget();
    // A quarter of the budget is under two 64 KiB pages: a rep straddling
    // two pages could not hold both, so reads go by rep.
    assert!(budget / 4 < 2 * (64 << 10));
    let (frames, _) = walk(
        Mode::NoPre,
        64 << 10,
        Duration::from_millis(10),
        30e6,
        budget,
    );
    assert_eq!(total(&frames, |f| u64::from(f.loader.page_hits)), 0);
    assert!(frames.iter().all(|f| f.loader.page_bytes == 0));
}

/// A network-like source: every read is a copy (its answer came ahead of
/// it), while the answers it reports took a round trip and a transfer;
/// `times` says whether it reports them.
struct AnsweredAhead {
    inner: Arc<dyn ByteSource>,
    times: bool,
    answers: std::sync::Mutex<crate::io::AnswerLog>,
}

impl ByteSource for AnsweredAhead {
    fn len(&self) -> u64 {
        self.inner.len()
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
        // 10 ms a round trip, 30 MB/s.
        let first_byte = Duration::from_millis(10);
        let took = first_byte + Duration::from_secs_f64(buf.len() as f64 / 30e6);
        self.answers.lock().unwrap().record(crate::io::Response {
            bytes: buf.len() as u64,
            first_byte,
            took,
        });
        self.inner.read_at(offset, buf)
    }

    fn is_ready(&self, _offset: u64, _len: u64) -> bool {
        true
    }

    fn times_requests(&self) -> bool {
        self.times
    }

    fn responses_since(&self, seen: &mut u64, out: &mut Vec<crate::io::Response>) {
        self.answers.lock().unwrap().since(seen, out);
    }
}

#[test]
fn pages_turn_on_from_the_answers_round_trips_when_reads_take_no_time() {
    let budget = budget();
    let pages = |times: bool| {
        let (skel, mem) = wide_compressed(64);
        let clock = Arc::new(crate::clock::ManualClock::new());
        // A read is a copy: 0.1 µs and 4 GB/s (400 bytes' worth, under
        // the half page that turns pages off once they are on).
        let copy = clocked(&mem, Duration::from_nanos(100), 4e9, &clock);
        let src = Arc::new(AnsweredAhead {
            inner: copy,
            times,
            answers: std::sync::Mutex::new(crate::io::AnswerLog::new(64)),
        });
        let p = RuntimeParams {
            coalesce_max_gap: 0,
            page_bytes: 4096,
            block_bytes: 16 << 10,
            ..params(Mode::NoPre, budget)
        };
        let mut w = Walkthrough::start_with_clock(skel, src, p, clock).unwrap();
        let frames = run_path(&mut w, &poses(), &mut NoneRenderer::new(0.0), 0.0).unwrap();
        drop(w);
        check_frames(&frames, budget);
        total(&frames, |f| u64::from(f.loader.page_hits))
    };
    // Learnt from the reads, a request costs a copy: pages go off once a
    // transfer rate is seen (before it, P_I probes with reads through gaps
    // of up to 64 KiB, which pages stand in for).
    let from_reads = pages(false);
    // Learnt from the answers, a round trip is worth 300 KB: pages stay on.
    let from_answers = pages(true);
    eprintln!("page hits: {from_reads} learnt from reads, {from_answers} from answers");
    assert!(
        from_answers > 5 * from_reads.max(1),
        "page hits: {from_reads} learnt from reads, {from_answers} from answers"
    );
}
