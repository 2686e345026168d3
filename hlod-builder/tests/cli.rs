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
    let rep0 = engine::SceneFile::open(&d.join("d.hlod"))
        .unwrap()
        .skeleton()
        .reps[0];
    bytes[(rep0.offset + u64::from(rep0.len) / 2) as usize] ^= 0x40;
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
    let out = hlod_build(&["gen", "lattice", "--units", "0", "-o", "l.glb"], d);
    assert_clean_failure(&out, "--units", d, 2);
    let out = hlod_build(&["gen", "lattice", "--units", "1", "-o", "l.glb"], d);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 3);
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

fn is_temp(name: &str) -> bool {
    name.ends_with(engine_cli::outfile::TEMP_SUFFIX)
}

fn names(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn outputs_never_replace_an_input_a_fifo_or_a_link() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(data("dragon_res4.glb"), d.join("in.glb")).unwrap();
    let original = std::fs::read(d.join("in.glb")).unwrap();
    let out = hlod_build(&["build", "in.glb", "-o", "in.glb", "-q"], d);
    assert_clean_failure(&out, "refusing to overwrite", d, 1);
    std::fs::hard_link(d.join("in.glb"), d.join("same.glb")).unwrap();
    let out = hlod_build(&["build", "in.glb", "-o", "same.glb", "-q"], d);
    assert_clean_failure(&out, "refusing to overwrite", d, 2);
    let out = hlod_build(
        &["gen", "tile", "in.glb", "--grid", "2x2", "-o", "in.glb"],
        d,
    );
    assert_clean_failure(&out, "refusing to overwrite", d, 2);
    assert_eq!(std::fs::read(d.join("in.glb")).unwrap(), original);
    std::fs::remove_file(d.join("same.glb")).unwrap();

    // A FIFO (as a device would be) is refused and stays what it was.
    let fifo = d.join("fifo");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let out = hlod_build(&["build", "in.glb", "-o", "fifo", "-q"], d);
    assert_clean_failure(&out, "a FIFO, not a regular file", d, 2);
    let out = hlod_build(
        &[
            "gen",
            "plant",
            "--objects",
            "10",
            "--triangles",
            "5000",
            "-o",
            "fifo",
        ],
        d,
    );
    assert_clean_failure(&out, "a FIFO, not a regular file", d, 2);
    use std::os::unix::fs::FileTypeExt;
    assert!(
        std::fs::symlink_metadata(&fifo)
            .unwrap()
            .file_type()
            .is_fifo()
    );
    std::fs::remove_file(&fifo).unwrap();

    // A symbolic link is never written through: refused, its target kept.
    std::fs::write(d.join("old.hlod"), b"old").unwrap();
    std::os::unix::fs::symlink("old.hlod", d.join("link.hlod")).unwrap();
    let out = hlod_build(&["build", "in.glb", "-o", "link.hlod", "-q"], d);
    assert_clean_failure(&out, "refusing to write through it", d, 3);
    let meta = std::fs::symlink_metadata(d.join("link.hlod")).unwrap();
    assert!(meta.file_type().is_symlink());
    assert_eq!(std::fs::read(d.join("old.hlod")).unwrap(), b"old");
}

#[test]
fn endless_inputs_and_a_full_disk_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = hlod_build(&["build", "/dev/zero", "-o", "z.hlod"], d);
    assert_clean_failure(&out, "not a regular file", d, 0);
    // The output's file system fills up mid-build (a file size limit makes
    // every write past 64 KiB fail, as a full disk would).
    let cmd = format!(
        "trap '' XFSZ; ulimit -f 128; exec '{}' build '{}' -o b.hlod -q",
        env!("CARGO_BIN_EXE_hlod-build"),
        data("bunny.glb")
    );
    let out = Command::new("sh")
        .args(["-c", &cmd])
        .current_dir(d)
        .output()
        .unwrap();
    assert_clean_failure(&out, "b.hlod", d, 0);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("File too large"), "{err}");
    assert_eq!(err.matches("File too large").count(), 1, "said once: {err}");
}

/// Starts a build of the bunny and waits for its temporary output.
fn interrupted_build(d: &Path, signal: &str) -> std::process::ExitStatus {
    let mut child = Command::new(env!("CARGO_BIN_EXE_hlod-build"))
        .args([
            "build",
            &data("bunny.glb"),
            "-o",
            "b.hlod",
            "-q",
            "--vdt-tris",
            "2000",
        ])
        .current_dir(d)
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let t = std::time::Instant::now();
    while !names(d).iter().any(|n| is_temp(n)) {
        assert!(t.elapsed().as_secs() < 60, "no temporary output appeared");
        assert!(child.try_wait().unwrap().is_none(), "the build ended first");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let pid = child.id().to_string();
    assert!(
        Command::new("kill")
            .args([signal, &pid])
            .status()
            .unwrap()
            .success()
    );
    child.wait().unwrap()
}

#[test]
fn an_interrupted_build_leaves_nothing_behind() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // SIGTERM (and SIGINT, SIGHUP): the temporary file goes with the process.
    let st = interrupted_build(d, "-TERM");
    assert_eq!(st.signal(), Some(15), "ends as the signal would: {st:?}");
    assert!(names(d).is_empty(), "left behind: {:?}", names(d));
    // SIGKILL cannot be caught: what it leaves, the next build removes.
    let st = interrupted_build(d, "-KILL");
    assert_eq!(st.signal(), Some(9));
    assert_eq!(names(d).len(), 1);
    let out = hlod_build(
        &["build", &data("dragon_res4.glb"), "-o", "d.hlod", "-q"],
        d,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("left by an interrupted run"), "said: {err}");
    assert_eq!(names(d), ["d.hlod"]);
}

#[test]
fn real_exports_build_or_fail_cleanly_and_warnings_print_either_way() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Draco builds; a damaged Draco stream is exit 2, one line naming the
    // file and the primitive, and nothing left.
    let draco = data("real/AC14-FZK-Haus.gt-draco.glb");
    let out = hlod_build(&["build", &draco, "-o", "x.hlod", "-q"], d);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::remove_file(d.join("x.hlod")).unwrap();
    let mut bytes = std::fs::read(&draco).unwrap();
    let at = bytes.windows(5).position(|w| w == b"DRACO").unwrap();
    bytes[at..at + 5].copy_from_slice(b"DRACA");
    let src = tempfile::tempdir().unwrap();
    let bad = src.path().join("bad-draco.glb");
    std::fs::write(&bad, &bytes).unwrap();
    let out = hlod_build(&["build", bad.to_str().unwrap(), "-o", "x.hlod"], d);
    assert_clean_failure(&out, "bad-draco.glb: meshes[", d, 0);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("KHR_draco_mesh_compression") && err.contains("Draco stream"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    // gltfpack's meshopt-compressed output builds, and `info` prints the origin.
    let out = hlod_build(
        &[
            "build",
            &data("real/AC14-FZK-Haus.gltfpack-cc.glb"),
            "-o",
            "h.hlod",
            "-q",
        ],
        d,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let info = hlod_build(&["info", "h.hlod"], d);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        text.contains("format v6")
            && text.contains("walk section: ")
            && text.contains("B per input triangle")
            && text.contains("mesh payloads compressed")
            && text.contains("origin 0 0 0")
            && text.contains("91 objects described")
            // gltfpack's quantization collapses 3,711 of the source's
            // triangles; `info` says so beside the input count.
            && text.contains(
                "input: 37146 triangles after instancing: 33435 drawn by the finest reps, 3711 \
                 degenerate dropped, 0 of hidden objects"
            ),
        "{text}"
    );
    // A build that fails still prints the import's warnings first.
    std::fs::write(
        d.join("lines.gltf"),
        r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":0},"mode":1}]}],
        "nodes":[{"mesh":0}],"accessors":[{"componentType":5126,"count":2,"type":"VEC3"}]}"#,
    )
    .unwrap();
    let out = hlod_build(&["build", "lines.gltf", "-o", "l.hlod"], d);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("LINES") && err.contains("no renderable triangles"),
        "{err}"
    );
}

#[test]
fn mt_report_rock_generator_and_their_failures() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = hlod_build(&["gen", "rock", "--tris", "20000", "-o", "rock.glb"], d);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_clean_failure(
        &hlod_build(&["gen", "rock", "--tris", "3", "-o", "r.glb"], d),
        "--tris",
        d,
        1,
    );
    let out = hlod_build(&["mt", "rock.glb", "--theta", "20", "-o", "rock.mt"], d);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("\n| 0 | ") && text.contains("wrote rock.mt"),
        "{text}"
    );
    let src = std::sync::Arc::new(engine::io::FileSource::open(&d.join("rock.mt")).unwrap());
    let f = engine::mt::file::MtFile::open(src).unwrap();
    assert!(f.header.node_count > 50 && f.parts.iter().all(|p| p.count <= 20));
    for (args, needle) in [
        (vec!["mt", "rock.glb", "--theta", "0"], "--theta"),
        (vec!["mt", "rock.glb", "--theta", "5000"], "--theta"),
        (
            vec!["mt", "rock.glb", "--cluster-tris", "4"],
            "--cluster-tris",
        ),
        (
            vec!["mt", "rock.glb", "--group-clusters", "1"],
            "--group-clusters",
        ),
        (vec!["mt", "missing.glb"], "missing.glb"),
        (vec!["mt", "rock.glb", "-o", "rock.glb"], "rock.glb"),
        (
            vec!["build", "rock.glb", "-o", "r.hlod", "--mt-tris", "10"],
            "--mt-tris",
        ),
        (
            vec![
                "build",
                "rock.glb",
                "-o",
                "r.hlod",
                "--mt-tris",
                "5000",
                "--mt-theta",
                "0",
            ],
            "--mt-theta",
        ),
    ] {
        assert_clean_failure(&hlod_build(&args, d), needle, d, 2);
    }
    let out = hlod_build(
        &[
            "build",
            "rock.glb",
            "-o",
            "r.hlod",
            "--mt-tris",
            "5000",
            "-q",
        ],
        d,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let info = hlod_build(&["info", "r.hlod"], d);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        info.status.success() && text.contains("1 Multi-Triangulations") && text.contains("MT rep"),
        "{text}"
    );
}

/// IFC without IfcOpenShell: one line naming the file, saying how to install
/// it; a Python that lacks it (a real one, run without its site packages)
/// and one that is not there at all. A file that is not IFC is said so.
#[test]
fn ifc_without_ifcopenshell_says_how_to_install_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fake = d.join("bare-python");
    std::fs::write(&fake, "#!/bin/sh\nexec python3 -I -S \"$@\"\n").unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    let ifc = data("ifc/AC14-FZK-Haus.ifc");
    for (python, said) in [
        (fake.to_str().unwrap(), "has no IfcOpenShell"),
        ("/nonexistent/python3", "/nonexistent/python3 not found"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_hlod-build"))
            .args(["build", &ifc, "-o", "x.hlod"])
            .env("HLOD_PYTHON", python)
            .current_dir(d)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(
            err.contains("AC14-FZK-Haus.ifc") && err.contains(said) && err.contains("pip install"),
            "{err}"
        );
        assert_eq!(err.lines().count(), 1, "{err}");
    }
    std::fs::write(d.join("notes.ifc"), "not STEP at all\n").unwrap();
    let out = hlod_build(&["build", "notes.ifc", "-o", "x.hlod"], d);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("notes.ifc: IFC: not an IFC file IfcOpenShell can read"),
        "{err}"
    );
    assert!(!d.join("x.hlod").exists());
}

#[test]
fn export_3dtiles_writes_a_tileset_and_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let haus = data("AC14-FZK-Haus.glb");
    let out = hlod_build(&["build", &haus, "-o", "h.hlod", "-q"], d);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = hlod_build(&["export-3dtiles", "h.hlod", "-o", "tiles"], d);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(said.contains("name their elements"), "{said}");
    assert!(d.join("tiles/tileset.json").is_file());
    // A missing scene is named; nothing is written.
    let n = std::fs::read_dir(d).unwrap().count();
    let out = hlod_build(&["export-3dtiles", "nope.hlod", "-o", "t2"], d);
    assert_clean_failure(&out, "nope.hlod", d, n);
    // A folder that is not an export is refused and left as it was.
    std::fs::create_dir(d.join("mine")).unwrap();
    std::fs::write(d.join("mine/notes.txt"), b"mine").unwrap();
    let n = std::fs::read_dir(d).unwrap().count();
    let out = hlod_build(&["export-3dtiles", "h.hlod", "-o", "mine"], d);
    assert_clean_failure(&out, "not an earlier export", d, n);
    assert_eq!(std::fs::read(d.join("mine/notes.txt")).unwrap(), b"mine");
    // A nonsense parameter.
    let out = hlod_build(
        &[
            "export-3dtiles",
            "h.hlod",
            "-o",
            "t3",
            "--max-tiles-per-json",
            "1",
        ],
        d,
    );
    assert_clean_failure(&out, "at least 16", d, n);
    let out = hlod_build(
        &["export-3dtiles", "h.hlod", "-o", "t3", "--bundle", "10"],
        d,
    );
    assert_clean_failure(&out, "at least 1K", d, n);
    // Bundled: fewer files, said so.
    let out = hlod_build(
        &["export-3dtiles", "h.hlod", "-o", "t4", "--bundle", "64K"],
        d,
    );
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(said.contains("bundles merge"), "{said}");
    assert!(d.join("t4/tileset.json").is_file());
}
