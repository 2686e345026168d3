//! Walk mode on real buildings (FZK-Haus, Duplex): the walk section the
//! build writes stops the walker at walls, carries it up the stairs and
//! lets it fall off a slab edge, reading nothing but that section.

use std::path::Path;

use engine::walk::{Body, Reach, SolidMap, WalkMap, Walker};
use engine::{MemSource, SceneFile};
use glam::{Mat4, Vec2, Vec3};
use hlod_builder::build::{BuildParams, build_scene};
use hlod_builder::import::{Imported, load};

const DT: f32 = 1.0 / 60.0;

fn data(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/data")
        .join(name)
}

/// The model, and its scene built in memory with a walk section.
fn built(name: &str) -> (Imported, SceneFile<MemSource>) {
    let model = load(&data(name)).unwrap();
    let mut out = std::io::Cursor::new(Vec::new());
    build_scene(&model, &mut out, &BuildParams::default(), false).unwrap();
    let scene = SceneFile::from_source(MemSource::new(out.into_inner())).unwrap();
    (model, scene)
}

fn walk_map(scene: &SceneFile<MemSource>) -> WalkMap<MemSource> {
    WalkMap::open(scene.source().clone(), engine::walk::DEFAULT_CAP)
        .unwrap()
        .expect("the build writes a walk section")
}

/// World boxes of the instances whose name starts with `prefix`.
fn boxes(model: &Imported, prefix: &str) -> Vec<(Vec3, Vec3)> {
    model
        .instances
        .iter()
        .filter(|i| i.name.starts_with(prefix))
        .filter_map(|i| {
            let b = model.meta[i.mesh]?.bounds;
            Some(corners(b.min, b.max, &i.transform))
        })
        .collect()
}

fn corners(min: Vec3, max: Vec3, m: &Mat4) -> (Vec3, Vec3) {
    (0..8).fold((Vec3::MAX, Vec3::MIN), |(lo, hi), k| {
        let c = Vec3::new(
            if k & 1 == 0 { min.x } else { max.x },
            if k & 2 == 0 { min.y } else { max.y },
            if k & 4 == 0 { min.z } else { max.z },
        );
        let p = m.transform_point3(c);
        (lo.min(p), hi.max(p))
    })
}

/// A walker standing at `p` on the floor within a step of `p.y`, with
/// nothing in its body.
fn stand(map: &mut impl SolidMap, p: Vec3) -> Option<Walker> {
    let w = Walker::from_eye(Body::default(), map, p + Vec3::Y * 1.6).ok()?;
    let free = !w.stuck(map).ok()?;
    (free && w.grounded() && (w.feet().y - p.y).abs() <= 0.3).then_some(w)
}

/// Doors: from 1 m away on a side with a floor, walking at a door for 4 s
/// never passes it closed; with the doors open most are passed (a few
/// lead to a wardrobe or a step too high). Returns (tried, passed open).
fn doors(name: &str) -> (usize, usize) {
    let (model, scene) = built(name);
    let mut map = walk_map(&scene);
    let (mut tried, mut passed) = (0, 0);
    for (lo, hi) in boxes(&model, "IfcDoor") {
        let size = hi - lo;
        let (across, normal) = if size.x < size.z {
            (0, Vec2::X)
        } else {
            (2, Vec2::Y)
        };
        let mid = (lo + hi) * 0.5;
        for side in [-1.0f32, 1.0] {
            let off = normal * side * 1.0;
            let Some(w) = stand(&mut map, Vec3::new(mid.x + off.x, lo.y, mid.z + off.y)) else {
                continue;
            };
            let mut ends = [0.0f32; 2];
            for (k, open) in [false, true].into_iter().enumerate() {
                let body = Body {
                    doors_open: open,
                    ..Body::default()
                };
                let mut w = Walker::from_eye(body, &mut map, w.eye()).unwrap();
                for _ in 0..240 {
                    w.step(&mut map, -normal * side * 1.4 * DT, DT).unwrap();
                }
                ends[k] = (w.feet()[across] - mid[across]) * side;
            }
            assert!(ends[0] > 0.0, "{name}: through the closed door at {mid}");
            tried += 1;
            passed += usize::from(ends[1] < -0.5);
        }
    }
    eprintln!("{name}: {passed} of {tried} door sides passed with the doors open");
    (tried, passed)
}

#[test]
fn closed_doors_stop_the_walker_and_open_ones_are_passed() {
    for name in ["AC14-FZK-Haus.glb", "Ifc2x3_Duplex_Architecture.glb"] {
        let (tried, passed) = doors(name);
        assert!(
            tried >= 4 && passed * 2 >= tried,
            "{name}: {passed} of {tried}"
        );
    }
}

/// Straight walls: from 1 m away on a side with a floor at the wall's
/// foot, walking at them for 4 s never crosses their middle.
fn walls_stop(name: &str) {
    let (model, scene) = built(name);
    let mut map = walk_map(&scene);
    let walls = boxes(&model, "IfcWall");
    let mut tested = 0;
    for (lo, hi) in &walls {
        let size = *hi - *lo;
        // Straight along x or z: thin across, long along.
        let (across, normal) = if size.x < 0.5 && size.z > 2.0 {
            (0, Vec2::X)
        } else if size.z < 0.5 && size.x > 2.0 {
            (2, Vec2::Y)
        } else {
            continue;
        };
        let mid = (*lo + *hi) * 0.5;
        for side in [-1.0f32, 1.0] {
            let off = normal * side * 1.0;
            let Some(mut w) = stand(&mut map, Vec3::new(mid.x + off.x, lo.y, mid.z + off.y)) else {
                continue;
            };
            for _ in 0..240 {
                w.step(&mut map, -normal * side * 1.4 * DT, DT).unwrap();
            }
            let past = (w.feet()[across] - mid[across]) * side;
            assert!(
                past > 0.0,
                "{name}: through the wall at {mid} to {}",
                w.feet()
            );
            tested += 1;
        }
    }
    assert!(tested >= 4, "{name}: {tested} wall sides tried");
}

/// The search from standing places around the foot of a stair (the first
/// from which it climbs `rise`, else the last): how high it climbs and the
/// deepest fall it finds; a climb of `rise` is walked on the path found.
fn stair_search(name: &str, stair: &str, rise: f32) -> (f32, f32) {
    let (model, scene) = built(name);
    let mut map = walk_map(&scene);
    let stairs = boxes(&model, stair);
    assert!(!stairs.is_empty(), "{name}: no {stair}");
    let (lo, hi) = stairs
        .iter()
        .fold((Vec3::MAX, Vec3::MIN), |(a, b), s| (a.min(s.0), b.max(s.1)));
    let c = (lo + hi) * 0.5;
    let radius = 0.5 * (hi - lo).max_element() + 0.5;
    let starts: Vec<Walker> = (0..48)
        .flat_map(|k| {
            let t = k as f32 / 48.0 * std::f32::consts::TAU;
            [0.4f32, 0.7, 1.0]
                .map(|f| Vec3::new(c.x + t.cos() * radius * f, lo.y, c.z + t.sin() * radius * f))
        })
        .filter_map(|p| stand(&mut map, p))
        .collect();
    assert!(
        !starts.is_empty(),
        "{name}: nowhere to stand at the foot of the stair"
    );
    let margin = Vec2::splat(2.5);
    let mut found = None;
    for (k, &s) in starts.iter().enumerate() {
        let r = Reach::explore(
            &mut map,
            s,
            Vec2::new(lo.x, lo.z) - margin,
            Vec2::new(hi.x, hi.z) + margin,
            400_000,
        )
        .unwrap();
        let top = (0..r.places.len())
            .max_by(|&a, &b| {
                r.places[a]
                    .walker
                    .feet()
                    .y
                    .total_cmp(&r.places[b].walker.feet().y)
            })
            .unwrap();
        let climb = r.places[top].walker.feet().y - s.feet().y;
        let done = climb > rise || k + 1 == starts.len();
        found = Some((s, r, top, climb, k));
        if done {
            break;
        }
    }
    let (start, r, top, climb, k) = found.expect("some start");
    if climb > rise {
        let mut w = start;
        for by in r.path_to(top) {
            w.step(&mut map, by, DT).unwrap();
            assert!(w.grounded(), "{name}: the path up never leaves the ground");
        }
        assert_eq!(
            w.feet(),
            r.places[top].walker.feet(),
            "{name}: the path walks"
        );
    }
    let deepest = r
        .falls
        .iter()
        .map(|f| r.places[f.from].walker.feet().y - f.landing.feet().y)
        .fold(0.0, f32::max);
    assert!(
        r.falls.iter().all(|f| f.landing.grounded()),
        "{name}: every fall lands"
    );
    eprintln!(
        "{name}: from start {} of {}: {} places, climbed {climb:.2} m, deepest fall {deepest:.2} m, \
         {} chunk reads, {} B held",
        k + 1,
        starts.len(),
        r.places.len(),
        map.reads,
        map.resident_bytes()
    );
    (climb, deepest)
}

#[test]
fn fzk_haus_walls_stop_the_walker() {
    walls_stop("AC14-FZK-Haus.glb");
}

#[test]
fn duplex_walls_stop_the_walker() {
    walls_stop("Ifc2x3_Duplex_Architecture.glb");
}

/// The Duplex's straight flights lead to the upper storey (2.8 m up).
#[test]
fn duplex_stair_is_climbed() {
    let (climb, _) = stair_search("Ifc2x3_Duplex_Architecture.glb", "IfcStairFlight", 2.5);
    assert!(climb > 2.5, "{climb}");
}

/// The FZK-Haus spiral stair has no railing on its open side: stepping
/// off it is a fall of more than two steps, landing on the floor or
/// a lower tread. (It is not climbed to the upper storey: the slab's
/// opening covers only part of the spiral, and a 1.8 m body meets the
/// slab's underside; the search climbs 1.6 m.)
#[test]
fn fzk_haus_stair_side_is_a_fall() {
    let (climb, deepest) = stair_search("AC14-FZK-Haus.glb", "IfcStair", 2.5);
    assert!(climb > 1.0, "{climb}");
    assert!(deepest > 0.6, "{deepest}");
}

#[test]
fn the_walk_section_is_deterministic_and_copied_by_a_relayout() {
    let (_, a) = built("Ifc2x3_Duplex_Architecture.glb");
    let (_, b) = built("Ifc2x3_Duplex_Architecture.glb");
    let walk = a.read_walk_bytes().unwrap();
    assert!(!walk.is_empty());
    assert_eq!(walk, b.read_walk_bytes().unwrap());
    let out = hlod_builder::layout::relayout(
        &a,
        std::io::Cursor::new(Vec::new()),
        hlod_builder::layout::Payloads::Keep,
    )
    .unwrap();
    let c = SceneFile::from_source(MemSource::new(out.into_inner())).unwrap();
    assert_eq!(c.read_walk_bytes().unwrap(), walk);
}

#[test]
fn the_walk_section_is_the_same_made_in_bands_under_a_small_heap() {
    let model = load(&data("schependomlaan_subcontractors.glb")).unwrap();
    let all = |_: &hlod_builder::import::Instance| true;
    // The smallest of these heaps under which it can be made (in bands).
    let (banded, b) = [1u64, 2, 3, 4, 6]
        .iter()
        .find_map(|m| hlod_builder::walkmap::walk_section(&model, 0.1, &all, m << 20).ok())
        .unwrap();
    let (whole, a) = hlod_builder::walkmap::walk_section(&model, 0.1, &all, u64::MAX).unwrap();
    assert!(whole.len() > 10_000);
    assert_eq!(whole, banded);
    assert_eq!((a.cells, a.bytes), (b.cells, b.bytes), "{a:?}");
    assert!(b.bands > a.bands, "{a:?} {b:?}");
    let e = hlod_builder::walkmap::walk_section(&model, 0.1, &all, 1_000).unwrap_err();
    assert!(e.to_string().contains("--walk-cell 0"), "{e}");
}

/// Generated walks on the walk section (`--path-kind walk`): on the
/// Duplex, the FZK-Haus and the Schependomlaan every pose's eye stands
/// 1.6 m over a floor with nothing inside the body, consecutive poses are
/// a step apart (nothing is passed between), and every storey reported is
/// walked on (the Duplex's two; three of the Schependomlaan's four in
/// 72 m of walking).
#[test]
fn generated_walks_stay_at_eye_height_and_reach_every_storey() {
    for (name, storeys) in [
        ("Ifc2x3_Duplex_Architecture.glb", 2),
        ("AC14-FZK-Haus.glb", 1),
        ("schependomlaan_subcontractors.glb", 3),
    ] {
        let (_, scene) = built(name);
        let mut map = walk_map(&scene);
        let r = &scene.skeleton().nodes[0];
        let bounds = (
            Vec2::new(r.bbox_min[0], r.bbox_min[2]),
            Vec2::new(r.bbox_max[0], r.bbox_max[2]),
        );
        let t = engine::walk::tour(&mut map, bounds, 1800, 0.04, 1).unwrap();
        assert_eq!(t.poses.len(), 1800);
        assert!(
            t.storeys.len() >= storeys,
            "{name}: storeys {:?}",
            t.storeys
        );
        let body = Body {
            doors_open: true,
            ..Body::default()
        };
        let mut visited = vec![false; t.storeys.len()];
        for (k, p) in t.poses.iter().enumerate() {
            let w = Walker::from_eye(body, &mut map, p.position).unwrap();
            assert!(w.grounded(), "{name}: pose {k} over no floor");
            assert!(!w.stuck(&mut map).unwrap(), "{name}: pose {k} inside solid");
            assert!(
                (w.eye().y - p.position.y).abs() < 0.2,
                "{name}: pose {k} not at eye height"
            );
            if k > 0 {
                let d = p.position - t.poses[k - 1].position;
                assert!(
                    Vec2::new(d.x, d.z).length() <= 0.0401,
                    "{name}: pose {k} jumps"
                );
            }
            for (s, level) in t.storeys.iter().enumerate() {
                visited[s] |= (w.feet().y - level).abs() < 0.15;
            }
        }
        assert!(
            visited.iter().all(|v| *v),
            "{name}: storeys {:?} visited {visited:?}",
            t.storeys
        );
        eprintln!("{name}: storeys {:?}, {} places", t.storeys, t.places);
    }
}

/// The Schependomlaan's walls were exported whole behind their door
/// openings: the build cuts the openings' voids out of them, so every door
/// hole is open at 1 m (with the doors open).
#[test]
fn door_openings_are_cut_out_of_whole_walls() {
    let (model, scene) = built("schependomlaan_subcontractors.glb");
    let mut map = walk_map(&scene);
    let g = map.grid();
    let doors = boxes(&model, "IfcDoor");
    let holes: Vec<(Vec3, Vec3)> = boxes(&model, "IfcOpeningElement")
        .into_iter()
        .filter(|(lo, hi)| {
            doors
                .iter()
                .any(|(a, b)| a.cmplt(*hi).all() && lo.cmplt(*b).all())
        })
        .collect();
    let solid = holes
        .iter()
        .filter(|(lo, hi)| {
            let c = (*lo + *hi) * 0.5;
            let y = lo.y + 1.0;
            let col = map.column(g.cell_of(c.x), g.cell_of(c.z)).unwrap();
            col.solid
                .iter()
                .any(|s| g.height(s.lo) < y && g.height(s.hi) > y)
        })
        .count();
    assert!(holes.len() >= 20, "{} door openings", holes.len());
    assert_eq!(solid, 0, "of {} door openings", holes.len());
}

/// A CAD part in millimetres (the 2CylinderEngine: 743 units across, 121,000
/// triangles) gets a coarser grid than the 0.1 unit asked for (at most a
/// million cells, or 8 per triangle) instead of a section 20 times larger
/// than its geometry; the buildings keep their 0.1 m.
#[test]
fn a_model_in_millimetres_gets_a_coarser_walk_grid() {
    let stats = |name: &str| {
        let model = load(&data(name)).unwrap();
        let mut out = std::io::Cursor::new(Vec::new());
        let s = build_scene(&model, &mut out, &BuildParams::default(), false).unwrap();
        (s.walk, out.into_inner().len() as u64)
    };
    let (w, file) = stats("2CylinderEngine/2CylinderEngine.gltf");
    assert!(w.cell >= 0.4, "{w:?}");
    // 41 MiB at 0.1 units (the file 2.2 MiB without it): now smaller than
    // the rest of the file.
    assert!(
        w.bytes * 2 < file + w.bytes,
        "{w:?} in a file of {file} bytes"
    );
    for house in ["AC14-FZK-Haus.glb", "Ifc2x3_Duplex_Architecture.glb"] {
        let (w, _) = stats(house);
        assert!((w.cell - 0.1).abs() < 1e-6, "{house}: {w:?}");
    }
}
