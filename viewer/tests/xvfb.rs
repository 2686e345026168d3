//! `hlod-view` in a real window under Xvfb on lavapipe: it plays a path,
//! exits after N frames and saves a screenshot that must show the scene; a
//! scene that cannot be opened leaves the viewer running with the error shown,
//! and its exit status non-zero.
//! The screenshots are kept in `target/test-output/` (CI artefacts).

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use engine::camera::{PathKind, format_path, generate_path};
use engine::image::RgbaImage;
use glam::Vec3;

fn artefacts() -> PathBuf {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/test-output");
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs the viewer under `xvfb-run`, killed after two minutes.
fn view(dir: &Path, args: &[&str]) -> Output {
    let have = Command::new("sh")
        .args(["-c", "command -v xvfb-run"])
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(
        have,
        "xvfb-run is missing: run scripts/setup.sh (installs xvfb)"
    );
    let mut child = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x800x24"])
        .arg(env!("CARGO_BIN_EXE_hlod-view"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            panic!("hlod-view did not exit");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    child.wait_with_output().unwrap()
}

fn scene(dir: &Path) -> PathBuf {
    let glb = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/data/2CylinderEngine/2CylinderEngine.gltf");
    let out = dir.join("engine.hlod");
    hlod_builder::build::build_file(&glb, &out, &Default::default(), false).unwrap();
    out
}

/// Share of pixels in the right part (beside the overlay) that are not background.
fn scene_coverage(img: &RgbaImage) -> f64 {
    let bg = [23u8, 26, 31];
    let x0 = img.width * 6 / 10;
    let mut n = 0u64;
    let mut hit = 0u64;
    for y in 0..img.height {
        for x in x0..img.width {
            let p = img.pixel(x, y);
            n += 1;
            let d = (0..3).map(|c| p[c].abs_diff(bg[c])).max().unwrap();
            hit += u64::from(d > 12);
        }
    }
    hit as f64 / n as f64
}

#[test]
fn plays_a_path_and_screenshots_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    let sk = engine::SceneFile::open(&s).unwrap();
    let r = &sk.skeleton().nodes[0];
    let poses = generate_path(
        PathKind::Orbit,
        Vec3::from(r.bbox_min),
        Vec3::from(r.bbox_max),
        30,
    );
    std::fs::write(d.join("p.txt"), format_path(&poses)).unwrap();
    let out = view(
        d,
        &[
            "engine.hlod",
            "--path",
            "p.txt",
            "--exit-after",
            "20",
            "--screenshot",
            "shot.png",
            "--csv",
            "m.csv",
            "--record",
            "rec.txt",
            "--budget",
            "60%",
            "--width",
            "800",
            "--height",
            "450",
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let img = RgbaImage::load_png(&d.join("shot.png")).unwrap();
    std::fs::copy(
        d.join("shot.png"),
        artefacts().join("viewer-screenshot.png"),
    )
    .unwrap();
    assert_eq!((img.width, img.height), (800, 450));
    let cov = scene_coverage(&img);
    assert!(
        cov > 0.03,
        "the scene is not visible beside the overlay ({cov})"
    );
    // The overlay is there too: its panel differs from the scene's background.
    assert!(img.coverage() > cov * 0.3);
    let csv = std::fs::read_to_string(d.join("m.csv")).unwrap();
    assert_eq!(csv.lines().count(), 21, "a metrics row per frame");
    assert!(d.join("m-loop.csv").exists());
    let rec = engine::camera::read_path(&d.join("rec.txt")).unwrap();
    assert_eq!(rec.len(), 20);
    assert!((rec[5].position - poses[5].position).length() < 1e-3);
}

#[test]
fn a_scene_that_cannot_open_shows_the_error_keeps_running_and_exits_non_zero() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("bad.hlod"), b"this is not a scene").unwrap();
    let out = view(
        d,
        &[
            "bad.hlod",
            "--exit-after",
            "5",
            "--screenshot",
            "err.png",
            "--width",
            "640",
            "--height",
            "400",
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    // Scripts can tell: the exit status says the scene never opened.
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("error: cannot open bad.hlod"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let img = RgbaImage::load_png(&d.join("err.png")).unwrap();
    std::fs::copy(d.join("err.png"), artefacts().join("viewer-error.png")).unwrap();
    assert!(img.coverage() > 0.01, "the overlay with the error is drawn");
}
