//! Requests in flight for a remote source: the ranges P_I says it reads
//! next ([`engine::ByteSource::hint`]) are requested several at a time, and
//! a later read inside one is served from its answer.
//!
//! The bookkeeping is a plain value (no runtime, no network): it is told
//! how to start a request (`start`, returning its handle) and which ranges
//! are hinted, and says which requests to cancel. Bounds: at most
//! `max_requests` requests live, and their ranges, in flight or answered
//! and not yet read, hold at most `cap` bytes — the share of the footprint
//! the runtime set aside for them.

use std::collections::{HashSet, VecDeque};

/// What a read finds among the requests started ahead.
#[derive(Debug)]
pub enum Lookup<H> {
    /// Served: the bytes were copied into the read's buffer.
    Done,
    /// Its request is in flight: wait for `handle`, then [`ReadAhead::finish`].
    Wait { handle: H, start: u64 },
    /// Not started ahead (or being waited for by another reader).
    Miss,
}

#[derive(Debug)]
enum State<H> {
    Pending(H),
    Ready(Vec<u8>),
    /// Being waited for by a reader.
    Taken,
}

#[derive(Debug)]
struct Live<H> {
    start: u64,
    end: u64,
    state: State<H>,
    /// Not in the last hint: kept (a read may still use it) until its
    /// slot or bytes are wanted for a hinted range.
    stale: bool,
    /// A read took bytes from it and its end is not read yet; once a later
    /// read starts past its end, the reads (in file order) have left it
    /// behind, and it gives its slot up after the stale ranges. (Kept as
    /// long as not stale, a page hinted whole and read rep by rep, its last
    /// rep not wanted, held a slot for the rest of the hint: 16 such pages
    /// and every later read of a Stage II was a request of its own, one
    /// round trip each.)
    used: bool,
}

/// Counters of reading ahead.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AheadStats {
    /// Reads served from a request started ahead.
    pub hits: u64,
    /// Requests started ahead.
    pub started: u64,
    /// Requests cancelled or answers dropped unread (their ranges were no
    /// longer hinted), and the bytes of the answers dropped.
    pub dropped: u64,
    pub dropped_bytes: u64,
    /// The most requests in flight at once.
    pub peak_in_flight: u64,
}

/// The requests started ahead, and the hinted ranges not started yet.
#[derive(Debug)]
pub struct ReadAhead<H> {
    cap: u64,
    max_requests: usize,
    queue: VecDeque<(u64, u64)>,
    live: Vec<Live<H>>,
    stats: AheadStats,
    /// Where the latest read started.
    at: u64,
}

impl<H> ReadAhead<H> {
    /// Off (a cap of 0) until [`set_cap`](Self::set_cap); at most
    /// `max_requests` requests live.
    pub fn new(max_requests: usize) -> Self {
        Self {
            cap: 0,
            max_requests: max_requests.max(1),
            queue: VecDeque::new(),
            live: Vec::new(),
            stats: AheadStats::default(),
            at: 0,
        }
    }

    pub fn stats(&self) -> AheadStats {
        self.stats
    }

    /// Bytes the live requests' ranges hold (in flight or answered).
    pub fn held(&self) -> u64 {
        self.live.iter().map(|l| l.end - l.start).sum()
    }

    /// The most bytes the live ranges may hold. A lower cap drops ranges
    /// until they fit — the stale ones first, then the least urgent (the
    /// last started), never one a read is waiting on — and returns the
    /// handles to cancel; ranges queued that no longer fit go too.
    pub fn set_cap(&mut self, cap: u64) -> Vec<H> {
        self.cap = cap;
        if cap == 0 {
            self.queue.clear();
            return self.drop_where(|_| true);
        }
        self.queue.retain(|&(a, b)| b - a <= cap);
        if self.held() <= cap {
            return Vec::new();
        }
        let mut cancel = self.drop_where(|l| l.stale);
        while self.held() > cap {
            let Some(i) = self
                .live
                .iter()
                .rposition(|l| !matches!(l.state, State::Taken))
            else {
                break;
            };
            let l = self.live.remove(i);
            cancel.extend(count_dropped(&mut self.stats, l));
        }
        cancel
    }

    /// The ranges read next, most urgent first: those already live stay,
    /// the others live become stale, and requests start for the rest in
    /// order, within the bounds, a stale range dropped (its handle
    /// returned, to cancel) whenever its slot or bytes are wanted.
    pub fn hint(&mut self, ranges: &[(u64, u64)], start: impl FnMut(u64, u64) -> H) -> Vec<H> {
        if self.cap == 0 {
            return Vec::new();
        }
        let wanted: HashSet<(u64, u64)> = ranges.iter().copied().collect();
        for l in &mut self.live {
            l.stale = !wanted.contains(&(l.start, l.end));
        }
        self.queue.clear();
        let mut seen: HashSet<(u64, u64)> = self.live.iter().map(|l| (l.start, l.end)).collect();
        for &(a, b) in ranges {
            if b > a && b - a <= self.cap && seen.insert((a, b)) {
                self.queue.push_back((a, b));
            }
        }
        self.fill(start)
    }

    /// Whether `offset..offset + len` lies in a range already answered
    /// (`done` says whether a request in flight has its answer).
    pub fn is_ready(&self, offset: u64, len: u64, done: impl Fn(&H) -> bool) -> bool {
        let end = offset + len;
        self.live.iter().any(|l| {
            l.start <= offset
                && end <= l.end
                && match &l.state {
                    State::Ready(_) => true,
                    State::Pending(h) => done(h),
                    State::Taken => false,
                }
        })
    }

    /// A read of `buf.len()` bytes at `offset`: served from an answer
    /// already here, or the handle of the request to wait for.
    pub fn lookup(&mut self, offset: u64, buf: &mut [u8]) -> Lookup<H> {
        self.at = offset;
        let end = offset + buf.len() as u64;
        let Some(i) = self
            .live
            .iter()
            .position(|l| l.start <= offset && end <= l.end)
        else {
            return Lookup::Miss;
        };
        let start = self.live[i].start;
        match std::mem::replace(&mut self.live[i].state, State::Taken) {
            State::Ready(bytes) => {
                self.serve(i, bytes, offset, buf);
                Lookup::Done
            }
            State::Pending(handle) => Lookup::Wait { handle, start },
            State::Taken => Lookup::Miss,
        }
    }

    /// The answer of the request at `start` that a read waited for:
    /// copies the read's bytes into `buf` and keeps the rest for later
    /// reads. `false` (the range dropped) when the request failed or the
    /// range is gone: the read goes to the server itself. Also the handles
    /// of stale requests dropped to start the next ranges, to cancel.
    pub fn finish(
        &mut self,
        start: u64,
        answer: Option<Vec<u8>>,
        offset: u64,
        buf: &mut [u8],
        begin: impl FnMut(u64, u64) -> H,
    ) -> (bool, Vec<H>) {
        let Some(i) = self
            .live
            .iter()
            .position(|l| l.start == start && matches!(l.state, State::Taken))
        else {
            return (false, Vec::new());
        };
        let ok = match answer {
            Some(bytes) if bytes.len() as u64 == self.live[i].end - start => {
                self.serve(i, bytes, offset, buf);
                true
            }
            _ => {
                self.live.remove(i);
                false
            }
        };
        (ok, self.fill(begin))
    }

    /// Copies `offset..offset + buf.len()` out of live range `i`'s
    /// `bytes`; the range goes once its end has been read.
    fn serve(&mut self, i: usize, bytes: Vec<u8>, offset: u64, buf: &mut [u8]) {
        let at = (offset - self.live[i].start) as usize;
        buf.copy_from_slice(&bytes[at..at + buf.len()]);
        self.stats.hits += 1;
        if offset + buf.len() as u64 >= self.live[i].end {
            self.live.remove(i);
        } else {
            self.live[i].state = State::Ready(bytes);
            self.live[i].used = true;
        }
    }

    /// Starts the queued ranges in order while the bounds allow (after a
    /// read took a range's last bytes); the handles to cancel.
    pub fn refill(&mut self, start: impl FnMut(u64, u64) -> H) -> Vec<H> {
        self.fill(start)
    }

    /// Starts the queued ranges in order while the bounds allow, dropping
    /// stale ranges (oldest first) for them; the handles to cancel.
    fn fill(&mut self, mut start: impl FnMut(u64, u64) -> H) -> Vec<H> {
        let mut cancel = Vec::new();
        while let Some(&(a, b)) = self.queue.front() {
            if self.live.len() >= self.max_requests || self.held() + (b - a) > self.cap {
                let at = self.at;
                let free = |l: &Live<H>, passed: bool| {
                    (l.stale || (passed && l.used && at >= l.end))
                        && !matches!(l.state, State::Taken)
                };
                let Some(i) = (self.live.iter().position(|l| free(l, false)))
                    .or_else(|| self.live.iter().position(|l| free(l, true)))
                else {
                    break;
                };
                let l = self.live.remove(i);
                cancel.extend(count_dropped(&mut self.stats, l));
                continue;
            }
            self.queue.pop_front();
            self.live.push(Live {
                start: a,
                end: b,
                state: State::Pending(start(a, b)),
                stale: false,
                used: false,
            });
            self.stats.started += 1;
        }
        let pending = self
            .live
            .iter()
            .filter(|l| !matches!(l.state, State::Ready(_)))
            .count() as u64;
        self.stats.peak_in_flight = self.stats.peak_in_flight.max(pending);
        cancel
    }

    /// Drops the live ranges `gone` picks (not those a reader waits for);
    /// the handles of their requests still in flight, to cancel.
    fn drop_where(&mut self, gone: impl Fn(&Live<H>) -> bool) -> Vec<H> {
        let mut cancel = Vec::new();
        let mut keep = Vec::with_capacity(self.live.len());
        for l in self.live.drain(..) {
            if matches!(l.state, State::Taken) || !gone(&l) {
                keep.push(l);
                continue;
            }
            cancel.extend(count_dropped(&mut self.stats, l));
        }
        self.live = keep;
        cancel
    }
}

/// Counts range `l` as dropped (an answer's bytes as dropped unread); the
/// handle of its request, to cancel, when it is still in flight.
fn count_dropped<H>(stats: &mut AheadStats, l: Live<H>) -> Option<H> {
    stats.dropped += 1;
    match l.state {
        State::Pending(h) => Some(h),
        State::Ready(b) => {
            stats.dropped_bytes += b.len() as u64;
            None
        }
        State::Taken => None,
    }
}

#[cfg(test)]
mod tests;
