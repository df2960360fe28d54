//! Images: linear RGB rasters, and the one decoder of image files, for textures here and for
//! `compare`, `converge` and the filters above. EXR and Radiance HDR are read as they are, any
//! other file (PNG) as 8-bit sRGB. The film re-exports these and keeps the writers.

use std::path::Path;

use glam::Vec3;
use rayon::prelude::*;

use crate::scene::limits;

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

    /// Whether every pixel is exactly zero (a layer with no light: a filter leaves it as it is).
    pub fn is_black(&self) -> bool {
        all_black(&self.pixels)
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

/// Named 32-bit whole-number channels, in writing order (a part file keeps its f64 sums in
/// two such channels each, bit for bit).
pub type Words = Vec<(String, Vec<u32>)>;

/// Whether every one of `pixels` is exactly zero ([`Image::is_black`] of any image's pixels).
pub fn all_black(pixels: &[Vec3]) -> bool {
    pixels.par_iter().all(|p| *p == Vec3::ZERO)
}

/// Reads every channel of an EXR's first layer, by name, with the image size: the whole-number
/// (`u32`) channels converted to floats as the others are.
pub fn read_exr_channels(path: &Path) -> Result<(u32, u32, Channels), String> {
    let (width, height, mut channels, words) = read_exr_layer(path)?;
    channels.extend(words.into_iter().map(|(name, w)| (name, w.into_iter().map(|v| v as f32).collect())));
    Ok((width, height, channels))
}

/// Reads an EXR's first layer: its size, its float (half and full) channels as `f32` and its
/// whole-number channels as they are. The headers are checked first ([`check_exr_headers`]),
/// so a file that declares more pixels than it holds or than memory holds allocates nothing.
pub fn read_exr_layer(path: &Path) -> Result<(u32, u32, Channels, Words), String> {
    exr_layer(path).map_err(|e| format!("{}: {e}", path.display()))
}

/// [`read_exr_layer`], its errors not naming the file (for a caller that names it).
pub(crate) fn exr_layer(path: &Path) -> Result<(u32, u32, Channels, Words), String> {
    use exr::prelude::*;
    check_exr_headers(path)?;
    let image = read_all_flat_layers_from_file(path).map_err(|e| e.to_string())?;
    let layer = image.layer_data.first().ok_or("no layers")?;
    let size = layer.size;
    let (mut channels, mut words) = (Channels::new(), Words::new());
    for c in &layer.channel_data.list {
        let name = c.name.to_string();
        match &c.sample_data {
            FlatSamples::U32(v) => words.push((name, v.clone())),
            other => channels.push((name, other.values_as_f32().collect())),
        }
    }
    Ok((size.width() as u32, size.height() as u32, channels, words))
}

/// The channels `{prefix}R`, `{prefix}G` and `{prefix}B` of an EXR's first layer, decoded into
/// the image and no other channel kept: a render's EXR holds 49 channels, which [`exr_layer`]
/// would hold all of (1.6 GB at 4K, to compare three). Without one of them, `Ok(Err(names))`:
/// the first layer's channel names, for the caller's message.
pub fn read_exr_rgb(path: &Path, prefix: &str) -> Result<Result<Image, Vec<String>>, String> {
    use exr::prelude::*;
    let meta = check_exr_headers(path)?;
    let header = meta.headers.first().ok_or("no layers")?;
    let [r, g, b] = ["R", "G", "B"].map(|c| format!("{prefix}{c}"));
    if ![&r, &g, &b].into_iter().all(|n| header.channels.list.iter().any(|c| c.name == *n.as_str())) {
        return Ok(Err(header.channels.list.iter().map(|c| c.name.to_string()).collect()));
    }
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .specific_channels()
        .required(r.as_str())
        .required(g.as_str())
        .required(b.as_str())
        .collect_pixels(
            |size, _| (size.width(), vec![Vec3::ZERO; size.width() * size.height()]),
            |(width, pixels): &mut (usize, Vec<Vec3>), at, (r, g, b): (f32, f32, f32)| {
                pixels[at.y() * *width + at.x()] = Vec3::new(r, g, b)
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| e.to_string())?;
    let layer = image.layer_data;
    let (width, height) = (layer.size.width() as u32, layer.size.height() as u32);
    Ok(Ok(self::Image { width, height, pixels: layer.channel_data.pixels.1 }))
}

/// The most bytes of pixels an EXR's compression packs into one byte of file, with room to
/// spare: deflate (ZIP, PXR24) packs at most 1032 to 1, RLE 64, PIZ's run-length Huffman codes
/// a few hundred, B44 about 2.
const MAX_PACKING: u64 = 4096;

/// Checks what an EXR's headers declare before any pixel is decoded, since the decoder
/// allocates every layer's samples from the declared size before it reads a block: a file of a
/// few hundred bytes can declare a 65536x32768 layer (12 GiB of samples). Each layer must be
/// at most [`MAX_SIZE`](limits::MAX_SIZE) a side and [`MAX_IMAGE_PIXELS`](limits::MAX_IMAGE_PIXELS)
/// in all, with tiles of at most that size; the file must be long enough to hold the pixels it
/// declares (uncompressed, byte for byte; compressed, at [`MAX_PACKING`]); and the samples,
/// with their 32-bit copies and the block offsets, must fit in the memory available. Returns
/// the headers it read.
pub fn check_exr_headers(path: &Path) -> Result<exr::meta::MetaData, String> {
    use exr::meta::{BlockDescription, MetaData};
    let meta = MetaData::read_from_file(path, false).map_err(|e| e.to_string())?;
    let file_bytes = std::fs::metadata(path).map_err(|e| e.to_string())?.len();
    let max_side = limits::MAX_SIZE as u64;
    let mut need = 0u64;
    for header in &meta.headers {
        let (w, h) = (header.layer_size.width() as u64, header.layer_size.height() as u64);
        if w > max_side || h > max_side || w * h > limits::MAX_IMAGE_PIXELS {
            return Err(format!(
                "it declares a layer of {w}x{h} pixels, and an image read has at most {max_side} a side and \
                 {} in all",
                limits::MAX_IMAGE_PIXELS
            ));
        }
        if let BlockDescription::Tiles(tiles) = header.blocks {
            let (tw, th) = (tiles.tile_size.width() as u64, tiles.tile_size.height() as u64);
            if tw > max_side || th > max_side {
                return Err(format!(
                    "it declares tiles of {tw}x{th} pixels, and a tile has at most {max_side} a side"
                ));
            }
        }
        let channels = header.channels.list.len() as u64;
        let sample_bytes: u64 =
            header.channels.list.iter().map(|c| c.sample_type.bytes_per_sample() as u64).sum();
        let pixel_bytes = w * h * sample_bytes;
        // Every declared sample is in the file, packed at most so far.
        let uncompressed = header.compression == exr::compression::Compression::Uncompressed;
        let packing = if uncompressed { 1 } else { MAX_PACKING };
        if pixel_bytes > file_bytes.saturating_mul(packing) {
            let how = if uncompressed {
                "uncompressed".to_string()
            } else {
                format!("more than the {packing} to 1 any EXR compression packs")
            };
            return Err(format!(
                "it declares {w}x{h} pixels of {channels} channels, {pixel_bytes} bytes, in a file of \
                 {file_bytes} bytes ({how}): the pixels are not there"
            ));
        }
        // The decoder's samples, the 32-bit copy made of them and the offset table.
        need += pixel_bytes + w * h * channels * 4 + header.chunk_count as u64 * 8;
    }
    limits::check_memory(need, "reading its pixels")?;
    Ok(meta)
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
        Some("exr") => match read_exr_rgb(path, "") {
            Ok(Ok(image)) => Ok(image),
            Ok(Err(names)) => {
                let missing =
                    ["R", "G", "B"].into_iter().find(|c| !names.iter().any(|n| n == c)).unwrap_or("R");
                Err(format!("{}: no `{missing}` channel", path.display()))
            }
            Err(e) => Err(format!("{}: {e}", path.display())),
        },
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

/// Reads an image as coverage (an OBJ's `map_d`), in all three channels: its alpha channel
/// where it has one, else its first channel, as data (without the sRGB curve).
pub fn read_coverage(path: &Path) -> Result<Image, String> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if matches!(ext.as_deref(), Some("exr" | "pfm" | "hdr")) {
        let image = read_linear(path)?;
        return Ok(Image { pixels: image.pixels.iter().map(|p| Vec3::splat(p.x)).collect(), ..image });
    }
    if std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.len() == 0) {
        return Err(format!("{}: the file is empty (0 bytes)", path.display()));
    }
    let img = image::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let alpha = img.color().has_alpha();
    let img = img.into_rgba32f();
    let pick = |p: &image::Rgba<f32>| Vec3::splat(if alpha { p.0[3] } else { p.0[0] });
    Ok(Image { width: img.width(), height: img.height(), pixels: img.pixels().map(pick).collect() })
}

/// The linear value of an sRGB-encoded one in [0, 1].
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}
