//! Pages of co-used reps: the I/O granularity of a seek-bound disk.
//!
//! The layout stores the reps of one selection band along a Morton curve
//! (`hlod-build`'s `layout`), so an aligned window of the file — a *page* —
//! holds reps of neighbouring nodes that enter the front at the same
//! distance: the reps one turn or one approach misses together. Where a seek
//! costs more than a page's transfer (the learnt break-even gap is at least
//! a page), P_I reads the whole page a rep lies in and keeps its stored
//! (compressed) bytes in a share of the budget ([`PageCache`]); a later
//! read of any rep in it is a copy and an expansion, not a seek. The page
//! bytes count in the footprint exactly like the reps: the reps' room is
//! the budget less the pages' bytes, a demand fetch evicts pages before it
//! gives up, and a page is cached only where it fits beside what is
//! resident. On a fast disk (break-even gap under a page) pages are off
//! and the cache is emptied.

use super::reads::{Reads, Turn};
use crate::format::RepRecord;
use crate::runtime::footprint::Held;
use crate::runtime::params::Mode;
use crate::runtime::resident::Purpose;
use crate::skeleton::RepId;

impl Reads {
    /// Whether pages are asked for and a seek, or a request's fixed cost
    /// (a network's round trip), costs at least a page's transfer (learnt).
    /// Once on, pages stay on until that cost falls under half a page: where
    /// it lies near a page (a network on loopback: 170–480 KiB learnt in
    /// runs of the same walk) the choice would flip from frame to frame,
    /// and each flip empties the pages read.
    fn paging(&self) -> bool {
        let p = self.params.page_bytes;
        let worth = if self.pages_on() { p / 2 } else { p };
        p > 0
            && self.params.mode != Mode::Incore
            && (self
                .costs
                .max_gap(self.params.coalesce_max_gap.max(p), 64 << 10)
                >= worth
                || self.costs.request_bytes() >= worth)
    }

    /// Decides, once a frame, whether reads go by pages and the pages'
    /// room: `page_share` of the budget while paging, if that holds the two
    /// pages a rep may straddle (with room for one, its second page would
    /// evict its first); else 0, and the pages held go. (Measured and
    /// rejected: a share that shrinks when the front is large, to give
    /// prefetching the room — the reads then fell back to one seek per rep
    /// just in the dense stretches.)
    pub(super) fn plan_pages(&mut self) {
        let cap = self.fp.pages_cap(self.params.page_bytes, self.paging());
        self.pages.set_cap(cap);
    }

    /// Whether rep `rec` is read by pages: pages on this frame, and stored
    /// in at most a page (a larger rep is read as it is).
    pub(super) fn by_pages(&self, rec: &RepRecord) -> bool {
        !rec.is_paged() && u64::from(rec.len) <= self.params.page_bytes && self.pages_on()
    }

    /// Whether reads go by pages this frame (else they go through short
    /// gaps as on a fast disk).
    pub(super) fn pages_on(&self) -> bool {
        self.pages.cap() > 0
    }

    /// Fills `buf` with the stored bytes of `rec` through the page cache,
    /// reading each missing page whole (one seek); the bytes filled. 0 —
    /// nothing read or copied — when it is not read by pages (or `buf` is
    /// not its stored bytes) or a page finds no room: it is then read as it
    /// is; a read error also gives 0, and the direct read that follows
    /// reports it.
    pub(super) fn read_by_pages(
        &mut self,
        rec: &RepRecord,
        buf: &mut [u8],
        purpose: Purpose,
        turn: &dyn Turn,
    ) -> usize {
        if buf.len() as u64 != u64::from(rec.len) || !self.by_pages(rec) {
            return 0;
        }
        let hit = self.pages.covers(rec.offset, u64::from(rec.len));
        if !self.fill_pages(rec, purpose) || !self.pages.copy_out(rec.offset, buf) {
            return 0;
        }
        if hit {
            self.stats.page_hits += 1;
        }
        if purpose == Purpose::Prefetch {
            self.demote_spent(rec, turn);
        }
        buf.len()
    }

    /// Once rep `rec` is copied out by a prefetch read, a page of it that
    /// holds no other rep P_I still wants (a candidate of this
    /// classification or the one before, not resident) goes first when a
    /// page needs room: its reps are expanded already, and the pages that
    /// still hold wanted reps are the ones worth their room. (By last use
    /// alone, the pages just copied out — spent — stayed, and pages of the
    /// reps ahead were evicted and read again.) A page read on demand holds
    /// the neighbourhood the walk is in and goes by last use: where P_I has
    /// no time to prefetch (a network's round trip per frame), the
    /// candidates do not say what the next frames miss, and demoting those
    /// pages had Stage II read them again (3.4× the bytes of `nopre` on the
    /// DE-size fly-through at RTT 50 ms). Without prefetching nothing is
    /// wanted ahead: the pages go by last use.
    fn demote_spent(&mut self, rec: &RepRecord, turn: &dyn Turn) {
        if self.params.mode != Mode::Pre {
            return;
        }
        let (a, b) = self.pages.span(rec.offset, u64::from(rec.len));
        let p = self.params.page_bytes;
        for page in a..=b {
            let end = (page + 1) * p;
            let wanted = self
                .order
                .starting_at(&self.skeleton, page * p)
                .iter()
                .take_while(|&&r| self.skeleton.reps[r as usize].offset < end)
                .any(|&r| {
                    self.skeleton.reps[r as usize].offset != rec.offset
                        && !self.failed[r as usize]
                        && !self.res.contains(r)
                        && turn.is_recent(r)
                });
            if !wanted {
                self.pages.demote(page);
            }
        }
    }

    /// Reads the missing pages of `rec` whole; false when one found no room
    /// or the read failed, or when the room for one page was made by
    /// evicting another page of `rec` (beside the reps held, one page fits
    /// and the rep straddles two: reading on would alternate between them
    /// for ever).
    fn fill_pages(&mut self, rec: &RepRecord, purpose: Purpose) -> bool {
        let len = u64::from(rec.len);
        let mut read = Vec::new();
        while let Some(page) = self.pages.first_missing(rec.offset, len) {
            if read.contains(&page) {
                return false;
            }
            read.push(page);
            let start = page * self.params.page_bytes;
            let n = self
                .params
                .page_bytes
                .min(self.source.len().saturating_sub(start));
            if n == 0 || !self.page_room(n) {
                return false;
            }
            let mut data = vec![0u8; n as usize];
            let t = self.clock.now();
            if self.source.read_at(start, &mut data).is_err() {
                return false;
            }
            let took = self.clock.now() - t;
            self.observe(start, n as usize, took, purpose);
            match purpose {
                Purpose::Demand => self.stats.stage2_bytes += n,
                Purpose::Prefetch => self.stats.prefetch_bytes += n,
            }
            self.pages.insert(page, data.into());
            self.note_resident();
        }
        true
    }

    /// Makes room for a page of `n` bytes: within the pages' share and
    /// beside what is resident, evicting pages (never reps).
    fn page_room(&mut self, n: u64) -> bool {
        let held = |l: &Self| Held {
            reps: l.res.bytes(),
            pages: l.pages.bytes(),
        };
        while !self.fp.page_fits(held(self), self.pages.cap(), n) {
            if self.pages.evict_lru().is_none() {
                return false;
            }
        }
        true
    }

    /// The reps' room for a read of `purpose` ([`Footprint::rep_room`]:
    /// P_I's side less the pages, and a prefetch also leaves the pages'
    /// share); `None` in core.
    pub(super) fn rep_room(&self, purpose: Purpose) -> Option<u64> {
        self.fp
            .rep_room(self.pages.bytes(), self.pages.cap(), purpose)
    }

    /// Makes room for `need` more bytes for a rep under the budget less the
    /// pages ([`rep_room`](Self::rep_room); the eviction rule is
    /// [`crate::runtime::resident::ResidentSet::make_room`]). A demand read
    /// takes the pages' room before it gives up.
    pub(super) fn make_room(&mut self, need: u64, purpose: Purpose) -> bool {
        let cap = self.fp.speculative_cap();
        let (evictions, wasted) = (self.res.evictions(), self.res.wasted_bytes());
        let ok = loop {
            let Some(room) = self.rep_room(purpose) else {
                break true; // in core: nothing bounds P_I
            };
            let skeleton = &self.skeleton;
            let ok = self.res.make_room(need, room, purpose, cap, |r| {
                skeleton.reps[r as usize].resident_len()
            });
            if ok || purpose == Purpose::Prefetch || !self.yield_pages() {
                break ok;
            }
        };
        self.stats.evictions += (self.res.evictions() - evictions) as u32;
        self.stats.wasted_bytes += self.res.wasted_bytes() - wasted;
        ok
    }

    /// Gives a demand read that found no room the pages' room (all of it:
    /// the front does not fit beside them); false when none is held.
    pub(super) fn yield_pages(&mut self) -> bool {
        let any = self.pages.bytes() > 0;
        self.pages.clear();
        any
    }

    /// Tells the source the reads that come next, `reps` in the order P_I
    /// reads them, as few ranges as cover them: the pages not held where
    /// reads go by pages, else each rep's stored bytes, and a range goes
    /// on over a gap P_I would read through (a read of the gap and of the
    /// rep after it are then one request). Up to what the reps' room holds
    /// (a rep that will find no room is not fetched) and `limit` ranges;
    /// what is resident or failed is skipped. A source that starts requests
    /// ahead (a network, within the footprint's `in_flight` share) serves
    /// the reads from them; a file ignores it.
    pub(super) fn hint_reads(&self, reps: impl IntoIterator<Item = RepId>, limit: usize) {
        if self.fp.in_flight() == 0 {
            return;
        }
        let (p, gap) = (self.params.page_bytes, self.max_gap());
        // As many ranges as the source keeps in flight fit the share at
        // once. (A quarter of it each: with reads through gaps of up to 1
        // MiB, four ranges held the share and the other reps of a Stage II
        // went one round trip at a time, 3–17 s frames at RTT 50 ms.)
        let longest = (self.fp.in_flight() / self.source.max_requests().max(1) as u64).max(p);
        let mut room = self.rep_room(Purpose::Demand).unwrap_or(u64::MAX);
        let mut ranges: Vec<(u64, u64)> = Vec::new();
        let add = |ranges: &mut Vec<(u64, u64)>, (a, b): (u64, u64)| match ranges.last_mut() {
            Some(l) if a >= l.0 && a <= l.1.saturating_add(gap) && b - l.0 <= longest => {
                l.1 = l.1.max(b);
            }
            _ => ranges.push((a, b)),
        };
        let mut last_owner = None;
        for r in reps {
            // A shared payload is read once, under its owner.
            let r = self.skeleton.payload_rep(r);
            let rec = &self.skeleton.reps[r as usize];
            if self.res.contains(r) || self.failed[r as usize] || last_owner == Some(r) {
                continue;
            }
            last_owner = Some(r);
            let need = self.cost(r) + rec.load_scratch();
            if need > room {
                break;
            }
            room -= need;
            if self.by_pages(rec) {
                let (a, b) = self.pages.span(rec.offset, u64::from(rec.len));
                for page in (a..=b).filter(|&g| !self.pages.covers(g * p, 1)) {
                    add(&mut ranges, (page * p, (page + 1) * p));
                }
            } else {
                add(&mut ranges, (rec.offset, rec.offset + u64::from(rec.len)));
            }
            if ranges.len() >= limit {
                break;
            }
        }
        self.source.hint(&ranges);
    }

    /// The expected time of rep `rec`'s read by pages: nothing but a copy
    /// when its pages are held, else the first missing page's seek and
    /// transfer. `None` when it is not read by pages.
    pub(super) fn page_read_s(&self, rec: &RepRecord) -> Option<f64> {
        if !self.by_pages(rec) {
            return None;
        }
        let len = u64::from(rec.len);
        let p = self.params.page_bytes;
        Some(match self.pages.first_missing(rec.offset, len) {
            None => self.costs.overhead_s,
            // Answered already: a copy.
            Some(page) if self.source.is_ready(page * p, p) => self.costs.overhead_s,
            Some(page) => self.costs.first_block_estimate(page * p, p, p),
        })
    }

    /// Records the footprint now (reps and pages) in the frame's maximum.
    pub(super) fn note_resident(&mut self) {
        let now = self.res.bytes() + self.pages.bytes();
        self.stats.max_resident_bytes = self.stats.max_resident_bytes.max(now);
    }
}
