//! Point-to-point measurement: a picked point snapped to the picked
//! triangle's nearest corner or edge when it lies within a few pixels of
//! it on screen, as CAD and BIM viewers snap.

use glam::Vec3;

use crate::camera::Pose;

/// What a measured point was snapped to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SnapKind {
    Vertex,
    Edge,
    /// Not snapped: the picked point on the face.
    Face,
}

impl SnapKind {
    pub fn name(self) -> &'static str {
        match self {
            Self::Vertex => "vertex",
            Self::Edge => "edge",
            Self::Face => "face",
        }
    }
}

/// Snaps `point` (on the triangle `corners`, picked at pixel `at` of a
/// `size` viewport seen from `pose`) to a corner within `radius_px` pixels
/// of `at`, else to the nearest point of an edge within it, else keeps it.
pub fn snap(
    pose: &Pose,
    size: (u32, u32),
    at: (f32, f32),
    point: Vec3,
    corners: [Vec3; 3],
    radius_px: f32,
) -> (Vec3, SnapKind) {
    let px = |p: Vec3| {
        pose.project(size.0, size.1, p)
            .map(|(x, y, _)| ((x - at.0).powi(2) + (y - at.1).powi(2)).sqrt())
    };
    let nearest = |c: &[(Vec3, f32)]| {
        c.iter()
            .copied()
            .filter(|(_, d)| *d <= radius_px)
            .min_by(|a, b| a.1.total_cmp(&b.1))
    };
    let vertices: Vec<(Vec3, f32)> = corners
        .iter()
        .filter_map(|&c| px(c).map(|d| (c, d)))
        .collect();
    if let Some((v, _)) = nearest(&vertices) {
        return (v, SnapKind::Vertex);
    }
    // On each edge, the point nearest the pick ray.
    let (o, dir) = pose.ray(size.0, size.1, at.0, at.1);
    let edges: Vec<(Vec3, f32)> = (0..3)
        .filter_map(|k| {
            let (a, b) = (corners[k], corners[(k + 1) % 3]);
            let p = nearest_on_segment_to_ray(a, b, o, dir);
            px(p).map(|d| (p, d))
        })
        .collect();
    if let Some((e, _)) = nearest(&edges) {
        return (e, SnapKind::Edge);
    }
    (point, SnapKind::Face)
}

/// The point of segment `[a, b]` nearest the line `o + t·dir`.
fn nearest_on_segment_to_ray(a: Vec3, b: Vec3, o: Vec3, dir: Vec3) -> Vec3 {
    let u = b - a;
    let w = a - o;
    let (uu, ud, dd) = (u.dot(u), u.dot(dir), dir.dot(dir));
    let (uw, dw) = (u.dot(w), dir.dot(w));
    let den = uu * dd - ud * ud;
    let s = if den.abs() <= 1e-12 * uu * dd {
        0.0
    } else {
        (ud * dw - dd * uw) / den
    };
    a + u * s.clamp(0.0, 1.0)
}

/// Two measured points and their distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement {
    pub a: Vec3,
    pub b: Vec3,
    pub snapped: [SnapKind; 2],
}

impl Measurement {
    /// The distance, in scene units (metres).
    pub fn distance(&self) -> f32 {
        self.a.distance(self.b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> (Pose, (u32, u32), [Vec3; 3]) {
        // Looking along -Z at a triangle 10 m away.
        let pose = Pose::look_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, 60.0);
        let tri = [
            Vec3::new(-2.0, -2.0, 0.0),
            Vec3::new(2.0, -2.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        ];
        (pose, (800, 600), tri)
    }

    /// Where `p` is on screen, and the hit of the ray through that pixel
    /// with the plane z = 0.
    fn click(pose: &Pose, size: (u32, u32), p: Vec3) -> ((f32, f32), Vec3) {
        let (x, y, _) = pose.project(size.0, size.1, p).unwrap();
        let (o, d) = pose.ray(size.0, size.1, x, y);
        ((x, y), o + d * (-o.z / d.z))
    }

    #[test]
    fn near_a_corner_snaps_to_it_near_an_edge_to_it_else_stays() {
        let (pose, size, tri) = setup();
        // 0.05 m from the corner: a few pixels at 10 m.
        let (at, hit) = click(&pose, size, tri[0] + Vec3::new(0.05, 0.03, 0.0));
        assert_eq!(
            snap(&pose, size, at, hit, tri, 8.0),
            (tri[0], SnapKind::Vertex)
        );
        // Near the bottom edge's middle: the point on the edge below it.
        let (at, hit) = click(&pose, size, Vec3::new(0.3, -1.96, 0.0));
        let (p, k) = snap(&pose, size, at, hit, tri, 8.0);
        assert_eq!(k, SnapKind::Edge);
        assert!((p - Vec3::new(0.3, -2.0, 0.0)).length() < 1e-3, "{p}");
        // In the middle of the face: unchanged.
        let (at, hit) = click(&pose, size, Vec3::new(0.0, 0.0, 0.0));
        assert_eq!(snap(&pose, size, at, hit, tri, 8.0), (hit, SnapKind::Face));
        // A smaller radius does not reach the corner.
        let (at, hit) = click(&pose, size, tri[0] + Vec3::new(0.3, 0.3, 0.0));
        assert_eq!(snap(&pose, size, at, hit, tri, 2.0).1, SnapKind::Face);
    }

    #[test]
    fn distances_are_between_the_snapped_points() {
        let m = Measurement {
            a: Vec3::new(1.0, 2.0, 3.0),
            b: Vec3::new(4.0, 6.0, 3.0),
            snapped: [SnapKind::Vertex, SnapKind::Edge],
        };
        assert_eq!(m.distance(), 5.0);
        assert_eq!(m.snapped[1].name(), "edge");
    }
}
