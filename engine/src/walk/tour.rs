//! Interior walks generated on the walk section: every pose is where a
//! [`Walker`] stands (eye at its height over the floor under it), every step
//! between two poses is one it took (no wall, slab or furniture passed; doors
//! opened), and every storey the walk reports is one it walked on.
//!
//! 1. **Start**: a standing place indoors (a ceiling above) on the lowest
//!    level, drawn with the seed from a 0.5 m lattice over the box.
//! 2. **Reach**: the places one cell apart the walker reaches from there
//!    ([`Reach`]), up and down the stairs.
//! 3. **Storeys**: the heights where most places stand (2 m apart at least).
//! 4. **Legs**: from the start to a place drawn on the top storey (through
//!    every storey between), then on each storey in turn, each there and
//!    back, along the search's paths, walked again by a walker, until the
//!    frames are walked. The storeys reported are those it stood on.

use glam::{Vec2, Vec3};

use super::{Body, Reach, SolidMap, Walker};
use crate::camera::Pose;
use crate::format::FormatError;

/// A generated walk.
#[derive(Clone, Debug, PartialEq)]
pub struct Tour {
    pub poses: Vec<Pose>,
    /// Floor heights of the storeys walked on (of those found).
    pub storeys: Vec<f32>,
    /// Places the walker could reach.
    pub places: usize,
}

/// Why no walk was made.
#[derive(Debug, thiserror::Error)]
pub enum TourError {
    #[error("nowhere to stand indoors: no floor with a ceiling above and room for a person")]
    NoStart,
    #[error(transparent)]
    Read(#[from] FormatError),
}

/// Places the search may hold (a 120 m × 120 m storey at 0.1 m and more).
pub const MAX_PLACES: usize = 1_500_000;
/// Starts searched from; the walk starts where the most is reachable.
pub const STARTS_TRIED: usize = 4;

/// A walk of `frames` poses `step` apart through the box `lo..hi` (x, z),
/// from a start drawn with `seed`.
pub fn tour(
    map: &mut impl SolidMap,
    (lo, hi): (Vec2, Vec2),
    frames: usize,
    step: f32,
    seed: u64,
) -> Result<Tour, TourError> {
    let body = Body {
        doors_open: true,
        ..Body::default()
    };
    // Of a few starts drawn, the one from which the most is reachable (a
    // flat's hall rather than a shut storeroom).
    let starts = find_starts(map, body, (lo, hi), seed)?;
    let mut best: Option<(Walker, Reach)> = None;
    for &s in starts.iter().take(STARTS_TRIED) {
        let r = Reach::explore(map, s, lo, hi, MAX_PLACES)?;
        if best
            .as_ref()
            .is_none_or(|b| r.places.len() > b.1.places.len())
        {
            best = Some((s, r));
        }
    }
    let (start, reach) = best.ok_or(TourError::NoStart)?;
    let levels = storeys(&reach);
    let mut rng = seed ^ 0x2545_f491_4f6c_dd1d;
    let mut draw = |n: usize| {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng % n.max(1) as u64) as usize
    };
    // The walker's eye along the legs, one point per cell moved. The first
    // leg climbs to the top storey (through every storey between), the
    // next go to the others in turn, each there and back.
    let mut points = vec![start.eye()];
    let mut w = start;
    let want = frames as f32 * step;
    let mut walked = 0.0;
    let order: Vec<f32> = levels
        .iter()
        .rev()
        .take(1)
        .chain(&levels)
        .copied()
        .collect();
    'legs: for _ in 0..64 {
        for &level in &order {
            let on: Vec<usize> = (0..reach.places.len())
                .filter(|&k| (reach.places[k].walker.feet().y - level).abs() < 0.15)
                .collect();
            let target = on[draw(on.len())];
            let there = reach.path_to(target);
            let back: Vec<Vec2> = there.iter().rev().map(|m| -*m).collect();
            for m in there.iter().chain(&back) {
                w.step(map, *m, 1.0 / 30.0)?;
                let e = w.eye();
                walked += e.distance(*points.last().expect("a point"));
                points.push(e);
                if walked >= want {
                    break 'legs;
                }
            }
        }
    }
    // The storeys the walk stood on.
    let eye = body.eye;
    let levels: Vec<f32> = levels
        .into_iter()
        .filter(|l| points.iter().any(|p| (p.y - eye - l).abs() < 0.15))
        .collect();
    Ok(Tour {
        poses: follow(&points, frames, step),
        storeys: levels,
        places: reach.places.len(),
    })
}

/// Standing places indoors on the lowest level with one: grounded, free,
/// with solid 1.8–4.3 m above the feet, on a 0.5 m lattice; in an order
/// drawn with `seed`.
fn find_starts(
    map: &mut impl SolidMap,
    body: Body,
    (lo, hi): (Vec2, Vec2),
    seed: u64,
) -> Result<Vec<Walker>, FormatError> {
    let grid = map.grid();
    let top = grid.y_base + 65535.0 * grid.quantum;
    let mut found: Vec<Walker> = Vec::new();
    let (nx, nz) = (
        ((hi.x - lo.x) / 0.5).ceil().clamp(1.0, 2000.0) as usize,
        ((hi.y - lo.y) / 0.5).ceil().clamp(1.0, 2000.0) as usize,
    );
    for i in 0..nx {
        for j in 0..nz {
            let (x, z) = (lo.x + 0.25 + i as f32 * 0.5, lo.y + 0.25 + j as f32 * 0.5);
            // Each floor of the column: a top with room for a person above.
            let col = map.column(grid.cell_of(x), grid.cell_of(z))?;
            let tops: Vec<(f32, f32)> = col
                .solid
                .iter()
                .enumerate()
                .map(|(k, s)| {
                    let next = col.solid.get(k + 1).map_or(top, |n| grid.height(n.lo));
                    (grid.height(s.hi), next)
                })
                .filter(|&(t, next)| next - t > body.height && next - t < body.height + 2.5)
                .collect();
            for (t, _) in tops {
                let w = Walker::from_eye(body, map, Vec3::new(x, t + body.eye, z))?;
                if w.grounded() && !w.stuck(map)? {
                    found.push(w);
                }
            }
        }
    }
    let Some(lowest) = found.iter().map(|w| w.feet().y).reduce(f32::min) else {
        return Ok(Vec::new());
    };
    found.retain(|w| w.feet().y < lowest + 0.5);
    // A seeded shuffle (Fisher–Yates on a xorshift).
    let mut r = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    for i in (1..found.len()).rev() {
        r ^= r << 13;
        r ^= r >> 7;
        r ^= r << 17;
        found.swap(i, (r % (i as u64 + 1)) as usize);
    }
    Ok(found)
}

/// The floor heights most places stand at: 0.2 m bins holding at least 5%
/// of the places, the fullest first, at least 2 m apart; ascending.
fn storeys(reach: &Reach) -> Vec<f32> {
    let mut bins: std::collections::BTreeMap<i64, usize> = std::collections::BTreeMap::new();
    for p in &reach.places {
        *bins
            .entry((p.walker.feet().y / 0.2).round() as i64)
            .or_default() += 1;
    }
    let mut full: Vec<(i64, usize)> = bins
        .into_iter()
        .filter(|&(_, n)| n * 20 >= reach.places.len())
        .collect();
    full.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    let mut levels: Vec<f32> = Vec::new();
    for (b, _) in full {
        // The bin's most common exact height.
        let y = b as f32 * 0.2;
        if levels.iter().all(|l| (l - y).abs() >= 2.0) {
            let exact = reach
                .places
                .iter()
                .map(|p| p.walker.feet().y)
                .filter(|f| (f - y).abs() <= 0.1)
                .fold(f32::MAX, f32::min);
            levels.push(exact);
        }
    }
    levels.sort_by(f32::total_cmp);
    levels
}

/// Poses `step` apart along the points, looking a few metres ahead (turns
/// smoothed, the gaze kept near level).
fn follow(points: &[Vec3], frames: usize, step: f32) -> Vec<Pose> {
    let mut cum = vec![0f32];
    for w in points.windows(2) {
        cum.push(cum.last().expect("a length") + w[0].distance(w[1]));
    }
    let total = *cum.last().expect("a length");
    let at = |s: f32| -> Vec3 {
        if points.len() < 2 {
            return points[0];
        }
        let s = s.clamp(0.0, total);
        let k = cum.partition_point(|&c| c <= s).clamp(1, points.len() - 1);
        let (a, b) = (points[k - 1], points[k]);
        let seg = cum[k] - cum[k - 1];
        if seg <= 0.0 {
            a
        } else {
            a.lerp(b, (s - cum[k - 1]) / seg)
        }
    };
    let mut last = Vec3::NEG_Z;
    (0..frames)
        .map(|i| {
            let s = (i as f32 * step).min(total);
            let eye = at(s);
            let ahead: Vec3 = (1..=8).map(|k| at(s + 0.15 * k as f32)).sum::<Vec3>() / 8.0;
            let mut dir = ahead - eye;
            dir.y *= 0.3;
            if dir.length() > 1e-3 {
                last = dir;
            }
            Pose::look_at(eye, eye + last, 60.0)
        })
        .collect()
}
