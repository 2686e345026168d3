//! `hlod-view`'s outputs (issue 50): a `--csv`, `--screenshot` or `--record`
//! that names the scene, the model or the path file, a link, or a device is
//! refused before the window opens (no display needed), with exit code 2;
//! a FIFO as the path file is refused at once.

use std::path::Path;
use std::process::{Command, Output};
use std::time::Duration;

/// Runs the viewer without a display, killed after 60 s.
fn view(dir: &Path, args: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_hlod-view"));
    cmd.args(args)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env("HLOD_CACHE_DIR", dir.join("cache"));
    e2e_tests::run_limited(&mut cmd, dir, Duration::from_secs(60))
}

fn refused(out: &Output, needle: &str, what: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{what}: {err}");
    assert!(
        err.contains(needle),
        "{what}: stderr lacks {needle:?}: {err}"
    );
    assert!(!err.contains("panicked"), "{what}: {err}");
}

#[test]
fn no_output_is_an_input_a_link_or_a_device() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/dragon_res4.glb");
    std::fs::copy(&model, d.join("m.glb")).unwrap();
    hlod_builder::build::build_file(
        &d.join("m.glb"),
        &d.join("s.hlod"),
        &Default::default(),
        false,
    )
    .unwrap();
    std::fs::write(d.join("p.txt"), "# hlod camera path v1\n0 0 5 0 0 0 1 60\n").unwrap();
    std::fs::hard_link(d.join("s.hlod"), d.join("hard.hlod")).unwrap();
    std::os::unix::fs::symlink("s.hlod", d.join("soft.csv")).unwrap();
    let kept: Vec<(&str, Vec<u8>)> = ["m.glb", "s.hlod", "p.txt"]
        .into_iter()
        .map(|f| (f, std::fs::read(d.join(f)).unwrap()))
        .collect();
    for flag in ["--csv", "--screenshot", "--record"] {
        for (scene, out, needle) in [
            ("s.hlod", "s.hlod", "refusing to overwrite"),
            ("s.hlod", "hard.hlod", "refusing to overwrite"),
            ("s.hlod", "p.txt", "refusing to overwrite"),
            ("s.hlod", "soft.csv", "refusing to write through it"),
            ("m.glb", "m.glb", "refusing to overwrite"),
            ("s.hlod", "/dev/null", "not a regular file"),
            ("s.hlod", ".", "not a regular file"),
        ] {
            let what = format!("{scene} {flag} {out}");
            let o = view(d, &[scene, "--path", "p.txt", flag, out]);
            refused(&o, needle, &what);
            assert!(
                String::from_utf8_lossy(&o.stderr).contains(flag),
                "{what}: names the option"
            );
        }
    }
    for (f, bytes) in &kept {
        assert_eq!(&std::fs::read(d.join(f)).unwrap(), bytes, "{f} unchanged");
    }
    // A FIFO as the path file: refused without waiting for a writer.
    e2e_tests::mkfifo(&d.join("pipe"));
    refused(
        &view(d, &["s.hlod", "--path", "pipe"]),
        "a FIFO, not a regular file",
        "--path pipe",
    );
}
