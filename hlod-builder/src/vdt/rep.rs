//! A large object's view-dependence tree as its finest object-rep.
//!
//! The object keeps its `keep` coarsest static LODs as coarser reps and the
//! tree replaces the finer ones; it is built only up to the error of the
//! finest static LOD kept (collapses stop there), so its coarsest switch value — the rep's
//! error — sits below that LOD's and errors stay strictly decreasing along
//! PAR/CHD. The tree is embedded in the scene file as a whole `.vdt` file:
//! the record's `len` covers its in-core part and root meta-nodes (what the
//! coarsest level needs: P_I loads it like any rep), `aux` the other
//! meta-nodes and the flat layout, paged at run time.

use std::io::{Seek, Write};

use engine::format::{RepKind, RepMesh, RepRecord, SceneWriter};
use engine::vdt::file::encode;
use engine::vdt::meta::levels_for_block;
use engine::{FormatError, format::BLOCK};

use super::{Metric, VdtParams, build_tree};
use crate::lod::{Level, LodParams, lod_chain};
use crate::mesh::Mesh;

/// A built paged rep (a view-dependence tree or a Multi-Triangulation),
/// ready to be written.
#[derive(Debug)]
pub struct TreeRep {
    /// [`RepKind::Vdt`] or [`RepKind::Mt`].
    pub kind: RepKind,
    /// The encoded `.vdt` or MT file.
    pub bytes: Vec<u8>,
    /// Bytes of its in-core part (the record's `len`).
    pub core: usize,
    /// The tree's coarsest switch value plus the quantisation error of
    /// drawing it over its box.
    pub error: f32,
    pub tri_count: u32,
    pub vertex_count: u32,
    pub bbox_min: [f32; 3],
    pub bbox_max: [f32; 3],
}

/// The static levels kept for a large object and its tree (`None` when the
/// chain is too short for the tree to replace anything).
pub fn tree_levels(mesh: &Mesh, lod: &LodParams, keep: usize) -> (Vec<Level>, Option<TreeRep>) {
    let mut chain = lod_chain(mesh, lod);
    if chain.len() <= keep {
        return (chain, None);
    }
    chain.truncate(keep);
    let limit = chain.last().expect("one level kept").error;
    let tree = build_tree(
        &mesh.positions,
        &mesh.indices,
        &VdtParams {
            metric: Metric::Quadric,
            max_switch: Some(limit),
        },
    );
    if tree.triangles.is_empty() {
        return (chain, None);
    }
    let coarsest = tree
        .roots
        .iter()
        .map(|&r| tree.nodes[r as usize].switch)
        .fold(0.0f32, f32::max);
    let (bbox_min, bbox_max) = mesh.bounds().to_arrays();
    let quantisation = box_quantisation(bbox_min, bbox_max);
    let bytes = encode(&tree, levels_for_block(BLOCK as usize));
    let core = engine::vdt::file::VdtHeader::rep_len(&bytes)
        .expect("an encoded tree has a header and its roots");
    let rep = TreeRep {
        kind: RepKind::Vdt,
        bytes,
        core,
        error: coarsest + quantisation,
        tri_count: tree.triangles.len() as u32,
        vertex_count: tree.positions.len() as u32,
        bbox_min,
        bbox_max,
    };
    (chain, Some(rep))
}

/// The codec's own error for a mesh spanning the box `min..max` (a paged
/// rep's drawn cut spans at most its object's box).
pub(crate) fn box_quantisation(min: [f32; 3], max: [f32; 3]) -> f32 {
    RepMesh::quantize(&[min, max], &[[0.0; 3]; 2], &[[0; 4]; 2], Vec::new()).quantization_error()
}

/// Writes the tree (or MT) after the node's static reps `below` (coarsest first) and
/// returns its record, its error kept strictly under the finest static one.
pub fn write_rep<W: Write + Seek>(
    writer: &mut SceneWriter<W>,
    node: u32,
    below: &[RepRecord],
    t: &TreeRep,
) -> Result<RepRecord, FormatError> {
    let finest = below.last().map_or(f32::INFINITY, |r| r.error);
    let core = t.core;
    let loc = writer.write_tree_rep(&t.bytes)?;
    let error = if t.error < finest {
        t.error
    } else {
        finest.next_down().max(0.0)
    };
    Ok(RepRecord {
        bbox_min: t.bbox_min,
        bbox_max: t.bbox_max,
        node,
        index: below.len() as u16,
        kind: t.kind as u16,
        error,
        checksum: crc32fast::hash(&t.bytes[..core]),
        offset: loc.offset,
        len: core as u32,
        tri_count: t.tri_count,
        vertex_count: t.vertex_count,
        aux: (t.bytes.len() - core) as u32,
    })
}
