//! `--walk`: the path walked by a person instead of flown. Each frame the
//! walker steers towards the path's position (at most twice the path's
//! speed), collides with the scene's walk section and falls under gravity;
//! the frame is drawn from its eye with the path's orientation. What walking
//! costs is printed: the walker's time per frame and the bytes its walk map
//! holds, beside the footprint (they are not part of it).

use anyhow::{Context, Result};
use engine::ByteSource;
use engine::camera::Pose;
use engine::walk::{Body, WalkMap, Walker};
use glam::Vec2;
use std::sync::Arc;
use std::time::Instant;

/// The walk section of the scene in `source`, for `option`.
fn open(
    source: Arc<dyn ByteSource>,
    name: &str,
    option: &str,
) -> Result<WalkMap<Arc<dyn ByteSource>>> {
    let map = WalkMap::open(source, engine::walk::DEFAULT_CAP).with_context(|| name.to_string())?;
    map.with_context(|| {
        format!(
            "{name}: {option}: the scene has no walk section (built before format version 5, \
             or with --walk-cell 0): rebuild it"
        )
    })
}

/// `--path-kind walk`: an interior walk generated on the scene's walk
/// section ([`engine::walk::tour`]): from a place indoors drawn with `seed`
/// to a place on each storey in turn and back, at 1.2 m/s (30 frames a
/// second), as a walker walks it.
pub fn tour_path(
    source: Arc<dyn ByteSource>,
    name: &str,
    root: &engine::NodeRecord,
    frames: usize,
    seed: u64,
) -> Result<Vec<Pose>> {
    let mut map = open(source, name, "--path-kind walk")?;
    let (lo, hi) = (
        Vec2::new(root.bbox_min[0], root.bbox_min[2]),
        Vec2::new(root.bbox_max[0], root.bbox_max[2]),
    );
    let t0 = Instant::now();
    let t = engine::walk::tour(&mut map, (lo, hi), frames, 0.04, seed)
        .with_context(|| format!("{name}: --path-kind walk"))?;
    println!(
        "walk path: storeys at {:?}, {} places reachable, made in {:.1} s",
        t.storeys,
        t.places,
        t0.elapsed().as_secs_f64()
    );
    Ok(t.poses)
}

/// The poses of `path` as walked through `source`'s walk section, `fps`
/// frames a second.
pub fn walked(
    source: Arc<dyn ByteSource>,
    name: &str,
    path: &[Pose],
    fps: f64,
) -> Result<Vec<Pose>> {
    let mut map = open(source, name, "--walk")?;
    let Some(first) = path.first() else {
        return Ok(Vec::new());
    };
    let dt = if fps > 0.0 {
        (1.0 / fps) as f32
    } else {
        1.0 / 30.0
    };
    let body = Body {
        doors_open: true,
        ..Body::default()
    };
    let mut w = Walker::from_eye(body, &mut map, first.position)?;
    let (mut times, mut held, mut blocked, mut off) = (Vec::new(), 0, 0u32, 0.0f64);
    let mut out = Vec::with_capacity(path.len());
    for (k, p) in path.iter().enumerate() {
        if k > 0 {
            let speed = (p.position - path[k - 1].position).length().max(0.02);
            let to = p.position - w.eye();
            let wish = Vec2::new(to.x, to.z).clamp_length_max(2.0 * speed);
            let t0 = Instant::now();
            let m = w
                .step(&mut map, wish, dt)
                .with_context(|| format!("{name}: frame {k}"))?;
            times.push(t0.elapsed().as_secs_f64() * 1e6);
            blocked += u32::from(m.blocked);
            held = held.max(map.resident_bytes());
        }
        off += f64::from((w.eye() - p.position).length());
        out.push(Pose {
            position: w.eye(),
            ..*p
        });
    }
    times.sort_by(f64::total_cmp);
    let at = |q: f64| {
        times
            .get(((times.len() as f64 - 1.0) * q).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    println!(
        "walk: {} frames walked (doors open); step {:.1} us median, {:.1} us p99; {} frames blocked by \
         solid; eye {:.2} m from the path on average; walk map held at most {} B (index {} B, {} chunk reads), \
         not counted in the footprint",
        out.len(),
        at(0.5),
        at(0.99),
        blocked,
        off / out.len() as f64,
        held,
        map.index_bytes(),
        map.reads
    );
    Ok(out)
}
