//! Leaf items and their geometry: the objects and chunks a leaf holds, the
//! LOD chain of a leaf (a shared mesh's chain placed, a chunk's with locked
//! borders, a merged leaf's with each object optimised on its own so that
//! its triangles stay one run), and the object section's entries.

use engine::format::objects::Run;
use glam::{Mat3, Mat4};

use super::BuildParams;
use super::source::CellGeometry;
use crate::import::Imported;
use crate::lod::{LodParams, lod_chain, lod_chain_from, optimize};
use crate::mesh::{Aabb, Mesh};

/// A leaf item: one instance, or one chunk of a large object.
pub(super) enum Item {
    Instance {
        mesh: usize,
        transform: Mat4,
        object: u32,
    },
    /// Chunk `chunk` of the object's world-space mesh split spatially.
    Chunk { object: u32, chunk: u32 },
    /// A large object (in world space), whose finest rep is a view-dependence
    /// tree (or a Multi-Triangulation, with `mt`).
    Tree { object: u32, mt: bool },
}

pub(super) fn item_object(item: &Item) -> u32 {
    match item {
        Item::Instance { object, .. } | Item::Chunk { object, .. } | Item::Tree { object, .. } => {
            *object
        }
    }
}

/// Each object's JSON text for the object section: names, extras, and its
/// world-space box (scene box plus origin).
pub(super) fn object_infos(imported: &Imported) -> Vec<String> {
    let o = glam::DVec3::from(imported.origin);
    imported
        .instances
        .iter()
        .enumerate()
        .map(|(k, inst)| {
            let mut v = imported.object_info(k);
            if let (Some(m), serde_json::Value::Object(map)) = (&imported.meta[inst.mesh], &mut v) {
                let b = transformed_bounds(m.bounds, &inst.transform);
                let w = |p: glam::Vec3| (p.as_dvec3() + o).to_array().to_vec();
                map.insert("box_min".into(), w(b.min).into());
                map.insert("box_max".into(), w(b.max).into());
            }
            v.to_string()
        })
        .collect()
}

/// A leaf's static LODs (coarsest first), its view-dependence tree, and
/// for a merged leaf the object of each run of its finest rep's triangles.
pub(super) type LeafGeometry = (
    Vec<crate::lod::Level>,
    Option<crate::vdt::TreeRep>,
    Option<Vec<Run>>,
);

/// The LOD chain of a leaf, in world space, coarsest first, and the tree of
/// a large object.
pub(super) fn leaf_levels<'a>(
    leaf_items: &[u32],
    items: &[Item],
    geo: &CellGeometry<'_>,
    params: &BuildParams,
    chain_of: &(dyn Fn(usize) -> Option<&'a Vec<crate::lod::Level>> + Sync),
) -> LeafGeometry {
    if let [k] = leaf_items {
        match &items[*k as usize] {
            Item::Instance {
                mesh, transform, ..
            } => {
                let scale = max_scale(transform);
                let local;
                let chain = match chain_of(*mesh) {
                    Some(c) => c,
                    None => {
                        local = lod_chain(geo.mesh(*mesh), &params.lod);
                        &local
                    }
                };
                let levels = chain
                    .iter()
                    .map(|l| crate::lod::Level {
                        mesh: l.mesh.transformed(transform),
                        error: l.error * scale,
                    })
                    .collect();
                return (levels, None, None);
            }
            item @ Item::Chunk { .. } => {
                let lod = LodParams {
                    lock_border: true,
                    ..params.lod
                };
                return (lod_chain(&geo.world(item), &lod), None, None);
            }
            item @ Item::Tree { mt, .. } => {
                let world = geo.world(item);
                let mesh = &*world;
                let (levels, tree) = if *mt {
                    crate::mt::mt_levels(mesh, &params.lod, params.vdt_keep, &params.mt)
                } else {
                    crate::vdt::tree_levels(mesh, &params.lod, params.vdt_keep)
                };
                return (levels, tree, None);
            }
        }
    }
    let parts: Vec<Mesh> = leaf_items
        .iter()
        .map(|&k| geo.world(&items[k as usize]).into_owned())
        .collect();
    // Each object optimised on its own, so that its triangles stay one run
    // of the finest rep (what picking resolves a merged leaf's hit by).
    let optimized: Vec<Mesh> = parts.iter().map(optimize).collect();
    let runs = runs_of(
        (leaf_items.iter().zip(&optimized))
            .map(|(&k, m)| (item_object(&items[k as usize]), m.tri_count() as u32)),
    );
    (
        lod_chain_from(Mesh::merge(&optimized), &params.lod),
        None,
        Some(runs),
    )
}

/// The runs of a merged leaf's finest level from its objects' triangle
/// counts, in the level's order (an object's consecutive items one run).
pub(super) fn runs_of(objects: impl IntoIterator<Item = (u32, u32)>) -> Vec<Run> {
    let mut runs: Vec<Run> = Vec::new();
    let mut end = 0u32;
    for (object, tris) in objects {
        end += tris;
        match runs.last_mut() {
            Some(r) if r.object == object => r.tri_end = end,
            _ => runs.push(Run {
                object,
                tri_end: end,
            }),
        }
    }
    runs
}

pub(crate) fn transformed_bounds(b: Aabb, m: &Mat4) -> Aabb {
    let mut out = Aabb::EMPTY;
    for p in b.corners() {
        out.add(m.transform_point3(p));
    }
    out
}

/// Largest stretch of the transform's linear part (scales object-space errors).
pub(super) fn max_scale(m: &Mat4) -> f32 {
    let l = Mat3::from_mat4(*m);
    l.x_axis
        .length()
        .max(l.y_axis.length())
        .max(l.z_axis.length())
}
