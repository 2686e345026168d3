//! Occlusion culling on real BIM models along interior walks: every sampled
//! frame equals the frame without culling (wgpu, lavapipe without a GPU),
//! the front shrinks, and the footprint (P_I's reps plus P_R's occluder
//! store) stays under the budget on every frame.

use std::path::Path;
use std::sync::Arc;

use engine::image::RgbaImage;
use engine::interior::{InteriorParams, interior_path, scene_triangles};
use engine::metrics::FrameMetrics;
use engine::runtime::{Mode, RuntimeParams, Walkthrough};
use engine::{MemSource, SceneFile};
use engine_gpu::{Colouring, GpuRenderer, RendererConfig};
use hlod_builder::build::{BuildParams, build_file};

const W: u32 = 320;
const H: u32 = 240;
/// Pixels (of 76,800) a sampled frame may differ in: coplanar faces drawn
/// in another order (fewer reps are drawn) may resolve their depth tie
/// the other way. Measured: see `docs/results.md`.
const MAX_DIFFERING: u64 = 40;

/// A walk's frames and its sampled images.
type Run = (Vec<FrameMetrics>, Vec<(u32, RgbaImage)>);

fn walk(name: &str, scene: &Path, mode: Mode, occlusion_bytes: u64, budget: u64) -> Option<Run> {
    let file = SceneFile::open(scene).unwrap();
    let skel = Arc::new(file.skeleton().clone());
    let tris = scene_triangles(&file).unwrap();
    let path = interior_path(&tris, 240, &InteriorParams::default()).unwrap();
    let ctx = e2e_tests::gpu_or_skip(name)?;
    let data: u64 = skel.reps.iter().map(|r| r.expanded_extent()).sum();
    let mut r = GpuRenderer::new(
        ctx,
        RendererConfig {
            colouring: Colouring::Object,
            ..RendererConfig::headless(W, H, if mode == Mode::Incore { data } else { budget })
        },
    )
    .unwrap();
    r.capture_every(6);
    let source = Arc::new(MemSource::new(std::fs::read(scene).unwrap()));
    let params = RuntimeParams {
        mode,
        budget_bytes: budget,
        tolerance_px: 1.0,
        width_px: W,
        height_px: H,
        near: 0.05,
        occlusion_bytes,
        ..RuntimeParams::default()
    };
    let mut w = Walkthrough::start(skel, source, params).unwrap();
    let frames: Vec<FrameMetrics> = path
        .poses
        .iter()
        .map(|p| w.frame(p, &mut r).unwrap())
        .collect();
    assert!(r.context().take_errors().is_empty());
    Some((frames, r.take_captures()))
}

fn check(model: &str) {
    let name = format!("occlusion_culling_changes_no_frame_{model}");
    let glb = e2e_tests::data_dir().join(model);
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.hlod");
    build_file(&glb, &scene, &BuildParams::default(), false).unwrap();
    let data: u64 = SceneFile::open(&scene)
        .unwrap()
        .skeleton()
        .reps
        .iter()
        .map(|r| r.expanded_extent())
        .sum();
    let Some((plain, want)) = walk(&name, &scene, Mode::Incore, 0, data) else {
        return;
    };
    let (culled, got) = walk(&name, &scene, Mode::Incore, 1 << 20, data).unwrap();
    assert_eq!(want.len(), got.len());
    let mut worst = 0;
    for ((i, a), (j, b)) in want.iter().zip(&got) {
        assert_eq!(i, j);
        let d = a.diff(b, 0).unwrap();
        worst = worst.max(d.pixels_over);
        assert!(
            d.pixels_over <= MAX_DIFFERING,
            "{model} frame {i}: {} pixels differ with occlusion culling",
            d.pixels_over
        );
    }
    let sum = |f: &[FrameMetrics], g: fn(&FrameMetrics) -> u64| f.iter().map(g).sum::<u64>();
    let occluded = sum(&culled, |f| u64::from(f.occluded_reps));
    let (front0, front1) = (
        sum(&plain, |f| u64::from(f.front_reps)),
        sum(&culled, |f| u64::from(f.front_reps)),
    );
    assert!(occluded > 0 && front1 < front0, "{model}: nothing culled");
    eprintln!(
        "{model}: {} frames compared, at most {worst} pixels differ; front reps {front0} -> {front1}",
        want.len()
    );
    // Out of core: the occluder store comes out of the footprint.
    let budget = data / 4;
    let store = budget / 8;
    let (frames, _) = walk(&name, &scene, Mode::Pre, store, budget).unwrap();
    for f in &frames {
        assert!(f.occluder_bytes <= store, "frame {}", f.frame);
        assert!(
            f.loader.max_resident_bytes + f.occluder_bytes <= budget,
            "frame {}: {} + {} > {budget}",
            f.frame,
            f.loader.max_resident_bytes,
            f.occluder_bytes
        );
        assert!(f.gpu_bytes <= budget);
        assert_eq!(
            f.drawn_reps + f.substituted,
            f.front_reps,
            "frame {}",
            f.frame
        );
    }
}

#[test]
fn occlusion_culling_changes_no_frame_of_the_fzk_house() {
    check("AC14-FZK-Haus.glb");
}

#[test]
fn occlusion_culling_changes_no_frame_of_the_duplex() {
    check("Ifc2x3_Duplex_Architecture.glb");
}
