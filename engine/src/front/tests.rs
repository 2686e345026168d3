use super::*;
use crate::camera::Pose;
use crate::format::{NONE, NodeRecord, RepKind, RepRecord};

/// A row of `n` leaves along +x under one root; leaf k spans x in [2k, 2k+1];
/// each leaf has LOD errors 1.0, 0.1, 0.01; the root one HLOD of error 10.
fn row(n: u32) -> Skeleton {
    let mut nodes = vec![NodeRecord {
        parent: NONE,
        first_child: 1,
        child_count: n,
        first_rep: 0,
        rep_count: 1,
        bbox_min: [0.0, 0.0, 0.0],
        bbox_max: [2.0 * n as f32, 1.0, 1.0],
        ..Default::default()
    }];
    let mut reps = vec![RepRecord {
        node: 0,
        kind: RepKind::Hlod as u16,
        error: 10.0,
        ..Default::default()
    }];
    for k in 0..n {
        nodes.push(NodeRecord {
            parent: 0,
            depth: 1,
            first_rep: 1 + 3 * k,
            rep_count: 3,
            bbox_min: [2.0 * k as f32, 0.0, 0.0],
            bbox_max: [2.0 * k as f32 + 1.0, 1.0, 1.0],
            ..Default::default()
        });
        for (i, e) in [1.0, 0.1, 0.01].into_iter().enumerate() {
            reps.push(RepRecord {
                node: k + 1,
                index: i as u16,
                error: e,
                ..Default::default()
            });
        }
    }
    Skeleton {
        nodes,
        reps,
        ..Skeleton::default()
    }
}

fn view_from(eye: Vec3, target: Vec3) -> View {
    View {
        pose: Pose::look_at(eye, target, 60.0),
        width_px: 800,
        height_px: 600,
        near: 0.01,
        far: 1e4,
        section: crate::section::Section::NONE,
    }
}

#[test]
fn far_away_takes_the_root_hlod_close_up_refines_and_culls() {
    let s = row(8);
    let idx = FrontIndex::new(&s);
    let mut front = Vec::new();
    let far = view_from(Vec3::new(8.0, 0.5, 1e4 * 0.9), Vec3::new(8.0, 0.5, 0.5));
    idx.compute(&far, &far.frustum(0.0), 1.0, &mut front);
    assert_eq!(front, vec![0], "the whole row is one HLOD from far away");

    // Close to leaf 0, looking along +x: leaf 0 needs its finest rep, leaves
    // further along coarser ones; looking away culls everything.
    let near = view_from(Vec3::new(-0.5, 0.5, 0.5), Vec3::new(20.0, 0.5, 0.5));
    idx.compute(&near, &near.frustum(0.0), 5.0, &mut front);
    assert_eq!(front.len(), 8);
    assert_eq!(front[0], 3, "leaf 0 finest");
    let last = *front.last().unwrap();
    assert_eq!(
        last,
        1 + 3 * 7 + 1,
        "the last leaf, 14.5 away, takes its middle LOD"
    );
    let away = view_from(Vec3::new(-0.5, 0.5, 0.5), Vec3::new(-20.0, 0.5, 0.5));
    idx.compute(&away, &away.frustum(0.0), 1.0, &mut front);
    assert!(front.is_empty());
}

#[test]
fn the_chosen_rep_is_the_coarsest_below_tolerance() {
    let s = row(4);
    let idx = FrontIndex::new(&s);
    let mut front = Vec::new();
    for d in [3.0f32, 30.0, 300.0, 3000.0] {
        let v = view_from(Vec3::new(4.0, 0.5, d), Vec3::new(4.0, 0.5, 0.0));
        idx.compute(&v, &v.frustum(0.0), 2.0, &mut front);
        for &r in &front {
            let node = s.reps[r as usize].node;
            let eps = idx.projected_error(&v, node, r);
            let n = &s.nodes[node as usize];
            let finest = r == n.first_rep + n.rep_count - 1;
            assert!(
                eps < 2.0 || (n.is_leaf() && finest),
                "rep {r} at distance {d}: {eps} px"
            );
            if r > n.first_rep {
                assert!(
                    idx.projected_error(&v, node, r - 1) >= 2.0,
                    "a coarser rep would do"
                );
            }
        }
    }
}

mod properties {
    use super::*;
    use crate::testutil::build;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn the_front_is_a_visible_cut_of_coarsest_qualifying_reps(
            (reps, children) in crate::testutil::shape_strategy(60),
            eye in (-5.0f32..40.0, -3.0f32..6.0, -10.0f32..10.0),
            yaw in -3.2f32..3.2,
            tol in 0.5f32..20.0,
        ) {
            let s = build(&reps, &children).1;
            let idx = FrontIndex::new(&s);
            let v = View {
                pose: Pose::from_yaw_pitch(Vec3::new(eye.0, eye.1, eye.2), yaw, 0.0, 60.0),
                width_px: 640,
                height_px: 480,
                near: 0.01,
                far: 1e4,
                section: crate::section::Section::NONE,
            };
            let f = v.frustum(0.0);
            let mut front = Vec::new();
            idx.compute(&v, &f, tol, &mut front);
            let mut in_front = vec![false; s.nodes.len()];
            for &r in &front {
                let rec = &s.reps[r as usize];
                let node = rec.node;
                let n = &s.nodes[node as usize];
                prop_assert!(!in_front[node as usize], "one rep per node");
                in_front[node as usize] = true;
                let (mn, mx) = idx.node_box(node);
                prop_assert!(f.intersects(mn, mx));
                let eps = idx.projected_error(&v, node, r);
                let finest = r == n.first_rep + n.rep_count - 1;
                prop_assert!(eps < tol || (n.is_leaf() && finest));
                if r > n.first_rep {
                    prop_assert!(idx.projected_error(&v, node, r - 1) >= tol, "a coarser rep qualifies");
                }
                // Every ancestor was refined because none of its reps qualified.
                let mut up = n.parent;
                while up != crate::format::NONE {
                    let a = &s.nodes[up as usize];
                    prop_assert!(!in_front[up as usize], "front reps on one root path");
                    for ar in a.first_rep..a.first_rep + a.rep_count {
                        prop_assert!(idx.projected_error(&v, up, ar) >= tol);
                    }
                    up = a.parent;
                }
            }
        }
    }
}

#[test]
fn restricting_the_all_around_front_to_a_frustum_computes_its_front() {
    let s = row(40);
    let index = FrontIndex::new(&s);
    for (eye, target) in [
        (Vec3::new(-5.0, 3.0, 0.5), Vec3::new(40.0, 0.0, 0.5)),
        (Vec3::new(30.0, 0.5, 3.0), Vec3::new(10.0, 0.5, 0.0)),
        (Vec3::new(41.0, 0.5, 0.5), Vec3::new(80.0, 0.5, 0.5)),
    ] {
        let view = view_from(eye, target);
        let mut all = Vec::new();
        let around = Frustum::all_around(eye, view.pose.forward());
        index.compute(&view, &around, 0.5, &mut all);
        for margin in [0.0, 0.4, 1.2] {
            let f = view.frustum(margin);
            let (mut direct, mut restricted) = (Vec::new(), all.clone());
            index.compute(&view, &f, 0.5, &mut direct);
            index.restrict(&s, &f, &mut restricted);
            assert_eq!(restricted, direct, "eye {eye}, margin {margin}");
        }
    }
}
