use super::*;
use crate::testutil::build;

/// A (1 HLOD) with children B (2 LODs) and C (3 LODs): the paper's Fig. 1 shape.
fn fig1() -> Skeleton {
    build(&[1, 2, 3], &[2, 0, 0]).1
}

#[test]
fn par_chd_asc_dsc_follow_section_3_1() {
    let s = fig1();
    // reps: A[0]=0, B[0]=1, B[1]=2, C[0]=3, C[1]=4, C[2]=5
    assert_eq!(s.par(0), None);
    assert_eq!(s.par(1), Some(0));
    assert_eq!(s.par(2), Some(1));
    assert_eq!(s.par(3), Some(0));
    assert_eq!(s.chd(0), vec![1, 3]);
    assert_eq!(s.chd(1), vec![2]);
    assert_eq!(s.chd(2), Vec::<u32>::new());
    assert_eq!(s.asc(5, 2), Some(3));
    assert_eq!(s.asc(5, 3), Some(0));
    assert_eq!(s.asc(5, 4), None);
    assert_eq!(s.dsc(0, 1), vec![1, 3]);
    assert_eq!(s.dsc(0, 2), vec![2, 4]);
    assert_eq!(s.height(), 2);
    s.validate(4096, u64::MAX).unwrap();
}

#[test]
fn repless_interior_nodes_are_transparent() {
    // root(1) -> mid(0 reps) -> two leaves(1 each)
    let s = build(&[1, 0, 1, 1], &[1, 2, 0, 0]).1;
    assert_eq!(s.chd(0), vec![1, 2]);
    assert_eq!(s.par(2), Some(0));
    s.validate(4096, u64::MAX).unwrap();
}

#[test]
fn validate_rejects_broken_hierarchies() {
    let good = fig1();
    let check = |f: &dyn Fn(&mut Skeleton)| {
        let mut s = good.clone();
        f(&mut s);
        s.validate(4096, u64::MAX).unwrap_err()
    };
    assert!(matches!(
        check(&|s| s.reps[2].error = s.reps[1].error),
        ValidationError::ErrorOrder { .. }
    ));
    assert!(matches!(
        check(&|s| s.reps[3].error = s.reps[0].error + 1.0),
        ValidationError::ErrorOrder { .. }
    ));
    assert!(matches!(
        check(&|s| s.nodes[1].bbox_max[0] += 5.0),
        ValidationError::BoxNotContained { .. }
    ));
    assert!(matches!(
        check(&|s| s.reps[4].bbox_min[1] = -3.0),
        ValidationError::BoxNotContained { .. }
    ));
    assert!(matches!(
        check(&|s| s.reps[1].offset += 1),
        ValidationError::Rep { .. }
    ));
    assert!(matches!(
        check(&|s| s.reps[1].offset = s.reps[2].offset),
        ValidationError::Overlap { .. }
    ));
    assert!(matches!(
        check(&|s| s.reps[1].error = f32::NAN),
        ValidationError::Rep { .. }
    ));
    assert!(matches!(
        check(&|s| s.reps[1].kind = 1),
        ValidationError::Rep { .. }
    ));
    assert!(matches!(
        check(&|s| s.nodes[2].parent = 2),
        ValidationError::Node { .. }
    ));
    assert!(matches!(
        check(&|s| s.nodes[0].child_count = 1),
        ValidationError::Node { .. }
    ));
    assert!(matches!(
        check(&|s| s.nodes[1].rep_count = 0),
        ValidationError::Node { .. }
    ));
    // A mesh rep stores at most its raw length (less when compressed), and
    // at least a payload header.
    assert!(matches!(
        check(&|s| s.reps[5].tri_count -= 1),
        ValidationError::Rep { .. }
    ));
    assert!(matches!(
        check(&|s| s.reps[5].len = 47),
        ValidationError::Rep { .. }
    ));
    let mut shorter = good.clone();
    shorter.reps[5].len -= 16;
    shorter.validate(4096, u64::MAX).unwrap();
    assert_eq!(
        Skeleton::default().validate(0, 0).unwrap_err(),
        ValidationError::Empty
    );
    let s = good.clone();
    assert!(s.validate(4096, 4200).is_err(), "ranges past the data end");
}

#[test]
fn shared_payloads_validate_and_are_counted_once() {
    // A root over four leaves of two levels, every leaf's levels shared.
    let (bytes, s) = crate::testutil::build_instanced(&[1, 2, 2, 2, 2], &[4, 0, 0, 0, 0]);
    let (_, plain) = build(&[1, 2, 2, 2, 2], &[4, 0, 0, 0, 0]);
    s.validate(4096, bytes.len() as u64).unwrap();
    assert_eq!(s.placements.len(), 8);
    assert_eq!(s.payloads_in_file_order().len(), 3);
    assert_eq!(s.payload_rep(7), s.payload_rep(1));
    assert!(s.owns_payload(1) && !s.owns_payload(7) && s.owns_payload(0));
    let leaf = plain.reps[1].expanded_extent();
    assert_eq!(s.in_core_bytes() + 6 * leaf, plain.in_core_bytes());
    // Read back as a placed mesh, a rep lies where its box says.
    let file = crate::format::SceneFile::from_source(crate::io::MemSource::new(bytes)).unwrap();
    assert_eq!(file.skeleton(), &s);
    let m = file.read_rep(8).unwrap();
    let rec = &s.reps[8];
    for v in &m.vertices {
        let p = m.position(v);
        assert!((0..3).all(|a| p[a] >= rec.bbox_min[a] - 1e-4 && p[a] <= rec.bbox_max[a] + 1e-4));
    }
}

#[test]
fn validate_rejects_broken_placements() {
    let (_, good) = crate::testutil::build_instanced(&[1, 2, 2], &[2, 0, 0]);
    let check = |f: &dyn Fn(&mut Skeleton)| {
        let mut s = good.clone();
        f(&mut s);
        s.validate(4096, u64::MAX).unwrap_err()
    };
    let placement = |e: ValidationError| matches!(e, ValidationError::Placement { .. });
    // A payload of another rep's range or counts.
    assert!(placement(check(&|s| s.reps[3].tri_count += 1)));
    assert!(placement(check(&|s| s.placements[2].source = 2)));
    // Out of range, out of order, not finite.
    assert!(placement(check(&|s| s.placements[3].rep = 99)));
    assert!(placement(check(&|s| s.placements.swap(0, 1))));
    assert!(placement(check(
        &|s| s.placements[1].transform[0][3] = f32::NAN
    )));
    // A source that does not own its payload.
    assert!(placement(check(&|s| {
        s.placements.remove(0);
    })));
    // Two payloads that overlap still do, placed or not.
    assert!(matches!(
        check(&|s| {
            for r in [1, 3] {
                s.reps[r].offset = s.reps[2].offset;
            }
        }),
        ValidationError::Overlap { .. } | ValidationError::Placement { .. }
    ));
}

#[test]
fn a_placement_carries_points_and_normals() {
    use crate::records::RepPlacement;
    // A quarter turn about z, scaled by 2 along x, mirrored in z, moved.
    let p = RepPlacement {
        rep: 0,
        source: 0,
        transform: [
            [0.0, -1.0, 0.0, 5.0],
            [2.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, -1.0, 1.0],
        ],
    };
    assert_eq!(p.point([1.0, 0.0, 0.0]), [5.0, 2.0, 1.0]);
    assert_eq!(p.point([0.0, 1.0, 1.0]), [4.0, 0.0, 0.0]);
    // A normal stays perpendicular to the transformed surface: the plane
    // x + y = 0 has normal (1, 1, 0); its points (1, -1, 0), (0, 0, 1).
    let n = p.normal([1.0, 1.0, 0.0]);
    let a = p.point([1.0, -1.0, 0.0]);
    let b = p.point([0.0, 0.0, 0.0]);
    let c = p.point([0.0, 0.0, 1.0]);
    let dot = |u: [f32; 3], v: [f32; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let sub = |u: [f32; 3], v: [f32; 3]| [u[0] - v[0], u[1] - v[1], u[2] - v[2]];
    assert!(dot(n, sub(a, b)).abs() < 1e-6 && dot(n, sub(c, b)).abs() < 1e-6);
    assert!((dot(n, n) - 1.0).abs() < 1e-6);
    // Outward stays outward under the mirror: the transformed normal points
    // the way the transformed offset along it does.
    let out = sub(p.point([1.0, 1.0, 0.0]), b);
    assert!(dot(n, out) > 0.0);
}
