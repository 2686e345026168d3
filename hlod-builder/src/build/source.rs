//! Where a build's geometry comes from, and the leaf items made of it.
//!
//! A [`SceneSource`] is an imported scene held in memory ([`Imported`]) or
//! one opened lazily ([`Opened`], read mesh by mesh). The build first makes
//! its items (objects and chunks) from sizes and boxes alone, loading only
//! the objects it splits or gives a tree; then, cell by cell, a
//! [`CellGeometry`] holds the geometry of one cell's leaves and nothing else.

use std::borrow::Cow;
use std::collections::BTreeMap;

use engine::FormatError;
use rayon::prelude::*;

use super::BuildParams;
use super::leaf::{Item, transformed_bounds};
use crate::cluster::ClusterItem;
use crate::import::{Imported, Opened};
use crate::mesh::Mesh;

/// A scene to build: its objects, and its meshes on request.
pub trait SceneSource: Sync {
    fn scene(&self) -> &Imported;
    /// Usable mesh `m` in its local space.
    fn mesh(&self, m: usize) -> Result<Cow<'_, Mesh>, FormatError>;
}

impl SceneSource for Imported {
    fn scene(&self) -> &Imported {
        self
    }
    fn mesh(&self, m: usize) -> Result<Cow<'_, Mesh>, FormatError> {
        Ok(Cow::Borrowed(
            self.meshes[m]
                .as_ref()
                .expect("instances refer to usable meshes"),
        ))
    }
}

impl SceneSource for Opened {
    fn scene(&self) -> &Imported {
        &self.scene
    }
    fn mesh(&self, m: usize) -> Result<Cow<'_, Mesh>, FormatError> {
        let io = |what: String| FormatError::Io(std::io::Error::other(what));
        match Opened::mesh(self, m) {
            Ok(Some(mesh)) => Ok(Cow::Owned(mesh)),
            Ok(None) => Err(io(format!(
                "{}: meshes[{m}] has no usable triangles now, though it had when opened \
                 (was the file changed during the build?)",
                self.path().display()
            ))),
            Err(e) => Err(io(e.to_string())),
        }
    }
}

/// The leaf items and what clustering needs of each.
pub(super) struct Items {
    pub items: Vec<Item>,
    pub cluster: Vec<ClusterItem>,
    pub chunked_objects: u64,
    pub hidden_objects: u64,
    pub hidden_triangles: u64,
}

/// Object `o`'s mesh in world (scene) space.
fn world_mesh<S: SceneSource>(src: &S, o: u32) -> Result<Mesh, FormatError> {
    let inst = &src.scene().instances[o as usize];
    Ok(src.mesh(inst.mesh)?.transformed(&inst.transform))
}

/// Chunks of object `o` (split in world space, deterministically).
fn chunks_of<S: SceneSource>(
    src: &S,
    o: u32,
    params: &BuildParams,
) -> Result<Vec<Mesh>, FormatError> {
    Ok(world_mesh(src, o)?.split_spatial(params.chunk_tris))
}

/// Whether the finest reps draw `inst`: IFC voids and spaces are left out
/// (unless `--ifc-voids`, or unless they are all the scene has).
pub(crate) fn drawn(
    scene: &Imported,
    params: &BuildParams,
) -> impl Fn(&crate::import::Instance) -> bool + Sync {
    let hide =
        move |i: &crate::import::Instance| !params.ifc_voids && crate::import::ifc_void(&i.name);
    let hide_any = scene.instances.iter().any(|i| !hide(i));
    move |i| !(hide_any && hide(i))
}

/// Items from every object: an instance of its mesh, chunks of a large
/// one, or a large one whose finest rep is a tree or an MT. Only split and
/// tree objects are loaded (one at a time), for their exact world boxes.
pub(super) fn make_items<S: SceneSource>(
    src: &S,
    params: &BuildParams,
) -> Result<Items, FormatError> {
    let scene = src.scene();
    let mut out = Items {
        items: Vec::new(),
        cluster: Vec::new(),
        chunked_objects: 0,
        hidden_objects: 0,
        hidden_triangles: 0,
    };
    // IFC voids and spaces are left out (they stay in the object section,
    // with no geometry), unless they are all the scene has.
    let draws = drawn(scene, params);
    for (obj, inst) in scene.instances.iter().enumerate() {
        let object = obj as u32;
        let meta = scene.meta[inst.mesh].expect("instances refer to usable meshes");
        if !draws(inst) {
            out.hidden_objects += 1;
            out.hidden_triangles += meta.tris as u64;
            continue;
        }
        let mt = params.mt_tris > 0 && meta.tris >= params.mt_tris;
        if mt || (params.vdt_tris > 0 && meta.tris >= params.vdt_tris) {
            let world = world_mesh(src, object)?;
            out.cluster.push(ClusterItem {
                bounds: world.bounds(),
                tris: world.tri_count(),
            });
            out.items.push(Item::Tree { object, mt });
        } else if meta.tris > params.chunk_tris {
            out.chunked_objects += 1;
            for (k, chunk) in chunks_of(src, object, params)?.iter().enumerate() {
                out.cluster.push(ClusterItem {
                    bounds: chunk.bounds(),
                    tris: chunk.tri_count(),
                });
                out.items.push(Item::Chunk {
                    object,
                    chunk: k as u32,
                });
            }
        } else {
            out.cluster.push(ClusterItem {
                bounds: transformed_bounds(meta.bounds, &inst.transform),
                tris: meta.tris,
            });
            out.items.push(Item::Instance {
                mesh: inst.mesh,
                transform: inst.transform,
                object,
            });
        }
    }
    Ok(out)
}

/// The geometry of one cell's leaves: the meshes its instances place, its
/// chunks and its tree objects in world space.
#[derive(Default)]
pub(super) struct CellGeometry<'a> {
    meshes: BTreeMap<usize, Cow<'a, Mesh>>,
    chunks: BTreeMap<(u32, u32), Mesh>,
    trees: BTreeMap<u32, Mesh>,
}

impl<'a> CellGeometry<'a> {
    /// Loads what `items` (the items of a cell's leaves) need.
    pub fn load<S: SceneSource>(
        src: &'a S,
        items: impl IntoIterator<Item = &'a Item>,
        params: &BuildParams,
    ) -> Result<Self, FormatError> {
        let mut meshes = Vec::new();
        let mut trees = Vec::new();
        let mut chunk_objects: BTreeMap<u32, Vec<u32>> = BTreeMap::new();
        for item in items {
            match *item {
                Item::Instance { mesh, .. } => meshes.push(mesh),
                Item::Chunk { object, chunk } => {
                    chunk_objects.entry(object).or_default().push(chunk);
                }
                Item::Tree { object, .. } => trees.push(object),
            }
        }
        meshes.sort_unstable();
        meshes.dedup();
        // Read and decoded in parallel; the first error in order is the one
        // reported, whatever the threads' timing.
        let loaded: Vec<Result<Cow<'a, Mesh>, FormatError>> =
            meshes.par_iter().map(|&m| src.mesh(m)).collect();
        let mut g = CellGeometry::default();
        for (m, mesh) in meshes.into_iter().zip(loaded) {
            g.meshes.insert(m, mesh?);
        }
        let worlds: Vec<Result<Mesh, FormatError>> =
            trees.par_iter().map(|&o| world_mesh(src, o)).collect();
        for (o, mesh) in trees.into_iter().zip(worlds) {
            g.trees.insert(o, mesh?);
        }
        for (object, wanted) in chunk_objects {
            for (k, chunk) in chunks_of(src, object, params)?.into_iter().enumerate() {
                if wanted.contains(&(k as u32)) {
                    g.chunks.insert((object, k as u32), chunk);
                }
            }
        }
        Ok(g)
    }

    /// Mesh `m` in its local space.
    pub fn mesh(&self, m: usize) -> &Mesh {
        &self.meshes[&m]
    }

    /// An item's geometry in world space (an instance's placed).
    pub fn world(&self, item: &Item) -> Cow<'_, Mesh> {
        match *item {
            Item::Instance {
                mesh, transform, ..
            } => Cow::Owned(self.mesh(mesh).transformed(&transform)),
            Item::Chunk { object, chunk } => Cow::Borrowed(&self.chunks[&(object, chunk)]),
            Item::Tree { object, .. } => Cow::Borrowed(&self.trees[&object]),
        }
    }
}
