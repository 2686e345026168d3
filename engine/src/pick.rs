//! Picking: which source object a ray through a pixel hits first.
//!
//! Leaves whose box the ray enters are tried nearest first; each one's
//! finest static rep is read from the scene file (a transient read outside
//! the walkthrough's cache: picking is rare, and the footprint guarantee
//! concerns resident reps) and its triangles are intersected. The search
//! stops when the best hit is nearer than the next box. The object of the
//! hit triangle comes from the leaf's record, or for a merged leaf from the
//! object section's runs ([`ObjectTable::object_at`]).

use glam::Vec3;

use crate::format::objects::ObjectTable;
use crate::format::{FormatError, RepKind, SceneFile};
use crate::io::ByteSource;
use crate::section::Section;
use crate::skeleton::RepId;

/// What a ray hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// The leaf node.
    pub node: u32,
    /// The rep intersected (the leaf's finest static rep).
    pub rep: RepId,
    /// Triangle index within that rep.
    pub triangle: u32,
    /// Distance along the (unit) ray.
    pub t: f32,
    /// The hit point, in scene coordinates.
    pub point: Vec3,
    /// The source object, when the scene describes its objects.
    pub object: Option<u32>,
    /// The triangle's corners, in scene coordinates (for snapping).
    pub corners: [Vec3; 3],
}

/// Ray parameter interval inside the box, `None` when it misses.
pub fn ray_box(origin: Vec3, inv_dir: Vec3, min: Vec3, max: Vec3) -> Option<(f32, f32)> {
    let t1 = (min - origin) * inv_dir;
    let t2 = (max - origin) * inv_dir;
    let lo = t1.min(t2).max_element().max(0.0);
    let hi = t1.max(t2).min_element();
    (lo <= hi).then_some((lo, hi))
}

/// Möller–Trumbore, both faces: the distance along the ray, if it hits.
pub fn ray_triangle(origin: Vec3, dir: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Option<f32> {
    let e1 = b - a;
    let e2 = c - a;
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t > 0.0).then_some(t)
}

/// The nearest hit of the ray `origin + t * dir` (`dir` need not be unit)
/// against the leaves' finest static reps; `objects` resolves the object.
pub fn pick<S: ByteSource>(
    scene: &SceneFile<S>,
    objects: &ObjectTable,
    origin: Vec3,
    dir: Vec3,
) -> Result<Option<Hit>, FormatError> {
    pick_cut(scene, objects, origin, dir, (&Section::NONE, &|_| true))
}

/// [`pick`] in a model cut open by `section`, of the objects `shown`
/// keeps: what the cut removes and hidden objects are not hit.
pub fn pick_cut<S: ByteSource>(
    scene: &SceneFile<S>,
    objects: &ObjectTable,
    origin: Vec3,
    dir: Vec3,
    (section, shown): (&Section, &dyn Fn(u32) -> bool),
) -> Result<Option<Hit>, FormatError> {
    let dir = dir.normalize_or_zero();
    if dir == Vec3::ZERO || !origin.is_finite() {
        return Ok(None);
    }
    let inv = dir.recip();
    let s = scene.skeleton();
    let mut candidates: Vec<(f32, u32)> = s
        .nodes
        .iter()
        .enumerate()
        .filter(|(_, n)| n.is_leaf() && n.rep_count > 0)
        .filter(|(_, n)| section.keeps_box(n.bbox_min.into(), n.bbox_max.into()))
        .filter_map(|(i, n)| {
            ray_box(origin, inv, n.bbox_min.into(), n.bbox_max.into()).map(|(lo, _)| (lo, i as u32))
        })
        .collect();
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut best: Option<Hit> = None;
    for (entry, node) in candidates {
        if best.is_some_and(|b| b.t <= entry) {
            break;
        }
        let n = &s.nodes[node as usize];
        // The finest static rep (a view-dependence tree's coarser LODs
        // stand in for it).
        let Some(rep) = (n.first_rep..n.first_rep + n.rep_count)
            .rev()
            .find(|&r| s.reps[r as usize].rep_kind() == Some(RepKind::Lod))
        else {
            continue;
        };
        let mesh = scene.read_rep(rep)?;
        let pos: Vec<Vec3> = mesh
            .vertices
            .iter()
            .map(|v| mesh.position(v).into())
            .collect();
        for (k, t) in mesh.indices.chunks_exact(3).enumerate() {
            let Some(d) = ray_triangle(
                origin,
                dir,
                pos[t[0] as usize],
                pos[t[1] as usize],
                pos[t[2] as usize],
            ) else {
                continue;
            };
            let visible = || objects.object_at(s, node, k as u32).is_none_or(shown);
            if best.is_none_or(|b| d < b.t) && section.keeps(origin + dir * d) && visible() {
                best = Some(Hit {
                    node,
                    rep,
                    triangle: k as u32,
                    t: d,
                    point: origin + dir * d,
                    object: None,
                    corners: [pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize]],
                });
            }
        }
    }
    Ok(best.map(|h| Hit {
        object: objects.object_at(s, h.node, h.triangle),
        ..h
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::objects::ObjectTable;
    use crate::io::MemSource;
    use crate::testutil::build_with;

    #[test]
    fn the_nearest_leaf_under_the_ray_is_picked_with_its_object() {
        // Leaves k span x in [k, k+1], quads at z = 0.
        let infos: Vec<String> = (0..3)
            .map(|k| format!("{{\"name\":\"leaf {k}\"}}"))
            .collect();
        let (bytes, _) = build_with(
            &[1, 1, 1, 1],
            &[3, 0, 0, 0],
            [0.0; 3],
            &ObjectTable::encode(&infos, &[]),
        );
        let scene = SceneFile::from_source(MemSource::new(bytes)).unwrap();
        let table = scene.read_objects().unwrap();
        for k in 0..3 {
            let o = Vec3::new(k as f32 + 0.5, 0.4, 5.0);
            let hit = pick(&scene, &table, o, Vec3::NEG_Z).unwrap().unwrap();
            assert!((hit.t - 5.0).abs() < 1e-3, "{hit:?}");
            let obj = hit.object.unwrap();
            assert_eq!(
                table.info(obj),
                Some(format!("{{\"name\":\"leaf {obj}\"}}").as_str())
            );
            assert_eq!(obj, k, "{hit:?}");
        }
        // Beside everything, or looking away: nothing.
        assert!(
            pick(&scene, &table, Vec3::new(9.0, 0.5, 5.0), Vec3::NEG_Z)
                .unwrap()
                .is_none()
        );
        assert!(
            pick(&scene, &table, Vec3::new(0.5, 0.5, 5.0), Vec3::Z)
                .unwrap()
                .is_none()
        );
    }

    #[test]
    fn what_a_section_cuts_away_is_not_picked() {
        let (bytes, _) = build_with(&[1, 1, 1, 1], &[3, 0, 0, 0], [0.0; 3], &[]);
        let scene = SceneFile::from_source(MemSource::new(bytes)).unwrap();
        let table = scene.read_objects().unwrap();
        // Everything beyond x = 1.2 cut away: leaf 1 is cut, leaf 2 removed.
        let cut = Section::from_planes(&[(Vec3::new(1.2, 0.0, 0.0), Vec3::X)]).unwrap();
        let at = |x: f32, s: &Section| {
            pick_cut(
                &scene,
                &table,
                Vec3::new(x, 0.4, 5.0),
                Vec3::NEG_Z,
                (s, &|_| true),
            )
            .unwrap()
            .map(|h| h.node)
        };
        let leaf = |k: u32| Some(1 + k);
        assert_eq!(at(1.1, &cut), leaf(1));
        assert_eq!(at(1.5, &Section::NONE), leaf(1));
        assert_eq!(at(1.5, &cut), None);
        assert_eq!(at(2.5, &cut), None);
        assert_eq!(at(0.5, &cut), leaf(0));
    }

    #[test]
    fn triangle_and_box_tests_agree_with_simple_cases() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        assert!(ray_triangle(Vec3::new(0.2, 0.2, 1.0), Vec3::NEG_Z, a, b, c).is_some());
        assert!(ray_triangle(Vec3::new(0.2, 0.2, -1.0), Vec3::Z, a, b, c).is_some());
        assert!(ray_triangle(Vec3::new(0.8, 0.8, 1.0), Vec3::NEG_Z, a, b, c).is_none());
        let inv = Vec3::new(1.0, 0.0, 0.0).recip();
        assert_eq!(
            ray_box(Vec3::new(-1.0, 0.5, 0.5), inv, Vec3::ZERO, Vec3::ONE),
            Some((1.0, 2.0))
        );
        assert_eq!(
            ray_box(Vec3::new(-1.0, 1.5, 0.5), inv, Vec3::ZERO, Vec3::ONE),
            None
        );
    }
}
