//! The order of the reps in the data section.
//!
//! A walkthrough's misses come in groups: the parts of the scene a turn
//! reveals, the objects that cross an LOD-switch distance together. They
//! are reps of nearby nodes selected at the same distance, and a rep `r` is
//! in the front at distances where its next coarser rep PAR(r) is too coarse
//! — a distance proportional to PAR(r)'s error. So the file is laid out by
//! **selection band** (⌊log2 ε(PAR(r))⌋, coarsest first) and, within a band,
//! along a **Morton curve** through the reps' box centres: the reps one
//! frame misses then lie close together, and P_I reads through the short
//! gaps between them instead of seeking (`engine::runtime`'s read
//! coalescing). Building in the order the reps are made and then copying
//! them into this order ([`relayout`]) keeps the builder streaming.

use std::io::{Seek, Write};

use engine::format::{FormatError, RepMesh, SceneFile, SceneWriter};
use engine::io::ByteSource;
use engine::skeleton::{RepId, Skeleton};

/// The reps of `skeleton` in layout order (deterministic).
pub fn file_order(skeleton: &Skeleton) -> Vec<RepId> {
    let Some(root) = skeleton.nodes.first() else {
        return Vec::new();
    };
    let lo = glam::Vec3::from(root.bbox_min);
    let size = (glam::Vec3::from(root.bbox_max) - lo).max(glam::Vec3::splat(1e-9));
    let mut keyed: Vec<(i32, u64, RepId)> = (0..skeleton.reps.len() as RepId)
        .map(|r| {
            let band = match skeleton.par(r) {
                None => i32::MAX,
                Some(p) => {
                    let e = skeleton.reps[p as usize].error;
                    if e > 0.0 && e.is_finite() {
                        e.log2().floor() as i32
                    } else {
                        i32::MIN
                    }
                }
            };
            let rec = &skeleton.reps[r as usize];
            let c = (glam::Vec3::from(rec.bbox_min) + glam::Vec3::from(rec.bbox_max)) * 0.5;
            let q = ((c - lo) / size).clamp(glam::Vec3::ZERO, glam::Vec3::ONE) * 2_097_151.0;
            (-band, morton3(q.x as u32, q.y as u32, q.z as u32), r)
        })
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, _, r)| r).collect()
}

/// Interleaves the low 21 bits of three coordinates.
fn morton3(x: u32, y: u32, z: u32) -> u64 {
    fn spread(v: u32) -> u64 {
        let mut v = u64::from(v) & 0x1f_ffff;
        v = (v | v << 32) & 0x1f_0000_0000_ffff;
        v = (v | v << 16) & 0x1f_0000_ff00_00ff;
        v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
        v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
        v = (v | v << 2) & 0x1249_2492_4924_9249;
        v
    }
    spread(x) | spread(y) << 1 | spread(z) << 2
}

/// What [`relayout`] does with mesh rep payloads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Payloads {
    /// Copied as they are.
    Keep,
    /// Compressed ([`engine::format::RepMesh::encode_compressed`]).
    Compressed,
    /// Stored raw (expanded if compressed).
    Raw,
}

/// Copies `src` into `sink` with its reps in [`file_order`]: the same
/// skeleton and meshes, new offsets (and, unless [`Payloads::Keep`], mesh
/// payloads re-encoded). Returns the sink (flushed).
pub fn relayout<S: ByteSource, W: Write + Seek>(
    src: &SceneFile<S>,
    sink: W,
    payloads: Payloads,
) -> Result<W, FormatError> {
    let mut skeleton = src.skeleton().clone();
    let mut writer = SceneWriter::new(sink)?;
    let mut buf = Vec::new();
    for r in file_order(&skeleton) {
        // A shared payload moves once, with its owner (placed below).
        if !skeleton.owns_payload(r) {
            continue;
        }
        let rec = &mut skeleton.reps[r as usize];
        // A tree rep moves whole: its in-core part and its paged part.
        buf.resize(rec.extent() as usize, 0);
        src.source().read_at(rec.offset, &mut buf)?;
        if rec.is_paged() || payloads == Payloads::Keep {
            // The same bytes (a tree's `len` and checksum cover only its
            // in-core part): only the offset changes.
            rec.offset = if rec.is_paged() {
                writer.write_tree_rep(&buf)?.offset
            } else {
                writer.write_rep(&buf)?.offset
            };
            continue;
        }
        let loc = {
            engine::format::check_rep_crc(r, rec, &buf)?;
            let mesh = RepMesh::decode(&buf, r, rec)?;
            let (node, index) = (rec.node, u32::from(rec.index));
            writer.write_rep(&match payloads {
                Payloads::Raw => mesh.encode(node, index),
                _ => mesh.encode_compressed(node, index),
            })?
        };
        (rec.offset, rec.len, rec.checksum) = (loc.offset, loc.len, loc.checksum);
    }
    follow_owners(&mut skeleton);
    writer.finish_with_sections(
        &skeleton,
        &src.meta(),
        &src.read_objects_bytes()?,
        &src.read_walk_bytes()?,
    )
}

/// Writes a scene whose reps lie in several files (a merged sharded build):
/// `skeleton`'s reps of node `i` are read from `sources[source_of_node[i]]`
/// at their offsets, checked, and written in [`file_order`] with the same
/// bytes, as [`relayout`] does with [`Payloads::Keep`]; then the object and
/// walk sections.
pub fn relayout_parts<S: ByteSource, W: Write + Seek>(
    skeleton: &Skeleton,
    source_of_node: &[usize],
    sources: &[S],
    meta: &engine::format::SceneMeta,
    (objects, walk): (&[u8], &[u8]),
    sink: W,
) -> Result<W, FormatError> {
    let mut skeleton = skeleton.clone();
    let mut writer = SceneWriter::new(sink)?;
    let mut buf = Vec::new();
    for r in file_order(&skeleton) {
        if !skeleton.owns_payload(r) {
            continue;
        }
        let rec = &mut skeleton.reps[r as usize];
        buf.resize(rec.extent() as usize, 0);
        sources[source_of_node[rec.node as usize]].read_at(rec.offset, &mut buf)?;
        rec.offset = if rec.is_paged() {
            // A tree's checksum covers its in-core part.
            engine::format::check_rep_crc(r, rec, &buf[..rec.len as usize])?;
            writer.write_tree_rep(&buf)?.offset
        } else {
            engine::format::check_rep_crc(r, rec, &buf)?;
            writer.write_rep(&buf)?.offset
        };
    }
    follow_owners(&mut skeleton);
    writer.finish_with_sections(&skeleton, meta, objects, walk)
}

/// Gives every rep that places a shared payload its owner's new range.
fn follow_owners(skeleton: &mut Skeleton) {
    for i in 0..skeleton.placements.len() {
        let p = skeleton.placements[i];
        let o = skeleton.reps[p.source as usize];
        let rec = &mut skeleton.reps[p.rep as usize];
        (rec.offset, rec.len, rec.checksum) = (o.offset, o.len, o.checksum);
    }
}

/// [`relayout`] from file `input` to file `output`, written atomically.
pub fn relayout_file(
    input: &std::path::Path,
    output: &std::path::Path,
    payloads: Payloads,
) -> Result<(), crate::BuildError> {
    let src = SceneFile::open(input).map_err(|source| crate::BuildError::Write {
        path: input.to_path_buf(),
        source,
    })?;
    engine_cli::outfile::write_with(output, &[input], |w| {
        relayout(&src, w, payloads)
            .map(|_| ())
            .map_err(std::io::Error::other)
    })
    .map_err(|source| crate::BuildError::Io {
        path: output.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_interleaves_bits() {
        assert_eq!(morton3(1, 0, 0), 1);
        assert_eq!(morton3(0, 1, 0), 2);
        assert_eq!(morton3(0, 0, 1), 4);
        assert_eq!(morton3(3, 0, 0), 0b1001);
        let m = morton3(0x1f_ffff, 0x1f_ffff, 0x1f_ffff);
        assert_eq!(m, (1u64 << 63) - 1);
    }
}
