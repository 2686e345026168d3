//! Resident MT nodes under a byte budget: misses read a node or its whole
//! partition through a [`ByteSource`] (so through the engine's disk
//! models), the [`NodeCache`] decides what stays after each frame, and a
//! node or partition failing its checksum is never read again (its region
//! keeps the level it has).

use std::sync::Arc;

use super::cache::{CacheMode, Mark, NodeCache};
use super::file::{MtFile, MtFileError, NodeData};
use crate::evict::Eviction;

/// Bytes a node of a `len`-byte record holds in core: the record and, at
/// most as much again, its arc and tuple tables (known before it is read,
/// so the budget is checked before every read).
pub fn node_bytes(len: u32) -> u64 {
    2 * u64::from(len) + 64
}

/// Bytes per node of the store's, the cache's and the cut's own tables
/// (resident pointer, pin count, checksum flag; cache slot; refined flag),
/// counted with the file's in-core part.
pub const TABLE_BYTES_PER_NODE: u64 = 48;

/// Counters since the store started.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MtStats {
    /// Read operations (one per node, or one per partition).
    pub reads: u64,
    pub bytes_read: u64,
    pub nodes_read: u64,
    pub partitions_read: u64,
    /// Nodes wanted but not read because the budget had no room.
    pub refused: u64,
    /// Nodes that failed their checksum or did not decode.
    pub corrupt: u64,
    pub io_errors: u64,
}

/// Why a store cannot start.
#[derive(Debug, thiserror::Error)]
pub enum MtStoreError {
    #[error(
        "footprint {budget} B is below what the MT needs to start ({need} B: its directory and root node)"
    )]
    Budget { budget: u64, need: u64 },
    #[error("the root node cannot be read: {0}")]
    Root(MtFileError),
}

/// The resident nodes of one MT.
pub struct MtStore {
    pub file: Arc<MtFile>,
    pub cache: NodeCache,
    pub budget: u64,
    /// By node id.
    resident: Vec<Option<Arc<NodeData>>>,
    count: usize,
    bytes: u64,
    peak: u64,
    /// Pin count by node id.
    pins: Vec<u32>,
    bad: Vec<bool>,
    /// The smallest read refused for want of room since the last unpin or
    /// removal: a read at least as large is refused at once.
    refused_at: Option<u64>,
    /// The eviction order ([`NodeCache::oldest`]) as of the first eviction
    /// of the frame (last frames on the cut change only at its end), and
    /// the nodes read since, which come first (never yet on a cut).
    evict_order: Option<Vec<u32>>,
    fresh: Vec<u32>,
    pub stats: MtStats,
}

impl MtStore {
    /// A store of `budget` bytes (the in-core part included); fails when
    /// that cannot hold the in-core part and the root.
    pub fn new(file: Arc<MtFile>, mode: CacheMode, budget: u64) -> Result<Self, MtStoreError> {
        let need = file.core_bytes()
            + TABLE_BYTES_PER_NODE * file.dir.len() as u64
            + node_bytes(file.dir[0].len);
        if budget < need {
            return Err(MtStoreError::Budget { budget, need });
        }
        let n = file.dir.len();
        let peak = file.core_bytes() + TABLE_BYTES_PER_NODE * n as u64;
        Ok(Self {
            file,
            cache: NodeCache::new(mode),
            budget,
            resident: vec![None; n],
            count: 0,
            bytes: 0,
            peak,
            pins: vec![0; n],
            bad: vec![false; n],
            refused_at: None,
            evict_order: None,
            fresh: Vec::new(),
            stats: MtStats::default(),
        })
    }

    /// In-core part, tables and resident nodes.
    pub fn resident_bytes(&self) -> u64 {
        self.file.core_bytes() + TABLE_BYTES_PER_NODE * self.resident.len() as u64 + self.bytes
    }

    /// The largest [`MtStore::resident_bytes`] since the last call.
    pub fn take_peak(&mut self) -> u64 {
        let now = self.resident_bytes();
        std::mem::replace(&mut self.peak, now)
    }

    pub fn resident_nodes(&self) -> usize {
        self.count
    }

    /// A resident node, without reading.
    pub fn peek(&self, id: u32) -> Option<&Arc<NodeData>> {
        self.resident.get(id as usize)?.as_ref()
    }

    /// Node `id`, read (with its partition, unless NP,NC) on a miss;
    /// `None` when it is corrupt, the read failed or the budget has no
    /// room for it.
    pub fn get(&mut self, id: u32) -> Result<Arc<NodeData>, Miss> {
        if let Some(n) = self.peek(id) {
            return Ok(n.clone());
        }
        if self.bad[id as usize] {
            return Err(Miss::Corrupt);
        }
        self.read(id)?;
        self.peek(id).cloned().ok_or(Miss::Corrupt)
    }

    /// The father or child of an arc entered the cut.
    pub fn pin(&mut self, id: u32) {
        self.pins[id as usize] += 1;
    }

    pub fn unpin(&mut self, id: u32) {
        let c = &mut self.pins[id as usize];
        if *c > 0 {
            *c -= 1;
            if *c == 0 {
                self.refused_at = None;
            }
        }
    }

    fn read(&mut self, id: u32) -> Result<(), Miss> {
        let f = self.file.clone();
        let p = f.part_of[id as usize];
        let pd = f.parts[p as usize];
        let (first, end) = (pd.first, pd.first + pd.count);
        let need = |a: u32, b: u32, s: &Self| -> u64 {
            (a..b)
                .filter(|&n| s.peek(n).is_none() && !s.bad[n as usize])
                .map(|n| node_bytes(f.dir[n as usize].len))
                .sum()
        };
        let whole =
            self.cache.mode.partitions() && self.make_room(need(first, end, self), first..end);
        let (a, b) = if whole {
            (first, end)
        } else if self.make_room(need(id, id + 1, self), id..id + 1) {
            (id, id + 1)
        } else {
            self.stats.refused += 1;
            return Err(Miss::Budget);
        };
        let got = match f.read_nodes(a, b) {
            Ok(g) => g,
            Err(e) => {
                self.stats.io_errors += 1;
                tracing::warn!("MT nodes {a}..{b}: {e}");
                return Err(Miss::Io);
            }
        };
        self.stats.reads += 1;
        let d = (&f.dir[a as usize], &f.dir[b as usize - 1]);
        self.stats.bytes_read += d.1.offset + u64::from(d.1.len) - d.0.offset;
        if whole {
            self.stats.partitions_read += 1;
            self.cache.partition_read(p);
        }
        for (n, r) in (a..b).zip(got) {
            self.stats.nodes_read += 1;
            match r {
                Ok(nd) if self.peek(n).is_none() && !self.bad[n as usize] => {
                    self.bytes += node_bytes(f.dir[n as usize].len);
                    Eviction::insert(&mut self.cache, n, (p, nd.head.layer));
                    self.resident[n as usize] = Some(Arc::new(nd));
                    self.count += 1;
                    if self.evict_order.is_some() {
                        self.fresh.push(n);
                    }
                }
                Ok(_) => {}
                Err(e) => {
                    if !std::mem::replace(&mut self.bad[n as usize], true) {
                        self.stats.corrupt += 1;
                        tracing::warn!("MT node {n}: {e}; its region keeps the level it has");
                    }
                }
            }
        }
        self.peak = self.peak.max(self.resident_bytes());
        debug_assert!(self.resident_bytes() <= self.budget);
        Ok(())
    }

    /// Evicts nodes off the cut and outside `keep` (the nodes about to be
    /// read), least recently used first, until `need` more bytes fit;
    /// `false` (nothing evicted) when they cannot.
    fn make_room(&mut self, need: u64, keep: std::ops::Range<u32>) -> bool {
        if self.resident_bytes() + need <= self.budget {
            return true;
        }
        if self.refused_at.is_some_and(|r| need >= r) {
            return false;
        }
        let cache = &self.cache;
        let sorted = self
            .evict_order
            .get_or_insert_with(|| cache.victims().map(|v| v.key).collect());
        let order: Vec<u32> = self
            .fresh
            .iter()
            .chain(sorted.iter())
            .copied()
            .filter(|&n| {
                self.resident[n as usize].is_some()
                    && self.pins[n as usize] == 0
                    && !keep.contains(&n)
            })
            .collect();
        let free: u64 = order
            .iter()
            .map(|&n| node_bytes(self.file.dir[n as usize].len))
            .sum();
        if self.resident_bytes().saturating_sub(free) + need > self.budget {
            self.refused_at = Some(self.refused_at.map_or(need, |r| r.min(need)));
            return false;
        }
        for n in order {
            if self.resident_bytes() + need <= self.budget {
                break;
            }
            self.drop_node(n);
        }
        // The order may name a node twice (read again after an eviction):
        // the bytes decide.
        self.resident_bytes() + need <= self.budget
    }

    fn drop_node(&mut self, n: u32) {
        if self.resident[n as usize].take().is_some() {
            self.bytes -= node_bytes(self.file.dir[n as usize].len);
            self.count -= 1;
            Eviction::remove(&mut self.cache, n);
        }
    }

    /// Ends frame `f` with the cut's arcs: the cache policy deletes what
    /// it does not keep.
    pub fn end_frame(&mut self, f: i64, arcs: &[(u32, Option<u32>, Mark)]) {
        self.refused_at = None;
        self.evict_order = None;
        self.fresh.clear();
        let file = self.file.clone();
        let part_of = |n: u32| file.part_of[n as usize];
        for n in self.cache.end_frame(f, arcs, &part_of) {
            if self.resident[n as usize].take().is_some() {
                self.bytes -= node_bytes(self.file.dir[n as usize].len);
                self.count -= 1;
            }
        }
    }
}

/// Why a node is not in core.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Miss {
    Budget,
    Corrupt,
    Io,
}

impl std::fmt::Debug for MtStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MtStore")
            .field("mode", &self.cache.mode)
            .field("budget", &self.budget)
            .field("resident", &self.count)
            .field("bytes", &self.bytes)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}
