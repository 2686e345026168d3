use glam::Vec3;

use crate::camera::Pose;
use crate::render::NoneRenderer;
use crate::runtime::tests::{check_frames, params, start, wide};
use crate::runtime::{Mode, RuntimeParams, run_path};

/// A still camera over a front that does not fit: the governor raises ε
/// until it does and stays there, with no substitute; without it, the
/// front's reps that find no room are substituted.
#[test]
fn the_governor_fits_the_front_and_settles_on_a_still_camera() {
    let (skel, src) = wide(64);
    let total: u64 = skel.reps.iter().map(|r| r.resident_len()).sum();
    let pose = Pose::look_at(Vec3::new(32.0, 2.0, 6.0), Vec3::new(32.0, 0.0, 0.0), 90.0);
    let run = |governor: bool, budget: u64| {
        let p = RuntimeParams {
            tolerance_px: 0.05,
            governor: governor.then(crate::governor::GovernorParams::default),
            ..params(Mode::NoPre, budget)
        };
        let mut walk = start(skel.clone(), src.clone(), p).unwrap();
        let mut r = NoneRenderer::new(0.0);
        let frames = run_path(&mut walk, &[pose; 40], &mut r, 0.0).unwrap();
        check_frames(&frames, budget);
        frames
    };
    // Half of what the front at ε needs.
    let budget = run(false, total)[0].front_bytes / 2;
    let plain = run(false, budget);
    assert!(plain.iter().all(|f| f.tolerance_px == f64::from(0.05f32)));
    assert!(
        plain.last().unwrap().substituted > 0,
        "the front must not fit"
    );
    let governed = run(true, budget);
    let last = &governed[30..];
    assert!(
        last.iter().all(|f| f.tolerance_px == last[0].tolerance_px),
        "settled"
    );
    assert!(last[0].tolerance_px > f64::from(0.05f32));
    assert!(
        last.iter().all(|f| f.substituted == 0),
        "no substitutes once it fits"
    );
    assert!(
        last.iter()
            .all(|f| f.front_bytes as f64 <= 0.8 * budget as f64)
    );
}
