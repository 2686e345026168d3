//! View-dependence trees inside the scene graph: the builder gives a large
//! object a tree rep, the runtime refines it under one footprint in every
//! mode, bad tree data degrades to the static LODs, and the wgpu renderer
//! draws the refined cut close to the full-resolution mesh.

use std::io::Cursor;
use std::sync::{Arc, OnceLock};

use engine::camera::Pose;
use engine::metrics::FrameMetrics;
use engine::render::NoneRenderer;
use engine::runtime::{Mode, RuntimeParams, Walkthrough};
use engine::{ByteSource, MemSource, RepKind, SceneFile, Skeleton};
use engine_cli::paths::{PathKind, generate_path};
use hlod_builder::build::{BuildParams, build_scene};

use super::gpu_shot;

/// The bunny with a tree (its two coarsest static LODs kept), and without.
fn scenes() -> &'static (Vec<u8>, Vec<u8>) {
    static S: OnceLock<(Vec<u8>, Vec<u8>)> = OnceLock::new();
    S.get_or_init(|| {
        let imp = hlod_builder::import::load(&e2e_tests::data_dir().join("bunny.glb")).unwrap();
        let build = |p: &BuildParams| {
            let mut out = Cursor::new(Vec::new());
            build_scene(&imp, &mut out, p, false).unwrap();
            out.into_inner()
        };
        let with = BuildParams {
            vdt_tris: 10_000,
            ..BuildParams::default()
        };
        let plain = BuildParams {
            chunk_tris: 1 << 20,
            ..BuildParams::default()
        };
        (build(&with), build(&plain))
    })
}

/// A scene in memory: its skeleton and a source over its bytes.
pub(crate) fn open(bytes: &[u8]) -> (Arc<Skeleton>, Arc<dyn ByteSource>) {
    let scene = SceneFile::from_source(MemSource::new(bytes.to_vec())).unwrap();
    let skel = Arc::new(scene.skeleton().clone());
    (skel, Arc::new(MemSource::new(bytes.to_vec())))
}

fn tree_rep(s: &Skeleton) -> u32 {
    let trees: Vec<u32> = (0..s.reps.len() as u32)
        .filter(|&r| s.reps[r as usize].is_vdt())
        .collect();
    assert_eq!(trees.len(), 1);
    trees[0]
}

/// Place holders of each tree: room for the bunny's working set on the
/// test path (its whole meta-node data is 4.9 MiB).
const POOL: u64 = 4 << 20;

fn params(mode: Mode, budget: u64) -> RuntimeParams {
    RuntimeParams {
        mode,
        budget_bytes: budget,
        tolerance_px: 1.0,
        width_px: 640,
        height_px: 480,
        near: 1e-4,
        far: 100.0,
        vdt_pool_bytes: POOL,
        ..RuntimeParams::default()
    }
}

/// An approach-and-orbit path around the whole scene.
pub(crate) fn path(s: &Skeleton, frames: usize) -> Vec<Pose> {
    let root = &s.nodes[0];
    generate_path(
        PathKind::ApproachOrbit,
        root.bbox_min.into(),
        root.bbox_max.into(),
        frames,
    )
}

/// Plays `poses`, then holds the last one for `hold` frames (letting the
/// meta-node reads catch up), checking the footprint on every frame.
fn walk(bytes: &[u8], mode: Mode, budget: u64, poses: &[Pose], hold: usize) -> Vec<FrameMetrics> {
    let (skel, src) = open(bytes);
    let mut w = Walkthrough::start(skel, src, params(mode, budget)).unwrap();
    let mut r = NoneRenderer::new(0.0);
    let last = *poses.last().unwrap();
    let mut out = Vec::new();
    for (i, p) in poses
        .iter()
        .chain(std::iter::repeat_n(&last, hold))
        .enumerate()
    {
        if i >= poses.len() {
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        let m = w.frame(p, &mut r).unwrap();
        if mode != Mode::Incore {
            assert!(
                m.loader.max_resident_bytes <= budget && m.vdt_bytes <= budget,
                "frame {i}: resident {} / trees {} over the budget {budget}",
                m.loader.max_resident_bytes,
                m.vdt_bytes
            );
        }
        out.push(m);
    }
    out
}

#[test]
fn the_builder_gives_a_large_object_a_tree_rep() {
    let (bytes, _) = scenes();
    let scene = SceneFile::from_source(MemSource::new(bytes.clone())).unwrap();
    let s = scene.skeleton();
    let t = tree_rep(s);
    let rec = s.reps[t as usize];
    let leaf = &s.nodes[rec.node as usize];
    assert!(leaf.is_leaf() && t == leaf.first_rep + leaf.rep_count - 1);
    assert_eq!(leaf.rep_count, 3, "two static LODs kept below the tree");
    assert!(rec.error < s.reps[t as usize - 1].error);
    assert_eq!(rec.vertex_count, 34_834);
    scene.verify_all_reps().unwrap();
    let file = scene.read_vdt(t).unwrap();
    file.load_tree().unwrap().validate().unwrap();
    assert!(scene.read_rep(t).is_err(), "a tree is not a mesh");
    // Same input and parameters: the same bytes.
    let again = {
        let imp = hlod_builder::import::load(&e2e_tests::data_dir().join("bunny.glb")).unwrap();
        let mut out = Cursor::new(Vec::new());
        let p = BuildParams {
            vdt_tris: 10_000,
            ..BuildParams::default()
        };
        build_scene(&imp, &mut out, &p, false).unwrap();
        out.into_inner()
    };
    assert!(&again == bytes);
    // Kind rules: a tree cannot be a leaf's coarsest rep.
    let mut bad = s.clone();
    bad.reps[leaf.first_rep as usize].kind = RepKind::Vdt as u16;
    let h = scene.header();
    assert!(
        bad.validate(h.data_offset, h.data_offset + h.data_len)
            .is_err()
    );
}

#[test]
fn trees_refine_under_one_footprint_in_every_mode() {
    let (bytes, _) = scenes();
    let (skel, _) = open(bytes);
    let t = tree_rep(&skel);
    let rec = skel.reps[t as usize];
    // Room for the static LODs, the tree's payload and its store, well
    // under the tree's data.
    let statics: u64 = skel.reps[..t as usize]
        .iter()
        .map(|r| r.resident_len())
        .sum();
    let budget = statics + u64::from(rec.len) + u64::from(rec.len) + POOL;
    assert!(budget < rec.extent());
    let poses = path(&skel, 240);
    let incore = walk(bytes, Mode::Incore, u64::MAX, &poses, 20);
    assert!(incore.iter().all(|m| m.metas_loaded == 0));
    let drawn: Vec<&FrameMetrics> = incore.iter().filter(|m| m.vdt_trees > 0).collect();
    assert!(drawn.len() > 100, "the approach ends at the tree");
    assert!(drawn.iter().map(|m| m.adapt).sum::<u32>() > 1000);
    for mode in [Mode::NoPre, Mode::Pre] {
        let f = walk(bytes, mode, budget, &poses, 20);
        let loaded: u32 = f.iter().map(|m| m.metas_loaded).sum();
        assert!(loaded > 50, "{mode:?}: {loaded} meta-nodes read");
        assert!(f.iter().all(|m| m.loader.read_errors == 0));
        assert!(f.iter().any(|m| m.vdt_bytes > 0));
        // Held still, the paged tree reaches the in-core cut.
        let (a, b) = (f.last().unwrap(), incore.last().unwrap());
        assert_eq!(a.vdt_tris, b.vdt_tris, "{mode:?}");
        assert_eq!(a.adapt, 0);
    }
}

#[test]
fn a_footprint_without_room_for_the_tree_draws_its_static_lod() {
    let (bytes, _) = scenes();
    let (skel, _) = open(bytes);
    let t = tree_rep(&skel) as usize;
    let statics: u64 = skel.reps[..t].iter().map(|r| r.resident_len()).sum();
    let budget = statics + u64::from(skel.reps[t].len) / 2;
    let f = walk(bytes, Mode::Pre, budget, &path(&skel, 120), 0);
    assert!(f.iter().all(|m| m.vdt_trees == 0));
    assert!(f.iter().map(|m| m.substituted).sum::<u32>() > 10);
}

#[test]
fn bad_tree_data_degrades_to_coarser_levels() {
    let (bytes, _) = scenes();
    let (skel, _) = open(bytes);
    let t = tree_rep(&skel);
    let rec = skel.reps[t as usize];
    let poses = path(&skel, 180);
    let flip = |at: u64| {
        let mut b = bytes.clone();
        b[at as usize] ^= 0x5a;
        b
    };
    // A meta-node in the paged part: the tree stays coarser there.
    let late = flip(rec.offset + u64::from(rec.len) + u64::from(rec.aux) / 4);
    let f = walk(&late, Mode::Pre, rec.extent(), &poses, 10);
    assert!(f.iter().any(|m| m.vdt_trees > 0 && m.vdt_tris > 0));
    // The payload (root meta-nodes): P_I's checksum fails, the static LOD is drawn.
    let early = flip(rec.offset + u64::from(rec.len) - 8);
    let f = walk(&early, Mode::Pre, rec.extent(), &poses, 0);
    assert!(f.iter().all(|m| m.vdt_trees == 0));
    assert!(f.iter().map(|m| m.loader.read_errors).sum::<u32>() >= 1);
    assert!(f.iter().map(|m| m.substituted).sum::<u32>() > 10);
    // The embedded header: the tree is unusable from the start.
    let head = flip(rec.offset + 4);
    let f = walk(&head, Mode::NoPre, rec.extent(), &poses, 0);
    assert!(f.iter().all(|m| m.vdt_trees == 0));
}

#[test]
fn the_wgpu_renderer_draws_the_refined_cut_close_to_full_resolution() {
    let (with, plain) = scenes();
    let Some(ctx) =
        e2e_tests::gpu_or_skip("the_wgpu_renderer_draws_the_refined_cut_close_to_full_resolution")
    else {
        return;
    };
    let pose = gpu_shot::overview(&open(with).0);
    let shoot = |bytes: &[u8], mode: Mode| {
        gpu_shot::shoot(&ctx, open(bytes), params(mode, u64::MAX / 2), &pose, 40)
    };
    let (full, _) = shoot(plain, Mode::Incore);
    let (tree_in, m_in) = shoot(with, Mode::Incore);
    let (tree_pre, m_pre) = shoot(with, Mode::Pre);
    assert!(m_in.vdt_trees == 1 && m_pre.vdt_trees == 1);
    assert!(
        m_in.vdt_tris < 69_451 / 2,
        "refined to the tolerance, not to the input"
    );
    assert_eq!(m_in.vdt_tris, m_pre.vdt_tris);
    let same = tree_pre.diff(&tree_in, 0).unwrap();
    assert!(same.psnr_db.is_infinite() || same.psnr_db > 60.0);
    let d = tree_in.diff(&full, 0).unwrap();
    assert!(
        d.psnr_db > 25.0,
        "refined cut vs full resolution: {:.1} dB",
        d.psnr_db
    );
    let bg = &tree_in.data[..3];
    let covered = tree_in
        .data
        .chunks_exact(4)
        .filter(|p| &p[..3] != bg)
        .count();
    assert!(covered > 320 * 240 / 20, "the bunny covers the view");
}
