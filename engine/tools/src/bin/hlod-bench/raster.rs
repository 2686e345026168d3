//! A triangle-id depth buffer on the CPU, for `--anatomy`: every front
//! triangle is rasterised at the view's full resolution (one sample at
//! each pixel centre, nearest wins), so that the triangles that own a
//! pixel at the end are the visible ones, and those that covered samples
//! but own none were hidden. Triangles are clipped at the near plane and
//! projected as the occlusion culler does (`engine::occlusion`'s
//! `Projector` and `clip_near`); depth is compared as `1/z`, which is
//! linear on the screen.

use glam::Vec3;

use engine::camera::View;
use engine::occlusion::{DEPTH_MARGIN, Projector, clip_near};

/// No triangle owns the pixel.
pub const NONE: u32 = u32::MAX;

/// What one triangle did in the buffer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Drawn {
    /// Pixel centres the triangle covered, nearest or not.
    pub samples: u32,
    /// Area on the screen in square pixels (after clipping; 0 off-screen).
    pub area: f32,
    /// Whether any part of it lies in the viewport.
    pub on_screen: bool,
}

/// The camera's projection and a depth buffer of triangle ids.
pub struct IdBuffer {
    w: u32,
    h: u32,
    proj: Projector,
    inv_z: Vec<f32>,
    owner: Vec<u32>,
}

impl IdBuffer {
    pub fn new(view: &View) -> Self {
        let (w, h) = (view.width_px.max(1), view.height_px.max(1));
        Self {
            w,
            h,
            proj: Projector::new(view),
            inv_z: vec![0.0; (w * h) as usize],
            owner: vec![NONE; (w * h) as usize],
        }
    }

    /// The owner of every pixel, row by row.
    pub fn owners(&self) -> &[u32] {
        &self.owner
    }

    /// Rasterises the scene triangle `tri` as `id`.
    pub fn triangle(&mut self, id: u32, tri: [Vec3; 3]) -> Drawn {
        let cam = tri.map(|p| self.proj.camera(p));
        let mut poly = [Vec3::ZERO; 4];
        let n = clip_near(&cam, self.proj.view().near.max(1e-6), &mut poly);
        let mut drawn = Drawn::default();
        if n < 3 {
            return drawn;
        }
        let s = poly.map(|c| {
            let p = self.proj.screen(c);
            (p.x, p.y, 1.0 / c.z)
        });
        for k in 1..n - 1 {
            let d = self.screen_triangle(id, [s[0], s[k], s[k + 1]]);
            drawn.samples += d.samples;
            drawn.area += d.area;
            drawn.on_screen |= d.on_screen;
        }
        drawn
    }

    /// The buffer's depth (`1/z`, 0 where nothing is drawn) at the
    /// granularity of `tile` x `tile` pixels: a tile holds its farthest
    /// sample, as an occlusion buffer of that tile size would at best.
    pub fn depth_tiles(&self, tile: u32) -> DepthTiles {
        let t = tile.max(1);
        let (tw, th) = (self.w.div_ceil(t), self.h.div_ceil(t));
        let mut inv_z = vec![f32::INFINITY; (tw * th) as usize];
        for y in 0..self.h {
            for x in 0..self.w {
                let k = ((y / t) * tw + x / t) as usize;
                inv_z[k] = inv_z[k].min(self.inv_z[(y * self.w + x) as usize]);
            }
        }
        DepthTiles {
            proj: self.proj,
            tile: t,
            tw,
            inv_z,
        }
    }

    fn screen_triangle(&mut self, id: u32, v: [(f32, f32, f32); 3]) -> Drawn {
        let [a, b, c] = v;
        let area2 = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
        let (wf, hf) = (self.w as f32, self.h as f32);
        let min_x = a.0.min(b.0).min(c.0);
        let max_x = a.0.max(b.0).max(c.0);
        let min_y = a.1.min(b.1).min(c.1);
        let max_y = a.1.max(b.1).max(c.1);
        let on_screen = max_x >= 0.0 && min_x <= wf && max_y >= 0.0 && min_y <= hf;
        let mut d = Drawn {
            samples: 0,
            area: 0.5 * area2.abs(),
            on_screen,
        };
        if !on_screen || area2 == 0.0 || !area2.is_finite() {
            return d;
        }
        // Pixel centres x + 0.5 inside the box, clamped to the viewport.
        let x0 = (min_x - 0.5).ceil().max(0.0) as u32;
        let x1 = ((max_x - 0.5).floor().min(wf - 1.0)).max(-1.0);
        let y0 = (min_y - 0.5).ceil().max(0.0) as u32;
        let y1 = ((max_y - 0.5).floor().min(hf - 1.0)).max(-1.0);
        if x1 < 0.0 || y1 < 0.0 {
            return d;
        }
        let (x1, y1) = (x1 as u32, y1 as u32);
        let inv_area = 1.0 / area2;
        let edge = |p: (f32, f32, f32), q: (f32, f32, f32), x: f32, y: f32| {
            (q.0 - p.0) * (y - p.1) - (q.1 - p.1) * (x - p.0)
        };
        // Each weight is linear in x along a row: the span where all three
        // are non-negative is found per row (a long thin diagonal triangle
        // would otherwise test its whole box), one pixel wider on each side
        // for rounding, and every pixel in it is tested exactly.
        let span = |p: (f32, f32, f32), q: (f32, f32, f32), py: f32, lo: &mut f32, hi: &mut f32| {
            let a = -(q.1 - p.1) * inv_area;
            let v0 = edge(p, q, 0.0, py) * inv_area;
            if a > 0.0 {
                *lo = lo.max(-v0 / a);
            } else if a < 0.0 {
                *hi = hi.min(-v0 / a);
            } else if v0 < 0.0 {
                *hi = f32::NEG_INFINITY;
            }
        };
        for y in y0..=y1 {
            let py = y as f32 + 0.5;
            let (mut lo, mut hi) = (f32::NEG_INFINITY, f32::INFINITY);
            span(b, c, py, &mut lo, &mut hi);
            span(c, a, py, &mut lo, &mut hi);
            span(a, b, py, &mut lo, &mut hi);
            if lo.is_nan() || hi.is_nan() || lo > hi + 2.0 {
                continue;
            }
            let sx0 = ((lo - 0.5).ceil() - 1.0).max(x0 as f32) as u32;
            let sx1 = ((hi - 0.5).floor() + 1.0).min(x1 as f32);
            if sx1 < sx0 as f32 {
                continue;
            }
            for x in sx0..=sx1 as u32 {
                let px = x as f32 + 0.5;
                // Barycentric weights, positive inside for either winding.
                let w0 = edge(b, c, px, py) * inv_area;
                let w1 = edge(c, a, px, py) * inv_area;
                let w2 = edge(a, b, px, py) * inv_area;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                d.samples += 1;
                let iz = w0 * a.2 + w1 * b.2 + w2 * c.2;
                let k = (y * self.w + x) as usize;
                if iz > self.inv_z[k] {
                    self.inv_z[k] = iz;
                    self.owner[k] = id;
                }
            }
        }
        d
    }
}

/// A depth buffer at tile granularity ([`IdBuffer::depth_tiles`]), for
/// the box test of an ideal occlusion culler.
pub struct DepthTiles {
    proj: Projector,
    tile: u32,
    tw: u32,
    inv_z: Vec<f32>,
}

impl DepthTiles {
    /// Whether the box `min..max` is hidden as the engine's culler decides
    /// (`OcclusionBuffer::box_occluded`: every tile its screen rectangle
    /// touches is nearer than its nearest corner, by the culler's relative
    /// [`DEPTH_MARGIN`]; a box reaching the near plane or sampling no pixel centre is
    /// not hidden), but against this complete depth buffer.
    pub fn box_hidden(&self, min: Vec3, max: Vec3) -> bool {
        let Some(b) = self.proj.box_samples(min, max) else {
            return false;
        };
        // Nearer than the culler's limit is 1/z above this.
        let limit = 1.0 / (b.z_near * (1.0 - DEPTH_MARGIN));
        let t = self.tile;
        for ty in b.y[0] / t..=b.y[1] / t {
            for tx in b.x[0] / t..=b.x[1] / t {
                if self.inv_z[(ty * self.tw + tx) as usize] <= limit {
                    return false;
                }
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use engine::camera::Pose;

    fn view() -> View {
        View {
            pose: Pose::look_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, 60.0),
            width_px: 64,
            height_px: 48,
            near: 0.1,
            far: 100.0,
            section: engine::section::Section::NONE,
        }
    }

    fn quad(z: f32, half: f32) -> [[Vec3; 3]; 2] {
        let p = |x: f32, y: f32| Vec3::new(x, y, z);
        [
            [p(-half, -half), p(half, -half), p(half, half)],
            [p(-half, -half), p(half, half), p(-half, half)],
        ]
    }

    #[test]
    fn the_nearer_quad_owns_the_pixels_and_hides_the_farther_one() {
        let mut b = IdBuffer::new(&view());
        let far = quad(0.0, 1.0);
        let near = quad(1.0, 2.0);
        let d0 = b.triangle(0, far[0]);
        b.triangle(1, far[1]);
        b.triangle(2, near[0]);
        b.triangle(3, near[1]);
        assert!(d0.samples > 0 && d0.on_screen);
        let owners = b.owners();
        assert!(!owners.contains(&0) && !owners.contains(&1));
        assert!(owners.contains(&2) && owners.contains(&3));
        // The two halves of a quad share their diagonal without a hole.
        let covered = owners.iter().filter(|&&o| o != NONE).count() as f32;
        let area: f32 = near
            .iter()
            .map(|&t| IdBuffer::new(&view()).triangle(0, t).area)
            .sum();
        assert!((covered - area).abs() < 0.1 * area, "{covered} of {area}");
    }

    #[test]
    fn a_box_behind_a_wall_is_hidden_per_pixel_and_one_beside_it_is_not() {
        let mut b = IdBuffer::new(&view());
        // A wall at z = 1 covering x, y in -1..1.
        for (k, t) in quad(1.0, 1.0).into_iter().enumerate() {
            b.triangle(k as u32, t);
        }
        let px = b.depth_tiles(1);
        let behind = (Vec3::new(-0.3, -0.3, -1.0), Vec3::new(0.3, 0.3, 0.0));
        assert!(px.box_hidden(behind.0, behind.1));
        // Nearer than the wall, or reaching past its edge: not hidden.
        assert!(!px.box_hidden(Vec3::new(-0.3, -0.3, 1.5), Vec3::new(0.3, 0.3, 2.0)));
        assert!(!px.box_hidden(Vec3::new(0.5, -0.3, -1.0), Vec3::new(1.6, 0.3, 0.0)));
        // Coarse tiles keep their farthest sample: the wall's border tiles
        // also hold background, so a box behind the wall's edge is hidden
        // per pixel and not per 16-pixel tile.
        let edge = (Vec3::new(0.55, -0.3, -0.2), Vec3::new(0.85, 0.3, 0.0));
        assert!(px.box_hidden(edge.0, edge.1));
        assert!(!b.depth_tiles(16).box_hidden(edge.0, edge.1));
    }

    #[test]
    fn a_triangle_behind_the_eye_or_off_screen_draws_nothing() {
        let mut b = IdBuffer::new(&view());
        let behind = quad(20.0, 1.0)[0];
        assert_eq!(b.triangle(0, behind), Drawn::default());
        let aside = [
            Vec3::new(100.0, 0.0, 0.0),
            Vec3::new(101.0, 0.0, 0.0),
            Vec3::new(100.0, 1.0, 0.0),
        ];
        let d = b.triangle(1, aside);
        assert!(!d.on_screen && d.samples == 0);
        // One crossing the near plane is clipped and still drawn.
        let across = [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, -1.0, 20.0),
        ];
        assert!(b.triangle(2, across).samples > 0);
        assert!(b.owners().iter().all(|&o| o == NONE || o == 2));
    }
}
