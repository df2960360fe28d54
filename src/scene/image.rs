//! Images: linear RGB rasters, and the one decoder of image files, for textures here and for
//! `compare`, `converge` and the filters above. EXR and Radiance HDR are read as they are, any
//! other file (PNG) as 8-bit sRGB. The film re-exports these and keeps the writers.

use std::path::Path;

use glam::Vec3;

/// A linear RGB image, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` colours, row by row from the top.
    pub pixels: Vec<Vec3>,
}

impl Image {
    /// A black image. Allocated as zeroed floats (one calloc, whose fresh pages the system
    /// zeroes lazily, on the first write of whichever thread gets there): `vec![Vec3::ZERO; n]`
    /// would write every pixel first, on one thread, which for a 4K image took 40 ms, longer
    /// than a filter pass over it.
    pub fn new(width: u32, height: u32) -> Self {
        let floats = vec![0.0f32; 3 * width as usize * height as usize];
        Image { width, height, pixels: bytemuck::allocation::cast_vec(floats) }
    }

    /// An image of no pixels: a buffer a render did not need.
    pub fn empty() -> Self {
        Image { width: 0, height: 0, pixels: Vec::new() }
    }

    /// The pixel at column `x`, row `y` (from the top).
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// Sets the pixel at column `x`, row `y` (from the top).
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

/// Named single-float channels, in writing order.
pub type Channels = Vec<(String, Vec<f32>)>;

/// Reads every float channel of an EXR's first layer, by name, with the image size.
pub fn read_exr_channels(path: &Path) -> Result<(u32, u32, Channels), String> {
    use exr::prelude::*;
    let image = read_all_flat_layers_from_file(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let layer = image.layer_data.first().ok_or_else(|| format!("{}: no layers", path.display()))?;
    let size = layer.size;
    let channels = layer
        .channel_data
        .list
        .iter()
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect::<Vec<f32>>()))
        .collect();
    Ok((size.width() as u32, size.height() as u32, channels))
}

/// A portable float map (`PF`, RGB; `Pf`, grey): a negative scale means little-endian floats;
/// rows run bottom to top.
fn read_pfm(path: &Path) -> Result<Image, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let bad = |what: &str| format!("{}: not a portable float map ({what})", path.display());
    // Three whitespace-separated header lines: the kind, the size, the scale; one byte after.
    let mut fields = Vec::new();
    let mut at = 0;
    while fields.len() < 4 {
        while bytes.get(at).is_some_and(u8::is_ascii_whitespace) {
            at += 1;
        }
        let start = at;
        while bytes.get(at).is_some_and(|b| !b.is_ascii_whitespace()) {
            at += 1;
        }
        if start == at {
            return Err(bad("short header"));
        }
        fields.push(std::str::from_utf8(&bytes[start..at]).map_err(|_| bad("header"))?);
    }
    let channels = match fields[0] {
        "PF" => 3,
        "Pf" => 1,
        _ => return Err(bad("no PF or Pf")),
    };
    let size = |s: &str| s.parse::<u32>().ok().filter(|&n| n > 0 && n <= 1 << 16);
    let (width, height) = size(fields[1]).zip(size(fields[2])).ok_or_else(|| bad("size"))?;
    let scale: f32 = fields[3].parse().map_err(|_| bad("scale"))?;
    let data = bytes.get(at + 1..).unwrap_or_default();
    let n = width as usize * height as usize;
    if data.len() < n * channels * 4 {
        return Err(bad("fewer pixels than its size"));
    }
    let value = |i: usize| {
        let b = [data[4 * i], data[4 * i + 1], data[4 * i + 2], data[4 * i + 3]];
        if scale < 0.0 {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    };
    let mut pixels = Vec::with_capacity(n);
    for y in (0..height as usize).rev() {
        for x in 0..width as usize {
            let i = (y * width as usize + x) * channels;
            pixels.push(if channels == 3 {
                Vec3::new(value(i), value(i + 1), value(i + 2))
            } else {
                Vec3::splat(value(i))
            });
        }
    }
    Ok(Image { width, height, pixels })
}

/// Reads an image as linear RGB: the `R`, `G`, `B` channels of an EXR, a Radiance HDR or a
/// portable float map as it is, any other file (PNG) decoded from 8-bit sRGB.
pub fn read(path: &Path) -> Result<Image, String> {
    read_with(path, true)
}

/// Reads an image as data rather than colour: as [`read`] does, but 8-bit files (PNG) as their
/// values over 255, without the sRGB curve (a height map).
pub fn read_linear(path: &Path) -> Result<Image, String> {
    read_with(path, false)
}

fn read_with(path: &Path, srgb: bool) -> Result<Image, String> {
    // A decoder says of an empty file only that it ended early.
    if std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.len() == 0) {
        return Err(format!("{}: the file is empty (0 bytes)", path.display()));
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("exr") => {
            let (width, height, channels) = read_exr_channels(path)?;
            let get = |name: &str| {
                channels
                    .iter()
                    .find(|(n, _)| n == name)
                    .map(|(_, d)| d)
                    .ok_or_else(|| format!("{}: no `{name}` channel", path.display()))
            };
            let (r, g, b) = (get("R")?, get("G")?, get("B")?);
            Ok(Image { width, height, pixels: (0..r.len()).map(|i| Vec3::new(r[i], g[i], b[i])).collect() })
        }
        Some("pfm") => read_pfm(path),
        Some("hdr") => {
            let img = image::open(path).map_err(|e| format!("{}: {e}", path.display()))?.into_rgb32f();
            Ok(Image {
                width: img.width(),
                height: img.height(),
                pixels: img.pixels().map(|p| Vec3::from(p.0)).collect(),
            })
        }
        _ => {
            let img = image::open(path).map_err(|e| format!("{}: {e}", path.display()))?.into_rgb8();
            let decode = |c: u8| if srgb { srgb_to_linear(c as f32 / 255.0) } else { c as f32 / 255.0 };
            Ok(Image {
                width: img.width(),
                height: img.height(),
                pixels: img.pixels().map(|p| Vec3::from(p.0.map(decode))).collect(),
            })
        }
    }
}

/// The linear value of an sRGB-encoded one in [0, 1].
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}
