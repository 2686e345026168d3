//! The `hlod-build` binary: exit codes, messages and no partial output.

use std::path::Path;
use std::process::{Command, Output};

fn hlod_build(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hlod-build"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("runs")
}

fn data(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/data")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

/// Fails with exit code 2 (not 0, not a panic's 101), says `needle` on
/// stderr, and leaves the directory as it was.
fn assert_clean_failure(out: &Output, needle: &str, dir: &Path, files_before: usize) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {err}");
    assert!(err.contains(needle), "stderr lacks {needle:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(
        std::fs::read_dir(dir).unwrap().count(),
        files_before,
        "partial output left"
    );
}

#[test]
fn build_info_and_failures() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = hlod_build(
        &["build", &data("dragon_res4.glb"), "-o", "d.hlod", "-q"],
        d,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(table.contains("| dragon_res4.glb |"), "{table}");

    let out = hlod_build(&["info", "d.hlod"], d);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains("validate(): ok") && text.contains("checksums"),
        "{text}"
    );

    // A bit flip in the rep data is found by `info`, a truncation at open.
    let mut bytes = std::fs::read(d.join("d.hlod")).unwrap();
    bytes[4096 + 200] ^= 0x40;
    std::fs::write(d.join("flip.hlod"), &bytes).unwrap();
    let out = hlod_build(&["info", "flip.hlod"], d);
    assert_clean_failure(&out, "checksum mismatch", d, 2);
    std::fs::write(d.join("cut.hlod"), &bytes[..bytes.len() - 10]).unwrap();
    let out = hlod_build(&["info", "cut.hlod"], d);
    assert_clean_failure(&out, "truncated", d, 3);

    let out = hlod_build(&["build", "missing.glb", "-o", "m.hlod"], d);
    assert_clean_failure(&out, "missing.glb", d, 3);
    let out = hlod_build(
        &[
            "build",
            &data("bunny.glb"),
            "-o",
            "b.hlod",
            "--branching",
            "1",
        ],
        d,
    );
    assert_clean_failure(&out, "--branching", d, 3);
    let out = hlod_build(&["build", "cut.hlod", "-o", "x.hlod"], d);
    assert_clean_failure(&out, "cut.hlod", d, 3);
    let out = hlod_build(
        &["build", &data("bunny.glb"), "-o", "no/such/dir/x.hlod"],
        d,
    );
    assert_clean_failure(&out, "x.hlod", d, 3);
}

#[test]
fn generators_validate_their_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = hlod_build(&["gen", "plant", "--objects", "0", "-o", "p.glb"], d);
    assert_clean_failure(&out, "--objects", d, 0);
    let out = hlod_build(
        &[
            "gen",
            "plant",
            "--objects",
            "10",
            "--triangles",
            "5",
            "-o",
            "p.glb",
        ],
        d,
    );
    assert_clean_failure(&out, "--triangles", d, 0);
    let out = hlod_build(
        &[
            "gen",
            "tile",
            &data("dragon_res4.glb"),
            "--grid",
            "0x3",
            "-o",
            "t.glb",
        ],
        d,
    );
    assert_clean_failure(&out, "--grid", d, 0);
    let out = hlod_build(
        &[
            "gen",
            "tile",
            &data("dragon_res4.glb"),
            "--grid",
            "2x2",
            "--baked",
            "-o",
            "t.glb",
        ],
        d,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = hlod_build(
        &[
            "gen",
            "plant",
            "--objects",
            "40",
            "--triangles",
            "20000",
            "-o",
            "p.glb",
        ],
        d,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 2);
}

#[test]
fn vdt_report_and_its_failures() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let engine = data("2CylinderEngine/2CylinderEngine.gltf");
    let out = hlod_build(&["vdt", &engine], d);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("L = 5 levels for 4096-byte blocks"), "{text}");
    assert!(
        text.lines().filter(|l| l.starts_with("| ")).count() > 10,
        "{text}"
    );
    // -o writes the largest mesh's tree; it opens and loads back valid.
    let out = hlod_build(&["vdt", &engine, "-o", "engine.vdt"], d);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let src = std::sync::Arc::new(engine::io::FileSource::open(&d.join("engine.vdt")).unwrap());
    let f = engine::vdt::file::VdtFile::open(src).unwrap();
    f.load_tree().unwrap();
    assert!(f.header.meta_count > 0);
    assert_eq!(
        std::fs::read_dir(d).unwrap().count(),
        1,
        "no temporary left"
    );
    assert_clean_failure(&hlod_build(&["vdt", "missing.glb"], d), "missing.glb", d, 1);
    assert_clean_failure(
        &hlod_build(&["vdt", &engine, "--metric", "area"], d),
        "--metric",
        d,
        1,
    );
    assert_clean_failure(
        &hlod_build(&["vdt", &engine, "--block", "8"], d),
        "--block",
        d,
        1,
    );
}
