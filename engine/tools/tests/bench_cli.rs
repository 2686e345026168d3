//! `hlod-bench` on a small scene: a real run, and clear errors for bad input.

use std::path::Path;
use std::process::{Command, Output};

use engine::Skeleton;
use engine::format::{NONE, NodeRecord, RepKind, RepMesh, RepRecord, SceneMeta, SceneWriter};

/// A two-leaf scene written with the format writer.
fn write_scene(path: &Path) {
    let mut w = SceneWriter::new(std::fs::File::create(path).unwrap()).unwrap();
    let mut reps = Vec::new();
    let boxes = [
        ([0.0f32, 0.0, 0.0], [3.0f32, 1.0, 1.0]),
        ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
        ([2.0, 0.0, 0.0], [3.0, 1.0, 1.0]),
    ];
    for (node, (mn, mx)) in boxes.iter().enumerate() {
        let p = [
            [mn[0], mn[1], mn[2]],
            [mx[0], mn[1], mn[2]],
            [mx[0], mx[1], mn[2]],
        ];
        let mesh = RepMesh::quantize(&p, &[[0.0, 0.0, 1.0]; 3], &[[255; 4]; 3], vec![0, 1, 2]);
        let loc = w.write_rep(&mesh.encode(node as u32, 0)).unwrap();
        reps.push(RepRecord {
            bbox_min: *mn,
            bbox_max: *mx,
            node: node as u32,
            index: 0,
            kind: if node == 0 {
                RepKind::Hlod
            } else {
                RepKind::Lod
            } as u16,
            error: if node == 0 { 1.0 } else { 0.01 },
            checksum: loc.checksum,
            offset: loc.offset,
            len: loc.len,
            tri_count: 1,
            vertex_count: 3,
            aux: 0,
        });
    }
    let node = |i: usize, parent: u32, depth: u32, first_child: u32, child_count: u32| NodeRecord {
        bbox_min: boxes[i].0,
        bbox_max: boxes[i].1,
        parent,
        first_child,
        child_count,
        first_rep: i as u32,
        rep_count: 1,
        depth,
        object: NONE,
        ..Default::default()
    };
    let skeleton = Skeleton {
        nodes: vec![
            node(0, NONE, 0, 1, 2),
            node(1, 0, 1, 0, 0),
            node(2, 0, 1, 0, 0),
        ],
        reps,
        ..Skeleton::default()
    };
    w.finish(
        &skeleton,
        &SceneMeta {
            object_count: 2,
            input_triangles: 2,
            ..Default::default()
        },
    )
    .unwrap();
}

fn bench(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hlod-bench"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

fn assert_fails(out: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(needle), "stderr lacks {needle:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn runs_and_rejects_bad_input_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_scene(&d.join("s.hlod"));
    let out = bench(
        d,
        &[
            "s.hlod", "--frames", "30", "--fps", "0", "--budget", "1MiB", "--out", "o",
        ],
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("| incore |") && text.contains("| nopre |") && text.contains("| pre |"),
        "{text}"
    );
    for f in [
        "incore.csv",
        "nopre.csv",
        "pre.csv",
        "summary.md",
        "path.txt",
        "frame_time.png",
        "stage2_vs_front.png",
        "resident.png",
    ] {
        assert!(d.join("o").join(f).exists(), "{f}");
    }
    let plot = <engine::image::RgbaImage as engine_cli::png::PngFile>::load_png(
        &d.join("o/frame_time.png"),
    )
    .unwrap();
    assert!(
        plot.coverage() > 0.02,
        "the plot has axes, labels and lines"
    );
    let csv = std::fs::read_to_string(d.join("o/pre.csv")).unwrap();
    assert_eq!(csv.lines().count(), 31);

    let out = bench(
        d,
        &[
            "s.hlod",
            "--frames",
            "10",
            "--fps",
            "0",
            "--budgets",
            "1MiB,2MiB",
            "--modes",
            "incore,pre",
            "--out",
            "sweep",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in [
        "incore.csv",
        "pre-1.00MiB.csv",
        "pre-2.00MiB.csv",
        "sweep.png",
    ] {
        assert!(d.join("sweep").join(f).exists(), "{f}");
    }
    let table = std::fs::read_to_string(d.join("sweep/summary.md")).unwrap();
    assert_eq!(
        table.lines().filter(|l| l.starts_with("| pre |")).count(),
        2,
        "{table}"
    );
    assert_fails(&bench(d, &["s.hlod", "--budgets", "1MiB,x"]), "--budget");

    assert_fails(
        &bench(d, &["s.hlod", "--modes", "incore,fast"]),
        "unknown mode \"fast\"",
    );
    std::fs::write(
        d.join("bad.txt"),
        "# path\n0 0 5 0 0 0 1 60\n0 0 x 0 0 0 1 60\n",
    )
    .unwrap();
    assert_fails(&bench(d, &["s.hlod", "--path", "bad.txt"]), "bad.txt:3:");
    std::fs::write(d.join("nan.txt"), "0 0 NaN 0 0 0 1 60\n").unwrap();
    assert_fails(
        &bench(d, &["s.hlod", "--path", "nan.txt"]),
        "nan.txt:1: non-finite",
    );
    assert_fails(
        &bench(d, &["s.hlod", "--budget", "10B", "--modes", "nopre"]),
        "below the minimal front",
    );
    assert_fails(&bench(d, &["s.hlod", "--budget", "lots"]), "--budget");
    assert_fails(&bench(d, &["missing.hlod"]), "missing.hlod");
    assert_fails(&bench(d, &["s.hlod", "--renderer", "vulkan"]), "--renderer");
    assert_fails(&bench(d, &["s.hlod", "--colouring", "pink"]), "colouring");
    assert_fails(
        &bench(d, &["s.hlod", "--disk", "floppy"]),
        "unknown disk model",
    );
    assert_fails(&bench(d, &["s.hlod", "--tolerance", "0"]), "tolerance");
}

#[test]
fn wgpu_renderer_reports_image_quality_and_a_missing_adapter_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_scene(&d.join("s.hlod"));
    let args = [
        "s.hlod",
        "--renderer",
        "wgpu",
        "--frames",
        "20",
        "--fps",
        "0",
        "--budget",
        "1MiB",
        "--width",
        "160",
        "--height",
        "120",
        "--psnr-every",
        "5",
        "--save-frames",
        "--out",
        "g",
    ];
    let out = bench(d, &args);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("Image quality against in-core"), "{text}");
    let psnr = std::fs::read_to_string(d.join("g/psnr.csv")).unwrap();
    // 4 samples for each of nopre and pre, plus the header.
    assert_eq!(psnr.lines().count(), 9, "{psnr}");
    assert!(d.join("g/frames/incore-00015.png").exists());
    // Without any Vulkan driver: a clear error, no panic.
    let out = Command::new(env!("CARGO_BIN_EXE_hlod-bench"))
        .args(args)
        .current_dir(d)
        .env("VK_ICD_FILENAMES", "/nonexistent.json")
        .env("VK_DRIVER_FILES", "/nonexistent.json")
        .output()
        .unwrap();
    assert_fails(&out, "no usable GPU adapter");
}

#[test]
fn nonsense_numbers_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_scene(&d.join("s.hlod"));
    for (opt, value, needle) in [
        ("--stall-deadline", "1e30", "--stall-deadline"),
        ("--render-rate", "1e-30", "--render-rate"),
        ("--disk", "0:1e-30", "out of range"),
        ("--fps", "1e-9", "--fps"),
        ("--fps", "NaN", "--fps"),
        ("--frames", "0", "--frames"),
        ("--width", "100000", "--width"),
        ("--warmup", "1e12", "--warmup"),
        ("--vdt-pool", "0", "--vdt-pool"),
        ("--budget", "1e30GiB", "this machine's memory"),
    ] {
        assert_fails(&bench(d, &["s.hlod", opt, value, "--out", "x"]), needle);
    }
    let vdt = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_vdt-bench"))
            .args(args)
            .current_dir(d)
            .output()
            .unwrap()
    };
    assert_fails(&vdt(&["t.vdt", "--frames", "1000000000"]), "--frames");
    assert_fails(&vdt(&["t.vdt", "--width", "100000"]), "--width");
    assert!(!d.join("x").exists(), "nothing written");
}

#[test]
fn sweep_points_that_round_alike_get_files_of_their_own() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_scene(&d.join("s.hlod"));
    let out = bench(
        d,
        &[
            "s.hlod",
            "--frames",
            "5",
            "--fps",
            "0",
            "--modes",
            "pre",
            "--budgets",
            "1000000B,1000001B,1000002B",
            "--out",
            "o",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csvs: Vec<_> = std::fs::read_dir(d.join("o"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".csv"))
        .collect();
    assert_eq!(csvs.len(), 3, "{csvs:?}");
}

/// `s.hlod` with a header (valid checksum) that claims `nodes` nodes and
/// a file as long as that needs (sparse).
fn lying_header(d: &Path, nodes: u32) -> std::path::PathBuf {
    use engine::FileHeader;
    let mut bytes = std::fs::read(d.join("s.hlod")).unwrap();
    const H: usize = std::mem::size_of::<FileHeader>();
    let mut h: FileHeader = bytemuck::pod_read_unaligned(&bytes[..H]);
    h.node_count = nodes;
    h.skeleton_len = u64::from(nodes) * 64 + u64::from(h.rep_count) * 64;
    h.objects_offset = h.skeleton_offset + h.skeleton_len;
    h.objects_len = 0;
    h.file_len = h.objects_offset;
    (h.walk_offset, h.walk_len, h.walk_crc) = (h.file_len, 0, 0);
    h.header_crc = 0;
    h.header_crc = crc32fast::hash(bytemuck::bytes_of(&h));
    bytes[..H].copy_from_slice(bytemuck::bytes_of(&h));
    let p = d.join(format!("lie{nodes}.hlod"));
    std::fs::write(&p, &bytes).unwrap();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&p)
        .unwrap()
        .set_len(h.file_len)
        .unwrap();
    p
}

#[test]
fn a_header_that_lies_about_its_counts_costs_no_memory() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_scene(&d.join("s.hlod"));
    lying_header(d, 1 << 31);
    assert_fails(
        &bench(d, &["lie2147483648.hlod"]),
        "more than this machine's memory",
    );
    // 2^24 nodes: a 1 GiB skeleton, refused by its checksum while the
    // process may not map more than 600 MB.
    lying_header(d, 1 << 24);
    let cmd = format!(
        "ulimit -v 600000; exec '{}' lie16777216.hlod --out o",
        env!("CARGO_BIN_EXE_hlod-bench")
    );
    let out = Command::new("sh")
        .args(["-c", &cmd])
        .current_dir(d)
        .output()
        .unwrap();
    assert_fails(&out, "checksum mismatch in skeleton");
}

#[test]
fn path_files_endless_with_a_bom_and_errors_said_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_scene(&d.join("s.hlod"));
    assert_fails(&bench(d, &["s.hlod", "--path", "/dev/zero"]), "/dev/zero");
    std::fs::write(d.join("bom.txt"), "\u{feff}# path\n1 0.5 5 0 0 0 1 60\n").unwrap();
    let out = bench(
        d,
        &[
            "s.hlod", "--path", "bom.txt", "--fps", "0", "--modes", "pre", "--budget", "1MiB",
            "--out", "o",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = bench(d, &["missing.hlod"]);
    assert_fails(&out, "missing.hlod");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.matches("No such file").count(), 1, "{err}");
}

#[test]
fn mt_bench_draws_the_papers_figures_and_refuses_nonsense() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (p, n, i) = hlod_builder::scenegen::rock::rock(30_000, 2);
    let m = hlod_builder::mt::build_mt(&p, &n, &i, &Default::default()).unwrap();
    let parts = engine::mt::partition(&m, 20).unwrap();
    std::fs::write(
        d.join("rock.mt"),
        engine::mt::file::encode(&m, &parts).unwrap(),
    )
    .unwrap();
    let mt = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_mt-bench"))
            .args(args)
            .current_dir(d)
            .output()
            .unwrap()
    };
    let out = mt(&["rock.mt", "--frames", "60", "--out", "o"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in [
        "summary.md",
        "frames.csv",
        "io-rock-far-near.png",
        "memory-rock-rotate.png",
    ] {
        assert!(d.join("o").join(f).exists(), "{f}");
    }
    // Same cuts in every mode (no footprint pressure), so what each keeps
    // nests: P,NC within P,C within P,CC; reads the other way round.
    let csv = std::fs::read_to_string(d.join("o/frames.csv")).unwrap();
    for path in ["far-near", "rotate"] {
        let last = |mode: &str, col: usize| -> (u64, u64) {
            let rows: Vec<Vec<String>> = csv
                .lines()
                .map(|l| l.split(',').map(str::to_string).collect::<Vec<_>>())
                .filter(|r| r[1] == path && r[2] == mode)
                .collect();
            let sum: u64 = rows.iter().map(|r| r[col].parse::<u64>().unwrap()).sum();
            (rows.last().unwrap()[4].parse().unwrap(), sum)
        };
        let (pnc, pc, pcc) = (last("p-nc", 7), last("p-c", 7), last("p-cc", 7));
        assert!(
            pcc.0 <= pc.0 && pc.0 <= pnc.0,
            "{path}: reads {pcc:?} {pc:?} {pnc:?}"
        );
        assert!(pnc.1 <= pc.1 && pc.1 <= pcc.1, "{path}: memory");
    }
    assert_fails(&mt(&["missing.mt", "--out", "x"]), "missing.mt");
    std::fs::write(d.join("junk.mt"), b"not an MT file at all, just bytes").unwrap();
    assert_fails(&mt(&["junk.mt", "--out", "x"]), "junk.mt");
    assert_fails(&mt(&["rock.mt", "--modes", "lru", "--out", "x"]), "--modes");
    assert_fails(&mt(&["rock.mt", "--frames", "1", "--out", "x"]), "--frames");
    assert_fails(
        &mt(&["rock.mt", "--tolerance", "0", "--out", "x"]),
        "--tolerance",
    );
    assert_fails(
        &mt(&["rock.mt", "--budget", "1KiB", "--out", "x"]),
        "footprint",
    );
    assert!(!d.join("x").exists(), "nothing written");
}

/// A footprint smaller than the path's fronts is said, on stderr and in
/// `summary.md` (out of core then draws ancestors, and only looks faster);
/// one that holds every front is not. The in-core row shows no budget.
#[test]
fn a_footprint_below_the_fronts_is_said() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let glb = d.join("p.glb");
    let p = hlod_builder::scenegen::plant::PlantParams {
        seed: 2,
        objects: 300,
        triangles: 150_000,
    };
    hlod_builder::scenegen::plant::write_plant(&p, &glb).unwrap();
    let params = hlod_builder::build::BuildParams::default();
    hlod_builder::build::build_file(&glb, &d.join("s.hlod"), &params, false).unwrap();
    let run = |budget: &str, out: &str| {
        let o = bench(
            d,
            &[
                "s.hlod", "--frames", "30", "--fps", "0", "--budget", budget, "--out", out,
            ],
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let table = std::fs::read_to_string(d.join(out).join("summary.md")).unwrap();
        (String::from_utf8_lossy(&o.stderr).into_owned(), table)
    };
    let (err, table) = run("3%", "short");
    assert!(err.contains("warning: nopre: the footprint of"), "{err}");
    assert!(err.contains("draws every front as itself"), "{err}");
    assert!(
        table.contains("**Warning:** pre: the footprint of"),
        "{table}"
    );
    let incore = table.lines().find(|l| l.starts_with("| incore |")).unwrap();
    assert!(incore.contains("| — (all) |"), "{incore}");
    let (err, table) = run("100%", "ample");
    assert!(!err.contains("warning: "), "{err}");
    assert!(!table.contains("Warning"), "{table}");
}

/// A scene on a web server (nginx, through `scripts/serve.sh`): the same
/// runs as from the local file, and a server that is down fails at start
/// with one clear error naming the URL.
#[test]
fn walks_a_scene_served_over_http() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let served = d.join("served");
    std::fs::create_dir(&served).unwrap();
    write_scene(&served.join("s.hlod"));
    let Some(nginx) = e2e_tests::servers::Nginx::start("bench_cli::over_http", &served) else {
        return;
    };
    let url = format!("{}/s.hlod", nginx.base);
    let args = |out: &'static str| {
        vec![
            "--frames", "30", "--fps", "0", "--budget", "1MiB", "--out", out,
        ]
    };
    let remote = bench(d, &[&[url.as_str()][..], &args("r")].concat());
    let err = String::from_utf8_lossy(&remote.stderr);
    assert!(remote.status.success(), "{err}");
    let local = bench(d, &[&["served/s.hlod"][..], &args("l")].concat());
    assert!(local.status.success());
    // The same fronts on every frame, whether read over HTTP or from disk.
    let fronts = |o: &str| -> Vec<String> {
        let csv = std::fs::read_to_string(d.join(o).join("pre.csv")).unwrap();
        let head: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        let col = head.iter().position(|c| *c == "front_reps").unwrap();
        csv.lines()
            .skip(1)
            .map(|l| l.split(',').nth(col).unwrap().to_string())
            .collect()
    };
    assert_eq!(fronts("r"), fronts("l"));
    assert!(nginx.access_log().iter().any(|l| l.contains(" 206 ")));
    // A disk model is for local files.
    let o = bench(
        d,
        &[&[url.as_str(), "--disk", "hdd"][..], &args("x")].concat(),
    );
    assert_fails(&o, "a disk model applies to local files only");
    drop(nginx);
    let down = bench(d, &[&[url.as_str()][..], &args("down")].concat());
    assert_fails(&down, &url);
    assert!(
        String::from_utf8_lossy(&down.stderr).contains("length and version"),
        "{}",
        String::from_utf8_lossy(&down.stderr)
    );
}

/// Walk mode with 2% of the Duplex resident: the walker follows the
/// generated interior walk through the scene's walk section while P_I
/// streams the reps; no frame's resident bytes pass the footprint, and
/// the walk is the same without and with prefetching (collision reads no
/// rep).
#[test]
fn the_duplex_is_walked_with_two_percent_resident() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = e2e_tests::data_dir().join("Ifc2x3_Duplex_Architecture.glb");
    hlod_builder::build::build_file(&model, &d.join("duplex.hlod"), &Default::default(), false)
        .unwrap();
    let out = bench(
        d,
        &[
            "duplex.hlod",
            "--path-kind",
            "interior",
            "--walk",
            "--frames",
            "240",
            "--fps",
            "0",
            "--budget",
            "2%",
            "--modes",
            "nopre,pre",
            "--out",
            "o",
        ],
    );
    let so = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(so.contains("walk: 240 frames walked"), "{so}");
    for mode in ["nopre", "pre"] {
        let csv = std::fs::read_to_string(d.join("o").join(format!("{mode}.csv"))).unwrap();
        let mut lines = csv.lines();
        let head: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = |n: &str| head.iter().position(|h| *h == n).unwrap();
        let (r, b) = (col("resident_bytes"), col("budget_bytes"));
        let mut frames = 0;
        for l in lines {
            let f: Vec<&str> = l.split(',').collect();
            let (res, bud): (u64, u64) = (f[r].parse().unwrap(), f[b].parse().unwrap());
            assert!(res <= bud, "{mode}: {res} > {bud}");
            frames += 1;
        }
        assert_eq!(frames, 240, "{mode}");
    }
    // The walked path is written once and used by both modes.
    let path = std::fs::read_to_string(d.join("o/path.txt")).unwrap();
    assert!(path.lines().filter(|l| !l.starts_with('#')).count() >= 240);
}

/// `--path-kind interior` walks the walk section where the scene has one,
/// and finds storeys and rooms from the geometry (`rooms`) where it has
/// none, saying so.
#[test]
fn interior_paths_walk_the_walk_section_or_say_they_cannot() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = e2e_tests::data_dir().join("AC14-FZK-Haus.glb");
    let without = hlod_builder::BuildParams {
        walk_cell: 0.0,
        ..Default::default()
    };
    hlod_builder::build::build_file(&model, &d.join("walk.hlod"), &Default::default(), false)
        .unwrap();
    hlod_builder::build::build_file(&model, &d.join("flat.hlod"), &without, false).unwrap();
    for (scene, line) in [
        ("walk.hlod", "walk path: storeys at"),
        ("flat.hlod", "rooms path:"),
    ] {
        let out = bench(
            d,
            &[
                scene,
                "--path-kind",
                "interior",
                "--frames",
                "60",
                "--modes",
                "incore",
                "--out",
                "o",
            ],
        );
        let so = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(so.contains(line), "{scene}: {so}");
        assert_eq!(so.contains("no walk section"), scene == "flat.hlod", "{so}");
    }
}
