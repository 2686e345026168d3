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
    };
    w.finish(
        &skeleton,
        &SceneMeta {
            object_count: 2,
            input_triangles: 2,
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
    let plot = engine::image::RgbaImage::load_png(&d.join("o/frame_time.png")).unwrap();
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
