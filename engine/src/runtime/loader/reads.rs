//! P_I's reads as a value: what it holds (the resident set, pages and a
//! preempted read, under its side of the footprint), where it reads from
//! (the source, through the learnt costs) and how a rep is read (block by
//! block, preemptibly, through pages on a seek-bound disk, through short
//! gaps in file order). The command loop ([`super::Loader`]) decides what
//! to read and when; what a read needs to know of that while it runs —
//! whether a fetch command arrived, whether a rep it passes is wanted,
//! whether it ends before the next command — it asks a [`Turn`]. With a
//! [`MemSource`](crate::io::MemSource), a manual clock and a test `Turn`, a
//! read is tested without a thread.
//!
//! The read-span planner (reads through gaps, timing) is in `span.rs`, the
//! page policy in `pages.rs`; both are methods of [`Reads`].

use std::sync::Arc;
use std::time::Instant;

use super::costs::IoCosts;
use super::order::{FileOrder, Partial};
use super::page_cache::PageCache;
use super::retry::{self, Retry};
use crate::clock::Clock;
use crate::format::{check_rep_crc, expand_payload};
use crate::io::ByteSource;
use crate::metrics::LoaderCounters;
use crate::runtime::footprint::Footprint;
use crate::runtime::params::{Mode, RuntimeParams};
use crate::runtime::resident::{Purpose, ResidentSet};
use crate::skeleton::{RepId, Skeleton};

/// Why a rep was not loaded.
#[derive(Debug, PartialEq, Eq)]
pub(super) enum LoadError {
    /// The budget cannot make room without evicting reps that must stay.
    NoRoom,
    /// Read or checksum failure (logged once; the rep is not tried again).
    Failed,
    /// A new fetch command arrived during a prefetch read.
    Preempted,
}

/// What a read asks of the command loop while it runs.
pub(super) trait Turn {
    /// Whether a new fetch command arrived (kept as pending): a prefetch
    /// read stops there.
    fn preempted(&mut self) -> bool;
    /// Whether rep `r` is queued for prefetching by this classification,
    /// or late in frame `frame`.
    fn queued(&self, r: RepId, frame: u32) -> bool;
    /// Whether rep `r` was missed by frame `frame`'s Stage II and is read
    /// after it.
    fn is_late(&self, r: RepId, frame: u32) -> bool;
    /// Whether rep `r` is a candidate of this classification or the one
    /// before.
    fn is_recent(&self, r: RepId) -> bool;
    /// Whether work of `need_s` seconds started at `now` ends before the
    /// next fetch command.
    fn ends_in_time(&mut self, now: Instant, need_s: f64) -> bool;
}

/// The parameters a read uses.
#[derive(Clone, Copy, Debug)]
pub(super) struct ReadParams {
    pub(super) mode: Mode,
    pub(super) block_bytes: usize,
    pub(super) page_bytes: u64,
    pub(super) coalesce_max_gap: u64,
}

impl ReadParams {
    pub(super) fn of(p: &RuntimeParams) -> Self {
        Self {
            mode: p.mode,
            block_bytes: p.block_bytes,
            page_bytes: p.page_bytes,
            coalesce_max_gap: p.coalesce_max_gap,
        }
    }
}

/// What P_I holds and how it reads.
pub(super) struct Reads {
    pub(super) skeleton: Arc<Skeleton>,
    pub(super) source: Arc<dyn ByteSource>,
    /// Where P_I's timing comes from (the system's clock, or a test's).
    pub(super) clock: Arc<dyn Clock>,
    pub(super) params: ReadParams,
    /// P_I's side of the footprint, and its shares.
    pub(super) fp: Footprint,
    /// The resident reps, their bytes, pins and the eviction rule.
    pub(super) res: ResidentSet,
    /// Stored bytes of whole pages read on a seek-bound disk.
    pub(super) pages: PageCache,
    /// A prefetch read preempted by a fetch command (its bytes reserved).
    pub(super) partial: Option<Partial>,
    /// Reps that failed (not tried again until `retry` releases them).
    pub(super) failed: Vec<bool>,
    pub(super) retry: Retry,
    /// Learnt read costs (seek, transfer, break-even gap).
    pub(super) costs: IoCosts,
    /// The reps in file order, for reads through gaps.
    pub(super) order: FileOrder,
    /// Bytes of a gap being read through (discarded).
    pub(super) gap_buf: Vec<u8>,
    /// This frame's counters.
    pub(super) stats: LoaderCounters,
}

impl Reads {
    /// Reads of `skeleton`'s reps from `source` under `fp`; `pools[r]` is
    /// the store reserve of rep `r` (a tree's or an MT's), `None` where
    /// its store could not be made (the rep is not usable).
    pub(super) fn new(
        skeleton: Arc<Skeleton>,
        source: Arc<dyn ByteSource>,
        pools: &[Option<u64>],
        (params, fp): (ReadParams, Footprint),
        clock: Arc<dyn Clock>,
    ) -> Self {
        let cost = skeleton
            .reps
            .iter()
            .zip(pools)
            .map(|(r, p)| r.resident_len() + p.unwrap_or(0))
            .collect();
        Self {
            res: ResidentSet::shared(
                cost,
                (0..skeleton.reps.len() as RepId)
                    .map(|r| skeleton.payload_rep(r))
                    .collect(),
            ),
            failed: pools.iter().map(Option::is_none).collect(),
            retry: Retry::default(),
            costs: IoCosts::for_source(&*source),
            order: FileOrder::new(&skeleton),
            pages: PageCache::new(params.page_bytes),
            skeleton,
            source,
            clock,
            params,
            fp,
            partial: None,
            gap_buf: Vec::new(),
            stats: LoaderCounters::default(),
        }
    }

    /// Footprint bytes of rep `r` while resident: its payload, and the
    /// reserve of a view-dependence tree's store.
    pub(super) fn cost(&self, r: RepId) -> u64 {
        self.res.cost(r)
    }

    /// Whether rep `r` was missed by this frame's Stage II and is read
    /// after it.
    pub(super) fn is_late(&self, r: RepId, turn: &dyn Turn) -> bool {
        turn.is_late(r, self.res.frame())
    }

    /// Removes resident rep `r` (P_R is told with the next reply).
    pub(super) fn drop_rep(&mut self, r: RepId) {
        let r = self.skeleton.payload_rep(r);
        let wasted = self.res.wasted_bytes();
        self.res
            .remove(r, self.skeleton.reps[r as usize].resident_len());
        self.stats.wasted_bytes += self.res.wasted_bytes() - wasted;
    }

    /// Gives up the preempted prefetch read, if any, and its reservation;
    /// returns whether there was one.
    pub(super) fn cancel_partial(&mut self) -> bool {
        match self.partial.take() {
            Some(p) => {
                // What `load` reserved: the footprint and the stored copy.
                let c = self.cost(p.rep) + self.skeleton.reps[p.rep as usize].load_scratch();
                self.res.release(c);
                true
            }
            None => false,
        }
    }

    /// Loads rep `r` block by block under the budget.
    pub(super) fn load(
        &mut self,
        r: RepId,
        purpose: Purpose,
        turn: &mut dyn Turn,
    ) -> Result<Arc<[u8]>, LoadError> {
        // A shared payload is read, held and failed under its owner, once.
        let r = self.skeleton.payload_rep(r);
        if let Some(p) = self.res.payload(r) {
            let p = p.clone();
            self.res.access(r);
            return Ok(p);
        }
        if self.failed[r as usize] {
            return Err(LoadError::Failed);
        }
        let rec = self.skeleton.reps[r as usize];
        let scratch = rec.load_scratch();
        let len = self.cost(r) + scratch;
        // In core, a tree comes whole (P_R then refines it without paging).
        let read = if self.params.mode == Mode::Incore && rec.is_paged() {
            rec.extent()
        } else {
            u64::from(rec.len)
        };
        let (mut buf, mut done) = match self.partial.take_if(|p| p.rep == r) {
            // A preempted prefetch read of this rep goes on (still reserved).
            Some(p) => {
                self.stats.resumed += 1;
                (p.buf, p.done)
            }
            None => {
                // Stage II may take the room of a preempted prefetch read.
                let room = self.make_room(len, purpose)
                    || (purpose == Purpose::Demand
                        && self.cancel_partial()
                        && self.make_room(len, purpose));
                if !room {
                    if purpose == Purpose::Prefetch {
                        self.stats.prefetch_noroom += 1;
                    }
                    return Err(LoadError::NoRoom);
                }
                // Reserve first: bytes being loaded count against the budget.
                self.res.reserve(len);
                self.note_resident();
                let mut buf = vec![0u8; read as usize];
                // On a seek-bound disk, through the page it lies in.
                let done = self.read_by_pages(&rec, &mut buf, purpose, turn);
                (buf, done)
            }
        };
        let block = self.params.block_bytes;
        while done < buf.len() {
            let end = (done + block).min(buf.len());
            let t = self.clock.now();
            if let Err(e) = self
                .source
                .read_at(rec.offset + done as u64, &mut buf[done..end])
            {
                self.res.release(len);
                return Err(self.fail(r, &e.to_string(), retry::transient(e.kind())));
            }
            let took = self.clock.now() - t;
            self.observe(rec.offset + done as u64, end - done, took, purpose);
            let n = (end - done) as u64;
            match purpose {
                Purpose::Demand => self.stats.stage2_bytes += n,
                Purpose::Prefetch if self.is_late(r, turn) => self.stats.late_bytes += n,
                Purpose::Prefetch => self.stats.prefetch_bytes += n,
            }
            done = end;
            if purpose == Purpose::Prefetch && done < buf.len() && turn.preempted() {
                // Kept, reserved, to go on when P_I is idle again (or when
                // Stage II needs it).
                self.cancel_partial();
                self.partial = Some(Partial { rep: r, buf, done });
                return Err(LoadError::Preempted);
            }
        }
        if let Err(e) = check_rep_crc(r, &rec, &buf[..rec.len as usize]) {
            self.res.release(len);
            return Err(self.fail(r, &e.to_string(), false));
        }
        let payload: Arc<[u8]> = if scratch == 0 {
            buf.into()
        } else {
            let t = self.clock.now();
            let expanded = match expand_payload(&buf, r, &rec) {
                Ok(p) => Arc::<[u8]>::from(&*p),
                Err(e) => {
                    self.res.release(len);
                    return Err(self.fail(r, &e.to_string(), false));
                }
            };
            self.stats.expand_ms += self.clock.ms_since(t);
            self.stats.expanded_bytes += expanded.len() as u64;
            drop(buf);
            self.res.release(scratch);
            expanded
        };
        let speculative = purpose == Purpose::Prefetch && !self.is_late(r, turn);
        self.res.insert(r, payload.clone(), speculative);
        self.retry.succeeded();
        Ok(payload)
    }

    /// Marks rep `r` failed (tried again later when the error may pass)
    /// and warns.
    fn fail(&mut self, r: RepId, why: &str, transient: bool) -> LoadError {
        self.failed[r as usize] = true;
        self.stats.read_errors += 1;
        let n = self.retry.failed(r, self.clock.now(), transient);
        // One warning, then one at each power of two: a server gone or a
        // file replaced fails every read that follows, not worth a line each.
        if n.is_power_of_two() {
            tracing::warn!(
                "rep {r} cannot be loaded ({why}); its nearest resident ancestor is drawn instead{}",
                if n > 1 {
                    format!(" ({n} reps so far)")
                } else {
                    String::new()
                }
            );
        } else {
            tracing::debug!("rep {r} cannot be loaded ({why})");
        }
        LoadError::Failed
    }
}

#[cfg(test)]
#[path = "reads_tests.rs"]
mod tests;
