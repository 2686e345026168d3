//! P_I: the resident set, fetching (Stage II) and prefetching (Stages III, I).
//!
//! Reads go in file order and through short gaps (`span`): a rep stored
//! just after the one being read costs its transfer, not a seek. Between
//! fetch commands P_I serves, in this order, the fronts of the viewpoints
//! the camera's motion reaches in a few frames (`ahead`), then the bins of
//! the F_I front and its PAR/CHD (`classify`). With
//! `PrefetchParams::sweep_bytes`, the small reps of F_I's front are also
//! read in file order, alternating with the bins (`sweep`). A prefetch
//! read starts only when its first block ends before the next fetch
//! command is due; otherwise P_I waits for that command and keeps its
//! candidates (a camera at rest is not reclassified).

mod ahead;
mod classify;
mod inbox;
mod late;
mod misses;
mod outbox;
mod pacing;
mod pages;
mod plan;
#[cfg(test)]
mod plan_tests;
mod retry;
mod span;
mod sweep;

use std::sync::Arc;

use crossbeam_channel::{Receiver, Sender, TryRecvError};

use super::footprint::Footprint;
use super::resident::{Purpose, ResidentSet};
use super::{Cmd, Draw, Mode, Reply, RuntimeError, RuntimeParams};
use crate::camera::View;
use crate::format::{check_rep_crc, expand_payload};
use crate::front::FrontIndex;
use crate::io::ByteSource;
use crate::metrics::LoaderCounters;
use crate::prefetch::Bins;
use crate::skeleton::{RepId, Skeleton};
use ahead::Lookahead;
use classify::Classifier;
use inbox::{Inbox, READY_POLL};
use late::LateReads;
use misses::MissAccount;
use outbox::Outbox;
pub(super) use outbox::capacity as reply_capacity;
use pacing::Pacing;
use pages::PageCache;
use plan::Plan;
use retry::Retry;
use span::{FileOrder, IoCosts, Partial};
use sweep::Sweep;

/// P_R is gone (its receiver dropped): P_I stops.
#[derive(Debug)]
struct RendererGone;

/// Why a rep was not loaded.
enum LoadError {
    /// The budget cannot make room without evicting reps that must stay.
    NoRoom,
    /// Read or checksum failure (logged once; the rep is not tried again).
    Failed,
    /// A new fetch command arrived during a prefetch read.
    Preempted,
}

/// P_I: a command loop around the resident set and the read planners; it
/// does the reads they ask for.
pub(super) struct Loader {
    skeleton: Arc<Skeleton>,
    index: Arc<FrontIndex>,
    source: Arc<dyn ByteSource>,
    params: RuntimeParams,
    /// P_I's side of the footprint, and its shares.
    fp: Footprint,
    /// P_R's commands, one taken early by a preemption check kept.
    inbox: Inbox,
    /// The replies to P_R, draws grouped.
    out: Outbox,
    /// Where P_I's timing comes from (the system's clock, or a test's).
    clock: Arc<dyn crate::clock::Clock>,
    /// The resident reps, their bytes, pins and the eviction rule.
    res: ResidentSet,
    failed: Vec<bool>,
    /// When failed reps are tried again (a network or device error).
    retry: Retry,
    stats: LoaderCounters,
    /// The planners: the binned candidates (CLASSIFY), the fronts ahead,
    /// the sweep through small reps, and the late reads of this frame.
    classes: Classifier,
    ahead: Lookahead,
    sweep: Sweep,
    late: LateReads,
    /// The fetch commands' rhythm (when the next one is due).
    pacing: Pacing,
    /// Learnt read costs (seek, transfer, break-even gap).
    costs: IoCosts,
    /// The reps in file order, for reads through gaps.
    order: FileOrder,
    /// Bytes of a gap being read through (discarded).
    gap_buf: Vec<u8>,
    /// A prefetch read preempted by a fetch command (its bytes reserved).
    partial: Option<Partial>,
    /// Stored bytes of whole pages read on a seek-bound disk.
    pages: PageCache,
    misses: MissAccount,
    /// P_I has no time for another prefetch read before the next fetch
    /// command (the candidates stay for the frames after it).
    wait_fetch: bool,
}

impl Loader {
    pub(super) fn new(
        skeleton: Arc<Skeleton>,
        index: Arc<FrontIndex>,
        source: Arc<dyn ByteSource>,
        pools: Arc<Vec<u64>>,
        (params, fp): (RuntimeParams, Footprint),
        (cmds, replies): (Receiver<Cmd>, Sender<Reply>),
        clock: Arc<dyn crate::clock::Clock>,
    ) -> Self {
        let n = skeleton.reps.len();
        let skeleton_reps_len: Vec<u64> = skeleton.reps.iter().map(|r| r.resident_len()).collect();
        Self {
            classes: Classifier::new(
                n,
                Bins::new(params.prefetch.bins, params.delta(), params.tolerance_px),
            ),
            ahead: Lookahead::default(),
            sweep: Sweep::default(),
            late: LateReads::new(n),
            pacing: Pacing::default(),
            misses: MissAccount::new(skeleton.nodes.len()),
            order: FileOrder::new(&skeleton),
            res: ResidentSet::new(
                (0..n)
                    .map(|r| footprint(&skeleton_reps_len, &pools, r))
                    .collect(),
            ),
            failed: pools.iter().map(|&p| p == super::trees::UNUSABLE).collect(),
            retry: Retry::default(),
            skeleton,
            index,
            costs: IoCosts::for_source(&*source),
            source,
            pages: PageCache::new(params.page_bytes),
            params,
            fp,
            inbox: Inbox::new(cmds),
            out: Outbox::new(replies),
            clock,
            stats: LoaderCounters::default(),
            gap_buf: Vec::new(),
            partial: None,
            wait_fetch: false,
        }
    }

    /// The thread body: start-up, then commands until shutdown.
    pub(super) fn run(mut self, ready: Sender<Result<(), RuntimeError>>) {
        let started = self.start_up();
        let ok = started.is_ok();
        let _ = ready.send(started);
        if !ok {
            return;
        }
        loop {
            let cmd = if self.inbox.waiting() {
                match self.inbox.try_recv() {
                    Ok(c) => c,
                    Err(_) => continue,
                }
            } else if !self.wait_fetch
                && (self.late.queue.pending()
                    || (self.params.mode == Mode::Pre
                        && (!self.classes.bins.is_empty() || self.ahead.queue.pending())))
            {
                match self.inbox.try_recv() {
                    Ok(c) => c,
                    Err(TryRecvError::Empty) => {
                        if !self.serve(|l| &mut l.late.queue) && self.params.mode == Mode::Pre {
                            self.prefetch_step();
                        }
                        continue;
                    }
                    Err(TryRecvError::Disconnected) => return,
                }
            } else {
                let t = self.clock.now();
                // Requests started ahead may answer meanwhile: look again soon.
                let poll = (self.wait_fetch && self.fp.in_flight() > 0).then_some(READY_POLL);
                let c = self.inbox.recv_within(poll);
                if !self.wait_fetch {
                    self.stats.idle_ms += self.clock.ms_since(t);
                }
                match c {
                    Ok(Some(c)) => c,
                    Ok(None) => {
                        self.wait_fetch = false;
                        continue;
                    }
                    Err(_) => return,
                }
            };
            match cmd {
                Cmd::Fetch {
                    view,
                    turn_rad,
                    front,
                    hidden,
                    tolerance_px,
                    fading,
                } => {
                    self.set_tolerance(tolerance_px);
                    self.classes.set_hidden(&front, &hidden);
                    self.keep_hidden(&hidden);
                    self.pacing
                        .on_fetch(self.clock.now(), f64::from(self.params.frame_period_s));
                    self.wait_fetch = false;
                    self.ahead.observe(&view.pose);
                    if self.fetch(&front, &fading).is_err() {
                        return;
                    }
                    if self.params.mode == Mode::Pre {
                        let t = self.clock.now();
                        self.classify(&view, turn_rad);
                        self.hint_prefetch();
                        self.stats.classify_ms += self.clock.ms_since(t);
                    }
                }
                Cmd::Unusable(r) => self.unusable(r),
                Cmd::Settle(_) => {} // kept by the inbox
                Cmd::Shutdown => return,
            }
        }
    }

    /// The front reps occlusion culling hid are still the view's front at
    /// ε: a resident one is touched (before this Stage II's mark, so a
    /// prefetch may still evict it) and no longer speculative, so that
    /// prefetching does not churn through them under the speculative cap.
    fn keep_hidden(&mut self, hidden: &[RepId]) {
        for &r in hidden {
            if self.res.contains(r) {
                self.res.access(r);
                self.res.set_speculative(r, false);
            }
        }
    }

    /// The governor changed the tolerance: the bins and the classification
    /// follow it.
    fn set_tolerance(&mut self, tol: f32) {
        if tol == self.params.tolerance_px {
            return;
        }
        self.params.tolerance_px = tol;
        self.classes.rebin(Bins::new(
            self.params.prefetch.bins,
            self.params.delta(),
            tol,
        ));
    }

    /// Classifies the front of `view` for prefetching (when it moved), and
    /// plans the sweep and the lookahead from F_I's front.
    fn classify(&mut self, view: &View, turn_rad: f32) {
        let Some(room) = self.rep_room(Purpose::Prefetch) else {
            return; // in core: nothing is prefetched
        };
        let plan = Plan::of(&self.skeleton, &self.index, &self.params).with_room(room);
        // A fetch command that arrives meanwhile cuts the classification
        // short: Stage II comes first.
        let inbox = &mut self.inbox;
        let mut stop = || inbox.waiting() || inbox.preempted();
        let Some((front, margin)) = self
            .classes
            .classify_front(&plan, &self.res, view, turn_rad, &mut stop)
        else {
            return;
        };
        self.sweep.plan(&plan, &self.res, &self.failed, front);
        let t = self.clock.now();
        self.ahead.plan(
            &plan,
            &mut self.res,
            &self.failed,
            &mut self.classes,
            view,
            margin,
            self.clock.as_ref(),
            &mut stop,
        );
        self.stats.lookahead_ms += self.clock.ms_since(t);
    }

    /// Footprint bytes of rep `r` while resident: its payload, and the
    /// reserve of a view-dependence tree's store.
    fn cost(&self, r: RepId) -> u64 {
        self.res.cost(r)
    }

    /// P_R could not use rep `r` (a view-dependence tree whose store did not
    /// start): drop it and substitute its ancestor from now on.
    fn unusable(&mut self, r: RepId) {
        if self.failed[r as usize] {
            return;
        }
        self.failed[r as usize] = true;
        self.stats.read_errors += 1;
        if self.partial.as_ref().is_some_and(|p| p.rep == r) {
            self.cancel_partial();
        }
        if self.res.contains(r) {
            self.drop_rep(r);
        }
    }

    /// Removes resident rep `r` and tells P_R.
    fn drop_rep(&mut self, r: RepId) {
        let wasted = self.res.wasted_bytes();
        self.res
            .remove(r, self.skeleton.reps[r as usize].resident_len());
        self.stats.wasted_bytes += self.res.wasted_bytes() - wasted;
    }

    fn start_up(&mut self) -> Result<(), RuntimeError> {
        let root = &self.skeleton.nodes[0];
        if self.params.mode == Mode::Incore {
            for r in 0..self.skeleton.reps.len() as RepId {
                // Unreadable reps are substituted at draw time, as in the other modes.
                let _ = self.load(r, Purpose::Demand);
            }
            self.stats = LoaderCounters {
                max_resident_bytes: self.res.bytes(),
                ..LoaderCounters::default()
            };
            return Ok(());
        }
        if root.rep_count == 0 {
            return Ok(());
        }
        let r = root.first_rep;
        let need = self.cost(r) + self.skeleton.reps[r as usize].load_scratch();
        self.fp.check_root(need)?;
        match self.load(r, Purpose::Demand) {
            Ok(_) => {
                self.res.keep(r);
                self.stats = LoaderCounters {
                    max_resident_bytes: self.res.bytes(),
                    ..LoaderCounters::default()
                };
                Ok(())
            }
            Err(_) => Err(RuntimeError::RootUnreadable(format!("rep {r}"))),
        }
    }

    /// Stage II for one front, and the reps P_R draws fading out.
    fn fetch(&mut self, front: &[RepId], fading: &[RepId]) -> Result<(), RendererGone> {
        for r in self.retry.release(self.clock.now()) {
            self.failed[r as usize] = false;
        }
        self.res.start_stage2(front);
        self.plan_pages();
        // Fading out: drawn first, pinned for the frame (the footprint
        // counts both reps of a switch); an evicted one is not read again.
        // A fade takes only room the front does not need: the whole front,
        // the kept root and what is reserved come first.
        let rec = |r: RepId| &self.skeleton.reps[r as usize];
        let mut need = if fading.is_empty() {
            0
        } else {
            self.res.reserved()
                + self.cost(self.skeleton.nodes[0].first_rep)
                + front
                    .iter()
                    .map(|&r| {
                        let scratch = if self.res.contains(r) {
                            0
                        } else {
                            rec(r).load_scratch()
                        };
                        self.cost(r) + scratch
                    })
                    .sum::<u64>()
        };
        let room = self.fp.reps();
        let outs: Vec<Draw> = fading
            .iter()
            .filter_map(|&r| {
                let payload = self.res.payload(r)?.clone();
                let c = self.cost(r);
                if room.is_some_and(|b| need.saturating_add(c) > b) {
                    return None;
                }
                need += c;
                self.res.pin(r);
                self.res.access(r);
                Some(Draw {
                    rep: r,
                    for_rep: r,
                    payload,
                })
            })
            .collect();
        if !outs.is_empty() {
            self.send(Reply::Fading(outs))?;
        }
        let mut missing = Vec::new();
        for &r in front {
            match self.res.payload(r) {
                Some(d) => {
                    let payload = d.clone();
                    self.res.access(r);
                    // P_R starts drawing while P_I goes through the rest.
                    self.send_draw(Draw {
                        rep: r,
                        for_rep: r,
                        payload,
                    })?;
                }
                None => missing.push(r),
            }
        }
        self.out.flush(self.clock.as_ref())?;
        self.stats.missing_reps = missing.len() as u32;
        let m = self
            .misses
            .account(&self.skeleton, self.res.frame(), front, &missing);
        self.stats.miss_lod += m.lod;
        self.stats.miss_hier += m.hier;
        self.stats.miss_new += m.new;
        // In file order: neighbouring reps are read without a seek.
        missing.sort_unstable_by_key(|&r| self.skeleton.reps[r as usize].offset);
        self.hint_reads(missing.iter().copied(), missing.len());
        self.late.clear();
        for (i, &r) in missing.iter().enumerate() {
            if !self.in_time_for_frame(r) {
                // Past the stall deadline: ancestors now, the reps after.
                for &x in &missing[i..] {
                    self.stats.late_reps += 1;
                    self.late.push(x, self.res.frame());
                    self.substitute(x)?;
                }
                break;
            }
            if let Some(end) = self.costs.last_end() {
                // Through a short gap (keeping prefetch candidates on the way).
                self.bridge(end, self.skeleton.reps[r as usize].offset, Purpose::Demand);
            }
            match self.load(r, Purpose::Demand) {
                Ok(payload) => self.send_draw(Draw {
                    rep: r,
                    for_rep: r,
                    payload,
                })?,
                Err(_) => self.substitute(r)?,
            }
        }
        self.stats.resident_bytes = self.res.bytes() + self.pages.bytes();
        self.stats.page_bytes = self.pages.bytes();
        self.stats.prefetch_queue = self.classes.bins.len() as u32;
        self.stats.coalesce_gap = u32::try_from(self.learnt_gap()).unwrap_or(u32::MAX);
        #[cfg(debug_assertions)]
        {
            if let Err(e) = self.res.validate().and_then(|()| self.pages.validate()) {
                panic!("P_I's resident set is inconsistent: {e}");
            }
            // Between reads, only a preempted prefetch read holds a
            // reservation: its footprint and its stored copy.
            let held = self.partial.as_ref().map_or(0, |p| {
                self.cost(p.rep) + self.skeleton.reps[p.rep as usize].load_scratch()
            });
            assert_eq!(self.res.reserved(), held, "a reservation leaked");
        }
        self.out.flush(self.clock.as_ref())?;
        self.stats.reply_wait_ms += self.out.take_wait_ms();
        let stats = std::mem::take(&mut self.stats);
        self.stats.max_resident_bytes = self.res.bytes() + self.pages.bytes();
        self.send(Reply::Done(stats))
    }

    /// Reply `r`, after the draws and evictions before it.
    fn send(&mut self, r: Reply) -> Result<(), RendererGone> {
        self.hand_over_evictions();
        self.out.send(r, self.clock.as_ref())
    }

    /// Draw `d` (grouped), after the evictions before it.
    fn send_draw(&mut self, d: Draw) -> Result<(), RendererGone> {
        self.hand_over_evictions();
        self.out.draw(d, self.clock.as_ref())
    }

    /// The reps evicted since the last reply go with the next message.
    fn hand_over_evictions(&mut self) {
        if self.res.has_evicted() {
            self.out.evicted(self.res.take_evicted());
        }
    }

    /// Draws the nearest resident ancestor in place of `r`.
    fn substitute(&mut self, r: RepId) -> Result<(), RendererGone> {
        let mut a = self.skeleton.par(r);
        while let Some(x) = a {
            if let Some(d) = self.res.payload(x) {
                let payload = d.clone();
                self.res.pin(x);
                self.res.access(x);
                return self.send_draw(Draw {
                    rep: x,
                    for_rep: r,
                    payload,
                });
            }
            a = self.skeleton.par(x);
        }
        self.send(Reply::Missing)
    }

    /// Loads rep `r` block by block under the budget.
    fn load(&mut self, r: RepId, purpose: Purpose) -> Result<Arc<[u8]>, LoadError> {
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
                let done = self.read_by_pages(&rec, &mut buf, purpose);
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
                Purpose::Prefetch if self.is_late(r) => self.stats.late_bytes += n,
                Purpose::Prefetch => self.stats.prefetch_bytes += n,
            }
            done = end;
            if purpose == Purpose::Prefetch && done < buf.len() && self.preempted() {
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
        let speculative = purpose == Purpose::Prefetch && !self.is_late(r);
        self.res.insert(r, payload.clone(), speculative);
        self.retry.succeeded();
        Ok(payload)
    }

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

    /// PREFETCH: loads the best classified rep, then classifies its parent
    /// and children (to the prefetch depth), which are loaded in their turn
    /// when their bins come up: a neighbour is read only when its own
    /// priority says it is needed soon (P_I has few seeks per frame).
    fn prefetch_step(&mut self) {
        if self.partial.is_none() && self.serve(|l| &mut l.ahead.queue) {
            return;
        }
        if self.sweep.take_turn() && self.partial.is_none() && self.sweep_step() {
            return;
        }
        if let Some(r) = self.partial.as_ref().map(|p| p.rep) {
            // Still a candidate: binned by this classification or the one
            // before (a child is binned again only when its parent comes up).
            if self.classes.is_recent(r) {
                let _ = self.prefetch_read(r);
                return;
            }
            self.cancel_partial();
        }
        let Some((o, _)) = self.classes.bins.peek() else {
            return;
        };
        if !self.res.contains(o) && !self.first_block_in_time(o) {
            // Not even its first block (the seek) before the next frame:
            // wait for the fetch command. (A longer read is preempted and
            // goes on later.)
            self.wait_fetch = true;
            self.stats.prefetch_waits += 1;
            return;
        }
        let Some((o, depth)) = self.classes.bins.pop() else {
            return;
        };
        if self.res.contains(o) {
            self.res.access(o);
        } else {
            // On through the file to the next candidates, while cheap.
            match self.prefetch_read(o) {
                Ok(()) | Err(LoadError::NoRoom) | Err(LoadError::Failed) => {}
                Err(LoadError::Preempted) => return,
            }
        }
        let plan = Plan::of(&self.skeleton, &self.index, &self.params);
        self.classes.classify_neighbours(&plan, o, depth);
    }
}

/// Footprint of rep `r` while resident: its payload, and the reserve of a
/// view-dependence tree's store.
fn footprint(lens: &[u64], pools: &[u64], r: usize) -> u64 {
    lens[r]
        + Some(pools[r])
            .filter(|&p| p != super::trees::UNUSABLE)
            .unwrap_or(0)
}
