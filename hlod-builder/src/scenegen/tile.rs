//! Tiling a real model on a grid: shipped models become 10M+ triangle scenes.

use std::path::Path;

use anyhow::{Context, Result};
use glam::{Mat4, Vec3};

use super::glb::{GlbObject, write_glb};
use crate::import;
use crate::mesh::{Aabb, Mesh};

/// What was written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TileStats {
    pub objects: usize,
    pub triangles: u64,
    pub bytes: u64,
}

/// Meshes and objects of `n x m` copies of the input on the XZ plane,
/// `gap` (a fraction of the footprint) apart; `baked` copies the geometry.
pub fn tile(
    imported: &import::Imported,
    n: usize,
    m: usize,
    baked: bool,
    gap: f32,
) -> (Vec<Mesh>, Vec<GlbObject>) {
    let mut bounds = Aabb::EMPTY;
    for inst in &imported.instances {
        if let Some(mesh) = &imported.meshes[inst.mesh] {
            for p in &mesh.positions {
                bounds.add(inst.transform.transform_point3(Vec3::from(*p)));
            }
        }
    }
    let e = bounds.extent() * (1.0 + gap.max(0.0));
    // Usable meshes, renumbered.
    let mut index = vec![usize::MAX; imported.meshes.len()];
    let mut meshes = Vec::new();
    if !baked {
        for (i, mm) in imported.meshes.iter().enumerate() {
            if let Some(mesh) = mm {
                index[i] = meshes.len();
                meshes.push(mesh.clone());
            }
        }
    }
    let mut objects = Vec::new();
    for row in 0..m {
        for col in 0..n {
            let offset = Mat4::from_translation(Vec3::new(col as f32 * e.x, 0.0, row as f32 * e.z));
            for inst in &imported.instances {
                let xf = offset * inst.transform;
                let name = format!("{}-{col}-{row}", inst.name);
                let mesh = imported.meshes[inst.mesh]
                    .as_ref()
                    .expect("instances use usable meshes");
                if baked {
                    objects.push(GlbObject {
                        name,
                        mesh: meshes.len(),
                        transform: Mat4::IDENTITY,
                    });
                    meshes.push(mesh.transformed(&xf));
                } else {
                    objects.push(GlbObject {
                        name,
                        mesh: index[inst.mesh],
                        transform: xf,
                    });
                }
            }
        }
    }
    (meshes, objects)
}

/// Loads `input`, tiles it and writes the GLB.
pub fn write_tiled(
    input: &Path,
    n: usize,
    m: usize,
    baked: bool,
    gap: f32,
    out: &Path,
) -> Result<TileStats> {
    if !(gap.is_finite() && gap >= 0.0) {
        anyhow::bail!("--gap must be a finite number >= 0");
    }
    engine::outfile::check_output(out, &[input])?;
    let imported = import::load(input)?;
    let (meshes, objects) = tile(&imported, n, m, baked, gap);
    let triangles = objects
        .iter()
        .map(|o| meshes[o.mesh].tri_count() as u64)
        .sum();
    let bytes = write_glb(out, &[input], &meshes, &objects)
        .with_context(|| format!("{}", out.display()))?;
    Ok(TileStats {
        objects: objects.len(),
        triangles,
        bytes,
    })
}
