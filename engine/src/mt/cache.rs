//! Node caching (Holst & Schumann §4.3) and the paper's three baselines,
//! as one policy over resident nodes; plain Rust, told the frame number.
//!
//! - [`CacheMode::NpNc`]: nodes read one at a time, deleted after the
//!   frame unless on the cut (the father or child of a cut arc);
//! - [`CacheMode::PNc`]: partitions read whole, nodes deleted as in NP,NC;
//! - [`CacheMode::PCc`]: a node is deleted only when no node of its
//!   partition is on the cut;
//! - [`CacheMode::PC`]: the paper's caching. Every partition partly in core
//!   has two tuples `T_min = (f_min, l_min)` and `T_max = (f_max, l_max)`,
//!   `(-1, -1)` after it is read. A cut arc found by a top-down step sets
//!   `T_min` of its father's and its child's partition by rule (1), one
//!   found by a bottom-up step sets `T_max` by rule (2), and an arc already
//!   in the last frame's cut only sets both frames to `f`. Resident nodes
//!   sit in a queue by the last frame they were on the cut; after the
//!   frame the queue is walked from the oldest up to the current frame: a
//!   node on the cut moves to the current frame, one that passes rule (3)
//!   `(f_min = f ∧ l_n > l_min) ∨ (f_max = f ∧ l_n > l_max)` stays, any
//!   other is deleted.
//!
//! Within a frame the new arcs' tuple updates are applied before the old
//! arcs' (which then only touch the frames), so the result does not depend
//! on the order arcs are visited.

use std::collections::{BTreeMap, BTreeSet};

/// Which nodes stay in core after a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CacheMode {
    NpNc,
    PNc,
    PCc,
    PC,
}

impl CacheMode {
    pub const ALL: [CacheMode; 4] = [Self::NpNc, Self::PNc, Self::PCc, Self::PC];

    /// Whether a miss reads the node's whole partition.
    pub fn partitions(self) -> bool {
        self != Self::NpNc
    }

    /// The paper's label.
    pub fn label(self) -> &'static str {
        match self {
            Self::NpNc => "NP,NC",
            Self::PNc => "P,NC",
            Self::PCc => "P,CC",
            Self::PC => "P,C",
        }
    }

    /// The command-line and CSV name: `np-nc`, `p-nc`, `p-cc`, `p-c`.
    pub fn name(self) -> &'static str {
        match self {
            Self::NpNc => "np-nc",
            Self::PNc => "p-nc",
            Self::PCc => "p-cc",
            Self::PC => "p-c",
        }
    }

    /// Parses a [`CacheMode::name`] (or a label).
    pub fn parse(s: &str) -> Option<Self> {
        let k = s.to_ascii_lowercase().replace([',', '_'], "-");
        Self::ALL.into_iter().find(|m| m.name() == k)
    }
}

/// How an arc of the current cut got there.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mark {
    /// In the last frame's cut too.
    Old,
    /// Added by refining its child's father (a top-down step).
    TopDown,
    /// Added by coarsening its father's child (a bottom-up step).
    BottomUp,
}

/// A frame and layer; `(-1, -1)` until set.
pub type Tuple = (i64, i64);

/// The caching policy's state: resident nodes, their layers and
/// partitions, the queue and the tuples.
#[derive(Clone, Debug)]
pub struct NodeCache {
    pub mode: CacheMode,
    /// Resident node → (partition, layer, last frame on the cut).
    nodes: BTreeMap<u32, (u32, u32, i64)>,
    queue: BTreeSet<(i64, u32)>,
    /// Resident nodes per partition.
    in_core: BTreeMap<u32, u32>,
    tmin: BTreeMap<u32, Tuple>,
    tmax: BTreeMap<u32, Tuple>,
}

impl NodeCache {
    pub fn new(mode: CacheMode) -> Self {
        Self {
            mode,
            nodes: BTreeMap::new(),
            queue: BTreeSet::new(),
            in_core: BTreeMap::new(),
            tmin: BTreeMap::new(),
            tmax: BTreeMap::new(),
        }
    }

    pub fn is_resident(&self, n: u32) -> bool {
        self.nodes.contains_key(&n)
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The tuples of partition `p` (while it is partly in core).
    pub fn tuples(&self, p: u32) -> Option<(Tuple, Tuple)> {
        Some((*self.tmin.get(&p)?, *self.tmax.get(&p)?))
    }

    /// Partition `p` was read: its tuples start over at `(-1, -1)`.
    pub fn partition_read(&mut self, p: u32) {
        self.tmin.insert(p, (-1, -1));
        self.tmax.insert(p, (-1, -1));
    }

    /// Node `n` (of partition `p`, layer `l`) came into core; it enters the
    /// queue at frame -1. A node already resident is left as it is.
    pub fn loaded(&mut self, n: u32, p: u32, l: u32) {
        if self.nodes.contains_key(&n) {
            return;
        }
        self.nodes.insert(n, (p, l, -1));
        self.queue.insert((-1, n));
        *self.in_core.entry(p).or_default() += 1;
        self.tmin.entry(p).or_insert((-1, -1));
        self.tmax.entry(p).or_insert((-1, -1));
    }

    /// Removes node `n` from core (its partition's tuples go with the last
    /// one).
    pub fn remove(&mut self, n: u32) {
        let Some((p, _, last)) = self.nodes.remove(&n) else {
            return;
        };
        self.queue.remove(&(last, n));
        let c = self.in_core.get_mut(&p).expect("counted");
        *c -= 1;
        if *c == 0 {
            self.in_core.remove(&p);
            self.tmin.remove(&p);
            self.tmax.remove(&p);
        }
    }

    /// The resident nodes, least recently on the cut first (candidates for
    /// eviction under memory pressure).
    pub fn oldest(&self) -> impl Iterator<Item = u32> + '_ {
        self.queue.iter().map(|&(_, n)| n)
    }

    /// Applies rules (1) and (2) for one endpoint of a new cut arc.
    fn touch_new(&mut self, n: u32, f: i64, mark: Mark) {
        let Some(&(p, l, _)) = self.nodes.get(&n) else {
            return;
        };
        let t = match mark {
            Mark::TopDown => self.tmin.get_mut(&p),
            Mark::BottomUp => self.tmax.get_mut(&p),
            Mark::Old => return,
        };
        let t = t.expect("resident partitions have tuples");
        let l = i64::from(l);
        *t = if t.0 == f { (f, t.1.min(l)) } else { (f, l) };
    }

    fn touch_old(&mut self, n: u32, f: i64) {
        let Some(&(p, _, _)) = self.nodes.get(&n) else {
            return;
        };
        for t in [self.tmin.get_mut(&p), self.tmax.get_mut(&p)]
            .into_iter()
            .flatten()
        {
            t.0 = f;
        }
    }

    /// Ends frame `f`: `arcs` are the cut's arcs as (father, child or
    /// `None` for the drain, mark); `part_of` gives any node's partition.
    /// Nodes on the cut (an end of a cut arc) move to frame `f`; the queue
    /// is then walked up to frame `f`, so only the nodes off the cut are
    /// visited. Returns the nodes to delete (already removed here),
    /// ascending.
    pub fn end_frame(
        &mut self,
        f: i64,
        arcs: &[(u32, Option<u32>, Mark)],
        part_of: &dyn Fn(u32) -> u32,
    ) -> Vec<u32> {
        for &(h, c, m) in arcs.iter().filter(|a| a.2 != Mark::Old) {
            self.touch_new(h, f, m);
            if let Some(c) = c {
                self.touch_new(c, f, m);
            }
        }
        for &(h, c, _) in arcs.iter().filter(|a| a.2 == Mark::Old) {
            self.touch_old(h, f);
            if let Some(c) = c {
                self.touch_old(c, f);
            }
        }
        let mut parts_on_cut = BTreeSet::new();
        for &(h, c, _) in arcs {
            for n in std::iter::once(h).chain(c) {
                if self.mode == CacheMode::PCc {
                    parts_on_cut.insert(part_of(n));
                }
                if let Some(e) = self.nodes.get_mut(&n)
                    && e.2 != f
                {
                    self.queue.remove(&(e.2, n));
                    e.2 = f;
                    self.queue.insert((f, n));
                }
            }
        }
        let stale: Vec<u32> = self.queue.range(..(f, 0)).map(|&(_, n)| n).collect();
        let mut gone = Vec::new();
        for n in stale {
            let (p, l, _) = self.nodes[&n];
            let keep = match self.mode {
                CacheMode::NpNc | CacheMode::PNc => false,
                CacheMode::PCc => parts_on_cut.contains(&p),
                CacheMode::PC => self.rule3(p, l, f),
            };
            if !keep {
                gone.push(n);
            }
        }
        for &n in &gone {
            self.remove(n);
        }
        gone.sort_unstable();
        gone
    }

    /// Rule (3) for a node of partition `p` at layer `l` in frame `f`.
    pub fn rule3(&self, p: u32, l: u32, f: i64) -> bool {
        let l = i64::from(l);
        let (tn, tx) = (self.tmin[&p], self.tmax[&p]);
        (tn.0 == f && l > tn.1) || (tx.0 == f && l > tx.1)
    }
}

#[cfg(test)]
mod tests;
