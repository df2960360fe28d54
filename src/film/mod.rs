//! Images and their writers: OpenEXR (32-bit float), PNG (8-bit sRGB with an exposure) and
//! Radiance HDR (RGBE, the paper's "real pixels"), picked by the file extension. Every writer
//! writes a temporary file beside the target and renames it, so no half-written file is left.

use std::fs;
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};

use glam::Vec3;

/// A linear RGB image, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

impl Image {
    pub fn new(width: u32, height: u32) -> Self {
        Image { width, height, pixels: vec![Vec3::ZERO; width as usize * height as usize] }
    }

    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    pub fn set(&mut self, x: u32, y: u32, c: Vec3) {
        self.pixels[y as usize * self.width as usize + x as usize] = c;
    }

    /// The mean over all pixels, per channel (accumulated in f64).
    pub fn mean(&self) -> Vec3 {
        let mut sum = [0.0f64; 3];
        for p in &self.pixels {
            for (s, c) in sum.iter_mut().zip(p.to_array()) {
                *s += c as f64;
            }
        }
        let n = self.pixels.len().max(1) as f64;
        Vec3::new((sum[0] / n) as f32, (sum[1] / n) as f32, (sum[2] / n) as f32)
    }
}

/// The file formats lightsplit writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Exr,
    Png,
    Hdr,
}

/// A failure to write an image.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    #[error("{0}: unknown image extension (use .exr, .png or .hdr)")]
    Extension(PathBuf),
    #[error("{0}: {1}")]
    Io(PathBuf, String),
}

impl Format {
    /// The format for a path's extension, case-insensitive.
    pub fn from_path(path: &Path) -> Result<Format, WriteError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("exr") => Ok(Format::Exr),
            Some("png") => Ok(Format::Png),
            Some("hdr") => Ok(Format::Hdr),
            _ => Err(WriteError::Extension(path.to_path_buf())),
        }
    }
}

/// Checks, before any work is done, that `path` has a known extension and a directory that
/// exists, so a long render never ends in an unwritable output.
pub fn check_output(path: &Path) -> Result<Format, WriteError> {
    let format = Format::from_path(path)?;
    let dir = parent_dir(path);
    if !dir.is_dir() {
        return Err(WriteError::Io(
            path.to_path_buf(),
            format!("the directory {} does not exist", dir.display()),
        ));
    }
    Ok(format)
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// 8-bit sRGB encoding of a linear value, after scaling by 2^exposure.
pub fn srgb8(linear: f32, exposure: f32) -> u8 {
    let c = (linear * exposure.exp2()).clamp(0.0, 1.0);
    let c = if c.is_nan() { 0.0 } else { c };
    let s = if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// Writes `image` to `path` in the format its extension names. `exposure` (stops) applies to
/// PNG only: EXR and HDR keep the linear values.
pub fn write(image: &Image, path: &Path, exposure: f32) -> Result<(), WriteError> {
    let format = Format::from_path(path)?;
    let io_err = |e: String| WriteError::Io(path.to_path_buf(), e);
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    // Same directory, so the rename is atomic; the same extension, for writers that look at it.
    let tmp = parent_dir(path).join(format!(".{name}.{}.tmp.{}", std::process::id(), extension(format)));
    let result = match format {
        Format::Exr => write_exr(image, &tmp),
        Format::Png => write_png(image, &tmp, exposure),
        Format::Hdr => write_hdr(image, &tmp),
    };
    match result.and_then(|()| fs::rename(&tmp, path).map_err(|e| e.to_string())) {
        Ok(()) => Ok(()),
        Err(e) => {
            let _ = fs::remove_file(&tmp);
            Err(io_err(e))
        }
    }
}

fn extension(format: Format) -> &'static str {
    match format {
        Format::Exr => "exr",
        Format::Png => "png",
        Format::Hdr => "hdr",
    }
}

fn write_exr(image: &Image, path: &Path) -> Result<(), String> {
    let w = image.width as usize;
    exr::prelude::write_rgb_file(path, w, image.height as usize, |x, y| {
        let c = image.pixels[y * w + x];
        (c.x, c.y, c.z)
    })
    .map_err(|e| e.to_string())
}

fn write_png(image: &Image, path: &Path, exposure: f32) -> Result<(), String> {
    let bytes: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|c| [srgb8(c.x, exposure), srgb8(c.y, exposure), srgb8(c.z, exposure)])
        .collect();
    let buffer = image::RgbImage::from_raw(image.width, image.height, bytes)
        .ok_or_else(|| "image buffer has the wrong size".to_string())?;
    buffer.save_with_format(path, image::ImageFormat::Png).map_err(|e| e.to_string())
}

fn write_hdr(image: &Image, path: &Path) -> Result<(), String> {
    let file = fs::File::create(path).map_err(|e| e.to_string())?;
    let pixels: Vec<image::Rgb<f32>> =
        image.pixels.iter().map(|c| image::Rgb([c.x.max(0.0), c.y.max(0.0), c.z.max(0.0)])).collect();
    let mut out = BufWriter::new(file);
    image::codecs::hdr::HdrEncoder::new(&mut out)
        .encode(&pixels, image.width as usize, image.height as usize)
        .map_err(|e| e.to_string())?;
    io::Write::flush(&mut out).map_err(|e| e.to_string())
}

/// Reads the RGB layer of an EXR file written by [`write`] (or any RGB EXR).
pub fn read_exr(path: &Path) -> Result<self::Image, String> {
    use exr::prelude::*;
    let img = read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![Vec3::ZERO; res.width() * res.height()]),
        |(w, px): &mut (usize, Vec<Vec3>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = Vec3::new(r, g, b);
        },
    )
    .map_err(|e| format!("{}: {e}", path.display()))?;
    let size = img.layer_data.size;
    Ok(self::Image {
        width: size.width() as u32,
        height: size.height() as u32,
        pixels: img.layer_data.channel_data.pixels.1,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient() -> Image {
        let mut img = Image::new(5, 3);
        for y in 0..3 {
            for x in 0..5 {
                img.set(x, y, Vec3::new(x as f32 * 0.25, y as f32 * 0.5, 1000.0 + x as f32));
            }
        }
        img
    }

    #[test]
    fn exr_round_trips_exactly() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("a.exr");
        let img = gradient();
        write(&img, &path, 0.0).expect("write");
        assert_eq!(read_exr(&path).expect("read"), img);
        // Only the final file is left behind.
        assert_eq!(fs::read_dir(dir.path()).expect("dir").count(), 1);
    }

    #[test]
    fn hdr_is_rgbe_within_its_precision() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("a.hdr");
        let img = gradient();
        write(&img, &path, 0.0).expect("write");
        let bytes = fs::read(&path).expect("read");
        assert!(bytes.starts_with(b"#?RADIANCE"));
        let decoded = image::open(&path).expect("decode").into_rgb32f();
        for (a, b) in decoded.pixels().zip(&img.pixels) {
            for (x, y) in a.0.iter().zip(b.to_array()) {
                // RGBE keeps 8 mantissa bits relative to the largest channel.
                assert!((x - y).abs() <= b.max_element() / 128.0, "{x} vs {y}");
            }
        }
    }

    #[test]
    fn png_applies_srgb_and_exposure() {
        assert_eq!(srgb8(0.0, 0.0), 0);
        assert_eq!(srgb8(1.0, 0.0), 255);
        assert_eq!(srgb8(0.215_860_5, 0.0), 128);
        assert_eq!(srgb8(0.215_860_5 / 2.0, 1.0), 128);
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("a.png");
        write(&gradient(), &path, 0.0).expect("write");
        let png = image::open(&path).expect("decode").into_rgb8();
        assert_eq!(png.get_pixel(4, 2).0, [255, 255, 255]);
        assert_eq!(png.get_pixel(0, 0).0[0], 0);
    }

    #[test]
    fn bad_extension_and_missing_directory_fail_before_writing() {
        assert!(matches!(check_output(Path::new("x.jpg")), Err(WriteError::Extension(_))));
        assert!(matches!(check_output(Path::new("/no/such/dir/x.png")), Err(WriteError::Io(..))));
        assert_eq!(check_output(Path::new("x.EXR")).expect("ok"), Format::Exr);
    }
}
