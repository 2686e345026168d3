//! A procedural CAD power-plant / ship-like environment.
//!
//! The plant is a grid of structural units (bays of steel frame with several
//! floors); each unit holds columns and beams (I-section girders with bolts),
//! grated walkways, a stair, tanks with domes and nozzles, pump skids (instanced
//! from a small library of meshes, as CAD assemblies repeat parts) and pipe runs
//! with elbows and flanges. Units are added until the object count is reached;
//! every object gets a share of the triangle target by a per-kind weight and
//! tessellates itself to that budget.

use std::path::Path;

use glam::{Mat4, Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::glb::GlbObject;
use super::shapes::ShapeBuilder;
use crate::mesh::Mesh;

/// Generator parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlantParams {
    pub seed: u64,
    pub objects: usize,
    /// Target triangles after instancing.
    pub triangles: u64,
}

/// What was generated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PlantStats {
    pub objects: usize,
    pub meshes: usize,
    /// Triangles after instancing.
    pub triangles: u64,
    /// Triangles of the distinct meshes.
    pub unique_triangles: u64,
    pub bytes: u64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Column,
    Beam,
    Walkway,
    Stair,
    Tank,
    Equipment,
    Pipe,
}

impl Kind {
    fn weight(self) -> f64 {
        match self {
            Kind::Column | Kind::Beam => 1.0,
            Kind::Walkway => 1.5,
            Kind::Stair | Kind::Equipment | Kind::Pipe => 2.0,
            Kind::Tank => 3.0,
        }
    }
}

const UNIT: f32 = 16.0;
const FLOOR: f32 = 5.0;
const EQUIPMENT_MODELS: usize = 6;
const STEEL: [u8; 4] = [222, 176, 48, 255];
const GREY: [u8; 4] = [128, 130, 134, 255];
const TANK: [u8; 4] = [214, 216, 222, 255];
const PIPES: [[u8; 4]; 5] = [
    [46, 139, 87, 255],
    [196, 64, 48, 255],
    [58, 102, 196, 255],
    [226, 204, 64, 255],
    [150, 150, 150, 255],
];

/// Checks the parameters.
pub fn check(p: &PlantParams) -> Result<(), String> {
    if p.objects == 0 || p.objects > MAX_OBJECTS {
        return Err(format!(
            "--objects {} must be in 1..={MAX_OBJECTS}",
            p.objects
        ));
    }
    if p.triangles < 64 * p.objects as u64 || p.triangles > MAX_TRIANGLES {
        return Err(format!(
            "--triangles {} must be at least 64 per object ({}) and at most {MAX_TRIANGLES}",
            p.triangles,
            64 * p.objects as u64
        ));
    }
    Ok(())
}

/// Limits of the generator: the Boeing 777's parts and triangles, twice over
/// (the generator streams; what it keeps per object is a few dozen bytes).
pub const MAX_OBJECTS: usize = 5_000_000;
pub const MAX_TRIANGLES: u64 = 1_000_000_000;

/// What one generation pass hands on, in order: a mesh (numbered from 0 in
/// the order given), or an object placing a mesh given before.
#[derive(Debug)]
pub enum Part {
    Mesh(Mesh),
    Object(GlbObject),
}

/// Generates the plant into memory: distinct meshes and the objects
/// placing them (small scenes and tests; [`write_plant`] streams).
pub fn generate(p: &PlantParams) -> Result<(Vec<Mesh>, Vec<GlbObject>), String> {
    let scale = budget_scale(p)?;
    let (mut meshes, mut objects) = (Vec::new(), Vec::new());
    generate_with(p, scale, &mut |part| {
        match part {
            Part::Mesh(m) => meshes.push(m),
            Part::Object(o) => objects.push(o),
        }
        Ok(())
    })
    .map_err(|e| e.to_string())?;
    Ok((meshes, objects))
}

/// Totals of one pass, counted without keeping the geometry.
#[derive(Default)]
struct Count {
    mesh_tris: Vec<u64>,
    triangles: u64,
    bin_bytes: u64,
}

fn count(p: &PlantParams, scale: f64) -> Count {
    let mut c = Count::default();
    generate_with(p, scale, &mut |part| {
        match part {
            Part::Mesh(m) => {
                c.mesh_tris.push(m.tri_count() as u64);
                c.bin_bytes += super::glb::bin_bytes(&m);
            }
            Part::Object(o) => c.triangles += c.mesh_tris[o.mesh],
        }
        Ok(())
    })
    .expect("counting does not fail");
    c
}

/// The factor on every budget that brings the triangle count (after
/// instancing) within a few percent of the target: 1, or a second pass's
/// correction, from a counting pass that keeps no geometry.
fn budget_scale(p: &PlantParams) -> Result<f64, String> {
    check(p)?;
    let first = count(p, 1.0);
    let ratio = p.triangles as f64 / first.triangles.max(1) as f64;
    Ok(if (ratio - 1.0).abs() < 0.02 {
        1.0
    } else {
        ratio
    })
}

/// One generation pass with every budget multiplied by `scale`, handing each
/// mesh and object to `emit` as it is made.
fn generate_with(
    p: &PlantParams,
    scale: f64,
    emit: &mut dyn FnMut(Part) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
    // Object kinds and placements, unit by unit.
    let mut specs: Vec<(Kind, u32, u32)> = Vec::new(); // kind, unit, index in unit
    let mut unit = 0u32;
    while specs.len() < p.objects {
        let floors = 3;
        let mut k = 0;
        let mut push = |kind, n: u32| {
            for _ in 0..n {
                specs.push((kind, unit, k));
                k += 1;
            }
        };
        push(Kind::Column, 4);
        push(Kind::Beam, 4 * floors);
        push(Kind::Walkway, floors);
        push(Kind::Stair, 1);
        push(Kind::Tank, 2);
        push(Kind::Equipment, 4);
        push(Kind::Pipe, 14);
        unit += 1;
    }
    specs.truncate(p.objects);
    let units = unit;
    let side = (units as f32).sqrt().ceil() as u32;
    let total_w: f64 = specs.iter().map(|s| s.0.weight()).sum();
    let per_w = scale * p.triangles as f64 / total_w;
    let budget = |k: Kind| ((k.weight() * per_w) as usize).max(48);

    for m in 0..EQUIPMENT_MODELS {
        emit(Part::Mesh(equipment_model(
            &mut ChaCha8Rng::seed_from_u64(p.seed ^ ((m as u64 + 1) * 0x9E37)),
            budget(Kind::Equipment),
        )))?;
    }
    let mut next_mesh = EQUIPMENT_MODELS;
    for (i, &(kind, u, k)) in specs.iter().enumerate() {
        let origin = Vec3::new(
            (u % side) as f32 * UNIT * 1.25,
            0.0,
            (u / side) as f32 * UNIT * 1.25,
        );
        let b = budget(kind);
        let name = format!("{kind:?}-{u}-{k}").to_lowercase();
        if kind == Kind::Equipment {
            let spot = Vec3::new(
                rng.random_range(2.0..UNIT - 2.0),
                0.0,
                rng.random_range(2.0..UNIT - 2.0),
            );
            let rot =
                Quat::from_rotation_y(std::f32::consts::FRAC_PI_2 * rng.random_range(0..4) as f32);
            emit(Part::Object(GlbObject {
                name,
                mesh: rng.random_range(0..EQUIPMENT_MODELS),
                transform: Mat4::from_rotation_translation(rot, origin + spot),
            }))?;
            continue;
        }
        let mesh = match kind {
            Kind::Column => column(origin, k, b),
            Kind::Beam => beam(origin, k - 4, b),
            Kind::Walkway => walkway(origin, k - 16, b),
            Kind::Stair => stair(origin, b),
            Kind::Tank => tank(&mut rng, origin, k - 20, b),
            Kind::Pipe => pipe(&mut rng, origin, i, b),
            Kind::Equipment => unreachable!("handled above"),
        };
        emit(Part::Mesh(mesh))?;
        emit(Part::Object(GlbObject {
            name,
            mesh: next_mesh,
            transform: Mat4::IDENTITY,
        }))?;
        next_mesh += 1;
    }
    Ok(())
}

/// Generates the plant and streams it to `path` (`.glb`, or `.gltf` with a
/// `.bin` past GLB's 4 GiB): memory stays at one object's geometry and a
/// few dozen bytes per object, whatever the size.
pub fn write_plant(p: &PlantParams, path: &Path) -> anyhow::Result<PlantStats> {
    let named = |e: std::io::Error| anyhow::anyhow!("{}: {e}", path.display());
    engine_cli::outfile::check_output(path, &[])?;
    let scale = budget_scale(p).map_err(anyhow::Error::msg)?;
    let glb = !path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf"));
    if glb {
        // The size is known before anything is written: refuse a GLB that
        // cannot hold the scene now rather than after generating it.
        let bin = count(p, scale).bin_bytes;
        if bin > super::glb::GLB_MAX_BYTES {
            anyhow::bail!(
                "{}: the scene's geometry is {}, past GLB's limit of 4 GiB: name a .gltf output \
                 (JSON and one .bin of any size)",
                path.display(),
                engine::limits::human(bin)
            );
        }
    }
    let mut out = super::glb::SceneStream::create(path, &[]).map_err(named)?;
    let mut stats = PlantStats::default();
    let mut mesh_tris: Vec<u64> = Vec::new();
    let mut used: Vec<bool> = Vec::new();
    generate_with(p, scale, &mut |part| {
        match part {
            Part::Mesh(m) => {
                mesh_tris.push(m.tri_count() as u64);
                used.push(false);
                out.add_mesh(&m)?;
            }
            Part::Object(o) => {
                stats.objects += 1;
                stats.triangles += mesh_tris[o.mesh];
                used[o.mesh] = true;
                out.add_object(&o);
            }
        }
        Ok(())
    })
    .map_err(named)?;
    stats.meshes = mesh_tris.len();
    stats.unique_triangles = mesh_tris
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .map(|(t, _)| t)
        .sum();
    stats.bytes = out.finish().map_err(named)?;
    Ok(stats)
}

/// Bolts (hex heads, 24 triangles each) along a line.
fn bolts(s: &mut ShapeBuilder, from: Vec3, to: Vec3, normal: Vec3, n: usize, r: f32) {
    for i in 0..n {
        let p = from.lerp(to, (i as f32 + 0.5) / n as f32);
        s.cylinder(p, p + normal * r, r, 6, 1, true);
    }
}

/// An I-section girder from `a` to `b` with its web in the `up` plane, bolted to budget.
fn girder(s: &mut ShapeBuilder, a: Vec3, b: Vec3, up: Vec3, size: f32, budget: usize) {
    let side = up.cross(b - a).normalize_or(Vec3::X);
    s.beam(a + up * size, b + up * size, side, size * 0.8, size * 0.08);
    s.beam(a - up * size, b - up * size, side, size * 0.8, size * 0.08);
    s.beam(a, b, up, size * 0.06, size);
    let n = budget.saturating_sub(36) / 48;
    for (off, dir) in [(size * 1.08, up), (-size * 1.08, -up)] {
        bolts(
            s,
            a + up * off + side * size * 0.5,
            b + up * off + side * size * 0.5,
            dir,
            n,
            size * 0.08,
        );
    }
}

fn column(origin: Vec3, k: u32, budget: usize) -> Mesh {
    let mut s = ShapeBuilder::new(STEEL);
    let corner = origin + Vec3::new((k % 2) as f32 * UNIT, 0.0, (k / 2) as f32 * UNIT);
    girder(
        &mut s,
        corner,
        corner + Vec3::Y * FLOOR * 3.0,
        Vec3::X,
        0.2,
        budget,
    );
    s.mesh
}

fn beam(origin: Vec3, k: u32, budget: usize) -> Mesh {
    let mut s = ShapeBuilder::new(STEEL);
    let y = FLOOR * (1 + k / 4) as f32;
    let (a, b) = match k % 4 {
        0 => (Vec3::new(0.0, y, 0.0), Vec3::new(UNIT, y, 0.0)),
        1 => (Vec3::new(UNIT, y, 0.0), Vec3::new(UNIT, y, UNIT)),
        2 => (Vec3::new(UNIT, y, UNIT), Vec3::new(0.0, y, UNIT)),
        _ => (Vec3::new(0.0, y, UNIT), Vec3::new(0.0, y, 0.0)),
    };
    girder(&mut s, origin + a, origin + b, Vec3::Y, 0.18, budget);
    s.mesh
}

fn walkway(origin: Vec3, floor: u32, budget: usize) -> Mesh {
    let mut s = ShapeBuilder::new(GREY);
    let y = FLOOR * (1 + floor) as f32 + 0.2;
    let c = origin + Vec3::new(UNIT * 0.5, y, UNIT * 0.5);
    for (d, h) in [(Vec3::X, Vec3::Z), (Vec3::Z, Vec3::X)] {
        for sign in [-1.0f32, 1.0] {
            let e = c + h * sign * UNIT * 0.45;
            s.beam(
                e - d * UNIT * 0.45,
                e + d * UNIT * 0.45,
                Vec3::Y,
                0.05,
                0.08,
            );
        }
    }
    let bars = (budget.saturating_sub(48) / 12).max(1);
    for i in 0..bars {
        let z = -0.45 + 0.9 * (i as f32 + 0.5) / bars as f32;
        let p = c + Vec3::Z * z * UNIT;
        s.beam(
            p - Vec3::X * UNIT * 0.45,
            p + Vec3::X * UNIT * 0.45,
            Vec3::Y,
            0.01,
            0.03,
        );
    }
    s.mesh
}

fn stair(origin: Vec3, budget: usize) -> Mesh {
    let mut s = ShapeBuilder::new([236, 160, 40, 255]);
    let base = origin + Vec3::new(1.5, 0.0, 2.0);
    let top = base + Vec3::new(0.0, FLOOR, FLOOR * 0.8);
    let steps = 25;
    for side in [-0.5f32, 0.5] {
        let o = Vec3::X * side;
        s.beam(base + o, top + o, Vec3::X, 0.02, 0.12);
    }
    for i in 0..steps {
        let p = base.lerp(top, (i as f32 + 0.5) / steps as f32);
        s.cuboid(p, Vec3::new(0.48, 0.02, 0.12));
    }
    let rest = budget.saturating_sub(24 + steps * 12);
    let radial = 12u32;
    let axial = ((rest / (2 * 2 * radial as usize)).max(1)) as u32;
    for side in [-0.5f32, 0.5] {
        let o = Vec3::X * side + Vec3::Y;
        s.cylinder(base + o, top + o, 0.025, radial, axial, false);
    }
    s.mesh
}

fn tank(rng: &mut ChaCha8Rng, origin: Vec3, k: u32, budget: usize) -> Mesh {
    let mut s = ShapeBuilder::new(TANK);
    let r = rng.random_range(1.2f32..2.6);
    let h = rng.random_range(3.0f32..8.0);
    let c = origin + Vec3::new(UNIT * (0.3 + 0.4 * k as f32), 0.0, UNIT * 0.7);
    let radial = ((budget as f32 / 3.0).sqrt() as u32).clamp(12, 512);
    let axial = ((budget as f32 * 0.45 / (2.0 * radial as f32)) as u32).max(1);
    let rings = ((budget as f32 * 0.3 / (2.0 * radial as f32)) as u32).max(2);
    s.cylinder(c, c + Vec3::Y * h, r, radial, axial, false);
    s.dome(c + Vec3::Y * h, Vec3::Y, r, rings, radial);
    let nozzle_radial = (radial / 4).max(8);
    for i in 0..4 {
        let ang = std::f32::consts::FRAC_PI_2 * i as f32 + 0.3;
        let d = Vec3::new(ang.cos(), 0.0, ang.sin());
        let p = c + Vec3::Y * (h * 0.3 + 0.4 * i as f32) + d * r * 0.9;
        s.cylinder(p, p + d * 0.6, 0.15, nozzle_radial, 1, false);
        s.cylinder(p + d * 0.6, p + d * 0.68, 0.25, nozzle_radial, 1, true);
    }
    s.mesh
}

/// A pump skid: base plate with bolts, motor, pump casing, coupling.
fn equipment_model(rng: &mut ChaCha8Rng, budget: usize) -> Mesh {
    let mut s = ShapeBuilder::new([48, 96, 176, 255]);
    let len = rng.random_range(1.5f32..3.0);
    s.cuboid(Vec3::new(0.0, 0.1, 0.0), Vec3::new(len * 0.5, 0.1, 0.5));
    let radial = ((budget as f32 / 12.0).sqrt() as u32).clamp(12, 256);
    let axial = ((budget as f32 * 0.3 / (2.0 * radial as f32)) as u32).max(1);
    let mr = rng.random_range(0.25f32..0.45);
    s.cylinder(
        Vec3::new(-len * 0.45, 0.3 + mr, 0.0),
        Vec3::new(0.0, 0.3 + mr, 0.0),
        mr,
        radial,
        axial,
        true,
    );
    s.dome(
        Vec3::new(len * 0.25, 0.3 + mr, 0.0),
        Vec3::X,
        mr * 1.1,
        (axial / 2).max(2),
        radial,
    );
    s.dome(
        Vec3::new(len * 0.25, 0.3 + mr, 0.0),
        -Vec3::X,
        mr * 1.1,
        (axial / 2).max(2),
        radial,
    );
    let used = s.mesh.tri_count();
    let n = budget.saturating_sub(used) / 24 / 2;
    for z in [-0.42f32, 0.42] {
        bolts(
            &mut s,
            Vec3::new(-len * 0.48, 0.2, z),
            Vec3::new(len * 0.48, 0.2, z),
            Vec3::Y,
            n,
            0.02,
        );
    }
    s.mesh
}

/// A pipe run of axis-aligned segments joined by elbows, flanged at both ends.
fn pipe(rng: &mut ChaCha8Rng, origin: Vec3, i: usize, budget: usize) -> Mesh {
    let mut s = ShapeBuilder::new(PIPES[i % PIPES.len()]);
    let r = rng.random_range(0.05f32..0.35);
    let bend_r = r * 1.5;
    let segments = rng.random_range(3..7);
    let radial = (((budget as f32) / (segments as f32 * 12.0)).sqrt() as u32).clamp(8, 96);
    let bend = (radial / 2).max(4);
    let fixed = segments * 2 * bend as usize * radial as usize + 4 * radial as usize * 3;
    let axial = ((budget.saturating_sub(fixed)) / (segments * 2 * radial as usize)).max(1) as u32;
    let dirs = [
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::Z,
        Vec3::NEG_Z,
    ];
    let mut p = origin
        + Vec3::new(
            rng.random_range(1.0..UNIT - 1.0),
            rng.random_range(0.5..FLOOR * 3.0),
            rng.random_range(1.0..UNIT - 1.0),
        );
    let mut dir = dirs[rng.random_range(0..dirs.len())];
    let start = p;
    let start_dir = dir;
    let mut pts = Vec::new();
    for seg in 0..segments {
        let mut len = rng.random_range(2.0f32..8.0);
        if dir.y < 0.0 {
            // Never below the ground: a falling segment stops 0.5 m above it.
            len = len.min(p.y - 0.5).max(bend_r * 2.0 + 0.1);
        }
        let next = p + dir * len;
        pts.push((p, next, dir));
        p = next;
        if seg + 1 < segments {
            // A perpendicular turn; downwards only with room for another segment.
            let options: Vec<Vec3> = dirs
                .iter()
                .copied()
                .filter(|d| d.dot(dir).abs() < 0.5 && (d.y >= 0.0 || p.y > 2.5))
                .collect();
            dir = options[rng.random_range(0..options.len())];
        }
    }
    // Trim straight parts at the elbows and add the elbows.
    for k in 0..pts.len() {
        let (a, b, d) = pts[k];
        let a2 = if k > 0 { a + d * bend_r } else { a };
        let b2 = if k + 1 < pts.len() { b - d * bend_r } else { b };
        s.cylinder(a2, b2, r, radial, axial, false);
        if k + 1 < pts.len() {
            s.elbow(b, d, pts[k + 1].2, (bend_r, r), bend, radial);
        }
    }
    for (at, d) in [(start, -start_dir), (p, dir)] {
        s.cylinder(at, at + d * r * 0.3, r * 1.6, radial, 1, true);
    }
    s.mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meets_object_count_and_triangle_target() {
        let p = PlantParams {
            seed: 7,
            objects: 300,
            triangles: 400_000,
        };
        let (meshes, objects) = generate(&p).unwrap();
        assert_eq!(objects.len(), 300);
        let tris: usize = objects.iter().map(|o| meshes[o.mesh].tri_count()).sum();
        let ratio = tris as f64 / p.triangles as f64;
        assert!(
            (0.8..1.2).contains(&ratio),
            "{tris} triangles for a target of 400000"
        );
        // Same seed, same scene; another seed, another scene.
        let (m2, _) = generate(&p).unwrap();
        assert_eq!(meshes, m2);
        let (m3, _) = generate(&PlantParams { seed: 8, ..p }).unwrap();
        assert_ne!(meshes, m3);
        assert!(check(&PlantParams { triangles: 10, ..p }).is_err());
        assert!(check(&PlantParams { objects: 0, ..p }).is_err());
    }
}
