//! Walking through a building: an eye at a person's height, held by gravity,
//! stopped by solid space, stepping up stairs. Plain Rust: no GPU, no
//! thread, no clock (the frame's `dt` is passed in).
//!
//! Collision reads the scene's walk section ([`crate::format::walk`]):
//! solid space as vertical spans per column of a 0.1 m grid, written by the
//! builder from every drawn triangle. It never looks at reps, so what is
//! resident changes nothing: a slab whose finest rep is not loaded still
//! holds the walker up. [`WalkMap`] reads the section chunk by chunk and
//! keeps a few; [`SpanGrid`] is the same in memory (the builder's, and the
//! tests').
//!
//! The body is a vertical cylinder (radius [`Body::radius`], height
//! [`Body::height`]) standing on the highest solid top under its disc. A move
//! is taken in steps of half a cell; a step that would put solid inside the
//! cylinder (above [`Body::step`] over the feet) is refused, then tried along
//! x and along z alone (sliding along a wall). Solid at most `step` above the
//! feet is climbed. With nothing under the feet the body falls (gravity,
//! landing on the first top below: no thin slab is passed however fast).

use glam::{Vec2, Vec3};

use crate::format::FormatError;
pub use crate::format::walk::{Column, Span};

mod grid;
mod map;
mod reach;
mod tour;

pub use grid::{Layer, Payload, SpanGrid};
pub use map::{DEFAULT_CAP, WalkMap};
pub use reach::{Fall, Place, Reach};
pub use tour::{MAX_PLACES, STARTS_TRIED, Tour, TourError, tour};

/// How spans map to space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// Cell side (x and z), scene units (metres).
    pub cell: f32,
    /// Height step of span values.
    pub quantum: f32,
    /// Height of span value 0.
    pub y_base: f32,
}

impl Grid {
    /// The cell holding coordinate `v` (x or z).
    pub fn cell_of(&self, v: f32) -> i64 {
        (v / self.cell).floor() as i64
    }

    /// Height of a span value.
    pub fn height(&self, q: u16) -> f32 {
        self.y_base + f32::from(q) * self.quantum
    }

    /// `[lo, hi]` heights rounded outwards to span values.
    pub fn span(&self, lo: f32, hi: f32) -> Span {
        let q = |v: f32| ((v - self.y_base) / self.quantum).clamp(0.0, f32::from(u16::MAX));
        Span {
            lo: q(lo).floor() as u16,
            hi: q(hi).ceil() as u16,
        }
    }
}

/// Solid space by columns, however stored.
pub trait SolidMap {
    fn grid(&self) -> Grid;
    /// The spans of cell `(x, z)`, each layer sorted and disjoint (empty:
    /// open air).
    fn column(&mut self, x: i64, z: i64) -> Result<Column<'_>, FormatError>;
}

/// The walker's size and strength.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Body {
    /// Eye above the feet.
    pub eye: f32,
    /// Head above the feet: less room than this is not passed.
    pub height: f32,
    pub radius: f32,
    /// Highest ledge climbed without a jump (a stair's riser).
    pub step: f32,
    /// m/s².
    pub gravity: f32,
    /// Doors' leaves are passed (the doors open) rather than walls.
    pub doors_open: bool,
}

impl Default for Body {
    /// A person: eye at 1.6 m, 1.8 m tall, 0.2 m wide, steps of 0.3 m; the
    /// doors closed.
    fn default() -> Self {
        Self {
            eye: 1.6,
            height: 1.8,
            radius: 0.2,
            step: 0.3,
            gravity: 9.81,
            doors_open: false,
        }
    }
}

/// What a step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Moved {
    /// Horizontal distance covered, of the distance asked.
    pub covered: f32,
    /// Whether some of the move was refused (a wall, a ledge, a low ceiling).
    pub blocked: bool,
    /// Height lost falling (not stepping down) this step.
    pub fell: f32,
}

/// A walking body: where its feet are and how fast it falls.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Walker {
    pub body: Body,
    feet: Vec3,
    /// Vertical speed (negative: falling).
    vy: f32,
    grounded: bool,
}

/// The highest ground a walker may drop to when nothing is under it: the
/// model's lowest level.
fn floor_of_void(map: &impl SolidMap) -> f32 {
    map.grid().y_base
}

impl Walker {
    /// A walker whose eye is at `eye`: placed on the solid top under it
    /// within one step of its feet, or left to fall.
    pub fn from_eye(body: Body, map: &mut impl SolidMap, eye: Vec3) -> Result<Self, FormatError> {
        let mut w = Self {
            body,
            feet: eye - Vec3::Y * body.eye,
            vy: 0.0,
            grounded: false,
        };
        if let Some(top) = w.support(map, w.feet, body.step)?
            && top >= w.feet.y - body.step
        {
            w.feet.y = top;
            w.grounded = true;
        }
        Ok(w)
    }

    pub fn feet(&self) -> Vec3 {
        self.feet
    }

    pub fn eye(&self) -> Vec3 {
        self.feet + Vec3::Y * self.body.eye
    }

    /// Whether solid is inside the body where it stands (a walker placed
    /// in a wall, or under a stair).
    pub fn stuck(&self, map: &mut impl SolidMap) -> Result<bool, FormatError> {
        Ok(self.inside(map, self.feet)? > 0)
    }

    /// Whether the feet stand on something.
    pub fn grounded(&self) -> bool {
        self.grounded
    }

    /// Moves by `wish` (x and z, scene units) and lets gravity act for `dt`
    /// seconds.
    pub fn step(
        &mut self,
        map: &mut impl SolidMap,
        wish: Vec2,
        dt: f32,
    ) -> Result<Moved, FormatError> {
        let mut moved = Moved::default();
        let len = wish.length();
        if len.is_finite() && len > 0.0 {
            let piece = 0.5 * map.grid().cell;
            let n = (len / piece).ceil().min(4096.0) as usize;
            let d = wish / n as f32;
            for _ in 0..n {
                let mut ok = self.try_move(map, d)?;
                if !ok {
                    moved.blocked = true;
                    ok = self.try_move(map, Vec2::new(d.x, 0.0))?
                        || self.try_move(map, Vec2::new(0.0, d.y))?;
                }
                if ok {
                    self.settle(map)?;
                }
            }
            moved.covered = len;
        }
        moved.fell = self.fall(map, dt.clamp(0.0, 0.25))?;
        Ok(moved)
    }

    /// One small move: climbs what is at most a step high, refuses solid in
    /// the body. A body already stuck in solid may move where less of it is.
    fn try_move(&mut self, map: &mut impl SolidMap, d: Vec2) -> Result<bool, FormatError> {
        if d == Vec2::ZERO {
            return Ok(false);
        }
        let to = self.feet + Vec3::new(d.x, 0.0, d.y);
        let stand = match self.support(map, to, self.body.step)? {
            Some(top) if self.grounded && top > to.y => top,
            _ => to.y,
        };
        let at = Vec3::new(to.x, stand, to.z);
        let inside = self.inside(map, at)?;
        if inside == 0 || inside < self.inside(map, self.feet)? {
            self.feet = at;
            return Ok(true);
        }
        Ok(false)
    }

    /// After a move on the ground: down a stair (a drop of at most a step).
    fn settle(&mut self, map: &mut impl SolidMap) -> Result<(), FormatError> {
        if !self.grounded {
            return Ok(());
        }
        match self.support(map, self.feet, 0.0)? {
            Some(top) if self.feet.y - top <= self.body.step => self.feet.y = top,
            _ => self.grounded = false,
        }
        Ok(())
    }

    /// Gravity for `dt`: the height lost.
    fn fall(&mut self, map: &mut impl SolidMap, dt: f32) -> Result<f32, FormatError> {
        let ground = self
            .support(map, self.feet, 0.0)?
            .unwrap_or_else(|| floor_of_void(map).min(self.feet.y));
        if self.grounded && self.feet.y - ground <= self.body.step {
            self.feet.y = ground;
            self.vy = 0.0;
            return Ok(0.0);
        }
        self.grounded = false;
        self.vy = (self.vy - self.body.gravity * dt).max(-50.0);
        let y0 = self.feet.y;
        let next = y0 + self.vy * dt;
        if next <= ground {
            self.feet.y = ground;
            self.vy = 0.0;
            self.grounded = true;
        } else {
            self.feet.y = next;
        }
        Ok(y0 - self.feet.y)
    }

    /// The cells whose square meets the body's disc at `p`.
    fn cells(&self, grid: &Grid, p: Vec3) -> impl Iterator<Item = (i64, i64)> + use<> {
        let (r, c) = (self.body.radius, grid.cell);
        let (x0, x1) = (grid.cell_of(p.x - r), grid.cell_of(p.x + r));
        let (z0, z1) = (grid.cell_of(p.z - r), grid.cell_of(p.z + r));
        let (px, pz) = (p.x, p.z);
        (z0..=z1)
            .flat_map(move |z| (x0..=x1).map(move |x| (x, z)))
            .filter(move |&(x, z)| {
                let nx = px.clamp(x as f32 * c, (x + 1) as f32 * c);
                let nz = pz.clamp(z as f32 * c, (z + 1) as f32 * c);
                (nx - px).powi(2) + (nz - pz).powi(2) <= r * r
            })
    }

    /// The highest solid top under the disc at `p` at most `reach` above
    /// `p.y`.
    fn support(
        &self,
        map: &mut impl SolidMap,
        p: Vec3,
        reach: f32,
    ) -> Result<Option<f32>, FormatError> {
        let grid = map.grid();
        let mut best: Option<f32> = None;
        let open = self.body.doors_open;
        for (x, z) in self.cells(&grid, p) {
            let col = map.column(x, z)?;
            let layers = [col.solid, if open { &[] } else { col.doors }];
            for spans in layers {
                if let Some(s) = spans
                    .iter()
                    .rev()
                    .find(|s| grid.height(s.hi) <= p.y + reach + 1e-4)
                {
                    let top = grid.height(s.hi);
                    best = Some(best.map_or(top, |b| b.max(top)));
                }
            }
        }
        Ok(best)
    }

    /// How many cells put solid inside the cylinder standing at `p` (above
    /// the climbable step): 0 when it is clear.
    fn inside(&self, map: &mut impl SolidMap, p: Vec3) -> Result<usize, FormatError> {
        let grid = map.grid();
        let (lo, hi) = (p.y + self.body.step.min(0.05), p.y + self.body.height);
        let open = self.body.doors_open;
        let mut n = 0;
        for (x, z) in self.cells(&grid, p) {
            let col = map.column(x, z)?;
            let layers = [col.solid, if open { &[] } else { col.doors }];
            if layers
                .iter()
                .flat_map(|l| l.iter())
                .any(|s| grid.height(s.hi) > lo && grid.height(s.lo) < hi)
            {
                n += 1;
            }
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests;
