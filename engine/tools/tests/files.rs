//! Every file `hlod-bench`, `mt-bench` and `vdt-bench` read or write
//! (issue 50): no output in `--out DIR` is ever one of the run's inputs (by
//! name, hard link or symbolic link), and no reader blocks on a FIFO.

use std::path::Path;
use std::process::{Command, Output};
use std::time::Duration;

/// Runs `exe` in `cwd`, killed after 60 s (a reader blocked on a FIFO
/// would hang the test otherwise).
fn run(exe: &str, args: &[&str], cwd: &Path) -> Output {
    e2e_tests::run_limited(Command::new(exe).args(args), cwd, Duration::from_secs(60))
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

const BENCH: &str = env!("CARGO_BIN_EXE_hlod-bench");
const MT: &str = env!("CARGO_BIN_EXE_mt-bench");
const VDT: &str = env!("CARGO_BIN_EXE_vdt-bench");

/// A small built scene (`s.hlod`), an MT file (`r.mt`), a `.vdt` file
/// (`t.vdt`) and a camera path (`p.txt`) in `d`.
fn inputs(d: &Path) {
    use hlod_builder::scenegen::{plant, rock};
    let glb = d.join("plant.glb");
    let p = plant::PlantParams {
        seed: 5,
        objects: 20,
        triangles: 8_000,
    };
    plant::write_plant(&p, &glb).unwrap();
    let params = hlod_builder::build::BuildParams::default();
    hlod_builder::build::build_file(&glb, &d.join("s.hlod"), &params, false).unwrap();
    std::fs::remove_file(&glb).unwrap();
    let (p, n, i) = rock::rock(3_000, 2);
    let m = hlod_builder::mt::build_mt(&p, &n, &i, &Default::default()).unwrap();
    let parts = engine::mt::partition(&m, 20).unwrap();
    std::fs::write(
        d.join("r.mt"),
        engine::mt::file::encode(&m, &parts).unwrap(),
    )
    .unwrap();
    let tree = hlod_builder::vdt::build_tree(
        &p,
        &i,
        &hlod_builder::vdt::VdtParams {
            metric: hlod_builder::vdt::Metric::Quadric,
            max_switch: None,
        },
    );
    let levels = engine::vdt::meta::levels_for_block(4096);
    std::fs::write(d.join("t.vdt"), engine::vdt::file::encode(&tree, levels)).unwrap();
    let out = run(
        BENCH,
        &[
            "s.hlod", "--frames", "12", "--fps", "0", "--modes", "pre", "--out", "gen",
        ],
        d,
    );
    assert!(out.status.success(), "{}", stderr(&out));
    std::fs::rename(d.join("gen/path.txt"), d.join("p.txt")).unwrap();
    std::fs::remove_dir_all(d.join("gen")).unwrap();
}

/// For every output `o` of a run into `o/` and every input `i`: the input
/// placed at `o/NAME` (by name, as a hard link, as a symbolic link) makes
/// the run fail with exit code 2, saying it refuses, and the input keeps
/// its bytes. `args` name the inputs by `{i}` placeholders.
fn try_pairs(d: &Path, exe: &str, args: &[&str], ins: &[&str], outs: &[&str]) -> usize {
    try_pairs_by(d, exe, args, ins, outs, &["name", "hard", "soft"])
}

/// [`try_pairs`] with the ways of placing the input listed (an output named
/// after the input's own stem cannot be the input by name).
fn try_pairs_by(
    d: &Path,
    exe: &str,
    args: &[&str],
    ins: &[&str],
    outs: &[&str],
    ways: &[&str],
) -> usize {
    let mut tried = 0;
    for &input in ins {
        let bytes = std::fs::read(d.join(input)).unwrap();
        for &output in outs {
            for &way in ways {
                std::fs::create_dir_all(d.join("o")).unwrap();
                let at = format!("o/{output}");
                // The argument that names `input`: the file at `at` itself,
                // or the original beside a link at `at`.
                let named = match way {
                    "name" => {
                        std::fs::copy(d.join(input), d.join(&at)).unwrap();
                        at.clone()
                    }
                    "hard" => {
                        std::fs::hard_link(d.join(input), d.join(&at)).unwrap();
                        input.to_string()
                    }
                    _ => {
                        std::os::unix::fs::symlink(d.join(input), d.join(&at)).unwrap();
                        input.to_string()
                    }
                };
                let before = std::fs::read(d.join(&at)).unwrap();
                let a: Vec<String> = args
                    .iter()
                    .map(|a| {
                        if *a == format!("{{{input}}}") {
                            named.clone()
                        } else if a.starts_with('{') {
                            a.trim_matches(|c| c == '{' || c == '}').to_string()
                        } else {
                            a.to_string()
                        }
                    })
                    .collect();
                let a: Vec<&str> = a.iter().map(String::as_str).collect();
                let out = run(exe, &a, d);
                let what = format!("{exe} {a:?}: {input} at {at} ({way})");
                let err = stderr(&out);
                assert_eq!(out.status.code(), Some(2), "{what}: {err}");
                assert!(err.contains("refusing to"), "{what}: {err}");
                assert!(!err.contains("panicked"), "{what}: {err}");
                assert_eq!(std::fs::read(d.join(&at)).unwrap(), before, "{what}");
                assert_eq!(std::fs::read(d.join(input)).unwrap(), bytes, "{what}");
                std::fs::remove_dir_all(d.join("o")).unwrap();
                tried += 1;
            }
        }
    }
    tried
}

#[test]
fn no_output_of_a_bench_run_is_one_of_its_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    inputs(d);
    let quick = ["--frames", "12", "--fps", "0", "--out", "o"];
    let mut tried = 0;
    let mut args = vec![
        "{s.hlod}",
        "--path",
        "{p.txt}",
        "--modes",
        "incore,nopre,pre",
    ];
    args.extend(quick);
    tried += try_pairs(
        d,
        BENCH,
        &args,
        &["s.hlod", "p.txt"],
        &[
            "path.txt",
            "incore.csv",
            "nopre.csv",
            "pre.csv",
            "summary.md",
            "frame_time.png",
            "stage2_vs_front.png",
            "resident.png",
        ],
    );
    let args = [
        "{r.mt}", "--paths", "rotate", "--frames", "12", "--out", "o",
    ];
    tried += try_pairs(d, MT, &args, &["r.mt"], &["summary.md", "frames.csv"]);
    tried += try_pairs_by(
        d,
        MT,
        &args,
        &["r.mt"],
        &["io-r-rotate.png", "memory-r-rotate.png"],
        &["hard", "soft"],
    );
    let mut args = vec![
        "{t.vdt}",
        "--path",
        "{p.txt}",
        "--psnr-every",
        "4",
        "--budgets",
        "200%",
    ];
    args.extend(quick);
    tried += try_pairs(
        d,
        VDT,
        &args,
        &["t.vdt", "p.txt"],
        &["path.txt", "frames.csv", "table2.md", "psnr.csv"],
    );
    assert_eq!(tried, 3 * (2 * 8 + 2 + 2 * 4) + 2 * 2);
}

#[test]
fn no_bench_blocks_on_a_fifo() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    inputs(d);
    e2e_tests::mkfifo(&d.join("pipe"));
    for (exe, args) in [
        (BENCH, vec!["pipe"]),
        (BENCH, vec!["s.hlod", "--path", "pipe"]),
        (MT, vec!["pipe"]),
        (VDT, vec!["pipe"]),
        (VDT, vec!["t.vdt", "--path", "pipe"]),
    ] {
        let mut a = args.clone();
        a.extend(["--frames", "12", "--out", "o"]);
        if exe != MT {
            a.extend(["--fps", "0"]);
        }
        let out = run(exe, &a, d);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{exe} {a:?}: {err}");
        assert!(
            err.contains("a FIFO, not a regular file"),
            "{exe} {a:?}: {err}"
        );
    }
}
