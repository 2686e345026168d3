//! Object-rep payloads: a small header, quantised vertices and an index list.
//!
//! ```text
//! RepHeader (48 B) | [PackedVertex; vertex_count] | indices (u16 or u32), padded to 4 B
//! ```
//!
//! Positions are 16-bit unorm over the rep's box (`p = quant_min + q * quant_scale`),
//! normals 8-bit snorm, colours RGBA8 — all plain wgpu vertex formats.

use bytemuck::{Pod, Zeroable};
use std::mem::size_of;

use super::{FormatError, RepRecord};

/// Payload magic.
pub const REP_MAGIC: u32 = u32::from_le_bytes(*b"REP1");

/// Header at the start of every rep payload.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RepHeader {
    pub magic: u32,
    pub node: u32,
    pub index: u32,
    pub vertex_count: u32,
    pub index_count: u32,
    /// 2 or 4.
    pub index_size: u32,
    pub quant_min: [f32; 3],
    pub quant_scale: [f32; 3],
}
const _: () = assert!(size_of::<RepHeader>() == crate::records::REP_HEADER_BYTES);

/// A render-ready vertex: 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Pod, Zeroable)]
pub struct PackedVertex {
    /// Unorm16 position over the rep's box; `[3]` is zero.
    pub position: [u16; 4],
    /// Snorm8 unit normal; `[3]` is zero.
    pub normal: [i8; 4],
    /// RGBA8 colour.
    pub color: [u8; 4],
}
const _: () = assert!(size_of::<PackedVertex>() == crate::records::PACKED_VERTEX_BYTES);

/// A decoded object-rep.
#[derive(Clone, Debug, PartialEq)]
pub struct RepMesh {
    pub quant_min: [f32; 3],
    pub quant_scale: [f32; 3],
    pub vertices: Vec<PackedVertex>,
    /// Triangle list; every index is `< vertices.len()`.
    pub indices: Vec<u32>,
    /// Where a shared payload is placed (its rep's [`crate::records::RepPlacement`]):
    /// [`RepMesh::position`] and [`RepMesh::normal`] apply it. `None` for a
    /// payload in scene coordinates.
    pub placement: Option<crate::records::RepPlacement>,
}

/// Snorm8 encoding of a unit normal (zero vectors stay zero).
pub fn quantize_unit_normal(n: [f32; 3]) -> [i8; 4] {
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let inv = if len > 0.0 && len.is_finite() {
        1.0 / len
    } else {
        0.0
    };
    let q = |c: f32| (c * inv * 127.0).round().clamp(-127.0, 127.0) as i8;
    [q(n[0]), q(n[1]), q(n[2]), 0]
}

impl RepMesh {
    /// Quantises float geometry. `positions`, `normals` and `colors` have one
    /// entry per vertex; the box is the positions' bounds.
    pub fn quantize(
        positions: &[[f32; 3]],
        normals: &[[f32; 3]],
        colors: &[[u8; 4]],
        indices: Vec<u32>,
    ) -> Self {
        let (min, max) = bounds(positions);
        let mut scale = [0f32; 3];
        for a in 0..3 {
            scale[a] = (max[a] - min[a]) / 65535.0;
        }
        let vertices = positions
            .iter()
            .zip(normals)
            .zip(colors)
            .map(|((p, n), c)| {
                let mut q = [0u16; 4];
                for a in 0..3 {
                    if scale[a] > 0.0 {
                        q[a] = ((p[a] - min[a]) / scale[a]).round().clamp(0.0, 65535.0) as u16;
                    }
                }
                PackedVertex {
                    position: q,
                    normal: quantize_unit_normal(*n),
                    color: *c,
                }
            })
            .collect();
        Self {
            quant_min: min,
            quant_scale: scale,
            vertices,
            indices,
            placement: None,
        }
    }

    /// Worst-case distance between a float position and its quantised value.
    pub fn quantization_error(&self) -> f32 {
        let s = self.quant_scale;
        0.5 * (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt()
    }

    /// The dequantised position of vertex `v`, in scene coordinates.
    pub fn position(&self, v: &PackedVertex) -> [f32; 3] {
        let mut p = [0f32; 3];
        for (a, out) in p.iter_mut().enumerate() {
            *out = self.quant_min[a] + f32::from(v.position[a]) * self.quant_scale[a];
        }
        match &self.placement {
            Some(pl) => pl.point(p),
            None => p,
        }
    }

    /// The unit normal of vertex `v`, in scene coordinates.
    pub fn normal(&self, v: &PackedVertex) -> [f32; 3] {
        let n = v.normal.map(|c| f32::from(c) / 127.0);
        let n = [n[0], n[1], n[2]];
        match &self.placement {
            Some(pl) => pl.normal(n),
            None => n,
        }
    }

    /// Triangles in the mesh.
    pub fn tri_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Index width on disk.
    pub fn index_size(&self) -> usize {
        if self.vertices.len() <= 1 << 16 { 2 } else { 4 }
    }

    /// Exact payload length for the given counts.
    pub fn encoded_len(vertex_count: usize, index_count: usize) -> usize {
        crate::records::rep_payload_len(vertex_count, index_count)
    }

    /// Serialises the rep for `node`, position `index`.
    pub fn encode(&self, node: u32, index: u32) -> Vec<u8> {
        let index_size = self.index_size();
        let header = RepHeader {
            magic: REP_MAGIC,
            node,
            index,
            vertex_count: self.vertices.len() as u32,
            index_count: self.indices.len() as u32,
            index_size: index_size as u32,
            quant_min: self.quant_min,
            quant_scale: self.quant_scale,
        };
        let mut out =
            Vec::with_capacity(Self::encoded_len(self.vertices.len(), self.indices.len()));
        out.extend_from_slice(bytemuck::bytes_of(&header));
        out.extend_from_slice(bytemuck::cast_slice(&self.vertices));
        if index_size == 2 {
            for &i in &self.indices {
                out.extend_from_slice(&(i as u16).to_le_bytes());
            }
        } else {
            for &i in &self.indices {
                out.extend_from_slice(&i.to_le_bytes());
            }
        }
        out.resize(out.len().next_multiple_of(4), 0);
        out
    }

    /// Parses and checks a payload against its skeleton record (checksum
    /// excluded: the reader checks it first).
    pub fn decode(bytes: &[u8], rep_id: u32, rec: &RepRecord) -> Result<Self, FormatError> {
        let bad = |reason: String| FormatError::BadRep {
            rep: rep_id,
            reason,
        };
        let hsize = size_of::<RepHeader>();
        if bytes.len() < hsize {
            return Err(bad(format!(
                "payload of {} bytes has no header",
                bytes.len()
            )));
        }
        if super::codec::is_compressed(bytes) {
            return super::codec::decode_compressed(bytes, rep_id, rec);
        }
        let h: RepHeader = bytemuck::pod_read_unaligned(&bytes[..hsize]);
        if h.magic != REP_MAGIC {
            return Err(bad("bad payload magic".into()));
        }
        check_header(&h, rec).map_err(bad)?;
        let (vc, ic) = (h.vertex_count as usize, h.index_count as usize);
        let expect_isize = if vc <= 1 << 16 { 2 } else { 4 };
        if h.index_size as usize != expect_isize {
            return Err(bad(format!(
                "index size {} for {vc} vertices",
                h.index_size
            )));
        }
        if bytes.len() != Self::encoded_len(vc, ic) {
            return Err(bad(format!(
                "payload is {} bytes, counts need {}",
                bytes.len(),
                Self::encoded_len(vc, ic)
            )));
        }
        let vbytes = &bytes[hsize..hsize + vc * size_of::<PackedVertex>()];
        let vertices: Vec<PackedVertex> = vbytes
            .chunks_exact(size_of::<PackedVertex>())
            .map(bytemuck::pod_read_unaligned)
            .collect();
        let ibytes = &bytes[hsize + vbytes.len()..];
        let indices: Vec<u32> = if expect_isize == 2 {
            ibytes
                .chunks_exact(2)
                .take(ic)
                .map(|c| u32::from(u16::from_le_bytes([c[0], c[1]])))
                .collect()
        } else {
            ibytes
                .chunks_exact(4)
                .take(ic)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect()
        };
        check_indices(&indices, vc).map_err(bad)?;
        Ok(Self {
            quant_min: h.quant_min,
            quant_scale: h.quant_scale,
            vertices,
            indices,
            placement: None,
        })
    }
}

/// A payload header against its skeleton record: the same owner and
/// counts, and a finite quantisation box with non-negative steps.
pub(super) fn check_header(h: &RepHeader, rec: &RepRecord) -> Result<(), String> {
    if h.node != rec.node || h.index != u32::from(rec.index) {
        return Err(format!(
            "payload belongs to node {} rep {}, skeleton says node {} rep {}",
            h.node, h.index, rec.node, rec.index
        ));
    }
    if h.vertex_count != rec.vertex_count || h.index_count != rec.tri_count.wrapping_mul(3) {
        return Err("payload counts differ from the skeleton".into());
    }
    if !h
        .quant_min
        .iter()
        .chain(&h.quant_scale)
        .all(|x| x.is_finite())
        || h.quant_scale.iter().any(|&s| s < 0.0)
    {
        return Err("non-finite or negative quantisation box".into());
    }
    Ok(())
}

/// Every index is below the vertex count.
pub(super) fn check_indices(indices: &[u32], vertex_count: usize) -> Result<(), String> {
    match indices.iter().find(|&&i| i as usize >= vertex_count) {
        Some(&i) => Err(format!("index {i} out of range of {vertex_count} vertices")),
        None => Ok(()),
    }
}

/// Bounds of a point set; `([0;3], [0;3])` when empty.
pub(crate) fn bounds(points: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    if points.is_empty() {
        return ([0.0; 3], [0.0; 3]);
    }
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for p in points {
        for a in 0..3 {
            min[a] = min[a].min(p[a]);
            max[a] = max[a].max(p[a]);
        }
    }
    (min, max)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    fn sample() -> RepMesh {
        let pos = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, -1.0]];
        let nrm = [[0.0, 0.0, 1.0]; 3];
        let col = [[255, 0, 0, 255]; 3];
        RepMesh::quantize(&pos, &nrm, &col, vec![0, 1, 2])
    }

    /// The record of `m` as node 3's rep 1, stored as `bytes`.
    pub(in crate::format) fn record_for(m: &RepMesh, bytes: &[u8]) -> RepRecord {
        RepRecord {
            node: 3,
            index: 1,
            tri_count: m.tri_count() as u32,
            vertex_count: m.vertices.len() as u32,
            len: bytes.len() as u32,
            ..Default::default()
        }
    }

    #[test]
    fn round_trip_and_quantisation_error_bound() {
        let m = sample();
        let bytes = m.encode(3, 1);
        assert_eq!(bytes.len(), RepMesh::encoded_len(3, 3));
        let back = RepMesh::decode(&bytes, 0, &record_for(&m, &bytes)).unwrap();
        assert_eq!(back, m);
        let p = back.position(&back.vertices[2]);
        let err = ((p[0]).powi(2) + (p[1] - 2.0).powi(2) + (p[2] + 1.0).powi(2)).sqrt();
        assert!(err <= m.quantization_error() + 1e-6);
    }

    #[test]
    fn decode_rejects_bad_index_and_wrong_owner() {
        let mut m = sample();
        m.indices[2] = 7;
        let bytes = m.encode(3, 1);
        let rec = record_for(&m, &bytes);
        assert!(matches!(
            RepMesh::decode(&bytes, 0, &rec),
            Err(FormatError::BadRep { .. })
        ));
        let m = sample();
        let bytes = m.encode(4, 1);
        assert!(RepMesh::decode(&bytes, 0, &record_for(&m, &bytes)).is_err());
        assert!(RepMesh::decode(&bytes[..10], 0, &record_for(&m, &bytes)).is_err());
    }
}
