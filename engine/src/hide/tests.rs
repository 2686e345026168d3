use super::*;
use crate::format::SceneFile;
use crate::format::objects::Run;
use crate::io::MemSource;
use crate::testutil::build_with;

/// A root over two groups of two leaves (nodes 3–6); leaf `k` names
/// object `k` unless it is merged (then `runs` describe it).
fn scene(merged: &[(u32, Vec<Run>)], objects: usize) -> (Skeleton, ObjectTable) {
    let infos: Vec<String> = (0..objects)
        .map(|k| format!("{{\"name\":\"o{k}\"}}"))
        .collect();
    let (bytes, _) = build_with(
        &[1, 1, 1, 2, 2, 2, 2],
        &[2, 2, 2, 0, 0, 0, 0],
        [0.0; 3],
        &ObjectTable::encode(&infos, &[]),
    );
    let file = SceneFile::from_source(MemSource::new(bytes)).unwrap();
    let mut s = file.skeleton().clone();
    for (node, _) in merged {
        s.nodes[*node as usize].object = NONE;
    }
    let table = ObjectTable::decode(&ObjectTable::encode(&infos, merged), &s).unwrap();
    (s, table)
}

#[test]
fn hidden_leaves_leave_and_their_ancestors_go_mixed() {
    let (s, t) = scene(&[], 4);
    // Objects follow the leaves: leaf node 3 + k names object k.
    let obj = |n: usize| s.nodes[n].object;
    assert_eq!((obj(3), obj(6)), (0, 3));
    let h = Hiding::new(&s, &t, |k| k == obj(3));
    use NodeVis::*;
    assert_eq!(
        h.nodes(),
        [Mixed, Mixed, Shown, Hidden, Shown, Shown, Shown]
    );
    assert_eq!(h.hidden_objects(), 1);
    // A whole group hidden: the group leaves too.
    let h = Hiding::new(&s, &t, |k| k == obj(3) || k == obj(4));
    assert_eq!(h.nodes()[1], Hidden);
    assert_eq!(h.nodes()[0], Mixed);
    // Everything hidden; nothing hidden.
    assert!(
        Hiding::new(&s, &t, |_| true)
            .nodes()
            .iter()
            .all(|v| *v == Hidden)
    );
    assert_eq!(Hiding::new(&s, &t, |_| false), Hiding::none(7));
}

/// Leaf 3's runs when it merges objects 0 and 1, a triangle each.
fn two_runs() -> Vec<Run> {
    [(0, 1), (1, 2)]
        .map(|(object, tri_end)| Run { object, tri_end })
        .to_vec()
}

#[test]
fn a_merged_leaf_in_part_hidden_draws_the_shown_runs_of_its_finest_rep() {
    // Leaf 3 merges objects 0, 1, 0 (triangles 0..1, 1..2 of its quad).
    let (s, t) = scene(&[(3, two_runs())], 4);
    let h = Hiding::new(&s, &t, |k| k == 1);
    assert_eq!(h.nodes()[3], NodeVis::Mixed);
    let finest = s.nodes[3].first_rep + s.nodes[3].rep_count - 1;
    let shown: Vec<std::ops::Range<u32>> = std::iter::once(0..1).collect();
    assert_eq!(h.parts().opaque, [(finest, shown)]);
    // Both of its objects hidden: the leaf leaves.
    let h = Hiding::new(&s, &t, |k| k <= 1);
    assert_eq!(h.nodes()[3], NodeVis::Hidden);
    assert!(h.parts().opaque.is_empty());
}

#[test]
fn xrayed_nodes_stay_in_the_front_drawn_translucent_and_mixed_ones_split() {
    use crate::tree::Look;
    let (s, t) = scene(&[(3, two_runs())], 4);
    let obj = |n: usize| s.nodes[n].object;
    // Leaf 3 merges objects 0 (shown) and 1 (x-rayed), which leaf 4 also
    // names; leaf 5's object is x-rayed, leaf 6's hidden.
    let h = Hiding::with_looks(&s, &t, |k| {
        if k == 1 || k == obj(5) {
            Look::XRay
        } else if k == obj(6) {
            Look::Hidden
        } else {
            Look::Shown
        }
    });
    use NodeVis::*;
    assert_eq!(h.nodes(), [Mixed, Mixed, Mixed, Mixed, XRay, XRay, Hidden]);
    assert_eq!((h.hidden_objects(), h.xray_objects()), (1, 2));
    let finest = |n: usize| s.nodes[n].first_rep + s.nodes[n].rep_count - 1;
    let reps = |n: usize| s.nodes[n].first_rep..s.nodes[n].first_rep + s.nodes[n].rep_count;
    // The merged leaf: its shown run opaque, its x-rayed run translucent.
    let mut opaque = vec![(finest(3), std::iter::once(0..1).collect::<Vec<_>>())];
    let mut xray = vec![(finest(3), std::iter::once(1..2).collect::<Vec<_>>())];
    // Every rep of the x-rayed leaves: nothing opaque, all of it x-rayed.
    for r in reps(4).chain(reps(5)) {
        opaque.push((r, vec![]));
        xray.push((r, vec![WHOLE]));
    }
    opaque.sort_by_key(|(r, _)| *r);
    xray.sort_by_key(|(r, _)| *r);
    assert_eq!(h.parts().opaque, opaque);
    assert_eq!(h.parts().xray, xray);
    // A group whose leaves are all x-rayed is x-rayed: its HLOD is drawn
    // translucent.
    let h = Hiding::with_looks(&s, &t, |k| {
        if k == obj(5) || k == obj(6) {
            Look::XRay
        } else {
            Look::Shown
        }
    });
    assert_eq!(h.nodes()[2], XRay);
    for r in reps(2) {
        assert!(h.parts().xray.iter().any(|(x, v)| *x == r && *v == [WHOLE]));
    }
}
