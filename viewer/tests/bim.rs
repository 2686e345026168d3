//! The BIM tools of `hlod-view` under Xvfb on lavapipe: BCF viewpoints
//! opened and saved, a section cutting the model, measuring with snaps.
//! The screenshots are kept in `target/test-output/` (CI artefacts).

mod common;

use engine::image::RgbaImage;
use engine_cli::png::PngFile as _;
use glam::Vec3;

use common::{artefacts, can_run, fzk_haus, scene_coverage, view};

/// `hlod-view` under Xvfb with `args`, in an 800×450 window.
fn view_800(dir: &std::path::Path, args: &[&str]) -> std::process::Output {
    let mut all = args.to_vec();
    all.extend(["--width", "800", "--height", "450"]);
    view(dir, &all)
}

/// A BCF 2.1 viewpoint of the box `[min, max]` (scene coordinates) of a
/// scene at `origin`, seen from a corner above, cut at mid-height when
/// `cut` (the half above removed).
fn bcf_viewpoint(min: Vec3, max: Vec3, origin: [f64; 3], cut: bool) -> String {
    let bcf = |v: Vec3, shift: bool| {
        let o = if shift { origin } else { [0.0; 3] };
        let w = [
            f64::from(v.x) + o[0],
            f64::from(v.y) + o[1],
            f64::from(v.z) + o[2],
        ];
        format!("<X>{}</X><Y>{}</Y><Z>{}</Z>", w[0], -w[2], w[1])
    };
    let c = (min + max) * 0.5;
    let eye = c + Vec3::new(1.0, 0.6, 1.0) * (max - min).length() * 0.8;
    let dir = (c - eye).normalize();
    let planes = if cut {
        format!(
            "<ClippingPlanes><ClippingPlane><Location>{}</Location><Direction>{}</Direction></ClippingPlane></ClippingPlanes>",
            bcf(c, true),
            bcf(Vec3::Y, false)
        )
    } else {
        String::new()
    };
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<VisualizationInfo Guid=\"0e2000cc-c831-4cea-a847-a3d87ae572ff\">\
         <Components><Visibility DefaultVisibility=\"true\"/></Components><PerspectiveCamera>\
         <CameraViewPoint>{}</CameraViewPoint><CameraDirection>{}</CameraDirection>\
         <CameraUpVector>{}</CameraUpVector><FieldOfView>50</FieldOfView></PerspectiveCamera>{planes}</VisualizationInfo>",
        bcf(eye, true),
        bcf(dir, false),
        bcf(Vec3::Y, false)
    )
}

/// The first row (from the top) right of the panel with the model in it.
fn top_row(img: &RgbaImage) -> u32 {
    (0..img.height)
        .find(|&y| {
            (img.width * 6 / 10..img.width).any(|x| {
                let p = img.pixel(x, y);
                (0..3)
                    .map(|c| p[c].abs_diff([23u8, 26, 31][c]))
                    .max()
                    .unwrap()
                    > 12
            })
        })
        .unwrap_or(img.height)
}

#[test]
fn opens_at_a_bcf_viewpoint_cuts_the_model_and_saves_the_view() {
    if !can_run("opens_at_a_bcf_viewpoint_cuts_the_model_and_saves_the_view") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = d.join("haus.hlod");
    hlod_builder::build::build_file(&fzk_haus(), &scene, &Default::default(), false).unwrap();
    let file = engine::SceneFile::open(&scene).unwrap();
    let r = &file.skeleton().nodes[0];
    let (min, max) = (Vec3::from(r.bbox_min), Vec3::from(r.bbox_max));
    let origin = file.meta().origin;
    let mut tops = Vec::new();
    for cut in [false, true] {
        let vp = d.join(format!("in-{cut}.bcfv"));
        std::fs::write(&vp, bcf_viewpoint(min, max, origin, cut)).unwrap();
        let (shot, saved) = (format!("{cut}.png"), format!("out-{cut}.bcfv"));
        let out = view_800(
            d,
            &[
                scene.to_str().unwrap(),
                "--viewpoint",
                vp.to_str().unwrap(),
                "--save-viewpoint",
                &saved,
                "--exit-when-complete",
                "--screenshot",
                &shot,
            ],
        );
        let so = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let planes = format!("camera and {} clipping plane(s) applied", u32::from(cut));
        assert!(so.contains(&planes), "{so}");
        let img = RgbaImage::load_png(&d.join(&shot)).unwrap();
        std::fs::copy(
            d.join(&shot),
            artefacts().join(format!("viewer-bcf-cut-{cut}.png")),
        )
        .unwrap();
        assert!(scene_coverage(&img) > 0.02, "the model is visible");
        tops.push(top_row(&img));
        // The view saved is the view opened: camera and planes, in BCF's
        // coordinates, read back by an XML parser.
        let xml = std::fs::read_to_string(d.join(&saved)).unwrap();
        let doc = roxmltree::Document::parse(&xml).unwrap();
        let nums = |tag: &str| -> Vec<f64> {
            let n = doc.descendants().find(|n| n.has_tag_name(tag)).unwrap();
            ["X", "Y", "Z"]
                .iter()
                .map(|a| {
                    let c = n.children().find(|c| c.has_tag_name(*a)).unwrap();
                    c.text().unwrap().parse().unwrap()
                })
                .collect()
        };
        let c = (min + max) * 0.5;
        let eye = c + Vec3::new(1.0, 0.6, 1.0) * (max - min).length() * 0.8;
        let want = [
            f64::from(eye.x) + origin[0],
            -(f64::from(eye.z) + origin[2]),
            f64::from(eye.y) + origin[1],
        ];
        let got = nums("CameraViewPoint");
        for k in 0..3 {
            assert!((got[k] - want[k]).abs() < 1e-2, "{got:?} {want:?}");
        }
        let saved_planes = doc
            .descendants()
            .filter(|n| n.has_tag_name("ClippingPlane"))
            .count();
        assert_eq!(saved_planes, usize::from(cut), "{xml}");
        if cut {
            let loc = nums("Location");
            assert!(
                (loc[2] - (f64::from(c.y) + origin[1])).abs() < 1e-2,
                "{loc:?}"
            );
            assert_eq!(nums("Direction"), [0.0, 0.0, 1.0]);
        }
    }
    // The roof is gone: the model starts lower in the cut view.
    assert!(tops[1] > tops[0] + 10, "top rows {tops:?}");
}

#[test]
fn measures_between_two_snapped_corners_in_metres() {
    if !can_run("measures_between_two_snapped_corners_in_metres") {
        return;
    }
    use hlod_builder::scenegen::glb::{GlbObject, to_glb};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A 2 m cube at the origin, seen face-on from 6 m along +z.
    let objects = [GlbObject {
        name: "cube".into(),
        mesh: 0,
        transform: glam::Mat4::IDENTITY,
    }];
    std::fs::write(
        d.join("cube.glb"),
        to_glb(
            &[e2e_tests::cube(Vec3::ZERO, 1.0, [180, 180, 200, 255])],
            &objects,
        )
        .unwrap(),
    )
    .unwrap();
    let scene = d.join("cube.hlod");
    hlod_builder::build::build_file(&d.join("cube.glb"), &scene, &Default::default(), false)
        .unwrap();
    let origin = engine::SceneFile::open(&scene).unwrap().meta().origin;
    let bcf = |v: [f64; 3], at: bool| {
        let o = if at { origin } else { [0.0; 3] };
        format!(
            "<X>{}</X><Y>{}</Y><Z>{}</Z>",
            v[0] + o[0],
            -(v[2] + o[2]),
            v[1] + o[1]
        )
    };
    let vp = format!(
        "<VisualizationInfo><Components><Visibility DefaultVisibility=\"true\"/></Components>\
         <PerspectiveCamera><CameraViewPoint>{}</CameraViewPoint><CameraDirection>{}</CameraDirection>\
         <CameraUpVector>{}</CameraUpVector><FieldOfView>50</FieldOfView></PerspectiveCamera></VisualizationInfo>",
        bcf([0.0, 0.0, 6.0], true),
        bcf([0.0, 0.0, -1.0], false),
        bcf([0.0, 1.0, 0.0], false)
    );
    std::fs::write(d.join("front.bcfv"), vp).unwrap();
    // The front face's lower corners on screen, clicked 3 px inside them.
    let pose = engine::camera::Pose::look_at(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO, 50.0);
    let px = |p: Vec3| pose.project(800, 450, p).unwrap();
    let (a, b) = (
        px(Vec3::new(-1.0, -1.0, 1.0)),
        px(Vec3::new(1.0, -1.0, 1.0)),
    );
    let clicks = format!("{},{},{},{}", a.0 + 3.0, a.1 - 3.0, b.0 - 3.0, b.1 - 3.0);
    let out = view_800(
        d,
        &[
            scene.to_str().unwrap(),
            "--viewpoint",
            "front.bcfv",
            "--measure",
            &clicks,
            "--exit-when-complete",
            "--screenshot",
            "measure.png",
        ],
    );
    let so = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::copy(
        d.join("measure.png"),
        artefacts().join("viewer-measure.png"),
    )
    .unwrap();
    let line = so
        .lines()
        .find(|l| l.starts_with("measured "))
        .unwrap_or_else(|| panic!("{so}"));
    // Both ends snapped to the corners: exactly the cube's 2 m edge.
    assert!(line.starts_with("measured 2.000 m from"), "{line}");
    assert_eq!(line.matches("(vertex)").count(), 2, "{line}");
    // Clicked on the face away from its edges (and from the diagonals of
    // its two triangles): not snapped, 1 m apart.
    let (l, r) = (px(Vec3::new(-0.5, 0.0, 1.0)), px(Vec3::new(0.5, 0.0, 1.0)));
    let clicks = format!("{},{},{},{}", l.0, l.1, r.0, r.1);
    let out = view_800(
        d,
        &[
            scene.to_str().unwrap(),
            "--viewpoint",
            "front.bcfv",
            "--measure",
            &clicks,
            "--exit-when-complete",
        ],
    );
    let so = String::from_utf8_lossy(&out.stdout).into_owned();
    let line = so.lines().find(|l| l.starts_with("measured ")).unwrap();
    assert_eq!(line.matches("(face)").count(), 2, "{line}");
    let got: f32 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!((got - 1.0).abs() < 0.005, "{line}");
}

#[test]
fn a_viewpoint_hides_its_components_and_the_view_saved_lists_them() {
    if !can_run("a_viewpoint_hides_its_components_and_the_view_saved_lists_them") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = d.join("haus.hlod");
    hlod_builder::build::build_file(&fzk_haus(), &scene, &Default::default(), false).unwrap();
    let file = engine::SceneFile::open(&scene).unwrap();
    let r = &file.skeleton().nodes[0];
    let (min, max) = (Vec3::from(r.bbox_min), Vec3::from(r.bbox_max));
    let origin = file.meta().origin;
    // The FZK-Haus's two roof slabs.
    let roofs = ["07Enbsqm9C7AQC9iyBwfSD", "2IxUUNUVPB6Ob$eicCfP2N"];
    let components = |default: bool, ids: &[&str]| {
        let list: String = ids
            .iter()
            .map(|g| format!("<Component IfcGuid=\"{g}\"/>"))
            .collect();
        format!(
            "<Components><Visibility DefaultVisibility=\"{default}\"><Exceptions>{list}</Exceptions></Visibility></Components>"
        )
    };
    let plain = "<Components><Visibility DefaultVisibility=\"true\"/></Components>";
    // The front door selected.
    let door = "2jTRqchjf7oB0yhQ6462T0";
    let selected = format!(
        "<Components><Selection><Component IfcGuid=\"{door}\"/></Selection><Visibility DefaultVisibility=\"true\"/></Components>"
    );
    let mut tops = Vec::new();
    for (name, comps) in [
        ("all", selected),
        ("roofless", components(true, &roofs)),
        ("roof-only", components(false, &roofs)),
    ] {
        let vp = d.join(format!("{name}.bcfv"));
        let xml = bcf_viewpoint(min, max, origin, false).replace(plain, &comps);
        std::fs::write(&vp, xml).unwrap();
        let (shot, saved) = (format!("{name}.png"), format!("{name}-out.bcfv"));
        let out = view_800(
            d,
            &[
                scene.to_str().unwrap(),
                "--viewpoint",
                vp.to_str().unwrap(),
                "--save-viewpoint",
                &saved,
                "--exit-when-complete",
                "--screenshot",
                &shot,
            ],
        );
        let so = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let img = RgbaImage::load_png(&d.join(&shot)).unwrap();
        std::fs::copy(
            d.join(&shot),
            artefacts().join(format!("viewer-bcf-{name}.png")),
        )
        .unwrap();
        let xml = std::fs::read_to_string(d.join(&saved)).unwrap();
        match name {
            "all" => {
                assert!(!so.contains("hidden"), "{so}");
                assert!(so.contains("selected IfcDoor:Haustuer"), "{so}");
                let sel = xml.split("<Selection>").nth(1).unwrap_or_default();
                assert!(sel.contains(door), "saved with the door selected: {xml}");
            }
            "roofless" => {
                assert!(
                    so.contains("2 element(s) hidden (2 of its 2 listed"),
                    "{so}"
                );
                assert!(xml.contains("DefaultVisibility=\"true\""), "{xml}");
                assert!(roofs.iter().all(|g| xml.contains(g)), "{xml}");
            }
            _ => {
                let line = so
                    .lines()
                    .find(|l| l.contains("element(s) hidden"))
                    .unwrap();
                assert!(line.contains("(2 of its 2 listed"), "{line}");
                // Isolated: saved as the shown ones against a hidden default.
                assert!(xml.contains("DefaultVisibility=\"false\""), "{xml}");
                assert!(roofs.iter().all(|g| xml.contains(g)), "{xml}");
            }
        }
        // The roof's tiles: orange pixels.
        let orange = (0..img.height)
            .flat_map(|y| (0..img.width).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let p = img.pixel(x, y);
                p[0] > 150 && p[1] > 40 && p[1] < 130 && p[2] < 60
            })
            .count();
        tops.push((orange, scene_coverage(&img)));
    }
    // Without its roof no tile shows; the roof alone shows as many tiles
    // as the whole house (nothing of it was hidden by walls) and less else.
    assert!(tops[0].0 > 300 && tops[1].0 < tops[0].0 / 50, "{tops:?}");
    assert!(tops[2].0 as f64 > tops[0].0 as f64 * 0.9, "{tops:?}");
    assert!(tops[2].1 < tops[0].1 * 0.8, "{tops:?}");
}

#[test]
fn finds_an_element_by_global_id_and_flies_to_it() {
    if !can_run("finds_an_element_by_global_id_and_flies_to_it") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = d.join("haus.hlod");
    hlod_builder::build::build_file(&fzk_haus(), &scene, &Default::default(), false).unwrap();
    let run = |find: &str, shot: &str| {
        let out = view_800(
            d,
            &[
                scene.to_str().unwrap(),
                "--find",
                find,
                "--exit-when-complete",
                "--screenshot",
                shot,
            ],
        );
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    // The front door, by its GlobalId (any case).
    let (ok, so, se) = run("2jtrqchjf7ob0", "door.png");
    assert!(ok, "{se}");
    let line = so
        .lines()
        .find(|l| l.starts_with("find "))
        .unwrap_or_else(|| panic!("{so}"));
    assert!(
        line.contains("1 element(s); selected IfcDoor:Haustuer"),
        "{line}"
    );
    std::fs::copy(d.join("door.png"), artefacts().join("viewer-find-door.png")).unwrap();
    // Framed beside the panel: the door fills much of the view.
    let img = RgbaImage::load_png(&d.join("door.png")).unwrap();
    assert!(scene_coverage(&img) > 0.3, "{}", scene_coverage(&img));
    // By type: every window; nothing for a text no element holds.
    let (ok, so, _) = run("IfcWindow", "windows.png");
    assert!(ok && so.contains("selected IfcWindow:"), "{so}");
    // An error a script sees: said, and the exit status is not 0.
    let (ok, _, se) = run("no such element", "none.png");
    assert!(!ok && se.contains("no element matches"), "{se}");
}

/// Walk mode (`--walk`) on the FZK-Haus from a viewpoint a little above
/// eye height in the ground storey: the eye stands at 1.6 m over the floor
/// the walk section holds, and the view is drawn from there.
#[test]
fn walk_mode_stands_the_eye_on_the_floor() {
    if !can_run("walk_mode_stands_the_eye_on_the_floor") {
        return;
    }
    use engine::walk::{Body, SolidMap, WalkMap, Walker};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = d.join("haus.hlod");
    hlod_builder::build::build_file(&fzk_haus(), &scene, &Default::default(), false).unwrap();
    let file = engine::SceneFile::open(&scene).unwrap();
    let origin = file.meta().origin;
    let mut map = WalkMap::open(engine::FileSource::open(&scene).unwrap(), 1 << 20)
        .unwrap()
        .unwrap();
    // A free standing place on the ground floor with a ceiling above, and
    // the direction with the longest free view at eye height from it.
    let r = &file.skeleton().nodes[0];
    let (min, max) = (Vec3::from(r.bbox_min), Vec3::from(r.bbox_max));
    let g = map.grid();
    let solid_at = |map: &mut WalkMap<engine::FileSource>, p: Vec3| -> bool {
        map.column(g.cell_of(p.x), g.cell_of(p.z))
            .map(|c| {
                c.solid
                    .iter()
                    .chain(c.doors)
                    .any(|s| g.height(s.lo) < p.y + 0.3 && g.height(s.hi) > p.y - 0.3)
            })
            .unwrap_or(true)
    };
    let mut best: Option<(f32, Vec3, Vec3)> = None;
    for k in 0..400 {
        let (i, j) = ((k % 20) as f32 / 20.0, (k / 20) as f32 / 20.0);
        let p = Vec3::new(
            min.x + (max.x - min.x) * (0.1 + 0.8 * i),
            0.0,
            min.z + (max.z - min.z) * (0.1 + 0.8 * j),
        );
        let Ok(w) = Walker::from_eye(Body::default(), &mut map, p + Vec3::Y * 1.6) else {
            continue;
        };
        let roofed = map.column(g.cell_of(p.x), g.cell_of(p.z)).is_ok_and(|c| {
            c.solid
                .iter()
                .any(|s| g.height(s.lo) > 2.0 && g.height(s.lo) < 3.5)
        });
        if !(roofed && w.grounded() && !w.stuck(&mut map).unwrap() && w.feet().y.abs() < 0.2) {
            continue;
        }
        // Indoors: solid at eye height in every direction within 12 m.
        let views: Vec<(f32, Vec3)> = (0..16)
            .map(|d| {
                let a = d as f32 * std::f32::consts::FRAC_PI_8;
                let dir = Vec3::new(a.cos(), 0.0, a.sin());
                let free = (1..120)
                    .map(|s| s as f32 * 0.1)
                    .find(|&t| solid_at(&mut map, w.eye() + dir * t))
                    .unwrap_or(f32::INFINITY);
                (free, dir)
            })
            .collect();
        if views.iter().any(|v| v.0.is_infinite()) {
            continue;
        }
        for (free, dir) in views {
            if best.is_none_or(|b| free > b.0) {
                best = Some((free, w.feet(), dir));
            }
        }
    }
    let (free, place, look) = best.expect("a place to stand on the ground floor");
    assert!(free > 2.0, "a free view of {free} m");
    let eye = place + Vec3::Y * 1.85;
    let bcf = |v: Vec3, o: [f64; 3]| {
        format!(
            "<X>{}</X><Y>{}</Y><Z>{}</Z>",
            f64::from(v.x) + o[0],
            -(f64::from(v.z) + o[2]),
            f64::from(v.y) + o[1]
        )
    };
    let vp = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<VisualizationInfo Guid=\"0e2000cc-c831-4cea-a847-a3d87ae572aa\">\
         <PerspectiveCamera><CameraViewPoint>{}</CameraViewPoint><CameraDirection>{}</CameraDirection>\
         <CameraUpVector>{}</CameraUpVector><FieldOfView>60</FieldOfView></PerspectiveCamera></VisualizationInfo>",
        bcf(eye, origin),
        bcf((look - Vec3::Y * 0.08).normalize(), [0.0; 3]),
        bcf(Vec3::Y, [0.0; 3])
    );
    std::fs::write(d.join("in.bcfv"), vp).unwrap();
    let out = view_800(
        d,
        &[
            scene.to_str().unwrap(),
            "--viewpoint",
            "in.bcfv",
            "--walk",
            "--no-overlay",
            "--save-viewpoint",
            "out.bcfv",
            "--exit-when-complete",
            "--screenshot",
            "walk.png",
        ],
    );
    let (so, se) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{se}");
    assert!(format!("{so}{se}").contains("walk mode"), "{so}{se}");
    let xml = std::fs::read_to_string(d.join("out.bcfv")).unwrap();
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let cam = doc
        .descendants()
        .find(|n| n.has_tag_name("CameraViewPoint"))
        .unwrap();
    let z: f64 = cam
        .children()
        .find(|c| c.has_tag_name("Z"))
        .unwrap()
        .text()
        .unwrap()
        .parse()
        .unwrap();
    let want = f64::from(place.y + 1.6) + origin[1];
    assert!((z - want).abs() < 0.03, "eye at {z}, want {want}");
    let img = RgbaImage::load_png(&d.join("walk.png")).unwrap();
    std::fs::copy(
        d.join("walk.png"),
        artefacts().join("viewer-walk-fzk-haus.png"),
    )
    .unwrap();
    assert!(
        scene_coverage(&img) > 0.3,
        "inside, the model fills the view"
    );
}
