//! The external-memory store (El-Sana & Chiang §3.3.2–§3.3.4).
//!
//! *Navigate* (the thread that refines, owner of this struct) keeps the
//! [`BufferManager`] and is the only one to change usage counts; the *I/O*
//! thread only reads and decodes meta-nodes into the holders it is told to
//! fill, so the paper's locks become two bounded channels (urgent reads
//! first). A holder's bytes are reserved when its read is issued, so the
//! resident bytes — the in-core MNT and permanent triangles plus the
//! holders — never exceed the footprint.
//!
//! When a meta-node gets its first active node it references its parent and
//! (the paper's rule, [`Prefetch::AllChildren`]) its child meta-nodes,
//! prefetching them; when it loses its last one it drops those references.
//! By default ([`Prefetch::BelowCut`]) only the child meta-nodes right below
//! active nodes are referenced. A split or collapse whose meta-node is missing is a
//! miss and asks for it urgently. A meta-node that fails its checksum is
//! never asked for again: that part of the tree stays at the level it has.

use std::collections::{HashMap, HashSet};
use std::sync::Arc;

use crossbeam_channel::{Receiver, Sender, TryRecvError};
use glam::Vec3;

use super::buffer::{BufferManager, Request, Urgency};
use super::file::{VdtError, VdtFile};
use super::meta::DecodedMeta;
use super::refine::{NodeStore, Placed, TriList};
use super::{NONE, VdNode};

/// A decoded meta-node in a holder.
#[derive(Debug)]
struct Resident {
    meta: u32,
    nodes: Vec<(u32, VdNode)>,
    /// Adjacent triangles per node (ranges into `tris`).
    adj: Vec<std::ops::Range<usize>>,
    tris: Vec<(u32, [u32; 3])>,
    /// Sorted `(leaf, position)`.
    leaves: Vec<(u32, Vec3)>,
    /// Child meta-nodes of the bottom nodes' children.
    child_meta: HashMap<u32, u32>,
}

type Loaded = (u32, u32, Result<DecodedMeta, VdtError>);

/// Which meta-nodes an active one keeps prefetched.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Prefetch {
    /// The paper's rule: the parent and every child meta-node of each
    /// active meta-node.
    AllChildren,
    /// The parent of each active meta-node, and only the child meta-nodes
    /// right below active nodes (where the next split would go): collapse
    /// trees are chain-like, so a meta-node has up to `2^(L-1)` small
    /// children and most are far from the cut.
    #[default]
    BelowCut,
}

/// Counters of the store (cumulative).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExtStats {
    pub loads: u64,
    pub bytes_read: u64,
    pub second_chances: u64,
    pub give_ups: u64,
    pub urgent: u64,
    pub failed: u64,
    pub requested_bytes: u64,
}

/// Meta-node trees read on demand into `K` place holders.
#[derive(Debug)]
pub struct ExtStore {
    file: Arc<VdtFile>,
    buf: BufferManager,
    residents: Vec<Option<Resident>>,
    /// Node id → (holder, index) for every meta-node in physical memory.
    node_at: HashMap<u32, (u32, u32)>,
    bad: HashSet<u32>,
    urgent_tx: Sender<(u32, u32)>,
    prefetch_tx: Sender<(u32, u32)>,
    done_rx: Receiver<Loaded>,
    policy: Prefetch,
    pub stats: ExtStats,
}

impl ExtStore {
    /// Holder bytes that fit in `budget` after the in-core part; an error
    /// when the root meta-nodes and three of the largest do not fit.
    pub fn buffer_for(file: &VdtFile, budget: u64) -> Result<u64, VdtError> {
        let need = file.holder_need();
        let k = budget.saturating_sub(file.core_bytes());
        if k < need {
            return Err(VdtError::Corrupt(format!(
                "footprint of {budget} bytes too small: the in-core part takes {} and the root meta-nodes with room to move {need} more",
                file.core_bytes()
            )));
        }
        Ok(k)
    }

    /// Starts the I/O thread and loads the root meta-nodes (waiting for
    /// them: the coarsest level must be there to draw anything).
    pub fn start(file: Arc<VdtFile>, budget: u64) -> Result<Self, VdtError> {
        Self::with_policy(file, budget, Prefetch::default())
    }

    /// [`start`](Self::start) with a prefetch policy.
    pub fn with_policy(
        file: Arc<VdtFile>,
        budget: u64,
        policy: Prefetch,
    ) -> Result<Self, VdtError> {
        let bytes = Self::buffer_for(&file, budget)?;
        // Every outstanding read holds a holder of at least 16 bytes.
        let k = (bytes / 16).clamp(16, 1 << 20) as usize;
        let (urgent_tx, urgent_rx) = crossbeam_channel::bounded::<(u32, u32)>(k);
        let (prefetch_tx, prefetch_rx) = crossbeam_channel::bounded::<(u32, u32)>(k);
        let (done_tx, done_rx) = crossbeam_channel::bounded::<Loaded>(k);
        let f = file.clone();
        std::thread::Builder::new()
            .name("vdt-io".into())
            .spawn(move || io_thread(&f, &urgent_rx, &prefetch_rx, &done_tx))?;
        let mut s = Self {
            file,
            buf: BufferManager::new(bytes),
            residents: Vec::new(),
            node_at: HashMap::new(),
            bad: HashSet::new(),
            urgent_tx,
            prefetch_tx,
            done_rx,
            policy,
            stats: ExtStats::default(),
        };
        for m in 0..s.file.header.root_count {
            s.want(m, Urgency::Up);
        }
        // Loaded root meta-nodes wait on the free list (nothing uses them
        // yet) until `roots` takes them back.
        let loaded = |s: &Self, m: u32| {
            s.buf
                .find(m)
                .is_some_and(|h| s.buf.holder(h).content == super::buffer::Content::Ready)
        };
        while (0..s.file.header.root_count).any(|m| !loaded(&s, m)) {
            if let Some(m) = (0..s.file.header.root_count).find(|m| s.bad.contains(m)) {
                return Err(VdtError::Corrupt(format!("root meta-node {m} unreadable")));
            }
            let done = s.done_rx.recv().map_err(|_| io_gone())?;
            s.install(done)?;
        }
        Ok(s)
    }

    /// Resident bytes: the in-core part plus the holders' meta-nodes.
    pub fn resident_bytes(&self) -> u64 {
        self.file.core_bytes() + self.buf.used()
    }

    /// Takes in what the I/O thread finished (call once per frame).
    pub fn poll(&mut self) -> Result<(), VdtError> {
        loop {
            match self.done_rx.try_recv() {
                Ok(d) => self.install(d)?,
                Err(TryRecvError::Empty) => return Ok(()),
                Err(TryRecvError::Disconnected) => return Err(io_gone()),
            }
        }
    }

    /// Checks the buffer manager's bookkeeping.
    pub fn validate(&self) -> Result<(), String> {
        self.buf.validate()
    }

    fn install(&mut self, (meta, h, res): Loaded) -> Result<(), VdtError> {
        let ok = res.is_ok();
        if !self.buf.loaded(h, meta, ok) {
            return Ok(()); // the holder went to another meta-node meanwhile
        }
        match res {
            Err(e) => {
                tracing::warn!("meta-node {meta}: {e}; that part of the tree stays coarser");
                self.stats.failed += 1;
                self.bad.insert(meta);
            }
            Ok(d) => {
                let r = self.resident(meta, d)?;
                for (i, (id, nd)) in r.nodes.iter().enumerate() {
                    self.file.check_node(*id, nd)?;
                    self.node_at.insert(*id, (h, i as u32));
                }
                self.stats.loads += 1;
                self.stats.bytes_read += u64::from(self.file.mnt[meta as usize].len);
                if self.residents.len() <= h as usize {
                    self.residents.resize_with(h as usize + 1, || None);
                }
                self.residents[h as usize] = Some(r);
            }
        }
        Ok(())
    }

    fn resident(&self, meta: u32, d: DecodedMeta) -> Result<Resident, VdtError> {
        let rec = &self.file.mnt[meta as usize];
        let mut child_meta = HashMap::new();
        let mut adj = Vec::with_capacity(d.nodes.len());
        let mut at = 0usize;
        let kids = rec.first_child..rec.first_child.saturating_add(rec.child_count);
        for r in &d.nodes {
            let nd = r.node;
            if r.child_meta != NONE {
                if !kids.contains(&r.child_meta) || nd.left == NONE {
                    return Err(VdtError::Corrupt(format!("meta-node {meta}: child links")));
                }
                child_meta.insert(nd.left, r.child_meta);
                child_meta.insert(nd.right, r.child_meta);
            }
            let end = at + r.adjacent as usize;
            adj.push(at..end);
            at = end;
        }
        if at != d.triangles.len() {
            return Err(VdtError::Corrupt(format!(
                "meta-node {meta}: adjacency counts"
            )));
        }
        Ok(Resident {
            meta,
            nodes: d.nodes.iter().map(|r| (r.id, r.node)).collect(),
            adj,
            tris: d.triangles,
            leaves: d.leaves.iter().map(|&(l, p)| (l, Vec3::from(p))).collect(),
            child_meta,
        })
    }

    /// Asks for `meta`; issues the read if it got a holder.
    fn want(&mut self, meta: u32, urgency: Urgency) -> Request {
        if self.bad.contains(&meta) {
            return Request::GiveUp;
        }
        let bytes = self.file.mnt[meta as usize].len;
        let r = if urgency == Urgency::Prefetch {
            self.buf.ref_inc(meta, bytes)
        } else {
            self.buf.request(meta, bytes, urgency)
        };
        self.after(meta, &r, urgency != Urgency::Prefetch);
        r
    }

    fn after(&mut self, meta: u32, r: &Request, urgent: bool) {
        match *r {
            Request::Load {
                holder,
                ref evicted,
            } => {
                for &(_, h) in evicted {
                    self.evict(h);
                }
                let tx = if urgent {
                    self.stats.urgent += 1;
                    &self.urgent_tx
                } else {
                    &self.prefetch_tx
                };
                // At most K reads are outstanding (one per loading holder),
                // and each channel holds K: this never blocks.
                let _ = tx.send((meta, holder));
                self.stats.requested_bytes += u64::from(self.file.mnt[meta as usize].len);
            }
            Request::SecondChance(_) => self.stats.second_chances += 1,
            Request::GiveUp => self.stats.give_ups += 1,
            Request::Present(_) => {}
        }
    }

    fn evict(&mut self, h: u32) {
        if let Some(r) = self.residents.get_mut(h as usize).and_then(Option::take) {
            for (id, _) in &r.nodes {
                self.node_at.remove(id);
            }
        }
    }

    /// The record of node `id` if its meta-node is in physical memory (a
    /// flushed one too: it is only claimed back when a node in it becomes
    /// active).
    fn lookup(&self, id: u32) -> Option<(u32, u32)> {
        self.node_at.get(&id).copied()
    }

    fn position(&self, h: u32, leaf: u32) -> Option<Vec3> {
        let r = self.residents.get(h as usize).and_then(Option::as_ref)?;
        let k = r.leaves.binary_search_by_key(&leaf, |x| x.0).ok()?;
        Some(r.leaves[k].1)
    }

    fn meta_of(&self, h: u32) -> u32 {
        self.residents
            .get(h as usize)
            .and_then(Option::as_ref)
            .map_or(NONE, |r| r.meta)
    }

    /// The meta-node holding `child` of `v` (same or child meta-node).
    fn child_meta(&self, v: u32, child: u32) -> Option<u32> {
        let &(h, _) = self.node_at.get(&v)?;
        let r = self.residents.get(h as usize).and_then(Option::as_ref)?;
        Some(r.child_meta.get(&child).copied().unwrap_or(r.meta))
    }

    /// The meta-nodes node `i` of holder `h` references while active: when
    /// it is the first (or last) active node of its meta-node, the parent
    /// meta-node and, under the paper's rule, every child meta-node; under
    /// [`Prefetch::BelowCut`], the child meta-nodes holding its own children.
    fn references(&self, h: u32, i: u32, whole_meta: bool) -> Vec<u32> {
        let rec = &self.file.mnt[self.meta_of(h) as usize];
        let mut out = Vec::new();
        if whole_meta && rec.parent != NONE {
            out.push(rec.parent);
        }
        match self.policy {
            Prefetch::AllChildren if whole_meta => {
                out.extend(rec.first_child..rec.first_child.saturating_add(rec.child_count));
            }
            Prefetch::AllChildren => {}
            Prefetch::BelowCut => out.extend(self.below_cut(h, i)),
        }
        out
    }

    /// The child meta-nodes holding the children of node `i` of holder `h`
    /// (none when they are in the same meta-node, or it is a leaf).
    fn below_cut(&self, h: u32, i: u32) -> Vec<u32> {
        let Some(r) = self.residents.get(h as usize).and_then(Option::as_ref) else {
            return Vec::new();
        };
        let nd = r.nodes[i as usize].1;
        [nd.left, nd.right]
            .iter()
            .filter_map(|c| r.child_meta.get(c).copied())
            .collect()
    }
}

impl NodeStore for ExtStore {
    fn roots(&mut self) -> Result<Vec<Placed>, VdtError> {
        let mut out = Vec::new();
        for m in 0..self.file.header.root_count {
            self.want(m, Urgency::Up);
            let h = self
                .buf
                .ready(m)
                .ok_or_else(|| VdtError::Corrupt(format!("root meta-node {m} unreadable")))?;
            let r = self.residents[h as usize].as_ref().expect("ready holder");
            for &(id, node) in r.nodes.iter().filter(|x| x.1.parent == NONE) {
                let pos = self
                    .position(h, node.leaf)
                    .ok_or_else(|| VdtError::Corrupt(format!("root {id}: no position")))?;
                out.push(Placed { id, node, pos });
            }
        }
        Ok(out)
    }

    fn permanent(&mut self) -> Result<TriList, VdtError> {
        Ok(self.file.permanent.clone())
    }

    fn children(&mut self, v: &Placed) -> Result<Option<[Placed; 2]>, VdtError> {
        let mut out = [*v; 2];
        for (k, c) in [v.node.left, v.node.right].into_iter().enumerate() {
            let Some((h, i)) = self.lookup(c) else {
                if let Some(m) = self.child_meta(v.id, c) {
                    self.want(m, Urgency::Down);
                }
                return Ok(None);
            };
            let node = self
                .residents
                .get(h as usize)
                .and_then(Option::as_ref)
                .expect("resident")
                .nodes[i as usize]
                .1;
            let pos = if k == 0 {
                v.pos
            } else {
                match self.position(h, node.leaf) {
                    Some(p) => p,
                    None => return Err(VdtError::Corrupt(format!("node {c}: no position"))),
                }
            };
            out[k] = Placed { id: c, node, pos };
        }
        Ok(Some(out))
    }

    fn parent(&mut self, v: &Placed) -> Result<Option<(u32, VdNode)>, VdtError> {
        let p = v.node.parent;
        if let Some((h, i)) = self.lookup(p) {
            return Ok(Some((
                p,
                self.residents
                    .get(h as usize)
                    .and_then(Option::as_ref)
                    .expect("resident")
                    .nodes[i as usize]
                    .1,
            )));
        }
        // v is the top of its meta-node: the parent is in the parent meta-node.
        if let Some(&(h, _)) = self.node_at.get(&v.id) {
            let pm = self.file.mnt[self.meta_of(h) as usize].parent;
            if pm != NONE {
                self.want(pm, Urgency::Up);
            }
        }
        Ok(None)
    }

    fn adjacent(&mut self, v: u32) -> Result<Option<TriList>, VdtError> {
        let Some((h, i)) = self.lookup(v) else {
            return Ok(None);
        };
        let r = self
            .residents
            .get(h as usize)
            .and_then(Option::as_ref)
            .expect("resident");
        Ok(Some(r.tris[r.adj[i as usize].clone()].to_vec()))
    }

    fn activated(&mut self, v: u32) {
        let Some((h, i)) = self.lookup(v) else {
            return;
        };
        let meta = self.meta_of(h);
        if !self.buf.in_real(meta) {
            // Second chance: found in its holder, taken off the free list.
            self.want(meta, Urgency::Up);
        }
        let first = self.buf.holder(h).usage == 0;
        self.buf.use_inc(h);
        for m in self.references(h, i, first) {
            self.want(m, Urgency::Prefetch);
        }
    }

    fn deactivated(&mut self, v: u32) {
        let Some(&(h, i)) = self.node_at.get(&v) else {
            return;
        };
        // Counted before the use drops: the holder's links stay readable.
        let last = self.buf.holder(h).usage == 1;
        let refs = self.references(h, i, last);
        self.buf.use_dec(h);
        for m in refs {
            self.buf.ref_dec(m);
        }
    }
}

fn io_gone() -> VdtError {
    VdtError::Io(std::io::Error::other("the meta-node I/O thread stopped"))
}

/// Reads meta-nodes: every urgent read first, then the pending prefetches
/// in elevator order (the next one at or after where the head stopped, so
/// a meta-node's children — contiguous in DATA — come without seeks).
fn io_thread(
    file: &VdtFile,
    urgent: &Receiver<(u32, u32)>,
    prefetch: &Receiver<(u32, u32)>,
    done: &Sender<Loaded>,
) {
    let mut pending: Vec<(u32, u32)> = Vec::new();
    let mut head = 0u64;
    let offset = |j: &(u32, u32)| file.mnt[j.0 as usize].offset;
    loop {
        let job = if let Ok(j) = urgent.try_recv() {
            j
        } else {
            pending.extend(prefetch.try_iter());
            if pending.is_empty() {
                crossbeam_channel::select! {
                    recv(urgent) -> j => match j { Ok(j) => j, Err(_) => return },
                    recv(prefetch) -> j => match j { Ok(j) => j, Err(_) => return },
                }
            } else {
                let k = (0..pending.len())
                    .filter(|&k| offset(&pending[k]) >= head)
                    .min_by_key(|&k| offset(&pending[k]))
                    .or_else(|| (0..pending.len()).min_by_key(|&k| offset(&pending[k])))
                    .expect("pending is not empty");
                pending.swap_remove(k)
            }
        };
        let res = file.read_meta(job.0);
        head = offset(&job) + u64::from(file.mnt[job.0 as usize].len);
        if done.send((job.0, job.1, res)).is_err() {
            return;
        }
    }
}
