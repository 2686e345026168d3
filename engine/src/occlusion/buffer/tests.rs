use glam::Vec3;
use proptest::prelude::*;

use super::*;
use crate::camera::Pose;

fn view(w: u32, h: u32) -> View {
    View {
        // At the origin looking along -Z.
        pose: Pose::from_yaw_pitch(Vec3::ZERO, 0.0, 0.0, 60.0),
        width_px: w,
        height_px: h,
        near: 0.1,
        far: 1e4,
        section: crate::section::Section::NONE,
    }
}

/// A wall at depth `d` spanning `[x0, x1] x [y0, y1]`, as two triangles.
fn wall(x0: f32, x1: f32, y0: f32, y1: f32, d: f32) -> [[Vec3; 3]; 2] {
    let (a, b) = (Vec3::new(x0, y0, -d), Vec3::new(x1, y0, -d));
    let (c, e) = (Vec3::new(x1, y1, -d), Vec3::new(x0, y1, -d));
    [[a, b, c], [a, c, e]]
}

fn cube(c: Vec3, r: f32) -> (Vec3, Vec3) {
    (c - Vec3::splat(r), c + Vec3::splat(r))
}

#[test]
fn a_wall_hides_what_is_behind_it_and_nothing_else() {
    let v = view(64, 48);
    let mut b = OcclusionBuffer::new(&v);
    // Two triangles sharing a diagonal: together they cover every tile.
    for t in wall(-20.0, 20.0, -20.0, 20.0, 10.0) {
        b.add_triangle(t);
    }
    assert_eq!(b.covered_tiles(), 16 * 12);
    let (mn, mx) = cube(Vec3::new(0.0, 0.0, -20.0), 1.0);
    assert!(b.box_occluded(mn, mx));
    let (mn, mx) = cube(Vec3::new(0.0, 0.0, -5.0), 1.0);
    assert!(!b.box_occluded(mn, mx), "in front of the wall");
    let (mn, mx) = cube(Vec3::new(0.0, 0.0, -10.0), 1.0);
    assert!(!b.box_occluded(mn, mx), "through the wall");
    // Around the eye: never hidden.
    assert!(!b.box_occluded(Vec3::splat(-1.0), Vec3::splat(1.0)));
}

#[test]
fn a_gap_in_the_wall_shows_what_is_behind_it() {
    let v = view(64, 48);
    let mut b = OcclusionBuffer::new(&v);
    // Two walls with a door between x = -0.5 and 0.5 at depth 10.
    for t in wall(-20.0, -0.5, -20.0, 20.0, 10.0)
        .into_iter()
        .chain(wall(0.5, 20.0, -20.0, 20.0, 10.0))
    {
        b.add_triangle(t);
    }
    let (mn, mx) = cube(Vec3::new(0.0, 0.0, -30.0), 1.0);
    assert!(!b.box_occluded(mn, mx), "seen through the door");
    let (mn, mx) = cube(Vec3::new(-6.0, 0.0, -30.0), 1.0);
    assert!(b.box_occluded(mn, mx), "behind the left wall");
}

#[test]
fn a_wall_crossing_the_near_plane_still_occludes() {
    let v = view(64, 48);
    let mut b = OcclusionBuffer::new(&v);
    // A side wall from behind the eye to far ahead, on the left.
    let (p, q) = (Vec3::new(-1.0, -5.0, 5.0), Vec3::new(-1.0, 5.0, 5.0));
    let (r, s) = (Vec3::new(-1.0, 5.0, -100.0), Vec3::new(-1.0, -5.0, -100.0));
    b.add_triangle([p, q, r]);
    b.add_triangle([p, r, s]);
    let (mn, mx) = cube(Vec3::new(-6.0, 0.0, -10.0), 1.0);
    assert!(b.box_occluded(mn, mx), "the room beside the corridor");
    let (mn, mx) = cube(Vec3::new(2.0, 0.0, -10.0), 0.5);
    assert!(!b.box_occluded(mn, mx), "the corridor's other side");
}

/// Depth of triangle `t` (camera at the origin looking along -Z) through
/// the pixel centre `(x, y)`, if it covers it.
fn reference_depth(v: &View, t: &[Vec3; 3], x: f32, y: f32) -> Option<f32> {
    let (o, d) = v.pose.ray(v.width_px, v.height_px, x, y);
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-9 {
        return None;
    }
    let s = o - t[0];
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let w = d.dot(q) / det;
    let dist = e2.dot(q) / det;
    (u >= 0.0 && w >= 0.0 && u + w <= 1.0 && dist > 0.0).then(|| dist * d.dot(v.pose.forward()))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// A box is reported hidden only when, at every pixel centre its
    /// corners' screen rectangle holds, some triangle lies nearer than
    /// the box's nearest corner (ray-cast reference).
    #[test]
    fn hidden_means_behind_at_every_pixel(
        tris in prop::collection::vec(
            prop::array::uniform3((-8.0f32..8.0, -6.0f32..6.0, 2.0f32..20.0)), 1..12),
        c in (-6.0f32..6.0, -4.0f32..4.0, 3.0f32..30.0),
        r in 0.1f32..3.0,
        wall_at in prop::option::of((3.0f32..25.0, -4.0f32..4.0)),
    ) {
        let v = view(32, 24);
        let tris: Vec<[Vec3; 3]> = tris
            .iter()
            .map(|t| t.map(|(x, y, d)| Vec3::new(x * d / 6.0, y * d / 6.0, -d)))
            .collect();
        let mut tris = tris;
        if let Some((d, x)) = wall_at {
            // A wall over most of the view, its edge somewhere across it.
            tris.extend(wall(x * d / 6.0, 20.0 * d, -20.0 * d, 20.0 * d, d));
        }
        let mut b = OcclusionBuffer::new(&v);
        for t in &tris {
            b.add_triangle(*t);
        }
        let centre = Vec3::new(c.0 * c.2 / 6.0, c.1 * c.2 / 6.0, -c.2);
        let (mn, mx) = cube(centre, r);
        if b.box_occluded(mn, mx) {
            let near = c.2 - r;
            let mut lo = (f32::MAX, f32::MAX);
            let mut hi = (f32::MIN, f32::MIN);
            for k in 0..8 {
                let p = Vec3::new(
                    if k & 1 == 0 { mn.x } else { mx.x },
                    if k & 2 == 0 { mn.y } else { mx.y },
                    if k & 4 == 0 { mn.z } else { mx.z },
                );
                let (x, y, _) = v.pose.project(32, 24, p).unwrap();
                lo = (lo.0.min(x), lo.1.min(y));
                hi = (hi.0.max(x), hi.1.max(y));
            }
            for py in 0..24 {
                for px in 0..32 {
                    let (x, y) = (px as f32 + 0.5, py as f32 + 0.5);
                    if x < lo.0 || x > hi.0 || y < lo.1 || y > hi.1 {
                        continue;
                    }
                    let z = tris
                        .iter()
                        .filter_map(|t| reference_depth(&v, t, x, y))
                        .fold(f32::INFINITY, f32::min);
                    prop_assert!(z < near, "pixel ({px}, {py}): nearest occluder {z}, box from {near}");
                }
            }
        }
    }
}
