//! The `.vdt` file: one view-dependence forest, in two layouts.
//!
//! ```text
//! header (112 B, CRC-32 of its own bytes)
//! MNT        meta_count × 32 B  MntRecord        (CRC in the header)
//! permanent  permanent × 16 B   (triangle id, 3 leaves)   (CRC in the header)
//! DATA       meta-node payloads, each with its own CRC in its MNT record
//! VIRT       the flat tree the virtual-memory baseline pages:
//!            nodes by id (36 B), leaf positions (12 B), adjacency offsets
//!            (u32 per internal node + 1), adjacency entries (16 B), root
//!            ids (u32 each)
//! ```
//!
//! The external-memory run time keeps the header, the MNT and the permanent
//! triangles in core and reads DATA one meta-node at a time; the baseline
//! reads VIRT in 4 KiB pages. Root meta-nodes are `0..root_count` (the
//! blocking is breadth-first).

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};

use super::meta::{self, MntRecord};
use super::{VdNode, VdTree};
use crate::io::ByteSource;

/// File magic.
pub const VDT_MAGIC: u32 = u32::from_le_bytes(*b"HVDT");
/// Format version this build writes and reads.
pub const VDT_VERSION: u32 = 1;

/// The fixed header at offset 0.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct VdtHeader {
    pub magic: u32,
    pub version: u32,
    pub leaf_count: u32,
    pub node_count: u32,
    pub triangle_count: u32,
    pub meta_count: u32,
    /// Root meta-nodes (`0..root_count`).
    pub root_count: u32,
    pub levels: u32,
    pub permanent_count: u32,
    /// Largest meta-node payload: the size of a place holder.
    pub max_meta_bytes: u32,
    pub mnt_crc: u32,
    pub permanent_crc: u32,
    pub data_offset: u64,
    pub data_len: u64,
    pub virt_offset: u64,
    pub adjacency_count: u64,
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    /// Roots of the forest (ids listed at the end of the flat layout).
    pub tree_roots: u32,
    pub header_crc: u32,
}
const _: () = assert!(std::mem::size_of::<VdtHeader>() == 112);

/// Bytes of one adjacency or permanent entry: triangle id and three leaves.
pub const TRI_ENTRY: u64 = 16;
/// Bytes of one node in the flat layout.
pub const NODE_ENTRY: u64 = std::mem::size_of::<VdNode>() as u64;

impl VdtHeader {
    /// The header and the bytes of the root meta-nodes, from a prefix of an
    /// encoded file holding at least the header and the roots' MNT records.
    /// `None` when the prefix is shorter or the root meta-nodes are not
    /// stored first in DATA, in order (the scene rep's payload relies on it).
    pub fn with_root_bytes(prefix: &[u8]) -> Option<(Self, u64)> {
        let h: VdtHeader = bytemuck::pod_read_unaligned(prefix.get(..112)?);
        let roots = h.root_count as usize;
        let mnt = prefix.get(112..112usize.checked_add(roots.checked_mul(32)?)?)?;
        let mut end = 0u64;
        for c in mnt.chunks_exact(32) {
            let r: meta::MntRecord = bytemuck::pod_read_unaligned(c);
            if r.offset != end {
                return None;
            }
            end = end.checked_add(u64::from(r.len))?;
        }
        Some((h, end))
    }

    /// Bytes of the file's prefix a scene rep covers: the in-core part
    /// (header, MNT, permanent triangles) and the root meta-nodes —
    /// everything the coarsest level needs. `None` when `bytes` is not that
    /// long or its header and root records disagree.
    pub fn rep_len(bytes: &[u8]) -> Option<usize> {
        let (h, roots) = Self::with_root_bytes(bytes)?;
        let end = usize::try_from(h.data_offset.checked_add(roots)?).ok()?;
        (end <= bytes.len()).then_some(end)
    }

    /// Holder bytes the external-memory store needs at least: the root
    /// meta-nodes and room for three of the largest.
    pub fn holder_need(&self, root_bytes: u64) -> u64 {
        root_bytes + 3 * u64::from(self.max_meta_bytes)
    }
}

/// Bytes of the flat layout of a tree with `leaves` leaves, `nodes` nodes
/// (`nodes >= leaves`), `adjacency` adjacency entries and `roots` roots.
/// Saturating: counts read from a corrupt header give `u64::MAX`, which no
/// file length equals.
pub fn flat_len(leaves: u64, nodes: u64, adjacency: u64, roots: u64) -> u64 {
    [
        nodes.saturating_mul(NODE_ENTRY),
        leaves.saturating_mul(12),
        nodes
            .saturating_sub(leaves)
            .saturating_add(1)
            .saturating_mul(4),
        adjacency.saturating_mul(TRI_ENTRY),
        roots.saturating_mul(4),
    ]
    .into_iter()
    .fold(0u64, u64::saturating_add)
}

/// What can go wrong reading a `.vdt` file or a part of it.
#[derive(Debug, thiserror::Error)]
pub enum VdtError {
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    #[error("not a view-dependence-tree file (magic {0:08x})")]
    Magic(u32),
    #[error("unsupported .vdt version {0} (this build reads {VDT_VERSION})")]
    Version(u32),
    #[error("checksum mismatch in {0}")]
    Checksum(&'static str),
    #[error("corrupt file: {0}")]
    Corrupt(String),
}

/// Serialises `tree`, blocked into meta-nodes of `levels` levels.
pub fn encode(tree: &VdTree, levels: u32) -> Vec<u8> {
    let mt = meta::block(tree, levels);
    let files = meta::encode(tree, &mt);
    encode_blocked(tree, &mt, &files)
}

/// Serialises `tree` with a blocking already made (`mt`, encoded as `files`).
pub fn encode_blocked(tree: &VdTree, mt: &meta::MetaTree, files: &meta::MetaFiles) -> Vec<u8> {
    let tri = |t: u32| -> [u8; 16] {
        let c = tree.triangles[t as usize];
        bytemuck::cast([t, c[0], c[1], c[2]])
    };
    let mnt: &[u8] = bytemuck::cast_slice(&files.mnt);
    let permanent: Vec<u8> = tree.permanent.iter().flat_map(|&t| tri(t)).collect();
    let hdr_len = std::mem::size_of::<VdtHeader>() as u64;
    let data_offset = hdr_len + mnt.len() as u64 + permanent.len() as u64;
    let virt_offset = data_offset + files.data.len() as u64;
    let n = tree.leaf_count();
    let mut virt: Vec<u8> = bytemuck::cast_slice(&tree.nodes).to_vec();
    virt.extend_from_slice(bytemuck::cast_slice(&tree.positions));
    let mut at = 0u32;
    for adj in std::iter::once(&Vec::new()).chain(&tree.adjacent) {
        at += adj.len() as u32;
        virt.extend_from_slice(&at.to_le_bytes());
    }
    for &t in tree.adjacent.iter().flatten() {
        virt.extend_from_slice(&tri(t));
    }
    virt.extend_from_slice(bytemuck::cast_slice(&tree.roots));
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in &tree.positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    if tree.positions.is_empty() {
        (lo, hi) = ([0.0; 3], [0.0; 3]);
    }
    let mut h = VdtHeader {
        magic: VDT_MAGIC,
        version: VDT_VERSION,
        leaf_count: n as u32,
        node_count: tree.nodes.len() as u32,
        triangle_count: tree.triangles.len() as u32,
        meta_count: files.mnt.len() as u32,
        root_count: mt.roots.len() as u32,
        levels: mt.levels,
        permanent_count: tree.permanent.len() as u32,
        max_meta_bytes: files.mnt.iter().map(|r| r.len).max().unwrap_or(0),
        mnt_crc: crc32fast::hash(mnt),
        permanent_crc: crc32fast::hash(&permanent),
        data_offset,
        data_len: files.data.len() as u64,
        virt_offset,
        adjacency_count: tree.adjacent.iter().map(Vec::len).sum::<usize>() as u64,
        bounds_min: lo,
        bounds_max: hi,
        tree_roots: tree.roots.len() as u32,
        header_crc: 0,
    };
    h.header_crc = crc32fast::hash(&bytemuck::bytes_of(&h)[..108]);
    let mut out = bytemuck::bytes_of(&h).to_vec();
    out.extend_from_slice(mnt);
    out.extend_from_slice(&permanent);
    out.extend_from_slice(&files.data);
    out.extend_from_slice(&virt);
    out
}

/// The in-core part of an open `.vdt` file.
///
/// The header is always `size_of::<VdtHeader>()` = 112 bytes.
pub struct VdtFile {
    pub header: VdtHeader,
    pub mnt: Vec<MntRecord>,
    /// `(triangle id, leaves)` of the triangles no collapse removes.
    pub permanent: Vec<(u32, [u32; 3])>,
    pub source: Arc<dyn ByteSource>,
}

impl std::fmt::Debug for VdtFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VdtFile")
            .field("header", &self.header)
            .finish()
    }
}

impl VdtFile {
    /// Reads and checks the header, the MNT and the permanent triangles.
    pub fn open(source: Arc<dyn ByteSource>) -> Result<Self, VdtError> {
        let mut hb = [0u8; 112];
        source.read_at(0, &mut hb)?;
        let h: VdtHeader = bytemuck::pod_read_unaligned(&hb);
        if h.magic != VDT_MAGIC {
            return Err(VdtError::Magic(h.magic));
        }
        if h.version != VDT_VERSION {
            return Err(VdtError::Version(h.version));
        }
        if crc32fast::hash(&hb[..108]) != h.header_crc {
            return Err(VdtError::Checksum("header"));
        }
        let n = u64::from(h.leaf_count);
        let nodes = u64::from(h.node_count);
        let metas = u64::from(h.meta_count);
        let mnt_len = metas * 32;
        let perm_len = u64::from(h.permanent_count) * TRI_ENTRY;
        if nodes < n {
            return Err(corrupt("fewer nodes than leaves"));
        }
        let virt_len = flat_len(n, nodes, h.adjacency_count, u64::from(h.tree_roots));
        if h.data_offset != 112 + mnt_len + perm_len
            || h.data_offset.checked_add(h.data_len) != Some(h.virt_offset)
            || h.virt_offset.checked_add(virt_len) != Some(source.len())
            || h.root_count > h.meta_count
            || h.root_count > h.tree_roots
            || nodes >= u64::from(u32::MAX)
        {
            return Err(corrupt("section sizes disagree with the file length"));
        }
        let mut mb = vec![0u8; mnt_len as usize];
        source.read_at(112, &mut mb)?;
        if crc32fast::hash(&mb) != h.mnt_crc {
            return Err(VdtError::Checksum("MNT"));
        }
        let mnt: Vec<MntRecord> = mb
            .chunks_exact(32)
            .map(bytemuck::pod_read_unaligned)
            .collect();
        for (i, r) in mnt.iter().enumerate() {
            let kids_ok = r.child_count == 0
                || (u64::from(r.first_child) + u64::from(r.child_count) <= metas
                    && r.first_child as usize > i);
            if r.offset
                .checked_add(u64::from(r.len))
                .is_none_or(|e| e > h.data_len)
                || r.len > h.max_meta_bytes
                || !kids_ok
            {
                return Err(corrupt(&format!("MNT record {i} out of range")));
            }
        }
        let mut pb = vec![0u8; perm_len as usize];
        source.read_at(112 + mnt_len, &mut pb)?;
        if crc32fast::hash(&pb) != h.permanent_crc {
            return Err(VdtError::Checksum("permanent triangles"));
        }
        let permanent: Vec<(u32, [u32; 3])> = pb
            .chunks_exact(16)
            .map(|c| {
                let w: [u32; 4] = bytemuck::pod_read_unaligned(c);
                (w[0], [w[1], w[2], w[3]])
            })
            .collect();
        if permanent
            .iter()
            .any(|(t, c)| *t >= h.triangle_count || c.iter().any(|&v| u64::from(v) >= n))
        {
            return Err(corrupt("permanent triangle out of range"));
        }
        Ok(Self {
            header: h,
            mnt,
            permanent,
            source,
        })
    }

    /// Bytes of the in-core part (header, MNT, permanent triangles).
    pub fn core_bytes(&self) -> u64 {
        self.header.data_offset
    }

    /// Bytes of the root meta-nodes (stored first in DATA).
    pub fn root_bytes(&self) -> u64 {
        self.mnt[..self.header.root_count as usize]
            .iter()
            .map(|r| u64::from(r.len))
            .sum()
    }

    /// Holder bytes the external-memory store needs at least: the root
    /// meta-nodes and room for three of the largest.
    pub fn holder_need(&self) -> u64 {
        self.header.holder_need(self.root_bytes())
    }

    /// Reads one meta-node payload and decodes it (checksum checked).
    pub fn read_meta(&self, id: u32) -> Result<meta::DecodedMeta, VdtError> {
        let r = self
            .mnt
            .get(id as usize)
            .ok_or_else(|| corrupt("meta-node id out of range"))?;
        let mut buf = vec![0u8; r.len as usize];
        self.source
            .read_at(self.header.data_offset + r.offset, &mut buf)?;
        meta::decode(&buf, r).map_err(|e| VdtError::Corrupt(format!("meta-node {id}: {e}")))
    }

    /// Offsets of the flat layout's parts: nodes, positions, adjacency
    /// offsets, adjacency entries, root ids.
    pub fn virt_parts(&self) -> [u64; 5] {
        let h = &self.header;
        let nodes = h.virt_offset;
        let pos = nodes + u64::from(h.node_count) * NODE_ENTRY;
        let offs = pos + u64::from(h.leaf_count) * 12;
        let adj = offs + (u64::from(h.node_count - h.leaf_count) + 1) * 4;
        let roots = adj + h.adjacency_count * TRI_ENTRY;
        [nodes, pos, offs, adj, roots]
    }

    /// Reads the whole flat tree into core (the in-core mode) and checks it.
    pub fn load_tree(&self) -> Result<VdTree, VdtError> {
        let h = &self.header;
        let [nodes_at, pos_at, offs_at, adj_at, roots_at] = self.virt_parts();
        let mut b = vec![0u8; (self.source.len() - nodes_at) as usize];
        self.source.read_at(nodes_at, &mut b)?;
        let part = |from: u64, to: u64| &b[(from - nodes_at) as usize..(to - nodes_at) as usize];
        let nodes: Vec<VdNode> = part(nodes_at, pos_at)
            .chunks_exact(NODE_ENTRY as usize)
            .map(bytemuck::pod_read_unaligned)
            .collect();
        let positions: Vec<[f32; 3]> = part(pos_at, offs_at)
            .chunks_exact(12)
            .map(bytemuck::pod_read_unaligned)
            .collect();
        let offs: Vec<u32> = part(offs_at, adj_at)
            .chunks_exact(4)
            .map(bytemuck::pod_read_unaligned)
            .collect();
        let entries: Vec<[u32; 4]> = part(adj_at, roots_at)
            .chunks_exact(16)
            .map(bytemuck::pod_read_unaligned)
            .collect();
        let roots: Vec<u32> = part(roots_at, self.source.len())
            .chunks_exact(4)
            .map(bytemuck::pod_read_unaligned)
            .collect();
        let mut triangles = vec![[u32::MAX; 3]; h.triangle_count as usize];
        let mut put = |id: u32, c: [u32; 3]| -> Result<(), VdtError> {
            let slot = triangles
                .get_mut(id as usize)
                .ok_or_else(|| corrupt("triangle id out of range"))?;
            *slot = c;
            Ok(())
        };
        let mut adjacent = Vec::with_capacity(offs.len().saturating_sub(1));
        for w in offs.windows(2) {
            let r = entries
                .get(w[0] as usize..w[1] as usize)
                .ok_or_else(|| corrupt("adjacency offsets"))?;
            for e in r {
                put(e[0], [e[1], e[2], e[3]])?;
            }
            adjacent.push(r.iter().map(|e| e[0]).collect());
        }
        for &(t, c) in &self.permanent {
            put(t, c)?;
        }
        let tree = VdTree {
            positions,
            triangles,
            nodes,
            adjacent,
            permanent: self.permanent.iter().map(|x| x.0).collect(),
            roots,
        };
        tree.validate().map_err(VdtError::Corrupt)?;
        Ok(tree)
    }

    /// Checks a node record read from the file against the header (ids and
    /// leaf interval in range, children younger than it).
    pub fn check_node(&self, id: u32, nd: &VdNode) -> Result<(), VdtError> {
        let (n, total) = (self.header.leaf_count, self.header.node_count);
        let leaf = id < n;
        let ok = id < total
            && nd.leaf < nd.leaf_end
            && nd.leaf_end <= n
            && (nd.parent == super::NONE || (nd.parent > id && nd.parent < total))
            && if leaf {
                nd.left == super::NONE && nd.right == super::NONE
            } else {
                nd.left < id && nd.right < id
            }
            && nd.switch.is_finite()
            && nd.radius.is_finite();
        if ok {
            Ok(())
        } else {
            Err(corrupt(&format!("node record {id} out of range")))
        }
    }
}

fn corrupt(s: &str) -> VdtError {
    VdtError::Corrupt(s.to_string())
}
