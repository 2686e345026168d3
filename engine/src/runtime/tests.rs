use std::sync::Arc;

use glam::Vec3;
use proptest::prelude::*;

use super::*;
use crate::camera::Pose;
use crate::disk::FaultySource;
use crate::format::SceneFile;
use crate::io::MemSource;
use crate::render::NoneRenderer;
use crate::testutil::{build, build_compressed};

pub(super) fn scene(reps: &[u32], children: &[u32]) -> (Arc<Skeleton>, Arc<dyn ByteSource>) {
    scene_of(build(reps, children).0)
}

pub(super) fn scene_of(bytes: Vec<u8>) -> (Arc<Skeleton>, Arc<dyn ByteSource>) {
    let file = SceneFile::from_source(MemSource::new(bytes.clone())).unwrap();
    (
        Arc::new(file.skeleton().clone()),
        Arc::new(MemSource::new(bytes)),
    )
}

/// A root with `n` leaves of three LODs under `n / 4` interior nodes.
pub(super) fn wide(n: u32) -> (Arc<Skeleton>, Arc<dyn ByteSource>) {
    let (reps, children) = wide_shape(n);
    scene(&reps, &children)
}

/// [`wide`] with its mesh payloads compressed.
pub(super) fn wide_compressed(n: u32) -> (Arc<Skeleton>, Arc<dyn ByteSource>) {
    let (reps, children) = wide_shape(n);
    scene_of(build_compressed(&reps, &children).0)
}

pub(super) fn wide_shape(n: u32) -> (Vec<u32>, Vec<u32>) {
    let groups = n / 4;
    let mut reps = vec![1];
    let mut children = vec![groups];
    reps.extend(std::iter::repeat_n(1, groups as usize));
    children.extend(std::iter::repeat_n(4, groups as usize));
    reps.extend(std::iter::repeat_n(3, (groups * 4) as usize));
    children.extend(std::iter::repeat_n(0, (groups * 4) as usize));
    (reps, children)
}

pub(super) fn params(mode: Mode, budget: u64) -> RuntimeParams {
    RuntimeParams {
        mode,
        budget_bytes: budget,
        tolerance_px: 1.0,
        width_px: 640,
        height_px: 480,
        near: 0.01,
        far: 1e4,
        block_bytes: 512,
        ..Default::default()
    }
}

pub(super) fn pose(x: f32, y: f32, z: f32, yaw: f32) -> Pose {
    Pose::from_yaw_pitch(Vec3::new(x, y, z), yaw, -0.2, 60.0)
}

pub(super) fn check_frames(frames: &[FrameMetrics], budget: u64) {
    for f in frames {
        // P_I's reps and P_R's occluder store share the footprint.
        assert!(
            f.loader.max_resident_bytes + f.occluder_bytes <= budget,
            "frame {}: {} + {} > {budget}",
            f.frame,
            f.loader.max_resident_bytes,
            f.occluder_bytes
        );
        assert!(f.loader.resident_bytes <= budget);
        assert_eq!(
            f.drawn_reps + f.substituted,
            f.front_reps,
            "frame {}",
            f.frame
        );
    }
}

/// A copy of `src` in memory and the disk model `latency` a seek, `bytes_per_sec`.
fn copy_and_model(
    src: &Arc<dyn ByteSource>,
    latency: std::time::Duration,
    bytes_per_sec: f64,
) -> (MemSource, crate::disk::DiskModel) {
    let mut bytes = vec![0u8; src.len() as usize];
    src.read_at(0, &mut bytes).unwrap();
    let model = crate::disk::DiskModel {
        latency,
        bytes_per_sec,
    };
    (MemSource::new(bytes), model)
}

/// Starts a walk on a manual clock of its own: time passes only as the
/// walk's reads, pacing and modelled drawing say, so that no runtime test
/// depends on the machine's speed or load.
pub(super) fn start(
    skel: Arc<Skeleton>,
    src: Arc<dyn ByteSource>,
    p: RuntimeParams,
) -> Result<Walkthrough, RuntimeError> {
    Walkthrough::start_with_clock(skel, src, p, Arc::new(crate::clock::ManualClock::new()))
}

/// [`start`] with `src` behind a disk model (`latency` a seek,
/// `bytes_per_sec`) on the walk's manual clock.
pub(super) fn start_throttled(
    skel: Arc<Skeleton>,
    src: &Arc<dyn ByteSource>,
    (latency, bytes_per_sec): (std::time::Duration, f64),
    p: RuntimeParams,
) -> Result<Walkthrough, RuntimeError> {
    let clock = Arc::new(crate::clock::ManualClock::new());
    let src = clocked(src, latency, bytes_per_sec, &clock);
    Walkthrough::start_with_clock(skel, src, p, clock)
}

/// `src` behind a simulated device on `clock` (reads advance it by their
/// modelled cost; nothing sleeps).
pub(super) fn clocked(
    src: &Arc<dyn ByteSource>,
    latency: std::time::Duration,
    bytes_per_sec: f64,
    clock: &Arc<crate::clock::ManualClock>,
) -> Arc<dyn ByteSource> {
    let (mem, model) = copy_and_model(src, latency, bytes_per_sec);
    Arc::new(crate::disk::ThrottledSource::with_clock(
        mem,
        model,
        clock.clone(),
    ))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]
    #[test]
    fn budget_is_never_exceeded_and_every_front_rep_is_drawn_or_substituted(
        budget_frac in 0.0f64..1.0,
        steps in prop::collection::vec((-3.0f32..3.0, -1.0f32..1.0, -3.0f32..3.0, -1.5f32..1.5), 200..400),
        prefetch in any::<bool>(),
        // A stall deadline (s) on a disk with 0.2 ms seeks, or none.
        deadline in prop_oneof![Just(0.0f32), 0.0001f32..0.001],
        compressed in any::<bool>(),
        occlusion in any::<bool>(),
        governor in any::<bool>(),
        fade in any::<bool>(),
        instanced in any::<bool>(),
    ) {
        let (skel, src) = if instanced {
            let (reps, children) = wide_shape(64);
            scene_of(crate::testutil::build_instanced(&reps, &children).0)
        } else if compressed { wide_compressed(64) } else { wide(64) };
        // A shared payload is resident once.
        let total: u64 = (skel.reps.iter().enumerate())
            .filter(|&(r, _)| skel.owns_payload(r as RepId))
            .map(|(_, r)| r.resident_len())
            .sum();
        let root = skel.reps[0].resident_len() + skel.reps[0].load_scratch();
        let budget = root + ((total - root) as f64 * budget_frac) as u64;
        let mode = if prefetch { Mode::Pre } else { Mode::NoPre };
        // The occluder store comes out of the footprint: P_I keeps enough
        // for the root's rep.
        let occlusion_bytes = if occlusion { ((budget - root) / 2).min(budget / 8) } else { 0 };
        let p = RuntimeParams {
            stall_deadline_s: deadline,
            occlusion_bytes,
            governor: governor.then(crate::governor::GovernorParams::default),
            fade_s: if fade { 0.02 } else { 0.0 },
            ..params(mode, budget)
        };
        // A deadline is tried on a disk with 0.2 ms seeks.
        let disk = (std::time::Duration::from_micros(200), 200e6);
        let mut walk = if deadline > 0.0 {
            start_throttled(skel, &src, disk, p).unwrap()
        } else {
            start(skel, src, p).unwrap()
        };
        let mut r = NoneRenderer::new(0.0);
        // A random walk, with jumps, along and around the row of leaves.
        let (mut x, mut y, mut z, mut yaw) = (0.0f32, 0.5f32, 3.0f32, 0.0f32);
        let mut poses = Vec::new();
        for &(dx, dy, dz, dyaw) in &steps {
            x = (x + dx).clamp(-10.0, 80.0);
            y = (y + dy).clamp(-2.0, 20.0);
            z = (z + dz).clamp(-20.0, 20.0);
            yaw += dyaw;
            poses.push(pose(x, y, z, yaw));
        }
        let frames = run_path(&mut walk, &poses, &mut r, 0.0).unwrap();
        check_frames(&frames, budget);
    }
}

#[test]
fn compressed_reps_are_expanded_counted_as_resident_and_drawn_as_in_core() {
    let (skel, src) = wide_compressed(64);
    assert!(
        skel.reps
            .iter()
            .all(|r| u64::from(r.len) < r.resident_len())
    );
    let total: u64 = skel.reps.iter().map(|r| r.resident_len()).sum();
    let poses: Vec<Pose> = (0..200)
        .map(|i| {
            pose(
                i as f32 * 0.35 - 5.0,
                0.5,
                2.0 + (i as f32 * 0.1).sin(),
                1.0,
            )
        })
        .collect();
    let mut drawn = Vec::new();
    for (mode, budget) in [
        (Mode::Incore, 1),
        (Mode::NoPre, total / 4),
        (Mode::Pre, total / 4),
    ] {
        let mut walk = start(skel.clone(), src.clone(), params(mode, budget)).unwrap();
        let frames = run_path(&mut walk, &poses, &mut NoneRenderer::new(0.0), 0.0).unwrap();
        if mode == Mode::Incore {
            assert!(frames.iter().all(|f| f.loader.resident_bytes == total));
        } else {
            check_frames(&frames, budget);
            let expanded: u64 = frames.iter().map(|f| f.loader.expanded_bytes).sum();
            let read: u64 = frames
                .iter()
                .map(|f| f.loader.stage2_bytes + f.loader.prefetch_bytes)
                .sum();
            // Disk bytes are the stored (compressed) ones; what was
            // expanded from them is larger.
            assert!(
                read > 0 && expanded > read,
                "{mode:?}: read {read}, expanded {expanded}"
            );
        }
        assert!(frames.iter().all(|f| f.loader.read_errors == 0));
        drawn.push((
            frames.iter().map(|f| f.drawn_tris).collect::<Vec<_>>(),
            frames.iter().map(|f| f.substituted).collect::<Vec<_>>(),
        ));
    }
    // Where nothing was substituted, the same triangles were drawn as in core.
    for (mode, (tris, subst)) in drawn[1..].iter().enumerate() {
        let same = (0..poses.len()).filter(|&i| subst[i] == 0);
        assert!(same.clone().count() > poses.len() / 2, "mode {mode}");
        for i in same {
            assert_eq!(tris[i], drawn[0].0[i], "mode {mode}, frame {i}");
        }
    }
}

#[test]
fn thousands_of_frames_under_a_tight_budget_do_not_deadlock() {
    let (skel, src) = wide(128);
    let budget = u64::from(skel.reps[0].len) * 6;
    for mode in [Mode::NoPre, Mode::Pre] {
        let mut walk = start(skel.clone(), src.clone(), params(mode, budget)).unwrap();
        let poses: Vec<Pose> = (0..3000)
            .map(|i| {
                let t = i as f32 * 0.05;
                pose(
                    64.0 + 60.0 * t.sin(),
                    0.5,
                    1.5 + (t * 0.7).cos(),
                    (t * 3.1).sin() * 2.5,
                )
            })
            .collect();
        let frames = run_path(&mut walk, &poses, &mut NoneRenderer::new(0.0), 0.0).unwrap();
        check_frames(&frames, budget);
        assert!(
            frames.iter().map(|f| f.substituted).sum::<u32>() > 0,
            "{mode:?}: the budget should bind"
        );
        assert!(frames.iter().map(|f| f.loader.evictions).sum::<u32>() > 0);
    }
}

#[test]
fn incore_holds_everything_and_fetches_nothing_per_frame() {
    let (skel, src) = wide(16);
    let total: u64 = skel.reps.iter().map(|r| u64::from(r.len)).sum();
    let mut walk = start(skel, src, params(Mode::Incore, 1)).unwrap();
    let poses: Vec<Pose> = (0..50)
        .map(|i| pose(i as f32 * 0.4, 0.5, 2.0, 1.2))
        .collect();
    let frames = run_path(&mut walk, &poses, &mut NoneRenderer::new(0.0), 0.0).unwrap();
    for f in &frames {
        assert_eq!(f.loader.stage2_bytes, 0);
        assert_eq!(f.loader.missing_reps, 0);
        assert_eq!(f.loader.resident_bytes, total);
        assert_eq!(f.drawn_reps, f.front_reps);
    }
}

#[test]
fn prefetching_cuts_demand_fetches_on_a_smooth_path() {
    let (skel, src) = wide(128);
    let total: u64 = skel.reps.iter().map(|r| u64::from(r.len)).sum();
    let poses: Vec<Pose> = (0..400)
        .map(|i| pose(i as f32 * 0.3 - 5.0, 0.5, 2.0, 1.0))
        .collect();
    let mut bytes = Vec::new();
    for mode in [Mode::NoPre, Mode::Pre] {
        let mut walk = start(skel.clone(), src.clone(), params(mode, total / 3)).unwrap();
        // A paced walk leaves P_I time to prefetch between frames.
        let frames = run_path(&mut walk, &poses, &mut NoneRenderer::new(0.0), 500.0).unwrap();
        check_frames(&frames, total / 3);
        bytes.push(frames.iter().map(|f| f.loader.stage2_bytes).sum::<u64>());
    }
    assert!(
        bytes[1] * 2 < bytes[0],
        "Stage II bytes nopre {} vs pre {}",
        bytes[0],
        bytes[1]
    );
}

#[test]
fn a_failing_rep_is_logged_substituted_and_the_run_goes_on() {
    let (bytes, skeleton) = build(&[1, 1, 3, 3], &[1, 2, 0, 0]);
    let bad = skeleton.reps[4]; // node 2's finest-but-one... any leaf rep
    let src = FaultySource::new(MemSource::new(bytes), vec![(bad.offset, bad.offset + 1)]);
    let skel = Arc::new(skeleton);
    let mut walk = start(skel.clone(), Arc::new(src), params(Mode::NoPre, 1 << 20)).unwrap();
    let mut errors = 0;
    let mut substituted = 0;
    for i in 0..200 {
        let p = pose(
            0.5 + (i % 20) as f32 * 0.05,
            0.5,
            0.2 + (i % 50) as f32 * 0.5,
            0.0,
        );
        let f = walk.frame(&p, &mut NoneRenderer::new(0.0)).unwrap();
        errors += f.loader.read_errors;
        substituted += f.substituted;
        assert_eq!(f.drawn_reps + f.substituted, f.front_reps);
    }
    assert_eq!(errors, 1, "logged once");
    assert!(substituted > 0);
}

#[test]
fn start_up_errors_are_typed() {
    let (skel, src) = wide(8);
    let root = u64::from(skel.reps[0].len);
    assert!(matches!(
        start(skel.clone(), src.clone(), params(Mode::NoPre, root - 1)),
        Err(RuntimeError::BudgetTooSmall { .. })
    ));
    let mut p = params(Mode::Pre, 1 << 20);
    p.tolerance_px = f32::NAN;
    assert!(matches!(
        start(skel.clone(), src.clone(), p),
        Err(RuntimeError::Params(_))
    ));
    let mut p = params(Mode::Pre, 1 << 20);
    p.prefetch.delta_px = 0.5;
    assert!(start(skel.clone(), src.clone(), p).is_err());
    let mut p = params(Mode::Pre, 1 << 20);
    p.prefetch.speculative_share = 0.0;
    assert!(matches!(
        start(skel.clone(), src.clone(), p),
        Err(RuntimeError::Params(_))
    ));
    let bad = Arc::new(FaultySource::new(
        MemSource::new(vec![0u8; src.len() as usize]),
        vec![(0, u64::MAX)],
    ));
    assert!(matches!(
        start(skel, bad, params(Mode::NoPre, 1 << 20)),
        Err(RuntimeError::RootUnreadable(_))
    ));
    assert!(Mode::parse("fast").is_err());
}

/// A renderer that panics after `n` draws.
struct Panicky(u32);

impl Renderer for Panicky {
    fn begin_frame(&mut self, _view: &crate::camera::View) {}
    fn draw(
        &mut self,
        _rep: RepId,
        _record: &crate::format::RepRecord,
        _payload: &Arc<[u8]>,
        _style: crate::render::DrawStyle,
    ) {
        self.0 = self.0.checked_sub(1).expect("renderer failure");
    }
    fn end_frame(&mut self) {}
    fn name(&self) -> &'static str {
        "panicky"
    }
}

#[test]
fn a_renderer_panic_mid_frame_does_not_hang_shutdown() {
    // Many reps per frame so that P_I fills the reply channel while P_R unwinds.
    let (skel, src) = wide(1024);
    let walk = std::sync::Mutex::new(start(skel, src, params(Mode::Incore, 1)).unwrap());
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let mut w = walk.lock().unwrap();
        let mut renderer = Panicky(3);
        let along_the_row = pose(-2.0, 0.5, 0.5, -std::f32::consts::FRAC_PI_2);
        let _ = w.frame(&along_the_row, &mut renderer);
    }));
    assert!(r.is_err());
    drop(walk); // must return
}

/// Counts the reads that do not continue where the previous one ended.
pub(super) struct SeekCounter {
    pub(super) inner: Arc<dyn ByteSource>,
    pub(super) state: std::sync::Mutex<(Option<u64>, u64)>,
}

impl ByteSource for SeekCounter {
    fn len(&self) -> u64 {
        self.inner.len()
    }

    fn read_at(&self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
        {
            let mut s = self.state.lock().unwrap();
            if s.0 != Some(offset) {
                s.1 += 1;
            }
            s.0 = Some(offset + buf.len() as u64);
        }
        self.inner.read_at(offset, buf)
    }
}

#[test]
fn reading_through_short_gaps_saves_seeks_and_changes_nothing_drawn() {
    let (skel, mem) = wide(64);
    let budget = skel.reps.iter().map(|r| u64::from(r.len)).sum::<u64>() / 3;
    // 10 ms seeks, 4 MB/s: reading through a gap of < 40 KB beats a seek.
    let poses: Vec<Pose> = (0..40)
        .map(|i| pose(i as f32 * 1.2, 0.5, 2.0, 1.2 + (i as f32 * 0.3).sin()))
        .collect();
    let mut runs = Vec::new();
    for (mode, gap) in [
        (Mode::NoPre, 0),
        (Mode::NoPre, 1 << 20),
        (Mode::Pre, 0),
        (Mode::Pre, 1 << 20),
    ] {
        // A simulated disk on a manual clock: the learnt costs are exact,
        // whatever the machine's load (the throttled device this test used
        // to sleep on made it fail under a busy machine).
        let clock = Arc::new(crate::clock::ManualClock::new());
        let counter = Arc::new(SeekCounter {
            inner: clocked(&mem, std::time::Duration::from_millis(10), 4e6, &clock),
            state: Default::default(),
        });
        let p = RuntimeParams {
            coalesce_max_gap: gap,
            block_bytes: 16 << 10,
            ..params(mode, budget)
        };
        let mut walk =
            Walkthrough::start_with_clock(skel.clone(), counter.clone(), p, clock.clone()).unwrap();
        let frames = run_path(&mut walk, &poses, &mut NoneRenderer::new(0.0), 0.0).unwrap();
        drop(walk);
        check_frames(&frames, budget);
        let seeks = counter.state.lock().unwrap().1;
        runs.push((mode, gap, frames, seeks));
    }
    let total = |f: &[FrameMetrics], k: fn(&FrameMetrics) -> u64| f.iter().map(k).sum::<u64>();
    let (off, on) = (&runs[0], &runs[1]);
    // On demand only, the same reps are fetched and drawn either way.
    for (a, b) in off.2.iter().zip(&on.2) {
        assert_eq!(
            a.loader.missing_reps, b.loader.missing_reps,
            "frame {}",
            a.frame
        );
        assert_eq!(
            a.loader.stage2_bytes, b.loader.stage2_bytes,
            "frame {}",
            a.frame
        );
        assert_eq!(a.drawn_reps, b.drawn_reps, "frame {}", a.frame);
    }
    assert_eq!(total(&off.2, |f| f.loader.skipped_bytes), 0);
    assert!(total(&on.2, |f| f.loader.skipped_bytes) > 0);
    eprintln!("nopre seeks: {} with, {} without", on.3, off.3);
    assert!(
        on.3 * 10 < off.3 * 8,
        "seeks: {} with, {} without",
        on.3,
        off.3
    );
    // With prefetching (timing-dependent, so only the invariants above and
    // that gaps were read through).
    assert!(total(&runs[3].2, |f| f.loader.skipped_bytes) > 0);
    assert_eq!(total(&runs[2].2, |f| f.loader.skipped_bytes), 0);
}

#[test]
fn an_all_around_f_i_and_the_sweep_leave_nothing_missing_after_a_sudden_turn() {
    let (skel, src) = wide(64);
    let total: u64 = skel.reps.iter().map(|r| u64::from(r.len)).sum();
    // The camera rests in the row of leaves looking along it, then turns
    // round in one frame.
    let half = std::f32::consts::FRAC_PI_2;
    let mut poses = vec![pose(30.0, 0.5, 0.5, -half); 12];
    poses.push(pose(30.0, 0.5, 0.5, half));
    let run = |margin: f32, sweep_bytes: u32| {
        let p = RuntimeParams {
            frame_period_s: 0.05,
            prefetch: PrefetchParams {
                margin_deg: margin,
                max_margin_deg: margin,
                speculative_share: 1.0,
                sweep_bytes,
                // The margins alone decide here.
                all_around_fit: 0.0,
                ..PrefetchParams::default()
            },
            ..params(Mode::Pre, total)
        };
        let mut walk = start(skel.clone(), src.clone(), p).unwrap();
        let frames = run_path(&mut walk, &poses, &mut NoneRenderer::new(0.0), 20.0).unwrap();
        check_frames(&frames, total);
        frames
    };
    for sweep in [0, 1 << 20] {
        let all_around = run(180.0, sweep);
        let last = all_around.last().unwrap();
        assert!(last.front_reps > 0);
        assert_eq!(
            last.loader.missing_reps, 0,
            "sweep {sweep}: behind was prefetched"
        );
    }
    // The control: F_I 30° wider than F_R does not reach behind the camera.
    let narrow = run(30.0, 0);
    assert!(narrow.last().unwrap().loader.missing_reps > 0);
}

#[test]
fn f_i_goes_all_around_when_the_all_around_front_fits_even_after_a_slow_first_frame() {
    let (skel, mem) = wide(64);
    let total: u64 = skel.reps.iter().map(|r| u64::from(r.len)).sum();
    // 5 ms a seek, 0.5 MB/s: the first front (packed reps, read on from
    // where start-up's read ended: no seek) takes longer than a frame period, so the first prefetch waits for the next
    // fetch command, and the camera does not move again before it turns
    // round.
    let half = std::f32::consts::FRAC_PI_2;
    let mut poses = vec![pose(30.0, 0.5, 0.5, -half); 40];
    poses.push(pose(30.0, 0.5, 0.5, half));
    let run = |budget: u64, all_around_fit: f32| {
        let p = RuntimeParams {
            frame_period_s: 0.05,
            prefetch: PrefetchParams {
                all_around_fit,
                ..PrefetchParams::default()
            },
            ..params(Mode::Pre, budget)
        };
        let disk = (std::time::Duration::from_millis(5), 0.5e6);
        let mut walk = start_throttled(skel.clone(), &mem, disk, p).unwrap();
        let frames = run_path(&mut walk, &poses, &mut NoneRenderer::new(0.0), 20.0).unwrap();
        check_frames(&frames, budget);
        frames
    };
    let fits = run(total, 1.0);
    assert!(
        fits[0].frame_ms > 50.0,
        "the first frame overran the period ({} ms)",
        fits[0].frame_ms
    );
    let last = fits.last().unwrap();
    assert!(last.front_reps > 0);
    assert_eq!(last.loader.missing_reps, 0, "behind was prefetched at rest");
    // Never all around: the default margins do not reach behind.
    assert!(run(total, 0.0).last().unwrap().loader.missing_reps > 0);
}

#[test]
fn a_stall_deadline_draws_ancestors_for_what_is_late_and_loads_it_after_the_frame() {
    let (skel, mem) = wide(64);
    let total: u64 = skel.reps.iter().map(|r| u64::from(r.len)).sum();
    // 5 ms a seek against a 2 ms deadline: a turn's misses cannot all be
    // read in time.
    let half = std::f32::consts::FRAC_PI_2;
    let mut poses = vec![pose(30.0, 0.5, 0.5, -half); 5];
    poses.extend(vec![pose(30.0, 0.5, 0.5, half); 30]);
    let run = |deadline_s: f32, mode: Mode| {
        let p = RuntimeParams {
            frame_period_s: 0.04,
            stall_deadline_s: deadline_s,
            // F_I never reaches behind: the turn misses.
            prefetch: PrefetchParams {
                all_around_fit: 0.0,
                max_margin_deg: 10.0,
                ..PrefetchParams::default()
            },
            ..params(mode, total)
        };
        let disk = (std::time::Duration::from_millis(5), 20e6);
        let mut walk = start_throttled(skel.clone(), &mem, disk, p).unwrap();
        let frames = run_path(&mut walk, &poses, &mut NoneRenderer::new(0.0), 25.0).unwrap();
        check_frames(&frames, total);
        frames
    };
    for mode in [Mode::NoPre, Mode::Pre] {
        let late = run(0.002, mode);
        let turn = &late[5];
        assert!(
            turn.loader.missing_reps > 1,
            "{mode:?}: the turn misses reps"
        );
        assert!(turn.loader.late_reps > 0 && turn.loader.late_reps <= turn.loader.missing_reps);
        assert!(
            turn.substituted >= turn.loader.late_reps,
            "late reps are drawn as ancestors"
        );
        let read_late: u64 = late.iter().map(|f| f.loader.late_bytes).sum();
        assert!(
            read_late > 0,
            "{mode:?}: late reps are read after their frame"
        );
        let last = late.last().unwrap();
        assert_eq!(
            last.loader.missing_reps, 0,
            "{mode:?}: at rest, everything came"
        );
        assert_eq!(last.substituted, 0);
        // Without a deadline P_R waits: nothing is late, nothing substituted.
        let wait = run(0.0, mode);
        assert!(
            wait.iter()
                .all(|f| f.loader.late_reps == 0 && f.loader.late_bytes == 0)
        );
        assert_eq!(wait[5].substituted, 0);
    }
    let bad = RuntimeParams {
        stall_deadline_s: -1.0,
        ..params(Mode::Pre, total)
    };
    assert!(matches!(bad.check(), Err(RuntimeError::Params(_))));
}
