//! What the viewer's Xvfb tests share: running `hlod-view` under
//! `xvfb-run`, the artefacts folder, the test scenes and image measures.
#![allow(dead_code)] // each test binary uses its own part

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use engine::image::RgbaImage;

pub fn artefacts() -> PathBuf {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/test-output");
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Whether the viewer can run here (`xvfb-run` and a GPU adapter, lavapipe
/// counts). When not, the test is reported as skipped in
/// `target/test-skips.txt` and returns; with `HLOD_REQUIRE_GPU` set (as
/// `scripts/test.sh` sets it after installing them) it fails instead.
pub fn can_run(test: &str) -> bool {
    let xvfb = Command::new("sh")
        .args(["-c", "command -v xvfb-run"])
        .output()
        .is_ok_and(|o| o.status.success());
    let why = if !xvfb {
        Some("xvfb-run is missing (scripts/setup.sh installs xvfb)".to_string())
    } else {
        engine_gpu::GpuContext::new().err().map(|e| e.to_string())
    };
    let Some(why) = why else { return true };
    assert!(
        std::env::var_os("HLOD_REQUIRE_GPU").is_none(),
        "{test}: {why}, although HLOD_REQUIRE_GPU is set"
    );
    e2e_tests::record_skip(test, &why);
    false
}

/// Runs the viewer under `xvfb-run`, killed after two minutes.
pub fn view(dir: &Path, args: &[&str]) -> Output {
    // Each run starts its search for a free display at its own number:
    // `xvfb-run -a` alone lets two runs started at once take the same one.
    static RUNS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let k = RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let first = 100 + (std::process::id() % 400) * 20 + k;
    let mut child = Command::new("xvfb-run")
        .args([
            "-a",
            "-n",
            &first.to_string(),
            "-s",
            "-screen 0 1280x800x24",
        ])
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

pub fn scene(dir: &Path) -> PathBuf {
    let glb = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/data/2CylinderEngine/2CylinderEngine.gltf");
    let out = dir.join("engine.hlod");
    hlod_builder::build::build_file(&glb, &out, &Default::default(), false).unwrap();
    out
}

/// Share of pixels in the right part (beside the overlay) that are not background.
pub fn scene_coverage(img: &RgbaImage) -> f64 {
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

pub fn fzk_haus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/AC14-FZK-Haus.glb")
}
