use super::*;

/// Rep 0 is the root; 1 and 2 its children; 3 and 4 the children of 1.
const PAR: [Option<RepId>; 5] = [None, Some(0), Some(0), Some(1), Some(1)];

fn par(r: RepId) -> Option<RepId> {
    PAR[r as usize]
}

/// One frame: plan, draw what P_I hands over (all fading-out reps when
/// `resident`), draw the front, end; the fades drawn.
fn frame(f: &mut Fades, now: f64, front: &[RepId], resident: bool) -> Vec<(RepId, Fade)> {
    let outs = f.plan(now, front, par, |_| true);
    let mut drawn = Vec::new();
    if resident {
        for r in outs {
            if let Some(x) = f.fade_out(r) {
                drawn.push((r, x));
            }
        }
    }
    for &r in front {
        drawn.push((r, f.fade_in(r)));
    }
    f.end_frame();
    drawn
}

#[test]
fn a_refinement_dissolves_the_parent_into_its_children_and_ends() {
    let mut f = Fades::new(0.5, 5);
    assert_eq!(frame(&mut f, 0.0, &[0], true), vec![(0, Fade::Opaque)]);
    let d = frame(&mut f, 0.1, &[1, 2], true);
    assert_eq!(
        d,
        vec![(0, Fade::Out(0.0)), (1, Fade::In(0.0)), (2, Fade::In(0.0))]
    );
    let d = frame(&mut f, 0.35, &[1, 2], true);
    assert_eq!(
        d,
        vec![(0, Fade::Out(0.5)), (1, Fade::In(0.5)), (2, Fade::In(0.5))]
    );
    // Over after half a second: the parent is no longer asked for.
    let d = frame(&mut f, 0.6, &[1, 2], true);
    assert_eq!(d, vec![(1, Fade::Opaque), (2, Fade::Opaque)]);
    assert_eq!(f.active(), (0, 0));
}

#[test]
fn a_coarsening_dissolves_the_children_into_their_ancestor() {
    let mut f = Fades::new(1.0, 5);
    frame(&mut f, 0.0, &[3, 4, 2], true);
    let d = frame(&mut f, 0.0, &[0], true);
    // 3 and 4 (grandchildren) and 2 (child) all replaced by 0 at once.
    assert_eq!(
        d,
        vec![
            (2, Fade::Out(0.0)),
            (3, Fade::Out(0.0)),
            (4, Fade::Out(0.0)),
            (0, Fade::In(0.0))
        ]
    );
    let d = frame(&mut f, 0.25, &[0], true);
    assert_eq!(d.last(), Some(&(0, Fade::In(0.25))));
    assert_eq!(d.len(), 4);
}

#[test]
fn a_sibling_that_comes_later_joins_the_switch_under_way() {
    let mut f = Fades::new(1.0, 5);
    frame(&mut f, 0.0, &[0], true);
    // Child 2 only (child 1 left the view, say): the root fades out.
    frame(&mut f, 0.0, &[2], true);
    let d = frame(&mut f, 0.5, &[1, 2], true);
    // 1 is new, its shown relative (0) is fading out since 0.0: it joins.
    assert_eq!(
        d,
        vec![(0, Fade::Out(0.5)), (1, Fade::In(0.5)), (2, Fade::In(0.5))]
    );
}

#[test]
fn without_the_replaced_rep_resident_the_new_one_is_opaque_at_once() {
    let mut f = Fades::new(1.0, 5);
    frame(&mut f, 0.0, &[0], true);
    let d = frame(&mut f, 0.1, &[1, 2], false);
    assert_eq!(d, vec![(1, Fade::Opaque), (2, Fade::Opaque)]);
    // And the replaced rep is not asked for again (no ghost).
    assert!(f.plan(0.2, &[1, 2], par, |_| true).is_empty());
    assert_eq!(f.active(), (0, 0));
}

#[test]
fn newly_visible_reps_and_unfadeable_ones_pop_in() {
    let mut f = Fades::new(1.0, 5);
    frame(&mut f, 0.0, &[2], true);
    // 3 has no shown relative (its ancestors 1 and 0 were not shown).
    assert_eq!(
        frame(&mut f, 0.1, &[2, 3], true),
        vec![(2, Fade::Opaque), (3, Fade::Opaque)]
    );
    // 2 -> 0 would be a coarsening, but 0 is a tree here.
    let outs = f.plan(0.2, &[0, 3], par, |r| r != 0);
    assert!(outs.is_empty());
}

#[test]
fn off_means_no_fades_and_no_state() {
    let mut f = Fades::new(0.0, 5);
    frame(&mut f, 0.0, &[0], true);
    assert_eq!(
        frame(&mut f, 0.1, &[1, 2], true),
        vec![(1, Fade::Opaque), (2, Fade::Opaque)]
    );
    assert_eq!(f.active(), (0, 0));
}

#[test]
fn a_reversed_switch_fades_back_without_a_ghost() {
    let mut f = Fades::new(1.0, 5);
    frame(&mut f, 0.0, &[0], true);
    frame(&mut f, 0.1, &[1, 2], true);
    // Back to the root half-way: the children fade out from now, the root
    // in, and nothing else is drawn.
    let d = frame(&mut f, 0.6, &[0], true);
    assert_eq!(
        d,
        vec![(1, Fade::Out(0.0)), (2, Fade::Out(0.0)), (0, Fade::In(0.0))]
    );
}

mod prop {
    use super::*;
    use proptest::prelude::*;

    /// The cuts of the five-rep hierarchy.
    const CUTS: [&[RepId]; 4] = [&[0], &[1, 2], &[3, 4, 2], &[2]];

    proptest! {
        /// Whatever the fronts, every fade ends within its time once the
        /// front holds still, partners share one `t`, and only reps that
        /// are not in the front are drawn fading out.
        #[test]
        fn fades_end_and_partners_stay_complementary(
            cuts in proptest::collection::vec((0usize..4, 0u32..200, any::<bool>()), 1..40),
        ) {
            let mut f = Fades::new(0.3, 5);
            let mut now = 0.0;
            let mut last = 0;
            for (c, dt_ms, resident) in cuts {
                now += f64::from(dt_ms) / 1e3;
                let d = frame(&mut f, now, CUTS[c], resident);
                let ins: Vec<f32> = d.iter().filter_map(|(_, x)| match x { Fade::In(t) => Some(*t), _ => None }).collect();
                for (r, x) in &d {
                    if let Fade::Out(t) = x {
                        prop_assert!(!CUTS[c].contains(r));
                        prop_assert!(ins.contains(t), "{r} fades out by {t}, no rep fades in by it");
                    }
                }
                last = c;
            }
            let d = frame(&mut f, now + 0.31, CUTS[last], true);
            prop_assert!(d.iter().all(|(_, x)| *x == Fade::Opaque), "{d:?}");
            prop_assert_eq!(f.active(), (0, 0));
        }
    }
}
