//! Multi-Triangulations inside the scene graph: the builder gives a large
//! object an MT rep, the runtime cuts it under one footprint in every mode
//! and cache policy, a footprint without room for it draws the static LOD,
//! corrupt MT data keeps its region at the level it has, and the wgpu
//! renderer draws the cut close to the full-resolution mesh.

use std::io::Cursor;
use std::sync::OnceLock;

use engine::camera::Pose;
use engine::metrics::FrameMetrics;
use engine::mt::cache::CacheMode;
use engine::render::NoneRenderer;
use engine::runtime::{Mode, RuntimeParams, Walkthrough};
use engine::{MemSource, RepKind, SceneFile, Skeleton};
use hlod_builder::build::{BuildParams, build_scene};

use super::gpu_shot;
use super::vdt_scene::{open, path};

fn with_mt() -> BuildParams {
    BuildParams {
        mt_tris: 10_000,
        ..BuildParams::default()
    }
}

/// The bunny with an MT (its two coarsest static LODs kept).
fn scene() -> &'static Vec<u8> {
    static S: OnceLock<Vec<u8>> = OnceLock::new();
    S.get_or_init(|| {
        let imp = hlod_builder::import::load(&e2e_tests::data_dir().join("bunny.glb")).unwrap();
        let mut out = Cursor::new(Vec::new());
        build_scene(&imp, &mut out, &with_mt(), false).unwrap();
        out.into_inner()
    })
}

fn mt_rep(s: &Skeleton) -> u32 {
    let mts: Vec<u32> = (0..s.reps.len() as u32)
        .filter(|&r| s.reps[r as usize].is_mt())
        .collect();
    assert_eq!(mts.len(), 1);
    mts[0]
}

/// Node bytes of the MT's store: room for the bunny on the test path.
const POOL: u64 = 8 << 20;

fn params(mode: Mode, budget: u64, cache: CacheMode, pool: u64) -> RuntimeParams {
    RuntimeParams {
        mode,
        budget_bytes: budget,
        tolerance_px: 1.0,
        width_px: 640,
        height_px: 480,
        near: 1e-4,
        far: 100.0,
        vdt_pool_bytes: pool,
        mt_cache: cache,
        ..RuntimeParams::default()
    }
}

/// Plays `poses` then holds the last one for `hold` frames, checking the
/// footprint on every frame.
fn walk(
    bytes: &[u8],
    (mode, cache, pool): (Mode, CacheMode, u64),
    budget: u64,
    poses: &[Pose],
    hold: usize,
) -> Vec<FrameMetrics> {
    let (skel, src) = open(bytes);
    let mut w = Walkthrough::start(skel, src, params(mode, budget, cache, pool)).unwrap();
    let mut r = NoneRenderer::new(0.0);
    let last = *poses.last().unwrap();
    let mut out = Vec::new();
    for (i, p) in poses
        .iter()
        .chain(std::iter::repeat_n(&last, hold))
        .enumerate()
    {
        let m = w.frame(p, &mut r).unwrap();
        if mode != Mode::Incore {
            assert!(
                m.loader.max_resident_bytes <= budget && m.vdt_bytes <= budget,
                "frame {i}: resident {} / MT store {} over the budget {budget}",
                m.loader.max_resident_bytes,
                m.vdt_bytes
            );
        }
        out.push(m);
    }
    out
}

#[test]
fn the_builder_gives_a_large_object_an_mt_rep() {
    let bytes = scene();
    let scene = SceneFile::from_source(MemSource::new(bytes.clone())).unwrap();
    assert_eq!(
        scene.header().version,
        engine::format::VERSION,
        "MT reps need version 4 or later"
    );
    let s = scene.skeleton();
    let t = mt_rep(s);
    let rec = s.reps[t as usize];
    let leaf = &s.nodes[rec.node as usize];
    assert!(leaf.is_leaf() && t == leaf.first_rep + leaf.rep_count - 1);
    assert_eq!(leaf.rep_count, 3, "two static LODs kept below the MT");
    assert!(rec.error < s.reps[t as usize - 1].error);
    assert_eq!(rec.tri_count, 69_451);
    scene.verify_all_reps().unwrap();
    let f = scene.read_mt(t).unwrap();
    assert_eq!(f.header.theta, 64);
    assert!(f.parts.iter().all(|p| p.count <= 64));
    assert!(scene.read_rep(t).is_err(), "an MT is not a mesh");
    let again = {
        let imp = hlod_builder::import::load(&e2e_tests::data_dir().join("bunny.glb")).unwrap();
        let mut out = Cursor::new(Vec::new());
        build_scene(&imp, &mut out, &with_mt(), false).unwrap();
        out.into_inner()
    };
    assert!(&again == bytes, "same input and parameters: the same bytes");
    let mut bad = s.clone();
    bad.reps[leaf.first_rep as usize].kind = RepKind::Mt as u16;
    let h = scene.header();
    assert!(
        bad.validate(h.data_offset, h.data_offset + h.data_len)
            .is_err(),
        "an MT cannot be a leaf's coarsest rep"
    );
}

#[test]
fn mts_cut_under_one_footprint_in_every_mode_and_cache_policy() {
    let bytes = scene();
    let (skel, _) = open(bytes);
    let t = mt_rep(&skel);
    let rec = skel.reps[t as usize];
    let statics: u64 = skel.reps[..t as usize]
        .iter()
        .map(|r| r.resident_len())
        .sum();
    let pool = rec.len as u64 + POOL;
    let budget = statics + u64::from(rec.len) + pool;
    let poses = path(&skel, 200);
    let incore = walk(
        bytes,
        (Mode::Incore, CacheMode::PC, POOL),
        u64::MAX,
        &poses,
        5,
    );
    let drawn: Vec<&FrameMetrics> = incore.iter().filter(|m| m.mt_trees > 0).collect();
    assert!(drawn.len() > 100, "the approach ends at the MT");
    assert!(drawn.iter().map(|m| m.mt_adapt).sum::<u32>() > 100);
    assert!(incore.iter().all(|m| m.mt_reads == 0 || m.mt_misses == 0));
    for mode in [Mode::NoPre, Mode::Pre] {
        for cache in CacheMode::ALL {
            let f = walk(bytes, (mode, cache, POOL), budget, &poses, 5);
            let reads: u32 = f.iter().map(|m| m.mt_reads).sum();
            assert!(reads > 20, "{mode:?} {cache:?}: {reads} reads");
            assert!(f.iter().all(|m| m.loader.read_errors == 0));
            // The same cut as in core wherever the footprint held it.
            let (a, b) = (f.last().unwrap(), incore.last().unwrap());
            assert_eq!(a.mt_misses, 0, "{mode:?} {cache:?}");
            assert_eq!(a.mt_tris, b.mt_tris, "{mode:?} {cache:?}");
            assert_eq!(a.drawn_tris, b.drawn_tris);
        }
    }
    // A tight store: misses, and the footprint still holds.
    let f = walk(
        bytes,
        (Mode::Pre, CacheMode::PC, 256 << 10),
        budget,
        &poses,
        0,
    );
    assert!(f.iter().map(|m| m.mt_misses).sum::<u32>() > 0);
    assert!(f.iter().any(|m| m.mt_trees > 0));
}

#[test]
fn a_footprint_without_room_for_the_mt_draws_its_static_lod() {
    let bytes = scene();
    let (skel, _) = open(bytes);
    let t = mt_rep(&skel) as usize;
    let statics: u64 = skel.reps[..t].iter().map(|r| r.resident_len()).sum();
    let budget = statics + u64::from(skel.reps[t].len) / 2;
    let f = walk(
        bytes,
        (Mode::Pre, CacheMode::PC, POOL),
        budget,
        &path(&skel, 120),
        0,
    );
    assert!(f.iter().all(|m| m.mt_trees == 0));
    assert!(f.iter().map(|m| m.substituted).sum::<u32>() > 10);
}

#[test]
fn corrupt_mt_data_keeps_its_region_and_the_run_goes_on() {
    let bytes = scene();
    let (skel, _) = open(bytes);
    let t = mt_rep(&skel);
    let rec = skel.reps[t as usize];
    let poses = path(&skel, 160);
    let flip = |at: u64| {
        let mut b = bytes.clone();
        b[at as usize] ^= 0x5a;
        b
    };
    let budget = rec.extent() * 4;
    let clean = walk(bytes, (Mode::Pre, CacheMode::PC, POOL), budget, &poses, 0);
    // Node records in the paged part: those regions stay coarser.
    let mut late = bytes.clone();
    for k in 1..8u64 {
        late[(rec.offset + u64::from(rec.len) + u64::from(rec.aux) * k / 9) as usize] ^= 0x5a;
    }
    let f = walk(&late, (Mode::Pre, CacheMode::PC, POOL), budget, &poses, 0);
    assert!(f.iter().any(|m| m.mt_trees > 0 && m.mt_tris > 0));
    assert!(f.iter().map(|m| m.mt_misses).sum::<u32>() > 0);
    let (a, b) = (f.last().unwrap(), clean.last().unwrap());
    assert!(a.mt_tris < b.mt_tris, "corrupt regions are not refined");
    // The in-core part (P_I's checksum): the static LOD is drawn.
    let early = flip(rec.offset + u64::from(rec.len) - 8);
    let f = walk(&early, (Mode::Pre, CacheMode::PC, POOL), budget, &poses, 0);
    assert!(f.iter().all(|m| m.mt_trees == 0));
    assert!(f.iter().map(|m| m.loader.read_errors).sum::<u32>() >= 1);
    // The embedded header: unusable from the start.
    let head = flip(rec.offset + 4);
    let f = walk(&head, (Mode::NoPre, CacheMode::PC, POOL), budget, &poses, 0);
    assert!(f.iter().all(|m| m.mt_trees == 0));
}

#[test]
fn the_wgpu_renderer_draws_the_cut_close_to_full_resolution() {
    let bytes = scene();
    let Some(ctx) =
        e2e_tests::gpu_or_skip("the_wgpu_renderer_draws_the_cut_close_to_full_resolution")
    else {
        return;
    };
    let pose = gpu_shot::overview(&open(bytes).0);
    let shoot = |tol: f32, mode: Mode| {
        let p = RuntimeParams {
            tolerance_px: tol,
            ..params(mode, u64::MAX / 2, CacheMode::PC, POOL)
        };
        gpu_shot::shoot(&ctx, open(bytes), p, &pose, 20)
    };
    let (full, m_full) = shoot(1e-6, Mode::Incore);
    assert_eq!(m_full.mt_tris, 69_451, "a tolerance of 0 draws the input");
    let (cut_in, m_in) = shoot(1.0, Mode::Incore);
    let (cut_pre, m_pre) = shoot(1.0, Mode::Pre);
    assert!(m_in.mt_trees == 1 && m_pre.mt_trees == 1);
    assert!(m_in.mt_tris < 69_451 / 2, "cut to the tolerance");
    assert_eq!(m_in.mt_tris, m_pre.mt_tris);
    let same = cut_pre.diff(&cut_in, 0).unwrap();
    assert!(same.psnr_db.is_infinite() || same.psnr_db > 60.0);
    let d = cut_in.diff(&full, 0).unwrap();
    assert!(
        d.psnr_db > 28.0,
        "cut vs full resolution: {:.1} dB",
        d.psnr_db
    );
}
