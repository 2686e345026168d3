use super::*;

/// An axis-aligned box as 12 triangles.
fn cuboid(min: Vec3, max: Vec3, out: &mut Vec<[Vec3; 3]>) {
    let c = |i: u32| {
        Vec3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        )
    };
    // Faces as quads of corner numbers, wound outwards.
    for q in [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ] {
        out.push([c(q[0]), c(q[1]), c(q[2])]);
        out.push([c(q[0]), c(q[2]), c(q[3])]);
    }
}

/// Two rooms of 6 x 6 m side by side along x, a wall between them with a
/// 1 m door, under a roof slab; `storeys` such floors stacked 3 m apart.
fn house(storeys: u32) -> Vec<[Vec3; 3]> {
    let mut t = Vec::new();
    for s in 0..storeys {
        let y = 3.0 * s as f32;
        cuboid(
            Vec3::new(0.0, y - 0.2, 0.0),
            Vec3::new(12.0, y, 6.0),
            &mut t,
        );
        cuboid(
            Vec3::new(0.0, y + 2.8, 0.0),
            Vec3::new(12.0, y + 3.0, 6.0),
            &mut t,
        );
        // Outer walls.
        cuboid(
            Vec3::new(-0.2, y, 0.0),
            Vec3::new(0.0, y + 2.8, 6.0),
            &mut t,
        );
        cuboid(
            Vec3::new(12.0, y, 0.0),
            Vec3::new(12.2, y + 2.8, 6.0),
            &mut t,
        );
        cuboid(
            Vec3::new(0.0, y, -0.2),
            Vec3::new(12.0, y + 2.8, 0.0),
            &mut t,
        );
        cuboid(
            Vec3::new(0.0, y, 6.0),
            Vec3::new(12.0, y + 2.8, 6.2),
            &mut t,
        );
        // The middle wall, its door from z = 2.5 to 3.5.
        cuboid(Vec3::new(5.9, y, 0.0), Vec3::new(6.1, y + 2.8, 2.5), &mut t);
        cuboid(Vec3::new(5.9, y, 3.5), Vec3::new(6.1, y + 2.8, 6.0), &mut t);
    }
    t
}

#[test]
fn the_walk_stays_indoors_at_eye_height_and_goes_through_the_door() {
    let tris = house(1);
    let p = InteriorParams::default();
    let path = interior_path(&tris, 2000, &p).unwrap();
    assert_eq!(path.poses.len(), 2000);
    assert_eq!(path.storeys.len(), 1);
    assert!((path.storeys[0] - 0.0).abs() < 0.1, "{:?}", path.storeys);
    let (mut left, mut right) = (false, false);
    for q in &path.poses {
        let e = q.position;
        assert!((e.y - 1.6).abs() < 0.15, "eye at {e}");
        assert!(
            e.x > 0.0 && e.x < 12.0 && e.z > 0.0 && e.z < 6.0,
            "outside at {e}"
        );
        // Never inside the middle wall except through the door.
        if e.x > 5.9 && e.x < 6.1 {
            assert!(e.z > 2.5 && e.z < 3.5, "through the wall at {e}");
        }
        left |= e.x < 5.0;
        right |= e.x > 7.0;
    }
    assert!(left && right, "both rooms are visited");
    // Deterministic, and another seed walks elsewhere.
    assert_eq!(interior_path(&tris, 2000, &p).unwrap(), path);
    let other = interior_path(&tris, 2000, &InteriorParams { seed: 9, ..p }).unwrap();
    assert_ne!(other.poses, path.poses);
}

#[test]
fn every_storey_is_walked() {
    let tris = house(3);
    let path = interior_path(&tris, 3000, &InteriorParams::default()).unwrap();
    assert_eq!(path.storeys.len(), 3, "{:?}", path.storeys);
    for (k, y) in [0.0, 3.0, 6.0].iter().enumerate() {
        assert!(
            path.poses
                .iter()
                .any(|q| (q.position.y - (y + 1.6)).abs() < 0.15),
            "storey {k}"
        );
    }
    // No stairwell in this house: each move up is a jump.
    assert_eq!(path.jumps, 2);
}

#[test]
fn a_scene_without_floors_or_rooms_is_refused() {
    let mut t = Vec::new();
    cuboid(Vec3::ZERO, Vec3::ONE, &mut t);
    // A cube has an up-facing top but no indoor space to stand in.
    assert_eq!(
        interior_path(&t, 10, &InteriorParams::default()),
        Err(InteriorError::NoFreeSpace)
    );
    let wall = vec![[Vec3::ZERO, Vec3::X, Vec3::Y]];
    assert_eq!(
        interior_path(&wall, 10, &InteriorParams::default()),
        Err(InteriorError::NoFloors)
    );
}

/// Two storeys 3 m apart (rooms as in [`house`]) joined by a straight
/// flight of 15 solid steps (0.25 m deep, 0.2 m high, 1 m wide) along x
/// in the first room, under an opening in the slab between them.
fn house_with_stair() -> Vec<[Vec3; 3]> {
    let mut t = Vec::new();
    for s in 0..2 {
        let y = 3.0 * s as f32;
        // Walls as in `house`.
        for (a, b) in [
            (Vec3::new(-0.2, y, 0.0), Vec3::new(0.0, y + 2.8, 6.0)),
            (Vec3::new(12.0, y, 0.0), Vec3::new(12.2, y + 2.8, 6.0)),
            (Vec3::new(0.0, y, -0.2), Vec3::new(12.0, y + 2.8, 0.0)),
            (Vec3::new(0.0, y, 6.0), Vec3::new(12.0, y + 2.8, 6.2)),
            (Vec3::new(5.9, y, 0.0), Vec3::new(6.1, y + 2.8, 2.5)),
            (Vec3::new(5.9, y, 3.5), Vec3::new(6.1, y + 2.8, 6.0)),
        ] {
            cuboid(a, b, &mut t);
        }
    }
    // The ground slab and the roof, whole.
    cuboid(Vec3::new(0.0, -0.2, 0.0), Vec3::new(12.0, 0.0, 6.0), &mut t);
    cuboid(Vec3::new(0.0, 5.8, 0.0), Vec3::new(12.0, 6.0, 6.0), &mut t);
    // The slab between, around the opening x 1..4.75, z 0.5..1.5.
    for (a, b) in [
        (Vec3::new(0.0, 2.8, 1.5), Vec3::new(12.0, 3.0, 6.0)),
        (Vec3::new(0.0, 2.8, 0.0), Vec3::new(12.0, 3.0, 0.5)),
        (Vec3::new(0.0, 2.8, 0.5), Vec3::new(1.0, 3.0, 1.5)),
        (Vec3::new(4.75, 2.8, 0.5), Vec3::new(12.0, 3.0, 1.5)),
    ] {
        cuboid(a, b, &mut t);
    }
    for i in 0..15 {
        let x = 1.0 + 0.25 * i as f32;
        cuboid(
            Vec3::new(x, 0.0, 0.5),
            Vec3::new(x + 0.25, 0.2 * (i + 1) as f32, 1.5),
            &mut t,
        );
    }
    t
}

#[test]
fn the_walk_climbs_the_stair_step_by_step() {
    let tris = house_with_stair();
    let path = interior_path(&tris, 3000, &InteriorParams::default()).unwrap();
    assert_eq!(path.storeys.len(), 2, "{:?}", path.storeys);
    assert_eq!((path.climbs, path.jumps), (1, 0));
    let eye = 1.6;
    let mut on_flight = 0;
    for w in path.poses.windows(2) {
        let (a, b) = (w[0].position, w[1].position);
        // No jump: at most a riser over a tread's depth, per step walked.
        assert!((b.y - a.y).abs() < 0.1, "{a} -> {b}");
    }
    for q in &path.poses {
        let e = q.position;
        if (1.0..4.75).contains(&e.x) && (0.55..1.45).contains(&e.z) {
            on_flight += 1;
            // Feet on the step under the eye (its cell may hold the next
            // one too; the storeys' floors are found within 0.25 m), never
            // inside it, nor above the flight at the upper floor's height.
            let step = ((e.x - 1.0) / 0.25).floor();
            let top = 0.2 * (step + 1.0);
            let feet = e.y - eye;
            assert!(
                feet > top - 0.25 && feet < top + 0.5,
                "feet {feet} over step top {top} at {e}"
            );
        }
    }
    assert!(
        on_flight > 10,
        "the walk goes up the flight ({on_flight} poses on it)"
    );
    assert!(
        path.poses
            .iter()
            .any(|q| (q.position.y - (3.0 + eye)).abs() < 0.15)
    );
    // Deterministic.
    assert_eq!(
        interior_path(&tris, 3000, &InteriorParams::default()).unwrap(),
        path
    );
}

#[test]
fn openings_spaces_and_doors_are_walked_through() {
    for (info, through) in [
        (r#"{"name":"IfcDoor:Single-Flush:1234"}"#, true),
        (r#"{"mesh":3,"name":"IfcOpeningElement::0ONCKt8ie"}"#, true),
        (r#"{"name":"IfcSpace:Kitchen"}"#, true),
        (r#"{"name":"IfcDoorStyle"}"#, false),
        (r#"{"name":"IfcWall:Basic:200"}"#, false),
        (r#"{"mesh_name":"IfcDoor:x","name":"IfcWindow:y"}"#, false),
        ("not json", false),
        ("{}", false),
    ] {
        assert_eq!(walk_through(info), through, "{info}");
    }
}

#[test]
fn a_walk_starts_in_the_stair_hall_when_the_largest_room_has_no_stair() {
    // The ground floor of `house_with_stair` cut in two with no door: a
    // stair hall (x < 4.9, the flight in it) and a larger room without a
    // stair. The walk starts in the hall and climbs instead of jumping.
    let mut tris = house_with_stair();
    cuboid(
        Vec3::new(4.9, 0.0, 0.0),
        Vec3::new(5.1, 2.8, 6.0),
        &mut tris,
    );
    cuboid(
        Vec3::new(5.9, 0.0, 2.5),
        Vec3::new(6.1, 2.8, 3.5),
        &mut tris,
    );
    let path = interior_path(&tris, 3000, &InteriorParams::default()).unwrap();
    assert_eq!((path.climbs, path.jumps), (1, 0));
    let hall = path.cells[0];
    // The hall is 4.9 x 6 m less its walls: under 470 cells of 0.25 m.
    assert!(hall < 470, "walked {hall} cells on the ground floor");
    let ground = |q: &Pose| q.position.y < 1.7;
    assert!(
        path.poses
            .iter()
            .filter(|q| ground(q))
            .all(|q| q.position.x < 4.9),
        "the ground-floor walk stays in the hall"
    );
    for w in path.poses.windows(2) {
        assert!((w[1].position.y - w[0].position.y).abs() < 0.1);
    }
}
