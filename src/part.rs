//! Part files: a render's per-pixel sums ([`Accumulated`]) in an EXR, what a render on many
//! machines leaves on each and what `lightsplit merge` adds up; also a checkpoint's file, from
//! which a render resumes.
//!
//! A part file is an ordinary EXR whose `R`, `G`, `B` and `A` are the part's own image (so any
//! viewer shows it), with the sums under `sums.` (the layers of a render's EXR, as sums: see
//! [`Accumulated::film`]; the sums of squares, in f64, as two 32-bit words each) and each
//! pixel's sample count in `samples.N`. Its header says which render it belongs to (the run
//! key: a hash of the scene's files and of every option that changes a sample), which part it
//! is and which samples it holds.
//!
//! A part file is input like any other: [`read`] refuses one whose sums no render could have
//! made (NaN, negative light, more samples than its part has, counts that do not fit its
//! sums), so a damaged or edited file is an error naming it rather than a wrong image.
//!
//! The filter is not linear (the median, the edge stops), so parts are never filtered: the merge
//! adds the sums, then filters once.

use std::ffi::OsString;
use std::fmt;
use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::component::{Component, Split};
use crate::film::{self, Channels, Film, Image, Metadata, Words, WriteError};
use crate::render::{Accumulated, Part, RenderOptions, Squares};
use crate::scene::limits;
use crate::scene::Scene;

/// Channel name prefix of the sums.
const SUMS: &str = "sums.";
/// The channel of each pixel's sample count.
const SAMPLES: &str = "samples.N";
/// How many missing parts a merge names; the rest it counts.
pub const MISSING_NAMED: usize = 8;

/// What a part file's header says of it.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// The render's key ([`run_key`]): parts of one render share it.
    pub key: String,
    pub part: Part,
    /// The samples per pixel of the whole render.
    pub spp: u32,
    /// The adaptive sampling threshold of the render, if it was adaptive: its pixels then take
    /// from 16 samples to all of their part's; otherwise every pixel takes the same number.
    pub adaptive: Option<f32>,
    /// Whether the part holds all its samples (not a checkpoint, not stopped).
    pub complete: bool,
    /// The render's own record (scene, seed, sampler, camera matrices...).
    pub meta: Metadata,
}

/// The key of a render: a hash (FNV-1a) of the contents of every file the scene was read from
/// and of every option that changes a sample: the image size, the samples per pixel, the path
/// length, the seed, the sampler, what the integrator computes, adaptive sampling, and the
/// program's version. Not the backend (Embree and the BVH give the same samples up to float
/// rounding), the threads, or which part.
pub fn run_key(scene: &Scene, options: &RenderOptions) -> Result<String, String> {
    let mut h = crate::math::Fnv::default();
    for path in &scene.inputs {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        h.write(&(bytes.len() as u64).to_le_bytes());
        h.write(&bytes);
    }
    let o = options;
    for v in [o.width as u64, o.height as u64, o.spp as u64, o.max_depth as u64, o.seed] {
        h.write(&v.to_le_bytes());
    }
    h.write(o.sampler.name().as_bytes());
    h.write(&[o.features.bits()]);
    h.write(&o.adaptive.map_or(u32::MAX, f32::to_bits).to_le_bytes());
    h.write(env!("CARGO_PKG_VERSION").as_bytes());
    Ok(format!("{:016x}", h.0))
}

/// The name of the sums of squares of a layer (`raw`, `direct`, ...) in a part file; each is
/// an f64 kept as its high and low 32-bit words (`NAME.hi`, `NAME.lo`), since an EXR holds no
/// 64-bit channel and a 32-bit float cannot hold the square of a bright sample.
fn squares_name(layer: &str) -> String {
    format!("{SUMS}{layer}_squares")
}

/// The names of the layers whose squares are summed: the beauty, then each component.
fn squared_layers() -> impl Iterator<Item = &'static str> {
    std::iter::once("raw").chain(Component::ALL.into_iter().map(Component::name))
}

/// The channels of a part file: the means (`R`, `G`, `B`, `A`) of `sums`, then the sums
/// themselves and the sample counts; and the sums of squares as words.
fn channels(sums: &Accumulated) -> (Channels, Words) {
    let film = &sums.film;
    // The means of the two layers shown, as [`Accumulated::into_means`] makes them.
    let inv: Vec<f32> = sums.samples.iter().map(|&n| if n > 0 { 1.0 / n as f32 } else { 0.0 }).collect();
    let mut out: Channels = Vec::new();
    for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
        out.push((name.into(), film.raw.pixels.iter().zip(&inv).map(|(p, i)| p[c] * i).collect()));
    }
    if film.has_guides() {
        out.push(("A".into(), film.alpha.iter().zip(&inv).map(|(a, i)| a * i).collect()));
    }
    let layers = film::film_channels(film.clone(), Image::empty(), None);
    out.extend(layers.into_iter().map(|(name, data)| (format!("{SUMS}{name}"), data)));
    out.push((SAMPLES.into(), sums.samples.iter().map(|&n| n as f32).collect()));
    let mut words = Words::new();
    for (layer, squares) in squared_layers().zip(sums.squares.layers()).filter(|(_, s)| !s.is_empty()) {
        let name = squares_name(layer);
        words.push((format!("{name}.hi"), squares.iter().map(|v| (v.to_bits() >> 32) as u32).collect()));
        words.push((format!("{name}.lo"), squares.iter().map(|v| v.to_bits() as u32).collect()));
    }
    (out, words)
}

/// Writes a part file (atomically, as every output).
pub fn write(path: &Path, sums: &Accumulated, header: &Header) -> Result<(), WriteError> {
    let meta = Metadata {
        extra: vec![
            ("lightsplit.key".into(), header.key.clone()),
            ("lightsplit.part".into(), header.part.to_string()),
            ("lightsplit.spp".into(), header.spp.to_string()),
            ("lightsplit.adaptive".into(), header.adaptive.map_or("no".into(), |t| t.to_string())),
            ("lightsplit.complete".into(), if header.complete { "yes" } else { "no" }.into()),
        ],
        ..header.meta.clone()
    };
    let (width, height) = (sums.film.width, sums.film.height);
    let (channels, words) = channels(sums);
    film::write_exr_atomically(path, channels, words, width, height, &meta)
}

/// Reads a part file's header, and checks that it names a part of a render
/// ([`Part::check`]: at most as many parts as the render has samples a pixel).
pub fn read_header(path: &Path) -> Result<Header, String> {
    let meta = Metadata::of_exr(path)?;
    let extra = |name: &str| -> Result<String, String> {
        meta.extra.iter().find(|(n, _)| n == name).map(|(_, v)| v.clone()).ok_or_else(|| {
            format!("no `{name}` in its header (not a part file, or one of an older lightsplit)")
        })
    };
    let key = extra("lightsplit.key")?;
    let part = parse_part(&extra("lightsplit.part")?)?;
    let spp = extra("lightsplit.spp")?;
    let spp =
        spp.parse::<u32>().ok().filter(|s| (1..=limits::MAX_SPP).contains(s)).ok_or_else(|| {
            format!("`lightsplit.spp` {spp} is not 1 to {} samples per pixel", limits::MAX_SPP)
        })?;
    part.check(spp)?;
    let adaptive = match extra("lightsplit.adaptive")?.as_str() {
        "no" => None,
        t => Some(
            t.parse::<f32>()
                .ok()
                .filter(|t| t.is_finite() && *t > 0.0)
                .ok_or_else(|| format!("`lightsplit.adaptive` {t} is neither `no` nor a threshold"))?,
        ),
    };
    let complete = match extra("lightsplit.complete")?.as_str() {
        "yes" => true,
        "no" => false,
        other => return Err(format!("`lightsplit.complete` {other} is neither `yes` nor `no`")),
    };
    Ok(Header { key, part, spp, adaptive, complete, meta })
}

/// Reads a part file: its header and its sums, checked ([`check_sums`]).
pub fn read(path: &Path) -> Result<(Header, Accumulated), String> {
    let header = read_header(path)?;
    let (width, height, channels, words) = crate::scene::image::exr_layer(path)?;
    let film = film_of(width, height, &channels)?;
    let n = film.raw.pixels.len();
    let squares = if film.has_split() {
        let read = |layer: &str| -> Result<Vec<f64>, String> {
            let name = squares_name(layer);
            let word = |half: &str| {
                let name = format!("{name}.{half}");
                words.iter().find(|(w, _)| *w == name).map(|(_, d)| d).ok_or_else(|| {
                    format!(
                        "no `{name}` channel (a part file of an older lightsplit has none: render it again)"
                    )
                })
            };
            let (hi, lo) = (word("hi")?, word("lo")?);
            if hi.len() != n || lo.len() != n {
                return Err("channel sizes do not match the image".into());
            }
            Ok(hi.iter().zip(lo).map(|(&h, &l)| f64::from_bits((h as u64) << 32 | l as u64)).collect())
        };
        let mut squares = Squares { beauty: read("raw")?, components: Split::from_fn(|_| Vec::new()) };
        for (c, layer) in squares.components.named_mut() {
            *layer = read(c.name())?;
        }
        squares
    } else {
        Squares::default()
    };
    let samples = find(&channels, SAMPLES)?;
    if samples.len() != n {
        return Err("channel sizes do not match the image".into());
    }
    let range = header.part.samples(header.spp);
    let most = range.end - range.start;
    if let Some(at) = samples.iter().position(|&s| !(s >= 0.0 && s <= most as f32 && s.fract() == 0.0)) {
        return Err(format!(
            "`{SAMPLES}`: pixel {} has {} samples, and part {} of {} spp has {most} (samples {}..{})",
            pixel(at, width),
            samples[at],
            header.part,
            header.spp,
            range.start,
            range.end
        ));
    }
    let samples = samples.iter().map(|&s| s as u32).collect();
    let sums = Accumulated { film, squares, samples };
    check_sums(&header, &sums)?;
    Ok((header, sums))
}

/// `(x, y)` of pixel `at` of an image `width` wide.
fn pixel(at: usize, width: u32) -> String {
    let w = width.max(1) as usize;
    format!("({}, {})", at % w, at / w)
}

/// `Err` naming `layer`, how many of its `n` pixels `bad` finds and where the first is, when
/// it finds any.
fn refuse_any(
    layer: &str,
    what: &str,
    n: usize,
    width: u32,
    bad: impl Fn(usize) -> bool,
) -> Result<(), String> {
    let mut found = (0..n).filter(|&i| bad(i));
    match found.next() {
        None => Ok(()),
        Some(first) => {
            let count = 1 + found.count();
            let pixels = if count == 1 { "pixel" } else { "pixels" };
            Err(format!("`{layer}` at {count} {pixels} (the first {}): {what}", pixel(first, width)))
        }
    }
}

/// Whether a pixel's `n` sample luminances can have the sum `sum` (the luminance of its 32-bit
/// sums) and the sum of squares `squares`: by Cauchy and Schwarz `sum² <= n squares`, and as
/// luminances are never negative `squares <= sum²`, each within the rounding of `n` 32-bit
/// additions. A part whose counts were lowered (8 claimed for 144 samples) breaks the first.
/// From about 800,000 samples that rounding bounds nothing and the test passes.
fn moments_fit(n: u32, sum: f64, squares: f64) -> bool {
    let mu = (2.0 * n as f64 + 8.0) * (f32::EPSILON as f64 / 2.0);
    if mu >= 0.1 {
        return true;
    }
    let slack = 1.0 + 4.0 * mu / (1.0 - mu);
    // Values near 32-bit underflow round on an absolute scale.
    let tiny = (n as f64 + 1.0) * f32::MIN_POSITIVE as f64;
    sum <= (n as f64 * squares).sqrt() * slack + tiny && squares.sqrt() <= sum * slack + tiny
}

/// Checks that a part file's sums are sums a render of its header could have made: every value
/// finite; light, albedo, depth and squares never negative; the sample counts those of its
/// part (every pixel all of its samples, or, for a checkpoint, the same number in every pixel;
/// an adaptive render's pixels at most all); nothing summed where no sample was taken; the
/// samples that saw the pixel's object or hit a surface whole numbers of at most the pixel's
/// samples; and the sums of squares fitting the sums and counts ([`moments_fit`]). Each of
/// these a damaged or edited file broke, and the merge or the resumed render came out NaN,
/// twice as bright, or 13% too bright, with status 0.
fn check_sums(header: &Header, sums: &Accumulated) -> Result<(), String> {
    let (f, n, w) = (&sums.film, sums.samples.len(), sums.film.width);
    let samples = &sums.samples;
    let range = header.part.samples(header.spp);
    let all = range.end - range.start;
    if header.adaptive.is_none() {
        let first = samples.first().copied().unwrap_or(0);
        if header.complete {
            refuse_any(SAMPLES, &format!("fewer than the {all} samples of a complete part"), n, w, |i| {
                samples[i] != all
            })?;
        } else {
            // Passes end at the same sample in every pixel.
            refuse_any(SAMPLES, &format!("another count than pixel (0, 0)'s {first}"), n, w, |i| {
                samples[i] != first
            })?;
        }
    }
    let rgb: Vec<(String, &Image)> = std::iter::once(("raw".to_string(), &f.raw))
        .chain(f.components.named().map(|(c, l)| (c.name().to_string(), l)))
        .chain(f.has_guides().then(|| ("albedo".to_string(), &f.albedo)))
        .filter(|(_, l)| !l.pixels.is_empty())
        .collect();
    let scalars: Vec<(&str, &Vec<f32>)> = if f.has_guides() {
        vec![("depth.Z", &f.depth), ("objectid.coverage", &f.coverage), ("A", &f.alpha)]
    } else {
        Vec::new()
    };
    let squares: Vec<(&str, &Vec<f64>)> =
        squared_layers().zip(sums.squares.layers()).filter(|(_, s)| !s.is_empty()).collect();
    let layer = |name: &str| format!("{SUMS}{name}");
    for (name, image) in &rgb {
        let p = &image.pixels;
        refuse_any(&layer(name), "NaN or infinite", n, w, |i| !p[i].is_finite())?;
        refuse_any(&layer(name), "negative", n, w, |i| p[i].min_element() < 0.0)?;
        refuse_any(&layer(name), "not zero where no sample was taken", n, w, |i| {
            samples[i] == 0 && p[i] != Vec3::ZERO
        })?;
    }
    for (name, v) in &scalars {
        refuse_any(&layer(name), "NaN or infinite", n, w, |i| !v[i].is_finite())?;
        refuse_any(&layer(name), "negative", n, w, |i| v[i] < 0.0)?;
        refuse_any(&layer(name), "not zero where no sample was taken", n, w, |i| {
            samples[i] == 0 && v[i] != 0.0
        })?;
    }
    for (name, v) in &squares {
        let name = squares_name(name);
        refuse_any(&name, "NaN or infinite", n, w, |i| !v[i].is_finite())?;
        refuse_any(&name, "negative", n, w, |i| v[i] < 0.0)?;
        refuse_any(&name, "not zero where no sample was taken", n, w, |i| samples[i] == 0 && v[i] != 0.0)?;
    }
    if f.has_guides() {
        let normal = &f.normal.pixels;
        refuse_any(&layer("normal"), "NaN or infinite", n, w, |i| !normal[i].is_finite())?;
        refuse_any(&layer("normal"), "not zero where no sample was taken", n, w, |i| {
            samples[i] == 0 && normal[i] != Vec3::ZERO
        })?;
        let object = &f.object;
        refuse_any(&layer("objectid.ID"), "not an object (a whole number from -1)", n, w, |i| {
            !(object[i].is_finite() && object[i] >= -1.0 && object[i].fract() == 0.0)
        })?;
        for (name, count) in [("objectid.coverage", &f.coverage), ("A", &f.alpha)] {
            refuse_any(&layer(name), "not a whole number of at most the pixel's samples", n, w, |i| {
                !(count[i].fract() == 0.0 && count[i] <= samples[i] as f32)
            })?;
        }
    }
    if !sums.squares.is_empty() {
        let light = std::iter::once(("raw", &f.raw)).chain(f.components.named().map(|(c, l)| (c.name(), l)));
        for ((name, image), sq) in light.zip(sums.squares.layers()) {
            let lum = |i: usize| crate::math::luminance(image.pixels[i]) as f64;
            let what = "not sums of as many samples as their count, by their sums of squares";
            refuse_any(&layer(name), what, n, w, |i| !moments_fit(samples[i], lum(i), sq[i]))?;
        }
    }
    Ok(())
}

/// `I/N` with I < N.
pub fn parse_part(text: &str) -> Result<Part, String> {
    let bad = || format!("`{text}` is not a part I/N (0 <= I < N)");
    let (i, n) = text.split_once('/').ok_or_else(bad)?;
    let (index, count): (u32, u32) =
        (i.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
    if count == 0 || index >= count {
        return Err(bad());
    }
    Ok(Part { index, count })
}

/// The part a batch scheduler gives this process, from its environment (`var` looks a variable
/// up): a Slurm job array (`SLURM_ARRAY_TASK_ID` less `SLURM_ARRAY_TASK_MIN`, of
/// `SLURM_ARRAY_TASK_COUNT`) or a Kubernetes Indexed Job (`JOB_COMPLETION_INDEX`, of
/// `LIGHTSPLIT_PART_COUNT`, which the Job sets to its completions).
pub fn part_from_scheduler(var: impl Fn(&str) -> Option<OsString>) -> Result<Part, String> {
    let number = |name: &str, value: OsString| -> Result<u32, String> {
        value.to_str().and_then(|v| v.trim().parse::<u32>().ok()).ok_or_else(|| {
            format!("{name}={} is not a number (a whole number from 0)", value.to_string_lossy())
        })
    };
    let (index, count) = if let (Some(id), Some(count)) =
        (var("SLURM_ARRAY_TASK_ID"), var("SLURM_ARRAY_TASK_COUNT"))
    {
        let id = number("SLURM_ARRAY_TASK_ID", id)?;
        let min = var("SLURM_ARRAY_TASK_MIN").map_or(Ok(0), |m| number("SLURM_ARRAY_TASK_MIN", m))?;
        let count = number("SLURM_ARRAY_TASK_COUNT", count)?;
        let index = id.checked_sub(min).ok_or_else(|| {
            format!("SLURM_ARRAY_TASK_ID={id} is below SLURM_ARRAY_TASK_MIN={min}: not a task of this array")
        })?;
        if index >= count {
            return Err(format!(
                "SLURM_ARRAY_TASK_ID={id} less SLURM_ARRAY_TASK_MIN={min} is {index}, past the last of \
                 SLURM_ARRAY_TASK_COUNT={count} parts (an array with a step, such as 1-9:2, does not \
                 split a render)"
            ));
        }
        (index, count)
    } else if let Some(index) = var("JOB_COMPLETION_INDEX") {
        let count = var("LIGHTSPLIT_PART_COUNT")
            .ok_or("JOB_COMPLETION_INDEX is set but LIGHTSPLIT_PART_COUNT (the Job's completions) is not")?;
        let (index, count) =
            (number("JOB_COMPLETION_INDEX", index)?, number("LIGHTSPLIT_PART_COUNT", count)?);
        if index >= count {
            return Err(format!(
                "JOB_COMPLETION_INDEX={index} is past the last of LIGHTSPLIT_PART_COUNT={count} parts"
            ));
        }
        (index, count)
    } else {
        return Err("no scheduler found (SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT, or \
                    JOB_COMPLETION_INDEX and LIGHTSPLIT_PART_COUNT)"
            .into());
    };
    Ok(Part { index, count })
}

fn find<'a>(channels: &'a Channels, name: &str) -> Result<&'a Vec<f32>, String> {
    channels.iter().find(|(n, _)| n == name).map(|(_, d)| d).ok_or_else(|| format!("no `{name}` channel"))
}

/// The sums film of a part file's `sums.` channels: the split and the guides when it has them.
fn film_of(width: u32, height: u32, channels: &Channels) -> Result<Film, String> {
    let has = |name: &str| channels.iter().any(|(n, _)| n == &format!("{SUMS}{name}"));
    let (split, guides) = (has("direct.R"), has("objectid.ID"));
    let mut film = Film::with_buffers(width, height, split, guides);
    // The variances are the merge's to make, from the sums of squares.
    film.variance = Vec::new();
    film.component_variance = Split::from_fn(|_| Vec::new());
    let get = |name: &str| find(channels, &format!("{SUMS}{name}")).cloned();
    let rgb = |prefix: &str, names: [&str; 3]| -> Result<Image, String> {
        let [r, g, b] = names.map(|c| get(&format!("{prefix}.{c}")));
        let (r, g, b) = (r?, g?, b?);
        if g.len() != r.len() || b.len() != r.len() {
            return Err("channel sizes do not match the image".into());
        }
        let pixels = (0..r.len()).map(|i| Vec3::new(r[i], g[i], b[i])).collect();
        Ok(Image { width, height, pixels })
    };
    film.raw = rgb("raw", ["R", "G", "B"])?;
    if split {
        for (c, layer) in film.components.named_mut() {
            *layer = rgb(c.name(), ["R", "G", "B"])?;
        }
    }
    if guides {
        film.albedo = rgb("albedo", ["R", "G", "B"])?;
        film.normal = rgb("normal", ["X", "Y", "Z"])?;
        film.depth = get("depth.Z")?;
        film.object = get("objectid.ID")?;
        film.coverage = get("objectid.coverage")?;
        film.alpha = get("A")?;
    }
    let n = width as usize * height as usize;
    let sizes_ok = film.raw.pixels.len() == n
        && film.components.iter().all(|c| c.pixels.is_empty() || c.pixels.len() == n)
        && [&film.depth, &film.object, &film.coverage, &film.alpha]
            .iter()
            .all(|v| v.is_empty() || v.len() == n)
        && [&film.albedo, &film.normal].iter().all(|i| i.pixels.is_empty() || i.pixels.len() == n);
    if !sizes_ok {
        return Err("channel sizes do not match the image".into());
    }
    Ok(film)
}

/// Reads the part file a render resumes from, `path`, for a render of `scene` with `options`
/// (whose part, spp and key it must have). A checkpoint holds the buffers its own output
/// needed; when it holds more than this render's output needs (written for an EXR, resumed to
/// a PNG), `options` takes them on, since they change no sample of the beauty.
pub fn read_checkpoint(
    path: &Path,
    scene: &Scene,
    options: &mut RenderOptions,
) -> Result<Accumulated, String> {
    let header = read_header(path).map_err(|e| {
        format!(
            "a resume file is a part file (`.part.exr`, an EXR that --part, --checkpoint or a \
             stopped render writes): {e}"
        )
    })?;
    if header.part != options.part || header.spp != options.spp {
        return Err(format!(
            "it holds part {} of {} spp, this render part {} of {} spp",
            header.part, header.spp, options.part, options.spp
        ));
    }
    if header.adaptive.is_some() {
        return Err("it is a part of an adaptive render, which cannot be resumed".into());
    }
    let (header, sums) = read(path)?;
    if header.key == run_key(scene, options)? {
        return Ok(sums);
    }
    let (split, guides) = (sums.film.has_split(), sums.film.has_guides());
    let with_its_buffers = RenderOptions {
        features: crate::render::Features { split, guides, ..options.features },
        ..options.clone()
    };
    if header.key != run_key(scene, &with_its_buffers)? {
        return Err(
            "it is not a checkpoint of this render: the scene files or the settings that change a sample \
             differ (size, seed, path length, sampler, features)"
                .into(),
        );
    }
    let lacking: Vec<&str> = [
        (options.features.split && !split, "the component split"),
        (options.features.guides && !guides, "the guide buffers"),
    ]
    .into_iter()
    .filter_map(|(lacks, what)| lacks.then_some(what))
    .collect();
    if !lacking.is_empty() {
        return Err(format!(
            "it was written for an output that needs fewer buffers (a PNG, say) and holds no {}, which this \
             output needs: resume it to such an output",
            lacking.join(" and no ")
        ));
    }
    options.features = with_its_buffers.features;
    Ok(sums)
}

/// A part to merge: its file and its header.
pub struct Named {
    pub path: PathBuf,
    pub header: Header,
}

/// Why parts cannot be merged: one line naming the files.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct MergeError(pub String);

/// The parts of a render that a merge lacks: how many, and the first few.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Missing {
    /// Of how many parts.
    pub of: u32,
    /// How many are missing.
    pub count: u32,
    /// The indices of the first [`MISSING_NAMED`] of them.
    pub first: Vec<u32>,
}

impl fmt::Display for Missing {
    /// `part 1/3`, `parts 1/8, 3/8`, or `parts 1/4096, ..., 8/4096 and 4087 more`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let named: Vec<String> = self.first.iter().map(|i| format!("{i}/{}", self.of)).collect();
        write!(f, "part{} {}", if self.count == 1 { "" } else { "s" }, named.join(", "))?;
        let more = self.count as usize - self.first.len();
        if more > 0 {
            write!(f, " and {more} more")?;
        }
        Ok(())
    }
}

/// Checks that `parts` are parts of one render, each once, and all of them unless
/// `allow_missing`; returns the part count and the missing parts. Nothing here is allocated or
/// done per part of the render, only per part given (a header may declare millions).
pub fn check(parts: &[Named], allow_missing: bool) -> Result<(u32, Missing), MergeError> {
    let first = parts.first().ok_or_else(|| MergeError("no parts to merge".into()))?;
    let (count, spp) = (first.header.part.count, first.header.spp);
    let different = |p: &Named, why: String| {
        MergeError(format!(
            "{} and {} are parts of different renders ({why})",
            p.path.display(),
            first.path.display()
        ))
    };
    for p in parts {
        let h = &p.header;
        if h.spp != spp {
            return Err(different(p, format!("of {} spp against {spp}", h.spp)));
        }
        if h.part.count != count {
            return Err(different(p, format!("{} parts against {count}", h.part.count)));
        }
        if h.key != first.header.key {
            return Err(different(
                p,
                format!("the scene files or settings differ: key {} against {}", h.key, first.header.key),
            ));
        }
    }
    let mut given: Vec<&Named> = parts.iter().collect();
    given.sort_by_key(|p| p.header.part.index);
    if let Some(pair) = given.windows(2).find(|w| w[0].header.part.index == w[1].header.part.index) {
        return Err(MergeError(format!(
            "{} and {} are both part {}: a part is merged once",
            pair[0].path.display(),
            pair[1].path.display(),
            pair[0].header.part
        )));
    }
    if let (Some(p), false) = (parts.iter().find(|p| !p.header.complete), allow_missing) {
        return Err(MergeError(format!(
            "{} is part {} stopped before its samples were all taken (a checkpoint): resume it \
             (`render --resume`), or merge what there is with --allow-missing",
            p.path.display(),
            p.header.part
        )));
    }
    // The gaps between the given indices, sorted: the first few named, all counted.
    let mut missing = Missing { of: count, count: count - given.len() as u32, first: Vec::new() };
    let mut next = 0;
    for index in given.iter().map(|p| p.header.part.index).chain([count]) {
        missing.first.extend((next..index).take(MISSING_NAMED - missing.first.len()));
        next = index + 1;
    }
    if missing.count > 0 && !allow_missing {
        return Err(MergeError(format!(
            "missing {missing} of {count} (--allow-missing merges what there is)"
        )));
    }
    Ok((count, missing))
}

/// Adds up the parts ([`check`]ed), read one at a time, in the order of their indices (so the
/// result does not depend on the order the files were named in); `each` is called after each.
pub fn merge(parts: &[Named], each: &dyn Fn()) -> Result<Accumulated, MergeError> {
    let mut order: Vec<&Named> = parts.iter().collect();
    order.sort_by_key(|p| p.header.part.index);
    let mut total: Option<Accumulated> = None;
    for p in order {
        let at = |e: String| MergeError(format!("{}: {e}", p.path.display()));
        let (header, sums) = read(&p.path).map_err(at)?;
        if header != p.header {
            return Err(at("the file changed while it was merged".into()));
        }
        match &mut total {
            None => total = Some(sums),
            Some(t) => t.add(&sums).map_err(at)?,
        }
        each();
    }
    total.ok_or_else(|| MergeError("no parts to merge".into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scheduler's variables, as `part_from_scheduler` looks them up.
    fn env<'a>(vars: &'a [(&'a str, &'a [u8])]) -> impl Fn(&str) -> Option<OsString> + 'a {
        use std::os::unix::ffi::OsStrExt;
        move |name| {
            vars.iter().find(|(n, _)| *n == name).map(|(_, v)| std::ffi::OsStr::from_bytes(v).to_owned())
        }
    }

    #[test]
    fn the_scheduler_gives_the_part_or_says_which_variable_is_wrong() {
        let slurm = |id: &'static [u8]| {
            part_from_scheduler(env(&[
                ("SLURM_ARRAY_TASK_ID", id),
                ("SLURM_ARRAY_TASK_MIN", b"1"),
                ("SLURM_ARRAY_TASK_COUNT", b"4"),
            ]))
        };
        assert_eq!(slurm(b"3"), Ok(Part { index: 2, count: 4 }));
        assert!(slurm(b"0").is_err_and(|e| e.contains("below SLURM_ARRAY_TASK_MIN=1")));
        assert!(slurm(b"5").is_err_and(|e| e.contains("past the last")));
        assert!(slurm(b"\xff").is_err_and(|e| e.contains("SLURM_ARRAY_TASK_ID=\u{fffd} is not a number")));
        let k8s =
            part_from_scheduler(env(&[("JOB_COMPLETION_INDEX", b"2"), ("LIGHTSPLIT_PART_COUNT", b"3")]));
        assert_eq!(k8s, Ok(Part { index: 2, count: 3 }));
        assert!(part_from_scheduler(env(&[("JOB_COMPLETION_INDEX", b"2")]))
            .is_err_and(|e| e.contains("LIGHTSPLIT_PART_COUNT")));
        assert!(part_from_scheduler(env(&[])).is_err_and(|e| e.contains("no scheduler found")));
    }

    #[test]
    fn missing_parts_are_named_a_few_and_counted() {
        let few = Missing { of: 3, count: 1, first: vec![1] };
        assert_eq!(few.to_string(), "part 1/3");
        let many = Missing { of: 4096, count: 4095, first: (1..=MISSING_NAMED as u32).collect() };
        assert_eq!(
            many.to_string(),
            "parts 1/4096, 2/4096, 3/4096, 4/4096, 5/4096, 6/4096, 7/4096, 8/4096 and 4087 more"
        );
    }

    #[test]
    fn moments_fit_the_sums_of_their_samples_and_not_of_more() {
        // Luminances from 0 to 1, summed as a render sums them: the beauty in f32, squares in f64.
        let mut state = 0x9e37_79b9u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state >> 8) as f32 / 16_777_216.0
        };
        for n in [1u32, 2, 8, 144, 4096] {
            for constant in [false, true] {
                let (mut sum, mut squares) = (0.0f32, 0.0f64);
                let c = next();
                for _ in 0..n {
                    let l = if constant { c } else { next() };
                    sum += l;
                    squares += (l as f64).powi(2);
                }
                assert!(moments_fit(n, sum as f64, squares), "{n} samples, constant {constant}");
                if n >= 8 {
                    // The same sums claimed for an eighth of the samples.
                    assert!(!moments_fit(n / 8, sum as f64, squares), "{n} samples as {}", n / 8);
                }
            }
        }
        assert!(moments_fit(0, 0.0, 0.0));
        assert!(!moments_fit(0, 1.0, 1.0));
        // Squares larger than the square of the sum: no non-negative samples make them.
        assert!(!moments_fit(4, 1.0, 4.0));
    }
}
