//! Camera controls (plain Rust, no window): fly (WASD + mouse look, speed on
//! the wheel, shift to run) and orbit (drag turns about a target, wheel
//! zooms), and "frame all".

use engine::camera::Pose;
use glam::Vec3;

/// Fly or orbit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControlMode {
    Fly,
    Orbit,
}

/// Keys held this frame.
#[derive(Clone, Copy, Debug, Default)]
pub struct Held {
    pub forward: bool,
    pub back: bool,
    pub left: bool,
    pub right: bool,
    pub up: bool,
    pub down: bool,
    pub run: bool,
}

/// The camera state the user steers.
#[derive(Clone, Copy, Debug)]
pub struct Controls {
    pub mode: ControlMode,
    pub position: Vec3,
    /// Heading about +Y (0 looks along -Z) and pitch, radians.
    pub yaw: f32,
    pub pitch: f32,
    /// Fly speed in scene units per second.
    pub speed: f32,
    pub fov_y_deg: f32,
    /// Orbit centre and distance.
    pub target: Vec3,
    pub distance: f32,
    /// Scene size, for speed limits.
    scene_diag: f32,
}

impl Controls {
    /// Looking at a scene box from outside, in fly mode.
    pub fn new(min: Vec3, max: Vec3) -> Self {
        let mut c = Self {
            mode: ControlMode::Fly,
            position: Vec3::ZERO,
            yaw: 0.0,
            pitch: 0.0,
            speed: 1.0,
            fov_y_deg: 60.0,
            target: Vec3::ZERO,
            distance: 1.0,
            scene_diag: 1.0,
        };
        c.frame_all(min, max);
        c
    }

    /// Places the camera so that the whole box is in view.
    pub fn frame_all(&mut self, min: Vec3, max: Vec3) {
        self.frame_all_beside(min, max, 16.0 / 9.0, 0.0);
    }

    /// Places the camera so that the whole box is in view in a viewport of
    /// `aspect` (width / height) whose left `panel` fraction an overlay
    /// covers: the box's bounding sphere fits the height and the width right
    /// of the panel, centred there. The camera looks (and orbits) at a point
    /// beside the box's centre, so that the centre shows in the middle of the
    /// free part. A panel over 60% of the width is not avoided.
    pub fn frame_all_beside(&mut self, min: Vec3, max: Vec3, aspect: f32, panel: f32) {
        let diag = (max - min).length().max(1e-3);
        self.scene_diag = diag;
        let centre = (min + max) * 0.5;
        let radius = 0.5 * diag;
        let half_fov = (0.5 * self.fov_y_deg).to_radians();
        let f = if (0.0..=0.6).contains(&panel) {
            panel
        } else {
            0.0
        };
        let tan_x = half_fov.tan() * aspect.max(1e-3);
        // The distance at which the sphere, its centre at NDC x = f, spans
        // at most [2f - 1, 1] across and its angular radius fits the height.
        let fits = |d: f32| {
            let off = d * tan_x * f;
            let (centre_angle, l) = (off.atan2(d), (d * d + off * off).sqrt());
            let spread = (radius / l).min(1.0).asin();
            (centre_angle + spread).tan() <= tan_x
                && (centre_angle - spread).tan() >= tan_x * (2.0 * f - 1.0)
                && spread <= half_fov
                && centre_angle + spread < std::f32::consts::FRAC_PI_2
        };
        let half_free = (tan_x * (1.0 - f)).atan();
        let mut d = radius / half_fov.sin().min(half_free.sin()).max(1e-3);
        for _ in 0..200 {
            if fits(d) {
                break;
            }
            d *= 1.02;
        }
        self.distance = d;
        self.yaw = 35f32.to_radians();
        self.pitch = -25f32.to_radians();
        let right = self.forward().cross(Vec3::Y).normalize();
        self.target = centre - right * (self.distance * tan_x * f);
        self.position = self.target - self.forward() * self.distance;
        self.speed = diag / 20.0;
    }

    /// Starts from an existing pose (e.g. a path's first frame).
    pub fn set_pose(&mut self, pose: &Pose) {
        let f = pose.forward();
        self.position = pose.position;
        self.yaw = (-f.x).atan2(-f.z);
        self.pitch = f.y.clamp(-1.0, 1.0).asin();
        self.fov_y_deg = pose.fov_y_deg;
        self.target = self.position + f * self.distance;
    }

    fn forward(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        Vec3::new(-sy * cp, sp, -cy * cp)
    }

    /// Mouse motion while looking (fly) or dragging (orbit), in pixels.
    pub fn look(&mut self, dx: f32, dy: f32) {
        let k = 0.004;
        self.yaw -= dx * k;
        self.pitch = (self.pitch - dy * k).clamp(-1.54, 1.54);
        if self.mode == ControlMode::Orbit {
            self.position = self.target - self.forward() * self.distance;
        }
    }

    /// Wheel steps: fly speed (×1.25 per step) or orbit distance.
    pub fn wheel(&mut self, steps: f32) {
        let f = 1.25f32.powf(steps);
        match self.mode {
            ControlMode::Fly => {
                self.speed = (self.speed * f).clamp(self.scene_diag * 1e-5, self.scene_diag * 10.0)
            }
            ControlMode::Orbit => {
                self.distance =
                    (self.distance / f).clamp(self.scene_diag * 1e-4, self.scene_diag * 20.0);
                self.position = self.target - self.forward() * self.distance;
            }
        }
    }

    /// Switches between fly and orbit (the orbit centre is ahead).
    pub fn toggle_mode(&mut self) {
        self.mode = match self.mode {
            ControlMode::Fly => {
                self.target = self.position + self.forward() * self.distance;
                ControlMode::Orbit
            }
            ControlMode::Orbit => ControlMode::Fly,
        };
    }

    /// Moves for `dt` seconds with the held keys (fly mode).
    pub fn update(&mut self, held: &Held, dt: f32) {
        if self.mode != ControlMode::Fly {
            return;
        }
        let f = self.forward();
        let right = f.cross(Vec3::Y).normalize_or(Vec3::X);
        let mut d = Vec3::ZERO;
        let axis = |on: bool| if on { 1.0 } else { 0.0 };
        d += f * (axis(held.forward) - axis(held.back));
        d += right * (axis(held.right) - axis(held.left));
        d += Vec3::Y * (axis(held.up) - axis(held.down));
        let run = if held.run { 4.0 } else { 1.0 };
        self.position += d.normalize_or_zero() * self.speed * run * dt.clamp(0.0, 0.25);
    }

    /// The pose to render.
    pub fn pose(&self) -> Pose {
        Pose::from_yaw_pitch(self.position, self.yaw, self.pitch, self.fov_y_deg)
    }
}

/// Near and far planes for a scene of diagonal `diag` (a room to a ship):
/// the far plane only culls, depth is reverse-Z with an infinite far plane.
pub fn clip_planes(diag: f32) -> (f32, f32) {
    ((diag * 1e-5).max(1e-3), diag * 10.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_all_sees_the_box_and_pose_matches_the_angles() {
        let (min, max) = (Vec3::splat(-10.0), Vec3::splat(10.0));
        let c = Controls::new(min, max);
        let p = c.pose();
        let to_centre = (Vec3::ZERO - p.position).normalize();
        assert!(p.forward().dot(to_centre) > 0.999, "looks at the centre");
        assert!(p.position.length() > 17.0, "outside the box");
        let mut d = c;
        d.set_pose(&p);
        assert!((d.yaw - c.yaw).abs() < 1e-4 && (d.pitch - c.pitch).abs() < 1e-4);
    }

    /// Every corner of the box projects inside the viewport and right of
    /// the panel, for wide and narrow windows.
    #[test]
    fn framing_keeps_the_box_clear_of_the_panel() {
        let (min, max) = (Vec3::new(-40.0, 0.0, -10.0), Vec3::new(40.0, 6.0, 10.0));
        for (aspect, panel) in [
            (16.0 / 9.0, 0.47),
            (16.0 / 9.0, 0.27),
            (1.0, 0.3),
            (2.5, 0.15),
            (0.6, 0.0),
        ] {
            let mut c = Controls::new(min, max);
            c.frame_all_beside(min, max, aspect, panel);
            let p = c.pose();
            let (f, up) = (p.forward(), Vec3::Y);
            let right = f.cross(up).normalize();
            let up = right.cross(f);
            let t = (0.5 * p.fov_y_deg).to_radians().tan();
            for i in 0..8 {
                let corner = Vec3::new(
                    if i & 1 == 0 { min.x } else { max.x },
                    if i & 2 == 0 { min.y } else { max.y },
                    if i & 4 == 0 { min.z } else { max.z },
                );
                let v = corner - p.position;
                let z = v.dot(f);
                let (x, y) = (v.dot(right) / (z * t * aspect), v.dot(up) / (z * t));
                assert!(
                    z > 0.0 && y.abs() <= 1.0,
                    "{aspect} {panel}: corner {i} at y {y}"
                );
                assert!(
                    x >= -1.0 + 2.0 * panel && x <= 1.0,
                    "{aspect} {panel}: corner {i} at x {x}"
                );
            }
        }
    }

    #[test]
    fn fly_moves_along_view_and_orbit_keeps_distance() {
        let mut c = Controls::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let p0 = c.pose();
        let held = Held {
            forward: true,
            ..Held::default()
        };
        c.update(&held, 0.1);
        let moved = c.pose().position - p0.position;
        assert!(moved.normalize().dot(p0.forward()) > 0.999);
        let run = Held { run: true, ..held };
        let before = c.position;
        c.update(&run, 0.1);
        assert!(((c.position - before).length() / moved.length() - 4.0).abs() < 1e-3);
        c.toggle_mode();
        let t = c.target;
        c.look(100.0, 30.0);
        assert!(((c.position - t).length() - c.distance).abs() < 1e-3);
        c.wheel(2.0);
        assert!(((c.position - t).length() - c.distance).abs() < 1e-3);
        assert!(c.pose().forward().dot((t - c.position).normalize()) > 0.999);
        assert!(clip_planes(100.0).0 > 0.0 && clip_planes(100.0).1 > 100.0);
    }
}
