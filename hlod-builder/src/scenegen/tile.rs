//! Tiling a real model on a grid: shipped models become 10M+ triangle scenes.

use std::path::{Path, PathBuf};

use anyhow::Result;
use glam::{Mat4, Vec3};

use super::glb::{GlbObject, SceneStream};
use crate::import;
use crate::mesh::Aabb;

/// What was written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TileStats {
    pub objects: usize,
    pub triangles: u64,
    pub bytes: u64,
}

/// Streams `n x m` copies of the input on the XZ plane, `gap` (a fraction of
/// the footprint) apart, into `out`; `baked` copies the geometry (one mesh
/// in memory at a time), else the tiles share the input's meshes.
fn tile_into(
    imported: &import::Imported,
    (n, m): (usize, usize),
    baked: bool,
    gap: f32,
    out: &mut SceneStream,
) -> std::io::Result<TileStats> {
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
    if !baked {
        for (i, mm) in imported.meshes.iter().enumerate() {
            if let Some(mesh) = mm {
                index[i] = out.add_mesh(mesh)?;
            }
        }
    }
    let mut stats = TileStats::default();
    for row in 0..m {
        for col in 0..n {
            let offset = Mat4::from_translation(Vec3::new(col as f32 * e.x, 0.0, row as f32 * e.z));
            for inst in &imported.instances {
                let xf = offset * inst.transform;
                let name = format!("{}-{col}-{row}", inst.name);
                let mesh = imported.meshes[inst.mesh]
                    .as_ref()
                    .expect("instances use usable meshes");
                let object = if baked {
                    GlbObject {
                        name,
                        mesh: out.add_mesh(&mesh.transformed(&xf))?,
                        transform: Mat4::IDENTITY,
                    }
                } else {
                    GlbObject {
                        name,
                        mesh: index[inst.mesh],
                        transform: xf,
                    }
                };
                out.add_object(&object);
                stats.objects += 1;
                stats.triangles += mesh.tri_count() as u64;
            }
        }
    }
    Ok(stats)
}

/// Loads `input`, tiles it and writes the scene (`.glb`, or `.gltf` with a
/// `.bin` of any size).
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
    let inputs = import::model_files(input);
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    engine_cli::outfile::check_output(out, &inputs)?;
    let imported = import::load(input)?;
    let named = |e: std::io::Error| anyhow::anyhow!("{}: {e}", out.display());
    let mut stream = SceneStream::create(out, &inputs).map_err(named)?;
    let mut stats = tile_into(&imported, (n, m), baked, gap, &mut stream).map_err(named)?;
    stats.bytes = stream.finish().map_err(named)?;
    Ok(stats)
}
