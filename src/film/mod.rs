//! Images and their writers: OpenEXR (32-bit float), PNG (8-bit sRGB with an exposure) and
//! Radiance HDR (RGBE, the paper's "real pixels"), picked by the file extension. Every writer
//! writes a temporary file beside the target and renames it, so no half-written file is left.

use std::fs;
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use glam::Vec3;

pub mod cryptomatte;
pub mod layers;
mod sums;

pub use crate::scene::image::{read_exr_channels, read_exr_layer, Channels, Image, Words};
pub use sums::{Squares, Sums};

use crate::component::{Component, Split};

/// Everything a render measures per pixel: the beauty, its split by light path, and the guide
/// buffers the edge-aware filter reads.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    /// The unfiltered beauty (the `raw` layer).
    pub raw: Image,
    /// The light-path components: they sum to `raw` up to float rounding.
    pub components: Split<Image>,
    pub albedo: Image,
    /// Unit shading normals (zero where the path left the scene).
    pub normal: Image,
    pub depth: Vec<f32>,
    /// Object ID of one chosen sample per pixel, -1 for none; never averaged.
    pub object: Vec<f32>,
    /// The fraction of the pixel's samples that saw that object: below 1 on an antialiased
    /// border, where the pixel mixes two surfaces.
    pub coverage: Vec<f32>,
    /// The fraction of the pixel's samples that hit a surface (any object): the EXR's alpha,
    /// 0 where only the background (a sky, or nothing) is seen.
    pub alpha: Vec<f32>,
    /// The variance of each pixel's mean luminance, of the beauty, estimated from its samples
    /// ([`variance_of_mean`]); empty without the split. While a render runs: the sum of the
    /// squared sample luminances.
    pub variance: Vec<f32>,
    /// The same for each component.
    pub component_variance: Split<Vec<f32>>,
    /// The beauty's sum over the samples of each pixel's second half ([`halves`]), divided by
    /// all its samples: so the second half's mean is `half / half_share` and the first's
    /// `(raw - half) / (1 - half_share)`. Empty without the split, or with a splatted filter.
    pub half: Image,
    /// The same for each component.
    pub component_half: Split<Image>,
    /// The share of each pixel's samples in its second half.
    pub half_share: Vec<f32>,
    /// The layers of light path expressions the render was asked for, in order (summed and
    /// averaged as the components are; no variance).
    pub aovs: Vec<AovLayer>,
    /// The Cryptomatte types the render was asked for, by type name (`--cryptomatte`).
    pub mattes: Vec<cryptomatte::Matte>,
}

/// An AOV's layer ([`crate::scene::Aov`]): the light of the paths its expression matches,
/// written as `name.R/G/B`.
#[derive(Clone, Debug, PartialEq)]
pub struct AovLayer {
    pub name: String,
    pub image: Image,
}

/// The names of the AOVs of a film, as its EXR header lists them ([`AOVS_ATTRIBUTE`]).
pub fn aov_list(aovs: &[AovLayer]) -> String {
    aovs.iter().map(|a| a.name.as_str()).collect::<Vec<_>>().join(",")
}

/// The header attribute that lists a render's AOVs, by name, comma-separated.
pub const AOVS_ATTRIBUTE: &str = "lightsplit.aovs";

/// The header attribute with each AOV's expression, `NAME=EXPR;...`.
pub const AOV_LPES_ATTRIBUTE: &str = "lightsplit.aov_lpes";

/// The attributes of `meta` that say what its AOVs are (for a file made from it).
pub fn aov_attributes(meta: &Metadata) -> impl Iterator<Item = (String, String)> + '_ {
    meta.extra.iter().filter(|(n, _)| n == AOVS_ATTRIBUTE || n == AOV_LPES_ATTRIBUTE).cloned()
}

/// The AOVs an EXR's header lists ([`AOVS_ATTRIBUTE`]; none without it), each name checked.
pub fn aov_names(meta: &Metadata) -> Result<Vec<String>, String> {
    let Some((_, list)) = meta.extra.iter().find(|(n, _)| n == AOVS_ATTRIBUTE) else {
        return Ok(Vec::new());
    };
    let names: Vec<String> = list.split(',').map(str::to_string).collect();
    for (i, name) in names.iter().enumerate() {
        let valid = name.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            && !layers::is_reserved(name)
            && !names[..i].contains(name);
        if !valid {
            return Err(format!("`{AOVS_ATTRIBUTE}` names `{name}`, which cannot be an AOV"));
        }
    }
    Ok(names)
}

/// The variance of the mean of `n` samples from their sum and sum of squares: the unbiased
/// sample variance over `n`, never negative. One sample says nothing of its spread: its
/// square, an upper bound, is returned.
pub fn variance_of_mean(n: u32, sum: f64, sum_sq: f64) -> f64 {
    if n < 2 {
        return sum_sq;
    }
    let n = n as f64;
    let mean = sum / n;
    ((sum_sq - n * mean * mean) / (n - 1.0)).max(0.0) / n
}

/// The variance of the mean of `n` samples from the sums of their luminance, `sum`, and of
/// the luminance of the `n_b` of them in the second half, `sum_b`; none unless both halves have
/// samples.
///
/// A render's samples of a pixel split into two halves by their index ([`half_of`]): each
/// half of a Sobol render is a union of aligned power-of-two blocks of the sequence, so each is
/// itself well stratified, and the difference of their means measures the noise of the whole. With
/// means `a` and `b` of `n_a` and `n_b` samples, `(a - b)² n_a n_b / n²` is unbiased for
/// independent samples (each mean's variance σ²/n_a and σ²/n_b, the whole's σ²/n). The sample
/// variance ([`variance_of_mean`]) assumes independent samples, and overstates a Sobol
/// render's noise: three times at 64 spp on Khronos' DamagedHelmet (docs/RESULTS.md).
pub fn variance_of_halves(n: u32, n_b: u32, sum: f64, sum_b: f64) -> Option<f64> {
    let n_a = n.checked_sub(n_b).filter(|&a| a > 0 && n_b > 0)?;
    let (a, b) = ((sum - sum_b) / n_a as f64, sum_b / n_b as f64);
    let n = n as f64;
    Some((a - b) * (a - b) * n_a as f64 * n_b as f64 / (n * n))
}

/// Which half of a pixel's samples sample `index` of a render of `spp` belongs to: the second
/// when its bit `2^(floor(log2 spp) - 1)` is set. Both halves are unions of aligned
/// power-of-two blocks of samples, each a stratified set of a Sobol sequence, and at a power
/// of two they are its first and second halves.
#[inline]
pub fn half_of(index: u32, spp: u32) -> bool {
    let shift = spp.max(2).ilog2() - 1;
    (index >> shift) & 1 == 1
}

impl Film {
    /// A film with every buffer.
    pub fn new(width: u32, height: u32) -> Film {
        Film::with_buffers(width, height, true, true)
    }

    /// A film with the component split and the guide buffers only when asked for; a buffer
    /// left out is empty (no pixels), and the EXR writer leaves its layers out.
    pub fn with_buffers(width: u32, height: u32, split: bool, guides: bool) -> Film {
        let n = width as usize * height as usize;
        let mut film = Film {
            width,
            height,
            raw: Image::empty(),
            components: Split::from_fn(|_| Image::empty()),
            albedo: Image::empty(),
            normal: Image::empty(),
            depth: Vec::new(),
            object: Vec::new(),
            coverage: Vec::new(),
            alpha: Vec::new(),
            variance: Vec::new(),
            component_variance: Split::from_fn(|_| Vec::new()),
            half: Image::empty(),
            component_half: Split::from_fn(|_| Image::empty()),
            half_share: Vec::new(),
            aovs: Vec::new(),
            mattes: Vec::new(),
        };
        for layer in &layers::LAYERS {
            let on = match layer.group {
                layers::Group::Beauty => true,
                layers::Group::Split | layers::Group::Variance | layers::Group::Halves => split,
                layers::Group::Guides => guides,
            };
            if on {
                film.set_values(layer.buffer, vec![layer.missing; n * layer.width()]);
            }
        }
        film
    }

    /// The film with a zero layer for each AOV of `names`.
    pub fn with_aovs(mut self, names: &[String]) -> Film {
        let (w, h) = (self.width, self.height);
        self.aovs = names.iter().map(|n| AovLayer { name: n.clone(), image: Image::new(w, h) }).collect();
        self
    }

    /// Whether the film holds the component split.
    pub fn has_split(&self) -> bool {
        !self.components[Component::Emitted].pixels.is_empty()
    }

    /// Whether the film holds the halves of its samples ([`Film::half`]).
    pub fn has_halves(&self) -> bool {
        !self.half_share.is_empty()
    }

    /// Whether the film holds the guide buffers.
    pub fn has_guides(&self) -> bool {
        !self.object.is_empty()
    }

    /// Bytes of its pixel buffers.
    pub fn bytes(&self) -> u64 {
        let aovs = self.aovs.iter().map(|a| &a.image);
        let images = [&self.raw, &self.albedo, &self.normal, &self.half]
            .into_iter()
            .chain(&self.components)
            .chain(&self.component_half)
            .chain(aovs);
        let rgb: usize = images.map(|i| i.pixels.capacity() * size_of::<Vec3>()).sum();
        let variance: usize = self.component_variance.iter().map(Vec::capacity).sum();
        let scalars = self.depth.capacity()
            + self.object.capacity()
            + self.coverage.capacity()
            + self.alpha.capacity()
            + self.variance.capacity()
            + self.half_share.capacity()
            + variance;
        (rgb + scalars * size_of::<f32>()) as u64
            + self.mattes.iter().map(cryptomatte::Matte::bytes).sum::<u64>()
    }

    /// The header attributes of its Cryptomatte types ([`cryptomatte::Matte::attributes`]).
    pub fn matte_attributes(&self) -> Vec<(String, String)> {
        self.mattes.iter().flat_map(cryptomatte::Matte::attributes).collect()
    }

    /// `indirect` (L_r,d,d) of this film.
    pub fn indirect(&self) -> &Image {
        &self.components[Component::Indirect]
    }
}

/// The file formats lightsplit writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Exr,
    Png,
    Hdr,
    /// Portable float map: 32-bit float RGB, the beauty only (what Mitsuba and pbrt write).
    Pfm,
}

/// A failure to write an image.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    #[error("{0}: unknown image extension (use .exr, .png, .hdr or .pfm)")]
    Extension(PathBuf),
    /// Refused before any work: the output cannot be written there, or is an input.
    #[error("{0}: {1}")]
    Refused(PathBuf, String),
    /// Writing failed.
    #[error("{0}: {1}")]
    Io(PathBuf, String),
}

impl crate::error::Classify for WriteError {
    fn is_input(&self) -> bool {
        !matches!(self, WriteError::Io(..))
    }
}

impl Format {
    /// The format for a path's extension, case-insensitive.
    pub fn from_path(path: &Path) -> Result<Format, WriteError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("exr") => Ok(Format::Exr),
            Some("png") => Ok(Format::Png),
            Some("hdr") => Ok(Format::Hdr),
            Some("pfm") => Ok(Format::Pfm),
            _ => Err(WriteError::Extension(path.to_path_buf())),
        }
    }
}

/// Checks, before any work is done, that `path` has a known extension and a directory that
/// exists, so a long render never ends in an unwritable output.
pub fn check_output(path: &Path) -> Result<Format, WriteError> {
    let format = Format::from_path(path)?;
    let dir = parent_dir(path);
    let refuse = |why: String| Err(WriteError::Refused(path.to_path_buf(), why));
    if !dir.is_dir() {
        return refuse(format!("the directory {} does not exist", dir.display()));
    }
    if path.is_dir() {
        return refuse("is a directory".into());
    }
    // The image is written to a temporary file beside it and renamed: that must be possible,
    // before any work is done. The probe's name is as long as the temporary's (`.chk.` for
    // `.tmp.`), so a name the directory cannot hold (a name of 250 bytes, 14 more for the
    // temporary's) is found now too, and a watcher of the temporary (a test that stops a write
    // under way) does not take the probe for it.
    let probe = temporary_named(path, std::process::id(), "chk");
    match std::fs::OpenOptions::new().write(true).create_new(true).open(&probe) {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
        }
        // Another run of this process id left it: the name is one the directory holds.
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
        Err(e) if e.kind() == io::ErrorKind::InvalidFilename => {
            let bytes = probe.file_name().map_or(0, |n| n.len());
            return refuse(format!(
                "the name is too long: the file is written as a temporary `.NAME.PID.tmp.EXT` of {bytes} \
                 bytes first, and the directory refuses it ({e})"
            ));
        }
        Err(e) => return refuse(format!("cannot write in {}: {e}", dir.display())),
    }
    Ok(format)
}

/// Refuses an output that is one of `inputs` (the same file, by device and inode: through
/// another name, a link or `..` as well): writing it would destroy what the command reads.
pub fn check_not_an_input(path: &Path, inputs: &[PathBuf]) -> Result<(), WriteError> {
    use std::os::unix::fs::MetadataExt;
    let Ok(out) = std::fs::metadata(path) else { return Ok(()) };
    for input in inputs {
        if let Ok(m) = std::fs::metadata(input) {
            if (m.dev(), m.ino()) == (out.dev(), out.ino()) {
                return Err(WriteError::Refused(
                    path.to_path_buf(),
                    format!("is an input ({}): choose another output", input.display()),
                ));
            }
        }
    }
    Ok(())
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
    write_with(image, path, exposure, &Metadata::default())
}

/// [`write`], with what an EXR's header records of how the image was made.
pub fn write_with(image: &Image, path: &Path, exposure: f32, meta: &Metadata) -> Result<(), WriteError> {
    // A temporary file in the same directory (so the rename is atomic), with the same
    // extension, for writers that look at it.
    match Format::from_path(path)? {
        Format::Exr => atomically(path, |tmp| write_exr(image, meta, tmp)),
        Format::Png => atomically(path, |tmp| write_png(image, tmp, exposure)),
        Format::Hdr => atomically(path, |tmp| write_hdr(image, tmp)),
        Format::Pfm => atomically(path, |tmp| write_pfm(image, tmp)),
    }
}

fn write_exr(image: &Image, meta: &Metadata, path: &Path) -> Result<(), String> {
    let channels: Channels = ["R", "G", "B"]
        .iter()
        .enumerate()
        .map(|(c, n)| (n.to_string(), image.pixels.iter().map(|p| p[c]).collect()))
        .collect();
    write_exr_channels(channels, image.width, image.height, meta, path)
}

fn write_png(image: &Image, path: &Path, exposure: f32) -> Result<(), String> {
    let bytes: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|c| [srgb8(c.x, exposure), srgb8(c.y, exposure), srgb8(c.z, exposure)])
        .collect();
    // A grey image (a difference image, say) is written with one channel: a third of the size.
    let grey = bytes.chunks_exact(3).all(|p| p[0] == p[1] && p[1] == p[2]);
    let (data, color) = if grey {
        (bytes.chunks_exact(3).map(|p| p[0]).collect(), image::ExtendedColorType::L8)
    } else {
        (bytes, image::ExtendedColorType::Rgb8)
    };
    encode_png(path, image.width, image.height, &data, color)
}

/// PNG with the encoder's best compression (these files are committed and published), an sRGB
/// chunk (the pixels are sRGB-encoded, so viewers need not guess) and a `Software` text chunk.
fn encode_png(
    path: &Path,
    width: u32,
    height: u32,
    data: &[u8],
    color: image::ExtendedColorType,
) -> Result<(), String> {
    let color = match color {
        image::ExtendedColorType::L8 => png::ColorType::Grayscale,
        image::ExtendedColorType::Rgb8 => png::ColorType::Rgb,
        image::ExtendedColorType::Rgba8 => png::ColorType::Rgba,
        other => return Err(format!("PNG: no 8-bit encoding for {other:?}")),
    };
    let file = BufWriter::new(fs::File::create(path).map_err(|e| e.to_string())?);
    let mut encoder = png::Encoder::new(file, width, height);
    encoder.set_color(color);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::High);
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    encoder.add_text_chunk("Software".into(), SOFTWARE.into()).map_err(|e| e.to_string())?;
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(data).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())
}

/// The software that wrote a file, as its metadata names it.
pub const SOFTWARE: &str = concat!("lightsplit ", env!("CARGO_PKG_VERSION"));

/// One pixel as Radiance RGBE, each channel rounded to the nearest step of the shared exponent
/// (the largest channel's, after rounding: a mantissa that rounds up to 256 takes the next
/// exponent). Negative and NaN values are written as 0. Read back as `mantissa 2^(e - 136)`,
/// as the `image` crate, stb_image and pbrt read it, a value is off by at most half a step and
/// by nothing on average; truncating, as the `image` crate's encoder does, lost half a step on
/// average (0.3 to 1.1% of the light).
fn rgbe(c: Vec3) -> [u8; 4] {
    let c = c.to_array().map(|x| if x > 0.0 { x.min(f32::MAX) as f64 } else { 0.0 });
    let v = c[0].max(c[1]).max(c[2]);
    if v < 1e-32 {
        return [0; 4];
    }
    // v = m 2^e with m in [0.5, 1): a channel's mantissa is x / 2^e * 256, rounded.
    let mut e = v.log2().floor() as i32 + 1;
    let mantissa = |x: f64, e: i32| (x * 256.0 / 2f64.powi(e) + 0.5).floor();
    if mantissa(v, e) >= 256.0 {
        e += 1;
    }
    let [r, g, b] = c.map(|x| mantissa(x, e).min(255.0) as u8);
    [r, g, b, (e + 128).clamp(0, 255) as u8]
}

/// Radiance RGBE (`.hdr`), flat scanlines, every channel rounded ([`rgbe`]).
fn write_hdr(image: &Image, path: &Path) -> Result<(), String> {
    let mut out = BufWriter::new(fs::File::create(path).map_err(|e| e.to_string())?);
    let header = format!(
        "#?RADIANCE\nSOFTWARE={SOFTWARE}\nFORMAT=32-bit_rle_rgbe\n\n-Y {} +X {}\n",
        image.height, image.width
    );
    let mut bytes = header.into_bytes();
    bytes.extend(image.pixels.iter().flat_map(|&c| rgbe(c)));
    io::Write::write_all(&mut out, &bytes).map_err(|e| e.to_string())?;
    io::Write::flush(&mut out).map_err(|e| e.to_string())
}

/// A portable float map: the header `PF`, the size and a negative scale (little-endian), then
/// the rows bottom to top, three 32-bit floats a pixel.
fn write_pfm(image: &Image, path: &Path) -> Result<(), String> {
    let (w, h) = (image.width as usize, image.height as usize);
    let mut out = BufWriter::new(fs::File::create(path).map_err(|e| e.to_string())?);
    let mut write = |bytes: &[u8]| io::Write::write_all(&mut out, bytes).map_err(|e| e.to_string());
    write(format!("PF\n{w} {h}\n-1.0\n").as_bytes())?;
    for row in image.pixels.chunks_exact(w.max(1)).rev().take(h) {
        let bytes: Vec<u8> = row.iter().flat_map(|c| c.to_array()).flat_map(f32::to_le_bytes).collect();
        write(&bytes)?;
    }
    io::Write::flush(&mut out).map_err(|e| e.to_string())
}

/// The channels of a film for a multi-layer EXR: the final image as `R`, `G`, `B`, then
/// `raw`, the four components, `indirect_filtered` (when given), `albedo`, `normal` (X, Y, Z),
/// `depth` (Z) and `objectid` (ID); the split and the guides only when the film holds them.
/// Consumes the film: each buffer is freed as soon as its channels exist, so the channels never
/// sit beside a second copy of the film.
pub fn film_channels(film: Film, final_image: Image, indirect_filtered: Option<Image>) -> Channels {
    let mut out: Channels = Vec::new();
    // A buffer the render did not fill (empty) has no layer.
    let mut rgb = |names: [&str; 3], img: Image| {
        if img.pixels.is_empty() {
            return;
        }
        for (c, name) in names.iter().enumerate() {
            out.push((name.to_string(), img.pixels.iter().map(|p| p[c]).collect()));
        }
    };
    rgb(["R", "G", "B"], final_image);
    if let Some(f) = indirect_filtered {
        rgb(["indirect_filtered.R", "indirect_filtered.G", "indirect_filtered.B"], f);
    }
    let mut film = film;
    for layer in &layers::LAYERS {
        // Each buffer leaves the film as its channels are made.
        let values = film.take_values(layer.buffer);
        if !values.is_empty() {
            push_layer(&mut out, "", layer, values.into());
        }
    }
    for aov in std::mem::take(&mut film.aovs) {
        push_aov(&mut out, "", aov);
    }
    for matte in std::mem::take(&mut film.mattes) {
        out.extend(matte.rank_channels());
    }
    out
}

/// Pushes an AOV's layer as its channels `NAME.R/G/B`, each after `prefix`.
fn push_aov(out: &mut Channels, prefix: &str, aov: AovLayer) {
    for c in 0..3 {
        out.push((
            format!("{prefix}{}.{}", aov.name, ["R", "G", "B"][c]),
            aov.image.pixels.iter().map(|p| p[c]).collect(),
        ));
    }
}

/// The AOV layers `names` from `channels`, each name after `prefix`: every one required.
pub fn aovs_from_channels(
    width: u32,
    height: u32,
    channels: &Channels,
    prefix: &str,
    names: &[String],
) -> Result<Vec<AovLayer>, String> {
    let n = width as usize * height as usize;
    let find = |name: &str| channels.iter().find(|(c, _)| c == name).map(|(_, d)| d);
    names
        .iter()
        .map(|name| {
            let rgb = ["R", "G", "B"].map(|c| find(&format!("{prefix}{name}.{c}")));
            let [Some(r), Some(g), Some(b)] = rgb else {
                return Err(format!("no `{prefix}{name}` layer (R, G, B) for AOV `{name}`"));
            };
            if [r, g, b].iter().any(|c| c.len() != n) {
                return Err("channel sizes do not match the image".into());
            }
            let pixels = (0..n).map(|i| Vec3::new(r[i], g[i], b[i])).collect();
            Ok(AovLayer { name: name.clone(), image: Image { width, height, pixels } })
        })
        .collect()
}

/// Pushes a layer's values ([`Film::values`]) as its channels, each name after `prefix`: moved
/// into its one channel when it has one, split pixel by pixel when it has three.
fn push_layer(out: &mut Channels, prefix: &str, layer: &layers::LayerDef, values: std::borrow::Cow<[f32]>) {
    let width = layer.width();
    if width == 1 {
        out.push((format!("{prefix}{}", layer.channels[0]), values.into_owned()));
        return;
    }
    for (c, name) in layer.channels.iter().enumerate() {
        out.push((format!("{prefix}{name}"), values.iter().skip(c).step_by(width).copied().collect()));
    }
}

/// The channels of every layer `film` holds ([`layers::LAYERS`]), each name after `prefix`.
pub fn layer_channels(film: &Film, prefix: &str) -> Channels {
    let mut out: Channels = Vec::new();
    for (layer, values) in film.layers() {
        push_layer(&mut out, prefix, layer, values.into());
    }
    for aov in &film.aovs {
        push_aov(&mut out, prefix, aov.clone());
    }
    out
}

/// The layers of a film from `channels`, each name after `prefix`: the layers of the groups
/// `wanted` says, each required ([`layers::LayerDef::required`]) unless `lenient` (an EXR a
/// render wrote: an optional layer it lacks, from before the layer existed, takes its
/// [`layers::LayerDef::missing`] value, or none for the variances). Every channel must have a
/// value for each pixel.
pub fn film_from_layers(
    width: u32,
    height: u32,
    channels: &Channels,
    prefix: &str,
    wanted: impl Fn(layers::Group) -> bool,
    lenient: bool,
) -> Result<Film, String> {
    let n = width as usize * height as usize;
    let find = |name: &str| channels.iter().find(|(c, _)| c == name).map(|(_, d)| d);
    let mut film = Film::with_buffers(width, height, false, false);
    film.variance = Vec::new();
    film.component_variance = Split::from_fn(|_| Vec::new());
    // The variances are all there or none, and so are the halves: a group is there when its
    // first channel is.
    let all_or_none = |g: layers::Group| matches!(g, layers::Group::Variance | layers::Group::Halves);
    let has_group = |g: layers::Group| {
        layers::LAYERS
            .iter()
            .find(|l| l.group == g)
            .is_some_and(|l| find(&format!("{prefix}{}", l.channels[0])).is_some())
    };
    for layer in layers::LAYERS.iter().filter(|l| wanted(l.group)) {
        let found: Vec<Option<&Vec<f32>>> =
            layer.channels.iter().map(|c| find(&format!("{prefix}{c}"))).collect();
        let grouped = all_or_none(layer.group);
        if lenient && grouped && !has_group(layer.group) {
            // A file written before the group existed (or a render without it): none.
            continue;
        }
        // The layers of such a group, once one is there, are all required.
        let optional = lenient && !layer.required && !grouped;
        if let Some(at) = found.iter().position(Option::is_none) {
            if optional {
                film.set_values(layer.buffer, vec![layer.missing; n * layer.width()]);
                continue;
            }
            let hint = if lenient { " (not a lightsplit render?)" } else { "" };
            return Err(format!("no `{prefix}{}` channel{hint}", layer.channels[at]));
        }
        let found: Vec<&Vec<f32>> = found.into_iter().flatten().collect();
        if found.iter().any(|c| c.len() != n) {
            return Err("channel sizes do not match the image".into());
        }
        let values = if found.len() == 1 {
            found[0].clone()
        } else {
            (0..n).flat_map(|i| found.iter().map(move |c| c[i])).collect()
        };
        film.set_values(layer.buffer, values);
    }
    Ok(film)
}

/// Writes a film: every layer into an EXR, or the final image alone into PNG or HDR. Consumes
/// the film and the images, so an EXR's channels replace them rather than copy them.
pub fn write_film(
    film: Film,
    final_image: Image,
    indirect_filtered: Option<Image>,
    path: &Path,
    exposure: f32,
    meta: &Metadata,
) -> Result<(), WriteError> {
    match Format::from_path(path)? {
        Format::Exr => {
            let (width, height) = (film.width, film.height);
            // The Cryptomatte types' attributes, in place of any the metadata brought along.
            let mut meta = meta.clone();
            meta.extra.retain(|(name, _)| !name.starts_with("cryptomatte/"));
            meta.extra.extend(film.matte_attributes());
            let channels = film_channels(film, final_image, indirect_filtered);
            atomically(path, |tmp| write_exr_channels(channels, width, height, &meta, tmp))
        }
        _ => write_with(&final_image, path, exposure, meta),
    }
}

/// Writes named float and whole-number channels as an EXR the way [`write_film`] does: whole
/// or not at all.
pub fn write_exr_atomically(
    path: &Path,
    channels: Channels,
    words: Words,
    width: u32,
    height: u32,
    meta: &Metadata,
) -> Result<(), WriteError> {
    atomically(path, |tmp| write_exr_samples(channels, words, width, height, meta, tmp))
}

/// Writes a text file (a summary, a table) the same way as images: whole or not at all.
pub fn write_text(path: &Path, text: impl AsRef<[u8]>) -> Result<(), WriteError> {
    atomically(path, |tmp| fs::write(tmp, text).map_err(|e| e.to_string()))
}

/// Writes 8-bit RGB pixels (a plot) as a PNG.
pub fn write_rgb8(path: &Path, width: u32, height: u32, rgb: Vec<u8>) -> Result<(), WriteError> {
    if rgb.len() != 3 * width as usize * height as usize {
        return Err(WriteError::Io(path.to_path_buf(), "the pixel buffer does not fit the size".into()));
    }
    atomically(path, |tmp| encode_png(tmp, width, height, &rgb, image::ExtendedColorType::Rgb8))
}

/// The temporary files being written now, removed by [`remove_temporaries`] when a
/// signal stops the process in the middle of a write.
static WRITING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// The temporary file of `path` for the process `pid`: `.NAME.PID.tmp.EXT` beside it (its
/// extension kept, so the encoder knows the format).
fn temporary(path: &Path, pid: u32) -> PathBuf {
    temporary_named(path, pid, "tmp")
}

/// `.NAME.PID.KIND.EXT` beside `path`.
fn temporary_named(path: &Path, pid: u32, kind: &str) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let ext = path.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default();
    parent_dir(path).join(format!(".{name}.{pid}.{kind}.{ext}"))
}

/// Removes the temporaries of `path` that processes no longer running left (a SIGKILL in the
/// middle of a write): those of its own naming whose process id is not in `/proc`. Where there
/// is no `/proc` to ask, nothing is removed.
fn remove_stale_temporaries(path: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let (dir, me) = (parent_dir(path), std::process::id());
    let Some(mine) = temporary(path, me).file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return;
    };
    let (prefix, suffix) = mine.split_once(&format!(".{me}.")).unwrap_or_default();
    let suffix = format!(".{suffix}");
    for entry in fs::read_dir(&dir).into_iter().flatten().flatten() {
        let file = entry.file_name();
        let file = file.to_string_lossy();
        let pid =
            file.strip_prefix(prefix).and_then(|r| r.strip_prefix('.')).and_then(|r| r.strip_suffix(&suffix));
        if let Some(pid) = pid.and_then(|p| p.parse::<u32>().ok()) {
            if pid != me && !Path::new(&format!("/proc/{pid}")).exists() {
                let _ = fs::remove_file(entry.path());
            }
        }
    }
}

/// Writes held: while it lives, no write starts or ends ([`remove_temporaries`]).
pub struct WritesHeld(#[allow(dead_code)] std::sync::MutexGuard<'static, Vec<PathBuf>>);

/// Removes every temporary file being written, and holds the list until the guard returned is
/// dropped, so that no write starts another meanwhile: for a SIGINT or SIGTERM handler, which
/// then ends the process (the outputs already there are left as they were).
pub fn remove_temporaries() -> WritesHeld {
    let writing = WRITING.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    for tmp in writing.iter() {
        let _ = fs::remove_file(tmp);
    }
    WritesHeld(writing)
}

/// Runs `write` on a temporary file beside `path`, then renames it over `path`. The temporary
/// is listed while it exists, so a signal removes it ([`remove_temporaries`]), and the
/// stale temporaries of `path` a killed process left are removed first.
fn atomically(path: &Path, write: impl FnOnce(&Path) -> Result<(), String>) -> Result<(), WriteError> {
    remove_stale_temporaries(path);
    let tmp = temporary(path, std::process::id());
    let listed = |add: bool| {
        let mut writing = WRITING.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        match add {
            true => writing.push(tmp.clone()),
            false => writing.retain(|t| t != &tmp),
        }
    };
    listed(true);
    let result = write(&tmp).and_then(|()| fs::rename(&tmp, path).map_err(|e| e.to_string()));
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    listed(false);
    result.map_err(|e| WriteError::Io(path.to_path_buf(), e))
}

/// How an EXR's pixels are compressed, all lossless. ZIP (the default) makes the smallest
/// files; the others trade bytes for time. A fresh 4K `filter --denoise` (49 channels, 1.6 GB
/// of floats) measured 23.4 s and 447 MB with ZIP, 19.9 s and 504 MB with PIZ, 15.4 s and
/// 602 MB with RLE, 18.7 s and 1.7 GB uncompressed (docs/RESULTS.md, "Denoising").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum ExrCompression {
    /// Deflate over blocks of 16 lines: the smallest files, the slowest to write.
    #[default]
    Zip,
    /// Wavelet and Huffman coding: OpenEXR's choice for grainy images.
    Piz,
    /// Run lengths: little smaller than raw for noisy floats, fast.
    Rle,
    /// No compression.
    None,
}

impl ExrCompression {
    /// Every compression, in the order the command line lists them.
    pub const ALL: [ExrCompression; 4] =
        [ExrCompression::Zip, ExrCompression::Piz, ExrCompression::Rle, ExrCompression::None];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ExrCompression::Zip => "zip",
            ExrCompression::Piz => "piz",
            ExrCompression::Rle => "rle",
            ExrCompression::None => "none",
        }
    }

    /// The compression named `name` (as [`ExrCompression::name`] spells it).
    pub fn parse(name: &str) -> Result<ExrCompression, String> {
        ExrCompression::ALL
            .into_iter()
            .find(|c| c.name() == name)
            .ok_or_else(|| format!("unknown EXR compression `{name}` (zip, piz, rle or none)"))
    }

    /// The `exr` crate's encoding: scan lines in increasing order (for ZIP, blocks of 16 lines:
    /// the crate's `SMALL_LOSSLESS`).
    fn encoding(self) -> exr::image::Encoding {
        use exr::prelude::*;
        let compression = match self {
            ExrCompression::Zip => Compression::ZIP16,
            ExrCompression::Piz => Compression::PIZ,
            ExrCompression::Rle => Compression::RLE,
            ExrCompression::None => Compression::Uncompressed,
        };
        Encoding { compression, blocks: Blocks::ScanLines, line_order: LineOrder::Increasing }
    }

    /// What an EXR header's compression is, as one of these (a lossy or other codec that
    /// lightsplit does not write reads as ZIP, the one it writes by default).
    fn of(compression: exr::compression::Compression) -> Self {
        use exr::compression::Compression as C;
        match compression {
            C::PIZ => ExrCompression::Piz,
            C::RLE => ExrCompression::Rle,
            C::Uncompressed => ExrCompression::None,
            _ => ExrCompression::Zip,
        }
    }
}

/// How an image was made, as its file records it: an EXR's header attributes (pbrt-v4's names
/// where it has one) and, for every format, the software that wrote it. What is not known (a
/// filtered file read back without it, say) is left out.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Metadata {
    /// The scene file, as given (`scene`).
    pub scene: Option<String>,
    /// Samples per pixel (`samplesPerPixel`, as pbrt-v4).
    pub spp: Option<u32>,
    /// The base seed (`seed`; text, to keep all 64 bits).
    pub seed: Option<u64>,
    /// The path length limit (`maxDepth`).
    pub max_depth: Option<u32>,
    /// The sampler's name (`sampler`).
    pub sampler: Option<String>,
    /// The render's wall-clock seconds (`renderTimeSeconds`, as pbrt-v4).
    pub render_seconds: Option<f64>,
    /// The filter setting that made the final image (`filter`).
    pub filter: Option<String>,
    /// `worldToCamera` and `worldToNDC`, as pbrt-v4 writes them
    /// ([`exr_matrices`](crate::render::camera::exr_matrices)).
    pub world_to_camera: Option<[f32; 16]>,
    pub world_to_ndc: Option<[f32; 16]>,
    /// lightsplit's own text attributes (`lightsplit.*`: a part file's key, part and spp),
    /// read back sorted by name.
    pub extra: Vec<(String, String)>,
    /// How an EXR's pixels are compressed (`compression`, the header's own).
    pub compression: ExrCompression,
}

impl Metadata {
    /// The EXR header attributes: `software` and Mitsuba's `generatedBy` always, the rest when
    /// known.
    fn exr_attributes(&self) -> exr::meta::header::LayerAttributes {
        use exr::meta::attribute::{AttributeValue as V, Text};
        let mut a = exr::meta::header::LayerAttributes {
            software_name: Some(Text::from(SOFTWARE)),
            world_to_camera: self.world_to_camera,
            world_to_normalized_device: self.world_to_ndc,
            ..Default::default()
        };
        let mut put = |name: &str, value: Option<V>| {
            if let Some(v) = value {
                a.other.insert(Text::from(name), v);
            }
        };
        // EXR text is Latin-1: any other character becomes `?`.
        let text = |t: &str| {
            let latin1: String = t.chars().map(|c| if (c as u32) < 256 { c } else { '?' }).collect();
            V::Text(Text::new_or_none(latin1).unwrap_or_default())
        };
        put("generatedBy", Some(text(SOFTWARE)));
        put("scene", self.scene.as_deref().map(text));
        put("samplesPerPixel", self.spp.map(|v| V::I32(v.min(i32::MAX as u32) as i32)));
        put("seed", self.seed.map(|v| text(&v.to_string())));
        put("maxDepth", self.max_depth.map(|v| V::I32(v.min(i32::MAX as u32) as i32)));
        put("sampler", self.sampler.as_deref().map(text));
        put("renderTimeSeconds", self.render_seconds.map(|v| V::F32(v as f32)));
        put("filter", self.filter.as_deref().map(text));
        // lightsplit's own attributes and Cryptomatte's are UTF-8 (a manifest's names may be
        // any), as Cryptomatte's specification says.
        for (name, value) in &self.extra {
            put(name, Some(V::Text(Text::from_slice_unchecked(value.as_bytes()))));
        }
        a
    }

    /// What an EXR's header records (the attributes [`Metadata::exr_attributes`] writes).
    pub fn of_exr(path: &Path) -> Result<Metadata, String> {
        use exr::meta::attribute::AttributeValue as V;
        let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| e.to_string())?;
        let header = meta.headers.first().ok_or("no header")?;
        let a = &header.own_attributes;
        let get = |name: &str| a.other.get(&exr::meta::attribute::Text::from(name));
        let text = |name: &str| match get(name) {
            Some(V::Text(t)) => Some(t.to_string()),
            _ => None,
        };
        let int = |name: &str| match get(name) {
            Some(V::I32(v)) => u32::try_from(*v).ok(),
            _ => None,
        };
        let mut extra: Vec<(String, String)> = a
            .other
            .iter()
            .filter_map(|(name, value)| match value {
                V::Text(t)
                    if name.to_string().starts_with("lightsplit.")
                        || name.to_string().starts_with("cryptomatte/") =>
                {
                    Some((name.to_string(), String::from_utf8_lossy(t.bytes()).into_owned()))
                }
                _ => None,
            })
            .collect();
        extra.sort();
        Ok(Metadata {
            scene: text("scene"),
            spp: int("samplesPerPixel"),
            seed: text("seed").and_then(|s| s.parse().ok()),
            max_depth: int("maxDepth"),
            sampler: text("sampler"),
            render_seconds: match get("renderTimeSeconds") {
                Some(V::F32(v)) => Some(*v as f64),
                _ => None,
            },
            filter: text("filter"),
            world_to_camera: a.world_to_camera,
            world_to_ndc: a.world_to_normalized_device,
            extra,
            compression: ExrCompression::of(header.compression),
        })
    }
}

/// Writes named float channels as one single-part EXR (32-bit float, lossless), with `meta` in
/// its header.
pub fn write_exr_channels(
    channels: Channels,
    width: u32,
    height: u32,
    meta: &Metadata,
    path: &Path,
) -> Result<(), String> {
    write_exr_samples(channels, Words::new(), width, height, meta, path)
}

/// [`write_exr_channels`], with whole-number (`u32`) channels beside the float ones.
fn write_exr_samples(
    channels: Channels,
    words: Words,
    width: u32,
    height: u32,
    meta: &Metadata,
    path: &Path,
) -> Result<(), String> {
    use exr::prelude::*;
    let floats = channels.into_iter().map(|(name, data)| (name, FlatSamples::F32(data)));
    let words = words.into_iter().map(|(name, data)| (name, FlatSamples::U32(data)));
    let list: Vec<AnyChannel<FlatSamples>> =
        floats.chain(words).map(|(name, data)| AnyChannel::new(name.as_str(), data)).collect();
    let layer = Layer::new(
        (width as usize, height as usize),
        meta.exr_attributes(),
        meta.compression.encoding(),
        AnyChannels::sort(SmallVec::from_vec(list)),
    );
    exr::image::Image::from_layer(layer).write().to_file(path).map_err(|e| e.to_string())
}

impl Film {
    /// A film back from the channels of a multi-layer EXR written by [`write_film`]. Every layer
    /// the filters need must be there; `albedo` may be missing.
    pub fn from_channels(width: u32, height: u32, channels: &Channels) -> Result<Film, String> {
        let film = film_from_layers(width, height, channels, "", |_| true, true)?;
        film.check_finite()?;
        Ok(film)
    }

    /// Refuses a film with a NaN or an infinity in any layer, naming the layer and counting
    /// its pixels: a filter spreads one to every pixel whose window holds it (box3: nine), and
    /// no render writes one (its non-finite samples are dropped).
    pub fn check_finite(&self) -> Result<(), String> {
        let images = [("raw", &self.raw), ("albedo", &self.albedo), ("normal", &self.normal)]
            .into_iter()
            .map(|(name, l)| (name.to_string(), l))
            .chain(self.components.named().map(|(c, l)| (c.name().to_string(), l)))
            .chain(self.aovs.iter().map(|a| (a.name.clone(), &a.image)))
            .chain(self.halves_named().map(|(name, _, half)| (name, half)))
            .map(|(name, l)| (name, bytemuck::cast_slice::<Vec3, f32>(&l.pixels), l.pixels.len()));
        let scalars = [
            ("depth", &self.depth),
            ("objectid", &self.object),
            ("objectid.coverage", &self.coverage),
            ("A", &self.alpha),
            ("raw_variance", &self.variance),
            ("half_share", &self.half_share),
        ]
        .into_iter()
        .map(|(name, v)| (name.to_string(), v))
        .chain(self.component_variance.named().map(|(c, v)| (format!("{}_variance", c.name()), v)))
        .map(|(name, v)| (name, v.as_slice(), v.len()));
        let bad = images.chain(scalars).map(|(name, values, pixels)| {
            // A pixel of three channels is one bad pixel however many of them are.
            let per = values.len().checked_div(pixels).unwrap_or(1).max(1);
            (name, values.chunks(per).filter(|p| p.iter().any(|x| !x.is_finite())).count(), pixels)
        });
        if let Some((name, count, of)) = bad.into_iter().find(|(_, count, _)| *count > 0) {
            return Err(format!(
                "{count} of the {of} pixels of its `{name}` layer are NaN or infinite: it cannot be filtered"
            ));
        }
        self.check_halves()
    }

    /// Each half layer by name (`raw_half`, `direct_half`, ...) with its whole layer: the
    /// beauty's, then each component's.
    pub fn halves_named(&self) -> impl Iterator<Item = (String, &Image, &Image)> {
        std::iter::once(("raw_half".to_string(), &self.raw, &self.half)).chain(
            self.components.named().map(|(c, l)| (format!("{}_half", c.name()), l, &self.component_half[c])),
        )
    }

    /// The halves a file holds fit its means: each share from 0 to 1, and each half's light at
    /// most the layer's own, channel by channel (a half's sum over fewer samples, divided by
    /// all of them, never exceeds the whole sum's, up to the rounding of a 32-bit sum). Light
    /// is never negative, so a half above its layer was not made by a render.
    pub fn check_halves(&self) -> Result<(), String> {
        if !self.has_halves() {
            return Ok(());
        }
        if let Some(at) = self.half_share.iter().position(|s| !(0.0..=1.0).contains(s)) {
            return Err(format!(
                "`half_share` at pixel {at} is {}, not a share from 0 to 1",
                self.half_share[at]
            ));
        }
        for (name, whole, half) in self.halves_named() {
            let above = |w: f32, h: f32| h > w + w.abs() * 1e-3 + f32::MIN_POSITIVE;
            let bad = whole.pixels.iter().zip(&half.pixels).position(|(w, h)| {
                above(w.x, h.x) || above(w.y, h.y) || above(w.z, h.z) || h.min_element() < 0.0
            });
            if let Some(at) = bad {
                return Err(format!(
                    "`{name}` at pixel {at} is {}, beyond its layer's {} (or negative): not the half of its samples",
                    half.pixels[at], whole.pixels[at]
                ));
            }
        }
        Ok(())
    }
}

/// Reads the final image of a file: the `R`, `G`, `B` channels of an EXR (any RGB EXR), a
/// Radiance HDR or a portable float map.
pub fn read_image(path: &Path) -> Result<Image, ReadError> {
    match Format::from_path(path).map_err(|e| ReadError(e.to_string()))? {
        Format::Exr | Format::Hdr | Format::Pfm => crate::scene::image::read(path).map_err(ReadError),
        Format::Png => {
            Err(ReadError(format!("{}: compare needs linear values: use .exr, .hdr or .pfm", path.display())))
        }
    }
}

/// Layer `layer` of an EXR, its channels `LAYER.R`, `.G` and `.B` (`final`: the image, `R`, `G`,
/// `B`), as an image.
pub fn read_layer(path: &Path, layer: &str) -> Result<Image, ReadError> {
    if layer == "final" {
        return read_image(path);
    }
    let at = |e: String| ReadError(format!("{}: {e}", path.display()));
    // Only the layer's three channels are decoded.
    match crate::scene::image::read_exr_rgb(path, &format!("{layer}.")).map_err(at)? {
        Ok(image) => Ok(image),
        Err(names) => {
            let mut layers: Vec<&str> =
                names.iter().filter_map(|n| n.rsplit_once('.').map(|p| p.0)).collect();
            layers.dedup();
            Err(at(format!("no layer `{layer}` (R, G, B); it has {}", layers.join(", "))))
        }
    }
}

/// The film of a multi-layer EXR that `lightsplit render` wrote ([`Film::from_channels`]).
pub fn read_film(path: &Path) -> Result<Film, ReadError> {
    let (width, height, channels) = read_exr_channels(path).map_err(ReadError)?;
    let at = |e: String| ReadError(format!("{}: {e}", path.display()));
    let meta = Metadata::of_exr(path).map_err(at)?;
    let names = aov_names(&meta).map_err(at)?;
    let mut film = Film::from_channels(width, height, &channels).map_err(at)?;
    film.aovs = aovs_from_channels(width, height, &channels, "", &names).map_err(at)?;
    let pixels = width as usize * height as usize;
    film.mattes = cryptomatte::Matte::read_all(&meta.extra, &channels, pixels).map_err(at)?;
    film.check_finite().map_err(at)?;
    Ok(film)
}

/// The object-ID layer (`objectid.ID`) of an EXR that `lightsplit render` wrote, with its size.
pub fn read_object_ids(path: &Path) -> Result<(u32, u32, Vec<f32>), ReadError> {
    let (width, height, channels, _) = read_exr_layer(path).map_err(ReadError)?;
    let ids = channels.into_iter().find(|(name, _)| name == "objectid.ID").map(|(_, v)| v);
    let ids = ids.ok_or_else(|| {
        ReadError(format!(
            "{}: no `objectid.ID` layer (an EXR that lightsplit rendered has one; a part file or a PNG none)",
            path.display()
        ))
    })?;
    if let Some(at) = ids.iter().position(|&o| !(o.is_finite() && o >= -1.0 && o.fract() == 0.0)) {
        return Err(ReadError(format!(
            "{}: `objectid.ID` at pixel {at} is {}, not an object (a whole number from -1)",
            path.display(),
            ids[at]
        )));
    }
    Ok((width, height, ids))
}

/// An image that cannot be read: always the input's fault. The message names the file.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ReadError(pub String);

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
    fn halves_beyond_their_layer_or_shares_beyond_one_are_refused() {
        let mut film = Film::new(2, 1);
        film.raw.pixels = vec![Vec3::splat(1.0); 2];
        film.half.pixels = vec![Vec3::splat(0.5); 2];
        film.half_share = vec![0.5; 2];
        assert_eq!(film.check_finite(), Ok(()));
        let mut bad = film.clone();
        bad.half.pixels[1].y = 1.5;
        assert!(bad.check_finite().is_err_and(|e| e.contains("raw_half") && e.contains("pixel 1")));
        let mut bad = film.clone();
        bad.half_share[0] = 1.5;
        assert!(bad.check_finite().is_err_and(|e| e.contains("half_share")));
        let mut bad = film.clone();
        bad.component_half[Component::Direct].pixels[0] = Vec3::NAN;
        assert!(bad.check_finite().is_err_and(|e| e.contains("direct_half")));
    }

    #[test]
    fn the_halves_measure_the_noise_of_independent_and_of_sobol_samples() {
        use crate::render::sampler::{PixelSampler, SamplerKind};
        // The share of a pixel a disc covers, a discontinuous integrand as an edge is: over
        // 2,000 pixels of 64 samples, each estimate's average against the spread of the
        // pixels' means (the truth).
        let (n, pixels) = (64u32, 2000u64);
        let disc = |p: glam::Vec2| ((p - glam::Vec2::splat(0.5)).length() < 0.4) as u32 as f64;
        let avg = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        for kind in [SamplerKind::Independent, SamplerKind::Sobol] {
            let (mut halves, mut iid, mut means) = (Vec::new(), Vec::new(), Vec::new());
            for pixel in 0..pixels {
                let streams = PixelSampler::new(kind, 9, pixel);
                let x: Vec<f64> = (0..n).map(|i| disc(streams.sample(i as u64).pixel_2d())).collect();
                let sum = x.iter().sum::<f64>();
                let n_b = (0..n).filter(|&i| half_of(i, n)).count() as u32;
                let sum_b: f64 = (0..n).filter(|&i| half_of(i, n)).map(|i| x[i as usize]).sum();
                assert_eq!(n_b, n / 2);
                halves.push(variance_of_halves(n, n_b, sum, sum_b).unwrap_or(f64::NAN));
                iid.push(variance_of_mean(n, sum, x.iter().map(|v| v * v).sum()));
                means.push(sum / n as f64);
            }
            let m = avg(&means);
            let truth = means.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (pixels - 1) as f64;
            let (h, i) = (avg(&halves) / truth, avg(&iid) / truth);
            // The halves' estimate has one degree of freedom: its average over 2,000 pixels has
            // a relative standard error of sqrt(2 / 2000) = 0.03, and the truth's too.
            match kind {
                // Both unbiased: within 4 standard errors of each (0.18).
                SamplerKind::Independent => {
                    assert!((h - 1.0).abs() < 0.18 && (i - 1.0).abs() < 0.18, "{kind:?}: {h} {i}")
                }
                // The sample variance overstates a stratified render's noise by about sqrt(n)
                // for an edge (8 at 64). The halves, as whole aligned blocks, are stratified
                // alike, but are not independent (one scrambled sequence): their estimate is
                // off by what their correlation is, within a factor of 1.8 either way for an
                // edge's convergence rate (2^1.5 - 1 high; as low, measured 0.77 here).
                SamplerKind::Sobol => assert!(i > 4.0 && (0.55..1.8).contains(&h), "{kind:?}: {h} {i}"),
            }
        }
        // Halves of 32 samples at 64 spp, and of blocks at other counts.
        assert!(!half_of(31, 64) && half_of(32, 64) && !half_of(64, 100) && half_of(96, 100));
        assert!(!half_of(0, 1) && half_of(1, 2) && half_of(1, 3));
        assert_eq!(variance_of_halves(4, 0, 1.0, 0.0), None);
        assert_eq!(variance_of_halves(4, 4, 1.0, 1.0), None);
        // Means 1 and 3 of two samples each: (2² 2 2) / 16 = 1.
        assert_eq!(variance_of_halves(4, 2, 8.0, 6.0), Some(1.0));
    }

    #[test]
    fn the_variance_of_the_mean_matches_a_known_stream() {
        // Uniform numbers in [0, 1) have variance 1/12, so the mean of n has 1/(12 n). Over
        // 2,000 streams of 64, the estimates average to it within their own standard error,
        // and the means' spread across streams agrees with it.
        let (n, streams) = (64u32, 2000);
        let mut estimates = Vec::new();
        let mut means = Vec::new();
        for k in 0..streams {
            let mut s = crate::render::sampler::Sampler::new(5, k, 0);
            let x: Vec<f64> = (0..n).map(|_| s.next_1d() as f64).collect();
            let (sum, sum_sq) = (x.iter().sum::<f64>(), x.iter().map(|v| v * v).sum::<f64>());
            estimates.push(variance_of_mean(n, sum, sum_sq));
            means.push(sum / n as f64);
        }
        let truth = 1.0 / (12.0 * n as f64);
        let avg = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let (mean_estimate, m) = (avg(&estimates), avg(&means));
        let spread =
            estimates.iter().map(|e| (e - mean_estimate).powi(2)).sum::<f64>() / (streams - 1) as f64;
        let se = (spread / streams as f64).sqrt();
        assert!((mean_estimate - truth).abs() < 4.0 * se, "{mean_estimate:e} vs {truth:e} (se {se:e})");
        let empirical = means.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (streams - 1) as f64;
        // The sample variance of 2,000 means is within 4 of its standard errors, sqrt(2/1999).
        assert!((empirical / truth - 1.0).abs() < 4.0 * (2.0 / (streams - 1) as f64).sqrt(), "{empirical:e}");
        // Never negative, and one sample gives its square.
        assert_eq!(variance_of_mean(3, 3.0, 3.0), 0.0);
        assert_eq!(variance_of_mean(1, 0.5, 0.25), 0.25);
    }

    #[test]
    fn the_variance_layers_round_trip_through_an_exr() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("f.exr");
        let mut film = Film::new(5, 3);
        film.raw = gradient();
        film.variance = (0..15).map(|i| i as f32 * 0.5).collect();
        for (k, c) in Component::ALL.into_iter().enumerate() {
            film.component_variance[c] = (0..15).map(|i| (i * 10 + k) as f32).collect();
        }
        let want = (film.variance.clone(), film.component_variance.clone());
        write_film(film, gradient(), None, &path, 0.0, &Metadata::default()).expect("write");
        let (w, h, channels) = read_exr_channels(&path).expect("read");
        let back = Film::from_channels(w, h, &channels).expect("a film");
        assert_eq!((back.variance, back.component_variance), want);
    }

    /// Every compression gives back every channel bit for bit, and the header says which it
    /// is; the raw floats take the most bytes.
    #[test]
    fn every_exr_compression_is_lossless() {
        let dir = tempfile::tempdir().expect("tempdir");
        let (w, h) = (37, 21);
        let mut film = Film::new(w, h);
        // Noise-like values (a hash of the index), as a render's are.
        let value = |i: u32| (i.wrapping_mul(2_654_435_761) % 1000) as f32 / 997.0;
        film.raw.pixels = (0..w * h).map(|i| Vec3::new(value(i), value(i + 7), value(3 * i))).collect();
        film.variance = (0..w * h).map(|i| value(5 * i + 1)).collect();
        let beauty = film.raw.clone();
        let mut sizes = Vec::new();
        let mut first = None;
        for c in ExrCompression::ALL {
            let path = dir.path().join(format!("{}.exr", c.name()));
            let meta = Metadata { compression: c, ..Metadata::default() };
            write_film(film.clone(), beauty.clone(), None, &path, 0.0, &meta).expect("write");
            assert_eq!(Metadata::of_exr(&path).expect("header").compression, c);
            let (_, _, channels) = read_exr_channels(&path).expect("read");
            let bits: Vec<(String, Vec<u32>)> =
                channels.into_iter().map(|(n, v)| (n, v.iter().map(|x| x.to_bits()).collect())).collect();
            match &first {
                None => first = Some(bits),
                Some(want) => assert_eq!(&bits, want, "{}", c.name()),
            }
            sizes.push(fs::metadata(&path).expect("size").len());
        }
        assert!(sizes[3] > sizes[0], "uncompressed {} bytes against zip's {}", sizes[3], sizes[0]);
    }

    #[test]
    fn exr_round_trips_exactly() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("a.exr");
        let img = gradient();
        write(&img, &path, 0.0).expect("write");
        assert_eq!(read_image(&path).expect("read"), img);
        // Only the final file is left behind.
        assert_eq!(fs::read_dir(dir.path()).expect("dir").count(), 1);
    }

    #[test]
    fn pfm_round_trips_exactly_and_is_written_bottom_row_first() {
        let img = gradient();
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("a.pfm");
        write(&img, &path, 0.0).expect("write");
        let bytes = fs::read(&path).expect("read");
        let header = b"PF\n5 3\n-1.0\n";
        assert_eq!(&bytes[..header.len()], header);
        assert_eq!(bytes.len(), header.len() + 5 * 3 * 12);
        // The first pixel in the file is the bottom-left one.
        let first = f32::from_le_bytes(bytes[header.len()..header.len() + 4].try_into().expect("4 bytes"));
        assert_eq!(first, img.pixels[2 * 5].x);
        assert_eq!(read_image(&path).expect("read back"), img);
        // A truncated file is an error, not a panic.
        fs::write(&path, &bytes[..bytes.len() - 1]).expect("truncate");
        assert!(read_image(&path).is_err());
        fs::write(&path, b"PF\n5 3\n").expect("short");
        assert!(read_image(&path).is_err());
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
                // RGBE keeps 8 mantissa bits relative to the largest channel, rounded: half a
                // step, a step being at most 1/128 of the largest channel.
                assert!((x - y).abs() <= b.max_element() / 256.0 * 1.0001, "{x} vs {y}");
            }
        }
    }

    /// RGBE rounds (issue 19): every channel within half a step of its value, and no bias: the
    /// mean error over many values, in steps, is zero within five standard errors of a
    /// uniform rounding error (1/sqrt(12) a value). Truncation was off by half a step.
    #[test]
    fn rgbe_rounds_to_the_nearest_step_without_bias() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let n = 20_000;
        let (mut sum, mut worst) = (0.0f64, 0.0f64);
        for _ in 0..n {
            // Values over 12 decades, channels of different sizes.
            let scale = 10f64.powf(12.0 * next() - 6.0);
            let c = Vec3::new((scale * next()) as f32, (scale * next()) as f32, scale as f32);
            let [r, g, b, e] = rgbe(c);
            let step = 2f64.powi(e as i32 - 136);
            for (m, x) in [r, g, b].into_iter().zip(c.to_array()) {
                let err = (m as f64 * step - x as f64) / step;
                worst = worst.max(err.abs());
                sum += err;
            }
        }
        let mean = sum / (3 * n) as f64;
        assert!(worst <= 0.5 + 1e-6, "a channel {worst} steps off");
        let bound = 5.0 / (12.0f64.sqrt() * ((3 * n) as f64).sqrt());
        assert!(mean.abs() < bound, "mean error {mean} steps (bound {bound})");
        assert_eq!(rgbe(Vec3::ZERO), [0; 4]);
        assert_eq!(rgbe(Vec3::new(-1.0, f32::NAN, 0.0)), [0; 4]);
        // 0.999 rounds to 256 at its exponent: the next exponent holds it.
        assert_eq!(rgbe(Vec3::splat(0.999)), [128, 128, 128, 129]);
    }

    /// Every field of the metadata comes back from the EXR header, a seed of 64 bits and a
    /// scene name outside Latin-1 (as `?`) included; an image without any has the software alone.
    #[test]
    fn exr_metadata_round_trips() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("m.exr");
        let meta = Metadata {
            scene: Some("scènes/ß.toml".into()),
            spp: Some(64),
            seed: Some(u64::MAX),
            max_depth: Some(1024),
            sampler: Some("sobol".into()),
            render_seconds: Some(1.5),
            filter: Some("box3 on indirect".into()),
            world_to_camera: Some(std::array::from_fn(|i| i as f32)),
            world_to_ndc: Some(std::array::from_fn(|i| -(i as f32))),
            extra: vec![("lightsplit.part".into(), "2/7".into())],
            compression: ExrCompression::Piz,
        };
        write_film(Film::new(5, 3), gradient(), None, &path, 0.0, &meta).expect("write");
        assert_eq!(Metadata::of_exr(&path).expect("read"), meta);
        let greek = Metadata { scene: Some("λ.toml".into()), ..Metadata::default() };
        write_with(&gradient(), &path, 0.0, &greek).expect("write");
        assert_eq!(Metadata::of_exr(&path).expect("read").scene.as_deref(), Some("?.toml"));
        write(&gradient(), &path, 0.0).expect("write");
        assert_eq!(Metadata::of_exr(&path).expect("read"), Metadata::default());
    }

    #[test]
    fn png_has_an_srgb_chunk_and_names_its_software() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("a.png");
        write(&gradient(), &path, 0.0).expect("write");
        let decoder = png::Decoder::new(std::io::BufReader::new(fs::File::open(&path).expect("open")));
        let reader = decoder.read_info().expect("a PNG");
        let info = reader.info();
        assert!(info.srgb.is_some(), "no sRGB chunk");
        let text: Vec<(&str, &str)> =
            info.uncompressed_latin1_text.iter().map(|t| (t.keyword.as_str(), t.text.as_str())).collect();
        assert_eq!(text, [("Software", SOFTWARE)]);
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
    fn every_exr_layer_reads_back_equal() {
        let mut film = Film::new(5, 3);
        for i in 0..15 {
            let v = Vec3::new(i as f32, -(i as f32) * 0.5, 1e-3 * i as f32);
            film.raw.pixels[i] = v;
            for (k, layer) in film.components.iter_mut().enumerate() {
                layer.pixels[i] = v * (k as f32 + 1.0);
            }
            film.albedo.pixels[i] = v * 0.1;
            film.normal.pixels[i] = Vec3::Z;
            film.depth[i] = 10.0 + i as f32;
            film.object[i] = (i % 3) as f32 - 1.0;
        }
        let final_image = film.components[Component::Emitted].clone();
        let filtered = film.components[Component::Indirect].clone();
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("film.exr");
        write_film(
            film.clone(),
            final_image.clone(),
            Some(filtered.clone()),
            &path,
            0.0,
            &Metadata::default(),
        )
        .expect("write");
        let (w, h, read) = read_exr_channels(&path).expect("read");
        assert_eq!((w, h), (5, 3));
        let written = film_channels(film, final_image, Some(filtered));
        assert_eq!(read.len(), written.len());
        for (name, data) in &written {
            let back = read.iter().find(|(n, _)| n == name).unwrap_or_else(|| panic!("{name} missing"));
            assert_eq!(&back.1, data, "{name}");
        }
        assert_eq!(fs::read_dir(dir.path()).expect("dir").count(), 1);
    }

    /// An image read from a render's EXR is its beauty alone, the other layers' channels left
    /// undecoded; an EXR of half floats reads as well, and one without a colour channel names it.
    #[test]
    fn an_image_read_from_a_renders_exr_is_its_beauty() {
        let mut film = Film::new(5, 3);
        film.components[Component::Direct]
            .pixels
            .iter_mut()
            .enumerate()
            .for_each(|(i, p)| *p = Vec3::splat(i as f32));
        let beauty = Image {
            width: 5,
            height: 3,
            pixels: (0..15).map(|i| Vec3::new(i as f32, 0.5 - i as f32, 1e-3 * i as f32)).collect(),
        };
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("film.exr");
        write_film(film, beauty.clone(), None, &path, 0.0, &Metadata::default()).expect("write");
        assert_eq!(read_image(&path).expect("read"), beauty);

        let half = dir.path().join("half.exr");
        // Half floats: channel c of pixel i holds i (c + 1).
        let write = |names: &[&str]| {
            use exr::prelude::*;
            let list = names.iter().enumerate().map(|(c, n)| {
                let samples = (0..15).map(|i| f16::from_f32(i as f32 * (c + 1) as f32)).collect();
                AnyChannel::new(*n, FlatSamples::F16(samples))
            });
            let layer = Layer::new(
                (5, 3),
                LayerAttributes::default(),
                Encoding::SMALL_LOSSLESS,
                AnyChannels::sort(SmallVec::from_vec(list.collect())),
            );
            exr::image::Image::from_layer(layer).write().to_file(&half).expect("write a half-float EXR");
        };
        write(&["R", "G", "B", "Z"]);
        let back = read_image(&half).expect("read");
        assert!(back.pixels.iter().enumerate().all(|(i, p)| *p == Vec3::new(1.0, 2.0, 3.0) * i as f32));
        write(&["R", "B"]);
        let e = read_image(&half).expect_err("no G");
        assert!(e.0.contains("no `G` channel") && e.0.contains("half.exr"), "{}", e.0);
    }

    /// The variance layers are all there or none: a file with some is damaged, one without any
    /// was written before they existed.
    #[test]
    fn the_variance_layers_are_read_all_or_none() {
        let film = Film::new(3, 2);
        let channels = film_channels(film, Image::new(3, 2), None);
        let without =
            |name: &str| -> Channels { channels.iter().filter(|(n, _)| n != name).cloned().collect() };
        let e = Film::from_channels(3, 2, &without("direct_variance.Y")).expect_err("one of them missing");
        assert!(e.contains("direct_variance.Y"), "{e}");
        let old: Channels = channels.iter().filter(|(n, _)| !n.contains("_variance")).cloned().collect();
        let back = Film::from_channels(3, 2, &old).expect("a file of before the variances");
        assert!(back.variance.is_empty() && back.component_variance.iter().all(Vec::is_empty));
        let back = Film::from_channels(3, 2, &without("raw_variance.Y")).expect("read as none");
        assert!(back.variance.is_empty() && back.component_variance.iter().all(Vec::is_empty));
        let all = Film::from_channels(3, 2, &channels).expect("every layer");
        assert_eq!(all.layers().count(), layers::LAYERS.len());
    }

    #[test]
    fn bad_extension_and_missing_directory_fail_before_writing() {
        assert!(matches!(check_output(Path::new("x.jpg")), Err(WriteError::Extension(_))));
        assert!(matches!(check_output(Path::new("/no/such/dir/x.png")), Err(WriteError::Refused(..))));
        assert_eq!(check_output(Path::new("x.EXR")).expect("ok"), Format::Exr);
    }
}
