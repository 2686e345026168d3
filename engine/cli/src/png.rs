//! PNG files of [`RgbaImage`]s: golden images, benchmark frames and
//! screenshots, written under the output-file policy and read under the
//! input policy.

use engine::image::RgbaImage;
use std::io::BufReader;
use std::path::Path;

/// Why an image cannot be read or written.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: not a usable PNG: {reason}")]
    Png { path: String, reason: String },
}

/// Reading and writing an image as a PNG file.
pub trait PngFile: Sized {
    /// Writes the image as an RGBA PNG (under the output-file policy:
    /// atomically, never over a device or a link's name).
    fn save_png(&self, path: &Path) -> Result<(), ImageError>;

    /// Reads an 8-bit RGB or RGBA PNG.
    fn load_png(path: &Path) -> Result<Self, ImageError>;
}

impl PngFile for RgbaImage {
    fn save_png(&self, path: &Path) -> Result<(), ImageError> {
        let name = path.display().to_string();
        crate::outfile::write_with(path, &[], |w| {
            let mut enc = png::Encoder::new(w, self.width, self.height);
            enc.set_color(png::ColorType::Rgba);
            enc.set_depth(png::BitDepth::Eight);
            let mut w = enc.write_header().map_err(std::io::Error::other)?;
            w.write_image_data(&self.data)
                .map_err(std::io::Error::other)?;
            w.finish().map_err(std::io::Error::other)
        })
        .map_err(|source| ImageError::Io { path: name, source })
    }

    fn load_png(path: &Path) -> Result<Self, ImageError> {
        let name = path.display().to_string();
        let file = engine::infile::open(path).map_err(|source| ImageError::Io {
            path: name.clone(),
            source,
        })?;
        let bad = |reason: String| ImageError::Png {
            path: name.clone(),
            reason,
        };
        let mut dec = png::Decoder::new(BufReader::new(file));
        dec.set_transformations(png::Transformations::EXPAND);
        let mut reader = dec.read_info().map_err(|e| bad(e.to_string()))?;
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| bad("image too large".into()))?;
        let mut buf = vec![0; size];
        let info = reader
            .next_frame(&mut buf)
            .map_err(|e| bad(e.to_string()))?;
        if info.bit_depth != png::BitDepth::Eight {
            return Err(bad(format!("bit depth {:?}, need 8", info.bit_depth)));
        }
        let px = info.width as usize * info.height as usize;
        let data = match info.color_type {
            png::ColorType::Rgba => buf[..px * 4].to_vec(),
            png::ColorType::Rgb => buf[..px * 3]
                .chunks_exact(3)
                .flat_map(|c| [c[0], c[1], c[2], 255])
                .collect(),
            other => return Err(bad(format!("colour type {other:?}, need RGB(A)"))),
        };
        Ok(RgbaImage {
            width: info.width,
            height: info.height,
            data,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = RgbaImage::filled(7, 5, [10, 20, 30, 255]);
        img.data[4 * 8] = 200;
        let p = dir.path().join("a.png");
        img.save_png(&p).unwrap();
        assert_eq!(RgbaImage::load_png(&p).unwrap(), img);
    }

    #[test]
    fn bad_png_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.png");
        std::fs::write(&p, b"not a png").unwrap();
        assert!(matches!(
            RgbaImage::load_png(&p),
            Err(ImageError::Png { .. })
        ));
        assert!(matches!(
            RgbaImage::load_png(&dir.path().join("missing.png")),
            Err(ImageError::Io { .. })
        ));
    }
}
