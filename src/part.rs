//! Part files: a render's per-pixel sums ([`Accumulated`]) in an EXR, what a render on many
//! machines leaves on each and what `lightsplit merge` adds up; also a checkpoint's file, from
//! which a render resumes.
//!
//! A part file is an ordinary EXR whose `R`, `G`, `B` and `A` are the part's own image (so any
//! viewer shows it), with the sums under `sums.` (the layers of a render's EXR, as sums: see
//! [`Accumulated::film`]) and each pixel's sample count in `samples.N`. Its header says which
//! render it belongs to (the run key: a hash of the scene's files and of every option that
//! changes a sample), which part it is and which samples it holds.
//!
//! The filter is not linear (the median, the edge stops), so parts are never filtered: the merge
//! adds the sums, then filters once.

use std::path::Path;

use crate::film::{self, Film, Image, Metadata, WriteError};
use crate::render::{Accumulated, Part, RenderOptions};
use crate::scene::image::Channels;
use crate::scene::Scene;

/// Channel name prefix of the sums.
const SUMS: &str = "sums.";
/// The channel of each pixel's sample count.
const SAMPLES: &str = "samples.N";

/// What a part file's header says of it.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// The render's key ([`run_key`]): parts of one render share it.
    pub key: String,
    pub part: Part,
    /// The samples per pixel of the whole render.
    pub spp: u32,
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

/// The channels of a part file: the means (`R`, `G`, `B`, `A`) of `sums`, then the sums
/// themselves and the sample counts.
fn channels(sums: &Film, samples: &[u32]) -> Channels {
    // The means of the two layers shown, as [`Accumulated::into_means`] makes them.
    let inv: Vec<f32> = samples.iter().map(|&n| if n > 0 { 1.0 / n as f32 } else { 0.0 }).collect();
    let mut out: Channels = Vec::new();
    for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
        out.push((name.into(), sums.raw.pixels.iter().zip(&inv).map(|(p, i)| p[c] * i).collect()));
    }
    if sums.has_guides() {
        out.push(("A".into(), sums.alpha.iter().zip(&inv).map(|(a, i)| a * i).collect()));
    }
    let sums = film::film_channels(sums.clone(), Image::empty(), None);
    out.extend(sums.into_iter().map(|(name, data)| (format!("{SUMS}{name}"), data)));
    out.push((SAMPLES.into(), samples.iter().map(|&n| n as f32).collect()));
    out
}

/// Writes a part file (atomically, as every output).
pub fn write(path: &Path, sums: &Film, samples: &[u32], header: &Header) -> Result<(), WriteError> {
    let meta = Metadata {
        extra: vec![
            ("lightsplit.key".into(), header.key.clone()),
            ("lightsplit.part".into(), header.part.to_string()),
            ("lightsplit.spp".into(), header.spp.to_string()),
            ("lightsplit.complete".into(), if header.complete { "yes" } else { "no" }.into()),
        ],
        ..header.meta.clone()
    };
    let (width, height) = (sums.width, sums.height);
    film::write_exr_atomically(path, channels(sums, samples), width, height, &meta)
}

/// Reads a part file's header.
pub fn read_header(path: &Path) -> Result<Header, String> {
    let meta = Metadata::of_exr(path)?;
    let extra = |name: &str| -> Result<String, String> {
        meta.extra
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.clone())
            .ok_or_else(|| format!("not a part file (no `{name}` in its header)"))
    };
    let key = extra("lightsplit.key")?;
    let part = parse_part(&extra("lightsplit.part")?)?;
    let spp: u32 = extra("lightsplit.spp")?.parse().map_err(|_| "a bad `lightsplit.spp`".to_string())?;
    let complete = extra("lightsplit.complete")? == "yes";
    Ok(Header { key, part, spp, complete, meta })
}

/// Reads a part file: its header and its sums.
pub fn read(path: &Path) -> Result<(Header, Accumulated), String> {
    let header = read_header(path)?;
    let spp = header.spp;
    let (width, height, channels) = crate::scene::image::read_exr_channels(path)?;
    let film = film_of(width, height, &channels)?;
    let samples = find(&channels, SAMPLES)?;
    if samples.len() != film.raw.pixels.len() {
        return Err("channel sizes do not match the image".into());
    }
    if samples.iter().any(|&n| !(n >= 0.0 && n <= spp as f32 && n.fract() == 0.0)) {
        return Err(format!("a sample count that is not a whole number from 0 to {spp}"));
    }
    let samples = samples.iter().map(|&n| n as u32).collect();
    Ok((header, Accumulated { film, samples }))
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

fn find<'a>(channels: &'a Channels, name: &str) -> Result<&'a Vec<f32>, String> {
    channels.iter().find(|(n, _)| n == name).map(|(_, d)| d).ok_or_else(|| format!("no `{name}` channel"))
}

/// The sums film of a part file's `sums.` channels: the split and the guides when it has them.
fn film_of(width: u32, height: u32, channels: &Channels) -> Result<Film, String> {
    let has = |name: &str| channels.iter().any(|(n, _)| n == &format!("{SUMS}{name}"));
    let (split, guides) = (has("direct.R"), has("objectid.ID"));
    let mut film = Film::with_buffers(width, height, split, guides);
    let get = |name: &str| find(channels, &format!("{SUMS}{name}")).cloned();
    let rgb = |prefix: &str, names: [&str; 3]| -> Result<Image, String> {
        let [r, g, b] = names.map(|c| get(&format!("{prefix}.{c}")));
        let (r, g, b) = (r?, g?, b?);
        let pixels = (0..r.len()).map(|i| glam::Vec3::new(r[i], g[i], b[i])).collect();
        Ok(Image { width, height, pixels })
    };
    film.raw = rgb("raw", ["R", "G", "B"])?;
    if split {
        for (c, layer) in film.components.named_mut() {
            *layer = rgb(c.name(), ["R", "G", "B"])?;
        }
        film.variance = get("raw_variance.Y")?;
        for (c, layer) in crate::component::Component::ALL.into_iter().zip(film.component_variance.iter_mut())
        {
            *layer = get(&format!("{}_variance.Y", c.name()))?;
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
        && [&film.depth, &film.object, &film.coverage, &film.alpha, &film.variance]
            .iter()
            .all(|v| v.is_empty() || v.len() == n)
        && [&film.albedo, &film.normal].iter().all(|i| i.pixels.is_empty() || i.pixels.len() == n);
    if !sizes_ok {
        return Err("channel sizes do not match the image".into());
    }
    Ok(film)
}

/// A part to merge: its file and its header.
pub struct Named {
    pub path: std::path::PathBuf,
    pub header: Header,
}

/// Why parts cannot be merged: one line naming the files.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct MergeError(pub String);

/// Checks that `parts` are parts of one render, each once, and all of them unless
/// `allow_missing`; returns the part count and the missing parts' indices.
pub fn check(parts: &[Named], allow_missing: bool) -> Result<(u32, Vec<u32>), MergeError> {
    let first = parts.first().ok_or_else(|| MergeError("no parts to merge".into()))?;
    let count = first.header.part.count;
    let mut seen: Vec<Option<&Path>> = vec![None; count as usize];
    for p in parts {
        let h = &p.header;
        if h.key != first.header.key || h.part.count != count || h.spp != first.header.spp {
            return Err(MergeError(format!(
                "{} and {} are parts of different renders (scene files or settings differ: key {} against {}, {} parts against {})",
                p.path.display(),
                first.path.display(),
                h.key,
                first.header.key,
                h.part.count,
                count
            )));
        }
        if let Some(other) = seen[h.part.index as usize].replace(&p.path) {
            return Err(MergeError(format!(
                "{} and {} are both part {}: a part is merged once",
                other.display(),
                p.path.display(),
                h.part
            )));
        }
    }
    let incomplete: Vec<&Named> = parts.iter().filter(|p| !p.header.complete).collect();
    if let (Some(p), false) = (incomplete.first(), allow_missing) {
        return Err(MergeError(format!(
            "{} is part {} stopped before its samples were all taken (a checkpoint): resume it \
             (`render --resume`), or merge what there is with --allow-missing",
            p.path.display(),
            p.header.part
        )));
    }
    let missing: Vec<u32> = (0..count).filter(|&i| seen[i as usize].is_none()).collect();
    if !missing.is_empty() && !allow_missing {
        let list: Vec<String> = missing.iter().map(|i| format!("{i}/{count}")).collect();
        return Err(MergeError(format!(
            "missing part{} {} of {count} (--allow-missing merges what there is)",
            if missing.len() == 1 { "" } else { "s" },
            list.join(", ")
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
