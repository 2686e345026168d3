//! A small depth-buffered CPU rasteriser (flat Lambert shading from a
//! headlight, two-sided) used to compare refined meshes with the full
//! resolution one without a GPU. Triangles crossing the near plane are
//! dropped (no clipping): both images of a comparison are drawn alike.

use glam::{Mat4, Vec3, Vec4Swizzles};

use crate::camera::View;
use crate::image::RgbaImage;

/// Background colour.
pub const BACKGROUND: [u8; 4] = [20, 24, 32, 255];

/// Draws `tris` as seen from `view` into a `view.width_px × view.height_px`
/// image.
pub fn rasterise(view: &View, tris: impl IntoIterator<Item = [Vec3; 3]>) -> RgbaImage {
    let (w, h) = (view.width_px.max(1), view.height_px.max(1));
    let mut img = RgbaImage::filled(w, h, BACKGROUND);
    let mut depth = vec![f32::INFINITY; (w * h) as usize];
    let pose = view.pose;
    let cam = Mat4::from_rotation_translation(pose.rotation, pose.position).inverse();
    let proj = glam::camera::rh::proj::directx::perspective(
        pose.fov_y_deg.to_radians(),
        view.aspect(),
        view.near,
        view.far,
    );
    let m = proj * cam;
    let eye_dir = pose.forward();
    for t in tris {
        let c = t.map(|p| m * p.extend(1.0));
        if c.iter().any(|v| v.w <= view.near) {
            continue;
        }
        let s = c.map(|v| {
            let n = v.xyz() / v.w;
            Vec3::new(
                (n.x + 1.0) * 0.5 * w as f32,
                (1.0 - n.y) * 0.5 * h as f32,
                n.z,
            )
        });
        let area = (s[1].x - s[0].x) * (s[2].y - s[0].y) - (s[2].x - s[0].x) * (s[1].y - s[0].y);
        if area.abs() < 1e-12 {
            continue;
        }
        let normal = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero();
        let shade = (40.0 + 200.0 * normal.dot(eye_dir).abs()) as u8;
        let x0 = s
            .iter()
            .map(|p| p.x)
            .fold(f32::MAX, f32::min)
            .floor()
            .max(0.0) as u32;
        let x1 = s
            .iter()
            .map(|p| p.x)
            .fold(f32::MIN, f32::max)
            .ceil()
            .min(w as f32 - 1.0);
        let y0 = s
            .iter()
            .map(|p| p.y)
            .fold(f32::MAX, f32::min)
            .floor()
            .max(0.0) as u32;
        let y1 = s
            .iter()
            .map(|p| p.y)
            .fold(f32::MIN, f32::max)
            .ceil()
            .min(h as f32 - 1.0);
        if x1 < 0.0 || y1 < 0.0 {
            continue;
        }
        for y in y0..=y1 as u32 {
            for x in x0..=x1 as u32 {
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                let e = |a: Vec3, b: Vec3| (b.x - a.x) * (py - a.y) - (px - a.x) * (b.y - a.y);
                let b0 = e(s[1], s[2]) / area;
                let b1 = e(s[2], s[0]) / area;
                let b2 = e(s[0], s[1]) / area;
                if b0 < 0.0 || b1 < 0.0 || b2 < 0.0 {
                    continue;
                }
                let z = b0 * s[0].z + b1 * s[1].z + b2 * s[2].z;
                let k = (y * w + x) as usize;
                if z < depth[k] {
                    depth[k] = z;
                    img.data[4 * k..4 * k + 4].copy_from_slice(&[shade, shade, shade, 255]);
                }
            }
        }
    }
    img
}
