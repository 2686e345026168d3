//! Generated camera paths over a scene's bounds: the benchmark's and the
//! tests' standard walks (a recorded path is a file: `engine::camera`).

use engine::camera::{Pose, yaw_of};
use glam::Vec3;

/// Standard generated paths over a scene's bounds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathKind {
    /// Walk through the scene at eye height with fast pans and sudden turns.
    Flythrough,
    /// Far-to-near approach towards the centre.
    Approach,
    /// Orbit around the centre.
    Orbit,
    /// Approach an object from afar, then orbit it while closing in (the
    /// view-dependence-tree benchmark's path).
    ApproachOrbit,
    /// A hostile random walk for soak tests: wandering at random speeds,
    /// turning at random, jumping to a random place (inside or around the
    /// scene) every few seconds, with a random field of view; the same
    /// `seed` gives the same path.
    Random { seed: u64 },
}

/// Generates a path of `frames` poses over the box `min..max` (deterministic).
pub fn generate_path(kind: PathKind, min: Vec3, max: Vec3, frames: usize) -> Vec<Pose> {
    let c = (min + max) * 0.5;
    let e = (max - min).max(Vec3::splat(1e-3));
    let radius = e.length() * 0.5;
    let n = frames.max(2);
    let fov = 60.0;
    match kind {
        PathKind::Orbit => (0..n)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / n as f32;
                let eye = c + Vec3::new(a.cos() * radius * 1.3, e.y * 0.6, a.sin() * radius * 1.3);
                Pose::look_at(eye, c, fov)
            })
            .collect(),
        PathKind::Approach => (0..n)
            .map(|i| {
                let t = i as f32 / (n - 1) as f32;
                let far = c + Vec3::new(-1.0, 0.6, -1.0).normalize() * radius * 3.0;
                let near = c + Vec3::new(-0.05, 0.02, -0.05) * radius;
                let eye = far.lerp(near, 1.0 - (1.0 - t) * (1.0 - t));
                Pose::look_at(eye, c, fov)
            })
            .collect(),
        PathKind::Flythrough => flythrough(min, e, n, fov),
        PathKind::Random { seed } => random_walk(min, e, n, seed),
        PathKind::ApproachOrbit => (0..n)
            .map(|i| {
                let t = i as f32 / (n - 1) as f32;
                let dir0 = Vec3::new(0.0, 0.25, 1.0).normalize();
                let (a, d, y) = if t < 0.3 {
                    // Ease in from 4 radii to 1.6.
                    let u = t / 0.3;
                    (0.0, 4.0 - 2.4 * u * (2.0 - u), dir0.y)
                } else {
                    // One turn, closing in to 0.9 radii, the height swinging.
                    let u = (t - 0.3) / 0.7;
                    let a = std::f32::consts::TAU * u;
                    (a, 1.6 - 0.7 * u, dir0.y + 0.35 * (2.0 * a).sin())
                };
                let dir = Vec3::new(a.sin(), y, a.cos()).normalize();
                Pose::look_at(c + dir * radius * d, c, fov)
            })
            .collect(),
    }
}

/// [`PathKind::Random`]: xorshift64* draws, so no dependency and the same
/// poses on every platform.
fn random_walk(min: Vec3, e: Vec3, n: usize, seed: u64) -> Vec<Pose> {
    let mut state = seed ^ 0x9e37_79b9_7f4a_7c15;
    let mut next = move || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        (state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 40) as f32 / (1u64 << 24) as f32
    };
    let diag = e.length();
    let place = |next: &mut dyn FnMut() -> f32| {
        // Up to a quarter of the box beyond each side.
        min + e * Vec3::new(next(), next(), next()) * 1.5 - e * 0.25
    };
    let mut pos = place(&mut next);
    let (mut yaw, mut pitch) = (next() * std::f32::consts::TAU, 0.0f32);
    let mut fov = 60.0;
    let mut speed = diag / 1200.0;
    let mut jump_in = 60 + (next() * 240.0) as usize;
    (0..n)
        .map(|_| {
            jump_in = jump_in.saturating_sub(1);
            if jump_in == 0 {
                pos = place(&mut next);
                yaw = next() * std::f32::consts::TAU;
                fov = 20.0 + next() * 80.0;
                speed = diag / (300.0 + next() * 3000.0);
                jump_in = 60 + (next() * 240.0) as usize;
            }
            yaw += (next() - 0.5) * 0.3;
            pitch = (pitch + (next() - 0.5) * 0.1).clamp(-1.2, 1.2);
            let pose = Pose::from_yaw_pitch(pos, yaw, pitch, fov);
            pos += pose.forward() * speed;
            pose
        })
        .collect()
}

/// A closed route through the scene at about a third of its height, flown at
/// a walkthrough pace (a fortieth of the scene's diagonal per second at 30
/// frames per second): straight stretches with smooth heading changes, a fast
/// pan to the side every 4 s and a sudden 90° turn every 7 s.
fn flythrough(min: Vec3, e: Vec3, n: usize, fov: f32) -> Vec<Pose> {
    let height = min.y + e.y * 0.35;
    let route = |t: f32| {
        // A Lissajous-like loop across the footprint.
        let a = std::f32::consts::TAU * t;
        Vec3::new(
            min.x + e.x * (0.5 + 0.38 * a.sin()),
            height,
            min.z + e.z * (0.5 + 0.38 * (2.0 * a).sin()),
        )
    };
    let loop_len: f32 = (0..1000)
        .map(|k| route((k + 1) as f32 / 1000.0).distance(route(k as f32 / 1000.0)))
        .sum();
    let step = e.length() / 40.0 / 30.0 / loop_len.max(1e-6);
    (0..n)
        .map(|i| {
            let t = i as f32 * step;
            let eye = route(t);
            let ahead = route(t + 0.002) - eye;
            let mut yaw = yaw_of(ahead.normalize_or(Vec3::NEG_Z));
            let mut pitch = -0.15;
            // Fast pan: 20 frames swinging up to 80 degrees to one side and back.
            let k = i % 120;
            if (60..80).contains(&k) {
                let s = ((k - 60) as f32 / 20.0 * std::f32::consts::PI).sin();
                yaw += s * 1.4 * if (i / 120) % 2 == 0 { 1.0 } else { -1.0 };
                pitch += s * 0.2;
            }
            // Sudden turn: 90 degrees to the side within 10 frames (270°/s),
            // held for 40 frames, then back.
            let j = i % 210;
            if (150..200).contains(&j) {
                let ramp = ((j - 150) as f32 / 10.0)
                    .min(1.0)
                    .min((200 - j) as f32 / 10.0);
                yaw += std::f32::consts::FRAC_PI_2 * ramp;
            }
            Pose::from_yaw_pitch(eye, yaw, pitch, fov)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use engine::camera::{format_path, parse_path};

    #[test]
    fn random_walks_are_reproducible_jump_and_stay_parseable() {
        let (lo, hi) = (Vec3::ZERO, Vec3::new(100.0, 20.0, 50.0));
        let a = generate_path(PathKind::Random { seed: 7 }, lo, hi, 2000);
        assert_eq!(a, generate_path(PathKind::Random { seed: 7 }, lo, hi, 2000));
        assert_ne!(a, generate_path(PathKind::Random { seed: 8 }, lo, hi, 2000));
        let jumps = a
            .windows(2)
            .filter(|w| w[0].position.distance(w[1].position) > 5.0)
            .count();
        assert!(jumps >= 5, "{jumps} jumps");
        assert_eq!(parse_path(&format_path(&a), "r").unwrap().len(), 2000);
    }

    #[test]
    fn flythrough_has_fast_pans_and_sudden_turns() {
        let poses = generate_path(
            PathKind::Flythrough,
            Vec3::ZERO,
            Vec3::new(100.0, 20.0, 100.0),
            600,
        );
        let max_step = poses
            .windows(2)
            .map(|w| w[0].angle_to(&w[1]))
            .fold(0.0, f32::max);
        assert!(max_step > 0.14, "largest per-frame turn {max_step} rad");
        let approach = generate_path(PathKind::Approach, Vec3::ZERO, Vec3::splat(10.0), 50);
        assert!(
            approach[0].position.distance(Vec3::splat(5.0))
                > approach[49].position.distance(Vec3::splat(5.0))
        );
    }
}
