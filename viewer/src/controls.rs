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
        let diag = (max - min).length().max(1e-3);
        self.scene_diag = diag;
        self.target = (min + max) * 0.5;
        let half_fov = (0.5 * self.fov_y_deg).to_radians();
        self.distance = 0.5 * diag / half_fov.sin();
        self.yaw = 35f32.to_radians();
        self.pitch = -25f32.to_radians();
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
