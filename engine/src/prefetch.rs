//! Binned priority prefetching (Varadhan & Manocha §4.2).
//!
//! `AngPr(O) = 1 / (1 + (θ ∼ θ0) / θ1)` with `θ ∼ θ0 = max(θ − θ0, 0)`, where θ
//! is the angle between the line of sight and the rep, θ0 the half-angle of the
//! view frustum F_R and θ1 the extra angle of the enlarged frustum F_I.
//! `Priority(O) = ε_O · AngPr(O)` if `ε_O < ε`, else `ε_O / AngPr(O)`.
//! `[0, δ]` is split into B bins; the bin holding ε is served first, then the
//! bins alternately below and above it, moving outwards. Items in a bin are
//! served in arrival order (a queue per bin, no sorting).

use std::collections::VecDeque;

use crate::skeleton::RepId;

/// The angle priority.
pub fn ang_pr(theta: f32, theta0: f32, theta1: f32) -> f32 {
    let excess = (theta - theta0).max(0.0);
    1.0 / (1.0 + excess / theta1.max(1e-6))
}

/// The integrated priority value of a rep with projected error `eps` (pixels)
/// under tolerance `tol`.
pub fn priority(eps: f32, tol: f32, angpr: f32) -> f32 {
    if eps < tol {
        eps * angpr
    } else {
        eps / angpr.max(1e-6)
    }
}

/// B bins over `[0, δ]` with the service order around ε.
#[derive(Clone, Debug)]
pub struct Bins {
    delta: f32,
    queues: Vec<VecDeque<(RepId, u8)>>,
    /// Bin indices from highest to lowest priority.
    order: Vec<usize>,
    /// Served after every bin: reps out of the view that were hidden when
    /// last in it.
    hidden: VecDeque<(RepId, u8)>,
    len: usize,
}

impl Bins {
    /// `b` bins over `[0, delta]` around the tolerance `tol` (`delta > tol`).
    pub fn new(b: usize, delta: f32, tol: f32) -> Self {
        let b = b.max(1);
        let width = delta / b as f32;
        let start = ((tol / width) as usize).min(b - 1);
        let mut order = vec![start];
        for k in 1..b {
            if start >= k {
                order.push(start - k);
            }
            if start + k < b {
                order.push(start + k);
            }
        }
        Self {
            delta,
            queues: vec![VecDeque::new(); b],
            order,
            hidden: Default::default(),
            len: 0,
        }
    }

    /// The service order of the bins (highest priority first).
    pub fn order(&self) -> &[usize] {
        &self.order
    }

    /// The bin for a priority value; `None` outside `[0, δ]`.
    pub fn bin_of(&self, prio: f32) -> Option<usize> {
        if !(0.0..=self.delta).contains(&prio) {
            return None;
        }
        let b = self.queues.len();
        Some(((prio / self.delta * b as f32) as usize).min(b - 1))
    }

    /// Appends `rep` (found `depth` PAR/CHD steps from the front) to its bin;
    /// returns whether it was classified.
    pub fn push(&mut self, rep: RepId, prio: f32, depth: u8) -> bool {
        match self.bin_of(prio) {
            Some(b) => {
                self.queues[b].push_back((rep, depth));
                self.len += 1;
                true
            }
            None => false,
        }
    }

    /// Appends `rep` after every bin: a rep out of the view that
    /// occlusion culling hid when it was last in it.
    pub fn push_hidden(&mut self, rep: RepId, depth: u8) {
        self.hidden.push_back((rep, depth));
        self.len += 1;
    }

    /// The item [`pop`](Self::pop) would return, left in its bin.
    pub fn peek(&self) -> Option<(RepId, u8)> {
        self.order
            .iter()
            .map(|&b| &self.queues[b])
            .chain([&self.hidden])
            .find_map(|q| q.front().copied())
    }

    /// The items in the order [`pop`](Self::pop) would return them.
    pub fn iter(&self) -> impl Iterator<Item = (RepId, u8)> + '_ {
        self.order
            .iter()
            .flat_map(move |&b| self.queues[b].iter().copied())
            .chain(self.hidden.iter().copied())
    }

    /// The first item of the highest-priority non-empty bin.
    pub fn pop(&mut self) -> Option<(RepId, u8)> {
        let x = self
            .order
            .iter()
            .find(|&&b| !self.queues[b].is_empty())
            .and_then(|&b| self.queues[b].pop_front())
            .or_else(|| self.hidden.pop_front());
        if x.is_some() {
            self.len -= 1;
        }
        x
    }

    /// Flushes every bin.
    pub fn clear(&mut self) {
        for q in self.queues.iter_mut().chain([&mut self.hidden]) {
            q.clear();
        }
        self.len = 0;
    }

    /// Items waiting.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no item waits.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peek_is_what_pop_returns() {
        let mut b = Bins::new(4, 4.0, 1.0);
        assert_eq!(b.peek(), None);
        b.push(7, 3.5, 0);
        b.push(8, 1.2, 1);
        b.push(9, 1.5, 0);
        while let Some(x) = b.peek() {
            assert_eq!(b.pop(), Some(x));
        }
        assert!(b.is_empty());
    }

    #[test]
    fn hidden_reps_come_after_every_bin_in_arrival_order() {
        let mut b = Bins::new(4, 4.0, 1.0);
        b.push_hidden(5, 0);
        b.push(7, 3.9, 1);
        b.push_hidden(6, 1);
        b.push(8, 0.1, 0);
        assert_eq!(b.len(), 4);
        let mut got = Vec::new();
        while let Some(x) = b.peek() {
            assert_eq!(b.pop(), Some(x));
            got.push(x.0);
        }
        assert_eq!(got, [8, 7, 5, 6]);
        b.push_hidden(1, 0);
        b.clear();
        assert!(b.is_empty() && b.pop().is_none());
    }

    #[test]
    fn bin_order_follows_figure_5() {
        // δ = 21, B = 21: bin i holds [i, i+1); ε = 10.5 lies in B10.
        let bins = Bins::new(21, 21.0, 10.5);
        assert_eq!(&bins.order()[..6], &[10, 9, 11, 8, 12, 7]);
        assert_eq!(bins.order().len(), 21);
        let mut sorted = bins.order().to_vec();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..21).collect::<Vec<_>>());
        // ε near the top: after the upper bins run out, the rest descend.
        let top = Bins::new(5, 5.0, 4.5);
        assert_eq!(top.order(), &[4, 3, 2, 1, 0]);
    }

    #[test]
    fn pop_serves_bins_in_priority_order_and_fifo_within() {
        let mut b = Bins::new(10, 10.0, 5.0);
        assert!(b.push(1, 0.5, 0));
        assert!(b.push(2, 5.2, 0));
        assert!(b.push(3, 4.1, 1));
        assert!(b.push(4, 5.9, 0));
        assert!(!b.push(5, 11.0, 0), "beyond δ is not classified");
        assert_eq!(b.len(), 4);
        assert_eq!(b.pop(), Some((2, 0)));
        assert_eq!(b.pop(), Some((4, 0)));
        assert_eq!(b.pop(), Some((3, 1)));
        assert_eq!(b.pop(), Some((1, 0)));
        assert_eq!(b.pop(), None);
        b.push(7, 1.0, 0);
        b.clear();
        assert!(b.is_empty() && b.pop().is_none());
    }

    #[test]
    fn angle_priority_and_integrated_priority() {
        assert_eq!(ang_pr(0.2, 0.5, 0.3), 1.0);
        assert!((ang_pr(0.8, 0.5, 0.3) - 0.5).abs() < 1e-6);
        assert!(ang_pr(1.5, 0.5, 0.3) < ang_pr(1.0, 0.5, 0.3));
        // Below ε the angle lowers the value (further from ε), above it raises it.
        assert_eq!(priority(4.0, 5.0, 0.5), 2.0);
        assert_eq!(priority(6.0, 5.0, 0.5), 12.0);
        assert_eq!(priority(6.0, 5.0, 1.0), 6.0);
    }
}
