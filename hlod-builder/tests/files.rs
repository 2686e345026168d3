//! Every file `hlod-build` reads or writes (issue 50): no output is ever one
//! of the command's inputs (by name, hard link or symbolic link), no reader
//! blocks on a FIFO, a model reads no file outside its folder, and memory
//! follows what a model uses, not the size of the files it names.

use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn hlod_build(args: &[&str], cwd: &Path) -> Output {
    run_limited(
        Command::new(env!("CARGO_BIN_EXE_hlod-build")).args(args),
        cwd,
    )
}

/// Runs `cmd` in `cwd`, killed after 60 s (a reader blocked on a FIFO
/// would hang the test otherwise).
fn run_limited(cmd: &mut Command, cwd: &Path) -> Output {
    e2e_tests::run_limited(cmd, cwd, Duration::from_secs(60))
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn assert_ok(out: &Output) {
    assert!(out.status.success(), "{}", stderr(out));
}

/// A refusal: exit code 2, one message with `needle`, no panic.
fn assert_refused(out: &Output, needle: &str, what: &str) {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(2), "{what}: {err}");
    assert!(
        err.contains(needle),
        "{what}: stderr lacks {needle:?}: {err}"
    );
    assert!(!err.contains("panicked"), "{what}: {err}");
}

/// A small `.gltf` model with an external buffer (`m.bin`) and an image
/// (`tex.png`, named but not read by the importer) in `d`.
fn model(d: &Path) {
    assert_ok(&hlod_build(
        &[
            "gen",
            "plant",
            "--objects",
            "12",
            "--triangles",
            "6000",
            "-o",
            "m.gltf",
        ],
        d,
    ));
    let path = d.join("m.gltf");
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    json["images"] = serde_json::json!([{ "uri": "tex.png" }]);
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    std::fs::write(d.join("tex.png"), b"\x89PNG not really").unwrap();
}

#[test]
fn no_output_of_any_command_is_one_of_its_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    model(d);
    assert_ok(&hlod_build(&["build", "m.gltf", "-o", "s.hlod", "-q"], d));
    for i in 0..2 {
        let spec = format!("{i}/2");
        let out = format!("s{i}.hlsh");
        assert_ok(&hlod_build(
            &["build", "m.gltf", "--shard", &spec, "-o", &out, "-q"],
            d,
        ));
    }
    // An OBJ with its material library.
    std::fs::write(
        d.join("o.obj"),
        "mtllib o.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(d.join("o.mtl"), "newmtl a\nKd 1 0 0\n").unwrap();
    let model_files = ["m.gltf", "m.bin", "tex.png"];
    // Each command, where its output goes (OUT), and every file it reads.
    let table: &[(&[&str], &[&str])] = &[
        (&["build", "m.gltf", "-o", "OUT", "-q"], &model_files),
        (
            &["build", "m.gltf", "--shard", "1/2", "-o", "OUT", "-q"],
            &model_files,
        ),
        (
            &["merge", "m.gltf", "s0.hlsh", "s1.hlsh", "-o", "OUT", "-q"],
            &["m.gltf", "m.bin", "tex.png", "s0.hlsh", "s1.hlsh"],
        ),
        (&["relayout", "s.hlod", "-o", "OUT"], &["s.hlod"]),
        (
            &["gen", "tile", "m.gltf", "--grid", "2x2", "-o", "OUT"],
            &model_files,
        ),
        (&["mt", "m.gltf", "-o", "OUT"], &model_files),
        (&["build", "o.obj", "-o", "OUT", "-q"], &["o.obj", "o.mtl"]),
        (&["vdt", "m.gltf", "-o", "OUT"], &model_files),
    ];
    let before: Vec<(String, Vec<u8>)> = e2e_tests::names(d)
        .into_iter()
        .map(|n| {
            let b = std::fs::read(d.join(&n)).unwrap();
            (n, b)
        })
        .collect();
    let mut tried = 0;
    for (args, inputs) in table {
        for input in *inputs {
            // The input itself, a hard link to it, a symbolic link to it.
            let hard = format!("hard-{input}");
            let soft = format!("soft-{input}");
            std::fs::hard_link(d.join(input), d.join(&hard)).unwrap();
            std::os::unix::fs::symlink(input, d.join(&soft)).unwrap();
            for out in [input.to_string(), hard.clone(), soft.clone()] {
                let args: Vec<&str> = args
                    .iter()
                    .map(|a| if *a == "OUT" { out.as_str() } else { a })
                    .collect();
                let what = format!("{args:?} onto {input}");
                assert_refused(&hlod_build(&args, d), "refusing to", &what);
                tried += 1;
            }
            std::fs::remove_file(d.join(&hard)).unwrap();
            std::fs::remove_file(d.join(&soft)).unwrap();
            // Nothing changed, nothing left behind.
            for (n, b) in &before {
                assert_eq!(&std::fs::read(d.join(n)).unwrap(), b, "{n} after {args:?}");
            }
            assert_eq!(
                e2e_tests::names(d).len(),
                before.len(),
                "{:?}",
                e2e_tests::names(d)
            );
        }
    }
    let pairs: usize = table.iter().map(|(_, inputs)| inputs.len()).sum();
    assert_eq!(tried, 3 * pairs);
}

#[test]
fn every_reader_refuses_a_fifo_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    model(d);
    assert_ok(&hlod_build(
        &["build", "m.gltf", "--shard", "0/2", "-o", "s0.hlsh", "-q"],
        d,
    ));
    e2e_tests::mkfifo(&d.join("pipe"));
    // A model whose buffer is the FIFO.
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("m.gltf")).unwrap()).unwrap();
    json["buffers"][0]["uri"] = "pipe".into();
    std::fs::write(d.join("piped.gltf"), serde_json::to_vec(&json).unwrap()).unwrap();
    let probes: &[&[&str]] = &[
        &["info", "pipe"],
        &["build", "pipe", "-o", "o.hlod"],
        &["build", "piped.gltf", "-o", "o.hlod"],
        &["build", "pipe", "--shard", "0/2", "-o", "o.hlsh"],
        &["merge", "m.gltf", "s0.hlsh", "pipe", "-o", "o.hlod"],
        &["relayout", "pipe", "-o", "o.hlod"],
        &["gen", "tile", "pipe", "--grid", "2x2", "-o", "o.glb"],
        &["gen", "tile", "piped.gltf", "--grid", "2x2", "-o", "o.glb"],
        &["mt", "pipe"],
        &["mt", "piped.gltf"],
        &["vdt", "pipe"],
    ];
    for args in probes {
        assert_refused(
            &hlod_build(args, d),
            "a FIFO, not a regular file",
            &format!("{args:?}"),
        );
        assert!(!d.join("o.hlod").exists() && !d.join("o.glb").exists());
    }
}

#[test]
fn a_model_reads_no_file_outside_its_folder_unless_allowed() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let m = root.join("model");
    let secret = root.join("secret");
    std::fs::create_dir_all(&m).unwrap();
    std::fs::create_dir_all(&secret).unwrap();
    model(&m);
    std::fs::rename(m.join("m.bin"), secret.join("real.bin")).unwrap();
    std::os::unix::fs::symlink("../secret/real.bin", m.join("link.bin")).unwrap();
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(m.join("m.gltf")).unwrap()).unwrap();
    let abs = secret.join("real.bin").to_string_lossy().into_owned();
    for (k, uri) in [
        "../secret/real.bin",
        "%2e%2e/secret/real.bin",
        "sub/../../secret/real.bin",
        abs.as_str(),
        "link.bin",
    ]
    .iter()
    .enumerate()
    {
        let mut j = json.clone();
        j["buffers"][0]["uri"] = (*uri).into();
        let name = format!("u{k}.gltf");
        std::fs::write(m.join(&name), serde_json::to_vec(&j).unwrap()).unwrap();
        let out = hlod_build(&["build", &name, "-o", "o.hlod", "-q"], &m);
        assert_refused(&out, "outside the model's folder", uri);
        assert!(
            stderr(&out).contains("buffers[0]"),
            "names the part: {}",
            stderr(&out)
        );
        assert!(!m.join("o.hlod").exists());
        // The user may allow the folder.
        let allow = secret.to_string_lossy().into_owned();
        let out = hlod_build(
            &["build", &name, "-o", "o.hlod", "-q", "--allow-dir", &allow],
            &m,
        );
        assert_ok(&out);
        std::fs::remove_file(m.join("o.hlod")).unwrap();
    }
}

/// `sh -c` with an address-space limit of `limit_mib` on the command.
fn limited(cmd: &str, limit_mib: u64, cwd: &Path) -> Output {
    let script = format!("ulimit -v {}; exec {cmd}", limit_mib * 1024);
    run_limited(Command::new("sh").args(["-c", &script]), cwd)
}

#[test]
fn memory_follows_what_a_model_uses_not_the_files_it_names() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    model(d);
    // The buffer file grows to 10 GB (sparse): the model still uses only
    // its first bytes.
    let bin = std::fs::OpenOptions::new()
        .write(true)
        .open(d.join("m.bin"))
        .unwrap();
    bin.set_len(10 << 30).unwrap();
    drop(bin);
    let exe = env!("CARGO_BIN_EXE_hlod-build");
    for args in [
        "build m.gltf -o o.hlod -q",
        "gen tile m.gltf --grid 2x2 -o t.glb",
        "mt m.gltf",
    ] {
        let t = Instant::now();
        let out = limited(&format!("'{exe}' {args}"), 4096, d);
        assert_ok(&out);
        assert!(
            t.elapsed() < Duration::from_secs(20),
            "{args}: {:?}",
            t.elapsed()
        );
    }
    // A node DAG of 60 levels of two nodes, each with both nodes of the
    // level below as children: 2^60 placements, refused before any is made.
    let mut nodes = vec![
        serde_json::json!({"mesh": 0}),
        serde_json::json!({"mesh": 0}),
    ];
    for k in 1..60 {
        let below = [2 * (k - 1), 2 * (k - 1) + 1];
        nodes.push(serde_json::json!({ "children": below }));
        nodes.push(serde_json::json!({ "children": below }));
    }
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("m.gltf")).unwrap()).unwrap();
    json["nodes"] = serde_json::Value::Array(nodes);
    json["scenes"] = serde_json::json!([{"nodes": [118, 119]}]);
    json["scene"] = 0.into();
    std::fs::write(d.join("dag.gltf"), serde_json::to_vec(&json).unwrap()).unwrap();
    let t = Instant::now();
    let out = limited(&format!("'{exe}' build dag.gltf -o dag.hlod"), 4096, d);
    assert_refused(&out, "places nodes more than", "the DAG");
    assert!(t.elapsed() < Duration::from_secs(20), "{:?}", t.elapsed());
}
