//! Tessellated CAD primitives (cylinders, boxes, elbows, domes) appended to a mesh.

use std::f32::consts::{FRAC_PI_2, TAU};

use glam::Vec3;

use crate::mesh::Mesh;

/// Appends shapes of one colour to a mesh.
#[derive(Debug)]
pub struct ShapeBuilder {
    pub mesh: Mesh,
    pub color: [u8; 4],
}

impl ShapeBuilder {
    /// An empty builder drawing in `color`.
    pub fn new(color: [u8; 4]) -> Self {
        Self {
            mesh: Mesh::default(),
            color,
        }
    }

    fn vertex(&mut self, p: Vec3, n: Vec3) -> u32 {
        self.mesh.positions.push(p.to_array());
        self.mesh.normals.push(n.to_array());
        self.mesh.colors.push(self.color);
        self.mesh.positions.len() as u32 - 1
    }

    fn tri(&mut self, a: u32, b: u32, c: u32) {
        self.mesh.indices.extend_from_slice(&[a, b, c]);
    }

    /// A grid of `rows x cols` quads between rings of vertices (`ring` gives
    /// position and normal at `(row, col)`; columns wrap around).
    fn tube(&mut self, rows: u32, cols: u32, ring: impl Fn(u32, u32) -> (Vec3, Vec3)) {
        let base = self.mesh.positions.len() as u32;
        for r in 0..=rows {
            for c in 0..cols {
                let (p, n) = ring(r, c);
                self.vertex(p, n);
            }
        }
        for r in 0..rows {
            for c in 0..cols {
                let c1 = (c + 1) % cols;
                let (a, b) = (base + r * cols + c, base + r * cols + c1);
                let (d, e) = (a + cols, b + cols);
                self.tri(a, b, e);
                self.tri(a, e, d);
            }
        }
    }

    /// A disc fan at `center` facing `normal`.
    fn disc(&mut self, center: Vec3, normal: Vec3, r: f32, radial: u32) {
        let (u, v) = normal.any_orthonormal_pair();
        let c = self.vertex(center, normal);
        let first = self.mesh.positions.len() as u32;
        for k in 0..radial {
            let a = TAU * k as f32 / radial as f32;
            self.vertex(center + (u * a.cos() + v * a.sin()) * r, normal);
        }
        for k in 0..radial {
            let (i, j) = (first + k, first + (k + 1) % radial);
            // Counter-clockwise seen from the normal side.
            if u.cross(v).dot(normal) > 0.0 {
                self.tri(c, i, j);
            } else {
                self.tri(c, j, i);
            }
        }
    }

    /// A cylinder from `a` to `b`: `2 * radial * axial` side triangles, plus
    /// `2 * radial` with caps.
    pub fn cylinder(&mut self, a: Vec3, b: Vec3, r: f32, radial: u32, axial: u32, caps: bool) {
        let d = (b - a).normalize_or(Vec3::Y);
        let (u, v) = d.any_orthonormal_pair();
        let radial = radial.max(3);
        let axial = axial.max(1);
        self.tube(axial, radial, |row, col| {
            let t = row as f32 / axial as f32;
            let ang = TAU * col as f32 / radial as f32;
            let n = u * ang.cos() + v * ang.sin();
            (a.lerp(b, t) + n * r, n)
        });
        if caps {
            self.disc(a, -d, r, radial);
            self.disc(b, d, r, radial);
        }
    }

    /// A box from `a` to `b` (its long axis) with half sizes `hw` along `side`
    /// and `hh` along `d x side`: 12 triangles.
    pub fn beam(&mut self, a: Vec3, b: Vec3, side: Vec3, hw: f32, hh: f32) {
        let d = (b - a).normalize_or(Vec3::X);
        let s = (side - d * side.dot(d)).normalize_or(d.any_orthonormal_vector());
        let t = d.cross(s);
        let c = (a + b) * 0.5;
        let hl = (b - a).length() * 0.5;
        self.oriented_box(c, [d * hl, s * hw, t * hh]);
    }

    /// An axis-aligned box.
    pub fn cuboid(&mut self, center: Vec3, half: Vec3) {
        self.oriented_box(
            center,
            [Vec3::X * half.x, Vec3::Y * half.y, Vec3::Z * half.z],
        );
    }

    /// A box given by its centre and three orthogonal half-axes.
    fn oriented_box(&mut self, c: Vec3, axes: [Vec3; 3]) {
        for k in 0..3 {
            let (n, u, v) = (axes[k], axes[(k + 1) % 3], axes[(k + 2) % 3]);
            for sign in [1.0f32, -1.0] {
                let nn = (n * sign).normalize_or_zero();
                let fc = c + n * sign;
                let q =
                    [fc - u - v, fc + u - v, fc + u + v, fc - u + v].map(|p| self.vertex(p, nn));
                if u.cross(v).dot(nn) > 0.0 {
                    self.tri(q[0], q[1], q[2]);
                    self.tri(q[0], q[2], q[3]);
                } else {
                    self.tri(q[0], q[2], q[1]);
                    self.tri(q[0], q[3], q[2]);
                }
            }
        }
    }

    /// A 90° pipe elbow at `corner` turning from `dir_in` to `dir_out`, with
    /// bend radius and pipe radius (`2 * bend * radial` triangles).
    pub fn elbow(
        &mut self,
        corner: Vec3,
        dir_in: Vec3,
        dir_out: Vec3,
        (bend_r, r): (f32, f32),
        bend: u32,
        radial: u32,
    ) {
        let center = corner - dir_in * bend_r + dir_out * bend_r;
        let b = dir_in
            .cross(dir_out)
            .normalize_or(dir_in.any_orthonormal_vector());
        let bend = bend.max(2);
        let radial = radial.max(3);
        self.tube(bend, radial, |row, col| {
            let t = FRAC_PI_2 * row as f32 / bend as f32;
            let radial_dir = -dir_out * t.cos() + dir_in * t.sin();
            let phi = TAU * col as f32 / radial as f32;
            let n = radial_dir * phi.cos() - b * phi.sin();
            (center + radial_dir * bend_r + n * r, n)
        });
    }

    /// A hemispherical dome on a circle of radius `r` around `center`, bulging along `up`.
    pub fn dome(&mut self, center: Vec3, up: Vec3, r: f32, rings: u32, radial: u32) {
        let (u, v) = up.any_orthonormal_pair();
        let rings = rings.max(2);
        let radial = radial.max(3);
        self.tube(rings, radial, |row, col| {
            let lat = FRAC_PI_2 * row as f32 / (rings as f32 + 0.5);
            let phi = TAU * col as f32 / radial as f32;
            let n = (u * phi.cos() + v * phi.sin()) * lat.cos() + up * lat.sin();
            (center + n * r, n)
        });
        let top_lat = FRAC_PI_2 * rings as f32 / (rings as f32 + 0.5);
        self.disc(
            center + up * r * top_lat.sin(),
            up,
            r * top_lat.cos(),
            radial,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Outward-facing: the triangle normal agrees with the stored vertex normal.
    fn outward(m: &Mesh) -> f32 {
        let mut good = 0;
        for t in m.indices.chunks_exact(3) {
            let p = [t[0], t[1], t[2]].map(|i| Vec3::from(m.positions[i as usize]));
            let n = (p[1] - p[0]).cross(p[2] - p[0]);
            if n.dot(Vec3::from(m.normals[t[0] as usize])) > 0.0 {
                good += 1;
            }
        }
        good as f32 / m.tri_count() as f32
    }

    #[test]
    fn primitives_have_expected_counts_and_face_outwards() {
        let mut s = ShapeBuilder::new([1, 2, 3, 255]);
        s.cylinder(Vec3::ZERO, Vec3::Y * 2.0, 0.5, 16, 3, true);
        assert_eq!(s.mesh.tri_count(), 2 * 16 * 3 + 2 * 16);
        assert!(outward(&s.mesh) > 0.99);
        let mut s = ShapeBuilder::new([1, 2, 3, 255]);
        s.beam(Vec3::ZERO, Vec3::X * 4.0, Vec3::Y, 0.1, 0.2);
        s.cuboid(Vec3::ONE, Vec3::splat(0.5));
        assert_eq!(s.mesh.tri_count(), 24);
        assert!(outward(&s.mesh) > 0.99);
        let mut s = ShapeBuilder::new([1, 2, 3, 255]);
        s.elbow(Vec3::ZERO, Vec3::X, Vec3::Y, (0.3, 0.1), 8, 12);
        s.dome(Vec3::ZERO, Vec3::Y, 1.0, 6, 16);
        assert!(outward(&s.mesh) > 0.99, "{}", outward(&s.mesh));
    }
}
