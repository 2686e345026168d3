//! The spatial layout of the reps on disk: the same scene as the build
//! order, rep for rep, and one walkthrough's misses need fewer seeks.

use std::path::Path;

use engine::camera::View;
use engine::front::FrontIndex;
use engine::{SceneFile, Skeleton};
use engine_cli::paths::{PathKind, generate_path};
use glam::Vec3;
use hlod_builder::build::{BuildParams, build_file};
use hlod_builder::scenegen::plant::{PlantParams, write_plant};

fn build(glb: &Path, out: &Path, spatial: bool) -> SceneFile {
    let params = BuildParams {
        spatial_layout: spatial,
        ..BuildParams::default()
    };
    build_file(glb, out, &params, false).unwrap();
    let scene = SceneFile::open(out).unwrap();
    scene.verify_all_reps().unwrap();
    scene
}

/// Seeks a reader needs along a fly-through when it reads each frame's new
/// front reps in file order and reads through gaps of at most `gap` bytes.
fn seeks(s: &Skeleton, gap: u64) -> (u64, u64) {
    let index = FrontIndex::new(s);
    let root = &s.nodes[0];
    let (min, max) = (Vec3::from(root.bbox_min), Vec3::from(root.bbox_max));
    let diag = (max - min).length();
    let mut prev = vec![false; s.reps.len()];
    let (mut seeks, mut reps) = (0, 0);
    let mut front = Vec::new();
    for pose in generate_path(PathKind::Flythrough, min, max, 300) {
        let view = View {
            pose,
            width_px: 1280,
            height_px: 720,
            near: diag * 1e-5,
            far: diag * 10.0,
            section: engine::section::Section::NONE,
        };
        index.compute(&view, &view.frustum(0.0), 1.0, &mut front);
        let mut new: Vec<_> = front
            .iter()
            .copied()
            .filter(|&r| !prev[r as usize])
            .collect();
        new.sort_by_key(|&r| s.reps[r as usize].offset);
        let mut end: Option<u64> = None;
        for &r in &new {
            let rec = &s.reps[r as usize];
            if end.is_none_or(|e| rec.offset > e + gap) {
                seeks += 1;
            }
            end = Some((rec.offset + rec.extent()).next_multiple_of(engine::format::REP_ALIGN));
        }
        reps += new.len() as u64;
        prev.iter_mut().for_each(|p| *p = false);
        for &r in &front {
            prev[r as usize] = true;
        }
    }
    (seeks, reps)
}

#[test]
fn spatial_layout_holds_the_same_reps_and_needs_fewer_seeks() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("plant.glb");
    write_plant(
        &PlantParams {
            seed: 5,
            objects: 600,
            triangles: 1_000_000,
        },
        &glb,
    )
    .unwrap();
    let spatial = build(&glb, &dir.path().join("s.hlod"), true);
    let made = build(&glb, &dir.path().join("b.hlod"), false);
    let (a, b) = (spatial.skeleton(), made.skeleton());
    assert_eq!(a.nodes, b.nodes);
    assert_eq!(a.reps.len(), b.reps.len());
    let mut moved = 0;
    for r in 0..a.reps.len() as u32 {
        let (ra, rb) = (a.reps[r as usize], b.reps[r as usize]);
        moved += usize::from(ra.offset != rb.offset);
        let same_but_offset = engine::format::RepRecord {
            offset: rb.offset,
            ..ra
        };
        assert_eq!(same_but_offset, rb, "rep {r}");
        assert_eq!(
            spatial.read_rep_bytes(r).unwrap(),
            made.read_rep_bytes(r).unwrap()
        );
    }
    assert!(
        moved > a.reps.len() / 2,
        "{moved} of {} reps moved",
        a.reps.len()
    );
    assert_eq!(
        spatial.header().data_len,
        made.header().data_len,
        "no bytes added"
    );
    // Deterministic: a second build is byte-identical.
    let again = dir.path().join("s2.hlod");
    build(&glb, &again, true);
    assert_eq!(
        std::fs::read(dir.path().join("s.hlod")).unwrap(),
        std::fs::read(&again).unwrap()
    );
    // The point of the layout: a frame's new reps lie close together.
    let (mut ta, mut tb) = (0, 0);
    for gap in [0u64, 16 << 10, 64 << 10] {
        let (sa, n) = seeks(a, gap);
        let (sb, m) = seeks(b, gap);
        assert_eq!(n, m);
        eprintln!("gap {gap}: spatial {sa} seeks, build order {sb}, for {n} reps");
        assert!(sa < sb, "gap {gap}: spatial {sa} seeks vs build order {sb}");
        (ta, tb) = (ta + sa, tb + sb);
    }
    // Compressed, packed reps (format version 3) are small enough that the
    // longer gaps bridge much of the build order too: 17% fewer seeks at gap
    // 0, 11% at 16 KiB, 6% at 64 KiB on this plant.
    assert!(
        ta * 100 <= tb * 90,
        "spatial {ta} seeks vs build order {tb}"
    );
}
