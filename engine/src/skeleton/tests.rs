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
