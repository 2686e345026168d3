//! A closed, scan-like surface of any size: a sphere whose radius is
//! displaced by a few octaves of smooth deterministic noise (ridges, bumps
//! and a dent), tessellated as a latitude-longitude grid. It stands in for
//! a large range scan where none is at hand.

use glam::Vec3;

/// Positions, vertex normals and triangles of a rock of about `tris`
/// triangles (at least 8 × 4 quads), the same for the same `seed`.
pub fn rock(tris: usize, seed: u64) -> (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<u32>) {
    // A rows × 2·rows grid of quads: about 4 rows² triangles.
    let rows = ((tris as f64 / 4.0).sqrt().round() as usize).max(4);
    let cols = 2 * rows;
    let mut state = seed ^ 0x2545_f491_4f6c_dd1d;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f32 / (1u64 << 53) as f32
    };
    let waves: Vec<(Vec3, f32, f32)> = (0..12)
        .map(|k| {
            let d = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize_or(Vec3::X);
            let freq = 2.0 * (1.6f32).powi(k);
            (d, freq, rnd() * std::f32::consts::TAU)
        })
        .collect();
    let radius = |n: Vec3| -> f32 {
        let mut r = 1.0;
        for (k, (d, f, ph)) in waves.iter().enumerate() {
            let s = (n.dot(*d) * f + ph).sin();
            r += 0.12 / (1.0 + k as f32) * if k % 3 == 0 { 1.0 - 2.0 * s.abs() } else { s };
        }
        r
    };
    let mut pos = Vec::with_capacity((rows - 1) * cols + 2);
    let at =
        |lat: f32, lon: f32| Vec3::new(lat.sin() * lon.cos(), lat.cos(), lat.sin() * lon.sin());
    pos.push(Vec3::Y * radius(Vec3::Y));
    for i in 1..rows {
        let lat = std::f32::consts::PI * i as f32 / rows as f32;
        for j in 0..cols {
            let lon = std::f32::consts::TAU * j as f32 / cols as f32;
            let n = at(lat, lon);
            pos.push(n * radius(n));
        }
    }
    pos.push(Vec3::NEG_Y * radius(Vec3::NEG_Y));
    let south = (pos.len() - 1) as u32;
    let v = |i: usize, j: usize| (1 + (i - 1) * cols + j % cols) as u32;
    let mut idx = Vec::with_capacity(6 * rows * cols);
    for j in 0..cols {
        idx.extend_from_slice(&[0, v(1, j + 1), v(1, j)]);
        idx.extend_from_slice(&[south, v(rows - 1, j), v(rows - 1, j + 1)]);
    }
    for i in 1..rows - 1 {
        for j in 0..cols {
            let (a, b, c, d) = (v(i, j), v(i, j + 1), v(i + 1, j), v(i + 1, j + 1));
            idx.extend_from_slice(&[a, b, d, a, d, c]);
        }
    }
    let mut nrm = vec![Vec3::ZERO; pos.len()];
    for t in idx.chunks_exact(3) {
        let p = [0, 1, 2].map(|k| pos[t[k] as usize]);
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        for &i in t {
            nrm[i as usize] += n;
        }
    }
    (
        pos.iter().map(|p| p.to_array()).collect(),
        nrm.iter()
            .map(|n| n.normalize_or_zero().to_array())
            .collect(),
        idx,
    )
}
