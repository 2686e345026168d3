//! The model tree of `hlod-view` under Xvfb on lavapipe: the FZK-Haus
//! built from its IFC (site, building, storeys), a storey x-rayed, hidden
//! and isolated by its name in the tree, and the tree panel's screenshot.
//! The screenshots are kept in `target/test-output/` (CI artefacts).

mod common;

use engine::image::RgbaImage;
use engine_cli::png::PngFile as _;

use common::{artefacts, can_run, scene_coverage, view};

/// The FZK-Haus built from its IFC (site, building, storeys) into `dir`.
fn ifc_haus(dir: &std::path::Path) -> std::path::PathBuf {
    let scene = dir.join("haus.hlod");
    let ifc = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/data/ifc/AC14-FZK-Haus.ifc");
    hlod_builder::build::build_file(&ifc, &scene, &Default::default(), false).unwrap();
    scene
}

/// The roof's tiles: orange pixels.
fn orange(img: &RgbaImage) -> usize {
    (0..img.height)
        .flat_map(|y| (0..img.width).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let p = img.pixel(x, y);
            p[0] > 150 && p[1] > 40 && p[1] < 130 && p[2] < 60
        })
        .count()
}

/// How many pixels differ between `a` and `b`, and their mean difference
/// (the largest of the three channels).
fn difference(a: &RgbaImage, b: &RgbaImage) -> (usize, f64) {
    let (mut n, mut sum) = (0usize, 0u64);
    for y in 0..a.height {
        for x in 0..a.width {
            let (p, q) = (a.pixel(x, y), b.pixel(x, y));
            let d = (0..3).map(|c| p[c].abs_diff(q[c])).max().unwrap_or(0);
            if d > 4 {
                n += 1;
                sum += u64::from(d);
            }
        }
    }
    (n, sum as f64 / n.max(1) as f64)
}

#[test]
fn a_storey_is_xrayed_hidden_and_isolated_by_its_name_in_the_tree() {
    if !can_run("a_storey_is_xrayed_hidden_and_isolated_by_its_name_in_the_tree") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = ifc_haus(d);
    let run = |name: &str, args: &[&str]| {
        let shot = format!("{name}.png");
        let mut all = vec![scene.to_str().unwrap(), "--exit-when-complete"];
        all.extend(args);
        all.extend(["--screenshot", &shot, "--width", "800", "--height", "450"]);
        let out = view(d, &all);
        let (so, se) = (
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        );
        assert!(out.status.success(), "{name}: {se}");
        std::fs::copy(
            d.join(&shot),
            artefacts().join(format!("viewer-tree-{name}.png")),
        )
        .unwrap();
        (RgbaImage::load_png(&d.join(&shot)).unwrap(), so)
    };
    let top = "1. Dachgeschoss";
    let (plain, _) = run("plain", &[]);
    let (xray, so) = run("xray", &["--xray", top]);
    let n: usize = so
        .lines()
        .find_map(|l| l.strip_prefix("XRay group \"1. Dachgeschoss\": "))
        .and_then(|l| l.split(' ').next()?.parse().ok())
        .unwrap_or_else(|| panic!("{so}"));
    assert!(n > 20, "{so}");
    assert!(
        so.contains(&format!("0 element(s) hidden, {n} x-rayed")),
        "{so}"
    );
    let (hidden, so) = run("hidden", &["--hide", top]);
    assert!(
        so.contains(&format!("{n} element(s) hidden, 0 x-rayed")),
        "{so}"
    );
    let (isolated, so) = run("isolated", &["--isolate", "0. Erdgeschoss"]);
    assert!(so.contains("Isolate group \"0. Erdgeschoss\""), "{so}");
    // The roof's tiles: many in the plain view, none hidden or isolated
    // below it, and x-rayed they are no longer drawn opaque.
    let tiles = [&plain, &xray, &hidden, &isolated].map(orange);
    assert!(tiles[0] > 300, "{tiles:?}");
    assert!(
        tiles[1] < tiles[0] / 4 && tiles[2] < tiles[0] / 50,
        "{tiles:?}"
    );
    assert!(tiles[3] < tiles[0] / 50, "{tiles:?}");
    // X-rayed is not hidden: the storey is drawn over the view without it,
    // faintly (translucent, hiding nothing), where drawn solid it differs
    // strongly.
    let (faint_n, faint) = difference(&xray, &hidden);
    let (solid_n, solid) = difference(&plain, &hidden);
    assert!(faint_n > solid_n / 4, "{faint_n} px, solid {solid_n} px");
    assert!(faint < solid * 0.6, "x-ray {faint:.1}, solid {solid:.1}");
    assert!(
        scene_coverage(&isolated) < scene_coverage(&plain),
        "isolated"
    );
}

#[test]
fn the_tree_panel_lists_the_storeys_and_a_text_that_names_nothing_is_an_error() {
    if !can_run("the_tree_panel_lists_the_storeys_and_a_text_that_names_nothing_is_an_error") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = ifc_haus(d);
    let s = scene.to_str().unwrap();
    let args = [
        s,
        "--tree",
        "--xray",
        "IfcSlab",
        "--exit-when-complete",
        "--screenshot",
        "tree.png",
        "--width",
        "1024",
        "--height",
        "576",
    ];
    let out = view(d, &args);
    let se = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{se}");
    assert!(
        se.contains("model tree: ") && se.contains("groups over"),
        "{se}"
    );
    std::fs::copy(
        d.join("tree.png"),
        artefacts().join("viewer-tree-panel.png"),
    )
    .unwrap();
    let img = RgbaImage::load_png(&d.join("tree.png")).unwrap();
    assert!(
        scene_coverage(&img) > 0.05,
        "the model is visible beside the panel"
    );
    // A name no group or element has: said, and the exit status not 0.
    let out = view(d, &[s, "--hide", "no such storey", "--exit-when-complete"]);
    let se = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && se.contains("no group or element matches"),
        "{se}"
    );
}
