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
mod costs;
mod inbox;
mod late;
mod misses;
mod order;
mod outbox;
mod pacing;
mod page_cache;
mod pages;
mod plan;
#[cfg(test)]
mod plan_tests;
mod reads;
mod retry;
mod span;
mod sweep;

use std::sync::Arc;
use std::time::Instant;

use crossbeam_channel::{Receiver, Sender, TryRecvError};

use super::footprint::Footprint;
use super::params::{Mode, RuntimeError, RuntimeParams};
use super::protocol::{Cmd, Draw, Reply};
use super::resident::Purpose;
use crate::camera::View;
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
use order::ReadQueue;
pub(super) use outbox::capacity as reply_capacity;
use outbox::{Outbox, RendererGone};
use pacing::Pacing;
use plan::Plan;
use reads::{LoadError, ReadParams, Reads, Turn};
use sweep::Sweep;

/// The read planners: the binned candidates (CLASSIFY), the fronts ahead,
/// the sweep through small reps, and the late reads of this frame.
struct Planners {
    classes: Classifier,
    ahead: Lookahead,
    sweep: Sweep,
    late: LateReads,
}

/// P_I: a command loop around the reads ([`Reads`]: the resident set
/// under the footprint, the source and the read costs) and the read
/// planners; it decides what is read and when.
pub(super) struct Loader {
    skeleton: Arc<Skeleton>,
    index: Arc<FrontIndex>,
    params: RuntimeParams,
    reads: Reads,
    plans: Planners,
    /// P_R's commands, one taken early by a preemption check kept.
    inbox: Inbox,
    /// The replies to P_R, draws grouped.
    out: Outbox,
    /// The fetch commands' rhythm (when the next one is due).
    pacing: Pacing,
    misses: MissAccount,
    /// P_I has no time for another prefetch read before the next fetch
    /// command (the candidates stay for the frames after it).
    wait_fetch: bool,
}

/// What a read asks of the loop ([`Turn`]): the inbox, P_R's draws not
/// yet started, the pacing and the planners' candidates.
struct LoopTurn<'a> {
    inbox: &'a mut Inbox,
    out: &'a mut Outbox,
    pacing: &'a Pacing,
    plans: &'a Planners,
}

impl Turn for LoopTurn<'_> {
    fn preempted(&mut self) -> bool {
        self.inbox.preempted()
    }

    fn queued(&self, r: RepId, frame: u32) -> bool {
        self.plans.classes.is_queued(r) || self.plans.late.is_late(r, frame)
    }

    fn is_late(&self, r: RepId, frame: u32) -> bool {
        self.plans.late.is_late(r, frame)
    }

    fn is_recent(&self, r: RepId) -> bool {
        self.plans.classes.is_recent(r)
    }

    /// Always while P_R has a group of draws it has not started (it draws
    /// before it asks again), else as the pacing expects.
    fn ends_in_time(&mut self, now: Instant, need_s: f64) -> bool {
        self.out.p_r_busy() || self.pacing.ends_in_time(now, need_s)
    }
}

impl Loader {
    pub(super) fn new(
        skeleton: Arc<Skeleton>,
        index: Arc<FrontIndex>,
        source: Arc<dyn ByteSource>,
        pools: &[Option<u64>],
        (params, fp): (RuntimeParams, Footprint),
        (cmds, replies): (Receiver<Cmd>, Sender<Reply>),
        clock: Arc<dyn crate::clock::Clock>,
    ) -> Self {
        let n = skeleton.reps.len();
        let bins = Bins::new(params.prefetch.bins, params.delta(), params.tolerance_px);
        Self {
            plans: Planners {
                classes: Classifier::new(n, bins),
                ahead: Lookahead::default(),
                sweep: Sweep::default(),
                late: LateReads::new(n),
            },
            pacing: Pacing::default(),
            misses: MissAccount::new(skeleton.nodes.len()),
            reads: Reads::new(
                skeleton.clone(),
                source,
                pools,
                (ReadParams::of(&params), fp),
                clock,
            ),
            skeleton,
            index,
            params,
            inbox: Inbox::new(cmds),
            out: Outbox::new(replies),
            wait_fetch: false,
        }
    }

    /// The reads, and what they ask of the loop while they run.
    fn parts(&mut self) -> (&mut Reads, LoopTurn<'_>) {
        let turn = LoopTurn {
            inbox: &mut self.inbox,
            out: &mut self.out,
            pacing: &self.pacing,
            plans: &self.plans,
        };
        (&mut self.reads, turn)
    }

    fn clock(&self) -> &dyn crate::clock::Clock {
        self.reads.clock.as_ref()
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
                && (self.plans.late.queue.pending()
                    || (self.params.mode == Mode::Pre
                        && (!self.plans.classes.bins.is_empty()
                            || self.plans.ahead.queue.pending())))
            {
                match self.inbox.try_recv() {
                    Ok(c) => c,
                    Err(TryRecvError::Empty) => {
                        if !self.serve(|p| &mut p.late.queue) && self.params.mode == Mode::Pre {
                            self.prefetch_step();
                        }
                        continue;
                    }
                    Err(TryRecvError::Disconnected) => return,
                }
            } else {
                let t = self.clock().now();
                // Requests started ahead may answer meanwhile: look again soon.
                let poll = (self.wait_fetch && self.reads.fp.in_flight() > 0).then_some(READY_POLL);
                let c = self.inbox.recv_within(poll);
                if !self.wait_fetch {
                    self.reads.stats.idle_ms += self.clock().ms_since(t);
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
                    self.plans.classes.set_hidden(&front, &hidden);
                    self.keep_hidden(&hidden);
                    let now = self.clock().now();
                    self.pacing
                        .on_fetch(now, f64::from(self.params.frame_period_s));
                    self.wait_fetch = false;
                    self.plans.ahead.observe(&view.pose);
                    if self.fetch(&front, &fading).is_err() {
                        return;
                    }
                    if self.params.mode == Mode::Pre {
                        let t = self.clock().now();
                        self.classify(&view, turn_rad);
                        self.hint_prefetch();
                        self.reads.stats.classify_ms += self.clock().ms_since(t);
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
        let res = &mut self.reads.res;
        for &r in hidden {
            if res.contains(r) {
                res.access(r);
                res.set_speculative(r, false);
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
        self.plans.classes.rebin(Bins::new(
            self.params.prefetch.bins,
            self.params.delta(),
            tol,
        ));
    }

    /// Classifies the front of `view` for prefetching (when it moved), and
    /// plans the sweep and the lookahead from F_I's front.
    fn classify(&mut self, view: &View, turn_rad: f32) {
        let Some(room) = self.reads.rep_room(Purpose::Prefetch) else {
            return; // in core: nothing is prefetched
        };
        let plan = Plan::of(&self.skeleton, &self.index, &self.params).with_room(room);
        // A fetch command that arrives meanwhile cuts the classification
        // short: Stage II comes first.
        let inbox = &mut self.inbox;
        let mut stop = || inbox.waiting() || inbox.preempted();
        let (reads, plans) = (&mut self.reads, &mut self.plans);
        let Some((front, margin)) = plans
            .classes
            .classify_front(&plan, &reads.res, view, turn_rad, &mut stop)
        else {
            return;
        };
        plans.sweep.plan(&plan, &reads.res, &reads.failed, front);
        let t = reads.clock.now();
        plans.ahead.plan(
            &plan,
            &mut reads.res,
            &reads.failed,
            &mut plans.classes,
            view,
            margin,
            reads.clock.as_ref(),
            &mut stop,
        );
        reads.stats.lookahead_ms += reads.clock.ms_since(t);
    }

    /// [`Reads::hint_reads`] for what P_I prefetches next: the fronts
    /// ahead, then the bins in the order they are served.
    fn hint_prefetch(&self) {
        let ahead = self.plans.ahead.queue.rest().iter().copied();
        let bins = self.plans.classes.bins.iter().map(|(r, _)| r);
        self.reads.hint_reads(ahead.chain(bins), 1024);
    }

    /// P_R could not use rep `r` (a view-dependence tree whose store did not
    /// start): drop it and substitute its ancestor from now on.
    fn unusable(&mut self, r: RepId) {
        let reads = &mut self.reads;
        if reads.failed[r as usize] {
            return;
        }
        reads.failed[r as usize] = true;
        reads.stats.read_errors += 1;
        if reads.partial.as_ref().is_some_and(|p| p.rep == r) {
            reads.cancel_partial();
        }
        if reads.res.contains(r) {
            reads.drop_rep(r);
        }
    }

    fn start_up(&mut self) -> Result<(), RuntimeError> {
        let root = &self.skeleton.nodes[0];
        if self.params.mode == Mode::Incore {
            for r in 0..self.skeleton.reps.len() as RepId {
                // Unreadable reps are substituted at draw time, as in the other modes.
                let (reads, mut turn) = self.parts();
                let _ = reads.load(r, Purpose::Demand, &mut turn);
            }
            self.reads.stats = LoaderCounters {
                max_resident_bytes: self.reads.res.bytes(),
                ..LoaderCounters::default()
            };
            return Ok(());
        }
        if root.rep_count == 0 {
            return Ok(());
        }
        let r = root.first_rep;
        let need = self.reads.cost(r) + self.skeleton.reps[r as usize].load_scratch();
        self.reads.fp.check_root(need)?;
        let (reads, mut turn) = self.parts();
        match reads.load(r, Purpose::Demand, &mut turn) {
            Ok(_) => {
                reads.res.keep(r);
                reads.stats = LoaderCounters {
                    max_resident_bytes: reads.res.bytes(),
                    ..LoaderCounters::default()
                };
                Ok(())
            }
            Err(_) => Err(RuntimeError::RootUnreadable(format!("rep {r}"))),
        }
    }

    /// Stage II for one front, and the reps P_R draws fading out.
    fn fetch(&mut self, front: &[RepId], fading: &[RepId]) -> Result<(), RendererGone> {
        let now = self.clock().now();
        for r in self.reads.retry.release(now) {
            self.reads.failed[r as usize] = false;
        }
        self.reads.res.start_stage2(front);
        self.reads.plan_pages();
        self.send_fading(front, fading)?;
        let mut missing = Vec::new();
        for &r in front {
            match self.reads.res.payload(r) {
                Some(d) => {
                    let payload = d.clone();
                    self.reads.res.access(r);
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
        self.out.flush(self.reads.clock.as_ref())?;
        let stats = &mut self.reads.stats;
        stats.missing_reps = missing.len() as u32;
        let m = self
            .misses
            .account(&self.skeleton, self.reads.res.frame(), front, &missing);
        stats.miss_lod += m.lod;
        stats.miss_hier += m.hier;
        stats.miss_new += m.new;
        // In file order: neighbouring reps are read without a seek.
        missing.sort_unstable_by_key(|&r| self.skeleton.reps[r as usize].offset);
        self.reads
            .hint_reads(missing.iter().copied(), missing.len());
        self.plans.late.clear();
        for (i, &r) in missing.iter().enumerate() {
            if !self.in_time_for_frame(r) {
                // Past the stall deadline: ancestors now, the reps after.
                for &x in &missing[i..] {
                    self.reads.stats.late_reps += 1;
                    self.plans.late.push(x, self.reads.res.frame());
                    self.substitute(x)?;
                }
                break;
            }
            let offset = self.skeleton.reps[r as usize].offset;
            let (reads, mut turn) = self.parts();
            if let Some(end) = reads.costs.last_end() {
                // Through a short gap (keeping prefetch candidates on the way).
                reads.bridge(end, offset, Purpose::Demand, &mut turn);
            }
            match reads.load(r, Purpose::Demand, &mut turn) {
                Ok(payload) => self.send_draw(Draw {
                    rep: r,
                    for_rep: r,
                    payload,
                })?,
                Err(_) => self.substitute(r)?,
            }
        }
        let reads = &mut self.reads;
        reads.stats.resident_bytes = reads.res.bytes() + reads.pages.bytes();
        reads.stats.page_bytes = reads.pages.bytes();
        reads.stats.prefetch_queue = self.plans.classes.bins.len() as u32;
        reads.stats.coalesce_gap = u32::try_from(reads.learnt_gap()).unwrap_or(u32::MAX);
        #[cfg(debug_assertions)]
        {
            if let Err(e) = reads.res.validate().and_then(|()| reads.pages.validate()) {
                panic!("P_I's resident set is inconsistent: {e}");
            }
            // Between reads, only a preempted prefetch read holds a
            // reservation: its footprint and its stored copy.
            let held = reads.partial.as_ref().map_or(0, |p| {
                reads.cost(p.rep) + self.skeleton.reps[p.rep as usize].load_scratch()
            });
            assert_eq!(reads.res.reserved(), held, "a reservation leaked");
        }
        self.out.flush(self.reads.clock.as_ref())?;
        self.reads.stats.reply_wait_ms += self.out.take_wait_ms();
        let stats = std::mem::take(&mut self.reads.stats);
        self.reads.stats.max_resident_bytes = self.reads.res.bytes() + self.reads.pages.bytes();
        self.send(Reply::Done(stats))
    }

    /// Fading out: drawn first, pinned for the frame (the footprint counts
    /// both reps of a switch); an evicted one is not read again. A fade
    /// takes only room the front does not need: the whole front, the kept
    /// root and what is reserved come first.
    fn send_fading(&mut self, front: &[RepId], fading: &[RepId]) -> Result<(), RendererGone> {
        let reads = &mut self.reads;
        let rec = |r: RepId| &self.skeleton.reps[r as usize];
        let mut need = if fading.is_empty() {
            0
        } else {
            reads.res.reserved()
                + reads.cost(self.skeleton.nodes[0].first_rep)
                + front
                    .iter()
                    .map(|&r| {
                        let scratch = if reads.res.contains(r) {
                            0
                        } else {
                            rec(r).load_scratch()
                        };
                        reads.cost(r) + scratch
                    })
                    .sum::<u64>()
        };
        let room = reads.fp.reps();
        let outs: Vec<Draw> = fading
            .iter()
            .filter_map(|&r| {
                let payload = reads.res.payload(r)?.clone();
                let c = reads.cost(r);
                if room.is_some_and(|b| need.saturating_add(c) > b) {
                    return None;
                }
                need += c;
                reads.res.pin(r);
                reads.res.access(r);
                Some(Draw {
                    rep: r,
                    for_rep: r,
                    payload,
                })
            })
            .collect();
        if outs.is_empty() {
            return Ok(());
        }
        self.send(Reply::Fading(outs))
    }

    /// Whether a Stage II read of rep `r` ends within the stall deadline.
    fn in_time_for_frame(&self, r: RepId) -> bool {
        self.pacing.in_time_for_frame(
            self.clock().now(),
            self.reads.first_block_s(r),
            f64::from(self.params.stall_deadline_s),
        )
    }

    /// Reply `r`, after the draws and evictions before it.
    fn send(&mut self, r: Reply) -> Result<(), RendererGone> {
        self.hand_over_evictions();
        self.out.send(r, self.reads.clock.as_ref())
    }

    /// Draw `d` (grouped), after the evictions before it.
    fn send_draw(&mut self, d: Draw) -> Result<(), RendererGone> {
        self.hand_over_evictions();
        self.out.draw(d, self.reads.clock.as_ref())
    }

    /// The reps evicted since the last reply go with the next message.
    fn hand_over_evictions(&mut self) {
        if self.reads.res.has_evicted() {
            self.out.evicted(self.reads.res.take_evicted());
        }
    }

    /// Draws the nearest resident ancestor in place of `r`.
    fn substitute(&mut self, r: RepId) -> Result<(), RendererGone> {
        let mut a = self.skeleton.par(r);
        while let Some(x) = a {
            if let Some(d) = self.reads.res.payload(x) {
                let payload = d.clone();
                self.reads.res.pin(x);
                self.reads.res.access(x);
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

    /// P_I has no time before the next fetch command: it waits for it.
    fn wait_for_fetch(&mut self) {
        self.wait_fetch = true;
        self.reads.stats.prefetch_waits += 1;
    }

    /// PREFETCH: loads the best classified rep, then classifies its parent
    /// and children (to the prefetch depth), which are loaded in their turn
    /// when their bins come up: a neighbour is read only when its own
    /// priority says it is needed soon (P_I has few seeks per frame).
    fn prefetch_step(&mut self) {
        if self.reads.partial.is_none() && self.serve(|p| &mut p.ahead.queue) {
            return;
        }
        if self.plans.sweep.take_turn() && self.reads.partial.is_none() && self.sweep_step() {
            return;
        }
        if let Some(r) = self.reads.partial.as_ref().map(|p| p.rep) {
            // Still a candidate: binned by this classification or the one
            // before (a child is binned again only when its parent comes up).
            if self.plans.classes.is_recent(r) {
                let (reads, mut turn) = self.parts();
                let _ = reads.prefetch_read(r, &mut turn);
                return;
            }
            self.reads.cancel_partial();
        }
        let Some((o, _)) = self.plans.classes.bins.peek() else {
            return;
        };
        let (reads, mut turn) = self.parts();
        if !reads.res.contains(o) && !reads.first_block_in_time(o, &mut turn) {
            // Not even its first block (the seek) before the next frame:
            // wait for the fetch command. (A longer read is preempted and
            // goes on later.)
            self.wait_for_fetch();
            return;
        }
        let Some((o, depth)) = self.plans.classes.bins.pop() else {
            return;
        };
        let (reads, mut turn) = self.parts();
        if reads.res.contains(o) {
            reads.res.access(o);
        } else {
            // On through the file to the next candidates, while cheap.
            match reads.prefetch_read(o, &mut turn) {
                Ok(()) | Err(LoadError::NoRoom) | Err(LoadError::Failed) => {}
                Err(LoadError::Preempted) => return,
            }
        }
        let plan = Plan::of(&self.skeleton, &self.index, &self.params);
        self.plans.classes.classify_neighbours(&plan, o, depth);
    }

    /// One read from the queue `queue` picks (the next rep still wanted), and
    /// on through the file while cheap. Returns whether P_I read or decided
    /// to wait for the next fetch command (the rep's seek would not end
    /// before it); with no room left without evicting what must stay, the
    /// rest of the queue is dropped.
    fn serve(&mut self, queue: fn(&mut Planners) -> &mut ReadQueue) -> bool {
        loop {
            let Some(r) = queue(&mut self.plans).next() else {
                return false;
            };
            let (reads, mut turn) = self.parts();
            if !reads.wanted(r, &turn) {
                queue(&mut self.plans).advance();
                continue;
            }
            if !reads.first_block_in_time(r, &mut turn) {
                self.wait_for_fetch();
                return true;
            }
            queue(&mut self.plans).advance();
            let (reads, mut turn) = self.parts();
            if let Err(LoadError::NoRoom) = reads.prefetch_read(r, &mut turn) {
                queue(&mut self.plans).clear();
            }
            return true;
        }
    }

    /// One sweep read ([`Sweep`]): the next small candidate at or after the
    /// cursor (wrapping round), and on through the file while cheap.
    /// Returns whether it read (or tried to).
    fn sweep_step(&mut self) -> bool {
        let plan = Plan::of(&self.skeleton, &self.index, &self.params);
        let turn = LoopTurn {
            inbox: &mut self.inbox,
            out: &mut self.out,
            pacing: &self.pacing,
            plans: &self.plans,
        };
        let reads = &self.reads;
        let Some(r) = self.plans.sweep.next(&plan, |r| reads.wanted(r, &turn)) else {
            self.plans.sweep.clear();
            return false;
        };
        let rec = self.skeleton.reps[r as usize];
        let (reads, mut turn) = self.parts();
        let bridged = reads
            .costs
            .last_end()
            .is_some_and(|end| reads.bridge(end, rec.offset, Purpose::Prefetch, &mut turn));
        if turn.inbox.waiting() {
            return true;
        }
        if !bridged && !reads.first_block_in_time(r, &mut turn) {
            return false;
        }
        let read = reads.prefetch_read(r, &mut turn);
        let at = reads.costs.last_end().unwrap_or(rec.offset);
        if let Err(LoadError::NoRoom) = read {
            self.plans.sweep.clear();
        }
        self.plans.sweep.moved_to(at);
        true
    }
}
