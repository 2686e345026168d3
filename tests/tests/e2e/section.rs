//! Section planes drawn by the wgpu renderer (lavapipe without a GPU): what
//! a plane removes is cut away exactly, the cut through a closed solid is
//! capped, and a node wholly on the removed side leaves the front.

use engine::camera::Pose;
use engine::runtime::{Mode, Walkthrough};
use engine::section::Section;
use engine_gpu::Colouring;
use glam::{Mat4, Vec3};
use hlod_builder::mesh::Mesh;
use hlod_builder::scenegen::glb::{GlbObject, to_glb};

use super::render::{build, load, params, renderer, shot};

/// The model (in the first folder) built into a scene (in the second).
fn scene(meshes: &[Mesh]) -> (tempfile::TempDir, tempfile::TempDir, std::path::PathBuf) {
    let objects: Vec<GlbObject> = (0..meshes.len())
        .map(|m| GlbObject {
            name: format!("object {m}"),
            mesh: m,
            transform: Mat4::IDENTITY,
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("section.glb");
    std::fs::write(&glb, to_glb(meshes, &objects).unwrap()).unwrap();
    let (d, scene) = build(&glb);
    (dir, d, scene)
}

#[test]
fn a_section_cuts_away_what_it_removes_and_caps_the_cut() {
    // Seen from +z: a grey cube in front (z in -1..1) and a green one far
    // behind it (z in -7..-5), both 2 m wide.
    let (_model, _d, path) = scene(&[
        e2e_tests::cube(Vec3::ZERO, 1.0, [200, 200, 200, 255]),
        e2e_tests::cube(Vec3::new(0.0, 0.0, -6.0), 1.0, [0, 220, 0, 255]),
    ]);
    let (skel, source, data) = load(&path);
    let test = "a_section_cuts_away_what_it_removes_and_caps_the_cut";
    let Some(mut r) = renderer(test, data, Colouring::Object) else {
        return;
    };
    let mut walk = Walkthrough::start(skel, source, params(Mode::Incore, 0, 0.5)).unwrap();
    let eye = Pose::look_at(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO, 50.0);
    let (cx, cy) = (super::render::W / 2, super::render::H / 2);

    // No section: the grey cube's lit front face.
    let whole = shot(&mut walk, &mut r, &eye);
    let lit = whole.pixel(cx, cy);
    assert!(lit[0] > 150 && lit[0] == lit[1], "front face {lit:?}");

    // Cut at z = 0, removing +z: the inside of the grey cube's back half,
    // flat and dark (the cap), where its lit face was.
    walk.set_section(Section::from_planes(&[(Vec3::ZERO, Vec3::Z)]).unwrap());
    let cut = shot(&mut walk, &mut r, &eye);
    let cap = cut.pixel(cx, cy);
    assert!(
        cap[0] < lit[0] / 2 && cap[0] > 40 && cap[0] == cap[1],
        "cap {cap:?} against {lit:?}"
    );
    // Beside the cubes nothing changed.
    assert_eq!(cut.pixel(4, 4), whole.pixel(4, 4));

    // Cut at z = -2: the grey cube is cut away whole and the green cube
    // behind it shows, uncut (the two share one merged leaf, whose rep the
    // shader clips).
    walk.set_section(Section::from_planes(&[(Vec3::new(0.0, 0.0, -2.0), Vec3::Z)]).unwrap());
    r.capture_next_frame();
    let f = walk.frame(&eye, &mut r).unwrap();
    let behind = r.take_capture().unwrap();
    let g = behind.pixel(cx, cy);
    assert!(g[1] > 100 && g[0] < 40 && g[2] < 40, "green cube {g:?}");
    assert_eq!(f.front_reps, 1, "the merged leaf's rep, clipped: {f:?}");

    // A section box that holds nothing: an empty image.
    walk.set_section(Section::boxed(Vec3::splat(50.0), Vec3::splat(60.0)).unwrap());
    r.capture_next_frame();
    let f = walk.frame(&eye, &mut r).unwrap();
    let empty = r.take_capture().unwrap();
    assert_eq!(f.front_reps, 0);
    assert_eq!(empty.pixel(cx, cy), whole.pixel(4, 4));
    assert!(r.context().take_errors().is_empty());
}

#[test]
fn a_hidden_element_of_a_merged_leaf_is_not_drawn_and_an_xrayed_one_hides_nothing() {
    use engine::hide::{Hiding, NodeVis};
    use engine::render::Renderer;
    // The same two cubes: small enough to share one merged leaf.
    let (_model, _d, path) = scene(&[
        e2e_tests::cube(Vec3::ZERO, 1.0, [200, 200, 200, 255]),
        e2e_tests::cube(Vec3::new(0.0, 0.0, -6.0), 1.0, [0, 220, 0, 255]),
    ]);
    let file = engine::SceneFile::open(&path).unwrap();
    let table = file.read_objects().unwrap();
    let grey = (0..table.len() as u32)
        .find(|&k| table.info(k).unwrap().contains("object 0"))
        .unwrap();
    let (skel, source, data) = load(&path);
    let hiding = Hiding::new(&skel, &table, |k| k == grey);
    let leaves = skel.nodes.iter().filter(|n| n.child_count == 0).count();
    let test = "a_hidden_element_of_a_merged_leaf_is_not_drawn_and_an_xrayed_one_hides_nothing";
    let Some(mut r) = renderer(test, data, Colouring::Object) else {
        return;
    };
    let mut walk = Walkthrough::start(skel.clone(), source, params(Mode::Incore, 0, 0.5)).unwrap();
    let eye = Pose::look_at(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO, 50.0);
    let (cx, cy) = (super::render::W / 2, super::render::H / 2);
    let before = shot(&mut walk, &mut r, &eye).pixel(cx, cy);
    assert!(
        before[0] > 150 && before[0] == before[1],
        "grey cube {before:?}"
    );
    walk.set_hiding(&hiding);
    r.set_parts(hiding.parts());
    let after = shot(&mut walk, &mut r, &eye).pixel(cx, cy);
    assert!(
        after[1] > 100 && after[0] < 40,
        "the green cube behind {after:?}"
    );
    // One merged leaf, drawn in part from its finest rep.
    assert_eq!(leaves, 1);
    assert_eq!(hiding.nodes()[0], NodeVis::Mixed);
    assert_eq!(hiding.parts().opaque.len(), 1);
    // X-rayed: the green cube shows through a pale translucent grey one.
    let xray = Hiding::with_looks(&skel, &table, |k| {
        if k == grey {
            engine::tree::Look::XRay
        } else {
            engine::tree::Look::Shown
        }
    });
    walk.set_hiding(&xray);
    r.set_parts(xray.parts());
    let through = shot(&mut walk, &mut r, &eye).pixel(cx, cy);
    assert!(
        through[1] > through[0] + 40 && through[2] > through[0] && through != after,
        "green through pale blue {through:?} (hidden: {after:?})"
    );
    // Shown again.
    walk.set_hiding(&Hiding::none(skel.nodes.len()));
    r.set_parts(&Default::default());
    assert_eq!(shot(&mut walk, &mut r, &eye).pixel(cx, cy), before);
    assert!(r.context().take_errors().is_empty());
}
