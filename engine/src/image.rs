//! RGBA8 images: PSNR and tolerance-based comparison with a difference
//! image, for golden-image tests and the benchmark's image quality. Plain
//! CPU code; PNG files are the programs' (`engine_cli::png`).

/// An 8-bit RGBA image, rows top to bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RgbaImage {
    pub width: u32,
    pub height: u32,
    pub data: Vec<u8>,
}

/// How two images differ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageDiff {
    /// Largest difference of any channel (0..=255).
    pub max_channel_diff: u8,
    /// Pixels whose largest channel difference exceeds the tolerance.
    pub pixels_over: u64,
    /// Peak signal-to-noise ratio over RGB in dB (`f64::INFINITY` if equal).
    pub psnr_db: f64,
}

impl RgbaImage {
    /// A `width × height` image filled with `rgba`.
    pub fn filled(width: u32, height: u32, rgba: [u8; 4]) -> Self {
        let n = width as usize * height as usize;
        Self {
            width,
            height,
            data: rgba.repeat(n),
        }
    }

    /// The pixel at `(x, y)`.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = 4 * (y as usize * self.width as usize + x as usize);
        [
            self.data[i],
            self.data[i + 1],
            self.data[i + 2],
            self.data[i + 3],
        ]
    }

    /// Compares RGB channels with `other` (same size required).
    pub fn diff(&self, other: &RgbaImage, tolerance: u8) -> Option<ImageDiff> {
        if (self.width, self.height) != (other.width, other.height) {
            return None;
        }
        let mut max = 0u8;
        let mut over = 0u64;
        let mut sq = 0f64;
        for (a, b) in self.data.chunks_exact(4).zip(other.data.chunks_exact(4)) {
            let mut px = 0u8;
            for c in 0..3 {
                let d = a[c].abs_diff(b[c]);
                px = px.max(d);
                sq += f64::from(d) * f64::from(d);
            }
            max = max.max(px);
            over += u64::from(px > tolerance);
        }
        let n = 3.0 * f64::from(self.width) * f64::from(self.height);
        let mse = sq / n.max(1.0);
        let psnr_db = if mse == 0.0 {
            f64::INFINITY
        } else {
            10.0 * (255.0f64 * 255.0 / mse).log10()
        };
        Some(ImageDiff {
            max_channel_diff: max,
            pixels_over: over,
            psnr_db,
        })
    }

    /// A visualisation of the differences: black where equal, brighter red
    /// where they differ more, white where over `tolerance`.
    pub fn diff_image(&self, other: &RgbaImage, tolerance: u8) -> Option<RgbaImage> {
        if (self.width, self.height) != (other.width, other.height) {
            return None;
        }
        let data = self
            .data
            .chunks_exact(4)
            .zip(other.data.chunks_exact(4))
            .flat_map(|(a, b)| {
                let d = (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0);
                if d > tolerance {
                    [255, 255, 255, 255]
                } else {
                    [d.saturating_mul(8), 0, 0, 255]
                }
            })
            .collect();
        Some(RgbaImage {
            width: self.width,
            height: self.height,
            data,
        })
    }

    /// Pixels that differ from `other` beyond a one-pixel tolerance: a
    /// pixel counts when no pixel of the other image within one pixel of
    /// it (its 3×3 neighbourhood) matches its colour within `tolerance` on
    /// every RGB channel, in either direction. A silhouette moved by one
    /// pixel does not count; a member that vanished or a wrong colour does.
    pub fn differing_beyond_one_pixel(&self, other: &RgbaImage, tolerance: u8) -> Option<u64> {
        if (self.width, self.height) != (other.width, other.height) {
            return None;
        }
        let (w, h) = (self.width as i64, self.height as i64);
        let near = |a: &RgbaImage, b: &RgbaImage, x: i64, y: i64| {
            let p = a.pixel(x as u32, y as u32);
            (-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    let (qx, qy) = (x + dx, y + dy);
                    qx >= 0 && qy >= 0 && qx < w && qy < h && {
                        let q = b.pixel(qx as u32, qy as u32);
                        (0..3).all(|c| p[c].abs_diff(q[c]) <= tolerance)
                    }
                })
            })
        };
        let mut n = 0u64;
        for y in 0..h {
            for x in 0..w {
                n += u64::from(!near(self, other, x, y) || !near(other, self, x, y));
            }
        }
        Some(n)
    }

    /// Fraction of pixels that differ from the colour of pixel (0, 0).
    pub fn coverage(&self) -> f64 {
        let bg = self.pixel(0, 0);
        let n = self
            .data
            .chunks_exact(4)
            .filter(|p| p[..3] != bg[..3])
            .count();
        n as f64 / (self.width as f64 * self.height as f64).max(1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psnr_and_differing_pixels() {
        let mut img = RgbaImage::filled(7, 5, [10, 20, 30, 255]);
        img.data[4 * 8] = 200;
        let back = img.clone();
        let d = img.diff(&back, 0).unwrap();
        assert_eq!(d.psnr_db, f64::INFINITY);
        assert_eq!(d.pixels_over, 0);
        let mut other = img.clone();
        other.data[0] = 20; // one channel off by 10
        let d = img.diff(&other, 5).unwrap();
        assert_eq!((d.max_channel_diff, d.pixels_over), (10, 1));
        let mse: f64 = 100.0 / (3.0 * 35.0);
        assert!((d.psnr_db - 10.0 * (255.0 * 255.0 / mse).log10()).abs() < 1e-9);
        let di = img.diff_image(&other, 5).unwrap();
        assert_eq!(di.pixel(0, 0), [255, 255, 255, 255]);
        assert_eq!(di.pixel(1, 0), [0, 0, 0, 255]);
        assert!(img.diff(&RgbaImage::filled(1, 1, [0; 4]), 0).is_none());
        assert!((img.coverage() - 1.0 / 35.0).abs() < 1e-12);
    }

    #[test]
    fn a_one_pixel_shift_is_tolerated_a_missing_line_is_not() {
        let bg = [0, 0, 0, 255];
        let mut a = RgbaImage::filled(12, 10, bg);
        let line = |img: &mut RgbaImage, x: usize| {
            for y in 0..10 {
                let i = 4 * (y * 12 + x);
                img.data[i..i + 3].copy_from_slice(&[200, 100, 50]);
            }
        };
        line(&mut a, 5);
        let mut shifted = RgbaImage::filled(12, 10, bg);
        line(&mut shifted, 6);
        assert_eq!(a.differing_beyond_one_pixel(&shifted, 8), Some(0));
        // A line two pixels over, or gone: its pixels and the old ones count.
        let mut far = RgbaImage::filled(12, 10, bg);
        line(&mut far, 7);
        assert_eq!(a.differing_beyond_one_pixel(&far, 8), Some(20));
        let empty = RgbaImage::filled(12, 10, bg);
        assert_eq!(a.differing_beyond_one_pixel(&empty, 8), Some(10));
        // Colours within the tolerance match.
        let mut dim = a.clone();
        dim.data[4 * 5] -= 8;
        assert_eq!(a.differing_beyond_one_pixel(&dim, 8), Some(0));
        assert!(
            a.differing_beyond_one_pixel(&RgbaImage::filled(1, 1, bg), 8)
                .is_none()
        );
    }
}
