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
//!   in the last frame's cut only sets both frames to `f`. Every resident
//!   node carries the last frame it was on the cut (the paper's queue);
//!   after the frame a node on the cut takes the current frame, and every
//!   other (what the paper's walk up to the current frame visits) stays if
//!   it passes rule (3) `(f_min = f ∧ l_n > l_min) ∨ (f_max = f ∧ l_n >
//!   l_max)` and is deleted otherwise.
//!
//! Within a frame the new arcs' tuple updates are applied before the old
//! arcs' (which then only touch the frames), so the result does not depend
//! on the order arcs are visited.

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

/// One node's state while resident.
#[derive(Clone, Copy, Debug)]
struct Slot {
    part: u32,
    layer: u32,
    /// The last frame it was on the cut (-1: not yet).
    last: i64,
    /// Index in `NodeCache::resident`.
    at: u32,
}

/// A partition's state while partly in core.
#[derive(Clone, Copy, Debug)]
struct Part {
    in_core: u32,
    tmin: Tuple,
    tmax: Tuple,
    /// The frame a node of it was last seen on the cut (for P,CC).
    on_cut: i64,
}

/// The caching policy's state: resident nodes, their layers and
/// partitions, when each was last on the cut, and the tuples. Dense
/// tables by node and partition id; the resident nodes also as a list, so
/// that the end of a frame visits only them. The paper's queue by last
/// frame on the cut is [`NodeCache::oldest`]: the walk it describes visits
/// every resident node off the cut (those kept by rule (3) stay at its
/// front), which the list does without keeping the queue sorted.
#[derive(Clone, Debug)]
pub struct NodeCache {
    pub mode: CacheMode,
    nodes: Vec<Option<Slot>>,
    resident: Vec<u32>,
    parts: Vec<Option<Part>>,
}

impl NodeCache {
    pub fn new(mode: CacheMode) -> Self {
        Self {
            mode,
            nodes: Vec::new(),
            resident: Vec::new(),
            parts: Vec::new(),
        }
    }

    fn slot(&self, n: u32) -> Option<&Slot> {
        self.nodes.get(n as usize).and_then(Option::as_ref)
    }

    fn part_mut(&mut self, p: u32) -> &mut Option<Part> {
        if self.parts.len() <= p as usize {
            self.parts.resize(p as usize + 1, None);
        }
        &mut self.parts[p as usize]
    }

    pub fn is_resident(&self, n: u32) -> bool {
        self.slot(n).is_some()
    }

    /// The tuples of partition `p` (while it is partly in core).
    pub fn tuples(&self, p: u32) -> Option<(Tuple, Tuple)> {
        let q = self.parts.get(p as usize)?.as_ref()?;
        Some((q.tmin, q.tmax))
    }

    /// Partition `p` was read: its tuples start over at `(-1, -1)`.
    pub fn partition_read(&mut self, p: u32) {
        let q = self.part_mut(p).get_or_insert(Part {
            in_core: 0,
            tmin: (-1, -1),
            tmax: (-1, -1),
            on_cut: -1,
        });
        q.tmin = (-1, -1);
        q.tmax = (-1, -1);
    }

    /// Node `n` (of partition `p`, layer `l`) came into core, not yet on a
    /// cut. A node already resident is left as it is.
    pub fn loaded(&mut self, n: u32, p: u32, l: u32) {
        if self.is_resident(n) {
            return;
        }
        if self.nodes.len() <= n as usize {
            self.nodes.resize(n as usize + 1, None);
        }
        self.nodes[n as usize] = Some(Slot {
            part: p,
            layer: l,
            last: -1,
            at: self.resident.len() as u32,
        });
        self.resident.push(n);
        self.part_mut(p)
            .get_or_insert(Part {
                in_core: 0,
                tmin: (-1, -1),
                tmax: (-1, -1),
                on_cut: -1,
            })
            .in_core += 1;
    }

    /// Removes node `n` from core (its partition's tuples go with the last
    /// one).
    pub fn remove(&mut self, n: u32) {
        let Some(s) = self.nodes.get_mut(n as usize).and_then(Option::take) else {
            return;
        };
        self.resident.swap_remove(s.at as usize);
        if let Some(&moved) = self.resident.get(s.at as usize) {
            self.nodes[moved as usize].as_mut().expect("resident").at = s.at;
        }
        let q = self.parts[s.part as usize].as_mut().expect("counted");
        q.in_core -= 1;
        if q.in_core == 0 {
            self.parts[s.part as usize] = None;
        }
    }

    /// The resident nodes, least recently on the cut first (then by id):
    /// the order evictions take under memory pressure.
    pub fn oldest(&self) -> Vec<u32> {
        let mut v: Vec<(i64, u32)> = self
            .resident
            .iter()
            .map(|&n| (self.slot(n).expect("resident").last, n))
            .collect();
        v.sort_unstable();
        v.into_iter().map(|(_, n)| n).collect()
    }

    /// Applies rules (1) and (2) for one endpoint of a new cut arc.
    fn touch_new(&mut self, n: u32, f: i64, mark: Mark) {
        let Some(&Slot { part, layer, .. }) = self.slot(n) else {
            return;
        };
        let q = self.parts[part as usize]
            .as_mut()
            .expect("resident partition");
        let t = match mark {
            Mark::TopDown => &mut q.tmin,
            Mark::BottomUp => &mut q.tmax,
            Mark::Old => return,
        };
        let l = i64::from(layer);
        *t = if t.0 == f { (f, t.1.min(l)) } else { (f, l) };
    }

    fn touch_old(&mut self, n: u32, f: i64) {
        let Some(&Slot { part, .. }) = self.slot(n) else {
            return;
        };
        let q = self.parts[part as usize]
            .as_mut()
            .expect("resident partition");
        q.tmin.0 = f;
        q.tmax.0 = f;
    }

    /// Ends frame `f`: `arcs` are the cut's arcs as (father, child or
    /// `None` for the drain, mark); `part_of` gives any node's partition.
    /// Nodes on the cut (an end of a cut arc) are marked as on it in frame
    /// `f`; every other resident node is kept or deleted by the mode's
    /// rule. Returns the nodes deleted (already removed here), ascending.
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
        for &(h, c, _) in arcs {
            for n in std::iter::once(h).chain(c) {
                if let Some(Some(s)) = self.nodes.get_mut(n as usize) {
                    s.last = f;
                }
                if self.mode == CacheMode::PCc
                    && let Some(Some(q)) = self.parts.get_mut(part_of(n) as usize)
                {
                    q.on_cut = f;
                }
            }
        }
        let mut gone: Vec<u32> = Vec::new();
        for &n in &self.resident {
            let s = self.slot(n).expect("resident");
            if s.last == f {
                continue;
            }
            let keep = match self.mode {
                CacheMode::NpNc | CacheMode::PNc => false,
                CacheMode::PCc => self.parts[s.part as usize].expect("resident").on_cut == f,
                CacheMode::PC => self.rule3(s.part, s.layer, f),
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
        let (tn, tx) = self
            .tuples(p)
            .expect("a resident node's partition has tuples");
        (tn.0 == f && l > tn.1) || (tx.0 == f && l > tx.1)
    }
}

/// The MT node cache as an [`Eviction`](crate::evict::Eviction) policy
/// under memory pressure: the node longest off the cut goes first. Use is
/// being on the cut, which [`NodeCache::end_frame`] records for a whole
/// frame; a read node is told its partition and layer.
impl crate::evict::Eviction for NodeCache {
    type Key = u32;
    /// The node's partition and layer.
    type Hint = (u32, u32);

    fn insert(&mut self, n: u32, (p, l): (u32, u32)) {
        self.loaded(n, p, l);
    }

    /// Nothing: a node's recency is the last frame it was on the cut.
    fn access(&mut self, _n: u32, _hint: (u32, u32)) {}

    fn remove(&mut self, n: u32) {
        NodeCache::remove(self, n);
    }

    fn victims(&self) -> Box<dyn Iterator<Item = crate::evict::Victim<u32>> + '_> {
        Box::new(
            self.oldest()
                .into_iter()
                .map(|key| crate::evict::Victim { key, recent: false }),
        )
    }

    fn contains(&self, n: u32) -> bool {
        self.is_resident(n)
    }

    fn len(&self) -> usize {
        self.resident.len()
    }
}

#[cfg(test)]
mod tests;
