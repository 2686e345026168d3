//! Interior walkthrough paths: a person walking at eye height through a
//! building's storeys and rooms, found from the scene's own triangles.
//!
//! 1. **Storeys**: the heights where up-facing horizontal triangles (floors,
//!    slabs) hold the most area, at least `min_storey_gap` apart.
//! 2. **Free space** per storey, on a grid of `cell` over the ground plan:
//!    a cell is walkable when a floor lies under it (within 0.25 m of the
//!    storey), nothing crosses the body's height above it (from knee to
//!    above the eye: walls, furniture, closed doors), and something covers
//!    it higher up (a ceiling: the cell is indoors).
//! 3. **The walk**: in the largest walkable region of each storey, from
//!    cell to randomly drawn cells along shortest grid paths (through doors),
//!    at walking speed, looking where it goes. Storeys are visited bottom to
//!    top; the walk climbs a stair to the next storey when one joins them
//!    (treads found in the triangles, see [`stairs`]), goes up through an
//!    opening in the floor above (a stairwell) when there is only that, and
//!    otherwise moves to the next storey's region directly (counted in
//!    [`InteriorPath::jumps`]).
//!
//! The up axis is +Y (glTF's). The same triangles, parameters and seed give
//! the same path.

use std::collections::VecDeque;

use glam::Vec3;

use crate::camera::Pose;

/// What the walk is made of (lengths in scene units; metres for BIM).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InteriorParams {
    pub eye_height: f32,
    pub cell: f32,
    /// Distance walked per frame.
    pub step: f32,
    pub min_storey_gap: f32,
    pub seed: u64,
    pub fov_y_deg: f32,
}

impl Default for InteriorParams {
    fn default() -> Self {
        Self {
            eye_height: 1.6,
            cell: 0.25,
            // 1.2 m/s at 30 frames a second.
            step: 0.04,
            min_storey_gap: 2.2,
            seed: 1,
            fov_y_deg: 60.0,
        }
    }
}

/// A generated interior path.
#[derive(Clone, Debug, PartialEq)]
pub struct InteriorPath {
    pub poses: Vec<Pose>,
    /// Floor heights of the storeys walked.
    pub storeys: Vec<f32>,
    /// Walkable cells of the region walked on each storey.
    pub cells: Vec<usize>,
    /// Moves to the next storey without an opening to climb through.
    pub jumps: u32,
    /// Moves to the next storey up a stair found in the triangles.
    pub climbs: u32,
}

/// Why no path was made.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum InteriorError {
    #[error("no floors: the scene has no up-facing horizontal triangles")]
    NoFloors,
    #[error("no walkable space indoors: no floor with a ceiling above and room to stand")]
    NoFreeSpace,
    #[error("the ground plan of {0} x {1} cells is too large (use a larger cell)")]
    TooLarge(usize, usize),
}

struct Grid {
    min: (f32, f32),
    nx: usize,
    nz: usize,
    cell: f32,
}

impl Grid {
    fn centre(&self, i: usize) -> (f32, f32) {
        let (x, z) = (i % self.nx, i / self.nx);
        (
            self.min.0 + (x as f32 + 0.5) * self.cell,
            self.min.1 + (z as f32 + 0.5) * self.cell,
        )
    }

    /// Marks the cells the xz shadow of polygon `p` touches.
    fn mark(&self, p: &[Vec3], out: &mut [bool]) {
        self.visit(p, |i| out[i] = true);
    }

    /// Calls `f` on the cells the xz shadow of polygon `p` touches (a cell
    /// may come more than once).
    fn visit(&self, p: &[Vec3], mut f: impl FnMut(usize)) {
        let lo = p.iter().fold(Vec3::INFINITY, |a, &b| a.min(b));
        let hi = p.iter().fold(Vec3::NEG_INFINITY, |a, &b| a.max(b));
        let (x0, x1) = (self.x_of(lo.x), self.x_of(hi.x));
        let (z0, z1) = (self.z_of(lo.z), self.z_of(hi.z));
        if x1 - x0 <= 1 || z1 - z0 <= 1 {
            // Thin (a wall seen from above): its box is its shadow.
            for z in z0..=z1 {
                for x in x0..=x1 {
                    f(z * self.nx + x);
                }
            }
            return;
        }
        // Edges, walked at half a cell, then the centres inside.
        for k in 0..p.len() {
            let (a, b) = (p[k], p[(k + 1) % p.len()]);
            let n = ((b - a).length() / (0.5 * self.cell)).ceil().max(1.0) as usize;
            for s in 0..=n {
                let q = a.lerp(b, s as f32 / n as f32);
                f(self.z_of(q.z) * self.nx + self.x_of(q.x));
            }
        }
        for z in z0..=z1 {
            for x in x0..=x1 {
                let (cx, cz) = self.centre(z * self.nx + x);
                if inside_xz(p, cx, cz) {
                    f(z * self.nx + x);
                }
            }
        }
    }

    fn x_of(&self, v: f32) -> usize {
        (((v - self.min.0) / self.cell).floor().max(0.0) as usize).min(self.nx - 1)
    }

    fn z_of(&self, v: f32) -> usize {
        (((v - self.min.1) / self.cell).floor().max(0.0) as usize).min(self.nz - 1)
    }
}

fn inside_xz(p: &[Vec3], x: f32, z: f32) -> bool {
    let mut sign = 0.0f32;
    for k in 0..p.len() {
        let (a, b) = (p[k], p[(k + 1) % p.len()]);
        let c = (b.x - a.x) * (z - a.z) - (b.z - a.z) * (x - a.x);
        if c != 0.0 {
            if sign != 0.0 && c.signum() != sign {
                return false;
            }
            sign = c.signum();
        }
    }
    true
}

/// The part of triangle `t` between heights `y0` and `y1`.
fn clip_y(t: &[Vec3; 3], y0: f32, y1: f32) -> Vec<Vec3> {
    let mut poly: Vec<Vec3> = t.to_vec();
    for (bound, keep_above) in [(y0, true), (y1, false)] {
        let inside = |p: &Vec3| {
            if keep_above {
                p.y >= bound
            } else {
                p.y <= bound
            }
        };
        let mut out = Vec::with_capacity(poly.len() + 1);
        for k in 0..poly.len() {
            let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
            if inside(&a) {
                out.push(a);
            }
            if inside(&a) != inside(&b) {
                out.push(a.lerp(b, (bound - a.y) / (b.y - a.y)));
            }
        }
        poly = out;
        if poly.is_empty() {
            break;
        }
    }
    poly
}

/// Storey heights: peaks of up-facing area per 0.1 unit of height.
fn storeys(tris: &[[Vec3; 3]], min_y: f32, max_y: f32, gap: f32) -> Vec<f32> {
    let bin = 0.1f32;
    let n = (((max_y - min_y) / bin).ceil() as usize).clamp(1, 1 << 20);
    let mut area = vec![0f64; n + 1];
    for t in tris {
        let nrm = (t[1] - t[0]).cross(t[2] - t[0]);
        let a = nrm.length();
        if a > 0.0 && nrm.y / a > 0.95 {
            let y = (t[0].y + t[1].y + t[2].y) / 3.0;
            area[(((y - min_y) / bin) as usize).min(n)] += f64::from(0.5 * a);
        }
    }
    let total: f64 = area.iter().sum();
    if total <= 0.0 {
        return Vec::new();
    }
    let mut idx: Vec<usize> = (0..=n).filter(|&i| area[i] >= 0.05 * total).collect();
    idx.sort_by(|&a, &b| area[b].total_cmp(&area[a]).then(a.cmp(&b)));
    let mut picked: Vec<f32> = Vec::new();
    for i in idx {
        let y = min_y + (i as f32 + 0.5) * bin;
        if picked.iter().all(|&p| (p - y).abs() >= gap) {
            picked.push(y);
        }
    }
    picked.sort_by(f32::total_cmp);
    picked
}

/// A deterministic generator (xorshift64*).
struct Rng(u64);

impl Rng {
    fn below(&mut self, n: usize) -> usize {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 33) as usize) % n.max(1)
    }
}

/// Generates an interior walk of `frames` poses through the scene made of
/// `tris` (world space).
pub fn interior_path(
    tris: &[[Vec3; 3]],
    frames: usize,
    p: &InteriorParams,
) -> Result<InteriorPath, InteriorError> {
    let lo = tris.iter().flatten().fold(Vec3::INFINITY, |a, &b| a.min(b));
    let hi = tris
        .iter()
        .flatten()
        .fold(Vec3::NEG_INFINITY, |a, &b| a.max(b));
    let levels = storeys(tris, lo.y, hi.y, p.min_storey_gap);
    if levels.is_empty() {
        return Err(InteriorError::NoFloors);
    }
    let cell = p.cell.max(1e-3);
    let g = Grid {
        min: (lo.x, lo.z),
        nx: (((hi.x - lo.x) / cell).ceil() as usize).max(1),
        nz: (((hi.z - lo.z) / cell).ceil() as usize).max(1),
        cell,
    };
    if g.nx * g.nz > 1 << 26 {
        return Err(InteriorError::TooLarge(g.nx, g.nz));
    }
    let cells = g.nx * g.nz;
    // Per storey: walkable cells, and floor cells (an opening has none).
    let mut walk: Vec<(f32, Vec<bool>, Vec<bool>)> = Vec::new();
    for &f in &levels {
        let (mut floor, mut body, mut roof) =
            (vec![false; cells], vec![false; cells], vec![false; cells]);
        for t in tris {
            let nrm = (t[1] - t[0]).cross(t[2] - t[0]);
            let up = nrm.length() > 0.0 && nrm.y.abs() / nrm.length() > 0.95;
            let (ty0, ty1) = (
                t[0].y.min(t[1].y).min(t[2].y),
                t[0].y.max(t[1].y).max(t[2].y),
            );
            if up && ty0 >= f - 0.25 && ty1 <= f + 0.25 {
                g.mark(t, &mut floor);
            }
            let (b0, b1) = (f + 0.4, f + p.eye_height + 0.3);
            if ty1 >= b0 && ty0 <= b1 {
                let part = clip_y(t, b0, b1);
                if part.len() >= 2 {
                    g.mark(&part, &mut body);
                }
            }
            if ty1 > f + p.eye_height + 0.3 && ty0 < f + 3.0 * p.min_storey_gap {
                let part = clip_y(t, f + p.eye_height + 0.3, f + 3.0 * p.min_storey_gap);
                if part.len() >= 3 {
                    g.mark(&part, &mut roof);
                }
            }
        }
        let free: Vec<bool> = (0..cells)
            .map(|i| floor[i] && !body[i] && roof[i])
            .collect();
        walk.push((f, free, floor));
    }
    let mut rng = Rng(p.seed ^ 0x9e37_79b9_7f4a_7c15);
    let mut out = InteriorPath {
        poses: Vec::with_capacity(frames),
        storeys: Vec::new(),
        cells: Vec::new(),
        jumps: 0,
        climbs: 0,
    };
    // Per storey walked: its index in `walk`, height and largest region.
    let regions: Vec<(usize, f32, Vec<usize>)> = walk
        .iter()
        .enumerate()
        .map(|(s, (f, free, _))| (s, *f, largest_region(&g, free)))
        .filter(|(_, _, r)| r.len() >= 16)
        .collect();
    if regions.is_empty() {
        return Err(InteriorError::NoFreeSpace);
    }
    let per = frames.div_ceil(regions.len());
    let mut points: Vec<Vec3> = Vec::new();
    let mut climbed: Option<usize> = None;
    for (k, (s, f, largest)) in regions.iter().enumerate() {
        // The region a climb from below arrived in (another flat of the
        // storey, say), else the storey's largest.
        let arrived = climbed.take();
        let own = arrived
            .filter(|&i| walk[*s].1[i])
            .map(|i| region_containing(&g, &walk[*s].1, i))
            .filter(|r| r.len() >= 16);
        // Not arrived by a stair: the largest region, unless no stair goes
        // up from it and one goes up from another region of this storey
        // (a stair hall beside the flats).
        let start_region = match (&own, regions.get(k + 1)) {
            (None, Some((ns, nf, _))) => {
                climbing_region(tris, &g, (*f, &walk[*s].1), (*nf, &walk[*ns].1), largest, p)
            }
            _ => None,
        };
        let region = own.as_ref().or(start_region.as_ref()).unwrap_or(largest);
        out.storeys.push(*f);
        out.cells.push(region.len());
        let y = f + p.eye_height;
        let at = |i: usize| {
            let (x, z) = g.centre(i);
            Vec3::new(x, y, z)
        };
        let mut free = vec![false; cells];
        for &i in region {
            free[i] = true;
        }
        // Enter where the climb from below arrived; otherwise jump (above
        // where the walk below ended, if that is walkable here).
        let mut cur = match (arrived, points.last()) {
            (Some(i), _) if free[i] => i,
            (_, Some(q)) => {
                out.jumps += 1;
                let i = cell_of(&g, *q);
                if free[i] {
                    i
                } else {
                    region[rng.below(region.len())]
                }
            }
            (_, None) => region[rng.below(region.len())],
        };
        points.push(at(cur));
        let budget = (per as f32 * p.step) * (k + 1) as f32;
        let mut length = path_length(&points);
        // To random cells until this storey's share of the frames is walked
        // (a route is cut there, so that every storey gets its share).
        'walk: while length < budget {
            let target = region[rng.below(region.len())];
            let route = bfs(&g, &free, cur, target);
            for &i in route.iter().skip(1) {
                let q = at(i);
                length += q.distance(*points.last().expect("a point"));
                points.push(q);
                cur = i;
                if length >= budget {
                    break 'walk;
                }
            }
            cur = target;
        }
        // Up the stairs to the next storey walked, if a stair joins the two;
        // else through an opening in the next storey's floor, if one is near.
        if let Some((ns, nf, _)) = regions.get(k + 1) {
            let lo = stairs::Storey {
                floor: *f,
                free: &free,
            };
            let hi = stairs::Storey {
                floor: *nf,
                free: &walk[*ns].1,
            };
            if let Some(c) = stairs::climb(tris, &g, lo, hi, &[cur], p.eye_height) {
                points.extend(c.points);
                climbed = Some(c.end);
                out.climbs += 1;
                continue;
            }
        }
        if let Some((nf, nfree, nfloor)) = walk.iter().find(|w| w.0 > *f) {
            // The nearest such opening along the floor.
            let route = route_to(&g, &free, cur, |i| !nfloor[i] && near_free(&g, nfree, i));
            if let Some(&i) = route.last() {
                points.extend(route.iter().skip(1).map(|&c| at(c)));
                points.push(at(i) + Vec3::Y * (nf - f));
                climbed = Some(i);
            }
        }
    }
    out.poses = follow(&points, frames, p);
    Ok(out)
}

/// The region of a storey (`(floor height, free cells)`) to walk before
/// climbing to the storey `up`: `None` when a stair goes up from its
/// `largest` region, or when none goes up from any region; otherwise the
/// region from which the shortest climb starts.
fn climbing_region(
    tris: &[[Vec3; 3]],
    g: &Grid,
    (floor, free): (f32, &[bool]),
    up: (f32, &[bool]),
    largest: &[usize],
    p: &InteriorParams,
) -> Option<Vec<usize>> {
    let hi = stairs::Storey {
        floor: up.0,
        free: up.1,
    };
    let mut mask = vec![false; free.len()];
    for &i in largest {
        mask[i] = true;
    }
    let lo = stairs::Storey { floor, free: &mask };
    if stairs::climb(tris, g, lo, hi, largest, p.eye_height).is_some() {
        return None;
    }
    let all: Vec<usize> = (0..free.len()).filter(|&i| free[i]).collect();
    let lo = stairs::Storey { floor, free };
    let c = stairs::climb(tris, g, lo, hi, &all, p.eye_height)?;
    Some(region_containing(g, free, c.start)).filter(|r| r.len() >= 16)
}

/// The triangles of a scene at full resolution: every leaf's finest static
/// rep (the finest level kept beside a view-dependence tree).
pub fn scene_triangles<S: crate::io::ByteSource>(
    scene: &crate::format::SceneFile<S>,
) -> Result<Vec<[Vec3; 3]>, crate::format::FormatError> {
    leaf_triangles(scene, |_, _| true)
}

/// The triangles a walk must go around: [`scene_triangles`] without those
/// of the objects [`walk_through`] names (from the scene's object section;
/// a scene without one keeps all). Also returns how many objects were left
/// out.
pub fn obstacle_triangles<S: crate::io::ByteSource>(
    scene: &crate::format::SceneFile<S>,
) -> Result<(Vec<[Vec3; 3]>, usize), crate::format::FormatError> {
    let table = scene.read_objects()?;
    let skel = scene.skeleton();
    let mut verdict: Vec<Option<bool>> = vec![None; table.len()];
    let mut left_out = 0;
    let tris = leaf_triangles(scene, |node, tri| {
        let Some(o) = table.object_at(skel, node, tri) else {
            return true;
        };
        let Some(v) = verdict.get_mut(o as usize) else {
            return true;
        };
        let pass = *v.get_or_insert_with(|| {
            let through = table.info(o).is_some_and(walk_through);
            left_out += usize::from(through);
            through
        });
        !pass
    })?;
    Ok((tris, left_out))
}

/// Whether an object, by the class its name starts with (as IFC exporters
/// name nodes), does not stand in a walk's way: an opening's void
/// (`IfcOpeningElement`, which some exporters write as a solid box in
/// every door and window hole), a room's volume (`IfcSpace`), or a door
/// (exported shut; the walk opens it).
pub fn walk_through(info: &str) -> bool {
    let Ok(v) = serde_json::from_str::<serde_json::Value>(info) else {
        return false;
    };
    let name = v.get("name").and_then(|n| n.as_str()).unwrap_or("");
    ifc_class_in(name, &["IfcOpeningElement", "IfcSpace", "IfcDoor"])
}

/// Whether an object's name starts with one of the IFC `classes` as a
/// whole word (`IfcDoor:…` is of class `IfcDoor`, `IfcDoorStyle` is not),
/// as IFC exporters name nodes.
pub fn ifc_class_in(name: &str, classes: &[&str]) -> bool {
    classes.iter().any(|c| {
        name.strip_prefix(c)
            .is_some_and(|rest| !rest.starts_with(|ch: char| ch.is_alphanumeric()))
    })
}

/// The finest static reps' triangles for which `keep(leaf, triangle)`.
fn leaf_triangles<S: crate::io::ByteSource>(
    scene: &crate::format::SceneFile<S>,
    mut keep: impl FnMut(u32, u32) -> bool,
) -> Result<Vec<[Vec3; 3]>, crate::format::FormatError> {
    let s = scene.skeleton();
    let mut out = Vec::new();
    for (i, n) in s.nodes.iter().enumerate().filter(|(_, n)| n.is_leaf()) {
        let finest = (n.first_rep..n.first_rep + n.rep_count)
            .rev()
            .find(|&r| !s.reps[r as usize].is_paged());
        let Some(r) = finest else { continue };
        let m = scene.read_rep(r)?;
        let pos: Vec<Vec3> = m
            .vertices
            .iter()
            .map(|v| Vec3::from(m.position(v)))
            .collect();
        for (k, t) in m.indices.chunks_exact(3).enumerate() {
            if keep(i as u32, k as u32) {
                out.push([pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize]]);
            }
        }
    }
    Ok(out)
}

fn cell_of(g: &Grid, q: Vec3) -> usize {
    g.z_of(q.z) * g.nx + g.x_of(q.x)
}

fn near_free(g: &Grid, free: &[bool], i: usize) -> bool {
    let (x, z) = ((i % g.nx) as isize, (i / g.nx) as isize);
    (-2..=2).any(|dz| {
        (-2..=2).any(|dx| {
            let (a, b) = (x + dx, z + dz);
            a >= 0
                && b >= 0
                && (a as usize) < g.nx
                && (b as usize) < g.nz
                && free[b as usize * g.nx + a as usize]
        })
    })
}

fn neighbours(g: &Grid, i: usize) -> impl Iterator<Item = usize> + '_ {
    let (x, z) = (i % g.nx, i / g.nx);
    [
        (x > 0).then(|| i - 1),
        (x + 1 < g.nx).then(|| i + 1),
        (z > 0).then(|| i - g.nx),
        (z + 1 < g.nz).then(|| i + g.nx),
    ]
    .into_iter()
    .flatten()
}

/// The largest 4-connected set of `free` cells, in ascending order.
fn largest_region(g: &Grid, free: &[bool]) -> Vec<usize> {
    let mut seen = vec![false; free.len()];
    let mut best: Vec<usize> = Vec::new();
    for s in 0..free.len() {
        if free[s] && !seen[s] {
            let region = flood(g, free, s, &mut seen);
            if region.len() > best.len() {
                best = region;
            }
        }
    }
    best.sort_unstable();
    best
}

/// The 4-connected set of `free` cells holding cell `i`, in ascending order.
fn region_containing(g: &Grid, free: &[bool], i: usize) -> Vec<usize> {
    let mut r = flood(g, free, i, &mut vec![false; free.len()]);
    r.sort_unstable();
    r
}

/// The free cells reached from free cell `s` (marked in `seen`).
fn flood(g: &Grid, free: &[bool], s: usize, seen: &mut [bool]) -> Vec<usize> {
    let mut region = vec![s];
    seen[s] = true;
    let mut k = 0;
    while k < region.len() {
        let i = region[k];
        k += 1;
        for n in neighbours(g, i) {
            if free[n] && !seen[n] {
                seen[n] = true;
                region.push(n);
            }
        }
    }
    region
}

/// A shortest 4-connected route through `free` cells from `a` to the
/// nearest cell where `goal` holds (empty when none is reachable).
fn route_to(g: &Grid, free: &[bool], a: usize, goal: impl Fn(usize) -> bool) -> Vec<usize> {
    let mut prev = vec![usize::MAX; free.len()];
    let mut q = VecDeque::from([a]);
    prev[a] = a;
    while let Some(i) = q.pop_front() {
        if goal(i) {
            let mut route = vec![i];
            while *route.last().expect("a cell") != a {
                route.push(prev[*route.last().expect("a cell")]);
            }
            route.reverse();
            return route;
        }
        for n in neighbours(g, i) {
            if free[n] && prev[n] == usize::MAX {
                prev[n] = i;
                q.push_back(n);
            }
        }
    }
    Vec::new()
}

/// A shortest 4-connected route from `a` to `b` through `free` cells
/// (`[a]` when there is none).
fn bfs(g: &Grid, free: &[bool], a: usize, b: usize) -> Vec<usize> {
    let route = route_to(g, free, a, |i| i == b);
    if route.is_empty() { vec![a] } else { route }
}

fn path_length(p: &[Vec3]) -> f32 {
    p.windows(2).map(|w| w[0].distance(w[1])).sum()
}

/// Poses `step` apart along the polyline, looking at a point a few steps
/// ahead on it (turns are smoothed).
fn follow(points: &[Vec3], frames: usize, p: &InteriorParams) -> Vec<Pose> {
    let mut cum = vec![0f32];
    for w in points.windows(2) {
        cum.push(cum.last().expect("a length") + w[0].distance(w[1]));
    }
    let total = *cum.last().expect("a length");
    let at = |s: f32| -> Vec3 {
        let s = s.clamp(0.0, total);
        let k = cum
            .partition_point(|&c| c <= s)
            .clamp(1, points.len().max(2) - 1);
        if points.len() < 2 {
            return points[0];
        }
        let (a, b) = (points[k - 1], points[k]);
        let seg = cum[k] - cum[k - 1];
        if seg <= 0.0 {
            a
        } else {
            a.lerp(b, (s - cum[k - 1]) / seg)
        }
    };
    let look = 30.0 * p.step;
    (0..frames)
        .map(|i| {
            let s = i as f32 * p.step;
            let eye = at(s);
            let mut ahead = Vec3::ZERO;
            for k in 1..=8 {
                ahead += at(s + look * k as f32 / 8.0);
            }
            let mut dir = ahead / 8.0 - eye;
            dir.y *= 0.3;
            if dir.length() < 1e-4 {
                dir = Vec3::NEG_Z;
            }
            Pose::look_at(eye, eye + dir, p.fov_y_deg)
        })
        .collect()
}

mod stairs;
#[cfg(test)]
mod tests;
