//! The out-of-core runtime on a scene made by the builder, read from disk.

use std::path::PathBuf;
use std::sync::Arc;

use engine::camera::Pose;
use engine::render::NoneRenderer;
use engine::runtime::{Mode, RuntimeParams, Walkthrough, run_path};
use engine::skeleton::Skeleton;
use engine::{ByteSource, FileSource, SceneFile};
use engine_cli::paths::{PathKind, generate_path};
use glam::Vec3;
use hlod_builder::build::{BuildParams, build_file};
use hlod_builder::scenegen::plant::{PlantParams, write_plant};

/// A generated plant built into `dir/plant.hlod`: the scene's path, its
/// skeleton, its rep bytes and a fly-through of `frames` poses.
fn plant_and_flythrough(
    dir: &tempfile::TempDir,
    seed: u64,
    objects: usize,
    triangles: u64,
    frames: usize,
) -> (PathBuf, Arc<Skeleton>, u64, Vec<Pose>) {
    let glb = dir.path().join("plant.glb");
    let scene_path = dir.path().join("plant.hlod");
    let p = PlantParams {
        seed,
        objects,
        triangles,
    };
    write_plant(&p, &glb).unwrap();
    build_file(&glb, &scene_path, &BuildParams::default(), false).unwrap();
    let skel = Arc::new(SceneFile::open(&scene_path).unwrap().skeleton().clone());
    let data: u64 = skel.reps.iter().map(|r| r.expanded_extent()).sum();
    let root = &skel.nodes[0];
    let poses = generate_path(
        PathKind::Flythrough,
        Vec3::from(root.bbox_min),
        Vec3::from(root.bbox_max),
        frames,
    );
    (scene_path, skel, data, poses)
}

#[test]
fn three_modes_on_one_path_keep_the_budget_and_draw_the_same_fronts() {
    let dir = tempfile::tempdir().unwrap();
    let (scene_path, skel, data, poses) = plant_and_flythrough(&dir, 5, 200, 150_000, 400);
    let budget = data / 20;
    let mut fronts = Vec::new();
    for mode in [Mode::Incore, Mode::NoPre, Mode::Pre] {
        let source: Arc<dyn ByteSource> = Arc::new(FileSource::open(&scene_path).unwrap());
        let params = RuntimeParams {
            mode,
            budget_bytes: budget,
            tolerance_px: 1.0,
            ..RuntimeParams::default()
        };
        let mut walk = Walkthrough::start(skel.clone(), source, params).unwrap();
        let frames = run_path(&mut walk, &poses, &mut NoneRenderer::new(0.0), 0.0).unwrap();
        for f in &frames {
            assert_eq!(
                f.drawn_reps + f.substituted,
                f.front_reps,
                "{mode:?} frame {}",
                f.frame
            );
            if mode == Mode::Incore {
                assert_eq!(f.loader.stage2_bytes, 0);
                assert_eq!(f.substituted, 0);
            } else {
                assert!(
                    f.loader.max_resident_bytes <= budget,
                    "{mode:?} frame {}",
                    f.frame
                );
            }
        }
        assert!(
            frames.iter().any(|f| f.front_reps > 20),
            "the path sees the plant"
        );
        fronts.push(
            frames
                .iter()
                .map(|f| (f.front_reps, f.front_bytes))
                .collect::<Vec<_>>(),
        );
    }
    assert_eq!(fronts[0], fronts[1]);
    assert_eq!(fronts[0], fronts[2]);
}

#[test]
fn committed_paths_parse_and_match_the_generator() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../paths");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "txt") {
            let poses = engine::camera::read_path(&p).unwrap();
            assert_eq!(poses.len(), 600, "{}", p.display());
            n += 1;
        }
    }
    assert!(n >= 3, "flythrough, approach and orbit of the demo plant");
}

#[test]
fn slow_disk_reads_through_gaps_and_resumes_preempted_prefetches_within_the_budget() {
    use engine::disk::{DiskModel, ThrottledSource};
    let dir = tempfile::tempdir().unwrap();
    let (scene_path, skel, data, poses) = plant_and_flythrough(&dir, 9, 300, 600_000, 300);
    let budget = data / 10;
    // 4 ms seeks, 8 MB/s, 1 KiB blocks: a block takes 0.13 ms, and a
    // compressed rep of a few KiB several blocks, so prefetch reads are
    // preempted by the next frame's fetch command.
    let model = DiskModel {
        latency: std::time::Duration::from_millis(4),
        bytes_per_sec: 8e6,
    };
    let source: Arc<dyn ByteSource> = Arc::new(ThrottledSource::new(
        FileSource::open(&scene_path).unwrap(),
        model,
    ));
    let params = RuntimeParams {
        mode: Mode::Pre,
        budget_bytes: budget,
        tolerance_px: 1.0,
        block_bytes: 1024,
        frame_period_s: 1.0 / 60.0,
        ..RuntimeParams::default()
    };
    let mut walk = Walkthrough::start(skel, source, params).unwrap();
    let frames = run_path(&mut walk, &poses, &mut NoneRenderer::new(0.0), 60.0).unwrap();
    for f in &frames {
        assert_eq!(
            f.drawn_reps + f.substituted,
            f.front_reps,
            "frame {}",
            f.frame
        );
        assert!(f.loader.max_resident_bytes <= budget, "frame {}", f.frame);
    }
    let sum = |k: fn(&engine::metrics::FrameMetrics) -> u64| frames.iter().map(k).sum::<u64>();
    assert!(sum(|f| f.loader.skipped_bytes) > 0, "gaps read through");
    assert!(
        sum(|f| u64::from(f.loader.resumed)) > 0,
        "preempted prefetches resumed"
    );
    assert!(sum(|f| f.loader.prefetch_bytes) > 0);
}
