//! What the scene tests with a large object draw on the GPU: one pose in
//! front of the whole scene, drawn by a headless 320 x 240 wgpu renderer
//! for a number of frames (P_I's reps arrive meanwhile), the last captured.

use std::sync::Arc;

use engine::camera::Pose;
use engine::image::RgbaImage;
use engine::metrics::FrameMetrics;
use engine::runtime::{RuntimeParams, Walkthrough};
use engine::{ByteSource, Skeleton};
use engine_gpu::{GpuContext, GpuRenderer, RendererConfig};
use glam::Vec3;

/// The viewport of the shots.
pub(crate) const SIZE: (u32, u32) = (320, 240);

/// A pose in front of the scene's root box, looking at its centre.
pub(crate) fn overview(skel: &Skeleton) -> Pose {
    let root = &skel.nodes[0];
    let (min, max) = (Vec3::from(root.bbox_min), Vec3::from(root.bbox_max));
    let c = (min + max) * 0.5;
    Pose::look_at(
        c + Vec3::new(0.3, 0.1, 1.0) * (max - min).length() * 0.9,
        c,
        50.0,
    )
}

/// Walks `frames` frames at `pose` with `params` (its viewport set to
/// [`SIZE`]) and returns the last frame's image and metrics.
pub(crate) fn shoot(
    ctx: &GpuContext,
    (skel, src): (Arc<Skeleton>, Arc<dyn ByteSource>),
    params: RuntimeParams,
    pose: &Pose,
    frames: usize,
) -> (RgbaImage, FrameMetrics) {
    let p = RuntimeParams {
        width_px: SIZE.0,
        height_px: SIZE.1,
        ..params
    };
    let mut w = Walkthrough::start(skel, src, p).unwrap();
    let config = RendererConfig::headless(SIZE.0, SIZE.1, 64 << 20);
    let mut r = GpuRenderer::new(ctx.clone(), config).unwrap();
    let mut last = None;
    for _ in 0..frames {
        std::thread::sleep(std::time::Duration::from_millis(5));
        r.capture_next_frame();
        last = Some(w.frame(pose, &mut r).unwrap());
    }
    (r.take_capture().unwrap(), last.expect("at least one frame"))
}
