//! The part file's format: its header, its channels, and the checks that refuse sums no render
//! could have made.

use std::path::Path;

use super::parse_part;
use crate::component::{Component, Split};
use crate::film::layers::{Group, Rule};
use crate::film::{self, Channels, Film, Metadata, Squares, Sums, Words, WriteError};
use crate::render::Part;
use crate::scene::limits;

/// Channel name prefix of the sums.
const SUMS: &str = "sums.";
/// The channel of each pixel's sample count.
const SAMPLES: &str = "samples.N";
/// The channel of each pixel's sum of filter weights, when the filter is splatted.
const WEIGHTS: &str = "weights.W";

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
fn channels(sums: &Sums) -> (Channels, Words) {
    let film = &sums.film;
    // The means of the two layers shown, as [`Sums::into_means`] makes them.
    let inv: Vec<f32> = sums.samples.iter().map(|&n| if n > 0 { 1.0 / n as f32 } else { 0.0 }).collect();
    let inv_weight: Vec<f32> = sums.weights.iter().map(|&w| if w > 0.0 { 1.0 / w } else { 0.0 }).collect();
    let beauty_inv = if sums.weights.is_empty() { &inv } else { &inv_weight };
    let mut out: Channels = Vec::new();
    for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
        out.push((name.into(), film.raw.pixels.iter().zip(beauty_inv).map(|(p, i)| p[c] * i).collect()));
    }
    if film.has_guides() {
        out.push(("A".into(), film.alpha.iter().zip(&inv).map(|(a, i)| a * i).collect()));
    }
    out.extend(film::layer_channels(film, SUMS));
    out.push((SAMPLES.into(), sums.samples.iter().map(|&n| n as f32).collect()));
    if !sums.weights.is_empty() {
        out.push((WEIGHTS.into(), sums.weights.clone()));
    }
    let mut words = Words::new();
    for (layer, squares) in squared_layers().zip(sums.squares.layers()).filter(|(_, s)| !s.is_empty()) {
        let name = squares_name(layer);
        words.push((format!("{name}.hi"), squares.iter().map(|v| (v.to_bits() >> 32) as u32).collect()));
        words.push((format!("{name}.lo"), squares.iter().map(|v| v.to_bits() as u32).collect()));
    }
    for matte in &film.mattes {
        words.extend(matte.words(&format!("{SUMS}{}", matte.kind)));
    }
    (out, words)
}

/// Writes a part file (atomically, as every output).
pub fn write(path: &Path, sums: &Sums, header: &Header) -> Result<(), WriteError> {
    let meta = Metadata {
        extra: vec![
            ("lightsplit.key".into(), header.key.clone()),
            ("lightsplit.part".into(), header.part.to_string()),
            ("lightsplit.spp".into(), header.spp.to_string()),
            ("lightsplit.adaptive".into(), header.adaptive.map_or("no".into(), |t| t.to_string())),
            ("lightsplit.complete".into(), if header.complete { "yes" } else { "no" }.into()),
        ]
        .into_iter()
        // The render's AOVs and Cryptomatte types, which reading the sums needs.
        .chain(film::aov_attributes(&header.meta))
        .chain(sums.film.matte_attributes())
        .collect(),
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
pub fn read(path: &Path) -> Result<(Header, Sums), String> {
    let header = read_header(path)?;
    let (width, height, channels, words) = crate::scene::image::exr_layer(path)?;
    let mut film = film_of(width, height, &channels)?;
    film.aovs = film::aovs_from_channels(width, height, &channels, SUMS, &film::aov_names(&header.meta)?)?;
    let n = film.raw.pixels.len();
    for (kind, manifest) in film::cryptomatte::Matte::types(&header.meta.extra)? {
        let prefix = format!("{SUMS}{kind}");
        film.mattes.push(film::cryptomatte::Matte::from_words(&kind, manifest, &prefix, &words, n)?);
    }
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
    let weights = match channels.iter().find(|(name, _)| name == WEIGHTS) {
        Some((_, w)) if w.len() != n => return Err("channel sizes do not match the image".into()),
        Some((_, w)) => w.clone(),
        None => Vec::new(),
    };
    let sums = Sums { film, squares, samples, weights };
    check_sums(&header, &sums)?;
    Ok((header, sums))
}

/// The values of pixel `i` of a layer of `width` values a pixel.
fn pixel_of(values: &[f32], width: usize, i: usize) -> &[f32] {
    &values[i * width..(i + 1) * width]
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
fn check_sums(header: &Header, sums: &Sums) -> Result<(), String> {
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
    // Each layer by its rule: first what every sum must be, then the squares, then what the
    // directions, the object and the counts must be besides.
    let held: Vec<_> = f.layers().filter(|(l, _)| l.rule != Rule::None).collect();
    let layer = |name: &str| format!("{SUMS}{name}");
    let summed = held
        .iter()
        .filter(|(l, _)| matches!(l.rule, Rule::Light | Rule::Scalar | Rule::Count))
        .map(|(l, v)| (l.name(), l.width(), *v))
        // An AOV's sums are light, as a component's.
        .chain(f.aovs.iter().map(|a| (a.name.as_str(), 3, bytemuck::cast_slice::<_, f32>(&a.image.pixels))));
    for (name, wd, v) in summed {
        let name = layer(name);
        refuse_any(&name, "NaN or infinite", n, w, |i| pixel_of(v, wd, i).iter().any(|x| !x.is_finite()))?;
        refuse_any(&name, "negative", n, w, |i| pixel_of(v, wd, i).iter().any(|&x| x < 0.0))?;
        refuse_any(&name, "not zero where no sample was taken", n, w, |i| {
            samples[i] == 0 && pixel_of(v, wd, i).iter().any(|&x| x != 0.0)
        })?;
    }
    let squares: Vec<(&str, &Vec<f64>)> =
        squared_layers().zip(sums.squares.layers()).filter(|(_, s)| !s.is_empty()).collect();
    for (name, v) in &squares {
        let name = squares_name(name);
        refuse_any(&name, "NaN or infinite", n, w, |i| !v[i].is_finite())?;
        refuse_any(&name, "negative", n, w, |i| v[i] < 0.0)?;
        refuse_any(&name, "not zero where no sample was taken", n, w, |i| samples[i] == 0 && v[i] != 0.0)?;
    }
    for (l, v) in &held {
        let (name, wd) = (layer(l.name()), l.width());
        match l.rule {
            Rule::Direction => {
                refuse_any(&name, "NaN or infinite", n, w, |i| {
                    pixel_of(v, wd, i).iter().any(|x| !x.is_finite())
                })?;
                refuse_any(&name, "not zero where no sample was taken", n, w, |i| {
                    samples[i] == 0 && pixel_of(v, wd, i).iter().any(|&x| x != 0.0)
                })?;
            }
            Rule::Object => refuse_any(&name, "not an object (a whole number from -1)", n, w, |i| {
                !(v[i].is_finite() && v[i] >= -1.0 && v[i].fract() == 0.0)
            })?,
            _ => {}
        }
    }
    for (l, v) in held.iter().filter(|(l, _)| l.rule == Rule::Count) {
        refuse_any(&layer(l.name()), "not a whole number of at most the pixel's samples", n, w, |i| {
            !(v[i].fract() == 0.0 && v[i] <= samples[i] as f32)
        })?;
    }
    let weights = &sums.weights;
    refuse_any(WEIGHTS, "NaN, infinite or negative", weights.len(), w, |i| {
        !(weights[i].is_finite() && weights[i] >= 0.0)
    })?;
    // Splatted sums are of the samples around a pixel, not of its own: no moments to fit.
    if !sums.squares.is_empty() && weights.is_empty() {
        let light = std::iter::once(("raw", &f.raw)).chain(f.components.named().map(|(c, l)| (c.name(), l)));
        for ((name, image), sq) in light.zip(sums.squares.layers()) {
            let lum = |i: usize| crate::math::luminance(image.pixels[i]) as f64;
            let what = "not sums of as many samples as their count, by their sums of squares";
            refuse_any(&layer(name), what, n, w, |i| !moments_fit(samples[i], lum(i), sq[i]))?;
        }
    }
    if f.has_halves() {
        // Halves are of a pixel's own samples: never with a splatted filter.
        if !weights.is_empty() {
            return Err(format!("{SUMS}half_share: halves beside a splatted filter's weights"));
        }
        // Without adaptive sampling a pixel's samples are the first of its part's range, so
        // which of them are in the second half is known.
        if header.adaptive.is_none() {
            let second = |taken: u32| {
                let end = range.start.saturating_add(taken).min(range.end);
                (range.start..end).filter(|&k| film::half_of(k, header.spp)).count() as f32
            };
            refuse_any(&layer("half_share"), "not the count of the samples in the second half", n, w, |i| {
                f.half_share[i] != second(samples[i])
            })?;
        }
        // A half's light, the sum of some of the samples, is at most the whole sum (light is
        // never negative), up to the rounding of a 32-bit sum over the samples.
        for (name, whole, half) in f.halves_named() {
            refuse_any(&layer(&name), "more than the whole sum of the pixel's samples", n, w, |i| {
                let (a, b) = (whole.pixels[i], half.pixels[i]);
                (b - a).max_element() > a.max_element() * 1e-3 + f32::MIN_POSITIVE
            })?;
        }
    }
    // A Cryptomatte's weights: each of the pixel's own samples weighs 1 with the pixel's box
    // (splatted, the weights are the filter's, not checked).
    for matte in f.mattes.iter().filter(|_| weights.is_empty()) {
        if let Some(c) = matte.coverage() {
            let what = "a total weight other than the pixel's sample count";
            refuse_any(&layer(&matte.kind), what, n, w, |i| {
                c[i].total_units() != u128::from(samples[i]) << 32
            })?;
        }
    }
    Ok(())
}

fn find<'a>(channels: &'a Channels, name: &str) -> Result<&'a Vec<f32>, String> {
    channels.iter().find(|(n, _)| n == name).map(|(_, d)| d).ok_or_else(|| format!("no `{name}` channel"))
}

/// The sums film of a part file's `sums.` channels: the split and the guides when it has them,
/// each of their layers required ([`film::layers::LAYERS`]); the halves with the split when it
/// has them (a file of a splatted render, or of before them, has none); no variances (the merge
/// makes them from the sums of squares).
fn film_of(width: u32, height: u32, channels: &Channels) -> Result<Film, String> {
    let has = |name: &str| channels.iter().any(|(n, _)| n == &format!("{SUMS}{name}"));
    let (split, guides) = (has("direct.R"), has("objectid.ID"));
    let halves = split && has("raw_half.R");
    film::film_from_layers(
        width,
        height,
        channels,
        SUMS,
        |group| match group {
            Group::Beauty => true,
            Group::Split => split,
            Group::Guides => guides,
            Group::Variance => false,
            Group::Halves => halves,
        },
        false,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

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
