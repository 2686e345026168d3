//! Read coalescing: P_I reads through a short gap between two reps it wants
//! instead of seeking over it, when the gap costs less to transfer than a
//! seek ([`IoCosts`](super::costs::IoCosts) learns what it costs), and keeps
//! the prefetch candidates it passes on the way.
//!
//! Also here: the timing checks that decide whether a prefetch read starts
//! before the next fetch command, and preemption.

use std::time::Duration;

use super::reads::{LoadError, Reads, Turn};
use crate::runtime::resident::Purpose;
use crate::skeleton::RepId;

impl Reads {
    /// Accounts one read of `n` bytes at `offset` (time, seek) and learns
    /// the read costs from it.
    pub(super) fn observe(&mut self, offset: u64, n: usize, took: Duration, purpose: Purpose) {
        let seek = u32::from(self.costs.last_end() != Some(offset));
        match purpose {
            Purpose::Demand => {
                self.stats.stage2_io_ms += took.as_secs_f64() * 1e3;
                self.stats.stage2_seeks += seek;
            }
            Purpose::Prefetch => {
                self.stats.prefetch_io_ms += took.as_secs_f64() * 1e3;
                self.stats.prefetch_seeks += seek;
            }
        }
        if self.costs.learns_from_responses() {
            self.costs.moved_to(offset + n as u64);
            self.costs.learn_from(&*self.source);
        } else {
            self.costs.observe(offset, n, took);
        }
    }

    /// The longest gap P_I reads through now (64 KiB until a transfer rate
    /// has been seen: reading through is how it is first seen); none while
    /// reading by pages (a page holds the neighbours).
    pub(super) fn max_gap(&self) -> u64 {
        if self.pages_on() {
            0
        } else {
            self.learnt_gap()
        }
    }

    /// The break-even gap learnt (capped by `coalesce_max_gap`), whether or
    /// not reads go through gaps now.
    pub(super) fn learnt_gap(&self) -> u64 {
        self.costs.max_gap(self.params.coalesce_max_gap, 64 << 10)
    }

    /// Whether rep `g` is a prefetch candidate worth keeping when a read
    /// passes over it: queued in this classification (or late in this
    /// frame) and not resident.
    pub(super) fn wanted(&self, g: RepId, turn: &dyn Turn) -> bool {
        turn.queued(g, self.res.frame()) && !self.res.contains(g) && !self.failed[g as usize]
    }

    /// Reads from `from` to `to` when the last read ended at `from` and the
    /// gap is short enough: keeps the prefetch candidates on the way (as
    /// prefetched reps, under the budget) and discards the other bytes.
    /// Returns whether the next read at `to` continues without a seek.
    pub(super) fn bridge(
        &mut self,
        from: u64,
        to: u64,
        purpose: Purpose,
        turn: &mut dyn Turn,
    ) -> bool {
        if to <= from || self.costs.last_end() != Some(from) || to - from > self.max_gap() {
            return to == from && self.costs.last_end() == Some(from);
        }
        let order = std::mem::take(&mut self.order);
        let mut cur = from;
        let mut ok = true;
        for &g in order.starting_at(&self.skeleton, from) {
            let rec = self.skeleton.reps[g as usize];
            if rec.offset >= to {
                break;
            }
            if rec.offset + rec.extent() > to || !self.wanted(g, turn) {
                continue;
            }
            if !self.skip(cur, rec.offset, purpose, turn) {
                ok = false;
                break;
            }
            match self.load(g, Purpose::Prefetch, turn) {
                Ok(_) => cur = rec.offset + u64::from(rec.len),
                Err(LoadError::NoRoom) | Err(LoadError::Failed) => {}
                Err(LoadError::Preempted) => {
                    ok = false;
                    break;
                }
            }
        }
        self.order = order;
        ok && self.skip(cur, to, purpose, turn)
    }

    /// Reads `from..to` and discards it (the bytes of a gap); false when the
    /// read failed or was preempted by a fetch command, or, from a source
    /// that times its requests, when the gap is not answered already.
    pub(super) fn skip(
        &mut self,
        from: u64,
        to: u64,
        purpose: Purpose,
        turn: &mut dyn Turn,
    ) -> bool {
        if to > from && self.costs.learns_from_responses() && !self.source.is_ready(from, to - from)
        {
            // Over a network a gap is worth reading only as part of a range
            // already requested whole (hinted); block by block it would be
            // a request a block (35 MiB of gaps took 30–60 s at 100 Mbit/s).
            return false;
        }
        let mut at = from;
        while at < to {
            let n = (to - at).min(self.params.block_bytes as u64) as usize;
            self.gap_buf.resize(n, 0);
            let t = self.clock.now();
            let mut buf = std::mem::take(&mut self.gap_buf);
            let res = self.source.read_at(at, &mut buf[..n]);
            self.gap_buf = buf;
            if res.is_err() {
                return false;
            }
            let took = self.clock.now() - t;
            self.observe(at, n, took, purpose);
            self.stats.skipped_bytes += n as u64;
            at += n as u64;
            if purpose == Purpose::Prefetch && at < to && turn.preempted() {
                return false;
            }
        }
        true
    }

    /// Whether the first block of a prefetch read of rep `r` ends before
    /// the next fetch command is due. A read that overruns delays P_R's
    /// next frame by the overrun: the estimate is per read, so that a small
    /// rep still fits at the end of a frame where a large one would not.
    pub(super) fn first_block_in_time(&self, r: RepId, turn: &mut dyn Turn) -> bool {
        turn.ends_in_time(self.clock.now(), self.first_block_s(r))
    }

    /// The expected time of the first block of a read of rep `r` (a seek
    /// unless it goes on from the last read, and up to a block; the rest
    /// may be preempted and resumed), from where a preempted read of it
    /// stopped.
    pub(super) fn first_block_s(&self, r: RepId) -> f64 {
        let rec = self.skeleton.reps[r as usize];
        let (at, bytes) = match &self.partial {
            Some(p) if p.rep == r => (rec.offset + p.done as u64, (p.buf.len() - p.done) as u64),
            _ => match self.page_read_s(&rec) {
                Some(s) => return s,
                None => (rec.offset, u64::from(rec.len)),
            },
        };
        let block = self.params.block_bytes as u64;
        if self.source.is_ready(at, bytes.min(block)) {
            // Answered already (a request started ahead): a copy.
            return self.costs.overhead_s;
        }
        self.costs.first_block_estimate(at, bytes, block)
    }

    /// Prefetches rep `r`, then reads on to the candidates stored after it
    /// while that is cheap ([`extend_prefetch`](Self::extend_prefetch)).
    pub(super) fn prefetch_read(&mut self, r: RepId, turn: &mut dyn Turn) -> Result<(), LoadError> {
        self.load(r, Purpose::Prefetch, turn)?;
        self.extend_prefetch(r, turn)
    }

    /// Continues a prefetch read past rep `x` to the next candidates stored
    /// within the break-even gap, while each read, going on from where the
    /// last one ended, still ends before the next fetch command is due.
    pub(super) fn extend_prefetch(
        &mut self,
        mut x: RepId,
        turn: &mut dyn Turn,
    ) -> Result<(), LoadError> {
        loop {
            let rec = self.skeleton.reps[x as usize];
            let end = rec.offset + u64::from(rec.len);
            let gap = self.max_gap();
            let next = self
                .order
                .after(x)
                .iter()
                .take_while(|&&g| self.skeleton.reps[g as usize].offset <= end + gap)
                .copied()
                .find(|&g| self.wanted(g, turn));
            let Some(n) = next else { return Ok(()) };
            let nrec = self.skeleton.reps[n as usize];
            let bytes = nrec.offset - end + u64::from(nrec.len);
            let need_s = self.costs.overhead_s + bytes as f64 * self.costs.per_byte_s;
            // `n` is the first candidate after `x`: the gap holds none.
            if self.costs.last_end() != Some(end)
                || !turn.ends_in_time(self.clock.now(), need_s)
                || !self.skip(end, nrec.offset, Purpose::Prefetch, turn)
            {
                return Ok(());
            }
            self.load(n, Purpose::Prefetch, turn)?;
            x = n;
        }
    }
}
