//! The virtual-memory baseline (*Virt.* in El-Sana & Chiang's Table 2):
//! the same refinement over the flat tree of the `.vdt` file, demand-paged
//! in 4 KiB pages with LRU replacement under the same byte budget. Every
//! fault is a synchronous read through the same disk model, on the
//! refining thread — the honest stand-in for the OS paging the paper used
//! (which also never misses: it waits).

use std::sync::Arc;

use crate::evict::lru::LruMap;
use glam::Vec3;

use super::file::{NODE_ENTRY, TRI_ENTRY, VdtError, VdtFile};
use super::refine::{NodeStore, Placed, TriList};
use super::{NONE, VdNode};

/// Page size of the baseline.
pub const PAGE: u64 = 4096;

/// Counters of the pager (cumulative).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PagerStats {
    pub faults: u64,
    pub bytes_read: u64,
    pub hits: u64,
}

/// Demand paging with LRU replacement.
#[derive(Debug)]
pub struct Pager {
    file: Arc<VdtFile>,
    pages: LruMap<u64, Box<[u8]>>,
    capacity: usize,
    pub stats: PagerStats,
}

impl Pager {
    pub fn new(file: Arc<VdtFile>, capacity: usize) -> Self {
        Self {
            file,
            pages: LruMap::default(),
            capacity: capacity.max(1),
            stats: PagerStats::default(),
        }
    }

    /// Copies `buf.len()` bytes at `offset`, faulting pages in as needed.
    pub fn read(&mut self, offset: u64, buf: &mut [u8]) -> Result<(), VdtError> {
        let len = self.file.source.len();
        let mut done = 0usize;
        while done < buf.len() {
            let at = offset + done as u64;
            let page = at / PAGE;
            if !self.pages.contains(page) {
                if self.pages.len() >= self.capacity {
                    self.pages.pop_victim();
                }
                let start = page * PAGE;
                let n = PAGE.min(len.saturating_sub(start)) as usize;
                if n == 0 {
                    return Err(VdtError::Corrupt(format!("read past the end at {at}")));
                }
                let mut p = vec![0u8; n].into_boxed_slice();
                self.file.source.read_at(start, &mut p)?;
                self.stats.faults += 1;
                self.stats.bytes_read += n as u64;
                self.pages.put(page, p);
            } else {
                self.stats.hits += 1;
            }
            let p = self.pages.get(page).expect("page just made resident");
            let within = (at - page * PAGE) as usize;
            let k = (p.len() - within).min(buf.len() - done);
            if k == 0 {
                return Err(VdtError::Corrupt(format!("read past the end at {at}")));
            }
            buf[done..done + k].copy_from_slice(&p[within..within + k]);
            done += k;
        }
        Ok(())
    }

    /// Resident bytes (pages held).
    pub fn resident_bytes(&self) -> u64 {
        self.pages.values().map(|(_, p)| p.len() as u64).sum()
    }
}

/// The flat tree behind a [`Pager`].
#[derive(Debug)]
pub struct VirtStore {
    file: Arc<VdtFile>,
    pub pager: Pager,
    parts: [u64; 5],
}

impl VirtStore {
    /// Pages that fit in `budget` after the in-core part of the file.
    pub fn start(file: Arc<VdtFile>, budget: u64) -> Result<Self, VdtError> {
        let pages = budget.saturating_sub(file.core_bytes()) / PAGE;
        if pages < 4 {
            return Err(VdtError::Corrupt(format!(
                "footprint of {budget} bytes too small for paging"
            )));
        }
        let parts = file.virt_parts();
        Ok(Self {
            pager: Pager::new(file.clone(), pages as usize),
            file,
            parts,
        })
    }

    /// Resident bytes: the in-core part plus the pages held.
    pub fn resident_bytes(&self) -> u64 {
        self.file.core_bytes() + self.pager.resident_bytes()
    }

    fn words<const N: usize>(&mut self, offset: u64) -> Result<[u32; N], VdtError> {
        let mut b = vec![0u8; 4 * N];
        self.pager.read(offset, &mut b)?;
        let mut w = [0u32; N];
        for (k, c) in b.chunks_exact(4).enumerate() {
            w[k] = u32::from_le_bytes([c[0], c[1], c[2], c[3]]);
        }
        Ok(w)
    }

    fn node(&mut self, id: u32) -> Result<VdNode, VdtError> {
        if id >= self.file.header.node_count {
            return Err(VdtError::Corrupt(format!("node id {id} out of range")));
        }
        let mut b = [0u8; NODE_ENTRY as usize];
        self.pager
            .read(self.parts[0] + u64::from(id) * NODE_ENTRY, &mut b)?;
        let nd: VdNode = bytemuck::pod_read_unaligned(&b);
        self.file.check_node(id, &nd)?;
        Ok(nd)
    }

    fn placed(&mut self, id: u32) -> Result<Placed, VdtError> {
        let node = self.node(id)?;
        let w: [u32; 3] = self.words(self.parts[1] + u64::from(node.leaf) * 12)?;
        Ok(Placed {
            id,
            node,
            pos: Vec3::from(w.map(f32::from_bits)),
        })
    }
}

impl NodeStore for VirtStore {
    fn roots(&mut self) -> Result<Vec<Placed>, VdtError> {
        (0..self.file.header.tree_roots)
            .map(|k| {
                let [r] = self.words::<1>(self.parts[4] + 4 * u64::from(k))?;
                self.placed(r)
            })
            .collect()
    }

    fn permanent(&mut self) -> Result<TriList, VdtError> {
        Ok(self.file.permanent.clone())
    }

    fn children(&mut self, v: &Placed) -> Result<Option<[Placed; 2]>, VdtError> {
        let mut l = self.placed(v.node.left)?;
        l.pos = v.pos;
        Ok(Some([l, self.placed(v.node.right)?]))
    }

    fn parent(&mut self, v: &Placed) -> Result<Option<(u32, VdNode)>, VdtError> {
        Ok(Some((v.node.parent, self.node(v.node.parent)?)))
    }

    fn adjacent(&mut self, v: u32) -> Result<Option<TriList>, VdtError> {
        let n = self.file.header.leaf_count;
        if v < n || v == NONE {
            return Err(VdtError::Corrupt(format!("adjacency of leaf {v}")));
        }
        let [a, b] = self.words::<2>(self.parts[2] + 4 * u64::from(v - n))?;
        if a > b || u64::from(b) > self.file.header.adjacency_count {
            return Err(VdtError::Corrupt(format!("node {v}: adjacency range")));
        }
        let mut out = Vec::with_capacity((b - a) as usize);
        for t in a..b {
            let [id, x, y, z] = self.words::<4>(self.parts[3] + u64::from(t) * TRI_ENTRY)?;
            if [x, y, z].iter().any(|&c| c >= n) {
                return Err(VdtError::Corrupt(format!(
                    "triangle {id}: corner out of range"
                )));
            }
            out.push((id, [x, y, z]));
        }
        Ok(Some(out))
    }

    fn activated(&mut self, _: u32) {}
    fn deactivated(&mut self, _: u32) {}
}
