//! Climbing the stairs between two storeys, found from the triangles.
//!
//! A stair is a chain of treads: up-facing horizontal surfaces between the
//! two floors, each within [`MAX_RISE`] of the next one a grid cell away,
//! with room for the body above each (nothing from the knee to above the
//! eye, as on a floor). The climb is a breadth-first search over walkable
//! places, a place being a grid cell at one height: the free cells of the
//! lower and upper storeys at their floor heights, and every tread with
//! headroom. A shortest route from where the walk stands to any free cell
//! of the upper storey is the climb; there is none when no stair, ramp of
//! steps or landing joins the two (the walk then jumps, as before).
//! Furniture does not make a stair: a seat or a table top is more than a
//! rise above the floor around it.

use std::collections::{BTreeMap, HashMap, VecDeque};

use glam::Vec3;

use super::{Grid, clip_y, neighbours};

/// The largest rise from one cell to the next that the walk takes: a
/// riser over a tread of about one cell (a stair's is 0.15–0.22 m).
pub(super) const MAX_RISE: f32 = 0.35;
/// How far a storey's floor may lie from its height (its bin, finishes).
const FLOOR_SLACK: f32 = 0.15;
/// A tread lies at least this far from either storey's height (what is
/// nearer is that floor, or its finish).
const TREAD_MARGIN: f32 = 0.08;
/// Height resolution of the headroom test.
const SLAB: f32 = 0.1;
/// Headroom needed above a tread: from this above it...
const KNEE: f32 = 0.5;
/// ...to this above the eye.
const CROWN: f32 = 0.2;
/// How far beyond the lower region's ground plan a stair may reach: a
/// flight and its landing (Schependomlaan's half-turn stairs put their
/// landings about 2 m beyond the landing the walk stands on).
const STAIR_REACH: f32 = 4.0;
/// Cells with treads beyond which the search is not tried (a scene whose
/// every surface between the floors is a candidate is not a building).
const MAX_TREAD_CELLS: usize = 1 << 22;

/// A storey as the climb sees it.
#[derive(Clone, Copy)]
pub(super) struct Storey<'a> {
    pub floor: f32,
    /// Its walkable region, one flag per grid cell.
    pub free: &'a [bool],
}

/// A climb: points at eye height from the start cell's neighbour to the
/// first free cell of the upper storey, the cell it started from and that
/// cell.
pub(super) struct Climb {
    pub points: Vec<Vec3>,
    pub start: usize,
    pub end: usize,
}

/// The shortest climb from any of the cells `from` of `lo` (a region, or
/// every region of a storey) to a free cell of `hi` (a storey's free
/// cells, any region) (`None` when no chain of treads joins them).
pub(super) fn climb(
    tris: &[[Vec3; 3]],
    g: &Grid,
    lo: Storey<'_>,
    hi: Storey<'_>,
    from: &[usize],
    eye: f32,
) -> Option<Climb> {
    // A stair up from the lower region starts in its ground plan and
    // reaches at most [`STAIR_REACH`] beyond it (the landing of a
    // half-turn stair lies a flight's length away).
    let a = region_box(g, lo.free)?;
    let pad = (STAIR_REACH / g.cell).ceil() as usize;
    let within = (
        a.0.saturating_sub(pad),
        a.1 + pad,
        a.2.saturating_sub(pad),
        a.3 + pad,
    );
    let treads = treads(tris, g, (lo.floor, hi.floor), within)?;
    let base = lo.floor - KNEE;
    let slabs = ((hi.floor + eye + CROWN + KNEE - base) / SLAB).ceil() as usize;
    if slabs > 128 {
        return None;
    }
    let occupied = occupancy(tris, g, &treads, base, slabs);
    let slab = |y: f32| (((y - base) / SLAB).floor().max(0.0) as usize).min(slabs - 1);
    let clear = |c: usize, h: f32| {
        let (a, b) = (slab(h + KNEE), slab(h + eye + CROWN));
        let band = (u128::MAX >> (127 - (b - a))) << a;
        occupied.get(&c).is_none_or(|&m| m & band == 0)
    };
    // Places: (cell, height key); the key is the height in centimetres.
    let key = |h: f32| (h * 100.0).round() as i32;
    // Each start place is its own predecessor: a route ends there.
    let mut prev: HashMap<(usize, i32), (usize, i32)> = HashMap::new();
    let mut queue = VecDeque::new();
    for &c in from {
        let start = (c, key(lo.floor));
        if prev.insert(start, start).is_none() {
            queue.push_back((c, lo.floor));
        }
    }
    let mut goal = None;
    while let Some((c, h)) = queue.pop_front() {
        if hi.free[c] && key(h) == key(hi.floor) {
            goal = Some((c, key(h)));
            break;
        }
        for n in neighbours(g, c) {
            let mut next: Vec<f32> = Vec::new();
            for s in [lo, hi] {
                if s.free[n] && (s.floor - h).abs() <= MAX_RISE + FLOOR_SLACK {
                    next.push(s.floor);
                }
            }
            if let Some(ts) = treads.get(&n) {
                next.extend(
                    ts.iter()
                        .copied()
                        .filter(|&t| (t - h).abs() <= MAX_RISE && clear(n, t)),
                );
            }
            for t in next {
                let k = (n, key(t));
                if let std::collections::hash_map::Entry::Vacant(e) = prev.entry(k) {
                    e.insert((c, key(h)));
                    queue.push_back((n, t));
                }
            }
        }
    }
    let goal = goal?;
    let mut route = vec![goal];
    loop {
        let at = *route.last().expect("a place");
        let back = prev[&at];
        if back == at {
            break;
        }
        route.push(back);
    }
    route.reverse();
    let start = route[0].0;
    let points = route
        .iter()
        .skip(1)
        .map(|&(c, k)| {
            let (x, z) = g.centre(c);
            Vec3::new(x, k as f32 / 100.0 + eye, z)
        })
        .collect();
    Some(Climb {
        points,
        start,
        end: goal.0,
    })
}

/// The cells `free` spans: x from, x to, z from, z to (`None` when empty).
fn region_box(g: &Grid, free: &[bool]) -> Option<(usize, usize, usize, usize)> {
    let mut b: Option<(usize, usize, usize, usize)> = None;
    for (i, _) in free.iter().enumerate().filter(|(_, f)| **f) {
        let (x, z) = (i % g.nx, i / g.nx);
        b = Some(match b {
            None => (x, x, z, z),
            Some(o) => (o.0.min(x), o.1.max(x), o.2.min(z), o.3.max(z)),
        });
    }
    b
}

/// Tread heights per cell of the box `within` (cells: x from, x to, z from,
/// z to): up-facing horizontal triangles strictly between the two floors,
/// heights closer than a centimetre merged.
fn treads(
    tris: &[[Vec3; 3]],
    g: &Grid,
    (lo, hi): (f32, f32),
    within: (usize, usize, usize, usize),
) -> Option<BTreeMap<usize, Vec<f32>>> {
    let inside = |c: usize| {
        let (x, z) = (c % g.nx, c / g.nx);
        (within.0..=within.1).contains(&x) && (within.2..=within.3).contains(&z)
    };
    let mut out: BTreeMap<usize, Vec<f32>> = BTreeMap::new();
    for t in tris {
        let nrm = (t[1] - t[0]).cross(t[2] - t[0]);
        let len = nrm.length();
        if len <= 0.0 || nrm.y / len <= 0.95 {
            continue;
        }
        let y = (t[0].y + t[1].y + t[2].y) / 3.0;
        if y <= lo + TREAD_MARGIN || y >= hi - TREAD_MARGIN {
            continue;
        }
        g.visit(t, |c| {
            if inside(c) {
                out.entry(c).or_default().push(y);
            }
        });
        if out.len() > MAX_TREAD_CELLS {
            return None;
        }
    }
    for hs in out.values_mut() {
        hs.sort_by(f32::total_cmp);
        hs.dedup_by(|a, b| (*a - *b).abs() < 0.01);
    }
    Some(out)
}

/// For each tread cell, the height slabs (of [`SLAB`], from `base`) that
/// some triangle crosses there.
fn occupancy(
    tris: &[[Vec3; 3]],
    g: &Grid,
    treads: &BTreeMap<usize, Vec<f32>>,
    base: f32,
    slabs: usize,
) -> HashMap<usize, u128> {
    let mut occ: HashMap<usize, u128> = treads.keys().map(|&c| (c, 0)).collect();
    // Blocks of 8 x 8 cells holding a tread cell: a triangle whose box
    // touches none is skipped without clipping.
    let bx = g.nx.div_ceil(8);
    let mut blocks = vec![false; bx * g.nz.div_ceil(8)];
    for &c in treads.keys() {
        blocks[(c / g.nx / 8) * bx + (c % g.nx) / 8] = true;
    }
    let top = base + slabs as f32 * SLAB;
    for t in tris {
        let (y0, y1) = (
            t[0].y.min(t[1].y).min(t[2].y),
            t[0].y.max(t[1].y).max(t[2].y),
        );
        if y1 < base || y0 > top {
            continue;
        }
        let lo = t[0].min(t[1]).min(t[2]);
        let hi = t[0].max(t[1]).max(t[2]);
        let (x0, x1) = (g.x_of(lo.x) / 8, g.x_of(hi.x) / 8);
        let (z0, z1) = (g.z_of(lo.z) / 8, g.z_of(hi.z) / 8);
        if !(z0..=z1).any(|z| (x0..=x1).any(|x| blocks[z * bx + x])) {
            continue;
        }
        let first = ((y0.max(base) - base) / SLAB).floor() as usize;
        let last = (((y1.min(top) - base) / SLAB).floor() as usize).min(slabs - 1);
        for s in first..=last {
            let part = clip_y(t, base + s as f32 * SLAB, base + (s + 1) as f32 * SLAB);
            if part.len() >= 2 {
                g.visit(&part, |c| {
                    if let Some(m) = occ.get_mut(&c) {
                        *m |= 1u128 << s;
                    }
                });
            }
        }
    }
    occ
}
