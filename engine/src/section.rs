//! Section planes and section boxes: half-spaces that cut the model open.
//!
//! A [`Section`] is up to [`MAX_PLANES`] planes; each keeps the half-space
//! `n · p + d ≥ 0` and removes the other, and the model that stays is
//! what every plane keeps (a section box is six planes). The view carries
//! it ([`crate::camera::View::section`]), so every frustum made from the
//! view culls what it removes: a node wholly on a removed side leaves the
//! front (P_R draws nothing of it) and every front P_I plans from (F_I,
//! the lookahead), so it is neither fetched nor kept. What straddles a
//! plane stays in the front and is clipped exactly by the renderer.
//!
//! Planes are given as BCF gives them (`ClippingPlane`: a `Location` on the
//! plane and a `Direction` that points into the removed half-space).

use glam::{Vec3, Vec4};

/// The most planes one section holds (a box and two more).
pub const MAX_PLANES: usize = 8;

/// Why a section cannot be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SectionError {
    #[error("a section holds at most {MAX_PLANES} planes, not {0}")]
    TooManyPlanes(usize),
    #[error("section plane {0}: its location and direction must be finite")]
    NotFinite(usize),
    #[error("section plane {0}: its direction is the zero vector")]
    ZeroDirection(usize),
    #[error("section box: its minimum {min:?} must lie below its maximum {max:?} on every axis")]
    EmptyBox { min: [f32; 3], max: [f32; 3] },
}

/// A set of clipping half-spaces (empty: nothing is removed).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Section {
    /// `(n, d)`: the half-space `n · p + d ≥ 0` is kept; `n` is a unit vector.
    planes: [Vec4; MAX_PLANES],
    count: u8,
}

impl Section {
    /// Nothing removed.
    pub const NONE: Section = Section {
        planes: [Vec4::ZERO; MAX_PLANES],
        count: 0,
    };

    /// Planes through `location`, removing the side `direction` points to
    /// (BCF's convention).
    pub fn from_planes(planes: &[(Vec3, Vec3)]) -> Result<Self, SectionError> {
        if planes.len() > MAX_PLANES {
            return Err(SectionError::TooManyPlanes(planes.len()));
        }
        let mut s = Self::NONE;
        for (i, &(at, dir)) in planes.iter().enumerate() {
            if !at.is_finite() || !dir.is_finite() {
                return Err(SectionError::NotFinite(i));
            }
            let len = dir.length();
            if !len.is_finite() || len <= 0.0 {
                return Err(SectionError::ZeroDirection(i));
            }
            // Kept: (p - at) · (-dir) ≥ 0.
            let n = -dir / len;
            s.planes[i] = n.extend(-n.dot(at));
        }
        s.count = planes.len() as u8;
        Ok(s)
    }

    /// A section box: only what lies inside `[min, max]` stays.
    pub fn boxed(min: Vec3, max: Vec3) -> Result<Self, SectionError> {
        if !min.is_finite() || !max.is_finite() || !min.cmplt(max).all() {
            return Err(SectionError::EmptyBox {
                min: min.to_array(),
                max: max.to_array(),
            });
        }
        let mut planes = Vec::with_capacity(6);
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            planes.push((max, axis));
            planes.push((min, -axis));
        }
        Self::from_planes(&planes)
    }

    /// Whether nothing is removed.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The kept half-spaces `(n, d)`, `n · p + d ≥ 0`.
    pub fn planes(&self) -> &[Vec4] {
        &self.planes[..usize::from(self.count)]
    }

    /// Each plane as BCF writes it: a point on it (the one nearest the
    /// origin) and the direction of the removed side.
    pub fn as_location_direction(&self) -> Vec<(Vec3, Vec3)> {
        self.planes()
            .iter()
            .map(|p| {
                let n = p.truncate();
                (-n * p.w, -n)
            })
            .collect()
    }

    /// The same section moved by `offset`: it keeps `p + offset` where this
    /// keeps `p`.
    pub fn translated(&self, offset: Vec3) -> Self {
        let mut s = *self;
        for p in &mut s.planes[..usize::from(self.count)] {
            p.w -= p.truncate().dot(offset);
        }
        s
    }

    /// Every plane moved by `by` along its kept side's outward direction:
    /// `by > 0` keeps more (a box grows, a cut rises above what it keeps),
    /// `by < 0` keeps less.
    pub fn grown(&self, by: f32) -> Self {
        let mut s = *self;
        for p in &mut s.planes[..usize::from(self.count)] {
            p.w += by;
        }
        s
    }

    /// Whether `p` is kept.
    pub fn keeps(&self, p: Vec3) -> bool {
        self.planes()
            .iter()
            .all(|q| q.truncate().dot(p) + q.w >= 0.0)
    }

    /// Whether some of the box `[min, max]` may be kept (conservative: a
    /// box wholly on the removed side of one plane is not).
    #[inline]
    pub fn keeps_box(&self, min: Vec3, max: Vec3) -> bool {
        self.planes().iter().all(|q| {
            let n = q.truncate();
            let far = Vec3::select(n.cmpge(Vec3::ZERO), max, min);
            n.dot(far) + q.w >= 0.0
        })
    }

    /// Whether the box `[min, max]` is kept whole (no plane cuts it).
    pub fn keeps_whole_box(&self, min: Vec3, max: Vec3) -> bool {
        self.planes().iter().all(|q| {
            let n = q.truncate();
            let near = Vec3::select(n.cmpge(Vec3::ZERO), min, max);
            n.dot(near) + q.w >= 0.0
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_keeps_the_side_its_direction_points_away_from() {
        // A horizontal cut at y = 3 removing what lies above.
        let s =
            Section::from_planes(&[(Vec3::new(5.0, 3.0, -2.0), Vec3::new(0.0, 2.0, 0.0))]).unwrap();
        assert!(s.keeps(Vec3::new(0.0, 2.9, 0.0)));
        assert!(!s.keeps(Vec3::new(0.0, 3.1, 0.0)));
        // Below, straddling, above.
        assert!(s.keeps_box(Vec3::ZERO, Vec3::splat(2.0)));
        assert!(s.keeps_whole_box(Vec3::ZERO, Vec3::splat(2.0)));
        assert!(s.keeps_box(Vec3::ZERO, Vec3::splat(4.0)));
        assert!(!s.keeps_whole_box(Vec3::ZERO, Vec3::splat(4.0)));
        assert!(!s.keeps_box(Vec3::splat(3.5), Vec3::splat(4.0)));
    }

    #[test]
    fn a_box_keeps_its_inside_only() {
        let s = Section::boxed(Vec3::ZERO, Vec3::new(10.0, 3.0, 10.0)).unwrap();
        assert_eq!(s.planes().len(), 6);
        assert!(s.keeps(Vec3::new(5.0, 1.0, 5.0)));
        for p in [
            Vec3::new(-0.1, 1.0, 5.0),
            Vec3::new(10.1, 1.0, 5.0),
            Vec3::new(5.0, 3.1, 5.0),
            Vec3::new(5.0, -0.1, 5.0),
            Vec3::new(5.0, 1.0, 10.1),
        ] {
            assert!(!s.keeps(p), "{p}");
        }
        // A storey above the box is removed; one that meets it is not.
        assert!(!s.keeps_box(Vec3::new(0.0, 3.5, 0.0), Vec3::new(10.0, 6.0, 10.0)));
        assert!(s.keeps_box(Vec3::new(0.0, 2.5, 0.0), Vec3::new(10.0, 6.0, 10.0)));
    }

    #[test]
    fn location_direction_and_translation_round_trip() {
        let s = Section::from_planes(&[
            (Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 1.0, 0.0)),
            (Vec3::new(-4.0, 0.0, 0.0), Vec3::NEG_Z),
        ])
        .unwrap();
        let back = Section::from_planes(&s.as_location_direction()).unwrap();
        for (a, b) in s.planes().iter().zip(back.planes()) {
            assert!((*a - *b).abs().max_element() < 1e-5, "{a} {b}");
        }
        let off = Vec3::new(100.0, -50.0, 7.0);
        let moved = s.translated(off);
        for p in [Vec3::new(1.5, 2.0, 3.0), Vec3::new(0.0, 2.0, 3.0)] {
            assert_eq!(s.keeps(p), moved.keeps(p + off), "{p}");
        }
    }

    #[test]
    fn growing_moves_every_plane_outwards() {
        let s = Section::boxed(Vec3::ZERO, Vec3::ONE).unwrap();
        let big = s.grown(0.5);
        assert!(big.keeps(Vec3::splat(1.4)) && !s.keeps(Vec3::splat(1.4)));
        assert!(big.keeps(Vec3::splat(-0.4)) && !big.keeps(Vec3::splat(-0.6)));
        let cut = Section::from_planes(&[(Vec3::new(0.0, 2.0, 0.0), Vec3::Y)]).unwrap();
        assert!(cut.grown(0.25).keeps(Vec3::new(0.0, 2.2, 0.0)));
        assert!(!cut.grown(-0.25).keeps(Vec3::new(0.0, 1.8, 0.0)));
    }

    #[test]
    fn nonsense_is_refused() {
        assert_eq!(
            Section::from_planes(&[(Vec3::ZERO, Vec3::ZERO)]),
            Err(SectionError::ZeroDirection(0))
        );
        assert_eq!(
            Section::from_planes(&[(Vec3::X, Vec3::X), (Vec3::NAN, Vec3::X)]),
            Err(SectionError::NotFinite(1))
        );
        assert_eq!(
            Section::from_planes(&[(Vec3::ZERO, Vec3::X); 9]),
            Err(SectionError::TooManyPlanes(9))
        );
        assert!(Section::boxed(Vec3::ONE, Vec3::ONE).is_err());
        assert!(Section::NONE.is_empty() && Section::NONE.keeps(Vec3::splat(1e30)));
    }
}
