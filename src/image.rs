//! Images (premultiplied linear RGBA in f32), the error metrics of DESIGN.md, PNG output and
//! difference images.

use std::path::Path;

/// A premultiplied RGBA image over transparent black, row-major, y down.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` pixels, row by row from the top, premultiplied RGBA in [0, 1].
    pub pixels: Vec<[f32; 4]>,
}

/// Problems reading, writing or comparing images; each names the file or the sizes.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// A PNG could not be written (the folder is missing or not writable, the disk is full).
    #[error("{path}: cannot write the PNG: {source}")]
    Write {
        /// The PNG file.
        path: String,
        /// The encoder's or the system's error.
        source: image::ImageError,
    },
    /// A PNG could not be read or decoded.
    #[error("{path}: cannot read the PNG: {source}")]
    Read {
        /// The PNG file.
        path: String,
        /// The decoder's or the system's error.
        source: image::ImageError,
    },
    /// Two images to compare differ in size (width x height of each).
    #[error("images differ in size: {0}x{1} and {2}x{3}; render both at the same --size")]
    SizeMismatch(u32, u32, u32, u32),
    /// An image's `pixels` are not `width * height` (the fields are public: an image built or
    /// changed by hand).
    #[error(
        "the image is {width}x{height} but has {len} pixels, not width x height; build images \
         with Image::new and keep `pixels` at that length"
    )]
    PixelCount {
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
        /// The length of its `pixels`.
        len: usize,
    },
}

/// Error of a result against a reference (DESIGN.md, "Accuracy").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorMetrics {
    /// Root mean square over all pixels and the four channels.
    pub rmse: f64,
    /// Largest absolute channel difference.
    pub max_abs: f64,
    /// `20 log10(1 / rmse)`; infinite for identical images.
    pub psnr: f64,
    /// Pixels the reference covers (alpha > 0.01) that the result leaves empty (alpha < 0.001).
    pub holes: usize,
    /// The reverse of holes: result covers, reference empty.
    pub spill: usize,
    /// Pixels of the result with a NaN or infinite channel.
    pub non_finite: usize,
}

impl std::fmt::Display for ErrorMetrics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "rmse {:.3e}, max_abs {:.3e}, psnr {:.2} dB, holes {}, spill {}, non-finite {}",
            self.rmse, self.max_abs, self.psnr, self.holes, self.spill, self.non_finite
        )
    }
}

impl Image {
    /// A transparent black image of `width` x `height` pixels.
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            pixels: vec![[0.0; 4]; (width as usize) * (height as usize)],
        }
    }

    /// The pixel at column `x`, row `y` (from the top).
    ///
    /// # Panics
    ///
    /// Outside the image (`x >= width` or `y >= height`), as slice indexing does.
    pub fn get(&self, x: u32, y: u32) -> [f32; 4] {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) is outside the {}x{} image",
            self.width,
            self.height
        );
        // In usize: in u32, y * width wrapped on images of over 4G pixels.
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// An error unless `pixels` holds `width * height` pixels.
    fn check_pixels(&self) -> Result<(), ImageError> {
        let len = self.pixels.len();
        match len as u128 == self.width as u128 * self.height as u128 {
            true => Ok(()),
            false => Err(ImageError::PixelCount {
                width: self.width,
                height: self.height,
                len,
            }),
        }
    }

    /// Error metrics of `self` (the result) against `reference`.
    pub fn compare(&self, reference: &Image) -> Result<ErrorMetrics, ImageError> {
        self.check_size(reference)?;
        let (mut sq, mut max_abs, mut holes, mut spill, mut non_finite) = (0.0f64, 0.0f64, 0, 0, 0);
        for (r, g) in self.pixels.iter().zip(&reference.pixels) {
            if r.iter().any(|c| !c.is_finite()) {
                non_finite += 1;
            }
            for c in 0..4 {
                let d = (r[c] as f64 - g[c] as f64).abs();
                let d = if d.is_finite() { d } else { 1.0 };
                sq += d * d;
                max_abs = max_abs.max(d);
            }
            if is_hole(r, g) {
                holes += 1;
            }
            if r[3] > 0.01 && g[3] < 0.001 {
                spill += 1;
            }
        }
        let rmse = (sq / (self.pixels.len() * 4).max(1) as f64).sqrt();
        Ok(ErrorMetrics {
            rmse,
            max_abs,
            psnr: 20.0 * (1.0 / rmse).log10(),
            holes,
            spill,
            non_finite,
        })
    }

    /// A picture of where two images differ: per pixel the largest channel difference, scaled
    /// so that `full_scale` is white, on a black-red-yellow-white heat ramp. Holes (reference
    /// covers, `self` empty) are marked in cyan.
    pub fn difference(&self, reference: &Image, full_scale: f32) -> Result<Image, ImageError> {
        self.check_size(reference)?;
        let mut out = Image::new(self.width, self.height);
        for ((o, r), g) in out
            .pixels
            .iter_mut()
            .zip(&self.pixels)
            .zip(&reference.pixels)
        {
            if is_hole(r, g) {
                *o = [0.0, 1.0, 1.0, 1.0];
                continue;
            }
            let d = (0..4)
                .map(|c| (r[c] - g[c]).abs())
                .fold(0.0f32, |a, b| if b.is_nan() { 1.0 } else { a.max(b) });
            let u = (d / full_scale).clamp(0.0, 1.0) * 3.0;
            *o = [
                u.min(1.0),
                (u - 1.0).clamp(0.0, 1.0),
                (u - 2.0).clamp(0.0, 1.0),
                1.0,
            ];
        }
        Ok(out)
    }

    /// 8-bit RGBA, composited over `background` (opaque) when given, else left premultiplied
    /// and converted to straight alpha. TF colours are written as given (no gamma curve), as
    /// ParaView and VTK show them.
    pub fn to_rgba8(&self, background: Option<[f32; 3]>) -> Vec<u8> {
        let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
        self.pixels
            .iter()
            .flat_map(|p| {
                let p = p.map(|c| if c.is_finite() { c } else { 0.0 });
                match background {
                    Some(bg) => {
                        let t = 1.0 - p[3];
                        [
                            q(p[0] + t * bg[0]),
                            q(p[1] + t * bg[1]),
                            q(p[2] + t * bg[2]),
                            255,
                        ]
                    }
                    None if p[3] > 0.0 => [q(p[0] / p[3]), q(p[1] / p[3]), q(p[2] / p[3]), q(p[3])],
                    None => [0, 0, 0, 0],
                }
            })
            .collect()
    }

    /// Writes a PNG (see [`Self::to_rgba8`]).
    pub fn save_png(&self, path: &Path, background: Option<[f32; 3]>) -> Result<(), ImageError> {
        // The encoder asserts the buffer's length: a wrong pixel count panicked in it.
        self.check_pixels()?;
        image::save_buffer(
            path,
            &self.to_rgba8(background),
            self.width,
            self.height,
            image::ColorType::Rgba8,
        )
        .map_err(|source| ImageError::Write {
            path: path.display().to_string(),
            source,
        })
    }

    /// Reads an 8-bit PNG as an image with straight alpha turned into premultiplied.
    pub fn load_png(path: &Path) -> Result<Image, ImageError> {
        // Read, then decoded as a PNG whatever the name: `image::open` guessed the format from
        // the extension, and said "The image format could not be determined" for a folder.
        let read_error = |source| ImageError::Read {
            path: path.display().to_string(),
            source,
        };
        let bytes = std::fs::read(path).map_err(|e| read_error(image::ImageError::IoError(e)))?;
        let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
            .map_err(read_error)?
            .to_rgba8();
        let pixels = img
            .pixels()
            .map(|p| {
                let a = p[3] as f32 / 255.0;
                [
                    p[0] as f32 / 255.0 * a,
                    p[1] as f32 / 255.0 * a,
                    p[2] as f32 / 255.0 * a,
                    a,
                ]
            })
            .collect();
        Ok(Image {
            width: img.width(),
            height: img.height(),
            pixels,
        })
    }

    /// Writes `<stem>-actual.png`, `<stem>-expected.png` (both over white) and `<stem>-diff.png`
    /// (see [`Self::difference`]) into `dir`, creating it: what a person looks at when an image
    /// comparison fails.
    pub fn save_comparison(
        &self,
        reference: &Image,
        dir: &Path,
        stem: &str,
        full_scale: f32,
    ) -> Result<(), ImageError> {
        std::fs::create_dir_all(dir).map_err(|e| ImageError::Write {
            path: dir.display().to_string(),
            source: image::ImageError::IoError(e),
        })?;
        let white = Some([1.0; 3]);
        self.save_png(&dir.join(format!("{stem}-actual.png")), white)?;
        reference.save_png(&dir.join(format!("{stem}-expected.png")), white)?;
        self.difference(reference, full_scale)?
            .save_png(&dir.join(format!("{stem}-diff.png")), None)
    }

    /// Both images' pixel counts are right ([`ImageError::PixelCount`]; zipped, a short one
    /// was compared on its pixels alone) and their sizes are equal.
    fn check_size(&self, other: &Image) -> Result<(), ImageError> {
        self.check_pixels()?;
        other.check_pixels()?;
        if (self.width, self.height) != (other.width, other.height) {
            return Err(ImageError::SizeMismatch(
                self.width,
                self.height,
                other.width,
                other.height,
            ));
        }
        Ok(())
    }
}

/// The reference covers the pixel (alpha > 0.01) and the result leaves it empty (alpha < 0.001
/// or NaN).
fn is_hole(result: &[f32; 4], reference: &[f32; 4]) -> bool {
    reference[3] > 0.01 && (result[3].is_nan() || result[3] < 0.001)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metrics_count_holes_spill_and_error() {
        let mut g = Image::new(2, 1);
        let mut r = Image::new(2, 1);
        g.pixels[0] = [0.5, 0.0, 0.0, 0.5];
        r.pixels[1] = [0.0, 0.2, 0.0, 0.2];
        let m = r.compare(&g).unwrap();
        assert_eq!((m.holes, m.spill, m.non_finite), (1, 1, 0));
        assert!((m.max_abs - 0.5).abs() < 1e-7);
        let expect = ((0.25 + 0.25 + 0.04 + 0.04) / 8.0f64).sqrt();
        assert!((m.rmse - expect).abs() < 1e-7);
        assert_eq!(g.compare(&g).unwrap().psnr, f64::INFINITY);
    }

    #[test]
    fn nan_pixels_are_counted_and_cost_full_error() {
        let g = Image::new(1, 1);
        let mut r = Image::new(1, 1);
        r.pixels[0][0] = f32::NAN;
        let m = r.compare(&g).unwrap();
        assert_eq!(m.non_finite, 1);
        assert_eq!(m.max_abs, 1.0);
    }

    #[test]
    fn png_round_trip_over_background() {
        let mut img = Image::new(2, 2);
        img.pixels[0] = [0.25, 0.0, 0.0, 0.5];
        let dir = std::env::temp_dir().join(format!("tetvr-img-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("a.png");
        img.save_png(&p, Some([1.0, 1.0, 1.0])).unwrap();
        let back = Image::load_png(&p).unwrap();
        // 0.25 + 0.5 * 1 = 0.75 red; green and blue 0.5; opaque.
        let px = back.get(0, 0);
        assert!(
            (px[0] - 0.75).abs() < 1.0 / 255.0 && (px[1] - 0.5).abs() < 1.0 / 255.0 && px[3] == 1.0
        );
        assert_eq!(
            img.compare(&Image::new(3, 2)).unwrap_err().to_string(),
            "images differ in size: 2x2 and 3x2; render both at the same --size"
        );
    }
}
