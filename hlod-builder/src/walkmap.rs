//! The walk section of a scene: every drawn triangle rasterised into solid
//! columns ([`engine::walk::SpanGrid`]), so that a viewer walks with
//! collision and gravity whatever reps are resident.
//!
//! Every object the finest reps draw counts (walls, slabs, stairs,
//! furniture; doors' leaves — `IfcDoor` objects — in a layer of their own,
//! which a walker passes with the doors open); the objects a build leaves
//! out (IFC openings' voids and spaces) do not. An opening's void left out
//! is cut out of the solid around it before the doors and windows are
//! added: some exports keep their walls whole behind the openings (the
//! Schependomlaan's door holes were solid). Meshes are read once each, in parallel; the union of
//! spans does not depend on the order, so the section is byte-identical
//! from run to run.

use engine::FormatError;
use engine::format::walk::WalkIndex;
use engine::walk::{Grid, Layer, Payload, SpanGrid};
use glam::Vec3;
use rayon::prelude::*;

use crate::build::SceneSource;
use crate::import::Instance;

/// Cells a walk section may have across its box: beyond this the cell is
/// doubled (a site of kilometres walks on a coarser grid).
pub const MAX_COLUMNS: f64 = 32.0e6;
/// Nor more than this many cells per drawn triangle, when that is more than
/// [`MIN_COLUMNS`]: a model in millimetres (a CAD part of 700 units across
/// has 20 million 0.1-unit cells for 121,000 triangles) gets a coarser grid
/// instead of a section larger than its geometry. Buildings in metres have
/// far fewer (0.3–1 per triangle), so they keep the cell asked for.
pub const COLUMNS_PER_TRIANGLE: f64 = 8.0;
/// Cells any model may have (a 100 m square at 0.1 m).
pub const MIN_COLUMNS: f64 = 1.0e6;

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
/// the meshes that reach it, so that a band's columns fit in `heap`; a
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
    let class = |i: &Instance, c: &str| engine::interior::ifc_class_in(&i.name, &[c]);
    let mut placed: Vec<Placed> = scene
        .instances
        .iter()
        .filter_map(|i| {
            let role = if !keep(i) {
                // A void left out of the build is cut out of its host.
                class(i, "IfcOpeningElement").then_some(Role::Void)?
            } else if class(i, "IfcDoor") {
                Role::Filling(Layer::Door)
            } else if class(i, "IfcWindow") {
                Role::Filling(Layer::Solid)
            } else {
                Role::Host
            };
            let meta = scene.meta[i.mesh]?;
            let b = crate::build::transformed_bounds(meta.bounds, &i.transform);
            Some(Placed {
                mesh: i.mesh,
                inst: i,
                min: b.min,
                max: b.max,
                role,
            })
        })
        .collect();
    placed.sort_by_key(|p| p.mesh);
    let (lo, hi) = placed.iter().filter(|p| p.role != Role::Void).fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(a, b), p| (a.min(p.min), b.max(p.max)),
    );
    if cell <= 0.0 || !(lo.is_finite() && hi.is_finite()) {
        return Ok((Vec::new(), WalkStats::default()));
    }
    let mut cell = cell;
    let area = |c: f32| f64::from((hi.x - lo.x) / c + 1.0) * f64::from((hi.z - lo.z) / c + 1.0);
    let triangles: u64 = (placed.iter())
        .filter(|p| p.role != Role::Void)
        .filter_map(|p| scene.meta[p.mesh].map(|m| m.tris as u64))
        .sum();
    let most = MAX_COLUMNS.min(MIN_COLUMNS.max(COLUMNS_PER_TRIANGLE * triangles as f64));
    while area(cell) > most {
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
    let (first, last) = (probe.chunk_row(lo.z), probe.chunk_row(hi.z) + 1);
    // Bands of a share of the heap each, one per thread at once; one that
    // outgrows its share is halved, a single row gets the whole heap alone.
    // (Two at once were 1.4x slower on 2 cores while every clip allocated,
    // the counted heap's allocations contending; without them two are
    // 1.2-1.3x faster.)
    let threads = rayon::current_num_threads().max(1) as i64;
    let rows = i64::from(last - first);
    let n = threads.min(rows).max(1);
    let cut = |k: i64| first + (rows * k / n) as i32;
    let mut todo: Vec<(i32, i32)> = (0..n).map(|k| (cut(k), cut(k + 1))).collect();
    let share = heap / threads as u64;
    let (mut chunks, mut cells, mut made) = (Vec::new(), 0u64, 0u32);
    while !todo.is_empty() {
        let results: Vec<Result<Made, FormatError>> = todo
            .par_iter()
            .map(|&b| Ok(band(src, &placed, grid, b, share)?.map(SpanGrid::into_chunks)))
            .collect();
        let mut next = Vec::new();
        for (&(z0, z1), r) in todo.iter().zip(results) {
            let made_now = match r? {
                Some(done) => Some(done),
                None if z1 - z0 > 1 => {
                    let mid = z0 + (z1 - z0) / 2;
                    next.extend([(z0, mid), (mid, z1)]);
                    continue;
                }
                None => band(src, &placed, grid, (z0, z1), heap)?.map(SpanGrid::into_chunks),
            };
            let Some((these, k)) = made_now else {
                return Err(FormatError::TooLargeForMachine(format!(
                    "the walk section needs more than {} for one row of 3.2 m chunks: \
                     give --memory-limit more, or --walk-cell 0 for none",
                    engine::limits::human(heap)
                )));
            };
            cells += k as u64;
            chunks.extend(these);
            made += 1;
        }
        todo = next;
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

/// A band's chunks and occupied cells, or `None` when it outgrew its heap.
type Made = Option<(Vec<Payload>, usize)>;

/// What an instance is to the walk section.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    /// Solid: walls, slabs, stairs, furniture.
    Host,
    /// An opening's void, cut out of the hosts' solid (a model whose walls
    /// were exported without their door holes).
    Void,
    /// What fills an opening, added after the cut: doors' leaves (their own
    /// layer) and windows (solid).
    Filling(Layer),
}

/// An instance, its world box and its role.
struct Placed<'a> {
    mesh: usize,
    inst: &'a Instance,
    min: Vec3,
    max: Vec3,
    role: Role,
}

/// Chunk rows `z0..z1` rasterised: the hosts, less the voids, and the
/// fillings; `None` when they grow past `heap`.
fn band<S: SceneSource>(
    src: &S,
    placed: &[Placed<'_>],
    grid: Grid,
    (z0, z1): (i32, i32),
    heap: u64,
) -> Result<Option<SpanGrid>, FormatError> {
    let mut g = SpanGrid::band(grid, z0, z1);
    let reach: Vec<&Placed<'_>> = placed
        .iter()
        .filter(|p| g.chunk_row(p.max.z) >= z0 && g.chunk_row(p.min.z) < z1)
        .collect();
    let of = |role: fn(Role) -> bool| -> Vec<&Placed<'_>> {
        reach.iter().copied().filter(|p| role(p.role)).collect()
    };
    if !rasterise(src, &of(|r| r == Role::Host), &mut g, heap)? {
        return Ok(None);
    }
    let voids = of(|r| r == Role::Void);
    if !voids.is_empty() {
        let mut v = SpanGrid::band(grid, z0, z1);
        if !rasterise(src, &voids, &mut v, heap)? {
            return Ok(None);
        }
        // Each column of a void, from its lowest to its highest surface,
        // less a step at either end (its sill and lintel stay).
        let cuts: Vec<(i64, i64, engine::walk::Span)> = v
            .solid_columns()
            .into_iter()
            .filter_map(|(x, z, c)| {
                let (lo, hi) = (c.first()?.lo, c.last()?.hi);
                (hi > lo + 2).then_some((
                    x,
                    z,
                    engine::walk::Span {
                        lo: lo + 1,
                        hi: hi - 1,
                    },
                ))
            })
            .collect();
        g.carve(&cuts);
    }
    let fillings = of(|r| matches!(r, Role::Filling(_)));
    Ok(rasterise(src, &fillings, &mut g, heap)?.then_some(g))
}

/// Adds the triangles of `placed` (sorted by mesh) to `g`; false when it
/// grows past `heap`.
fn rasterise<S: SceneSource>(
    src: &S,
    placed: &[&Placed<'_>],
    g: &mut SpanGrid,
    heap: u64,
) -> Result<bool, FormatError> {
    for group in placed.chunk_by(|a, b| a.mesh == b.mesh) {
        let mesh = src.mesh(group[0].mesh)?;
        for p in group {
            let layer = match p.role {
                Role::Filling(l) => l,
                Role::Host | Role::Void => Layer::Solid,
            };
            let world: Vec<Vec3> = mesh
                .positions
                .iter()
                .map(|v| p.inst.transform.transform_point3(Vec3::from(*v)))
                .collect();
            for t in mesh.indices.chunks_exact(3) {
                let v = |k: usize| world.get(t[k] as usize).copied();
                if let (Some(a), Some(b), Some(c)) = (v(0), v(1), v(2)) {
                    g.insert_triangle(layer, [a, b, c]);
                }
            }
        }
        if g.heap_bytes() as u64 > heap {
            return Ok(false);
        }
    }
    Ok(true)
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
