//! Compressed mesh payloads (version 3): the same [`RepHeader`], then the
//! vertices and the indices through meshoptimizer's vertex and index codecs.
//!
//! ```text
//! RepHeader (48 B, magic REPZ) | vertex stream length: u32 | 0: u32
//!     | vertex stream (meshopt vertex codec v1, 16-byte vertices)
//!     | index stream (meshopt index codec, the rest of the payload)
//! ```
//!
//! A payload is stored compressed only when that is shorter than the raw
//! [`REP_MAGIC`] layout, so a rep's stored `len` never exceeds its
//! [`RepRecord::resident_len`]. P_I expands a compressed payload into the raw
//! layout as it loads it ([`expand_payload`]): what is resident, what P_R
//! decodes and what the footprint counts is always the raw payload.

use std::borrow::Cow;
use std::mem::size_of;

use super::rep::{PackedVertex, RepHeader, RepMesh, check_header, check_indices};
use super::{FormatError, RepRecord};

/// Magic of a compressed payload.
pub const REPZ_MAGIC: u32 = u32::from_le_bytes(*b"REPZ");

/// The vertex codec's format version, pinned so that the same mesh always
/// gives the same bytes (version 1: meshoptimizer 0.23 and later decode it).
const VERTEX_CODEC_VERSION: i32 = 1;
/// The vertex codec's effort (0 fastest … 3 smallest); decoding speed does
/// not depend on it.
const VERTEX_CODEC_LEVEL: i32 = 2;
/// Bytes between the header and the vertex stream.
const PREFIX: usize = 8;

impl RepMesh {
    /// Serialises the rep compressed, or raw ([`RepMesh::encode`]) when
    /// compressing would not make it shorter.
    pub fn encode_compressed(&self, node: u32, index: u32) -> Vec<u8> {
        let raw = self.encode(node, index);
        match self.compress(&raw) {
            Some(z) if z.len() < raw.len() => z,
            _ => raw,
        }
    }

    fn compress(&self, raw: &[u8]) -> Option<Vec<u8>> {
        let vs = meshopt::encode_vertex_buffer_level(
            &self.vertices,
            VERTEX_CODEC_LEVEL,
            Some(VERTEX_CODEC_VERSION),
        )
        .ok()?;
        let is = meshopt::encode_index_buffer(&self.indices, self.vertices.len()).ok()?;
        let hsize = size_of::<RepHeader>();
        let mut header: RepHeader = bytemuck::pod_read_unaligned(&raw[..hsize]);
        header.magic = REPZ_MAGIC;
        let mut out = Vec::with_capacity(hsize + PREFIX + vs.len() + is.len());
        out.extend_from_slice(bytemuck::bytes_of(&header));
        out.extend_from_slice(&u32::try_from(vs.len()).ok()?.to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        out.extend_from_slice(&vs);
        out.extend_from_slice(&is);
        Some(out)
    }
}

/// Whether a stored payload is compressed (by its magic).
pub fn is_compressed(bytes: &[u8]) -> bool {
    bytes.len() >= 4 && bytes[..4] == REPZ_MAGIC.to_le_bytes()
}

/// The raw payload that stored payload `bytes` of rep `rep_id` stands for:
/// itself when it is stored raw, its expansion when compressed
/// ([`decode_compressed`] re-encoded raw). The checksum is the caller's (it
/// covers the stored bytes).
pub fn expand_payload<'a>(
    bytes: &'a [u8],
    rep_id: u32,
    rec: &RepRecord,
) -> Result<Cow<'a, [u8]>, FormatError> {
    if !is_compressed(bytes) {
        return Ok(Cow::Borrowed(bytes));
    }
    let mesh = decode_compressed(bytes, rep_id, rec)?;
    Ok(Cow::Owned(mesh.encode(rec.node, u32::from(rec.index))))
}

/// Decodes a compressed payload, checked against the skeleton's record
/// (owner, counts, indices in range).
pub(super) fn decode_compressed(
    bytes: &[u8],
    rep_id: u32,
    rec: &RepRecord,
) -> Result<RepMesh, FormatError> {
    let bad = |reason: String| FormatError::BadRep {
        rep: rep_id,
        reason,
    };
    let hsize = size_of::<RepHeader>();
    if bytes.len() < hsize + PREFIX {
        return Err(bad(format!(
            "compressed payload of {} bytes has no header",
            bytes.len()
        )));
    }
    let h: RepHeader = bytemuck::pod_read_unaligned(&bytes[..hsize]);
    check_header(&h, rec).map_err(bad)?;
    let (vc, ic) = (h.vertex_count as usize, h.index_count as usize);
    let vlen = u32::from_le_bytes(bytes[hsize..hsize + 4].try_into().expect("4 bytes")) as usize;
    let body = &bytes[hsize + PREFIX..];
    if vlen > body.len() {
        return Err(bad(format!(
            "vertex stream of {vlen} bytes in a body of {}",
            body.len()
        )));
    }
    let (vs, is) = body.split_at(vlen);
    // Sized by the skeleton's counts: refused, not aborted, when a lying
    // record asks for more than the machine has.
    let raw_len = RepMesh::encoded_len(vc, ic) as u64;
    crate::limits::check_alloc(raw_len, "an expanded rep").map_err(|e| bad(e.to_string()))?;
    let vertices: Vec<PackedVertex> = meshopt::decode_vertex_buffer(vs, vc)
        .map_err(|e| bad(format!("vertex stream does not decode: {e:?}")))?;
    let indices: Vec<u32> = meshopt::decode_index_buffer(is, ic)
        .map_err(|e| bad(format!("index stream does not decode: {e:?}")))?;
    check_indices(&indices, vc).map_err(bad)?;
    Ok(RepMesh {
        quant_min: h.quant_min,
        quant_scale: h.quant_scale,
        vertices,
        indices,
        placement: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 1000, ..ProptestConfig::default() })]
        /// Hostile compressed payloads (valid header, any body and counts):
        /// an error or a mesh with every index in range, never a panic.
        #[test]
        fn hostile_compressed_payloads_never_panic(
            body in prop::collection::vec(any::<u8>(), 0..400),
            vc in 1u32..300,
            tris in 1u32..300,
            vlen in any::<u32>(),
        ) {
            let h = RepHeader { magic: REPZ_MAGIC, node: 3, index: 1, vertex_count: vc, index_count: tris * 3, index_size: if vc <= 1 << 16 { 2 } else { 4 }, ..Default::default() };
            let mut bytes = bytemuck::bytes_of(&h).to_vec();
            bytes.extend_from_slice(&(vlen % 512).to_le_bytes());
            bytes.extend_from_slice(&0u32.to_le_bytes());
            bytes.extend_from_slice(&body);
            let rec = RepRecord { node: 3, index: 1, tri_count: tris, vertex_count: vc, len: bytes.len() as u32, ..Default::default() };
            if let Ok(m) = decode_compressed(&bytes, 0, &rec) {
                prop_assert!(m.indices.iter().all(|&i| i < vc));
                prop_assert_eq!(m.vertices.len(), vc as usize);
            }
        }
    }

    fn mesh(n: usize) -> RepMesh {
        // A strip of quads: shared vertices, one colour, smooth positions.
        let mut pos = Vec::new();
        for i in 0..n {
            pos.push([i as f32, 0.0, 0.0]);
            pos.push([i as f32, 1.0, 0.0]);
        }
        let mut idx = Vec::new();
        for i in 0..n as u32 - 1 {
            let a = 2 * i;
            idx.extend_from_slice(&[a, a + 2, a + 1, a + 1, a + 2, a + 3]);
        }
        let nrm = vec![[0.0, 0.0, 1.0]; pos.len()];
        let col = vec![[200, 100, 50, 255]; pos.len()];
        RepMesh::quantize(&pos, &nrm, &col, idx)
    }

    use super::super::rep::tests::record_for as record;

    #[test]
    fn compressed_payloads_expand_to_the_raw_payload() {
        for n in [2, 40, 5_000, 40_000] {
            let m = mesh(n);
            let raw = m.encode(3, 1);
            let z = m.encode_compressed(3, 1);
            assert!(is_compressed(&z), "{n} quads");
            assert!(z.len() < raw.len(), "{n}: {} vs {}", z.len(), raw.len());
            if n >= 40 {
                assert!(z.len() * 3 < raw.len(), "{n}: {} vs {}", z.len(), raw.len());
            }
            assert_eq!(z, m.encode_compressed(3, 1), "deterministic");
            let back = expand_payload(&z, 0, &record(&m, &z)).unwrap();
            assert_eq!(back.len(), raw.len());
            let got = RepMesh::decode(&back, 0, &record(&m, &back)).unwrap();
            assert_eq!(got, RepMesh::decode(&z, 0, &record(&m, &z)).unwrap());
            assert_eq!(got.vertices, m.vertices);
            // The index codec may rotate a triangle's corners (its winding
            // kept); the triangles and their order are the same.
            assert_eq!(got.indices.len(), m.indices.len());
            for (a, b) in got.indices.chunks(3).zip(m.indices.chunks(3)) {
                let rotations = [[b[0], b[1], b[2]], [b[1], b[2], b[0]], [b[2], b[0], b[1]]];
                assert!(rotations.contains(&[a[0], a[1], a[2]]), "{a:?} vs {b:?}");
            }
            // A raw payload passes through untouched.
            assert!(matches!(
                expand_payload(&raw, 0, &record(&m, &raw)).unwrap(),
                Cow::Borrowed(_)
            ));
        }
    }

    #[test]
    fn a_mesh_that_does_not_compress_is_stored_raw() {
        let pos = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, -1.0]];
        let m = RepMesh::quantize(
            &pos,
            &[[0.0, 0.0, 1.0]; 3],
            &[[1, 2, 3, 4]; 3],
            vec![0, 1, 2],
        );
        let z = m.encode_compressed(3, 1);
        assert!(!is_compressed(&z) || z.len() < m.encode(3, 1).len());
    }

    #[test]
    fn corrupt_compressed_payloads_are_errors() {
        let m = mesh(300);
        let z = m.encode_compressed(3, 1);
        let rec = record(&m, &z);
        for cut in [0, 20, 52, 60, z.len() / 2, z.len() - 1] {
            let _ = expand_payload(&z[..cut], 0, &rec); // an error or garbage, never a panic
        }
        assert!(expand_payload(&z[..60], 0, &rec).is_err());
        let mut other = rec;
        other.node = 4;
        assert!(expand_payload(&z, 0, &other).is_err());
        let mut lying = z.clone();
        lying[48..52].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(expand_payload(&lying, 0, &rec).is_err());
        // Any single flipped byte of the body: an error or a mesh whose
        // indices are in range (the checksum catches it first in a file).
        for pos in (56..z.len()).step_by(7) {
            let mut b = z.clone();
            b[pos] ^= 0x5a;
            if let Ok(raw) = expand_payload(&b, 0, &rec) {
                RepMesh::decode(&raw, 0, &record(&m, &raw)).unwrap();
            }
        }
    }
}
