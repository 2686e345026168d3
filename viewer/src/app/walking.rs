//! Walk mode (key G, `--walk`): the eye at 1.6 m over the floor, held by
//! gravity, stopped by walls, up the stairs, colliding with the scene's
//! walk section ([`engine::walk`]) and never with what is resident.

use std::sync::Arc;

use engine::ByteSource;
use engine::walk::{Body, WalkMap, Walker};
use glam::Vec2;

use super::App;

/// The walk section being walked and the walker.
pub(super) struct Walking {
    map: WalkMap<Arc<dyn ByteSource>>,
    walker: Walker,
}

impl std::fmt::Debug for Walking {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Walking")
            .field("feet", &self.walker.feet())
            .finish_non_exhaustive()
    }
}

/// Walking speed, m/s (shift runs at 2.5 times it).
const WALK_SPEED: f32 = 1.4;

impl App {
    /// Starts or stops walking where the eye is.
    pub(super) fn toggle_walk(&mut self) {
        if self.walking.take().is_some() {
            tracing::info!("fly mode");
            return;
        }
        let Some(sess) = &self.session else {
            return;
        };
        let path = sess.path.display().to_string();
        let map = match sess.walk_map() {
            Ok(Some(m)) => m,
            Ok(None) => {
                return self.report(format!(
                    "{path}: no walk section (a scene built before format version 5, or with \
                     --walk-cell 0): rebuild it to walk"
                ));
            }
            Err(e) => return self.report(format!("walk mode: {e:#}")),
        };
        let mut map = map;
        match Walker::from_eye(Body::default(), &mut map, self.controls.position) {
            Ok(walker) => {
                tracing::info!(
                    "walk mode: eye at 1.6 m, steps up to 0.3 m; the walk section's index holds {} B",
                    map.index_bytes()
                );
                self.controls.pitch = self.controls.pitch.clamp(-0.6, 0.6);
                self.walking = Some(Walking { map, walker });
            }
            Err(e) => self.report(format!("walk mode: {e:#}")),
        }
    }

    /// Opens or closes every door (its leaf passed or a wall) while walking.
    pub(super) fn toggle_doors(&mut self) {
        if let Some(w) = &mut self.walking {
            let b = &mut w.walker.body;
            b.doors_open = !b.doors_open;
            tracing::info!("doors {}", if b.doors_open { "open" } else { "closed" });
        }
    }

    /// Moves the eye for `dt` seconds with the held keys: flying or orbiting
    /// as the controls do, or walking.
    pub(super) fn move_camera(&mut self, dt: f32) {
        let Some(w) = &mut self.walking else {
            self.controls.update(&self.held, dt);
            return;
        };
        let h = &self.held;
        let axis = |on: bool| if on { 1.0 } else { 0.0 };
        let (sy, cy) = self.controls.yaw.sin_cos();
        let forward = Vec2::new(-sy, -cy);
        let right = Vec2::new(cy, -sy);
        let d = forward * (axis(h.forward) - axis(h.back)) + right * (axis(h.right) - axis(h.left));
        let run = if h.run { 2.5 } else { 1.0 };
        let dt = dt.clamp(0.0, 0.25);
        let wish = d.normalize_or_zero() * WALK_SPEED * run * dt;
        match w.walker.step(&mut w.map, wish, dt) {
            Ok(_) => self.controls.position = w.walker.eye(),
            Err(e) => {
                self.walking = None;
                self.report(format!("walk mode stopped: {e}"));
            }
        }
    }
}

/// What the overlay says of walk mode (`None`: not walking).
pub(super) fn status(w: Option<&Walking>) -> Option<String> {
    w.map(|w| {
        format!(
            "walking: feet at {:.2} m{}, doors {} (O), walk map {} KiB held",
            w.walker.feet().y,
            if w.walker.grounded() { "" } else { ", falling" },
            if w.walker.body.doors_open {
                "open"
            } else {
                "closed"
            },
            w.map.resident_bytes() / 1024
        )
    })
}
