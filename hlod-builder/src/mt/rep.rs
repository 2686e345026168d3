//! A large object's Multi-Triangulation as its finest object-rep, the
//! counterpart of [`crate::vdt::tree_levels`]: the object keeps its `keep`
//! coarsest static LODs and the MT replaces the finer ones. The MT file is
//! embedded whole; the record's `len` covers its in-core part (header,
//! directory, partition table), `aux` the node records, read partition by
//! partition at run time. The rep's error is that of the MT's coarsest cut,
//! kept under the finest static LOD's when written.

use engine::format::RepKind;

use super::{MtParams, build_mt};
use crate::lod::{Level, LodParams, lod_chain};
use crate::mesh::Mesh;
use crate::vdt::TreeRep;

/// Parameters of an MT rep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MtRepParams {
    pub mt: MtParams,
    /// Nodes per partition, at most (the paper: 50-100 for scenes of many
    /// objects).
    pub theta: u32,
}

impl Default for MtRepParams {
    fn default() -> Self {
        Self {
            mt: MtParams::default(),
            theta: 64,
        }
    }
}

/// The static levels kept for a large object and its MT (`None` when the
/// chain is too short for the MT to replace anything, or the mesh cannot
/// be built into one: it then keeps its whole chain).
pub fn mt_levels(
    mesh: &Mesh,
    lod: &LodParams,
    keep: usize,
    p: &MtRepParams,
) -> (Vec<Level>, Option<TreeRep>) {
    let mut chain = lod_chain(mesh, lod);
    if chain.len() <= keep {
        return (chain, None);
    }
    let built = build_mt(&mesh.positions, &mesh.normals, &mesh.indices, &p.mt)
        .map_err(|e| e.to_string())
        .and_then(|mt| mt.validate().map(|()| mt).map_err(|e| e.to_string()))
        .and_then(|mt| {
            let parts = engine::mt::partition(&mt, p.theta).map_err(|e| e.to_string())?;
            let bytes = engine::mt::file::encode(&mt, &parts).map_err(|e| e.to_string())?;
            Ok((mt, bytes))
        });
    let (mt, bytes) = match built {
        Ok(x) => x,
        Err(why) => {
            tracing::warn!(
                "no Multi-Triangulation for a large object ({why}): its static LODs stay"
            );
            return (chain, None);
        }
    };
    chain.truncate(keep);
    // The coarsest cut's error: the largest error below the root.
    let coarsest = mt.nodes[1..].iter().map(|n| n.error).fold(0.0f32, f32::max);
    let (bbox_min, bbox_max) = mesh.bounds().to_arrays();
    // The stored vertices are quantised over the object's box and drawn
    // as stored.
    let quantisation = crate::vdt::rep::box_quantisation(bbox_min, bbox_max);
    let core = bytemuck::pod_read_unaligned::<engine::mt::file::MtHeader>(&bytes[..136]).data_offset
        as usize;
    let rep = TreeRep {
        kind: RepKind::Mt,
        core,
        error: coarsest + quantisation,
        tri_count: mt.input_triangles as u32,
        vertex_count: mt.positions.len() as u32,
        bbox_min,
        bbox_max,
        bytes,
    };
    (chain, Some(rep))
}
