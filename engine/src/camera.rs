//! Camera poses, views, frustum culling, projected error, and the camera
//! path file (the generated paths are the programs': `engine_cli::paths`).
//!
//! World space is right-handed with +Y up (glTF's convention); a camera looks
//! along its local -Z. A **path file** is plain text, one pose per line:
//!
//! ```text
//! # hlod camera path v1
//! # x y z qx qy qz qw fov_y_deg
//! 12.5 1.7 -3.0 0 0.3826834 0 0.9238795 60
//! ```
//!
//! `#` starts a comment; blank lines are ignored; the orientation quaternion is
//! the rotation from camera to world space (normalised on read).

use std::fmt::Write as _;
use std::path::Path;

use glam::{EulerRot, Quat, Vec3};

use crate::section::Section;

/// One camera pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    pub position: Vec3,
    /// Camera-to-world rotation; the camera looks along `rotation * -Z`.
    pub rotation: Quat,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f32,
}

impl Pose {
    /// A pose at `eye` looking towards `target`.
    pub fn look_at(eye: Vec3, target: Vec3, fov_y_deg: f32) -> Self {
        let d = (target - eye).normalize_or(Vec3::NEG_Z);
        Self::from_yaw_pitch(eye, yaw_of(d), d.y.clamp(-1.0, 1.0).asin(), fov_y_deg)
    }

    /// A pose from heading (about +Y, 0 looks along -Z) and pitch, in radians.
    pub fn from_yaw_pitch(eye: Vec3, yaw: f32, pitch: f32, fov_y_deg: f32) -> Self {
        Self {
            position: eye,
            rotation: Quat::from_euler(EulerRot::YXZ, yaw, pitch, 0.0),
            fov_y_deg,
        }
    }

    /// Unit view direction.
    pub fn forward(&self) -> Vec3 {
        self.rotation * Vec3::NEG_Z
    }

    /// The ray through pixel `(x, y)` (from the top left, in pixels) of a
    /// `width` x `height` viewport: the eye and a unit direction.
    pub fn ray(&self, width: u32, height: u32, x: f32, y: f32) -> (Vec3, Vec3) {
        let (w, h) = (width.max(1) as f32, height.max(1) as f32);
        let tan = (0.5 * self.fov_y_deg.to_radians()).tan();
        let sx = (2.0 * x / w - 1.0) * tan * (w / h);
        let sy = (1.0 - 2.0 * y / h) * tan;
        let d = self.rotation * Vec3::new(sx, sy, -1.0);
        (self.position, d.normalize_or(self.forward()))
    }

    /// Where the scene point `p` lands on the viewport, in pixels from the
    /// top left, and its depth along the view; `None` behind the eye.
    pub fn project(&self, width: u32, height: u32, p: Vec3) -> Option<(f32, f32, f32)> {
        let c = self.rotation.inverse() * (p - self.position);
        let depth = -c.z;
        if depth <= 1e-6 {
            return None;
        }
        let (w, h) = (width.max(1) as f32, height.max(1) as f32);
        let tan = (0.5 * self.fov_y_deg.to_radians()).tan();
        let sx = c.x / depth / (tan * w / h);
        let sy = c.y / depth / tan;
        Some(((sx + 1.0) * 0.5 * w, (1.0 - sy) * 0.5 * h, depth))
    }

    /// Angle in radians between this pose's view direction and `other`'s.
    pub fn angle_to(&self, other: &Pose) -> f32 {
        self.forward().dot(other.forward()).clamp(-1.0, 1.0).acos()
    }
}

/// The yaw of a direction (0 looks along -Z).
pub fn yaw_of(d: Vec3) -> f32 {
    (-d.x).atan2(-d.z)
}

/// A pose on a viewport: what the front is computed for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    pub pose: Pose,
    pub width_px: u32,
    pub height_px: u32,
    pub near: f32,
    pub far: f32,
    /// Section planes: what they remove is culled by every frustum made
    /// from this view (see [`crate::section`]).
    pub section: Section,
}

impl View {
    /// Pixels per unit of object-space error at distance 1: `H / (2 tan(fov/2))`.
    pub fn pixels_per_radian(&self) -> f32 {
        self.height_px as f32 / (2.0 * (0.5 * self.pose.fov_y_deg.to_radians()).tan())
    }

    /// Projected screen-space size in pixels of an error `e` at distance `dist`.
    pub fn projected(&self, e: f32, dist: f32) -> f32 {
        e * self.pixels_per_radian() / dist.max(self.near)
    }

    /// Width / height.
    pub fn aspect(&self) -> f32 {
        self.width_px as f32 / self.height_px.max(1) as f32
    }

    /// The view frustum, its half-angles widened by `margin_rad` and kept
    /// below 90° (a wide frustum tends to the half-space in front). A
    /// margin of 90° or more reaches behind the eye, where planes cannot
    /// follow: the frustum is then all around it ([`Frustum::all_around`]).
    pub fn frustum(&self, margin_rad: f32) -> Frustum {
        if margin_rad >= std::f32::consts::FRAC_PI_2 {
            let mut f = Frustum::all_around(self.pose.position, self.pose.forward());
            f.section = self.section;
            return f;
        }
        let half_y0 = 0.5 * self.pose.fov_y_deg.to_radians();
        let half_x0 = (half_y0.tan() * self.aspect()).atan();
        let tan_y = (half_y0 + margin_rad).min(1.55).tan();
        let tan_x = (half_x0 + margin_rad).min(1.55).tan();
        let r = self.pose.rotation;
        let (right, up, fwd) = (r * Vec3::X, r * Vec3::Y, r * Vec3::NEG_Z);
        let eye = self.pose.position;
        // Inward normals of the four side planes through the eye.
        // Directions of the four edges at the half-angles.
        let sides = [
            (fwd + right * tan_x).normalize(),
            (fwd - right * tan_x).normalize(),
            (fwd + up * tan_y).normalize(),
            (fwd - up * tan_y).normalize(),
        ];
        let mut planes = [(Vec3::ZERO, 0.0); 6];
        for (k, s) in sides.iter().enumerate() {
            // The plane holds the edge and the other screen axis; its normal faces inwards.
            let axis = if k < 2 { up } else { right };
            let mut n = s.cross(axis).normalize();
            if n.dot(fwd) < 0.0 {
                n = -n;
            }
            planes[k] = (n, -n.dot(eye));
        }
        planes[4] = (fwd, -fwd.dot(eye + fwd * self.near));
        planes[5] = (-fwd, fwd.dot(eye + fwd * self.far));
        Frustum {
            planes,
            eye,
            forward: fwd,
            half_angle: tan_y.atan().max(tan_x.atan()),
            section: self.section,
        }
    }
}

/// Six inward-facing planes `n . p + d >= 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    pub planes: [(Vec3, f32); 6],
    pub eye: Vec3,
    pub forward: Vec3,
    /// The larger of the horizontal and vertical half-angles.
    pub half_angle: f32,
    /// The view's section planes, culled with the six.
    pub section: Section,
}

impl Frustum {
    /// Every direction from `eye`: no plane culls (each is `0 . p + 0 >= 0`);
    /// `forward` still gives the angles of [`Frustum::angle_to_box`].
    pub fn all_around(eye: Vec3, forward: Vec3) -> Self {
        Self {
            planes: [(Vec3::ZERO, 0.0); 6],
            eye,
            forward,
            half_angle: std::f32::consts::PI,
            section: Section::NONE,
        }
    }

    /// Whether the box may intersect the frustum (conservative).
    #[inline]
    pub fn intersects(&self, min: Vec3, max: Vec3) -> bool {
        self.planes.iter().all(|(n, d)| {
            let p = Vec3::select(n.cmpge(Vec3::ZERO), max, min);
            n.dot(p) + d >= 0.0
        }) && self.section.keeps_box(min, max)
    }

    /// Angle between the line of sight and the direction to the box's centre.
    pub fn angle_to_box(&self, min: Vec3, max: Vec3) -> f32 {
        let c = (min + max) * 0.5 - self.eye;
        let len = c.length();
        if len <= 1e-6 {
            return 0.0;
        }
        (c.dot(self.forward) / len).clamp(-1.0, 1.0).acos()
    }
}

/// Distance from `p` to the box (0 inside).
#[inline]
pub fn box_distance(p: Vec3, min: Vec3, max: Vec3) -> f32 {
    (min - p).max(p - max).max(Vec3::ZERO).length()
}

/// Why a path file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum PathError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}:{line}: {what}")]
    Syntax {
        path: String,
        line: usize,
        what: String,
    },
    #[error("{path}: the path has no poses")]
    Empty { path: String },
}

/// Parses a path file's text; `name` is used in errors.
pub fn parse_path(text: &str, name: &str) -> Result<Vec<Pose>, PathError> {
    let mut out = Vec::new();
    // A byte-order mark, as some editors write, is not part of the text.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    for (i, raw) in text.lines().enumerate() {
        if out.len() >= MAX_PATH_POSES {
            return Err(PathError::Syntax {
                path: name.to_string(),
                line: i + 1,
                what: format!("more than {MAX_PATH_POSES} poses"),
            });
        }
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let err = |what: String| PathError::Syntax {
            path: name.to_string(),
            line: i + 1,
            what,
        };
        let vals: Vec<f32> = line
            .split_whitespace()
            .map(|t| {
                t.parse::<f32>()
                    .map_err(|_| err(format!("{t:?} is not a number")))
            })
            .collect::<Result<_, _>>()?;
        if vals.len() != 8 {
            return Err(err(format!(
                "expected 8 numbers (x y z qx qy qz qw fov), found {}",
                vals.len()
            )));
        }
        if vals.iter().any(|v| !v.is_finite()) {
            return Err(err("non-finite value".into()));
        }
        let q = Quat::from_xyzw(vals[3], vals[4], vals[5], vals[6]);
        if q.length() < 1e-3 {
            return Err(err("zero orientation quaternion".into()));
        }
        if !(vals[7] > 1.0 && vals[7] < 179.0) {
            return Err(err(format!(
                "field of view {} outside (1, 179) degrees",
                vals[7]
            )));
        }
        out.push(Pose {
            position: Vec3::new(vals[0], vals[1], vals[2]),
            rotation: q.normalize(),
            fov_y_deg: vals[7],
        });
    }
    if out.is_empty() {
        return Err(PathError::Empty {
            path: name.to_string(),
        });
    }
    Ok(out)
}

/// Reads a path file.
pub fn read_path(path: &Path) -> Result<Vec<Pose>, PathError> {
    let name = path.display().to_string();
    let io = |source| PathError::Io {
        path: name.clone(),
        source,
    };
    let bytes = crate::limits::read_bounded(path, MAX_PATH_FILE_BYTES).map_err(io)?;
    let text = String::from_utf8(bytes).map_err(|e| {
        io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        ))
    })?;
    parse_path(&text, &name)
}

/// The most poses a path file may hold (a million frames: over nine hours
/// at 30 fps).
pub const MAX_PATH_POSES: usize = 1_000_000;
/// The largest path file read: a million poses of eight long numbers.
pub const MAX_PATH_FILE_BYTES: u64 = 256 << 20;

/// Serialises poses in the path format.
pub fn format_path(poses: &[Pose]) -> String {
    let mut s = String::from("# hlod camera path v1\n# x y z qx qy qz qw fov_y_deg\n");
    for p in poses {
        let (t, q) = (p.position, p.rotation);
        let _ = writeln!(
            s,
            "{} {} {} {} {} {} {} {}",
            t.x, t.y, t.z, q.x, q.y, q.z, q.w, p.fov_y_deg
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(pose: Pose) -> View {
        View {
            pose,
            width_px: 1280,
            height_px: 720,
            near: 0.1,
            far: 1000.0,
            section: crate::section::Section::NONE,
        }
    }

    #[test]
    fn a_pixel_ray_and_projection_invert_each_other() {
        let pose = Pose::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::new(-4.0, 0.5, -2.0), 55.0);
        for (x, y) in [(640.0, 360.0), (10.0, 700.0), (1270.0, 5.0)] {
            let (o, d) = pose.ray(1280, 720, x, y);
            let (px, py, depth) = pose.project(1280, 720, o + d * 7.0).unwrap();
            assert!(
                (px - x).abs() < 0.01 && (py - y).abs() < 0.01,
                "{x},{y} -> {px},{py}"
            );
            assert!(depth > 0.0);
        }
        let (_, centre) = pose.ray(1280, 720, 640.0, 360.0);
        assert!(centre.angle_between(pose.forward()) < 1e-4);
        assert!(
            pose.project(1280, 720, pose.position - pose.forward())
                .is_none()
        );
    }

    #[test]
    fn frustum_keeps_what_is_ahead_and_culls_behind_and_beside() {
        let v = view(Pose::look_at(Vec3::ZERO, Vec3::NEG_Z, 60.0));
        let f = v.frustum(0.0);
        let unit = |c: Vec3| (c - Vec3::splat(0.5), c + Vec3::splat(0.5));
        let (a, b) = unit(Vec3::new(0.0, 0.0, -10.0));
        assert!(f.intersects(a, b));
        let (a, b) = unit(Vec3::new(0.0, 0.0, 10.0));
        assert!(!f.intersects(a, b));
        let (a, b) = unit(Vec3::new(30.0, 0.0, -10.0));
        assert!(!f.intersects(a, b), "far to the right");
        let (a, b) = unit(Vec3::new(0.0, 9.0, -10.0));
        assert!(!f.intersects(a, b), "above the 30-degree half-angle");
        let (a, b) = unit(Vec3::new(0.0, 0.0, -2000.0));
        assert!(!f.intersects(a, b), "past the far plane");
        // Widening by 30 degrees brings the box above into view.
        let (a, b) = unit(Vec3::new(0.0, 9.0, -10.0));
        assert!(v.frustum(30f32.to_radians()).intersects(a, b));
        assert!((f.angle_to_box(a, b) - (9.0f32 / 10.0).atan()).abs() < 1e-4);
    }

    #[test]
    fn a_frustum_widened_by_90_degrees_or_more_is_all_around() {
        let v = view(Pose::look_at(Vec3::ZERO, Vec3::NEG_Z, 60.0));
        let behind = (Vec3::new(-0.5, -0.5, 9.5), Vec3::new(0.5, 0.5, 10.5));
        assert!(!v.frustum(40f32.to_radians()).intersects(behind.0, behind.1));
        let all = v.frustum(std::f32::consts::PI);
        assert!(all.intersects(behind.0, behind.1));
        assert_eq!(all.half_angle, std::f32::consts::PI);
        assert!((all.angle_to_box(behind.0, behind.1) - std::f32::consts::PI).abs() < 1e-3);
        // Below 90°, the planes still cull what is behind.
        assert!(!v.frustum(1.5).intersects(behind.0, behind.1));
    }

    #[test]
    fn projected_error_scales_with_distance_and_viewport() {
        let v = view(Pose::look_at(Vec3::ZERO, Vec3::NEG_Z, 90.0));
        // fov 90: tan(45) = 1, so 1 unit at distance 1 spans half the height.
        assert!((v.projected(1.0, 1.0) - 360.0).abs() < 1e-3);
        assert!((v.projected(1.0, 10.0) - 36.0).abs() < 1e-3);
        assert_eq!(v.projected(1.0, 0.0), v.projected(1.0, 0.1));
        assert_eq!(
            box_distance(Vec3::ZERO, Vec3::ONE, Vec3::splat(2.0)),
            3f32.sqrt()
        );
        assert_eq!(
            box_distance(Vec3::splat(1.5), Vec3::ONE, Vec3::splat(2.0)),
            0.0
        );
    }

    #[test]
    fn path_format_round_trips_and_reports_line_numbers() {
        let poses: Vec<Pose> = (0..300)
            .map(|i| {
                let t = i as f32 * 0.1;
                Pose::from_yaw_pitch(Vec3::new(t, 1.7, -t * 0.5), t.sin() * 3.0, -0.15, 60.0)
            })
            .collect();
        let back = parse_path(&format_path(&poses), "p").unwrap();
        assert_eq!(back.len(), 300);
        for (a, b) in poses.iter().zip(&back) {
            assert!(a.position.distance(b.position) < 1e-4);
            assert!(a.angle_to(b) < 1e-3);
        }
        let bad = "# c\n1 2 3 0 0 0 1 60\n\n1 2 x 0 0 0 1 60\n";
        let e = parse_path(bad, "p.txt").unwrap_err().to_string();
        assert!(e.starts_with("p.txt:4:"), "{e}");
        assert!(parse_path("1 2 NaN 0 0 0 1 60", "p").is_err());
        assert!(parse_path("1 2 3 0 0 0 0 60", "p").is_err());
        assert!(parse_path("1 2 3 0 0 0 1 60 7", "p").is_err());
        assert!(parse_path("1 2 3 0 0 0 1 0", "p").is_err());
        assert!(matches!(
            parse_path("# nothing\n", "p"),
            Err(PathError::Empty { .. })
        ));
        // A byte-order mark is not a syntax error.
        assert_eq!(
            parse_path("\u{feff}1 2 3 0 0 0 1 60\n", "p").unwrap().len(),
            1
        );
    }
}
