//! `hlod-bench --anatomy` on a built plant: the per-frame counts add up
//! (triangles by what they do, reps by whether they own a pixel), a
//! coarser tolerance draws fewer triangles, and nonsense is refused.

use std::process::Command;

use hlod_builder::build::{BuildParams, build_file};
use hlod_builder::scenegen::plant::{PlantParams, write_plant};

const W: u64 = 320;
const H: u64 = 200;

#[test]
fn the_fronts_triangles_are_counted_once_each_and_thin_out_with_the_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let glb = d.join("p.glb");
    write_plant(
        &PlantParams {
            seed: 3,
            objects: 300,
            triangles: 300_000,
        },
        &glb,
    )
    .unwrap();
    build_file(&glb, &d.join("p.hlod"), &BuildParams::default(), false).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_hlod-bench"))
        .args([
            "p.hlod",
            "--frames",
            "40",
            "--anatomy",
            "1,4",
            "--anatomy-every",
            "10",
        ])
        .args([
            "--width",
            &W.to_string(),
            "--height",
            &H.to_string(),
            "--out",
            "o",
        ])
        .current_dir(d)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let table = std::fs::read_to_string(d.join("o/anatomy.md")).unwrap();
    assert_eq!(
        table
            .lines()
            .filter(|l| l.starts_with("| 1 |") || l.starts_with("| 4 |"))
            .count(),
        2,
        "{table}"
    );
    let csv = std::fs::read_to_string(d.join("o/anatomy.csv")).unwrap();
    let rows: Vec<Vec<f64>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 80);
    let mut tris = [0.0; 2];
    let mut sampled = 0;
    for r in &rows {
        let (tol, frame, reps, t) = (r[0], r[1] as u64, r[2], r[3]);
        let (hlod, was_sampled) = (r[5], r[6] == 1.0);
        let (visible, hidden, unsampled, off, sub, thin, covered, paged) =
            (r[7], r[8], r[9], r[10], r[11], r[12], r[13], r[14]);
        let (seen_reps, seen_tris, seen_bytes, hidden_reps_tris, unsampled_reps_tris) =
            (r[15], r[16], r[17], r[18], r[19]);
        let (box_px, box_tile, rep_box_px) = (r[20], r[21], r[22]);
        tris[usize::from(tol > 1.0)] += t;
        assert!(
            hlod <= t && paged == 0.0 && (reps > 0.0) == (t > 0.0),
            "{r:?}"
        );
        assert_eq!(was_sampled, frame % 10 == 0, "{r:?}");
        if was_sampled {
            sampled += 1;
            // Every triangle falls in exactly one class.
            assert_eq!(visible + hidden + unsampled + off, t, "{r:?}");
            assert!(sub <= t && thin <= t && covered <= (W * H) as f64, "{r:?}");
            // A pixel has one owner: no more visible triangles than pixels.
            assert!(visible <= covered && (t == 0.0 || visible > 0.0), "{r:?}");
            // Every rep owns a pixel, is hidden or is unsampled; the reps
            // owning a pixel hold every visible triangle.
            assert_eq!(
                seen_tris + hidden_reps_tris + unsampled_reps_tris,
                t,
                "{r:?}"
            );
            assert!(
                seen_reps >= 1.0 && seen_reps <= reps && seen_tris >= visible,
                "{r:?}"
            );
            assert!(seen_bytes > 0.0 && seen_bytes <= r[4], "{r:?}");
            // A box hidden behind the drawn depth holds a rep that owns no
            // pixel; whole tiles hide less than pixels.
            assert!(box_px <= hidden_reps_tris + unsampled_reps_tris, "{r:?}");
            assert!(
                rep_box_px <= hidden_reps_tris + unsampled_reps_tris,
                "{r:?}"
            );
            assert!(box_tile <= box_px, "{r:?}");
        } else {
            assert_eq!(visible + hidden + unsampled + off + covered, 0.0, "{r:?}");
            assert_eq!(
                seen_reps + seen_tris + hidden_reps_tris + unsampled_reps_tris,
                0.0
            );
            assert_eq!(box_px + box_tile + rep_box_px, 0.0);
        }
    }
    assert_eq!(sampled, 8);
    assert!(
        tris[1] < tris[0],
        "ε 4 px draws {} triangles, ε 1 px {}",
        tris[1],
        tris[0]
    );
}

#[test]
fn nonsense_anatomy_settings_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for args in [
        &["x.hlod", "--anatomy", "0"][..],
        &["x.hlod", "--anatomy", "1,abc"],
        &["x.hlod", "--anatomy", "1", "--anatomy-every", "0"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_hlod-bench"))
            .args(args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("anatomy"), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}
