//! Where a walker can go: a breadth-first search over standing places, one
//! cell apart, each move made by a [`Walker`] on the same map (so that a
//! path found here is a path walk mode walks, stairs and doors included).

use std::collections::{HashMap, VecDeque};

use glam::{Vec2, Vec3};

use super::{SolidMap, Walker};
use crate::format::FormatError;

const DT: f32 = 1.0 / 60.0;

/// One place reached: the walker standing there and how it got there.
#[derive(Clone, Copy, Debug)]
pub struct Place {
    pub walker: Walker,
    /// The place it came from (itself for the start) and the move.
    pub from: usize,
    pub by: Vec2,
}

/// A move that falls: from place `from`, `by`, landing at `landing`.
#[derive(Clone, Copy, Debug)]
pub struct Fall {
    pub from: usize,
    pub by: Vec2,
    pub landing: Walker,
}

/// The places reachable from a start.
#[derive(Clone, Debug, Default)]
pub struct Reach {
    pub places: Vec<Place>,
    /// Moves that leave the ground (drops of more than a step).
    pub falls: Vec<Fall>,
}

impl Reach {
    /// Every place reachable on foot from `start` (standing) within the box
    /// `lo..hi` (x and z), at most `max` places, moving one cell along x or
    /// z at a time. A move counts when it covers the whole cell and the
    /// walker stands within a step of where it was; a move that drops
    /// further is a fall (kept apart, not walked on from).
    pub fn explore(
        map: &mut impl SolidMap,
        start: Walker,
        lo: Vec2,
        hi: Vec2,
        max: usize,
    ) -> Result<Self, FormatError> {
        let grid = map.grid();
        let c = grid.cell;
        // Places lie a whole number of cells from the start.
        let s0 = start.feet();
        let key = |w: &Walker| {
            let f = w.feet();
            (
                ((f.x - s0.x) / c).round() as i64,
                ((f.z - s0.z) / c).round() as i64,
                (f.y / grid.quantum).round() as i64,
            )
        };
        let mut out = Reach::default();
        let mut seen = HashMap::new();
        let mut queue = VecDeque::new();
        if !start.grounded() {
            return Ok(out);
        }
        seen.insert(key(&start), 0);
        out.places.push(Place {
            walker: start,
            from: 0,
            by: Vec2::ZERO,
        });
        queue.push_back(0);
        let moves = [Vec2::X * c, -Vec2::X * c, Vec2::Y * c, -Vec2::Y * c];
        while let Some(k) = queue.pop_front() {
            let here = out.places[k].walker;
            for by in moves {
                let to = here.feet() + Vec3::new(by.x, 0.0, by.y);
                if to.x < lo.x || to.z < lo.y || to.x > hi.x || to.z > hi.y {
                    continue;
                }
                let mut w = here;
                w.step(map, by, DT)?;
                let moved = Vec2::new(w.feet().x - here.feet().x, w.feet().z - here.feet().z);
                if (moved - by).length() > 1e-3 {
                    continue;
                }
                if !w.grounded() {
                    for _ in 0..600 {
                        if w.grounded() {
                            break;
                        }
                        w.step(map, Vec2::ZERO, DT)?;
                    }
                    out.falls.push(Fall {
                        from: k,
                        by,
                        landing: w,
                    });
                    continue;
                }
                if out.places.len() >= max || seen.contains_key(&key(&w)) {
                    continue;
                }
                seen.insert(key(&w), out.places.len());
                out.places.push(Place {
                    walker: w,
                    from: k,
                    by,
                });
                queue.push_back(out.places.len() - 1);
            }
        }
        Ok(out)
    }

    /// The moves from the start to place `k`.
    pub fn path_to(&self, mut k: usize) -> Vec<Vec2> {
        let mut moves = Vec::new();
        while k != 0 {
            moves.push(self.places[k].by);
            k = self.places[k].from;
        }
        moves.reverse();
        moves
    }
}
