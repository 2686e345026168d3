//! A generated scene of thin members (issue 21, item 5): steel lattice
//! towers, pipe racks and railed walkways, the parts of plants and
//! buildings whose members are a few centimetres thick and metres long,
//! so that simplification and HLOD merging are tempted to drop them.
//!
//! Units on a grid, each one:
//! - a lattice tower: four legs, horizontal and diagonal bracing on every
//!   face, one object per storey;
//! - a pipe rack: portal frames every 6 m carrying pipes of 3–9 cm radius,
//!   one object per pipe and per frame;
//! - a walkway along the rack: a grating plate with a railing (posts,
//!   top and knee rails of 2–3 cm), one object per side.

use std::path::Path;

use glam::{Mat4, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::glb::{GlbObject, write_glb};
use super::plant::PlantStats;
use super::shapes::ShapeBuilder;
use crate::mesh::Mesh;

/// Generator parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LatticeParams {
    pub seed: u64,
    /// Units on a side (`units × units`).
    pub units: u32,
}

const SPACING: f32 = 40.0;
const STEEL: [u8; 4] = [222, 176, 48, 255];
const GRATING: [u8; 4] = [120, 124, 130, 255];
const RAIL: [u8; 4] = [230, 200, 40, 255];
const PIPES: [[u8; 4]; 4] = [
    [46, 139, 87, 255],
    [196, 64, 48, 255],
    [58, 102, 196, 255],
    [210, 210, 210, 255],
];

/// Checks the parameters.
pub fn check(p: &LatticeParams) -> Result<(), String> {
    if p.units == 0 || p.units > 200 {
        return Err(format!("--units {} must be in 1..=200", p.units));
    }
    Ok(())
}

/// A box member from `a` to `b` of half thickness `h`.
fn member(s: &mut ShapeBuilder, a: Vec3, b: Vec3, h: f32) {
    let d = (b - a).normalize_or(Vec3::Y);
    let side = if d.y.abs() > 0.9 { Vec3::X } else { Vec3::Y };
    s.beam(a, b, side, h, h);
}

/// One storey of a lattice tower of `width` between heights `y0` and `y1`.
fn tower_storey(origin: Vec3, width: f32, y0: f32, y1: f32, leg: f32, brace: f32) -> Mesh {
    let mut s = ShapeBuilder::new(STEEL);
    let c = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(width, 0.0, 0.0),
        Vec3::new(width, 0.0, width),
        Vec3::new(0.0, 0.0, width),
    ];
    let at = |k: usize, y: f32| origin + c[k % 4] + Vec3::Y * y;
    for k in 0..4 {
        member(&mut s, at(k, y0), at(k, y1), leg);
        // The face from corner k to k + 1: a ring and an X of braces.
        member(&mut s, at(k, y1), at(k + 1, y1), brace);
        member(&mut s, at(k, y0), at(k + 1, y1), brace);
        member(&mut s, at(k + 1, y0), at(k, y1), brace);
    }
    s.mesh
}

/// A portal frame of the rack at `x`: two columns and two cross beams.
fn portal(origin: Vec3, x: f32, width: f32, height: f32) -> Mesh {
    let mut s = ShapeBuilder::new(STEEL);
    let p = |z: f32, y: f32| origin + Vec3::new(x, y, z);
    member(&mut s, p(0.0, 0.0), p(0.0, height), 0.08);
    member(&mut s, p(width, 0.0), p(width, height), 0.08);
    member(&mut s, p(0.0, height), p(width, height), 0.06);
    member(&mut s, p(0.0, height * 0.6), p(width, height * 0.6), 0.06);
    s.mesh
}

/// A railing along x from `x0` to `x1` at `z`, on a deck at `y`.
fn railing(origin: Vec3, x0: f32, x1: f32, z: f32, y: f32) -> Mesh {
    let mut s = ShapeBuilder::new(RAIL);
    let p = |x: f32, h: f32| origin + Vec3::new(x, y + h, z);
    let posts = ((x1 - x0) / 1.5).ceil() as u32;
    for k in 0..=posts {
        let x = x0 + (x1 - x0) * k as f32 / posts as f32;
        s.cylinder(p(x, 0.0), p(x, 1.1), 0.02, 6, 1, false);
    }
    s.cylinder(p(x0, 1.1), p(x1, 1.1), 0.025, 8, 1, false);
    s.cylinder(p(x0, 0.55), p(x1, 0.55), 0.02, 6, 1, false);
    s.mesh
}

/// Generates the scene: one mesh per object.
pub fn generate(p: &LatticeParams) -> Result<(Vec<Mesh>, Vec<GlbObject>), String> {
    check(p)?;
    let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
    let mut meshes = Vec::new();
    let mut objects = Vec::new();
    let mut push = |name: String, mesh: Mesh| {
        objects.push(GlbObject {
            name,
            mesh: meshes.len(),
            transform: Mat4::IDENTITY,
        });
        meshes.push(mesh);
    };
    for u in 0..p.units * p.units {
        let origin = Vec3::new(
            (u % p.units) as f32 * SPACING,
            0.0,
            (u / p.units) as f32 * SPACING,
        );
        // The tower.
        let width = rng.random_range(3.0..5.0f32);
        let storeys = rng.random_range(4..9u32);
        let storey_h = rng.random_range(3.0..4.5f32);
        for k in 0..storeys {
            let shrink = 1.0 - 0.06 * k as f32;
            let o = origin
                + Vec3::new(
                    width * (1.0 - shrink) / 2.0,
                    0.0,
                    width * (1.0 - shrink) / 2.0,
                );
            push(
                format!("tower-{u}-{k}"),
                tower_storey(
                    o,
                    width * shrink,
                    k as f32 * storey_h,
                    (k + 1) as f32 * storey_h,
                    0.06,
                    0.025,
                ),
            );
        }
        // The rack beside it, along x.
        let rack = origin + Vec3::new(8.0, 0.0, 2.0);
        let (len, rw, rh) = (30.0f32, 4.0f32, rng.random_range(4.0..6.0f32));
        for k in 0..=5 {
            push(
                format!("portal-{u}-{k}"),
                portal(rack, len * k as f32 / 5.0, rw, rh),
            );
        }
        let pipes = rng.random_range(5..10u32);
        for k in 0..pipes {
            let r = rng.random_range(0.03..0.09f32);
            let z = 0.3 + (rw - 0.6) * k as f32 / (pipes - 1).max(1) as f32;
            let y = rh + r + 0.06;
            let mut s = ShapeBuilder::new(PIPES[(k as usize) % PIPES.len()]);
            s.cylinder(
                rack + Vec3::new(0.0, y, z),
                rack + Vec3::new(len, y, z),
                r,
                12,
                10,
                true,
            );
            push(format!("pipe-{u}-{k}"), s.mesh);
        }
        // The walkway along the rack, railed on both sides.
        let deck = rack + Vec3::new(0.0, 0.0, rw + 0.5);
        let mut g = ShapeBuilder::new(GRATING);
        g.cuboid(
            deck + Vec3::new(len / 2.0, 2.5, 0.6),
            Vec3::new(len / 2.0, 0.02, 0.6),
        );
        push(format!("walkway-{u}"), g.mesh);
        for (side, z) in [(0, 0.0f32), (1, 1.2)] {
            push(
                format!("railing-{u}-{side}"),
                railing(deck, 0.0, len, z, 2.52),
            );
        }
    }
    Ok((meshes, objects))
}

/// Generates the scene and writes it as GLB.
pub fn write_lattice(p: &LatticeParams, path: &Path) -> anyhow::Result<PlantStats> {
    engine_cli::outfile::check_output(path, &[])?;
    let (meshes, objects) = generate(p).map_err(anyhow::Error::msg)?;
    let triangles = meshes.iter().map(|m| m.tri_count() as u64).sum();
    let bytes = write_glb(path, &[], &meshes, &objects)
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(PlantStats {
        objects: objects.len(),
        meshes: meshes.len(),
        triangles,
        unique_triangles: triangles,
        bytes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lattice_is_thin_members_and_deterministic() {
        let p = LatticeParams { seed: 3, units: 2 };
        let (m, o) = generate(&p).unwrap();
        assert_eq!(m.len(), o.len());
        assert!(o.len() > 4 * 20, "{} objects", o.len());
        let (m2, _) = generate(&p).unwrap();
        assert!(m.iter().zip(&m2).all(|(a, b)| a.positions == b.positions));
        // Most objects are members: long and at most 20 cm thick.
        let thin = m
            .iter()
            .filter(|x| {
                let e = x.bounds().extent();
                let (lo, hi) = (e.min_element(), e.max_element());
                lo <= 0.2 || hi / lo.max(1e-6) > 20.0
            })
            .count();
        assert!(thin * 2 > m.len(), "{thin} of {} thin", m.len());
        assert!(check(&LatticeParams { seed: 1, units: 0 }).is_err());
    }
}
