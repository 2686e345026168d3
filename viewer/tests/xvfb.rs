//! `hlod-view` in a real window under Xvfb on lavapipe: it plays a path,
//! exits after N frames and saves a screenshot that must show the scene; a
//! scene that cannot be opened leaves the viewer running with the error shown,
//! and its exit status non-zero.
//! The screenshots are kept in `target/test-output/` (CI artefacts).

mod common;

use engine_cli::png::PngFile as _;
use std::path::Path;

use common::{artefacts, can_run, fzk_haus, scene, scene_coverage, view};

use engine::camera::format_path;
use engine::image::RgbaImage;
use engine_cli::paths::{PathKind, generate_path};
use glam::Vec3;

#[test]
fn plays_a_path_and_screenshots_the_scene() {
    if !can_run("plays_a_path_and_screenshots_the_scene") {
        return;
    }
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
    if !can_run("a_scene_that_cannot_open_shows_the_error_keeps_running_and_exits_non_zero") {
        return;
    }
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

#[test]
fn opens_a_glb_directly_builds_it_once_and_shows_it() {
    if !can_run("opens_a_glb_directly_builds_it_once_and_shows_it") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = fzk_haus();
    let args = |shot: &str| {
        vec![
            model.to_str().unwrap().to_string(),
            "--cache".into(),
            "cache".into(),
            "--exit-when-complete".into(),
            "--screenshot".into(),
            shot.into(),
            "--width".into(),
            "800".into(),
            "--height".into(),
            "450".into(),
        ]
    };
    let a1 = args("first.png");
    let out = view(d, &a1.iter().map(String::as_str).collect::<Vec<_>>());
    let (so, se) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{se}");
    assert!(so.contains("built into"), "{so}");
    assert!(se.contains("into the cache at"), "a build says so: {se}");
    // What the build left out is said, as `hlod-build` says it.
    let left_out = "left out the IFC opening voids and spaces (24 objects, 856 triangles)";
    assert!(so.contains(left_out), "{so}");
    assert!(so.contains("first complete frame"), "{so}");
    let img = RgbaImage::load_png(&d.join("first.png")).unwrap();
    std::fs::copy(d.join("first.png"), artefacts().join("viewer-open-glb.png")).unwrap();
    let cov = scene_coverage(&img);
    assert!(cov > 0.03, "the model is not visible ({cov})");
    // The second open is a cache hit, and shows the same.
    let a2 = args("second.png");
    let out = view(d, &a2.iter().map(String::as_str).collect::<Vec<_>>());
    let (so, se) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success());
    assert!(so.contains("cached scene"), "{so}");
    assert!(
        !se.contains("into the cache at"),
        "a cache hit builds nothing: {se}"
    );
    // The file records the triangles left out, not how many objects.
    assert!(
        so.contains("left out the IFC opening voids and spaces (856 triangles)"),
        "{so}"
    );
    assert_eq!(std::fs::read_dir(d.join("cache")).unwrap().count(), 1);
    let cov2 = scene_coverage(&RgbaImage::load_png(&d.join("second.png")).unwrap());
    assert!((cov2 - cov).abs() < 0.01, "{cov} vs {cov2}");
}

/// The element nearest along a ray, by brute force over the model's
/// triangles as the importer reads them (not through the scene file).
fn nearest_by_brute_force(model: &Path, o: Vec3, d: Vec3) -> Option<String> {
    let imp = hlod_builder::import::load(model).unwrap();
    let origin = glam::DVec3::from(imp.origin);
    let mut best: Option<(f32, String)> = None;
    for inst in &imp.instances {
        let Some(m) = &imp.meshes[inst.mesh] else {
            continue;
        };
        let w: Vec<Vec3> = m
            .positions
            .iter()
            .map(|p| {
                (inst.transform.transform_point3(Vec3::from(*p)).as_dvec3() + origin).as_vec3()
            })
            .collect();
        for t in m.indices.chunks_exact(3) {
            let hit = engine::pick::ray_triangle(
                o,
                d,
                w[t[0] as usize],
                w[t[1] as usize],
                w[t[2] as usize],
            );
            if let Some(h) = hit
                && best.as_ref().is_none_or(|b| h < b.0)
            {
                best = Some((h, inst.name.clone()));
            }
        }
    }
    best.map(|b| b.1)
}

#[test]
fn picks_the_element_at_a_known_pixel_and_shows_its_name() {
    if !can_run("picks_the_element_at_a_known_pixel_and_shows_its_name") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = fzk_haus();
    let mut names = Vec::new();
    // Pixels on the house, which framing places right of the main panel.
    for px in ["585,205", "525,265", "630,285"] {
        let out = view(
            d,
            &[
                model.to_str().unwrap(),
                "--cache",
                "cache",
                "--exit-when-complete",
                "--pick",
                px,
                "--screenshot",
                "pick.png",
                "--width",
                "800",
                "--height",
                "450",
            ],
        );
        let so = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let line = so
            .lines()
            .find(|l| l.starts_with("picked at"))
            .unwrap_or_else(|| panic!("{so}"));
        assert!(!line.contains("nothing"), "{line}");
        // "picked at X,Y: NAME (mesh …" and "ray [o] [d]" at the end.
        let name = line
            .split_once(": ")
            .unwrap()
            .1
            .split(" (mesh ")
            .next()
            .unwrap()
            .to_string();
        let nums: Vec<f32> = line
            .rsplit_once("ray ")
            .unwrap()
            .1
            .replace(['[', ']', ','], " ")
            .split_whitespace()
            .map(|v| v.parse().unwrap())
            .collect();
        let (o, dir_) = (
            Vec3::new(nums[0], nums[1], nums[2]),
            Vec3::new(nums[3], nums[4], nums[5]),
        );
        let expected = nearest_by_brute_force(&model, o, dir_);
        assert_eq!(Some(name.clone()), expected, "pixel {px}");
        names.push(name);
    }
    std::fs::copy(d.join("pick.png"), artefacts().join("viewer-pick.png")).unwrap();
    // The overlay shows the selection: its panel is drawn at the top right.
    let img = RgbaImage::load_png(&d.join("pick.png")).unwrap();
    let panel = (img.width - 200..img.width - 20)
        .filter(|&x| {
            let p = img.pixel(x, 40);
            (0..3)
                .map(|c| p[c].abs_diff([23u8, 26, 31][c]))
                .max()
                .unwrap()
                > 12
        })
        .count();
    assert!(panel > 100, "no selection panel ({panel})");
    assert!(names.iter().any(|n| n.contains("Ifc")), "{names:?}");
}

#[test]
fn a_budget_below_the_minimal_front_is_an_error_that_cannot_be_missed() {
    if !can_run("a_budget_below_the_minimal_front_is_an_error_that_cannot_be_missed") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = fzk_haus();
    let out = view(
        d,
        &[
            model.to_str().unwrap(),
            "--cache",
            "cache",
            "--budget",
            "1KiB",
            "--exit-after",
            "40",
            "--exit-when-complete",
            "--screenshot",
            "small.png",
            "--width",
            "640",
            "--height",
            "400",
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("below the minimal front"), "{err}");
    // The red panel is painted in the screenshot, centred at the bottom.
    let img = RgbaImage::load_png(&d.join("small.png")).unwrap();
    let red = (0..img.width)
        .flat_map(|x| (img.height / 2..img.height).map(move |y| (x, y)))
        .filter(|&(x, y)| {
            let p = img.pixel(x, y);
            p[0] > 70 && p[0] < 110 && p[1] < 40 && p[2] < 40
        })
        .count();
    assert!(red > 2000, "no error panel ({red} red pixels)");
}

#[test]
fn the_smallest_scenes_complete_under_budget_auto_and_a_budget_too_small_to_complete_is_said() {
    if !can_run(
        "the_smallest_scenes_complete_under_budget_auto_and_a_budget_too_small_to_complete_is_said",
    ) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // One triangle, one rep; and the dragon as one node of six LODs.
    let (p, i) = (
        vec![[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![0, 1, 2],
    );
    std::fs::write(d.join("tri.gltf"), e2e_tests::tiny_gltf(&p, &i, 4, None)).unwrap();
    let dragon = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/dragon_res4.glb");
    for (model, scene) in [(d.join("tri.gltf"), "tri.hlod"), (dragon, "dragon.hlod")] {
        hlod_builder::build::build_file(&model, &d.join(scene), &Default::default(), false)
            .unwrap();
        let out = view(d, &[scene, "--exit-when-complete", "--exit-after", "600"]);
        let text = String::from_utf8_lossy(&out.stdout);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{scene}: {err}");
        assert!(
            text.contains("first complete frame"),
            "{scene}: {text} {err}"
        );
    }
    // The dragon's finest rep needs more than 100 KiB to load: said, and
    // --exit-when-complete ends with that error instead of waiting.
    let out = view(
        d,
        &["dragon.hlod", "--budget", "100KiB", "--exit-when-complete"],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("the view cannot complete at this budget"),
        "{err}"
    );
}

#[test]
fn opens_ply_obj_and_stl_models_by_their_path() {
    if !can_run("opens_ply_obj_and_stl_models_by_their_path") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (p, i) = e2e_tests::grid(12);
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        p.len(),
        i.len() / 3
    );
    let mut obj = String::new();
    let mut stl = String::from("solid grid\n");
    for v in &p {
        ply += &format!("{} {} {}\n", v[0], v[1], v[2]);
        obj += &format!("v {} {} {}\n", v[0], v[1], v[2]);
    }
    for t in i.chunks_exact(3) {
        ply += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
        obj += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
        stl += "facet normal 0 0 1\nouter loop\n";
        for &k in t {
            let v = p[k as usize];
            stl += &format!("vertex {} {} {}\n", v[0], v[1], v[2]);
        }
        stl += "endloop\nendfacet\n";
    }
    stl += "endsolid grid\n";
    for (name, text) in [("grid.ply", ply), ("grid.obj", obj), ("grid.stl", stl)] {
        std::fs::write(d.join(name), text).unwrap();
        opens_and_completes(d, name, "600");
    }
}

/// `hlod-view MODEL` builds the model into its cache and reaches a complete
/// frame within `frames`, exiting 0.
fn opens_and_completes(d: &Path, model: &str, frames: &str) {
    let out = view(
        d,
        &[
            model,
            "--cache",
            "cache",
            "--exit-when-complete",
            "--exit-after",
            frames,
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{model}: {err}");
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains("first complete frame"),
        "{model}: {said}\n{err}"
    );
}

/// An IFC file opens by its path: IfcOpenShell (installed by
/// scripts/setup.sh in target/ifc-venv) converts it, and the viewer builds
/// it and walks it to a complete frame.
#[test]
fn opens_an_ifc_model_by_its_path() {
    if !can_run("opens_an_ifc_model_by_its_path") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let ifc = e2e_tests::data_dir().join("ifc/Ifc2x3_Duplex_Architecture.ifc");
    opens_and_completes(dir.path(), ifc.to_str().unwrap(), "900");
}

/// A scene on a web server (nginx through `scripts/serve.sh`), opened by its
/// URL: it completes and shows the scene as from the file.
#[test]
fn opens_a_scene_by_its_url() {
    let test = "opens_a_scene_by_its_url";
    if !can_run(test) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let served = d.join("served");
    std::fs::create_dir(&served).unwrap();
    let s = scene(&served);
    let Some(nginx) = e2e_tests::servers::Nginx::start(test, &served) else {
        return;
    };
    let url = format!(
        "{}/{}",
        nginx.base,
        s.file_name().unwrap().to_string_lossy()
    );
    let args = [
        "--exit-when-complete",
        "--width",
        "800",
        "--height",
        "450",
        "--screenshot",
    ];
    let out = view(d, &[&[url.as_str()][..], &args, &["url.png"]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("first complete frame"));
    assert!(nginx.access_log().iter().any(|l| l.contains(" 206 ")));
    let img = RgbaImage::load_png(&d.join("url.png")).unwrap();
    let cov = scene_coverage(&img);
    assert!(cov > 0.03, "the scene is not visible ({cov})");
    // The same view as from the file.
    let local = s.to_string_lossy().to_string();
    let out = view(d, &[&[local.as_str()][..], &args, &["file.png"]].concat());
    assert!(out.status.success());
    let file = RgbaImage::load_png(&d.join("file.png")).unwrap();
    let off = (scene_coverage(&file) - cov).abs();
    assert!(
        off < 0.01,
        "coverage {cov} over HTTP, {} from the file",
        scene_coverage(&file)
    );
}
