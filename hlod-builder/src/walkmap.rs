//! The walk section of a scene: every drawn triangle rasterised into solid
//! columns ([`engine::walk::SpanGrid`]), so that a viewer walks with
//! collision and gravity whatever reps are resident.
//!
//! Every object the finest reps draw counts (walls, slabs, stairs,
//! furniture; doors' leaves — `IfcDoor` objects — in a layer of their own,
//! which a walker passes with the doors open); the objects a build leaves
//! out (IFC openings' voids and spaces) do not. Meshes are read once each, in parallel; the union of
//! spans does not depend on the order, so the section is byte-identical
//! from run to run.

use engine::FormatError;
use engine::format::walk::WalkIndex;
use engine::walk::{Grid, Layer, SpanGrid};
use glam::Vec3;

use crate::build::SceneSource;
use crate::import::Instance;

/// Cells a walk section may have across its box: beyond this the cell is
/// doubled (a site of kilometres walks on a coarser grid).
pub const MAX_COLUMNS: f64 = 32.0e6;

/// What the section holds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WalkStats {
    /// Cell side used, metres (0: no section).
    pub cell: f32,
    /// Cells holding solid.
    pub cells: u64,
    /// Bytes of the section.
    pub bytes: u64,
    /// Bands of chunk rows it was made in (1: at once).
    pub bands: u32,
}

/// The walk section of the objects `keep` admits, with cells of about
/// `cell` metres (0: none), holding at most about `heap` bytes at once.
///
/// The scene is rasterised in bands of chunk rows (along z), each band from
/// the meshes that reach it, so that one band's columns fit in `heap`; a
/// band that grows past it is halved and made again. Each chunk lies in one
/// band and holds the union of every triangle touching it, so the bytes do
/// not depend on the bands.
pub fn walk_section<S: SceneSource>(
    src: &S,
    cell: f32,
    keep: &(dyn Fn(&Instance) -> bool + Sync),
    heap: u64,
) -> Result<(Vec<u8>, WalkStats), FormatError> {
    let scene = src.scene();
    // Each kept instance with its world box, by mesh.
    let mut placed: Vec<(usize, &Instance, Vec3, Vec3)> = scene
        .instances
        .iter()
        .filter(|i| keep(i))
        .filter_map(|i| {
            let meta = scene.meta[i.mesh]?;
            let b = crate::build::transformed_bounds(meta.bounds, &i.transform);
            Some((i.mesh, i, b.min, b.max))
        })
        .collect();
    placed.sort_by_key(|p| p.0);
    let (lo, hi) = placed.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(a, b), p| (a.min(p.2), b.max(p.3)),
    );
    if cell <= 0.0 || placed.is_empty() || !(lo.is_finite() && hi.is_finite()) {
        return Ok((Vec::new(), WalkStats::default()));
    }
    let mut cell = cell;
    let area = |c: f32| f64::from((hi.x - lo.x) / c + 1.0) * f64::from((hi.z - lo.z) / c + 1.0);
    while area(cell) > MAX_COLUMNS {
        cell *= 2.0;
    }
    if cell > 100.0 {
        // A site of thousands of kilometres: nothing to walk on at this scale.
        return Ok((Vec::new(), WalkStats::default()));
    }
    let quantum = ((hi.y - lo.y) / 65000.0).max(0.02);
    let grid = Grid {
        cell,
        quantum,
        y_base: lo.y - quantum,
    };
    let probe = SpanGrid::new(grid);
    let (first, last) = (probe.chunk_row(lo.z), probe.chunk_row(hi.z));
    let mut bands = vec![(first, last + 1)];
    let (mut chunks, mut cells, mut made) = (Vec::new(), 0u64, 0u32);
    while let Some((z0, z1)) = bands.pop() {
        match band(src, &placed, grid, (z0, z1), heap)? {
            Some(g) => {
                let (these, n) = g.into_chunks();
                cells += n as u64;
                chunks.extend(these);
                made += 1;
            }
            None if z1 - z0 > 1 => {
                let mid = z0 + (z1 - z0) / 2;
                // Made in order: the lower half next.
                bands.push((mid, z1));
                bands.push((z0, mid));
            }
            None => {
                return Err(FormatError::TooLargeForMachine(format!(
                    "the walk section needs more than {} for one row of 3.2 m chunks: \
                     give --memory-limit more, or --walk-cell 0 for none",
                    engine::limits::human(heap)
                )));
            }
        }
    }
    let bytes = WalkIndex::encode(grid.cell, grid.quantum, grid.y_base, &chunks);
    let stats = WalkStats {
        cell,
        cells,
        bytes: bytes.len() as u64,
        bands: made,
    };
    Ok((bytes, stats))
}

/// Chunk rows `z0..z1` rasterised, or `None` when they grow past `heap`.
fn band<S: SceneSource>(
    src: &S,
    placed: &[(usize, &Instance, Vec3, Vec3)],
    grid: Grid,
    (z0, z1): (i32, i32),
    heap: u64,
) -> Result<Option<SpanGrid>, FormatError> {
    let mut g = SpanGrid::band(grid, z0, z1);
    let inside =
        |p: &(usize, &Instance, Vec3, Vec3)| g.chunk_row(p.3.z) >= z0 && g.chunk_row(p.2.z) < z1;
    let reach: Vec<&(usize, &Instance, Vec3, Vec3)> = placed.iter().filter(|p| inside(p)).collect();
    for group in reach.chunk_by(|a, b| a.0 == b.0) {
        let mesh = src.mesh(group[0].0)?;
        for (_, inst, _, _) in group {
            let layer = if engine::interior::ifc_class_in(&inst.name, &["IfcDoor"]) {
                Layer::Door
            } else {
                Layer::Solid
            };
            let world: Vec<Vec3> = mesh
                .positions
                .iter()
                .map(|p| inst.transform.transform_point3(Vec3::from(*p)))
                .collect();
            for t in mesh.indices.chunks_exact(3) {
                let v = |k: usize| world.get(t[k] as usize).copied();
                if let (Some(a), Some(b), Some(c)) = (v(0), v(1), v(2)) {
                    g.insert_triangle(layer, [a, b, c]);
                }
            }
        }
        if g.heap_bytes() as u64 > heap {
            return Ok(None);
        }
    }
    Ok(Some(g))
}

/// One line saying what the walk section holds.
pub fn walk_line(w: &WalkStats) -> String {
    if w.bytes == 0 {
        return "walk section: none (walk mode needs a build with --walk-cell > 0)".into();
    }
    let cells = if w.cells > 0 {
        format!("{} solid columns of ", w.cells)
    } else {
        String::new()
    };
    format!(
        "walk section: {cells}{:.2} m cells, {}",
        w.cell,
        engine::limits::human(w.bytes)
    )
}
