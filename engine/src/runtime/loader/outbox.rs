//! P_I's replies to P_R, with the draws of a frame grouped into messages.
//!
//! The reply channel is bounded. A front of tens of thousands of reps
//! sent one message per rep fills it, and P_I then waits on the channel
//! for as long as P_R takes to draw: at a sudden turn of the DE-size
//! plant, the reps read in Stage II kept P_I blocked for 200–500 ms of a
//! 250–650 ms frame, with nothing prefetched. So draws are grouped: a group
//! goes out when it is full, or at once when P_R has nothing left to draw
//! (the channel is empty), so that P_R never waits on a group being
//! filled. Every other reply first sends the group before it.
//!
//! The reps evicted while a group fills go out in one message just before
//! it (one message per eviction would break the groups up again, since in
//! Stage II nearly every read evicts). Only the order of an eviction and
//! the draws of *other* reps changes: P_I pins the whole front, and any
//! substitute, for the frame, so a rep evicted during a frame's Stage II
//! is never one P_R draws in that frame. P_R checks this (debug builds).
//!
//! [`capacity`] sizes the channel so that any front fits it in full
//! groups: P_I then never waits for P_R to draw.
//!
//! The draws still in the channel also tell P_I that P_R is busy: its next
//! fetch command cannot come before it has drawn them
//! ([`Outbox::p_r_busy`]).

use std::collections::VecDeque;

use crossbeam_channel::Sender;

use crate::clock::Clock;
use crate::runtime::protocol::{Draw, Reply};
use crate::skeleton::RepId;

/// P_R is gone (its receiver dropped): P_I stops.
#[derive(Debug)]
pub(super) struct RendererGone;

/// Draws per message at most.
pub(super) const DRAW_BATCH: usize = 256;

/// Messages the reply channel holds for a scene of `reps` reps: a front
/// (at most every rep) in full groups, each with its evictions, and the
/// fading, missing and done replies.
pub(crate) fn capacity(reps: usize) -> usize {
    2 * reps.div_ceil(DRAW_BATCH) + 64
}

/// The reply channel and the draws not yet sent.
pub(super) struct Outbox {
    tx: Sender<Reply>,
    group: Vec<Draw>,
    /// Reps evicted since the last message (sent before the group).
    evicted: Vec<RepId>,
    /// Time spent waiting on a full channel since the last `take_wait_ms`.
    wait_ms: f64,
    /// The draws in each message sent and maybe not yet received (the
    /// newest last), and their sum.
    sent: VecDeque<usize>,
    sent_draws: usize,
}

impl Outbox {
    pub(super) fn new(tx: Sender<Reply>) -> Self {
        Self {
            tx,
            group: Vec::new(),
            evicted: Vec::new(),
            wait_ms: 0.0,
            sent: VecDeque::new(),
            sent_draws: 0,
        }
    }

    /// One message, timed when the channel is full.
    fn put(&mut self, r: Reply, clock: &dyn Clock) -> Result<(), RendererGone> {
        let draws = match &r {
            Reply::Draws(ds) | Reply::Fading(ds) => ds.len(),
            _ => 0,
        };
        self.queued_draws();
        self.sent.push_back(draws);
        self.sent_draws += draws;
        match self.tx.try_send(r) {
            Ok(()) => Ok(()),
            Err(crossbeam_channel::TrySendError::Full(r)) => {
                let t = clock.now();
                let sent = self.tx.send(r).map_err(|_| RendererGone);
                self.wait_ms += clock.ms_since(t);
                sent
            }
            Err(crossbeam_channel::TrySendError::Disconnected(_)) => Err(RendererGone),
        }
    }

    /// Sends the evictions and the draws grouped so far.
    pub(super) fn flush(&mut self, clock: &dyn Clock) -> Result<(), RendererGone> {
        if !self.evicted.is_empty() {
            let ev = std::mem::take(&mut self.evicted);
            self.put(Reply::Evicted(ev), clock)?;
        }
        if self.group.is_empty() {
            return Ok(());
        }
        let g = std::mem::replace(&mut self.group, Vec::with_capacity(DRAW_BATCH));
        self.put(Reply::Draws(g), clock)
    }

    /// Reps evicted since the last reply: they go out with the next
    /// message, before the group.
    pub(super) fn evicted(&mut self, reps: Vec<RepId>) {
        self.evicted.extend(reps);
    }

    /// Reply `r`, after the reps evicted and the draws grouped before it.
    pub(super) fn send(&mut self, r: Reply, clock: &dyn Clock) -> Result<(), RendererGone> {
        self.flush(clock)?;
        self.put(r, clock)
    }

    /// Draw `d`, grouped.
    pub(super) fn draw(&mut self, d: Draw, clock: &dyn Clock) -> Result<(), RendererGone> {
        self.group.push(d);
        if self.group.len() >= DRAW_BATCH || self.tx.is_empty() {
            self.flush(clock)?;
        }
        Ok(())
    }

    /// Draws sent that P_R has not taken yet (messages are taken in order).
    pub(super) fn queued_draws(&mut self) -> usize {
        while self.sent.len() > self.tx.len() {
            self.sent_draws -= self.sent.pop_front().unwrap_or(0);
        }
        self.sent_draws
    }

    /// Whether P_R has at least a full group of draws it has not started:
    /// its next fetch command is not about to come, whatever the pacing
    /// expected (a frame that draws a large front takes longer than the
    /// frame period).
    pub(super) fn p_r_busy(&mut self) -> bool {
        self.queued_draws() >= DRAW_BATCH
    }

    /// The time spent waiting on a full channel since the last call.
    pub(super) fn take_wait_ms(&mut self) -> f64 {
        std::mem::take(&mut self.wait_ms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crossbeam_channel::bounded;
    use std::sync::Arc;

    fn d(r: RepId) -> Draw {
        Draw {
            rep: r,
            for_rep: r,
            payload: Arc::from(vec![0u8; 4]),
        }
    }

    /// What P_R would see, in order: `D[reps]`, `E[reps]`, `M` or `.`.
    fn seen(rx: &crossbeam_channel::Receiver<Reply>) -> Vec<String> {
        rx.try_iter()
            .map(|r| match r {
                Reply::Draws(ds) => format!("D{:?}", ds.iter().map(|d| d.rep).collect::<Vec<_>>()),
                Reply::Evicted(ev) => format!("E{ev:?}"),
                Reply::Missing => "M".into(),
                _ => ".".into(),
            })
            .collect()
    }

    #[test]
    fn draws_are_grouped_while_p_r_is_busy_and_sent_at_once_when_it_is_not() {
        let (tx, rx) = bounded(4);
        let clock = crate::clock::ManualClock::new();
        let mut out = Outbox::new(tx);
        // P_R has nothing to draw: the first draw goes out alone.
        out.draw(d(1), &clock).unwrap();
        // Not taken yet: the next ones wait in a group.
        out.draw(d(2), &clock).unwrap();
        out.draw(d(3), &clock).unwrap();
        assert_eq!(seen(&rx), ["D[1]"]);
        // P_R took everything: the next draw sends the group with it.
        out.draw(d(4), &clock).unwrap();
        assert_eq!(seen(&rx), ["D[2, 3, 4]"]);
        // A full group goes out even while P_R is busy.
        out.draw(d(5), &clock).unwrap();
        for r in 6..6 + DRAW_BATCH as RepId {
            out.draw(d(r), &clock).unwrap();
        }
        let s = seen(&rx);
        assert_eq!(s.len(), 2);
        assert!(s[1].starts_with("D[6, 7,"), "{s:?}");
    }

    #[test]
    fn evictions_go_just_before_their_group_and_other_replies_after_it() {
        let (tx, rx) = bounded(16);
        let clock = crate::clock::ManualClock::new();
        let mut out = Outbox::new(tx);
        out.evicted(vec![7]);
        out.draw(d(1), &clock).unwrap();
        out.draw(d(2), &clock).unwrap();
        // Evictions while a group fills do not break it up.
        out.evicted(vec![9]);
        out.draw(d(3), &clock).unwrap();
        out.draw(d(4), &clock).unwrap();
        // Another reply sends the evictions and the group before it.
        out.evicted(vec![8]);
        out.send(Reply::Missing, &clock).unwrap();
        assert_eq!(seen(&rx), ["E[7]", "D[1]", "E[9, 8]", "D[2, 3, 4]", "M"]);
        assert_eq!(out.take_wait_ms(), 0.0);
    }

    #[test]
    fn the_channel_holds_any_front_in_groups() {
        // Every rep of the scene drawn, each read evicting: full groups,
        // each with its evictions, fill the channel and never overflow it.
        let reps = 10 * DRAW_BATCH + 3;
        let (tx, rx) = bounded(capacity(reps));
        let clock = crate::clock::ManualClock::new();
        let mut out = Outbox::new(tx);
        for r in 0..reps as RepId {
            out.evicted(vec![r + 100_000]);
            out.draw(d(r), &clock).unwrap();
        }
        out.send(Reply::Missing, &clock).unwrap();
        assert_eq!(out.take_wait_ms(), 0.0);
        assert!(rx.len() <= 2 * 12 + 1, "{}", rx.len());
    }

    #[test]
    fn hundreds_of_draws_fit_a_channel_of_a_few_messages_while_p_r_draws() {
        // P_R takes nothing (it is drawing): one message a rep would have
        // filled the 4 slots after 4 draws and waited there.
        let (tx, rx) = bounded(4);
        let clock = crate::clock::ManualClock::new();
        let mut out = Outbox::new(tx);
        for r in 0..1 + 3 * DRAW_BATCH as RepId {
            out.draw(d(r), &clock).unwrap();
        }
        assert_eq!(rx.len(), 4);
        assert_eq!(out.take_wait_ms(), 0.0);
        let drawn: usize = rx
            .try_iter()
            .map(|r| match r {
                Reply::Draws(ds) => ds.len(),
                _ => 0,
            })
            .sum();
        assert_eq!(drawn, 1 + 3 * DRAW_BATCH);
    }

    #[test]
    fn p_r_is_busy_while_a_group_it_has_not_taken_is_queued() {
        let (tx, rx) = bounded(capacity(4 * DRAW_BATCH));
        let clock = crate::clock::ManualClock::new();
        let mut out = Outbox::new(tx);
        assert!(!out.p_r_busy());
        for r in 0..2 * DRAW_BATCH as RepId {
            out.draw(d(r), &clock).unwrap();
        }
        out.send(Reply::Missing, &clock).unwrap();
        // One draw alone (P_R was waiting), a full group, then the rest.
        assert_eq!(out.queued_draws(), 2 * DRAW_BATCH);
        assert!(out.p_r_busy());
        rx.recv().unwrap();
        rx.recv().unwrap();
        assert_eq!(out.queued_draws(), DRAW_BATCH - 1);
        assert!(!out.p_r_busy(), "less than a group left");
        rx.try_iter().count();
        assert_eq!(out.queued_draws(), 0);
    }

    #[test]
    fn a_gone_renderer_is_an_error_not_a_hang() {
        let (tx, rx) = bounded(1);
        drop(rx);
        let clock = crate::clock::ManualClock::new();
        let mut out = Outbox::new(tx);
        assert!(out.draw(d(1), &clock).is_err());
    }
}
