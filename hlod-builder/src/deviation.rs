//! The measured deviation of a simplified mesh from its input: a sampled,
//! symmetric Hausdorff distance (issue 21, item 5).
//!
//! meshopt's sloppy simplifier reports the size of its vertex clusters as
//! the error, but a thin member (a brace, a pipe, a rail) that collapses
//! inside one cluster disappears entirely: its points are then as far from
//! the simplified surface as the nearest *other* member, which can be
//! metres. A level whose error ignores that is drawn where the member still
//! covers pixels, and the member vanishes from the screen. The deviation
//! measured here — the largest distance from a sample of either mesh
//! (vertices and triangle centroids) to the other mesh's triangles — is
//! what the level's error must be at least, so that it is drawn only where
//! what vanished is within ε pixels.
//!
//! Nearest-triangle queries go through a BVH of the triangles (obvhs,
//! PLOC), searched branch and bound. At most [`MAX_SAMPLES`] samples per
//! direction, spread evenly, keep the cost bounded on large merges.

use std::time::Duration;

use glam::{DVec3, Vec3A};
use obvhs::{BvhBuildParams, aabb::Aabb as BvhAabb, bvh2::builder::build_bvh2};

use crate::mesh::Mesh;

/// Samples taken from each mesh, at most.
pub const MAX_SAMPLES: usize = 8192;

/// Meshes of at most this many triangles are searched without a BVH.
const BRUTE_FORCE_TRIS: usize = 64;

/// A mesh's triangles and a BVH over them, for nearest-point queries.
struct Triangles {
    tris: Vec<[Vec3A; 3]>,
    bvh: Option<obvhs::bvh2::Bvh2>,
}

impl Triangles {
    fn new(m: &Mesh) -> Self {
        let p = |i: u32| Vec3A::from(m.positions[i as usize]);
        let tris: Vec<[Vec3A; 3]> = m
            .indices
            .chunks_exact(3)
            .map(|t| [p(t[0]), p(t[1]), p(t[2])])
            .collect();
        if tris.len() <= BRUTE_FORCE_TRIS {
            return Self { tris, bvh: None };
        }
        let boxes: Vec<BvhAabb> = tris
            .iter()
            .map(|t| BvhAabb::new(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2])))
            .collect();
        let mut params = BvhBuildParams::fastest_build();
        params.max_prims_per_leaf = 4;
        let mut t = Duration::ZERO;
        let bvh = build_bvh2(&boxes, params, &mut t);
        Self {
            tris,
            bvh: Some(bvh),
        }
    }

    /// Squared distance from `p` to the nearest triangle (infinite when
    /// there is none), or any value at most `enough` as soon as one
    /// triangle is that near (the caller wants the largest distance of
    /// many points: one within the largest so far cannot change it).
    ///
    /// Consecutive samples lie close together, so the triangle and the leaf
    /// that ended the last search are tried first: most searches end there.
    /// (Stopping early changes no result: the minimum is the same in any
    /// order, and a value at most `enough` is all the caller needs.)
    fn nearest2(&self, p: Vec3A, enough: f32, q: &mut Query) -> f32 {
        let near = |t: u32| point_triangle2(p, &self.tris[t as usize]);
        // The triangle that ended the last search, first: often it ends this one.
        let mut best = q.last_tri.map_or(f32::INFINITY, near);
        if best <= enough {
            return best;
        }
        let Some(bvh) = self.bvh.as_ref().filter(|b| !b.nodes.is_empty()) else {
            for t in 0..self.tris.len() as u32 {
                best = best.min(near(t));
                if best <= enough {
                    q.last_tri = Some(t);
                    break;
                }
            }
            return best;
        };
        // A leaf's triangles until one is near enough (its index then).
        let leaf = |i: usize, best: &mut f32| {
            let node = &bvh.nodes[i];
            let f = node.first_index as usize;
            for &t in &bvh.primitive_indices[f..f + node.prim_count as usize] {
                *best = best.min(near(t));
                if *best <= enough {
                    return Some(t);
                }
            }
            None
        };
        if let Some(i) = q.last_leaf
            && let Some(t) = leaf(i, &mut best)
        {
            q.last_tri = Some(t);
            return best;
        }
        q.stack.clear();
        q.stack.push((0usize, 0.0f32));
        while let Some((i, d)) = q.stack.pop() {
            if d >= best {
                continue;
            }
            let node = &bvh.nodes[i];
            if node.is_leaf() {
                if let Some(t) = leaf(i, &mut best) {
                    (q.last_leaf, q.last_tri) = (Some(i), Some(t));
                    return best;
                }
                continue;
            }
            let (a, b) = (node.first_index as usize, node.first_index as usize + 1);
            let (da, db) = (box2(p, &bvh.nodes[a].aabb), box2(p, &bvh.nodes[b].aabb));
            // The nearer child is searched first (popped last).
            if da < db {
                q.stack.push((b, db));
                q.stack.push((a, da));
            } else {
                q.stack.push((a, da));
                q.stack.push((b, db));
            }
        }
        best
    }
}

/// A search's scratch state, kept from one sample to the next.
#[derive(Default)]
struct Query {
    stack: Vec<(usize, f32)>,
    /// The leaf that ended the last search early, and its triangle.
    last_leaf: Option<usize>,
    last_tri: Option<u32>,
}

fn box2(p: Vec3A, b: &BvhAabb) -> f32 {
    let d = (b.min - p).max(p - b.max).max(Vec3A::ZERO);
    d.length_squared()
}

/// Squared distance from `p` to triangle `t` (closest point by regions,
/// in f64: long thin triangles lose too much in f32).
fn point_triangle2(p: Vec3A, t: &[Vec3A; 3]) -> f32 {
    let d = |v: Vec3A| DVec3::new(f64::from(v.x), f64::from(v.y), f64::from(v.z));
    let (p, a, b, c) = (d(p), d(t[0]), d(t[1]), d(t[2]));
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    let out = |q: DVec3| (p - q).length_squared() as f32;
    if d1 <= 0.0 && d2 <= 0.0 {
        return out(a);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return out(b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return out(a + ab * (d1 / (d1 - d3)));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return out(c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return out(a + ac * (d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return out(b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE {
        // Degenerate: the nearest of its vertices.
        return out(a).min(out(b)).min(out(c));
    }
    out(a + ab * (vb / denom) + ac * (vc / denom))
}

/// Up to [`MAX_SAMPLES`] points of `m`: its vertices and triangle
/// centroids, evenly strided (deterministic).
fn samples(m: &Mesh) -> Vec<Vec3A> {
    let p = |i: u32| Vec3A::from(m.positions[i as usize]);
    let centroids = m
        .indices
        .chunks_exact(3)
        .map(|t| (p(t[0]) + p(t[1]) + p(t[2])) / 3.0);
    let used: Vec<Vec3A> = {
        let mut seen = vec![false; m.positions.len()];
        let mut v = Vec::new();
        for &i in &m.indices {
            if !std::mem::replace(&mut seen[i as usize], true) {
                v.push(p(i));
            }
        }
        v
    };
    let n = used.len() + m.tri_count();
    let stride = n.div_ceil(MAX_SAMPLES).max(1);
    used.into_iter().chain(centroids).step_by(stride).collect()
}

/// The largest distance from a sample of either mesh to the other's
/// triangles (0 when both are empty; infinite when only one is).
pub fn deviation(input: &Mesh, simplified: &Mesh) -> f32 {
    deviation_above(input, simplified, 0.0)
}

/// `floor.max(deviation(input, simplified))`, exactly, but faster: only a
/// sample farther than `floor` needs its exact nearest triangle, so the
/// searches start from `floor` instead of 0 and most end at the first leaf.
/// (The result is `floor` whenever no sample is farther: the square root of
/// a rounded square is the number itself, so nothing is lost by squaring.)
pub fn deviation_above(input: &Mesh, simplified: &Mesh, floor: f32) -> f32 {
    // Below the normal range squaring loses digits: start from 0 there.
    let start = if floor >= 1e-18 { floor * floor } else { 0.0 };
    let b = Triangles::new(simplified);
    let m = one_way2(input, &b, start);
    let a = Triangles::new(input);
    let m = one_way2(simplified, &a, m);
    if m > start {
        floor.max(m.sqrt())
    } else {
        floor.max(0.0)
    }
}

/// The largest distance from a sample of `from` to the triangles of `to`
/// (how far what `from` shows lies from what `to` draws).
pub fn distance_from(from: &Mesh, to: &Mesh) -> f32 {
    one_way2(from, &Triangles::new(to), 0.0).sqrt()
}

/// The largest of `start` and the samples' squared distances: exactly
/// whenever it is above `start` (a sample whose search stops early is
/// within the largest so far); at most `start` otherwise.
fn one_way2(from: &Mesh, to: &Triangles, start: f32) -> f32 {
    let mut q = Query::default();
    samples(from)
        .into_iter()
        .fold(start, |m, p| m.max(to.nearest2(p, m, &mut q)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenegen::shapes::ShapeBuilder;
    use glam::Vec3;

    fn bar(at: Vec3, len: f32) -> Mesh {
        let mut s = ShapeBuilder::new([255; 4]);
        s.beam(at, at + Vec3::X * len, Vec3::Y, 0.02, 0.02);
        s.mesh
    }

    #[test]
    fn a_vanished_member_costs_its_distance_to_what_is_left() {
        let mut both = bar(Vec3::ZERO, 4.0);
        both.append(&bar(Vec3::new(0.0, 3.0, 0.0), 4.0));
        let one = bar(Vec3::ZERO, 4.0);
        let d = deviation(&both, &one);
        // The upper bar's points are 3 m (less its thickness) from the lower.
        assert!((2.9..3.01).contains(&d), "{d}");
        // (Rounding of thin triangles: well below a millimetre.)
        assert!(deviation(&both, &both) < 1e-3);
        assert_eq!(deviation(&Mesh::default(), &Mesh::default()), 0.0);
        assert!(deviation(&both, &Mesh::default()).is_infinite());
    }

    #[test]
    fn a_floor_gives_the_same_number_as_the_max_with_it() {
        let mut both = bar(Vec3::ZERO, 4.0);
        both.append(&bar(Vec3::new(0.0, 3.0, 0.0), 4.0));
        both.append(&bar(Vec3::new(0.0, 0.5, 0.7), 2.0));
        let one = bar(Vec3::ZERO, 4.0);
        let d = deviation(&both, &one);
        for floor in [
            -1.0,
            0.0,
            1e-20,
            1e-3,
            0.1,
            0.7,
            2.5,
            d,
            d * 0.999,
            d * 1.001,
            4.0,
            1e30,
        ] {
            assert_eq!(deviation_above(&both, &one, floor), floor.max(d), "{floor}");
        }
        assert!(deviation_above(&both, &Mesh::default(), 1.0).is_infinite());
    }

    #[test]
    fn the_distance_to_a_triangle_is_the_distance_to_its_nearest_point() {
        let t = [Vec3A::ZERO, Vec3A::X, Vec3A::Y];
        let cases = [
            (Vec3A::new(0.25, 0.25, 2.0), 4.0), // above the face
            (Vec3A::new(-1.0, -1.0, 0.0), 2.0), // beyond vertex a
            (Vec3A::new(0.5, -2.0, 0.0), 4.0),  // beyond edge ab
            (Vec3A::new(1.0, 1.0, 0.0), 0.5),   // beyond edge bc
            (Vec3A::new(3.0, 0.0, 0.0), 4.0),   // beyond vertex b
        ];
        for (p, want) in cases {
            let d = point_triangle2(p, &t);
            assert!((d - want).abs() < 1e-5, "{p}: {d} != {want}");
        }
    }
}
