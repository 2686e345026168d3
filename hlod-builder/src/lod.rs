//! Static LOD chains and HLODs with meshopt.
//!
//! A chain is made by simplifying each level from the previous one, so a
//! level's object-space error is the sum of the steps' errors (an upper bound
//! on its distance from the original). Topology-preserving `simplify` is tried
//! first; when it stalls, `simplify_sloppy` makes the drastic levels. A
//! step's error is the larger of meshopt's estimate and the deviation
//! measured between the two meshes ([`crate::deviation`]): the estimate
//! misses members that collapse away whole, and a level that hides them
//! must not be drawn where they still cover pixels.

use meshopt::SimplifyOptions;

use crate::mesh::Mesh;

/// Bumped whenever the same input and parameters simplify to different
/// levels (the build cache's key holds it). 2: sloppy levels' errors are at
/// least their measured deviation ([`crate::deviation`]).
pub const SIMPLIFICATION_REVISION: u32 = 2;

/// Parameters of LOD and HLOD construction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodParams {
    /// Target triangle ratio between successive levels.
    pub ratio: f32,
    /// No level below this many triangles.
    pub min_tris: usize,
    /// At most this many levels, the original included.
    pub max_levels: usize,
    /// Stop when a level keeps more than this fraction of the previous one.
    pub max_keep: f32,
    /// Lock open borders (chunks of one object stay crack-free).
    pub lock_border: bool,
}

impl Default for LodParams {
    fn default() -> Self {
        Self {
            ratio: 0.25,
            min_tris: 16,
            max_levels: 6,
            max_keep: 0.8,
            lock_border: false,
        }
    }
}

/// One level: geometry and its object-space error (simplification only).
#[derive(Clone, Debug)]
pub struct Level {
    pub mesh: Mesh,
    pub error: f32,
}

/// Reorders for the post-transform cache, then vertices by first use (the
/// vertex-fetch order), dropping unused ones.
pub fn optimize(mesh: &Mesh) -> Mesh {
    let mut m = Mesh {
        indices: meshopt::optimize_vertex_cache(&mesh.indices, mesh.vertex_count()),
        ..mesh.clone()
    };
    m = m.subset(0..m.tri_count());
    m
}

/// Simplifies towards `target` triangles. Returns the result and its error in
/// the mesh's units, or `None` when nothing could be removed.
pub fn simplify(
    mesh: &Mesh,
    target: usize,
    lock_border: bool,
    allow_sloppy: bool,
) -> Option<(Mesh, f32)> {
    let positions: &[u8] = bytemuck::cast_slice(&mesh.positions);
    let adapter = meshopt::VertexDataAdapter::new(positions, 12, 0).ok()?;
    let mut options = SimplifyOptions::ErrorAbsolute;
    if lock_border {
        options |= SimplifyOptions::LockBorder;
    }
    let mut err = 0f32;
    let mut idx = meshopt::simplify(
        &mesh.indices,
        &adapter,
        target * 3,
        f32::MAX,
        options,
        Some(&mut err),
    );
    if allow_sloppy && idx.len() > target * 3 * 3 / 2 {
        let mut rel = 0f32;
        let sloppy =
            meshopt::simplify_sloppy(&mesh.indices, &adapter, target * 3, 1.0, Some(&mut rel));
        if !sloppy.is_empty() && sloppy.len() < idx.len() {
            idx = sloppy;
            err = rel * meshopt::simplify_scale(&adapter);
        }
    }
    if idx.is_empty() || idx.len() >= mesh.indices.len() || !err.is_finite() {
        return None;
    }
    let m = Mesh {
        indices: idx,
        ..mesh.clone()
    };
    // meshopt's estimate misses what collapsed away whole (a sloppy
    // cluster's thin member, a brace folded into its leg): the measured
    // deviation does not.
    err = crate::deviation::deviation_above(mesh, &m, err);
    if !err.is_finite() {
        return None;
    }
    Some((optimize(&m), err.max(0.0)))
}

/// The LOD chain of `mesh`, coarsest first, the (optimised) original last with
/// error 0. Errors strictly decrease from coarse to fine.
pub fn lod_chain(mesh: &Mesh, p: &LodParams) -> Vec<Level> {
    lod_chain_from(optimize(mesh), p)
}

/// [`lod_chain`] whose finest level is `finest` as given (already
/// optimised; its triangle order is kept).
pub fn lod_chain_from(finest: Mesh, p: &LodParams) -> Vec<Level> {
    let mut levels = vec![Level {
        mesh: finest,
        error: 0.0,
    }];
    while levels.len() < p.max_levels {
        let cur = levels.last().expect("chain starts non-empty");
        let n = cur.mesh.tri_count();
        let target = ((n as f32 * p.ratio) as usize).max(p.min_tris);
        if target >= n {
            break;
        }
        let Some((m, err)) = simplify(&cur.mesh, target, p.lock_border, !p.lock_border) else {
            break;
        };
        if m.tri_count() as f32 > n as f32 * p.max_keep {
            break;
        }
        let error = strictly_above(cur.error, cur.error + err);
        levels.push(Level { mesh: m, error });
    }
    levels.reverse();
    levels
}

/// An HLOD of merged child geometry: simplified drastically to at most
/// `budget` triangles (sloppy when topology blocks it). The error returned is
/// that of this step only.
pub fn hlod(merged: &Mesh, budget: usize) -> (Mesh, f32) {
    if merged.tri_count() <= budget {
        return (optimize(merged), 0.0);
    }
    match simplify(merged, budget, false, true) {
        Some(r) => r,
        None => (optimize(merged), 0.0),
    }
}

/// `max(candidate, the next float above floor)`: keeps errors strictly monotone.
pub fn strictly_above(floor: f32, candidate: f32) -> f32 {
    candidate.max(floor.next_up()).max(floor * (1.0 + 1e-5))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere(n: usize) -> Mesh {
        let mut m = Mesh::default();
        for i in 0..=n {
            let th = std::f32::consts::PI * i as f32 / n as f32;
            for j in 0..=2 * n {
                let ph = std::f32::consts::PI * j as f32 / n as f32;
                let p = [th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()];
                m.positions.push(p);
                m.normals.push(p);
                m.colors.push([255, 255, 255, 255]);
            }
        }
        let w = 2 * n as u32 + 1;
        for i in 0..n as u32 {
            for j in 0..2 * n as u32 {
                let a = i * w + j;
                m.indices
                    .extend_from_slice(&[a, a + w, a + 1, a + 1, a + w, a + w + 1]);
            }
        }
        m.remove_degenerate();
        m
    }

    #[test]
    fn chain_is_coarse_to_fine_with_strictly_decreasing_error() {
        let s = sphere(40);
        let chain = lod_chain(&s, &LodParams::default());
        assert!(chain.len() >= 3, "only {} levels", chain.len());
        assert_eq!(chain.last().unwrap().mesh.tri_count(), s.tri_count());
        for w in chain.windows(2) {
            assert!(w[0].error > w[1].error);
            assert!(w[0].mesh.tri_count() < w[1].mesh.tri_count());
        }
        // A unit sphere's coarse levels deviate by less than its radius.
        let e: Vec<_> = chain
            .iter()
            .map(|l| (l.mesh.tri_count(), l.error))
            .collect();
        // Any approximation inside the unit sphere's box is within its diameter.
        assert!(chain[0].error < 2.0 && chain[0].error > 0.0, "{e:?}");
    }

    #[test]
    fn hlod_meets_its_budget() {
        let mut parts = Vec::new();
        for k in 0..8 {
            let m = sphere(12).transformed(&glam::Mat4::from_translation(
                glam::Vec3::X * 3.0 * k as f32,
            ));
            parts.push(m);
        }
        let merged = Mesh::merge(&parts);
        let (h, err) = hlod(&merged, 200);
        assert!(h.tri_count() <= 300, "{} triangles", h.tri_count());
        assert!(err > 0.0);
    }
}
