//! The Multi-Triangulation file (Holst & Schumann §4.1): hierarchy and
//! geometry together, each node followed by its outgoing arcs with their
//! triangles, its ingoing arcs as (father, arc position) tuples; nodes
//! stored partition after partition, so one partition is one read.
//!
//! ```text
//! MtHeader (136 B, CRC-32 of its own bytes)
//! directory  node_count × 16 B NodeDir (offset in DATA, length, CRC-32)
//!            partition_count × 8 B PartDir (first node, node count)
//!            (one CRC-32 each in the header)
//! DATA       node records, in id order:
//!            NodeHead (32 B)
//!            out_count × { ArcHead (12 B), PackedVertex × vertex_count,
//!                          indices (u16, or u32 past 65535 vertices),
//!                          zero-padded to 4 B }
//!            in_count × (father u32, position u32)
//! ```
//!
//! Positions are 16-bit unorm over the header's box, normals 8-bit snorm
//! (the scene format's [`PackedVertex`]). The directory and the partition
//! table are the MT's in-core part; nodes are read on demand.

use bytemuck::{Pod, Zeroable};
use std::sync::Arc;

use super::{DRAIN, Mt, Partitioning};
use crate::format::{PackedVertex, quantize_unit_normal};
use crate::io::ByteSource;

/// File magic.
pub const MT_MAGIC: u32 = u32::from_le_bytes(*b"HMT1");
/// Format version this build writes and reads.
pub const MT_VERSION: u32 = 1;

#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct MtHeader {
    pub magic: u32,
    pub version: u32,
    pub node_count: u32,
    pub arc_count: u32,
    pub partition_count: u32,
    pub theta: u32,
    pub layers: u32,
    /// Largest node record.
    pub max_record: u32,
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    pub quant_min: [f32; 3],
    pub quant_scale: [f32; 3],
    pub dir_crc: u32,
    pub part_crc: u32,
    pub input_triangles: u64,
    pub arc_triangles: u64,
    pub dir_offset: u64,
    pub data_offset: u64,
    pub data_len: u64,
    pub header_crc: u32,
    pub pad: u32,
}
const _: () = assert!(std::mem::size_of::<MtHeader>() == 136);

/// Where a node's record is.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct NodeDir {
    /// From the start of DATA.
    pub offset: u64,
    pub len: u32,
    pub crc: u32,
}
const _: () = assert!(std::mem::size_of::<NodeDir>() == 16);

/// A partition: nodes `first..first + count`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PartDir {
    pub first: u32,
    pub count: u32,
}
const _: () = assert!(std::mem::size_of::<PartDir>() == 8);

/// The head of a node record.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct NodeHead {
    pub layer: u32,
    pub error: f32,
    pub center: [f32; 3],
    pub radius: f32,
    pub out_count: u32,
    pub in_count: u32,
}
const _: () = assert!(std::mem::size_of::<NodeHead>() == 32);

/// The head of an outgoing arc.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct ArcHead {
    /// A node or [`DRAIN`].
    pub child: u32,
    pub vertex_count: u32,
    pub tri_count: u32,
}
const _: () = assert!(std::mem::size_of::<ArcHead>() == 12);

const HEADER: usize = std::mem::size_of::<MtHeader>();

/// Errors reading an MT file.
#[derive(Debug, thiserror::Error)]
pub enum MtFileError {
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    #[error("not a Multi-Triangulation file (bad magic)")]
    BadMagic,
    #[error("unsupported MT format version {0} (this build reads {MT_VERSION})")]
    Version(u32),
    #[error("checksum mismatch in {0}")]
    Checksum(String),
    #[error("corrupt {0}")]
    Corrupt(String),
    #[error("{0}")]
    TooLarge(String),
}

/// The id each node gets in the file: partition by partition, each in its
/// node order.
pub fn file_ids(parts: &Partitioning) -> Vec<u32> {
    let mut new_id = vec![0u32; parts.of_node.len()];
    for (k, &old) in parts.members().iter().flatten().enumerate() {
        new_id[old as usize] = k as u32;
    }
    new_id
}

/// Encodes `mt` with its partitioning: nodes renumbered partition by
/// partition (each in its node order), arcs of a node sorted by new child.
pub fn encode(mt: &Mt, parts: &Partitioning) -> Result<Vec<u8>, MtFileError> {
    let n = mt.nodes.len();
    let members = parts.members();
    let order: Vec<u32> = members.iter().flatten().copied().collect();
    let new_id = file_ids(parts);
    let map = |c: u32| {
        if c == DRAIN {
            DRAIN
        } else {
            new_id[c as usize]
        }
    };
    // Outgoing arcs per new node, sorted by new child; positions of arcs.
    let mut outs: Vec<Vec<u32>> = vec![Vec::new(); n];
    for (k, &old) in order.iter().enumerate() {
        let mut a: Vec<u32> = mt.out_arcs(old).map(|i| i as u32).collect();
        a.sort_by_key(|&i| map(mt.arcs[i as usize].child));
        outs[k] = a;
    }
    let mut ins: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n];
    for (f, arcs) in outs.iter().enumerate() {
        for (pos, &i) in arcs.iter().enumerate() {
            let c = mt.arcs[i as usize].child;
            if c != DRAIN {
                ins[new_id[c as usize] as usize].push((f as u32, pos as u32));
            }
        }
    }
    let (lo, hi) = bounds(&mt.positions);
    let scale = std::array::from_fn::<f32, 3, _>(|a| (hi[a] - lo[a]) / 65535.0);
    let quant = |p: [f32; 3]| -> [u16; 4] {
        let mut q = [0u16; 4];
        for a in 0..3 {
            if scale[a] > 0.0 {
                q[a] = ((p[a] - lo[a]) / scale[a]).round().clamp(0.0, 65535.0) as u16;
            }
        }
        q
    };
    let mut data = Vec::new();
    let mut dir = Vec::with_capacity(n);
    let mut max_record = 0usize;
    for (k, &old) in order.iter().enumerate() {
        let start = data.len();
        let nd = mt.nodes[old as usize];
        let head = NodeHead {
            layer: nd.layer,
            error: nd.error,
            center: nd.center,
            radius: nd.radius,
            out_count: outs[k].len() as u32,
            in_count: ins[k].len() as u32,
        };
        data.extend_from_slice(bytemuck::bytes_of(&head));
        for &i in &outs[k] {
            let a = &mt.arcs[i as usize];
            let mut local: std::collections::HashMap<u32, u32> = Default::default();
            let mut verts = Vec::new();
            let mut idx = Vec::with_capacity(a.triangles.len() * 3);
            for &v in a.triangles.iter().flatten() {
                let next = verts.len() as u32;
                let l = *local.entry(v).or_insert_with(|| {
                    verts.push(v);
                    next
                });
                idx.push(l);
            }
            let ah = ArcHead {
                child: map(a.child),
                vertex_count: verts.len() as u32,
                tri_count: a.triangles.len() as u32,
            };
            data.extend_from_slice(bytemuck::bytes_of(&ah));
            for &v in &verts {
                let nrm = mt.normals.get(v as usize).copied().unwrap_or([0.0; 3]);
                let pv = PackedVertex {
                    position: quant(mt.positions[v as usize]),
                    normal: quantize_unit_normal(nrm),
                    color: [255; 4],
                };
                data.extend_from_slice(bytemuck::bytes_of(&pv));
            }
            if verts.len() > 65535 {
                idx.iter()
                    .for_each(|i| data.extend_from_slice(&i.to_le_bytes()));
            } else {
                idx.iter()
                    .for_each(|&i| data.extend_from_slice(&(i as u16).to_le_bytes()));
            }
            while data.len() % 4 != 0 {
                data.push(0);
            }
        }
        for &(f, pos) in &ins[k] {
            data.extend_from_slice(&f.to_le_bytes());
            data.extend_from_slice(&pos.to_le_bytes());
        }
        let len = data.len() - start;
        let len32 = u32::try_from(len)
            .map_err(|_| MtFileError::TooLarge(format!("node {k}: record of {len} bytes")))?;
        max_record = max_record.max(len);
        dir.push(NodeDir {
            offset: start as u64,
            len: len32,
            crc: crc32fast::hash(&data[start..]),
        });
    }
    let mut table = Vec::with_capacity(members.len());
    let mut first = 0u32;
    for m in &members {
        table.push(PartDir {
            first,
            count: m.len() as u32,
        });
        first += m.len() as u32;
    }
    let dir_bytes: &[u8] = bytemuck::cast_slice(&dir);
    let part_bytes: &[u8] = bytemuck::cast_slice(&table);
    let dir_offset = HEADER as u64;
    let data_offset = dir_offset + (dir_bytes.len() + part_bytes.len()) as u64;
    let mut h = MtHeader {
        magic: MT_MAGIC,
        version: MT_VERSION,
        node_count: n as u32,
        arc_count: mt.arcs.len() as u32,
        partition_count: parts.count,
        theta: parts.theta,
        layers: mt.layers(),
        max_record: max_record as u32,
        bounds_min: lo,
        bounds_max: hi,
        quant_min: lo,
        quant_scale: scale,
        dir_crc: crc32fast::hash(dir_bytes),
        part_crc: crc32fast::hash(part_bytes),
        input_triangles: mt.input_triangles,
        arc_triangles: mt.arc_triangles(),
        dir_offset,
        data_offset,
        data_len: data.len() as u64,
        header_crc: 0,
        pad: 0,
    };
    h.header_crc = crc32fast::hash(&bytemuck::bytes_of(&h)[..HEADER - 8]);
    let mut out = Vec::with_capacity(data_offset as usize + data.len());
    out.extend_from_slice(bytemuck::bytes_of(&h));
    out.extend_from_slice(dir_bytes);
    out.extend_from_slice(part_bytes);
    out.extend_from_slice(&data);
    Ok(out)
}

fn bounds(p: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for v in p {
        for a in 0..3 {
            lo[a] = lo[a].min(v[a]);
            hi[a] = hi[a].max(v[a]);
        }
    }
    if !lo[0].is_finite() {
        return ([0.0; 3], [0.0; 3]);
    }
    (lo, hi)
}

/// An MT file opened for reading: header, directory and partition table in
/// core, node records read on demand.
pub struct MtFile {
    pub source: Arc<dyn ByteSource>,
    pub header: MtHeader,
    pub dir: Vec<NodeDir>,
    pub parts: Vec<PartDir>,
    /// Partition of each node.
    pub part_of: Vec<u32>,
}

/// A node record in core.
#[derive(Clone, Debug)]
pub struct NodeData {
    pub id: u32,
    pub head: NodeHead,
    /// The record as read (checked).
    pub raw: Arc<[u8]>,
    /// Byte offsets of the outgoing arcs' heads in `raw`.
    pub arc_at: Vec<u32>,
    /// Ingoing arcs: (father, position among the father's outgoing arcs).
    pub ins: Vec<(u32, u32)>,
}

impl NodeData {
    /// Bytes this node holds in core.
    pub fn bytes(&self) -> u64 {
        self.raw.len() as u64 + 8 * (self.arc_at.len() + self.ins.len()) as u64 + 96
    }

    /// Outgoing arc `k`: its head, vertices and indices.
    pub fn arc(&self, k: usize) -> (ArcHead, &[u8], Vec<u32>) {
        let at = self.arc_at[k] as usize;
        let h: ArcHead = bytemuck::pod_read_unaligned(&self.raw[at..at + 12]);
        let v0 = at + 12;
        let v1 = v0 + 16 * h.vertex_count as usize;
        let wide = h.vertex_count > 65535;
        let n = 3 * h.tri_count as usize;
        let ib = &self.raw[v1..v1 + n * if wide { 4 } else { 2 }];
        let idx = if wide {
            ib.chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect()
        } else {
            ib.chunks_exact(2)
                .map(|c| u32::from(u16::from_le_bytes([c[0], c[1]])))
                .collect()
        };
        (h, &self.raw[v0..v1], idx)
    }

    /// Child of outgoing arc `k`.
    pub fn child(&self, k: usize) -> u32 {
        let at = self.arc_at[k] as usize;
        u32::from_le_bytes(self.raw[at..at + 4].try_into().expect("4 bytes"))
    }
}

impl MtFile {
    /// Opens and checks the header, the directory and the partition table.
    pub fn open(source: Arc<dyn ByteSource>) -> Result<Self, MtFileError> {
        let len = source.len();
        if len < HEADER as u64 {
            return Err(MtFileError::Corrupt(format!(
                "file of {len} bytes: no header"
            )));
        }
        let mut hb = [0u8; HEADER];
        source.read_at(0, &mut hb)?;
        let h: MtHeader = bytemuck::pod_read_unaligned(&hb);
        if h.magic != MT_MAGIC {
            return Err(MtFileError::BadMagic);
        }
        if h.version != MT_VERSION {
            return Err(MtFileError::Version(h.version));
        }
        if crc32fast::hash(&hb[..HEADER - 8]) != h.header_crc {
            return Err(MtFileError::Checksum("header".into()));
        }
        let dir_len = u64::from(h.node_count) * 16;
        let part_len = u64::from(h.partition_count) * 8;
        let data_end = h.data_offset.checked_add(h.data_len);
        if h.dir_offset != HEADER as u64
            || h.data_offset != h.dir_offset + dir_len + part_len
            || data_end != Some(len)
            || h.node_count == 0
            || h.partition_count == 0
            || h.partition_count > h.node_count
        {
            return Err(MtFileError::Corrupt(
                "header: section ranges disagree with the file".into(),
            ));
        }
        let mut db = vec![0u8; (dir_len + part_len) as usize];
        source.read_at(h.dir_offset, &mut db)?;
        let (dbytes, pbytes) = db.split_at(dir_len as usize);
        if crc32fast::hash(dbytes) != h.dir_crc {
            return Err(MtFileError::Checksum("node directory".into()));
        }
        if crc32fast::hash(pbytes) != h.part_crc {
            return Err(MtFileError::Checksum("partition table".into()));
        }
        let dir: Vec<NodeDir> = bytemuck::pod_collect_to_vec(dbytes);
        let parts: Vec<PartDir> = bytemuck::pod_collect_to_vec(pbytes);
        let mut next = 0u64;
        for (k, d) in dir.iter().enumerate() {
            if d.offset != next || d.len < 32 {
                return Err(MtFileError::Corrupt(format!("directory entry of node {k}")));
            }
            next += u64::from(d.len);
        }
        if next != h.data_len {
            return Err(MtFileError::Corrupt("directory does not tile DATA".into()));
        }
        let mut part_of = vec![0u32; dir.len()];
        let mut first = 0u32;
        for (p, pd) in parts.iter().enumerate() {
            if pd.first != first || pd.count == 0 || pd.count > h.theta {
                return Err(MtFileError::Corrupt(format!("partition {p}")));
            }
            let end = first.checked_add(pd.count).filter(|&e| e <= h.node_count);
            let end = end.ok_or_else(|| MtFileError::Corrupt(format!("partition {p}")))?;
            part_of[first as usize..end as usize].fill(p as u32);
            first = end;
        }
        if first != h.node_count {
            return Err(MtFileError::Corrupt(
                "partitions do not tile the nodes".into(),
            ));
        }
        Ok(Self {
            source,
            header: h,
            dir,
            parts,
            part_of,
        })
    }

    /// Bytes the open file holds in core (header, directory, table).
    pub fn core_bytes(&self) -> u64 {
        (HEADER + 16 * self.dir.len() + 8 * self.parts.len() + 4 * self.part_of.len()) as u64
    }

    /// Reads nodes `first..end` in one read; each node is checked on its
    /// own, so a corrupt one does not spoil its neighbours.
    pub fn read_nodes(
        &self,
        first: u32,
        end: u32,
    ) -> Result<Vec<Result<NodeData, MtFileError>>, MtFileError> {
        let (a, b) = (&self.dir[first as usize], &self.dir[end as usize - 1]);
        let len = b.offset + u64::from(b.len) - a.offset;
        let mut buf = vec![0u8; len as usize];
        self.source
            .read_at(self.header.data_offset + a.offset, &mut buf)?;
        Ok((first..end)
            .map(|id| {
                let d = &self.dir[id as usize];
                let at = (d.offset - a.offset) as usize;
                self.decode(id, &buf[at..at + d.len as usize])
            })
            .collect())
    }

    fn decode(&self, id: u32, rec: &[u8]) -> Result<NodeData, MtFileError> {
        if crc32fast::hash(rec) != self.dir[id as usize].crc {
            return Err(MtFileError::Checksum(format!("node {id}")));
        }
        let bad = |why: &str| MtFileError::Corrupt(format!("node {id}: {why}"));
        let head: NodeHead = bytemuck::pod_read_unaligned(&rec[..32]);
        let n = self.header.node_count;
        let mut at = 32usize;
        let mut arc_at = Vec::with_capacity(head.out_count as usize);
        for _ in 0..head.out_count {
            let h: ArcHead =
                bytemuck::pod_read_unaligned(rec.get(at..at + 12).ok_or_else(|| bad("arc head"))?);
            if (h.child != DRAIN && h.child >= n) || h.child == id || h.tri_count == 0 {
                return Err(bad("arc child or size"));
            }
            let wide = h.vertex_count > 65535;
            let ib = 3 * h.tri_count as usize * if wide { 4 } else { 2 };
            let end = (at + 12 + 16 * h.vertex_count as usize + ib).next_multiple_of(4);
            if end > rec.len() {
                return Err(bad("arc past the record"));
            }
            arc_at.push(at as u32);
            at = end;
        }
        let ins_len = 8 * head.in_count as usize;
        let sane = |x: f32| x >= 0.0;
        if at + ins_len != rec.len() || !sane(head.error) || !sane(head.radius) {
            return Err(bad("record length or bounds"));
        }
        let ins: Vec<(u32, u32)> = rec[at..]
            .chunks_exact(8)
            .map(|c| {
                let f = u32::from_le_bytes(c[..4].try_into().expect("4"));
                let p = u32::from_le_bytes(c[4..].try_into().expect("4"));
                (f, p)
            })
            .collect();
        if ins.iter().any(|&(f, _)| f >= n || f == id) {
            return Err(bad("ingoing arc father"));
        }
        let node = NodeData {
            id,
            head,
            raw: rec.into(),
            arc_at,
            ins,
        };
        for k in 0..node.arc_at.len() {
            let (h, _, idx) = node.arc(k);
            if idx.iter().any(|&i| i >= h.vertex_count) {
                return Err(bad("index past the arc's vertices"));
            }
        }
        Ok(node)
    }
}

impl std::fmt::Debug for MtFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MtFile")
            .field("header", &self.header)
            .field("nodes", &self.dir.len())
            .field("partitions", &self.parts.len())
            .finish_non_exhaustive()
    }
}
