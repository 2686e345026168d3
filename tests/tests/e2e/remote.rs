//! Scenes read from a real web server (nginx, started through
//! `scripts/serve.sh`): the same bytes and fronts as the local file under
//! the same budget, a file replaced on the server mid-walk, and the faults
//! a network brings (5xx, 404, 416, `Range` ignored, short bodies, resets,
//! stalls) injected by a proxy in front of nginx.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use e2e_tests::servers::{Fault, FaultProxy, Nginx};
use engine::camera::Pose;
use engine::metrics::FrameMetrics;
use engine::render::NoneRenderer;
use engine::runtime::{Mode, RuntimeParams, Walkthrough, run_path};
use engine::skeleton::Skeleton;
use engine::{ByteSource, FileSource, SceneFile};
use engine_cli::SceneHandle;
use engine_cli::paths::{PathKind, generate_path};
use engine_cli::remote::{RemoteOptions, RemoteSource};
use glam::Vec3;
use hlod_builder::build::{BuildParams, build_file};
use hlod_builder::scenegen::plant::{PlantParams, write_plant};

/// A plant built into `dir/NAME`.
fn plant(dir: &Path, name: &str, seed: u64) -> PathBuf {
    let glb = dir.join(format!("{name}.glb"));
    let scene = dir.join(name);
    let p = PlantParams {
        seed,
        objects: 120,
        triangles: 60_000,
    };
    write_plant(&p, &glb).unwrap();
    build_file(&glb, &scene, &BuildParams::default(), false).unwrap();
    std::fs::remove_file(&glb).unwrap();
    scene
}

fn flythrough(skel: &Skeleton, frames: usize) -> Vec<Pose> {
    let root = &skel.nodes[0];
    generate_path(
        PathKind::Flythrough,
        Vec3::from(root.bbox_min),
        Vec3::from(root.bbox_max),
        frames,
    )
}

fn params(mode: Mode, budget: u64) -> RuntimeParams {
    RuntimeParams {
        mode,
        budget_bytes: budget,
        tolerance_px: 1.0,
        ..RuntimeParams::default()
    }
}

/// A plant built into a temporary folder as `plant.hlod` and served there
/// by nginx, or `None` (the skip recorded) without nginx.
fn served_plant(test: &str) -> Option<(tempfile::TempDir, PathBuf, Nginx, String)> {
    let dir = tempfile::tempdir().unwrap();
    let local = plant(dir.path(), "plant.hlod", 5);
    let nginx = Nginx::start(test, dir.path())?;
    let url = format!("{}/plant.hlod", nginx.base);
    Some((dir, local, nginx, url))
}

/// Walks `source` in `mode` under `budget`, checking every frame: the
/// footprint within the budget, every front rep drawn as itself or an
/// ancestor.
fn walk(
    skel: &Arc<Skeleton>,
    source: Arc<dyn ByteSource>,
    mode: Mode,
    budget: u64,
    poses: &[Pose],
) -> Vec<FrameMetrics> {
    let mut w = Walkthrough::start(skel.clone(), source, params(mode, budget)).unwrap();
    let frames = run_path(&mut w, poses, &mut NoneRenderer::new(0.0), 0.0).unwrap();
    for f in &frames {
        assert!(
            f.loader.max_resident_bytes <= budget,
            "{mode:?} frame {}",
            f.frame
        );
        assert_eq!(
            f.drawn_reps + f.substituted,
            f.front_reps,
            "{mode:?} frame {}",
            f.frame
        );
    }
    frames
}

fn errors(frames: &[FrameMetrics]) -> u32 {
    frames.iter().map(|f| f.loader.read_errors).sum()
}

fn fast_options() -> RemoteOptions {
    RemoteOptions {
        read_timeout: Duration::from_millis(400),
        connect_timeout: Duration::from_secs(2),
        timeout: Duration::from_secs(10),
        retries: 3,
        init_backoff: Duration::from_millis(10),
        max_backoff: Duration::from_millis(50),
        retry_timeout: Duration::from_secs(5),
        // One request at a time: each fault pattern meets the reads it is
        // queued for (reading ahead is tested on its own).
        max_requests: 1,
        read_ahead_bytes: 0,
    }
}

#[test]
fn a_scene_on_nginx_reads_and_walks_as_the_local_file() {
    let Some((_dir, local, nginx, url)) = served_plant("remote::reads_and_walks") else {
        return;
    };
    let handle = SceneHandle::open(Path::new(&url)).unwrap();
    assert!(handle.is_remote());
    let remote = SceneFile::from_source(handle.raw().unwrap()).unwrap();
    let file = SceneFile::open(&local).unwrap();
    assert_eq!(remote.skeleton(), file.skeleton());
    assert_eq!(
        remote.read_objects_bytes().unwrap(),
        file.read_objects_bytes().unwrap()
    );
    for r in 0..file.skeleton().reps.len() as u32 {
        assert_eq!(
            remote.read_rep_bytes(r).unwrap(),
            file.read_rep_bytes(r).unwrap(),
            "rep {r}"
        );
    }
    assert!(
        handle.source(Some(engine::disk::DiskModel::HDD)).is_err(),
        "no disk model over a network"
    );

    let skel = Arc::new(file.skeleton().clone());
    let data: u64 = skel.reps.iter().map(|r| r.expanded_extent()).sum();
    let poses = flythrough(&skel, 160);
    for mode in [Mode::NoPre, Mode::Pre] {
        let over_http = walk(&skel, handle.source(None).unwrap(), mode, data / 20, &poses);
        let from_file: Arc<dyn ByteSource> = Arc::new(FileSource::open(&local).unwrap());
        let on_disk = walk(&skel, from_file, mode, data / 20, &poses);
        assert_eq!(errors(&over_http), 0, "{mode:?}");
        // The front depends on the view alone: the same on every frame.
        let fronts = |f: &[FrameMetrics]| f.iter().map(|m| m.front_reps).collect::<Vec<_>>();
        assert_eq!(fronts(&over_http), fronts(&on_disk), "{mode:?}");
        let fetched: u64 = over_http
            .iter()
            .map(|f| f.loader.stage2_bytes + f.loader.prefetch_bytes)
            .sum();
        assert!(fetched > 0, "{mode:?} read reps over HTTP");
    }
    // Every read was a ranged GET answered with 206.
    let log = nginx.access_log();
    let gets: Vec<&String> = log.iter().filter(|l| l.starts_with("GET ")).collect();
    assert!(gets.len() > 10, "{log:?}");
    for l in gets {
        assert!(l.contains(" 206 ") && l.contains("\"bytes="), "{l}");
    }
}

#[test]
fn a_scene_replaced_on_the_server_is_not_read_against_the_old_skeleton() {
    let Some((dir, local, nginx, url)) = served_plant("remote::replaced") else {
        return;
    };
    let src = RemoteSource::open(&url, &fast_options()).unwrap();
    let skel = Arc::new(SceneFile::open(&local).unwrap().skeleton().clone());
    let data: u64 = skel.reps.iter().map(|r| r.expanded_extent()).sum();
    let budget = data / 10;
    let params = params(Mode::Pre, budget);
    let poses = flythrough(&skel, 120);
    let mut w = Walkthrough::start(skel.clone(), Arc::new(src.clone()), params).unwrap();
    let mut none = NoneRenderer::new(0.0);
    let mut frames = run_path(&mut w, &poses[..30], &mut none, 0.0).unwrap();
    assert_eq!(errors(&frames), 0);
    // A rebuild renamed over the served file mid-walk (another plant:
    // another length, hence another ETag even within the same second).
    let other = plant(dir.path(), "other.hlod", 9);
    std::fs::rename(&other, &local).unwrap();
    frames.extend(run_path(&mut w, &poses[30..], &mut none, 0.0).unwrap());
    drop(w);
    // The walk went on with what was resident, within the budget; the
    // reads it still wanted failed and were reported.
    for f in &frames {
        assert!(f.loader.max_resident_bytes <= budget, "frame {}", f.frame);
        assert_eq!(
            f.drawn_reps + f.substituted,
            f.front_reps,
            "frame {}",
            f.frame
        );
    }
    assert!(errors(&frames) > 0 && src.changed());
    let mut b = [0u8; 64];
    let e = src.read_at(100, &mut b).unwrap_err().to_string();
    assert!(
        e.contains(&url) && e.contains("changed on the server"),
        "{e}"
    );
    // From now on no request is made for the old version.
    let logged = nginx.access_log().len();
    assert!(src.read_at(0, &mut b).is_err());
    assert_eq!(nginx.access_log().len(), logged);
    // Opened again, it is the new scene.
    let again = RemoteSource::open(&url, &fast_options()).unwrap();
    assert_eq!(again.len(), std::fs::metadata(&local).unwrap().len());
}

#[test]
fn network_faults_are_retried_or_reported_never_hung() {
    let Some((_dir, local, nginx, _)) = served_plant("remote::faults") else {
        return;
    };
    let bytes = std::fs::read(&local).unwrap();
    let proxy = FaultProxy::start(nginx.port, Duration::ZERO);
    let url = format!("{}/plant.hlod", proxy.base);
    let open = || RemoteSource::open(&url, &fast_options()).unwrap();
    let src = open();
    let (at, n) = (bytes.len() / 3, 4000);
    let read = |s: &RemoteSource| {
        let mut b = vec![0u8; n];
        let t = Instant::now();
        let r = s.read_at(at as u64, &mut b).map(|()| b);
        let took = t.elapsed();
        assert!(
            took < Duration::from_secs(8),
            "{took:?}: bounded by the time-outs"
        );
        r
    };
    let want = bytes[at..at + n].to_vec();
    // Transient: retried with backoff, and the bytes are right.
    for faults in [
        vec![Fault::Status(503), Fault::Status(502)],
        vec![Fault::Reset],
        vec![Fault::ShortBody],
        vec![Fault::Stall(Duration::from_secs(2))],
    ] {
        proxy.push(&faults);
        assert_eq!(read(&src).unwrap(), want, "{faults:?}");
    }
    // Lasting: one clear error naming the URL and the byte range.
    for (faults, says) in [
        (vec![Fault::Status(503); 8], "503"),
        (vec![Fault::ShortBody; 8], "bytes"),
        (vec![Fault::Status(416)], "416"),
        (vec![Fault::IgnoreRange], "bytes"),
    ] {
        proxy.push(&faults);
        let e = read(&src).unwrap_err().to_string();
        proxy.clear();
        assert!(e.contains(&url) && e.contains(says), "{faults:?}: {e}");
        assert!(!src.changed(), "{faults:?}");
        assert_eq!(read(&src).unwrap(), want, "{faults:?}: the next read works");
    }
    // Gone from the server: the scene is no longer read.
    proxy.push(&[Fault::Status(404)]);
    let e = read(&src).unwrap_err().to_string();
    assert!(e.contains("changed on the server") && src.changed(), "{e}");
    // Down at start: a clear error.
    proxy.push(&[Fault::Status(503); 8]);
    let e = RemoteSource::open(&url, &fast_options())
        .unwrap_err()
        .to_string();
    assert!(e.contains(&url) && e.contains("length and version"), "{e}");
    proxy.clear();

    // A walk through a flaky server: every read that failed is reported,
    // its rep drawn as an ancestor, the budget held on every frame.
    let src = open();
    let skel = Arc::new(SceneFile::open(&local).unwrap().skeleton().clone());
    let data: u64 = skel.reps.iter().map(|r| r.expanded_extent()).sum();
    let mut faults = Vec::new();
    for i in 0..60 {
        faults.push(Fault::Pass);
        faults.extend(match i % 4 {
            0 => vec![Fault::Status(500); 5],
            1 => vec![Fault::Reset],
            2 => vec![Fault::ShortBody; 5],
            _ => vec![Fault::Status(503)],
        });
    }
    proxy.push(&faults);
    let frames = walk(
        &skel,
        Arc::new(src.clone()),
        Mode::Pre,
        data / 20,
        &flythrough(&skel, 120),
    );
    assert!(errors(&frames) > 0, "some reads failed for good");
    assert!(src.stats().requests > 0, "and others were served");
}

/// The `.blk` files under `dir` and their total size.
fn cached_blocks(dir: &Path) -> (Vec<PathBuf>, u64) {
    let mut files = Vec::new();
    let mut total = 0;
    for scene in std::fs::read_dir(dir).unwrap().flatten() {
        for f in std::fs::read_dir(scene.path()).unwrap().flatten() {
            if f.path().extension().is_some_and(|e| e == "blk") {
                total += f.metadata().unwrap().len();
                files.push(f.path());
            }
        }
    }
    files.sort();
    (files, total)
}

#[test]
fn a_second_walk_reads_from_the_disk_cache_and_nothing_from_the_network() {
    use engine_cli::scene_handle::DiskCacheSpec;
    let dir = tempfile::tempdir().unwrap();
    let served = dir.path().join("served");
    std::fs::create_dir(&served).unwrap();
    let local = plant(&served, "plant.hlod", 5);
    let Some(nginx) = Nginx::start("remote::disk_cache", &served) else {
        return;
    };
    let url = format!("{}/plant.hlod", nginx.base);
    let spec = DiskCacheSpec {
        dir: dir.path().join("cache"),
        max_bytes: 1 << 30,
    };
    let skel = Arc::new(SceneFile::open(&local).unwrap().skeleton().clone());
    let data: u64 = skel.reps.iter().map(|r| r.expanded_extent()).sum();
    let poses = flythrough(&skel, 120);
    let gets = || {
        nginx
            .access_log()
            .iter()
            .filter(|l| l.starts_with("GET "))
            .count()
    };
    let visit = || {
        let h = SceneHandle::open_cached(Path::new(&url), Some(&spec)).unwrap();
        // Without prefetching what a walk reads depends on the path alone
        // (prefetching also on timing: another run may look further ahead).
        let frames = walk(
            &skel,
            h.source(None).unwrap(),
            Mode::NoPre,
            data / 20,
            &poses,
        );
        assert_eq!(errors(&frames), 0);
        (
            h.network(),
            frames.iter().map(|f| f.front_reps).collect::<Vec<_>>(),
        )
    };
    // The root's rep: every walk reads it at start.
    let root = skel.reps[skel.nodes[0].first_rep as usize];
    let ready = || {
        let h = SceneHandle::open_cached(Path::new(&url), Some(&spec)).unwrap();
        h.source(None)
            .unwrap()
            .is_ready(root.offset, u64::from(root.len))
    };
    assert!(!ready(), "nothing cached yet: a read would be a request");
    let (first, fronts) = visit();
    assert!(first.requests > 0, "{first:?}");
    assert!(
        ready(),
        "cached: a read costs a copy, whatever a request costs"
    );
    let asked = gets();
    let (second, again) = visit();
    assert_eq!(second.requests, 0, "{second:?}");
    assert!(second.cache_hit_bytes > 0);
    assert_eq!(gets(), asked, "no GET on the second visit (only its HEAD)");
    assert_eq!(fronts, again);

    // Reads within one block open and check its file once: the block the
    // last read checked is kept for the next (here its file is gone by then).
    let block = root.offset / engine_cli::disk_cache::BLOCK;
    assert_eq!(
        (root.offset + 31) / engine_cli::disk_cache::BLOCK,
        block,
        "a root rep within one block"
    );
    let h = SceneHandle::open_cached(Path::new(&url), Some(&spec)).unwrap();
    let src = h.source(None).unwrap();
    let mut bytes = [0u8; 32];
    src.read_at(root.offset, &mut bytes[..16]).unwrap();
    let (files, _) = cached_blocks(&spec.dir);
    let file = files
        .iter()
        .find(|p| {
            p.file_stem()
                .is_some_and(|s| s == block.to_string().as_str())
        })
        .unwrap();
    std::fs::remove_file(file).unwrap();
    src.read_at(root.offset + 16, &mut bytes[16..]).unwrap();
    assert_eq!(h.network().requests, 0, "served from the block kept");
    let mut want = [0u8; 32];
    FileSource::open(&local)
        .unwrap()
        .read_at(root.offset, &mut want)
        .unwrap();
    assert_eq!(bytes, want);

    // A damaged block is caught by its checksum and fetched again.
    let (files, _) = cached_blocks(&spec.dir);
    let mut b = std::fs::read(&files[0]).unwrap();
    b[10] ^= 0x40;
    std::fs::write(&files[0], &b).unwrap();
    let (third, _) = visit();
    assert!(third.requests >= 1, "{third:?}");

    // A new version on the server: its own entry, never the old bytes.
    let other = plant(dir.path(), "other.hlod", 9);
    std::fs::rename(&other, &local).unwrap();
    let h = SceneHandle::open_cached(Path::new(&url), Some(&spec)).unwrap();
    let new = SceneFile::from_source(h.raw().unwrap()).unwrap();
    let file = SceneFile::open(&local).unwrap();
    assert_eq!(new.skeleton(), file.skeleton());
    for r in 0..file.skeleton().reps.len() as u32 {
        assert_eq!(
            new.read_rep_bytes(r).unwrap(),
            file.read_rep_bytes(r).unwrap()
        );
    }
    assert!(h.network().requests > 0);
    let entries = std::fs::read_dir(&spec.dir).unwrap().count();
    assert_eq!(entries, 2, "one entry per version");

    // Bounded: a small cache keeps within its size.
    let small = DiskCacheSpec {
        dir: dir.path().join("small"),
        max_bytes: 300 << 10,
    };
    let h = SceneHandle::open_cached(Path::new(&url), Some(&small)).unwrap();
    let skel = Arc::new(file.skeleton().clone());
    walk(
        &skel,
        h.source(None).unwrap(),
        Mode::Pre,
        data / 20,
        &flythrough(&skel, 60),
    );
    let (files, total) = cached_blocks(&small.dir);
    assert!(!files.is_empty() && total <= small.max_bytes, "{total}");
}

#[test]
fn reps_that_failed_while_the_server_was_down_are_read_once_it_is_back() {
    let Some((_dir, local, nginx, _)) = served_plant("remote::server_back") else {
        return;
    };
    let proxy = FaultProxy::start(nginx.port, Duration::ZERO);
    let url = format!("{}/plant.hlod", proxy.base);
    let skel = Arc::new(SceneFile::open(&local).unwrap().skeleton().clone());
    let data: u64 = skel.reps.iter().map(|r| r.expanded_extent()).sum();
    let poses = flythrough(&skel, 240);
    // Without prefetching the walk is the same at any pace: a clean walk
    // from the file is the reference.
    let clean = walk(
        &skel,
        Arc::new(FileSource::open(&local).unwrap()),
        Mode::NoPre,
        data / 20,
        &poses,
    );
    let src = RemoteSource::open(&url, &fast_options()).unwrap();
    let params = params(Mode::NoPre, data / 20);
    let mut w = Walkthrough::start(skel.clone(), Arc::new(src), params).unwrap();
    // Down for 40 requests (ten reads, each tried four times), then back.
    proxy.push(&[Fault::Status(503); 40]);
    // In real time (30 fps, 8 s): the failed reps are tried again after
    // their backoff (at most 4 s).
    let frames = run_path(&mut w, &poses, &mut NoneRenderer::new(0.0), 30.0).unwrap();
    assert!(
        errors(&frames) > 0,
        "reads failed while the server was down"
    );
    for f in &frames {
        assert!(
            f.loader.max_resident_bytes <= data / 20,
            "frame {}",
            f.frame
        );
    }
    assert_eq!(errors(&frames[180..]), 0);
    let subst = |f: &[FrameMetrics]| f.iter().map(|m| m.substituted).collect::<Vec<_>>();
    assert_eq!(
        subst(&frames[180..]),
        subst(&clean[180..]),
        "every rep lost to the outage is drawn again"
    );
}

#[test]
fn requests_in_flight_serve_the_walk_as_one_at_a_time_does_within_the_budget() {
    let Some((_dir, local, nginx, _url)) = served_plant("remote::requests_in_flight") else {
        return;
    };
    // 20 ms a request, as a server some way off.
    let proxy = FaultProxy::start(nginx.port, Duration::from_millis(20));
    let url = format!("{}/plant.hlod", proxy.base);
    let file = SceneFile::open(&local).unwrap();
    let skel = Arc::new(file.skeleton().clone());
    let data: u64 = skel.reps.iter().map(|r| r.expanded_extent()).sum();
    let poses = flythrough(&skel, 90);
    let budget = data / 8;
    for mode in [Mode::NoPre, Mode::Pre] {
        let from_file: Arc<dyn ByteSource> = Arc::new(FileSource::open(&local).unwrap());
        let on_disk = walk(&skel, from_file, mode, budget, &poses);
        for max_requests in [1, 16] {
            let opts = RemoteOptions {
                max_requests,
                ..RemoteOptions::default()
            };
            let src = RemoteSource::open(&url, &opts).unwrap();
            let p = RuntimeParams {
                page_bytes: engine::runtime::REMOTE_PAGE_BYTES,
                ..params(mode, budget)
            };
            let mut w = Walkthrough::start(skel.clone(), Arc::new(src.clone()), p).unwrap();
            let ahead = w.footprint().in_flight();
            let frames = run_path(&mut w, &poses, &mut NoneRenderer::new(0.0), 0.0).unwrap();
            drop(w);
            let fronts = |f: &[FrameMetrics]| f.iter().map(|m| m.front_reps).collect::<Vec<_>>();
            assert_eq!(fronts(&frames), fronts(&on_disk), "{mode:?} {max_requests}");
            assert_eq!(errors(&frames), 0, "{mode:?} {max_requests}");
            for f in &frames {
                // The reps and pages held, beside what the requests ahead
                // may hold: within the budget on every frame.
                assert!(
                    f.loader.max_resident_bytes + ahead <= budget,
                    "frame {}",
                    f.frame
                );
                assert_eq!(f.drawn_reps + f.substituted, f.front_reps);
            }
            let st = src.stats();
            if max_requests == 1 {
                assert_eq!(
                    (ahead, st.ahead.started),
                    (0, 0),
                    "one at a time: nothing ahead"
                );
            } else {
                assert!(ahead > 0 && ahead <= budget / 8, "{ahead} of {budget}");
                assert!(st.ahead.peak_in_flight > 1, "{st:?}");
                assert!(
                    st.ahead.hits > 0,
                    "reads served from requests started ahead: {st:?}"
                );
            }
        }
    }
}

#[test]
fn a_proxy_link_of_a_given_rate_is_shared_by_the_answers_and_timed_by_the_source() {
    let Some((_dir, _local, nginx, _url)) = served_plant("remote::link_rate") else {
        return;
    };
    // 10 ms a request, 8 Mbit/s (1 MB/s) shared by all connections.
    let proxy = FaultProxy::start_link(0, nginx.port, Duration::from_millis(10), Some(1e6));
    let src = RemoteSource::open(
        &format!("{}/plant.hlod", proxy.base),
        &RemoteOptions::default(),
    )
    .unwrap();
    assert!(src.times_requests());
    let n = (src.len() / 4).min(300_000) as usize;
    let t = Instant::now();
    std::thread::scope(|s| {
        for k in 0..2u64 {
            let src = &src;
            s.spawn(move || {
                let mut buf = vec![0u8; n];
                src.read_at(k * n as u64, &mut buf).unwrap();
            });
        }
    });
    // Two answers through one link: their bytes' time at the rate, at
    // least (the round trips overlap).
    let least = 2.0 * n as f64 / 1e6;
    let took = t.elapsed().as_secs_f64();
    assert!(took >= least * 0.95, "{took} s for {} bytes", 2 * n);
    let (mut answers, mut seen) = (Vec::new(), 0);
    src.responses_since(&mut seen, &mut answers);
    assert_eq!(answers.len(), 2, "{answers:?}");
    for a in &answers {
        assert_eq!(a.bytes, n as u64);
        assert!(
            a.took.as_secs_f64() >= 0.010 + n as f64 / 1e6 * 0.95,
            "{a:?}"
        );
    }
    let mut again = Vec::new();
    src.responses_since(&mut seen, &mut again);
    assert!(again.is_empty(), "seen once");
    // A second reader starts from the answers kept.
    src.responses_since(&mut 0, &mut again);
    assert_eq!(again.len(), 2);
}
