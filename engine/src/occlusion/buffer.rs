//! A conservative occlusion buffer on the CPU.
//!
//! The viewport is cut into tiles of 4 x 4 pixels. A tile keeps, for the
//! sixteen pixel centres it holds (the very samples a GPU rasterises), an
//! upper bound `full` on the depth seen there: every one of its samples is
//! covered by some occluder no farther than `full`. Coverage is gathered
//! per sample (a 16-bit mask) from triangles that cover the tile only in
//! part, so two triangles sharing an edge cover it together (a wall's
//! diagonal leaves no holes). Depth is the distance along the view
//! direction; a triangle's bound over a tile is the farthest its plane
//! reaches at the tile's corner samples (1/depth is linear on the screen),
//! and never beyond its farthest vertex.
//!
//! A box is occluded when every tile its screen rectangle touches is
//! covered nearer than the box's nearest corner. The test goes through a
//! max pyramid over the tiles. Everything is plain `f32` arithmetic on the
//! camera's projection, so it decides alike under lavapipe and on a GPU;
//! a sample on an edge shared by two triangles goes to exactly one of them.

use glam::{Vec2, Vec3};

use crate::camera::View;

/// Pixels per tile side.
pub const TILE: u32 = 4;
const FULL: u16 = u16::MAX;

/// Relative depth margin of the box test.
pub const DEPTH_MARGIN: f32 = 1e-4;

/// The camera's projection as the renderers use it (see `Pose::project`).
#[derive(Clone, Copy, Debug)]
pub struct Projector {
    view: View,
    /// `rotation⁻¹`, as columns of a 3x3 matrix.
    inv: glam::Mat3,
    sx: f32,
    sy: f32,
}

impl Projector {
    pub fn new(view: &View) -> Self {
        let tan = (0.5 * view.pose.fov_y_deg.to_radians()).tan();
        let (w, h) = (view.width_px.max(1) as f32, view.height_px.max(1) as f32);
        Self {
            view: *view,
            inv: glam::Mat3::from_quat(view.pose.rotation.inverse()),
            sx: 0.5 * w / (tan * w / h),
            sy: 0.5 * h / tan,
        }
    }

    /// The view projected.
    pub fn view(&self) -> &View {
        &self.view
    }

    /// Camera space: x right, y up, `z` the depth along the view.
    pub fn camera(&self, p: Vec3) -> Vec3 {
        let c = self.inv * (p - self.view.pose.position);
        Vec3::new(c.x, c.y, -c.z)
    }

    /// Pixel coordinates of a camera-space point in front of the eye.
    pub fn screen(&self, c: Vec3) -> Vec2 {
        let (w, h) = (self.view.width_px as f32, self.view.height_px as f32);
        Vec2::new(0.5 * w + c.x / c.z * self.sx, 0.5 * h - c.y / c.z * self.sy)
    }

    /// The pixel centres of the box `min..max`'s screen rectangle and the
    /// depth of its nearest corner, as the box test takes them: `None` when
    /// the box reaches the near plane or its rectangle holds no pixel
    /// centre of the viewport (nothing of it is drawn, but that is not
    /// occlusion).
    pub fn box_samples(&self, min: Vec3, max: Vec3) -> Option<BoxSamples> {
        let near = self.view.near;
        let mut lo = Vec2::splat(f32::INFINITY);
        let mut hi = Vec2::splat(f32::NEG_INFINITY);
        let mut z_near = f32::INFINITY;
        for k in 0..8 {
            let p = Vec3::new(
                if k & 1 == 0 { min.x } else { max.x },
                if k & 2 == 0 { min.y } else { max.y },
                if k & 4 == 0 { min.z } else { max.z },
            );
            let c = self.camera(p);
            if c.z < near * 1.001 {
                return None;
            }
            let s = self.screen(c);
            lo = lo.min(s);
            hi = hi.max(s);
            z_near = z_near.min(c.z);
        }
        let (w, h) = (self.view.width_px as f32, self.view.height_px as f32);
        let px0 = (lo.x - 0.5).ceil().max(0.0);
        let py0 = (lo.y - 0.5).ceil().max(0.0);
        let px1 = (hi.x - 0.5).floor().min(w - 1.0);
        let py1 = (hi.y - 0.5).floor().min(h - 1.0);
        (px0 <= px1 && py0 <= py1).then_some(BoxSamples {
            x: [px0 as u32, px1 as u32],
            y: [py0 as u32, py1 as u32],
            z_near,
        })
    }
}

/// A box's pixel centres on the screen ([`Projector::box_samples`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxSamples {
    /// First and last pixel column and row, inclusive.
    pub x: [u32; 2],
    pub y: [u32; 2],
    /// Depth of the box's nearest corner along the view.
    pub z_near: f32,
}

/// Clips a camera-space triangle ([`Projector::camera`]) to `z >= near`
/// (Sutherland–Hodgman, one plane): the polygon's corners (0, 3 or 4) go to
/// `out`, and their count is returned. Cut corners lie exactly on the plane.
pub fn clip_near(c: &[Vec3; 3], near: f32, out: &mut [Vec3; 4]) -> usize {
    let mut n = 0;
    for i in 0..3 {
        let (a, b) = (c[i], c[(i + 1) % 3]);
        let (ia, ib) = (a.z >= near, b.z >= near);
        if ia {
            out[n] = a;
            n += 1;
        }
        if ia != ib {
            let s = (near - a.z) / (b.z - a.z);
            let mut p = a.lerp(b, s);
            p.z = near;
            out[n] = p;
            n += 1;
        }
    }
    n
}

/// The x extent of triangle `s` between the heights `ya` and `yb`.
fn row_span(s: &[Vec2; 3], ya: f32, yb: f32) -> Option<(f32, f32)> {
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for i in 0..3 {
        let (a, b) = (s[i], s[(i + 1) % 3]);
        if a.y >= ya && a.y <= yb {
            lo = lo.min(a.x);
            hi = hi.max(a.x);
        }
        for y in [ya, yb] {
            if (a.y - y) * (b.y - y) < 0.0 {
                let x = a.x + (b.x - a.x) * (y - a.y) / (b.y - a.y);
                lo = lo.min(x);
                hi = hi.max(x);
            }
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// One edge's function over the screen.
#[derive(Clone, Copy, Debug)]
struct Edge {
    origin: Vec2,
    dir: Vec2,
    /// +1 or -1: the inside is where `dir.perp_dot(p - origin) * side > 0`.
    side: f32,
    /// A sample exactly on the edge is inside (a top-left rule).
    ties_in: bool,
}

impl Edge {
    /// The edge from `a` to `b` of a triangle whose signed area has sign `sign`.
    fn new(a: Vec2, b: Vec2, sign: f32) -> Self {
        let d = (b - a) * sign;
        let ties_in = d.y > 0.0 || (d.y == 0.0 && d.x < 0.0);
        let (origin, to, flip) = if (a.x, a.y) < (b.x, b.y) {
            (a, b, 1.0)
        } else {
            (b, a, -1.0)
        };
        Self {
            origin,
            dir: to - origin,
            side: sign * flip,
            ties_in,
        }
    }

    fn inside(&self, p: Vec2) -> bool {
        let e = self.dir.perp_dot(p - self.origin) * self.side;
        e > 0.0 || (e == 0.0 && self.ties_in)
    }
}

#[derive(Clone, Copy, Debug)]
struct Tile {
    /// Depth bound over every sample (infinity: not known covered).
    full: f32,
    /// Samples covered by the partial layer, and its farthest depth.
    mask: u16,
    layer: f32,
    /// Samples beyond the viewport (never drawn: always covered).
    outside: u16,
}

/// The occlusion buffer of one view.
#[derive(Clone, Debug)]
pub struct OcclusionBuffer {
    proj: Projector,
    tw: u32,
    th: u32,
    tiles: Vec<Tile>,
    /// Max pyramid over `tiles[..].full`: level 1 halves each side, and so on.
    levels: Vec<(u32, u32, Vec<f32>)>,
    pub triangles: u64,
}

impl OcclusionBuffer {
    /// An empty buffer (nothing covered) for `view`.
    pub fn new(view: &View) -> Self {
        let tw = view.width_px.div_ceil(TILE).max(1);
        let th = view.height_px.div_ceil(TILE).max(1);
        let mut b = Self {
            proj: Projector::new(view),
            tw,
            th,
            tiles: Vec::new(),
            levels: Vec::new(),
            triangles: 0,
        };
        b.reset(view);
        b
    }

    /// Empties the buffer for `view` (keeping its allocation; the tiles'
    /// samples beyond the viewport are worked out again only when its size
    /// changes).
    pub fn reset(&mut self, view: &View) {
        let same_size = (self.proj.view.width_px, self.proj.view.height_px)
            == (view.width_px, view.height_px)
            && !self.tiles.is_empty();
        self.proj = Projector::new(view);
        self.levels.clear();
        self.triangles = 0;
        if same_size {
            for t in &mut self.tiles {
                *t = Tile {
                    full: f32::INFINITY,
                    mask: t.outside,
                    layer: 0.0,
                    outside: t.outside,
                };
            }
            return;
        }
        self.tw = view.width_px.div_ceil(TILE).max(1);
        self.th = view.height_px.div_ceil(TILE).max(1);
        self.tiles.clear();
        let (w, h) = (view.width_px, view.height_px);
        for ty in 0..self.th {
            for tx in 0..self.tw {
                // Samples beyond the viewport are never drawn: count them covered.
                let mut outside = 0u16;
                for j in 0..TILE {
                    for i in 0..TILE {
                        if tx * TILE + i >= w || ty * TILE + j >= h {
                            outside |= 1 << (j * TILE + i);
                        }
                    }
                }
                self.tiles.push(Tile {
                    full: f32::INFINITY,
                    mask: outside,
                    layer: 0.0,
                    outside,
                });
            }
        }
    }

    /// Adds one occluding triangle (world space; either winding).
    pub fn add_triangle(&mut self, t: [Vec3; 3]) {
        self.levels.clear();
        let near = self.proj.view.near;
        let c = t.map(|p| self.proj.camera(p));
        if c.iter().all(|v| v.z >= near) {
            self.add_clipped(&c);
            return;
        }
        let mut poly: [Vec3; 4] = [Vec3::ZERO; 4];
        let n = clip_near(&c, near, &mut poly);
        if n >= 3 {
            self.add_clipped(&[poly[0], poly[1], poly[2]]);
        }
        if n == 4 {
            self.add_clipped(&[poly[0], poly[2], poly[3]]);
        }
    }

    /// A triangle in camera space, wholly in front of the near plane.
    fn add_clipped(&mut self, c: &[Vec3; 3]) {
        let s = c.map(|v| self.proj.screen(v));
        let area = (s[1] - s[0]).perp_dot(s[2] - s[0]);
        if !area.is_finite() || area.abs() < 1e-6 {
            return;
        }
        self.triangles += 1;
        // Edge functions, positive inside. Each is computed from its end
        // points in a fixed order, so the two triangles of a shared edge get
        // the same value with opposite signs, and a sample exactly on it
        // goes to one of them (as a GPU's fill rule gives it to one).
        let sign = area.signum();
        let edges: [Edge; 3] = std::array::from_fn(|i| Edge::new(s[i], s[(i + 1) % 3], sign));
        let inside = |p: Vec2| -> bool { edges.iter().all(|e| e.inside(p)) };
        // 1/depth is linear on the screen: q = qa * x + qb * y + qc.
        let q = c.map(|v| 1.0 / v.z);
        let (e1, e2) = (s[1] - s[0], s[2] - s[0]);
        let qa = ((q[1] - q[0]) * e2.y - (q[2] - q[0]) * e1.y) / area;
        let qb = ((q[2] - q[0]) * e1.x - (q[1] - q[0]) * e2.x) / area;
        let qc = q[0] - qa * s[0].x - qb * s[0].y;
        let q_far = q[0].min(q[1]).min(q[2]);
        let z_near = 1.0 / q[0].max(q[1]).max(q[2]);
        let lo = s[0].min(s[1]).min(s[2]);
        let hi = s[0].max(s[1]).max(s[2]);
        let (w, h) = (
            self.proj.view.width_px as f32,
            self.proj.view.height_px as f32,
        );
        if hi.x < 0.0 || hi.y < 0.0 || lo.x > w || lo.y > h {
            return;
        }
        let t = TILE as f32;
        let tx0 = (lo.x.max(0.0) / t) as u32;
        let ty0 = (lo.y.max(0.0) / t) as u32;
        let tx1 = ((hi.x.min(w - 1.0) / t) as u32).min(self.tw - 1);
        let ty1 = ((hi.y.min(h - 1.0) / t) as u32).min(self.th - 1);
        for ty in ty0..=ty1 {
            // Only the tiles of this row that the triangle reaches.
            let Some((sx0, sx1)) = row_span(&s, (ty * TILE) as f32, ((ty + 1) * TILE) as f32)
            else {
                continue;
            };
            let rx0 = ((sx0.max(0.0) / t) as u32).max(tx0);
            let rx1 = ((sx1.min(w - 1.0).max(0.0) / t) as u32).min(tx1);
            for tx in rx0..=rx1 {
                let x0 = (tx * TILE) as f32 + 0.5;
                let y0 = (ty * TILE) as f32 + 0.5;
                let x1 = x0 + t - 1.0;
                let y1 = y0 + t - 1.0;
                let corners = [
                    Vec2::new(x0, y0),
                    Vec2::new(x1, y0),
                    Vec2::new(x0, y1),
                    Vec2::new(x1, y1),
                ];
                let i = (ty * self.tw + tx) as usize;
                if z_near >= self.tiles[i].full {
                    continue;
                }
                // Farthest the plane reaches over the tile's samples, and
                // no farther than the farthest vertex.
                let q_min = corners
                    .iter()
                    .map(|p| qa * p.x + qb * p.y + qc)
                    .fold(f32::INFINITY, f32::min)
                    .max(q_far);
                let z = 1.0 / q_min;
                if z >= self.tiles[i].full {
                    // Behind what already covers the tile.
                    continue;
                }
                let mask = if corners.iter().all(|&p| inside(p)) {
                    FULL
                } else {
                    if edges.iter().any(|e| corners.iter().all(|&p| !e.inside(p))) {
                        continue;
                    }
                    let mut m = 0u16;
                    for j in 0..TILE {
                        for i in 0..TILE {
                            if inside(Vec2::new(x0 + i as f32, y0 + j as f32)) {
                                m |= 1 << (j * TILE + i);
                            }
                        }
                    }
                    if m == 0 {
                        continue;
                    }
                    m
                };
                self.cover(i, mask, z);
            }
        }
    }

    /// Samples `mask` of tile `i` are covered no farther than `z`.
    fn cover(&mut self, i: usize, mask: u16, z: f32) {
        let tile = &mut self.tiles[i];
        if z >= tile.full {
            return;
        }
        let merged = tile.mask | mask;
        if merged == FULL {
            // Every sample is covered by the layer's triangles and this one.
            tile.full = tile.full.min(tile.layer.max(z));
            tile.mask = tile.outside;
            tile.layer = 0.0;
        } else {
            tile.mask = merged;
            tile.layer = tile.layer.max(z);
        }
    }

    fn pyramid(&mut self) {
        if !self.levels.is_empty() {
            return;
        }
        let base: Vec<f32> = self.tiles.iter().map(|t| t.full).collect();
        self.levels.push((self.tw, self.th, base));
        loop {
            let (w, h, ref prev) = *self.levels.last().expect("level 0");
            if w == 1 && h == 1 {
                break;
            }
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            let mut next = vec![0f32; (nw * nh) as usize];
            for y in 0..nh {
                for x in 0..nw {
                    let mut m = 0f32;
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (sx, sy) = ((2 * x + dx).min(w - 1), (2 * y + dy).min(h - 1));
                        m = m.max(prev[(sy * w + sx) as usize]);
                    }
                    next[(y * nw + x) as usize] = m;
                }
            }
            self.levels.push((nw, nh, next));
        }
    }

    /// Whether the box `min..max` is hidden behind the occluders.
    pub fn box_occluded(&mut self, min: Vec3, max: Vec3) -> bool {
        let Some(b) = self.proj.box_samples(min, max) else {
            return false;
        };
        self.pyramid();
        let limit = b.z_near * (1.0 - DEPTH_MARGIN);
        let r = [b.x[0] / TILE, b.y[0] / TILE, b.x[1] / TILE, b.y[1] / TILE];
        // The coarsest level at which the range spans at most 2 x 2 texels.
        let mut level = 0;
        while level + 1 < self.levels.len()
            && ((r[2] >> level) - (r[0] >> level) > 1 || (r[3] >> level) - (r[1] >> level) > 1)
        {
            level += 1;
        }
        for y in (r[1] >> level)..=(r[3] >> level) {
            for x in (r[0] >> level)..=(r[2] >> level) {
                if !self.texel_below(level, x, y, &r, limit) {
                    return false;
                }
            }
        }
        true
    }

    /// Every tile of texel `(x, y)` at `level` within the tile range `r` is
    /// covered nearer than `limit`.
    fn texel_below(&self, level: usize, x: u32, y: u32, r: &[u32; 4], limit: f32) -> bool {
        let (w, _, ref v) = self.levels[level];
        if v[(y * w + x) as usize] < limit {
            return true;
        }
        if level == 0 {
            return false;
        }
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (cx, cy) = (2 * x + dx, 2 * y + dy);
            let s = level - 1;
            let (cw, ch, _) = self.levels[s];
            if cx >= cw || cy >= ch {
                continue;
            }
            // Only the children that hold tiles of the range.
            let (a0, a1) = (cx << s, ((cx + 1) << s) - 1);
            let (b0, b1) = (cy << s, ((cy + 1) << s) - 1);
            if a1 < r[0] || a0 > r[2] || b1 < r[1] || b0 > r[3] {
                continue;
            }
            if !self.texel_below(s, cx, cy, r, limit) {
                return false;
            }
        }
        true
    }

    /// Tiles known covered (for reports and tests).
    pub fn covered_tiles(&self) -> usize {
        self.tiles.iter().filter(|t| t.full.is_finite()).count()
    }
}

#[cfg(test)]
mod tests;
