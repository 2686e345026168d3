//! Element picking in the viewer: a click casts a ray through the pixel
//! ([`engine::pick`]) and the object section of the scene file names what
//! it hit (glTF node and mesh names, `extras`, the world-space box).

use std::path::Path;

use anyhow::{Context, Result};
use engine::format::objects::ObjectTable;
use engine::{ByteSource, SceneFile};
use engine_cli::SceneHandle;
use glam::Vec3;
use serde_json::Value;

/// The scene file and its object section, opened at the first pick.
pub struct Picker {
    scene: SceneFile<std::sync::Arc<dyn ByteSource>>,
    objects: ObjectTable,
    /// The first leaf drawing each object ([`engine::tree::first_leaves`]).
    leaves: Vec<u32>,
}

/// What a click selected.
#[derive(Clone, Debug, PartialEq)]
pub struct Selection {
    pub object: Option<u32>,
    pub node: u32,
    /// The glTF node's name (or `nodes[i]`); the leaf's number when the
    /// scene describes no objects (a version-1 file).
    pub name: String,
    pub mesh_name: Option<String>,
    /// The node's `extras` (IFC exports carry GlobalId and type there), as JSON text.
    pub extras: Option<String>,
    /// World-space box.
    pub world_min: [f64; 3],
    pub world_max: [f64; 3],
    /// The same box in scene coordinates, for the highlight.
    pub scene_min: Vec3,
    pub scene_max: Vec3,
    /// The hit point in world coordinates.
    pub point: [f64; 3],
    /// The hit point and the hit triangle's corners, in scene coordinates
    /// (for measuring).
    pub scene_point: Vec3,
    pub corners: [Vec3; 3],
}

impl Picker {
    /// The scene's object section.
    pub fn objects(&self) -> &ObjectTable {
        &self.objects
    }

    /// Which objects some leaf draws (the others the build left out).
    pub fn drawn(&self) -> Vec<bool> {
        self.leaves
            .iter()
            .map(|&l| l != engine::format::NONE)
            .collect()
    }

    /// Object `k`'s GlobalId, if its description carries one.
    pub fn global_id(&self, k: u32) -> Option<String> {
        let id = engine::tree::Described::parse(self.objects.info(k)?).global_id;
        (!id.is_empty()).then_some(id)
    }

    pub fn open(path: &Path, handle: &SceneHandle) -> Result<Self> {
        let named = || path.display().to_string();
        let src = handle.raw().with_context(named)?;
        let scene = SceneFile::from_source(src).with_context(named)?;
        let objects = scene.read_objects().with_context(named)?;
        let leaves = engine::tree::first_leaves(scene.skeleton(), &objects);
        Ok(Self {
            scene,
            objects,
            leaves,
        })
    }

    /// The element under pixel `(x, y)` of a `size` viewport seen from
    /// `pose`, in the model cut open by `section`, hidden and x-rayed
    /// objects left out (one sees and picks through them).
    pub fn pick(
        &self,
        pose: &engine::camera::Pose,
        size: (u32, u32),
        x: f32,
        y: f32,
        (origin, section, looks): ([f64; 3], &engine::section::Section, &[engine::tree::Look]),
    ) -> Result<Option<Selection>> {
        let (o, d) = pose.ray(size.0, size.1, x, y);
        let shown = |k: u32| {
            looks.get(k as usize).copied().unwrap_or_default() == engine::tree::Look::Shown
        };
        let cut = (section, &shown as &dyn Fn(u32) -> bool);
        let Some(hit) = engine::pick::pick_cut(&self.scene, &self.objects, o, d, cut)? else {
            return Ok(None);
        };
        let sel = self.selection(hit.object, hit.node, origin);
        Ok(Some(Selection {
            point: world_of(hit.point, origin),
            scene_point: hit.point,
            corners: hit.corners,
            ..sel
        }))
    }

    /// Object `object` (found at leaf `node`) as a selection, its box from
    /// its description (else the node's), its point the box's centre.
    fn selection(&self, object: Option<u32>, node: u32, origin: [f64; 3]) -> Selection {
        let n = &self.scene.skeleton().nodes[node as usize];
        let (mut smin, mut smax) = (Vec3::from(n.bbox_min), Vec3::from(n.bbox_max));
        let info: Option<Value> = object
            .and_then(|k| self.objects.info(k))
            .and_then(|t| serde_json::from_str(t).ok());
        let field = |k: &str| info.as_ref().and_then(|v| v.get(k));
        let boxed = |k: &str| -> Option<[f64; 3]> {
            let a = field(k)?.as_array()?;
            Some([
                a.first()?.as_f64()?,
                a.get(1)?.as_f64()?,
                a.get(2)?.as_f64()?,
            ])
        };
        let (wmin, wmax) = match (boxed("box_min"), boxed("box_max")) {
            (Some(a), Some(b)) => {
                let s = |w: [f64; 3]| {
                    Vec3::new(
                        (w[0] - origin[0]) as f32,
                        (w[1] - origin[1]) as f32,
                        (w[2] - origin[2]) as f32,
                    )
                };
                (smin, smax) = (s(a), s(b));
                (a, b)
            }
            _ => (world_of(smin, origin), world_of(smax, origin)),
        };
        let name = field("name")
            .and_then(Value::as_str)
            .map(str::to_string)
            .unwrap_or_else(|| match object {
                Some(k) => format!("object {k}"),
                None => format!("leaf node {node}"),
            });
        let centre = (smin + smax) * 0.5;
        Selection {
            object,
            node,
            name,
            mesh_name: field("mesh_name")
                .and_then(Value::as_str)
                .map(str::to_string),
            extras: field("extras").map(Value::to_string),
            world_min: wmin,
            world_max: wmax,
            scene_min: smin,
            scene_max: smax,
            point: world_of(centre, origin),
            scene_point: centre,
            corners: [centre; 3],
        }
    }

    /// The elements whose name, mesh name, `extras` (IFC type, GlobalId)
    /// contain `text` (ignoring case), in object order, as selections.
    pub fn find(&self, text: &str, origin: [f64; 3]) -> Vec<Selection> {
        let needle = text.trim().to_lowercase();
        if needle.is_empty() {
            return Vec::new();
        }
        let leaf = &self.leaves;
        (0..self.objects.len() as u32)
            .filter(|&k| leaf[k as usize] != engine::format::NONE)
            .filter(|&k| {
                self.objects
                    .info(k)
                    .is_some_and(|t| t.to_lowercase().contains(&needle))
            })
            .map(|k| self.selection(Some(k), leaf[k as usize], origin))
            .collect()
    }

    /// Object `k` as a selection (`None`: no leaf draws it).
    pub fn select(&self, k: u32, origin: [f64; 3]) -> Option<Selection> {
        let leaf = *self.leaves.get(k as usize)?;
        (leaf != engine::format::NONE).then(|| self.selection(Some(k), leaf, origin))
    }
}

/// A scene point in world coordinates.
fn world_of(p: Vec3, origin: [f64; 3]) -> [f64; 3] {
    let p = p.as_dvec3();
    [p.x + origin[0], p.y + origin[1], p.z + origin[2]]
}

/// The twelve edges of a box as pixel segments of the view from `pose`
/// (edges crossing behind the eye are clipped to a near plane).
pub fn box_edges(
    pose: &engine::camera::Pose,
    size: (u32, u32),
    min: Vec3,
    max: Vec3,
) -> Vec<[(f32, f32); 2]> {
    let corner = |k: usize| {
        Vec3::new(
            if k & 1 == 0 { min.x } else { max.x },
            if k & 2 == 0 { min.y } else { max.y },
            if k & 4 == 0 { min.z } else { max.z },
        )
    };
    let near = 1e-3 * (max - min).length().max(1e-3);
    let depth = |p: Vec3| (p - pose.position).dot(pose.forward());
    let mut out = Vec::new();
    for a in 0..8usize {
        for bit in [1, 2, 4] {
            let b = a | bit;
            if b == a {
                continue;
            }
            let (mut p, mut q) = (corner(a), corner(b));
            let (dp, dq) = (depth(p), depth(q));
            if dp < near && dq < near {
                continue;
            }
            // Clip the part behind the near plane.
            if dp < near {
                p = p + (q - p) * ((near - dp) / (dq - dp));
            } else if dq < near {
                q = q + (p - q) * ((near - dq) / (dp - dq));
            }
            if let (Some(s), Some(t)) = (
                pose.project(size.0, size.1, p),
                pose.project(size.0, size.1, q),
            ) {
                out.push([(s.0, s.1), (t.0, t.1)]);
            }
        }
    }
    out
}
