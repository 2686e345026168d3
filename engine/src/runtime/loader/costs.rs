//! What a read costs, learnt: P_I's own reads give the time per byte (those
//! that continue where the previous one ended) and the seek time (the
//! others), so the break-even gap of reading through is seek time ×
//! transfer rate — hundreds of KB on a seek-bound disk, tens on an SSD and
//! nothing on a warm page cache. From a source that times its own requests
//! (a network's, whose answers may arrive before P_I reads them) the same
//! costs are learnt from the answers instead: the round trip (the time to an
//! answer's head) takes the seek's place, and every request pays it; the
//! rate comes from the answers' bodies ([`IoCosts::observe_response`]).

use std::time::Duration;

/// Learnt read costs of the rep source.
#[derive(Clone, Debug, Default)]
pub(super) struct IoCosts {
    /// A decaying maximum of the time of a read that seeks (the estimate of
    /// a first block until seek and transfer costs are learnt).
    pub(super) first_block_s: f64,
    /// Seconds per byte and per read of reads that do not seek: the line
    /// `overhead_s + bytes * per_byte_s` fitted to them ([`SeqFit`]).
    pub(super) per_byte_s: f64,
    pub(super) overhead_s: f64,
    seq: SeqFit,
    /// A moving average of the seek time (a seeking read less its transfer).
    pub(super) seek_s: f64,
    /// A decaying maximum of the seek time (learnt once the transfer rate
    /// is known).
    pub(super) seek_max_s: f64,
    /// Where P_I's last read ended.
    last_end: Option<u64>,
    /// Learnt from the source's answers ([`IoCosts::observe_response`]):
    /// every read that is not answered already is a request and pays the
    /// round trip (`seek_s`), whether or not it goes on from the last read.
    by_responses: bool,
    /// The number of the last of the source's answers learnt from, and
    /// those taken before they are learnt from.
    seen: u64,
    answers: Vec<crate::io::Response>,
    /// The answers' bodies: bytes and the time from head to last byte,
    /// fitted as the sequential disk reads are ([`SeqFit`]).
    body: SeqFit,
}

/// Decayed sums over the reads that do not seek — count, bytes, seconds,
/// bytes², bytes × seconds — for a least-squares line `t = a + b · bytes`.
/// A read's fixed cost (the system call, the clock, the throttle's wake-up)
/// is `a`: averaged into a rate per byte, the many small reads (a coarse LOD
/// of a small part is a few hundred bytes) made a byte look ten times
/// dearer than it is, and the break-even gap of read coalescing shrank to
/// nothing.
#[derive(Clone, Debug, Default)]
struct SeqFit {
    sums: [f64; 5],
}

impl SeqFit {
    /// Each read's weight decays by this factor per read after it.
    const DECAY: f64 = 0.98;

    fn observe(&mut self, bytes: f64, t: f64) {
        for (s, x) in self
            .sums
            .iter_mut()
            .zip([1.0, bytes, t, bytes * bytes, bytes * t])
        {
            *s = *s * Self::DECAY + x;
        }
    }

    /// The decayed number of reads observed.
    fn count(&self) -> f64 {
        self.sums[0]
    }

    /// `(a, b)`: the fitted cost per read and per byte (`a = 0` when the
    /// reads are too alike in size to tell them apart, or the fit is not
    /// physical).
    fn fit(&self) -> (f64, f64) {
        let [_, n, t, _, _] = self.sums;
        if n <= 0.0 {
            return (0.0, 0.0);
        }
        self.line().unwrap_or((0.0, t / n))
    }

    /// The fitted line, when the reads tell its two terms apart.
    fn line(&self) -> Option<(f64, f64)> {
        let [c, n, t, nn, nt] = self.sums;
        let var = c * nn - n * n;
        if c >= 4.0 && n > 0.0 && var > 1e-3 * c * nn {
            let b = (c * nt - n * t) / var;
            let a = (t - b * n) / c;
            if b > 0.0 && a >= 0.0 && b.is_finite() && a.is_finite() {
                return Some((a, b));
            }
        }
        None
    }
}

impl IoCosts {
    const A: f64 = 0.2;

    /// Learns from one read of `bytes` at `offset` that took `took`.
    pub(super) fn observe(&mut self, offset: u64, bytes: usize, took: Duration) {
        let t = took.as_secs_f64();
        if self.last_end == Some(offset) {
            if bytes > 0 {
                self.seq.observe(bytes as f64, t);
                (self.overhead_s, self.per_byte_s) = self.seq.fit();
            }
        } else {
            // A decaying maximum: a seek may come with any read, and a
            // prefetch still running when the fetch command arrives stalls P_R.
            self.first_block_s = t.max(self.first_block_s * 0.995);
            let seek = (t - self.overhead_s - bytes as f64 * self.per_byte_s).max(0.0);
            if self.per_byte_s > 0.0 {
                // Until a transfer rate is known a read's transfer would
                // count as seek time, and a large one would hold the
                // maximum up for hundreds of reads.
                self.seek_max_s = seek.max(self.seek_max_s * 0.95);
            }
            if self.seek_s > 0.0 {
                self.seek_s += Self::A * (seek - self.seek_s);
            } else {
                // The first seek seen starts the average (from 0 it would
                // take a dozen seeks to learn the break-even gap).
                self.seek_s = seek;
            }
        }
        self.last_end = Some(offset + bytes as u64);
    }

    /// Nothing learnt yet, for reads of `source`: from the source's answers
    /// when it times its requests ([`crate::ByteSource::times_requests`]),
    /// and P_I's own reads then only move [`last_end`](Self::last_end);
    /// else from P_I's reads.
    pub(super) fn for_source(source: &dyn crate::ByteSource) -> Self {
        Self {
            by_responses: source.times_requests(),
            ..Self::default()
        }
    }

    /// Whether the costs come from the source's answers.
    pub(super) fn learns_from_responses(&self) -> bool {
        self.by_responses
    }

    /// Learns from one answer: the round trip (the seek's place) from the
    /// time to its head, whatever its size, and the transfer rate from the
    /// time its body took. Each is learnt apart from the other, so the mix
    /// of sizes P_I asks for does not move them. (Before, the line `round
    /// trip plus bytes over rate` was fitted to the answers' whole times:
    /// once reads went by pages all answers were a page, the line could not
    /// be refitted, and on loopback the first frames' answers decided a
    /// whole walk.) A
    /// copy of an answer already here costs nothing (`overhead_s` 0).
    /// Answers that shared the link with others in flight took longer per
    /// byte: the rate learnt is a request's share of it.
    pub(super) fn observe_response(&mut self, r: crate::io::Response) {
        let t = r.took.as_secs_f64();
        let head = r.first_byte.as_secs_f64().min(t);
        self.first_block_s = t.max(self.first_block_s * 0.995);
        if self.seek_s > 0.0 {
            self.seek_s += Self::A * (head - self.seek_s);
        } else {
            self.seek_s = head;
        }
        // The slowest round trip lately: the estimate of a request's first
        // block, as the seek's on a disk.
        self.seek_max_s = head.max(self.seek_max_s * 0.95);
        self.overhead_s = 0.0;
        // A body's time has a fixed part too (a small body comes with the
        // head, and still takes a poll or two to hand over): the slope of
        // the line fitted to the bodies is the rate, or, where their sizes
        // are too alike to fit one (all a page), their bytes over their
        // times. (Bytes over times alone made a walk of 3 KiB reps see a
        // link several times slower than one of pages, on the same
        // loopback.) A few answers first, as the disk's line needs four.
        self.body.observe(r.bytes as f64, (t - head).max(0.0));
        let (_, b) = self.body.fit();
        if self.body.count() >= 4.0 && b > 0.0 {
            self.per_byte_s = b;
        }
    }

    /// Learns from the answers `source` received since the last call (the
    /// first call: from all it kept, which a new walk starts from).
    pub(super) fn learn_from(&mut self, source: &dyn crate::ByteSource) {
        let mut answers = std::mem::take(&mut self.answers);
        source.responses_since(&mut self.seen, &mut answers);
        for r in answers.drain(..) {
            self.observe_response(r);
        }
        self.answers = answers;
    }

    /// P_I read up to `end` (costs learnt from answers, not from this read).
    pub(super) fn moved_to(&mut self, end: u64) {
        self.last_end = Some(end);
    }

    /// How long the first block (up to `block` bytes) of a read of `bytes`
    /// at `offset` is expected to take: a seek unless it goes on from the
    /// last read, and the block's transfer. Until both costs are known, the
    /// slowest seeking read seen.
    pub(super) fn first_block_estimate(&self, offset: u64, bytes: u64, block: u64) -> f64 {
        if self.seek_max_s <= 0.0 || self.per_byte_s <= 0.0 {
            return self.first_block_s;
        }
        let seek = if self.last_end == Some(offset) && !self.by_responses {
            0.0
        } else {
            self.seek_max_s
        };
        // A 3 % margin for the jitter of the clock and the disk.
        (seek + self.overhead_s + bytes.min(block) as f64 * self.per_byte_s) * 1.03
    }

    /// Where P_I's last read ended (the next read there does not seek).
    pub(super) fn last_end(&self) -> Option<u64> {
        self.last_end
    }

    /// The longest gap worth reading through rather than seeking over,
    /// capped at `cap` (0 turns coalescing off). Until a transfer rate has
    /// been seen, `probe` bytes.
    pub(super) fn max_gap(&self, cap: u64, probe: u64) -> u64 {
        if cap == 0 {
            return 0;
        }
        if self.per_byte_s <= 0.0 {
            return probe.min(cap);
        }
        let g = self.seek_s / self.per_byte_s;
        if g.is_finite() {
            (g as u64).min(cap)
        } else {
            cap
        }
    }

    /// The bytes whose transfer costs what one more read costs: its fixed
    /// cost and its seek. On a disk that is the seek's break-even; over a
    /// network every request pays the round trip, sequential or not (the
    /// fixed cost), so one larger read (a page) beats several small ones.
    /// 0 until a transfer rate has been seen.
    pub(super) fn request_bytes(&self) -> u64 {
        if self.per_byte_s <= 0.0 {
            return 0;
        }
        let g = (self.seek_s + self.overhead_s) / self.per_byte_s;
        if g.is_finite() { g as u64 } else { u64::MAX }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn learns_seek_and_transfer_and_the_break_even_gap() {
        let mut c = IoCosts::default();
        assert_eq!(
            c.max_gap(1 << 20, 4096),
            4096,
            "probe until a rate is known"
        );
        assert_eq!(c.max_gap(0, 4096), 0, "off");
        // 10 ms seeks, 30 MB/s: a seeking 30 KB read takes 11 ms, a
        // sequential 30 KB read 1 ms.
        let ms = |x: f64| Duration::from_secs_f64(x / 1e3);
        let mut at = 0u64;
        for _ in 0..60 {
            at += 1_000_000;
            c.observe(at, 30_000, ms(11.0));
            c.observe(at + 30_000, 30_000, ms(1.0));
        }
        assert!((c.per_byte_s * 30e6 - 1.0).abs() < 1e-3);
        assert!((c.seek_s - 0.010).abs() < 1e-4, "{}", c.seek_s);
        let g = c.max_gap(1 << 20, 4096);
        assert!((290_000..310_000).contains(&g), "{g}");
        assert_eq!(c.max_gap(100_000, 4096), 100_000, "capped");
        assert!((c.first_block_s - 0.011).abs() < 1e-3);
        // A read's first block: the seek and the block's transfer, or the
        // transfer alone where the last read ended; 3 % margin.
        let end = c.last_end().unwrap();
        let est = |at, bytes| c.first_block_estimate(at, bytes, 65_536) * 1e3;
        assert!(
            (est(end + 1, 30_000) - 11.33).abs() < 0.05,
            "{}",
            est(end + 1, 30_000)
        );
        assert!(
            (est(end, 30_000) - 1.03).abs() < 0.05,
            "{}",
            est(end, 30_000)
        );
        let capped = 1.03 * (10.0 + 65_536.0 / 30_000.0);
        assert!((est(end + 1, 1 << 20) - capped).abs() < 0.05);
        // Small reads with a fixed cost each: an SSD (0.1 ms seeks, 500 MB/s)
        // whose reads also cost 20 µs apiece. The break-even gap is the
        // seek's worth of transfer, 50 KB, not the seek over the small
        // reads' inflated cost per byte.
        let mut c = IoCosts::default();
        let cost = |n: f64, seek: bool| ms(0.02 + n / 500e3 + if seek { 0.1 } else { 0.0 });
        let mut at = 0u64;
        for i in 0..200u64 {
            let n = [300u64, 2_000, 5_000, 60_000][i as usize % 4];
            at += 10_000_000;
            c.observe(at, n as usize, cost(n as f64, true));
            c.observe(at + n, n as usize, cost(n as f64, false));
        }
        assert!((c.overhead_s - 20e-6).abs() < 1e-6, "{}", c.overhead_s);
        assert!(
            (c.per_byte_s * 500e6 - 1.0).abs() < 0.01,
            "{}",
            c.per_byte_s
        );
        let g = c.max_gap(1 << 20, 4096);
        assert!((48_000..52_000).contains(&g), "{g}");
        // Until costs are known: the slowest seeking read seen.
        let fresh = IoCosts::default();
        assert_eq!(fresh.first_block_estimate(0, 100, 65_536), 0.0);
    }

    #[test]
    fn learns_a_round_trip_and_a_rate_from_answers() {
        let net = crate::MemSource::new(Vec::new());
        assert!(!IoCosts::for_source(&net).learns_from_responses());
        let answers = || IoCosts {
            by_responses: true,
            ..IoCosts::default()
        };
        // 50 ms a round trip, 12.5 MB/s (100 Mbit/s): the head after the
        // round trip, the body at the rate.
        let answer = |n: u64| crate::io::Response {
            bytes: n,
            first_byte: Duration::from_millis(50),
            took: Duration::from_secs_f64(0.050 + n as f64 / 12.5e6),
        };
        let mut c = answers();
        for i in 0..100u64 {
            let n = [1_000u64, 4_096, 20_000, 131_072][i as usize % 4];
            c.observe_response(answer(n));
        }
        assert!((c.seek_s - 0.050).abs() < 1e-4, "{}", c.seek_s);
        assert!((c.per_byte_s * 12.5e6 - 1.0).abs() < 1e-3);
        // A request is worth 625 KB of transfer: pages and wide ranges.
        let r = c.request_bytes();
        assert!((620_000..630_000).contains(&r), "{r}");
        // Every read not answered yet pays the round trip, whether or not it
        // goes on from the last one.
        c.moved_to(4096);
        let est = c.first_block_estimate(4096, 4096, 65_536);
        assert!(
            (est - 1.03 * (0.050 + 4096.0 / 12.5e6)).abs() < 1e-3,
            "{est}"
        );
        // Answers all of one size (a page each, once reads go by pages)
        // teach the same: the round trip and the rate are learnt apart, so
        // what P_I asks for does not move what it learns.
        let mut pages = answers();
        for _ in 0..100 {
            pages.observe_response(answer(131_072));
        }
        let near = |x: u64| x.abs_diff(r) < 1_000;
        assert_eq!(pages.seek_s, c.seek_s);
        assert!(near(pages.request_bytes()), "{}", pages.request_bytes());
        // Small answers alone too: their bodies are short, but their bytes
        // over their times still give the rate.
        let mut small = answers();
        for _ in 0..100 {
            small.observe_response(answer(1_000));
        }
        assert!(near(small.request_bytes()), "{}", small.request_bytes());
        // Bodies with a fixed cost each (20 µs to hand over, however small):
        // small answers of mixed sizes, and pages, learn the same rate.
        let slow = |n: u64| crate::io::Response {
            took: answer(n).took + Duration::from_micros(20),
            ..answer(n)
        };
        let (mut reps, mut paged) = (answers(), answers());
        for i in 0..100u64 {
            reps.observe_response(slow([700u64, 1_500, 3_000, 8_000][i as usize % 4]));
            paged.observe_response(slow(131_072));
        }
        for x in [&reps, &paged] {
            // Within 1 % (a page's 20 µs is 0.2 % of its transfer).
            let got = x.request_bytes();
            assert!(got.abs_diff(r) < r / 100, "{got}");
        }
        // Until a few answers came: no rate, and the slowest answer is the
        // estimate of every read.
        let mut fresh = answers();
        for _ in 0..3 {
            fresh.observe_response(answer(131_072));
        }
        assert_eq!(fresh.request_bytes(), 0);
        let slowest = answer(131_072).took.as_secs_f64();
        assert_eq!(fresh.first_block_estimate(0, 4096, 65_536), slowest);
    }
}
