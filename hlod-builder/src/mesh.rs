//! Indexed triangle meshes in float precision, as the builder works on them.

use glam::{Mat3, Mat4, Vec3};

/// An indexed triangle list with one normal and one RGBA8 colour per vertex.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub colors: Vec<[u8; 4]>,
    pub indices: Vec<u32>,
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (union identity).
    pub const EMPTY: Self = Self {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// The eight corners (bit 0 of the index picks x, bit 1 y, bit 2 z).
    pub fn corners(&self) -> [Vec3; 8] {
        std::array::from_fn(|k| {
            Vec3::new(
                if k & 1 == 0 { self.min.x } else { self.max.x },
                if k & 2 == 0 { self.min.y } else { self.max.y },
                if k & 4 == 0 { self.min.z } else { self.max.z },
            )
        })
    }

    /// Whether no point was added.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x
    }

    /// Grows the box to hold `p`.
    pub fn add(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// The smallest box holding both.
    pub fn union(self, o: Self) -> Self {
        Self {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// `max - min` (zero for the empty box).
    pub fn extent(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }

    /// Centre point.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// As arrays, for the file format.
    pub fn to_arrays(self) -> ([f32; 3], [f32; 3]) {
        (self.min.to_array(), self.max.to_array())
    }
}

impl Mesh {
    /// Triangles in the mesh.
    pub fn tri_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Vertices in the mesh.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Heap bytes its arrays hold.
    pub fn heap_bytes(&self) -> u64 {
        (self.positions.capacity() * 12
            + self.normals.capacity() * 12
            + self.colors.capacity() * 4
            + self.indices.capacity() * 4) as u64
    }

    /// Bounds of the referenced vertices' positions.
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for &i in &self.indices {
            b.add(Vec3::from(self.positions[i as usize]));
        }
        b
    }

    /// Bounds of all vertex positions, referenced or not.
    pub fn bounds_of_all(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for p in &self.positions {
            b.add(Vec3::from(*p));
        }
        b
    }

    /// Appends `other`'s geometry.
    pub fn append(&mut self, other: &Mesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.normals.extend_from_slice(&other.normals);
        self.colors.extend_from_slice(&other.colors);
        self.indices.extend(other.indices.iter().map(|i| i + base));
    }

    /// Concatenates meshes.
    pub fn merge<'a>(meshes: impl IntoIterator<Item = &'a Mesh>) -> Mesh {
        let mut out = Mesh::default();
        for m in meshes {
            out.append(m);
        }
        out
    }

    /// The mesh under an affine transform; winding flips with mirroring.
    pub fn transformed(&self, m: &Mat4) -> Mesh {
        let normal_m = Mat3::from_mat4(*m).inverse().transpose();
        let positions = self
            .positions
            .iter()
            .map(|p| m.transform_point3(Vec3::from(*p)).to_array())
            .collect();
        let normals = self
            .normals
            .iter()
            .map(|n| (normal_m * Vec3::from(*n)).normalize_or_zero().to_array())
            .collect();
        let mut indices = self.indices.clone();
        if Mat3::from_mat4(*m).determinant() < 0.0 {
            for t in indices.chunks_exact_mut(3) {
                t.swap(1, 2);
            }
        }
        Mesh {
            positions,
            normals,
            colors: self.colors.clone(),
            indices,
        }
    }

    /// A mesh of the given triangles only, with unreferenced vertices dropped
    /// (vertices keep their first-use order).
    pub fn subset(&self, tris: impl IntoIterator<Item = usize>) -> Mesh {
        let mut remap = vec![u32::MAX; self.positions.len()];
        let mut out = Mesh::default();
        for t in tris {
            for k in 0..3 {
                let v = self.indices[3 * t + k] as usize;
                if remap[v] == u32::MAX {
                    remap[v] = out.positions.len() as u32;
                    out.positions.push(self.positions[v]);
                    out.normals.push(self.normals[v]);
                    out.colors.push(self.colors[v]);
                }
                out.indices.push(remap[v]);
            }
        }
        out
    }

    /// Drops triangles with repeated indices or zero area and unused vertices.
    /// Returns how many triangles were dropped.
    pub fn remove_degenerate(&mut self) -> usize {
        let keep: Vec<usize> = (0..self.tri_count())
            .filter(|&t| {
                let [a, b, c] = [0, 1, 2].map(|k| self.indices[3 * t + k]);
                if a == b || b == c || a == c {
                    return false;
                }
                let [pa, pb, pc] = [a, b, c].map(|i| Vec3::from(self.positions[i as usize]));
                (pb - pa).cross(pc - pa).length_squared() > 0.0
            })
            .collect();
        let dropped = self.tri_count() - keep.len();
        *self = self.subset(keep);
        dropped
    }

    /// Area-weighted vertex normals from the triangles.
    pub fn compute_normals(&mut self) {
        let mut acc = vec![Vec3::ZERO; self.positions.len()];
        for t in self.indices.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| Vec3::from(self.positions[i as usize]));
            let n = (b - a).cross(c - a);
            for &i in t {
                acc[i as usize] += n;
            }
        }
        self.normals = acc
            .iter()
            .map(|n| n.normalize_or_zero().to_array())
            .collect();
    }

    /// The colour covering most triangles (by their first vertex).
    pub fn dominant_color(&self) -> [u8; 4] {
        let mut counts: Vec<([u8; 4], usize)> = Vec::new();
        for t in self.indices.chunks_exact(3) {
            let c = self.colors[t[0] as usize];
            match counts.iter_mut().find(|(k, _)| *k == c) {
                Some((_, n)) => *n += 1,
                None => counts.push((c, 1)),
            }
        }
        counts
            .iter()
            .max_by_key(|(_, n)| *n)
            .map_or([200, 200, 200, 255], |(c, _)| *c)
    }

    /// Splits the mesh into spatially coherent pieces of at most `max_tris`
    /// triangles (median splits of triangle centroids along the widest axis).
    pub fn split_spatial(&self, max_tris: usize) -> Vec<Mesh> {
        let mut tris: Vec<usize> = (0..self.tri_count()).collect();
        let mut out = Vec::new();
        self.split_rec(&mut tris, max_tris.max(1), &mut out);
        out
    }

    fn split_rec(&self, tris: &mut [usize], max_tris: usize, out: &mut Vec<Mesh>) {
        if tris.len() <= max_tris {
            out.push(self.subset(tris.iter().copied()));
            return;
        }
        let centroid = |t: usize| {
            (0..3)
                .map(|k| Vec3::from(self.positions[self.indices[3 * t + k] as usize]))
                .sum::<Vec3>()
        };
        let mut b = Aabb::EMPTY;
        for &t in tris.iter() {
            b.add(centroid(t));
        }
        let e = b.extent();
        let axis = if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        };
        let mid = tris.len() / 2;
        tris.select_nth_unstable_by(mid, |&a, &b| {
            centroid(a)[axis]
                .total_cmp(&centroid(b)[axis])
                .then(a.cmp(&b))
        });
        let (lo, hi) = tris.split_at_mut(mid);
        self.split_rec(lo, max_tris, out);
        self.split_rec(hi, max_tris, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn grid(n: usize) -> Mesh {
        let mut m = Mesh::default();
        for y in 0..=n {
            for x in 0..=n {
                m.positions.push([x as f32, y as f32, 0.0]);
                m.normals.push([0.0, 0.0, 1.0]);
                m.colors.push([10, 20, 30, 255]);
            }
        }
        let w = n as u32 + 1;
        for y in 0..n as u32 {
            for x in 0..n as u32 {
                let i = y * w + x;
                m.indices
                    .extend_from_slice(&[i, i + 1, i + w + 1, i, i + w + 1, i + w]);
            }
        }
        m
    }

    #[test]
    fn split_keeps_every_triangle_and_respects_the_limit() {
        let m = grid(20);
        let parts = m.split_spatial(100);
        assert_eq!(
            parts.iter().map(Mesh::tri_count).sum::<usize>(),
            m.tri_count()
        );
        assert!(parts.iter().all(|p| p.tri_count() <= 100));
        assert!(parts.len() >= 8);
    }

    #[test]
    fn mirroring_flips_winding_and_degenerates_are_removed() {
        let mut m = grid(1);
        let mirrored = m.transformed(&Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0)));
        assert_eq!(mirrored.indices[1], m.indices[2]);
        m.indices.extend_from_slice(&[0, 0, 1, 0, 1, 3]);
        m.positions[3] = [2.0, 0.0, 0.0]; // 0,1,3 now collinear
        assert!(m.remove_degenerate() >= 2);
        assert!(m.positions.iter().all(|p| p[2] == 0.0));
    }
}
