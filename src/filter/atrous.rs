//! Beyond the paper's 3x3 filters: an edge-avoiding à-trous wavelet filter (Dammertz et al.
//! 2010), guided by each pixel's variance as in SVGF (Schied et al. 2017).
//!
//! Several passes of one small kernel (B3-spline 5x5, or 3x3) with holes growing 1, 2, 4, ...
//! Each neighbour's weight stops at the object ID (hard), the normal, the depth and the colour:
//! the colour stop is the luminance difference in standard deviations of the pixel's own
//! filtered variance, so noisy pixels are smoothed hard and clean ones kept. What is filtered is
//! illumination, not texture: each layer is divided by the albedo first and multiplied back.
//!
//! One pass, for a centre `p` with taps `q = p + s (dx, dy)`, `s = 2^pass`, `h` the kernel:
//! - `k_q = h(dx) h(dy) [key_p = key_q] 2^-(t_n + t_z + t_l)` with
//!   `t_n = σ_n (1 - n_p·n_q)`, `t_z = |z_p - z_q| / (σ_z |∇z|_p s |(dx, dy)|)` and
//!   `t_l = |l_p - l'_q| / (σ_l sqrt(g3x3(V)_p))` (the exponents in units of log2 e), `l'` the
//!   layer's own luminance or, for one half of a layer's samples, the other half's
//!   ([`FilterInput::stops_from`]), against which the first pass takes `l_p` blurred as `V`;
//! - `u'_p = u_p + Σ k_q (u_q - u_p) / W` with `W = h(0) + Σ k_q` (the centre counts with its
//!   kernel weight alone), so a constant image is exact;
//! - `V'_p = (h(0)² V_p + Σ k_q² V_q) / W²`, the variance of that weighted mean;
//! - with [`Atrous::linear`], from its pass on, `u'_p` is instead the value at `p` of the plane
//!   fitted to the centre (weight `h(0)`) and its taps (weights `k_q`) by least squares, its
//!   slopes held by a ridge that grows with the centre's relative noise (`RIDGE`).
//!
//! A pixel whose blurred variance `g3x3(V)_p` is 0 has no noise to remove and keeps its value
//! (every tap of another luminance would weigh 2^-125 or less anyway); rows are filtered only
//! over their runs of noisy pixels.
//!
//! The sums are fused multiply-adds (`mul_add`: one rounding each, in every build: the SIMD
//! builds have FMA, the portable one computes it by a call), as is the cubic of [`exp2_neg`].
//!
//! Taps outside the image are left out (not replicated: at a hole of 16 pixels replication
//! would pile weight onto the border). Every output pixel is computed on its own from the
//! previous pass, so the result is the same for any number of threads.

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use crate::accel::bvh::simd::{Inlined, Isa};
use crate::component::Component;
use crate::film::{Film, Image};
use crate::math::luminance;

use super::pool::{Pixels, Plane};

/// The à-trous filter's settings; [`Atrous::default`] holds the measured defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Atrous {
    /// Passes, with holes 1, 2, 4, ... 2^(passes - 1).
    pub passes: u32,
    /// The colour stop: a luminance difference of this many standard deviations of the
    /// centre's (filtered, 3x3-blurred) variance weighs 1/e.
    pub sigma_l: f32,
    /// The normal stop: a neighbour weighs `exp(-sigma_n (1 - cos θ))`.
    pub sigma_n: f32,
    /// The depth stop: a depth difference of `sigma_z` times the centre's depth gradient
    /// over the tap's distance weighs 1/e.
    pub sigma_z: f32,
    /// The kernel's width: 5 (B3 spline, 1 4 6 4 1) or 3 (1 2 1).
    pub taps: u32,
    /// Under `--filter-target components`, the direct light's own `sigma_l` and `passes`
    /// (`direct_sigma_l`, `direct_passes`); unset, the ones above.
    pub direct: Strength,
    /// The same for the caustic light (`caustic_sigma_l`, `caustic_passes`).
    pub caustic: Strength,
    /// `clamp=K`: no pixel's channel moves by more than K standard deviations of its mean
    /// (the layer's variance, scaled to the channel), so a filter can take away noise but
    /// not detail the noise cannot explain; unset, no bound.
    pub clamp: Option<f32>,
    /// `cross=1` (the default): where the film has the halves of its samples, each layer is
    /// also filtered half by half and kept only where that check says it lowers the error
    /// ([`super::cross`]); `cross=0` filters without the check.
    pub cross: bool,
    /// `linear=P`: pass P (counted from 1) and the later ones fit a plane to their taps
    /// (weighted least squares, the slopes held by a ridge that grows with the pixel's noise:
    /// `RIDGE`) and keep the plane's value
    /// at the centre, not the taps' weighted mean: a gradient of the light, and the one-sided
    /// windows beside an object's border, are kept without the mean's pull toward the
    /// window's centroid, so the wider passes smooth noise without flattening the light. 0
    /// (the default): no pass does.
    pub linear: u32,
}

/// One component's colour stop and passes, where they differ from the filter's own.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Strength {
    pub sigma_l: Option<f32>,
    /// 0 leaves the component as it is.
    pub passes: Option<u32>,
}

impl Default for Atrous {
    fn default() -> Self {
        Atrous {
            passes: 5,
            sigma_l: 4.0,
            sigma_n: 128.0,
            sigma_z: 1.0,
            taps: 5,
            direct: Strength::default(),
            caustic: Strength::default(),
            clamp: None,
            cross: true,
            linear: 0,
        }
    }
}

const MAX_PASSES: u32 = 12;

impl Atrous {
    /// `atrous`, optionally with settings: `atrous:passes=4:sigma_l=8`.
    pub fn parse(spec: &str) -> Result<Atrous, String> {
        let mut parts = spec.split(':');
        if parts.next() != Some("atrous") {
            return Err(format!("`{spec}` is not an atrous filter"));
        }
        let mut a = Atrous::default();
        for part in parts {
            let (key, value) = part
                .split_once('=')
                .ok_or_else(|| format!("atrous setting `{part}` is not key=value (e.g. atrous:passes=4)"))?;
            let number = value
                .trim()
                .parse::<f32>()
                .map_err(|_| format!("atrous setting {key}: `{value}` is not a number"))?;
            match key.trim() {
                "passes" => a.passes = whole(key, number)?,
                "sigma_l" => a.sigma_l = number,
                "sigma_n" => a.sigma_n = number,
                "sigma_z" => a.sigma_z = number,
                "taps" => a.taps = whole(key, number)?,
                "direct_sigma_l" => a.direct.sigma_l = Some(number),
                "direct_passes" => a.direct.passes = Some(whole(key, number)?),
                "caustic_sigma_l" => a.caustic.sigma_l = Some(number),
                "caustic_passes" => a.caustic.passes = Some(whole(key, number)?),
                "clamp" => a.clamp = Some(number),
                "cross" if number == 0.0 || number == 1.0 => a.cross = number == 1.0,
                "cross" => return Err(format!("atrous setting cross: `{value}` is not 0 or 1")),
                "linear" => a.linear = whole(key, number)?,
                other => {
                    return Err(format!(
                        "unknown atrous setting `{other}` (passes, sigma_l, sigma_n, sigma_z, taps, \
                         direct_sigma_l, direct_passes, caustic_sigma_l, caustic_passes, clamp, cross, linear)"
                    ))
                }
            }
        }
        a.check()?;
        Ok(a)
    }

    /// Checks the ranges: 1 to 12 passes (0 to 12 for a component's own), positive finite
    /// sigmas, 3 or 5 taps.
    pub fn check(&self) -> Result<(), String> {
        if !(1..=MAX_PASSES).contains(&self.passes) {
            return Err(format!("atrous passes must be 1 to {MAX_PASSES}, not {}", self.passes));
        }
        if self.linear > MAX_PASSES {
            return Err(format!("atrous linear must be 0 to {MAX_PASSES}, not {}", self.linear));
        }
        for (name, p) in [("direct_passes", self.direct.passes), ("caustic_passes", self.caustic.passes)] {
            if p.is_some_and(|p| p > MAX_PASSES) {
                return Err(format!("atrous {name} must be 0 to {MAX_PASSES}, not {}", p.unwrap_or(0)));
            }
        }
        let own = |s: Option<f32>| s.unwrap_or(self.sigma_l);
        for (name, v) in [
            ("sigma_l", self.sigma_l),
            ("sigma_n", self.sigma_n),
            ("sigma_z", self.sigma_z),
            ("direct_sigma_l", own(self.direct.sigma_l)),
            ("caustic_sigma_l", own(self.caustic.sigma_l)),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("atrous {name} must be a positive number, not {v}"));
            }
        }
        if let Some(k) = self.clamp.filter(|k| !(k.is_finite() && *k >= 0.0)) {
            return Err(format!("atrous clamp must be a non-negative number, not {k}"));
        }
        if self.taps != 3 && self.taps != 5 {
            return Err(format!("atrous taps must be 3 or 5, not {}", self.taps));
        }
        Ok(())
    }

    /// The name [`Atrous::parse`] reads back: `atrous` and the settings that differ from the
    /// defaults.
    pub fn name(&self) -> String {
        let d = Atrous::default();
        let mut out = "atrous".to_string();
        let mut add = |key: &str, v: f32, default: f32| {
            if v != default {
                out.push_str(&format!(":{key}={v}"));
            }
        };
        add("passes", self.passes as f32, d.passes as f32);
        add("sigma_l", self.sigma_l, d.sigma_l);
        add("sigma_n", self.sigma_n, d.sigma_n);
        add("sigma_z", self.sigma_z, d.sigma_z);
        add("taps", self.taps as f32, d.taps as f32);
        add("linear", self.linear as f32, d.linear as f32);
        for (name, s) in [("direct", self.direct), ("caustic", self.caustic)] {
            if let Some(v) = s.sigma_l {
                out.push_str(&format!(":{name}_sigma_l={v}"));
            }
            if let Some(p) = s.passes {
                out.push_str(&format!(":{name}_passes={p}"));
            }
        }
        if let Some(k) = self.clamp {
            out.push_str(&format!(":clamp={k}"));
        }
        out
    }

    /// Whether pass `pass` (counted from 0) fits a plane: from pass `linear` on, counted from 1.
    fn fits_plane(&self, pass: u32) -> bool {
        self.linear > 0 && pass + 1 >= self.linear
    }

    /// The colour stop and passes of a layer that is `component` (if it is one).
    fn strength(&self, component: Option<Component>) -> (f32, u32) {
        let own = match component {
            Some(Component::Direct) => self.direct,
            Some(Component::Caustic) => self.caustic,
            _ => Strength::default(),
        };
        (own.sigma_l.unwrap_or(self.sigma_l), own.passes.unwrap_or(self.passes))
    }

    /// Whether this filter changes `layer` at all: not when the layer has no passes or is zero
    /// everywhere (no caustics in the scene); such a layer is left as it is.
    pub(super) fn changes(&self, layer: &FilterInput) -> bool {
        self.strength(layer.component).1 > 0 && !crate::scene::image::all_black(layer.image)
    }

    /// The 1-D kernel, centre in the middle.
    fn kernel(&self) -> &'static [f32] {
        if self.taps == 3 {
            &[0.25, 0.5, 0.25]
        } else {
            &[1.0 / 16.0, 0.25, 0.375, 0.25, 1.0 / 16.0]
        }
    }
}

fn whole(key: &str, v: f32) -> Result<u32, String> {
    if v.fract() == 0.0 && (0.0..=1e6).contains(&v) {
        Ok(v as u32)
    } else {
        Err(format!("atrous setting {key} must be a whole number, not {v}"))
    }
}

/// One layer to filter: an image of means and the variance of each pixel's mean luminance.
#[derive(Clone, Copy)]
pub struct FilterInput<'a> {
    /// The layer's pixels, the film's size.
    pub image: &'a [Vec3],
    /// Without it (an old film), the colour stop sees no noise and nothing is smoothed.
    pub variance: Option<&'a [f32]>,
    /// The light-path component the layer holds, if it is one: [`Atrous::direct`] and
    /// [`Atrous::caustic`] apply to theirs.
    pub component: Option<Component>,
    /// The layer's second half and its share of the samples ([`crate::film::Film::half`],
    /// [`crate::film::Film::half_share`]), when the film has them: the filter is then checked
    /// against the layer's own noise ([`super::cross`]).
    pub halves: Option<(&'a [Vec3], &'a [f32])>,
    /// The layer of the same call (an index into its layers) whose luminance at a tap the
    /// colour stop compares with the centre's own: the other half of its samples, whose noise
    /// is independent of this half's, so a tap's weight does not follow the value it adds. The
    /// centre's luminance and variance stay the layer's own, so the filtered half stays
    /// independent of the other half at the centre, which the check against it needs
    /// ([`super::cross`]). None: its own. Used only where both have the same passes.
    pub stops_from: Option<usize>,
}

impl<'a> FilterInput<'a> {
    /// A layer that is no particular component.
    pub fn new(image: &'a Image, variance: Option<&'a [f32]>) -> FilterInput<'a> {
        FilterInput { image: &image.pixels, variance, component: None, halves: None, stops_from: None }
    }
}

/// The smallest albedo divided by: darker channels are treated as black ([`demodulate`]).
const MIN_ALBEDO: f32 = 1e-3;
const LOG2_E: f32 = std::f32::consts::LOG2_E;
/// Planes per layer in the working buffers: r, g, b (illumination), l (its luminance), v.
const PLANES: usize = 5;
/// The extra sums per layer of a pass that fits a plane ([`Atrous::linear`]): the weights'
/// moments `Σk dx`, `Σk dy`, `Σk dx²`, `Σk dx dy`, `Σk dy²` and the weighted differences'
/// `Σk Δr dx`, `Σk Δg dx`, `Σk Δb dx`, `Σk Δr dy`, `Σk Δg dy`, `Σk Δb dy` (taps' offsets in
/// kernel steps).
const MOMENTS: usize = 11;
/// The plane fit's ridge on its slopes, as a share of the weight sum, grown with the centre's
/// relative noise: `Σk dx² + RIDGE W (1 + RIDGE_NOISE V / l²)`, `V` the variance carried to
/// the pass and `l` the luminance. Without it a window of taps on one line has no plane; with
/// it fixed, slopes fitted to noise cost the Cornell box 7% of its relMSE at 4 spp. Measured on
/// the three denoising scenes: 0.1 against 0.03 and 0.3, and 32 against 0, 16, 64 and 256
/// (docs/RESULTS.md, "Denoising").
const RIDGE: f32 = 0.1;
const RIDGE_NOISE: f32 = 32.0;

/// Filters each layer with `a`, its colour stop scaled by its own variance, all sharing the
/// guides of `film` (albedo, normal, depth, object; with `pure`, pixels whose samples saw more
/// than one object stay out of their neighbours' windows and are filtered only among
/// themselves). The film's guides and
/// the layers must have the film's size. The passes run in the best build this CPU has: AVX-512
/// was the same time as AVX2 on a Zen 5 machine and about 5% faster at 256x256 on a Zen 4 one
/// (docs/RESULTS.md, "On a Zen 4 machine").
pub fn filter(layers: &[FilterInput], film: &Film, a: &Atrous, pure: bool) -> Vec<Pixels> {
    filter_with(Isa::best(), layers, film, a, pure)
}

/// [`filter`] with the passes in the build `isa`, in bands of rows when the working buffers
/// of the whole image would be large ([`band_rows`]).
fn filter_with(isa: Isa, layers: &[FilterInput], film: &Film, a: &Atrous, pure: bool) -> Vec<Pixels> {
    filter_in_bands(isa, layers, film, a, pure, None)
}

/// The most bytes the two working buffers of a call may take together before the image is
/// filtered in bands: a 512x512 film's with a few layers stays whole, a 4K one (1.3 GB of
/// buffers, most of a call's fresh memory) goes in bands.
const WHOLE_BYTES: usize = 64 << 20;
/// The rows a band filters at least, besides the rows its passes read above and below it.
const BAND: usize = 128;

/// The output rows of each band for an image of `w` x `h` with `k` live layers whose passes read
/// `reach` rows around a band: [`BAND`] once the whole image's two buffers would take more than
/// [`WHOLE_BYTES`] and the image is tall enough for bands to save rows, else all of them.
fn band_rows(w: usize, h: usize, k: usize, reach: usize) -> usize {
    let bytes = 2 * h * k * PLANES * w * size_of::<f32>();
    if bytes > WHOLE_BYTES && h > BAND + 2 * reach {
        BAND
    } else {
        h
    }
}

/// The rows above and below its own that pass `pass` reads for one output row: its taps' reach,
/// and at least the one row of the colour stops' 3x3 blur.
fn pass_reach(a: &Atrous, pass: u32) -> usize {
    ((a.kernel().len() / 2) << pass).max(1)
}

/// The rows above and below a band that its passes `0..passes` read, all together.
fn band_reach(a: &Atrous, passes: u32) -> usize {
    (0..passes).map(|p| pass_reach(a, p)).sum()
}

/// [`filter_with`] in bands of `band` output rows ([`band_rows`] without): each band
/// demodulates the rows its passes read, runs every pass over the rows the next pass reads,
/// and multiplies back its own rows. Every row is computed from the same rows of the pass
/// before as in one band, so the bands give the same bits; the rows around a band are computed
/// again by its neighbours (about an eighth more arithmetic at 4K), and the buffers are a band's,
/// not the image's.
fn filter_in_bands(
    isa: Isa,
    layers: &[FilterInput],
    film: &Film,
    a: &Atrous,
    pure: bool,
    band: Option<usize>,
) -> Vec<Pixels> {
    let (w, h) = (film.width as usize, film.height as usize);
    // Layers that are zero everywhere, or have no passes, stay as they are.
    let live: Vec<usize> = (0..layers.len()).filter(|&i| a.changes(&layers[i])).collect();
    // The layers left as they are copied in parallel, as are the halves and the final sum:
    // copies by the calling thread alone, while the pool's threads waited, were two fifths of
    // its time (perf, 256x256).
    let mut out: Vec<Pixels> = layers
        .iter()
        .enumerate()
        .map(|(i, l)| {
            // A live layer's every row is written by its multiply-back, from its input.
            if live.contains(&i) {
                Pixels::overwritten(l.image.len())
            } else {
                Pixels::copy_of(l.image)
            }
        })
        .collect();
    if live.is_empty() || w == 0 || h == 0 {
        return out;
    }
    let guides = Guides::new(film, a, pure);
    let k = live.len();
    // Each layer's colour stop and passes.
    let strengths: Vec<(f32, u32)> = live.iter().map(|&li| a.strength(layers[li].component)).collect();
    // The live layer whose taps' luminance each live layer's colour stop reads: the one it
    // names, if that one runs at least its passes (a layer past its passes is not written),
    // else its own.
    let stops_from: Vec<usize> = live
        .iter()
        .enumerate()
        .map(|(c, &li)| {
            let from = layers[li].stops_from.and_then(|j| live.iter().position(|&l| l == j));
            from.filter(|&d| strengths[d].1 >= strengths[c].1).unwrap_or(c)
        })
        .collect();
    // The passes run: none once a pass's every tap would fall outside the image.
    let run = (0..strengths.iter().map(|s| s.1).max().unwrap_or(0))
        .take_while(|&p| (1usize << p) < w.max(h))
        .count() as u32;
    let reach = band_reach(a, run);
    let band = band.unwrap_or_else(|| band_rows(w, h, k, reach)).clamp(1, h);
    // Rows `rest[p]` above and below a band that pass p writes: what the passes after it read.
    let rest: Vec<usize> = (0..run).map(|p| reach - band_reach(a, p + 1)).collect();
    let rows_held = (band + 2 * reach).min(h);
    // Demodulated illumination, its luminance and its variance, row by row.
    let mut cur = Plane::overwritten(rows_held * k * PLANES * w);
    // Each pass writes the rows of its live layers only; a layer past its passes stays in the
    // buffer its last pass wrote, and neither buffer's other planes are read.
    let mut next = Plane::overwritten(cur.len());
    let albedo = |i: usize| film.albedo.pixels[i].max(Vec3::ZERO);
    // With `clamp`, each channel's change at most K standard deviations of the pixel's mean:
    // the layer's luminance deviation, scaled to a channel brighter than the luminance.
    let bound = a.clamp;
    for b0 in (0..h).step_by(band) {
        let b1 = (b0 + band).min(h);
        // The image rows the buffers hold, from `row0`.
        let row0 = b0.saturating_sub(reach);
        let held = row0..(b1 + reach).min(h);
        cur[..held.len() * k * PLANES * w].par_chunks_mut(k * PLANES * w).enumerate().for_each(|(r, row)| {
            let y = row0 + r;
            for (c, &li) in live.iter().enumerate() {
                let layer = layers[li];
                let planes = &mut row[c * PLANES * w..(c + 1) * PLANES * w];
                for x in 0..w {
                    let i = y * w + x;
                    let (v, a) = (layer.image[i], albedo(i));
                    let u = demodulate(v, a);
                    let (lu, lv) = (luminance(u), luminance(v));
                    let ratio = if lv > 0.0 { lu / lv } else { 1.0 / luminance(a).max(MIN_ALBEDO) };
                    let var = layer.variance.map_or(0.0, |v| v[i].max(0.0)) * ratio * ratio;
                    for (p, value) in
                        [u.x, u.y, u.z, lu, if var.is_finite() { var } else { 0.0 }].into_iter().enumerate()
                    {
                        planes[p * w + x] = value;
                    }
                }
            }
        });
        for pass in 0..run {
            let rows = b0.saturating_sub(rest[pass as usize])..(b1 + rest[pass as usize]).min(h);
            let buffers = (&cur[..], &mut next[..]);
            run_pass(isa, (a, &strengths, &stops_from), &guides, (w, h, k), pass, (rows, row0), buffers);
            std::mem::swap(&mut cur, &mut next);
        }
        // Multiplied back, as a change to the input: out = in + albedo (u_last - u_first), the
        // first made again as it was (bounded by `bound`).
        for (c, &li) in live.iter().enumerate() {
            let (variance, input) = (layers[li].variance, layers[li].image);
            let image = &mut out[li];
            // The buffer the layer's last pass wrote: `cur` after an even number of passes since.
            let cur = if (run - strengths[c].1.min(run)).is_multiple_of(2) { &cur } else { &next };
            image[b0 * w..b1 * w].par_chunks_mut(w).enumerate().for_each(|(r, row)| {
                let y = b0 + r;
                let base = ((y - row0) * k + c) * PLANES * w;
                for (x, o) in row.iter_mut().enumerate() {
                    let i = y * w + x;
                    let px = input[i];
                    let albedo = albedo(i);
                    let last = Vec3::new(cur[base + x], cur[base + w + x], cur[base + 2 * w + x]);
                    let change = albedo * (last - demodulate(px, albedo));
                    let change = match (bound, variance) {
                        (Some(k), Some(v)) => {
                            let lum = luminance(px);
                            let scale = if lum > 0.0 { (px / lum).max(Vec3::ONE) } else { Vec3::ONE };
                            let limit = k * v[i].max(0.0).sqrt() * scale;
                            change.clamp(-limit, limit)
                        }
                        _ => change,
                    };
                    *o = px + change;
                }
            });
        }
    }
    out
}

/// Pass `pass` (holes of `2^pass` pixels) over `cur`, rows of `k` layers of [`PLANES`] planes
/// of width `w` holding the image rows from `row0`, into the image rows `rows` of `next`, which
/// holds the same rows as `cur`.
#[allow(clippy::too_many_arguments)]
fn run_pass(
    isa: Isa,
    (a, strengths, stops_from): (&Atrous, &[(f32, u32)], &[usize]),
    guides: &Guides,
    (w, h, k): (usize, usize, usize),
    pass: u32,
    (rows, row0): (std::ops::Range<usize>, usize),
    (cur, next): (&[f32], &mut [f32]),
) {
    let step = 1usize << pass;
    let pass = Pass { a, strengths, stops_from, pass, w, h, k, step, guides, cur, row0 };
    let (first, last) = (rows.start - row0, rows.end - row0);
    let width = k * PLANES * w;
    next[first * width..last * width].par_chunks_mut(width).enumerate().for_each_init(
        || Scratch::new(w, k),
        |scratch, (r, out)| isa.run(Row { pass: &pass, y: rows.start + r, out, scratch }),
    );
}

/// One output row of a pass ([`Pass::row`]) with its colour stops first ([`Pass::colour_stops`]),
/// as a job [`Isa::run`] compiles for its build. A job, not a closure: a closure run in the AVX2
/// build was left outlined, in the portable build, and the passes took 1.3x as long (criterion
/// 11.8 to 13.1 ms against 9.1 to 9.4 ms at 256x256).
struct Row<'p, 'a> {
    pass: &'p Pass<'a>,
    y: usize,
    out: &'p mut [f32],
    scratch: &'p mut Scratch,
}

impl Inlined for Row<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let s = self.scratch;
        self.pass.colour_stops(self.y, &mut s.stops, &mut s.blur);
        self.pass.row(self.y, self.out, s)
    }
}

/// The illumination that albedo `a` turned into `v`: `v / a` per channel, and where a channel
/// of the albedo is (nearly) black, so that its light cannot be seen, the grey light
/// `lum(v) / lum(a)`. Multiplied back by `a`, that channel's change vanishes anyway; the
/// estimate keeps the luminance of a red surface's light comparable with a grey one's.
#[inline(always)]
fn demodulate(v: Vec3, a: Vec3) -> Vec3 {
    if a.min_element() >= MIN_ALBEDO {
        // Every channel seen: one vector division.
        return Vec3::from(Vec3A::from(v) / Vec3A::from(a));
    }
    let grey = luminance(v) / luminance(a).max(MIN_ALBEDO);
    Vec3::select(a.cmpge(Vec3::splat(MIN_ALBEDO)), v / a.max(Vec3::splat(MIN_ALBEDO)), Vec3::splat(grey))
}

/// The key of a pixel whose samples saw more than one object, under `pure`: such pixels mix
/// only with each other, along the border they lie on (their normals and depths are averages
/// of both sides, so the other stops keep them there).
const MIXED: f32 = -2.0;

/// The guide planes, made once: normal, depth, the object key (NaN where the pixel may not
/// mix: no object; [`MIXED`] with `pure` for a mixed pixel) and the inverse depth gradient.
struct Guides {
    nx: Plane,
    ny: Plane,
    nz: Plane,
    z: Plane,
    key: Plane,
    /// `log2 e / (σ_z |∇z|)` per pixel.
    inv_dz: Plane,
}

impl Guides {
    fn new(film: &Film, a: &Atrous, pure: bool) -> Guides {
        let (w, h) = (film.width as usize, film.height as usize);
        let n = w * h;
        let mut key = Plane::overwritten(n);
        key.par_iter_mut().enumerate().for_each(|(i, k)| {
            let o = film.object[i];
            *k = if o < 0.0 {
                f32::NAN
            } else if pure && film.coverage[i] < 1.0 {
                MIXED
            } else {
                o
            };
        });
        let mut z = Plane::overwritten(n);
        z.par_iter_mut().zip(&film.depth).for_each(|(z, &d)| *z = if d.is_finite() { d } else { 0.0 });
        let (mut nx, mut ny, mut nz) = (Plane::overwritten(n), Plane::overwritten(n), Plane::overwritten(n));
        nx.par_iter_mut().zip(&mut *ny).zip(&mut *nz).zip(&film.normal.pixels).for_each(
            |(((x, y), z), &v)| {
                let v = if v.is_finite() { v } else { Vec3::ZERO };
                (*x, *y, *z) = (v.x, v.y, v.z);
            },
        );
        // The depth gradient: along each axis the smaller one-sided difference to a neighbour
        // of the same object (so a silhouette does not count), then the larger of the axes.
        // Row by row, from the steps between neighbours (INFINITY across objects and past the
        // image's ends), each step made once for both of its pixels: flat loops.
        let mut inv_dz = Plane::overwritten(n);
        let (keys, depths) = (&*key, &*z);
        inv_dz.par_chunks_mut(w).enumerate().for_each_init(
            || (vec![0.0f32; w + 1], vec![0.0f32; w], vec![0.0f32; w]),
            |(across, up, down), (y, row)| {
                let (kr, zr) = (&keys[y * w..(y + 1) * w], &depths[y * w..(y + 1) * w]);
                let step = |ka: f32, kb: f32, za: f32, zb: f32| {
                    if ka == kb {
                        (za - zb).abs()
                    } else {
                        f32::INFINITY
                    }
                };
                // across[x]: the step from x - 1 to x.
                (across[0], across[w]) = (f32::INFINITY, f32::INFINITY);
                for x in 1..w {
                    across[x] = step(kr[x - 1], kr[x], zr[x - 1], zr[x]);
                }
                for (ry, out) in [(y.checked_sub(1), &mut *up), ((y + 1 < h).then_some(y + 1), &mut *down)] {
                    match ry {
                        Some(ry) => {
                            let (ko, zo) = (&keys[ry * w..(ry + 1) * w], &depths[ry * w..(ry + 1) * w]);
                            for x in 0..w {
                                out[x] = step(ko[x], kr[x], zo[x], zr[x]);
                            }
                        }
                        None => out.fill(f32::INFINITY),
                    }
                }
                let axis = |a: f32, b: f32| if a.min(b).is_finite() { a.min(b) } else { 0.0 };
                for x in 0..w {
                    let (gx, gy) = (axis(across[x], across[x + 1]), axis(up[x], down[x]));
                    row[x] = LOG2_E / (a.sigma_z * gx.max(gy) + 1e-4 * zr[x].abs() + 1e-12);
                }
            },
        );
        Guides { nx, ny, nz, z, key, inv_dz }
    }
}

/// One pass: reads `cur`, writes rows of the next buffer.
struct Pass<'a> {
    a: &'a Atrous,
    /// Per layer, its `sigma_l` and passes.
    strengths: &'a [(f32, u32)],
    /// Per layer, the layer whose luminance at the taps its colour stop reads (itself, or the
    /// other half of its samples: [`FilterInput::stops_from`]).
    stops_from: &'a [usize],
    pass: u32,
    w: usize,
    h: usize,
    /// Layers.
    k: usize,
    step: usize,
    guides: &'a Guides,
    /// The rows of the pass before, from image row `row0`.
    cur: &'a [f32],
    /// The image row that the first row of `cur` holds.
    row0: usize,
}

/// Per-thread scratch for one output row: per layer the accumulators of r, g, b, v and the weight
/// sum; the tap's geometric weight and exponent; and the row's colour stops.
struct Scratch {
    acc: Vec<f32>,
    /// Per layer, the [`MOMENTS`] sums of a pass that fits a plane.
    moments: Vec<f32>,
    /// A tap's weights, in a pass that fits a plane.
    weights: Vec<f32>,
    geo: Vec<f32>,
    exponent: Vec<f32>,
    /// Per layer, the runs of the row's pixels with noise to remove.
    spans: Vec<Vec<(usize, usize)>>,
    /// The row's colour stops: per layer `log2 e / (σ_l sqrt(g3x3(V)))`, then per layer the
    /// luminance its colour stop gives the centre where [`Pass::blurs_centre`]. Made by the row's
    /// own job, as no other row reads them.
    stops: Vec<f32>,
    /// Scratch of [`Pass::colour_stops`]'s blur.
    blur: (Vec<f32>, Vec<f32>, Vec<f32>),
}

impl Scratch {
    fn new(w: usize, k: usize) -> Scratch {
        Scratch {
            acc: vec![0.0; k * PLANES * w],
            moments: Vec::new(),
            weights: vec![0.0; w],
            geo: vec![0.0; w],
            exponent: vec![0.0; w],
            spans: vec![Vec::new(); k],
            stops: vec![0.0; 2 * k * w],
            blur: (Vec::new(), Vec::new(), Vec::new()),
        }
    }
}

/// A row's weighted means from its centres and sums (plane by plane, so the loop vectorises):
/// the centre plus the weighted differences over the weight sum, its luminance, and the
/// variance of the weighted mean.
#[inline(always)]
fn finish_row(
    h0: f32,
    [r0, g0, b0, v0]: [&[f32]; 4],
    [ar, ag, ab, av, aw]: [&[f32]; 5],
    [dr, dg, db, dl, dv]: [&mut [f32]; 5],
) {
    let n = dr.len();
    let (r0, g0, b0, v0) = (&r0[..n], &g0[..n], &b0[..n], &v0[..n]);
    let (ar, ag, ab, av, aw) = (&ar[..n], &ag[..n], &ab[..n], &av[..n], &aw[..n]);
    let (dg, db, dl, dv) = (&mut dg[..n], &mut db[..n], &mut dl[..n], &mut dv[..n]);
    for x in 0..n {
        let inv = 1.0 / (h0 + aw[x]);
        let (r, g, b) = (r0[x] + ar[x] * inv, g0[x] + ag[x] * inv, b0[x] + ab[x] * inv);
        dr[x] = r;
        dg[x] = g;
        db[x] = b;
        // `luminance`, term by term in its order.
        dl[x] = r * 0.2126 + g * 0.7152 + b * 0.0722;
        dv[x] = (h0 * h0 * v0[x] + av[x]) * inv * inv;
    }
}

/// [`finish_row`] for a pass that fits a plane: the centre's value is the plane's, from the
/// weighted least squares over the centre (offset 0, weight `h0`) and its taps, solved by the
/// first row of the 3x3 normal matrix's inverse (its cofactors over its determinant; the ridge
/// keeps it positive definite). The variance is the weighted mean's, as in [`finish_row`]: it
/// only sets the next pass's colour stops, and the plane's own (larger beside a border, equal
/// in a full symmetric window) measured no better there.
#[inline(always)]
fn finish_row_linear(
    h0: f32,
    [r0, g0, b0, v0]: [&[f32]; 4],
    [ar, ag, ab, av, aw]: [&[f32]; 5],
    m: &[f32],
    [dr, dg, db, dl, dv]: [&mut [f32]; 5],
) {
    let n = dr.len();
    let (r0, g0, b0, v0) = (&r0[..n], &g0[..n], &b0[..n], &v0[..n]);
    let (ar, ag, ab, av, aw) = (&ar[..n], &ag[..n], &ab[..n], &av[..n], &aw[..n]);
    let w = m.len() / MOMENTS;
    let mo = |i: usize| &m[i * w..i * w + n];
    let (sx, sy, sxx, sxy, syy) = (mo(0), mo(1), mo(2), mo(3), mo(4));
    let (rx, gx, bx, ry, gy, by) = (mo(5), mo(6), mo(7), mo(8), mo(9), mo(10));
    let (dg, db, dl, dv) = (&mut dg[..n], &mut db[..n], &mut dl[..n], &mut dv[..n]);
    for x in 0..n {
        let sum = h0 + aw[x];
        let l0 = r0[x] * 0.2126 + g0[x] * 0.7152 + b0[x] * 0.0722;
        let ridge = RIDGE * sum * (1.0 + RIDGE_NOISE * v0[x] / (l0 * l0 + 1e-12));
        let (xx, yy) = (sxx[x] + ridge, syy[x] + ridge);
        let c0 = xx * yy - sxy[x] * sxy[x];
        let c1 = sxy[x] * sy[x] - sx[x] * yy;
        let c2 = sx[x] * sxy[x] - xx * sy[x];
        let inv = 1.0 / (sum * c0 + sx[x] * c1 + sy[x] * c2);
        let (c0, c1, c2) = (c0 * inv, c1 * inv, c2 * inv);
        let (r, g, b) = (
            r0[x] + c0 * ar[x] + c1 * rx[x] + c2 * ry[x],
            g0[x] + c0 * ag[x] + c1 * gx[x] + c2 * gy[x],
            b0[x] + c0 * ab[x] + c1 * bx[x] + c2 * by[x],
        );
        dr[x] = r;
        dg[x] = g;
        db[x] = b;
        dl[x] = r * 0.2126 + g * 0.7152 + b * 0.0722;
        let inv = 1.0 / sum;
        dv[x] = (h0 * h0 * v0[x] + av[x]) * inv * inv;
    }
}

/// The colour stop of a pixel whose blurred variance is 0: one with no noise to remove, which
/// keeps its value (taps of any other luminance would weigh 2^-125 or less anyway).
const NOISELESS: f32 = LOG2_E / 1e-10;

/// Into `spans`, the runs of pixels of a row whose colour stops `inv_sigma` show noise, runs
/// less than 8 pixels apart joined (a few noiseless pixels cost less than another call). A
/// block of 16 pixels all with noise is taken in one step (a test the compiler vectorises),
/// as pixel by pixel it would join them into one run.
#[inline(always)]
fn active_spans(inv_sigma: &[f32], spans: &mut Vec<(usize, usize)>) {
    const BLOCK: usize = 16;
    spans.clear();
    let mut add = |x0: usize, x1: usize| match spans.last_mut() {
        Some(last) if x0 < last.1 + 8 => last.1 = x1,
        _ => spans.push((x0, x1)),
    };
    for (b, block) in inv_sigma.chunks(BLOCK).enumerate() {
        let x0 = b * BLOCK;
        if block.len() == BLOCK && block.iter().fold(true, |all, &isg| all & (isg < NOISELESS)) {
            add(x0, x0 + BLOCK);
            continue;
        }
        for (x, &isg) in block.iter().enumerate() {
            if isg < NOISELESS {
                add(x0 + x, x0 + x + 1);
            }
        }
    }
}

impl Pass<'_> {
    /// The plane `p` of layer `c` in row `y` of `cur`.
    #[inline(always)]
    fn plane(&self, y: usize, c: usize, p: usize) -> &[f32] {
        let base = (((y - self.row0) * self.k + c) * PLANES + p) * self.w;
        &self.cur[base..base + self.w]
    }

    /// Row `y` of the colour stops: each layer's variance blurred over the 3x3 Gaussian
    /// (1/4 centre, 1/8 sides, 1/16 corners) among same-object neighbours, then where
    /// [`Self::blurs_centre`] the layer's luminance blurred the same way; `sum`, `weight` and
    /// `lum` are scratch.
    #[inline(always)]
    fn colour_stops(
        &self,
        y: usize,
        out: &mut [f32],
        (sum, weight, lum): &mut (Vec<f32>, Vec<f32>, Vec<f32>),
    ) {
        let (w, h) = (self.w, self.h);
        let key = &self.guides.key;
        let kc = &key[y * w..(y + 1) * w];
        const K: [f32; 3] = [0.25, 0.5, 0.25];
        for c in 0..self.k {
            if self.pass >= self.strengths[c].1 {
                // Past its passes: the layer is carried over ([`Pass::row`] reads no stop).
                continue;
            }
            let blur = self.blurs_centre(c);
            for plane in [&mut *sum, &mut *weight, &mut *lum] {
                plane.clear();
                plane.resize(w, 0.0);
            }
            for dy in -1i64..=1 {
                let yy = y as i64 + dy;
                if yy < 0 || yy >= h as i64 {
                    continue;
                }
                let yy = yy as usize;
                let (v, l) = (self.plane(yy, c, 4), self.plane(yy, c, 3));
                for dx in -1i64..=1 {
                    let kw = K[(dx + 1) as usize] * K[(dy + 1) as usize];
                    let x0 = (-dx).max(0) as usize;
                    let x1 = (w as i64 - dx.max(0)).max(x0 as i64) as usize;
                    let q0 = (x0 as i64 + dx) as usize;
                    let n = x1 - x0;
                    let (kc, kq, vq) = (&kc[x0..x1], &key[yy * w + q0..yy * w + q0 + n], &v[q0..q0 + n]);
                    let (sm, wt) = (&mut sum[x0..x1], &mut weight[x0..x1]);
                    let centre = dx == 0 && dy == 0;
                    for j in 0..n {
                        let kwj = if centre || kc[j] == kq[j] { kw } else { 0.0 };
                        sm[j] = kwj.mul_add(vq[j], sm[j]);
                        wt[j] += kwj;
                    }
                    if blur {
                        let (lq, ls) = (&l[q0..q0 + n], &mut lum[x0..x1]);
                        for j in 0..n {
                            ls[j] += if centre || kc[j] == kq[j] { kw * lq[j] } else { 0.0 };
                        }
                    }
                }
            }
            let sigma_l = self.strengths[c].0;
            for ((o, s), wt) in out[c * w..(c + 1) * w].iter_mut().zip(sum.iter()).zip(weight.iter()) {
                // NOISELESS where the variance is 0.
                *o = LOG2_E / (sigma_l * (s / wt).max(0.0).sqrt() + 1e-10);
            }
            if blur {
                for ((o, l), wt) in
                    out[(self.k + c) * w..(self.k + c + 1) * w].iter_mut().zip(lum.iter()).zip(weight.iter())
                {
                    *o = l / wt;
                }
            }
        }
    }

    /// Whether layer `c`'s colour stop gives the centre its luminance blurred over 3x3 (among
    /// same-object neighbours, as the variance) rather than its own: in the first pass, for a
    /// half whose taps' luminance is the other half's ([`FilterInput::stops_from`]). Against
    /// the other half's taps, a centre's own noise would set which taps pass, so a bright
    /// centre would keep more of itself than a dark one.
    #[inline(always)]
    fn blurs_centre(&self, c: usize) -> bool {
        self.pass == 0 && self.stops_from[c] != c
    }

    /// Output row `y` (all layers, all planes) from the current buffer.
    #[inline(always)]
    fn row(&self, y: usize, out: &mut [f32], s: &mut Scratch) {
        let (w, k, step) = (self.w, self.k, self.step);
        let kernel = self.a.kernel();
        let r = kernel.len() / 2;
        let h0 = kernel[r] * kernel[r];
        let g = self.guides;
        let sigma_n = self.a.sigma_n * LOG2_E;
        let linear = self.a.fits_plane(self.pass);
        // Only the sums of the layers this pass filters are read: theirs are zeroed.
        if linear && s.moments.len() < k * MOMENTS * w {
            s.moments.resize(k * MOMENTS * w, 0.0);
        }
        for c in (0..k).filter(|&c| self.pass < self.strengths[c].1) {
            s.acc[c * PLANES * w..(c + 1) * PLANES * w].fill(0.0);
            if linear {
                s.moments[c * MOMENTS * w..(c + 1) * MOMENTS * w].fill(0.0);
            }
        }
        // Each layer's runs of pixels that have noise to remove; elsewhere, and in a layer past
        // its passes, nothing changes.
        for c in 0..k {
            if self.pass >= self.strengths[c].1 {
                s.spans[c].clear();
            } else {
                active_spans(&s.stops[c * w..(c + 1) * w], &mut s.spans[c]);
            }
        }
        let hull = (
            s.spans[..k].iter().filter_map(|v| v.first()).map(|r| r.0).min().unwrap_or(0),
            s.spans[..k].iter().filter_map(|v| v.last()).map(|r| r.1).max().unwrap_or(0),
        );
        if hull.0 >= hull.1 {
            s.spans.iter_mut().for_each(Vec::clear);
        }
        for (dyi, &ky) in kernel.iter().enumerate() {
            let dy = dyi as i64 - r as i64;
            let yy = y as i64 + dy * step as i64;
            if yy < 0 || yy >= self.h as i64 || hull.0 >= hull.1 {
                continue;
            }
            let yy = yy as usize;
            for (dxi, &kx) in kernel.iter().enumerate() {
                let dx = dxi as i64 - r as i64;
                if dx == 0 && dy == 0 {
                    continue;
                }
                let off = dx * step as i64;
                // Centres x0..x1 have their tap inside the row (and some noise to remove).
                let x0 = ((-off).max(0) as usize).max(hull.0);
                let x1 = ((w as i64 - off.max(0)).max(0) as usize).min(hull.1);
                if x0 >= x1 {
                    continue;
                }
                let inv_dist = 1.0 / (step as f32 * ((dx * dx + dy * dy) as f32).sqrt());
                let hk = kx * ky;
                // The guides of centres a..b and of their taps.
                let guides = |a: usize, b: usize| {
                    let (pc, pq) = (y * w + a, (yy * w + a) as i64 + off);
                    let (pq, n) = (pq as usize, b - a);
                    (
                        [&g.key[pc..pc + n], &g.key[pq..pq + n]],
                        [&g.nx[pc..pc + n], &g.ny[pc..pc + n], &g.nz[pc..pc + n]],
                        [&g.nx[pq..pq + n], &g.ny[pq..pq + n], &g.nz[pq..pq + n]],
                        [&g.z[pc..pc + n], &g.z[pq..pq + n], &g.inv_dz[pc..pc + n]],
                    )
                };
                if k > 1 || linear {
                    // The geometric weight and exponent, shared by every layer.
                    geometry(
                        hk,
                        sigma_n,
                        inv_dist,
                        guides(x0, x1),
                        &mut s.geo[..x1 - x0],
                        &mut s.exponent[..x1 - x0],
                    );
                }
                for c in 0..k {
                    let base = c * w;
                    let (ar, rest) = s.acc[c * PLANES * w..(c + 1) * PLANES * w].split_at_mut(w);
                    let (ag, rest) = rest.split_at_mut(w);
                    let (ab, rest) = rest.split_at_mut(w);
                    let (av, aw) = rest.split_at_mut(w);
                    for &(a, b) in &s.spans[c] {
                        let (a, b) = (a.max(x0), b.min(x1));
                        if a >= b {
                            continue;
                        }
                        let q = (a as i64 + off) as usize;
                        let centre = |p: usize| &self.plane(y, c, p)[a..b];
                        let tap = |p: usize| &self.plane(yy, c, p)[q..q + b - a];
                        let isg = &s.stops[base + a..base + b];
                        let sums =
                            [&mut ar[a..b], &mut ag[a..b], &mut ab[a..b], &mut av[a..b], &mut aw[a..b]];
                        // The taps' luminance for the colour stop: [`FilterInput::stops_from`].
                        let from = self.stops_from[c];
                        let lc = if self.blurs_centre(c) {
                            &s.stops[base + k * w + a..base + k * w + b]
                        } else {
                            centre(3)
                        };
                        let centres = [centre(0), centre(1), centre(2), lc];
                        let taps = [tap(0), tap(1), tap(2), &self.plane(yy, from, 3)[q..q + b - a], tap(4)];
                        if linear {
                            let (ga, gb) = (a - x0, b - x0);
                            let m = &mut s.moments[c * MOMENTS * w..(c + 1) * MOMENTS * w];
                            let moments: [&mut [f32]; MOMENTS] = split_planes(m, w, a, b);
                            accumulate_linear(
                                (&s.geo[ga..gb], &s.exponent[ga..gb], isg),
                                (dx as f32, dy as f32),
                                centres,
                                taps,
                                sums,
                                moments,
                                &mut s.weights[ga..gb],
                            );
                        } else if k == 1 {
                            // One layer: the geometry in the same loop, never stored.
                            accumulate_one((hk, sigma_n, inv_dist), guides(a, b), isg, centres, taps, sums);
                        } else {
                            let (ga, gb) = (a - x0, b - x0);
                            accumulate((&s.geo[ga..gb], &s.exponent[ga..gb], isg), centres, taps, sums);
                        }
                    }
                }
            }
        }
        // The weighted means, as changes to the centre; a layer past its passes is not written
        // (its last pass's buffer holds it: [`filter_with`]).
        for c in 0..k {
            if self.pass >= self.strengths[c].1 {
                continue;
            }
            let (ar, rest) = s.acc[c * PLANES * w..(c + 1) * PLANES * w].split_at(w);
            let (ag, rest) = rest.split_at(w);
            let (ab, rest) = rest.split_at(w);
            let (av, aw) = rest.split_at(w);
            let (dr, rest) = out[c * PLANES * w..(c + 1) * PLANES * w].split_at_mut(w);
            let (dg, rest) = rest.split_at_mut(w);
            let (db, rest) = rest.split_at_mut(w);
            let (dl, dv) = rest.split_at_mut(w);
            let (r0, g0, b0, v0) =
                (self.plane(y, c, 0), self.plane(y, c, 1), self.plane(y, c, 2), self.plane(y, c, 4));
            if linear {
                let m = &s.moments[c * MOMENTS * w..(c + 1) * MOMENTS * w];
                finish_row_linear(h0, [r0, g0, b0, v0], [ar, ag, ab, av, aw], m, [dr, dg, db, dl, dv]);
            } else {
                finish_row(h0, [r0, g0, b0, v0], [ar, ag, ab, av, aw], [dr, dg, db, dl, dv]);
            }
        }
    }
}

/// One tap's geometric weight (kernel weight, 0 across objects) and exponent (normal and depth
/// stops) for a run of centres, from the centres' and the taps' guides: a flat loop over
/// equal-length slices, which the compiler vectorises.
#[inline(always)]
fn geometry(hk: f32, sigma_n: f32, inv_dist: f32, guides: TapGuides, geo: &mut [f32], e: &mut [f32]) {
    let ([kc, kq], [nxc, nyc, nzc], [nxq, nyq, nzq], [zc, zq, idz]) = guides;
    let n = geo.len();
    let (kc, kq, nxc, nyc, nzc) = (&kc[..n], &kq[..n], &nxc[..n], &nyc[..n], &nzc[..n]);
    let (nxq, nyq, nzq, zc, zq, idz, e) =
        (&nxq[..n], &nyq[..n], &nzq[..n], &zc[..n], &zq[..n], &idz[..n], &mut e[..n]);
    for j in 0..n {
        geo[j] = if kc[j] == kq[j] { hk } else { 0.0 };
        let dot = nzc[j].mul_add(nzq[j], nyc[j].mul_add(nyq[j], nxc[j] * nxq[j]));
        e[j] = sigma_n.mul_add(1.0 - dot, (zc[j] - zq[j]).abs() * idz[j] * inv_dist);
    }
}

/// The guides of a run of centres and of their taps: object keys (centre, tap), the centres'
/// normals, the taps' normals, and depths (centre, tap) with the centres' inverse gradients.
type TapGuides<'a> = ([&'a [f32]; 2], [&'a [f32]; 3], [&'a [f32]; 3], [&'a [f32]; 3]);

/// [`geometry`] and [`accumulate`] in one loop, for a single layer.
#[inline(always)]
fn accumulate_one(
    (hk, sigma_n, inv_dist): (f32, f32, f32),
    guides: TapGuides,
    isg: &[f32],
    [rc, gc, bc, lc]: [&[f32]; 4],
    [rq, gq, bq, lq, vq]: [&[f32]; 5],
    [ar, ag, ab, av, aw]: [&mut [f32]; 5],
) {
    let ([kc, kq], [nxc, nyc, nzc], [nxq, nyq, nzq], [zc, zq, idz]) = guides;
    let n = isg.len();
    let (kc, kq, nxc, nyc, nzc) = (&kc[..n], &kq[..n], &nxc[..n], &nyc[..n], &nzc[..n]);
    let (nxq, nyq, nzq, zc, zq, idz) = (&nxq[..n], &nyq[..n], &nzq[..n], &zc[..n], &zq[..n], &idz[..n]);
    let (rc, gc, bc, lc) = (&rc[..n], &gc[..n], &bc[..n], &lc[..n]);
    let (rq, gq, bq, lq, vq) = (&rq[..n], &gq[..n], &bq[..n], &lq[..n], &vq[..n]);
    let (ar, ag, ab, av, aw) = (&mut ar[..n], &mut ag[..n], &mut ab[..n], &mut av[..n], &mut aw[..n]);
    for j in 0..n {
        let geo = if kc[j] == kq[j] { hk } else { 0.0 };
        let dot = nzc[j].mul_add(nzq[j], nyc[j].mul_add(nyq[j], nxc[j] * nxq[j]));
        let e = sigma_n.mul_add(1.0 - dot, (zc[j] - zq[j]).abs() * idz[j] * inv_dist);
        let k = tap_weight(geo, e, (lc[j], lq[j]), isg[j]);
        ar[j] = k.mul_add(rq[j] - rc[j], ar[j]);
        ag[j] = k.mul_add(gq[j] - gc[j], ag[j]);
        ab[j] = k.mul_add(bq[j] - bc[j], ab[j]);
        av[j] = (k * k).mul_add(vq[j], av[j]);
        aw[j] += k;
    }
}

/// One tap of one layer for a run of centres: the weight `k = geo 2^-(e + |Δl| inv_sigma)`,
/// added to the sums of weighted differences (r, g, b), of squared weights times the tap's
/// variance, and of weights.
#[inline(always)]
fn accumulate(
    (geo, e, isg): (&[f32], &[f32], &[f32]),
    [rc, gc, bc, lc]: [&[f32]; 4],
    [rq, gq, bq, lq, vq]: [&[f32]; 5],
    [ar, ag, ab, av, aw]: [&mut [f32]; 5],
) {
    let n = geo.len();
    let (e, isg, rc, gc, bc, lc) = (&e[..n], &isg[..n], &rc[..n], &gc[..n], &bc[..n], &lc[..n]);
    let (rq, gq, bq, lq, vq) = (&rq[..n], &gq[..n], &bq[..n], &lq[..n], &vq[..n]);
    let (ar, ag, ab, av, aw) = (&mut ar[..n], &mut ag[..n], &mut ab[..n], &mut av[..n], &mut aw[..n]);
    for j in 0..n {
        let k = tap_weight(geo[j], e[j], (lc[j], lq[j]), isg[j]);
        ar[j] = k.mul_add(rq[j] - rc[j], ar[j]);
        ag[j] = k.mul_add(gq[j] - gc[j], ag[j]);
        ab[j] = k.mul_add(bq[j] - bc[j], ab[j]);
        av[j] = (k * k).mul_add(vq[j], av[j]);
        aw[j] += k;
    }
}

/// Columns `a..b` of each of the `N` planes of width `w` in `m`.
#[inline(always)]
fn split_planes<const N: usize>(m: &mut [f32], w: usize, a: usize, b: usize) -> [&mut [f32]; N] {
    let mut rest = m;
    std::array::from_fn(|_| {
        let (plane, tail) = std::mem::take(&mut rest).split_at_mut(w);
        rest = tail;
        &mut plane[a..b]
    })
}

/// [`accumulate`] for a pass that fits a plane: also the weights' moments and the weighted
/// differences' first moments over the tap's offset `(dx, dy)` in kernel steps ([`MOMENTS`]),
/// only those the offset makes nonzero, with `weights` as scratch. In loops of a few arrays
/// each: one loop over all the sums was not vectorised.
#[inline(always)]
fn accumulate_linear(
    (geo, e, isg): (&[f32], &[f32], &[f32]),
    (dx, dy): (f32, f32),
    centres: [&[f32]; 4],
    taps: [&[f32]; 5],
    sums: [&mut [f32]; 5],
    [sx, sy, sxx, sxy, syy, rx, gx, bx, ry, gy, by]: [&mut [f32]; MOMENTS],
    weights: &mut [f32],
) {
    let n = geo.len();
    tap_weights((geo, e, isg), centres[3], taps[3], &mut weights[..n]);
    let k = &weights[..n];
    let [rc, gc, bc, _] = centres;
    let [rq, gq, bq, _, vq] = taps;
    let [ar, ag, ab, av, aw] = sums;
    {
        let (vq, av, aw) = (&vq[..n], &mut av[..n], &mut aw[..n]);
        for j in 0..n {
            av[j] = (k[j] * k[j]).mul_add(vq[j], av[j]);
            aw[j] += k[j];
        }
    }
    if dx != 0.0 {
        weight_moments(k, dx, [sx, sxx]);
    }
    if dy != 0.0 {
        weight_moments(k, dy, [sy, syy]);
    }
    // The weighted differences and their first moments, channel by channel, each difference
    // read once for every sum it adds to.
    for (c, q, sums) in [(rc, rq, [ar, rx, ry]), (gc, gq, [ag, gx, gy]), (bc, bq, [ab, bx, by])] {
        match (dx != 0.0, dy != 0.0) {
            (true, true) => differences::<true, true>(k, (dx, dy), c, q, sums),
            (true, false) => differences::<true, false>(k, (dx, dy), c, q, sums),
            (false, true) => differences::<false, true>(k, (dx, dy), c, q, sums),
            (false, false) => differences::<false, false>(k, (dx, dy), c, q, sums),
        }
    }
    if dx != 0.0 && dy != 0.0 {
        let (sxy, d) = (&mut sxy[..n], dx * dy);
        for j in 0..n {
            sxy[j] = k[j].mul_add(d, sxy[j]);
        }
    }
}

/// One axis of [`accumulate_linear`]'s weight moments, for a tap `d` kernel steps along it:
/// `Σk d`, `Σk d²`. A function, not a closure: a closure was left outlined, in the portable
/// build.
#[inline(always)]
fn weight_moments(k: &[f32], d: f32, [s, ss]: [&mut [f32]; 2]) {
    let n = k.len();
    let (s, ss, dd) = (&mut s[..n], &mut ss[..n], d * d);
    for j in 0..n {
        s[j] = k[j].mul_add(d, s[j]);
        ss[j] = k[j].mul_add(dd, ss[j]);
    }
}

/// One channel's weighted differences `Σk Δ` and, along each axis the tap is off the centre
/// (`X`, `Y`), their first moments `Σk d Δ`, from one read of the centres `c` and the tap `q`:
/// each sum is `(k d) Δ`, as when the three were summed in loops of their own (the same bits).
#[inline(always)]
fn differences<const X: bool, const Y: bool>(
    k: &[f32],
    (dx, dy): (f32, f32),
    c: &[f32],
    q: &[f32],
    [sum, along_x, along_y]: [&mut [f32]; 3],
) {
    let n = k.len();
    let (c, q, sum, along_x, along_y) =
        (&c[..n], &q[..n], &mut sum[..n], &mut along_x[..n], &mut along_y[..n]);
    for j in 0..n {
        let d = q[j] - c[j];
        sum[j] = k[j].mul_add(d, sum[j]);
        if X {
            along_x[j] = (k[j] * dx).mul_add(d, along_x[j]);
        }
        if Y {
            along_y[j] = (k[j] * dy).mul_add(d, along_y[j]);
        }
    }
}

/// A tap's weights `k = geo 2^-(e + |Δl| inv_sigma)` for a run of centres, from the centres'
/// and the tap's luminance.
#[inline(always)]
fn tap_weights((geo, e, isg): (&[f32], &[f32], &[f32]), lc: &[f32], lq: &[f32], k: &mut [f32]) {
    let n = k.len();
    let (geo, e, isg, lc, lq) = (&geo[..n], &e[..n], &isg[..n], &lc[..n], &lq[..n]);
    for j in 0..n {
        k[j] = tap_weight(geo[j], e[j], (lc[j], lq[j]), isg[j]);
    }
}

/// A tap's weight from its geometric weight `geo` and exponent `e` (normal and depth stops),
/// the centre's and the tap's luminance and the centre's colour stop `isg`:
/// `geo 2^-(e + |Δl| isg)`.
#[inline(always)]
fn tap_weight(geo: f32, e: f32, (lc, lq): (f32, f32), isg: f32) -> f32 {
    geo * exp2_neg((lc - lq).abs().mul_add(isg, e))
}

/// `2^-t` for `t >= 0` (NaN and anything above 125 give about 2^-125), to a relative error
/// below 2e-4: the nearest integer through the exponent bits, the rest by a cubic. Plain
/// float and integer arithmetic, so a row loop of it vectorises.
#[inline(always)]
fn exp2_neg(t: f32) -> f32 {
    // In this order a NaN becomes 125 (`clamp` would keep it).
    #[allow(clippy::manual_clamp)]
    let t = t.min(125.0).max(0.0);
    // Rounded to the nearest integer by adding 1.5 2^23: its low mantissa bits are then `i`.
    const MAGIC: f32 = 12_582_912.0;
    let m = t + MAGIC;
    let i = m.to_bits().wrapping_sub(MAGIC.to_bits());
    let f = t - (m - MAGIC);
    // 2^-f for f in [-1/2, 1/2].
    let p = f.mul_add(f.mul_add(f.mul_add(-0.054_602_28, 0.241_924_8), -0.693_316_6), 1.0);
    p * f32::from_bits((127 - i) << 23)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`super::filter`]'s layers as images of the film's size.
    fn filter(layers: &[FilterInput], film: &Film, a: &Atrous, pure: bool) -> Vec<Image> {
        super::filter(layers, film, a, pure).iter().map(|p| p.to_image(film.width, film.height)).collect()
    }

    /// A xorshift stream in [0, 1).
    fn stream(seed: u32) -> impl FnMut() -> f32 {
        let mut state = seed.max(1);
        move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state >> 8) as f32 / 16_777_216.0
        }
    }

    /// One pass by the definition, pixel by pixel, as the module comment states it.
    fn pass_by_definition(
        a: &Atrous,
        g: &Guides,
        (w, h, k): (usize, usize, usize),
        pass: u32,
        cur: &[f32],
        stops_from: &[usize],
    ) -> Vec<f32> {
        let at = |y: usize, c: usize, p: usize, x: usize| cur[((y * k + c) * PLANES + p) * w + x];
        let kernel = a.kernel();
        let r = kernel.len() as i64 / 2;
        let step = 1i64 << pass;
        let h0 = kernel[r as usize] * kernel[r as usize];
        let mut next = vec![0.0; cur.len()];
        for y in 0..h {
            for x in 0..w {
                let p = y * w + x;
                for (c, &from) in stops_from.iter().enumerate().take(k) {
                    // The colour stop: the variance blurred among same-object neighbours. The
                    // taps' luminance is that of the layer `from` (`stops_from`); against
                    // another layer's, the first pass gives the centre its luminance blurred
                    // the same way.
                    let (mut sum, mut weight, mut lum) = (0.0f32, 0.0f32, 0.0f32);
                    for dy in -1i64..=1 {
                        for dx in -1i64..=1 {
                            let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                            if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                                continue;
                            }
                            let q = yy as usize * w + xx as usize;
                            if q == p || g.key[q] == g.key[p] {
                                let kw = [0.25f32, 0.5, 0.25][(dx + 1) as usize]
                                    * [0.25f32, 0.5, 0.25][(dy + 1) as usize];
                                sum += kw * at(yy as usize, c, 4, xx as usize);
                                lum += kw * at(yy as usize, c, 3, xx as usize);
                                weight += kw;
                            }
                        }
                    }
                    let isg = LOG2_E / (a.sigma_l * (sum / weight).max(0.0).sqrt() + 1e-10);
                    let centre_l = if pass == 0 && from != c { lum / weight } else { at(y, c, 3, x) };
                    let mut acc = [0.0f32; 5];
                    // With `linear`, the plane fitted by weighted least squares: the normal
                    // equations over the centre (offset 0, weight h0) and the taps, in f64, raw
                    // values rather than differences, solved by Cramer's rule.
                    let linear = a.fits_plane(pass);
                    let mut normal = [[0.0f64; 3]; 3];
                    let mut rhs = [[0.0f64; 3]; 3];
                    let mut add = |wt: f32, d: [f64; 3], value: [f32; 3]| {
                        for i in 0..3 {
                            for j in 0..3 {
                                normal[i][j] += wt as f64 * d[i] * d[j];
                            }
                            for (ch, v) in value.iter().enumerate() {
                                rhs[ch][i] += wt as f64 * *v as f64 * d[i];
                            }
                        }
                    };
                    add(h0, [1.0, 0.0, 0.0], std::array::from_fn(|ch| at(y, c, ch, x)));
                    // A pixel without noise keeps its value.
                    let reach = if isg >= NOISELESS { 0 } else { r };
                    for dy in -reach..=reach {
                        for dx in -reach..=reach {
                            let (xx, yy) = (x as i64 + dx * step, y as i64 + dy * step);
                            if (dx, dy) == (0, 0) || xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                                continue;
                            }
                            let (xx, yy) = (xx as usize, yy as usize);
                            let q = yy * w + xx;
                            let hk = kernel[(dx + r) as usize] * kernel[(dy + r) as usize];
                            let geo = if g.key[p] == g.key[q] { hk } else { 0.0 };
                            let dot = g.nx[p] * g.nx[q] + g.ny[p] * g.ny[q] + g.nz[p] * g.nz[q];
                            let inv_dist = 1.0 / (step as f32 * ((dx * dx + dy * dy) as f32).sqrt());
                            let e = a.sigma_n * LOG2_E * (1.0 - dot)
                                + (g.z[p] - g.z[q]).abs() * g.inv_dz[p] * inv_dist;
                            let t = e + (centre_l - at(yy, from, 3, xx)).abs() * isg;
                            let kq = geo * exp2_neg(t);
                            for (ch, a) in acc.iter_mut().take(3).enumerate() {
                                *a += kq * (at(yy, c, ch, xx) - at(y, c, ch, x));
                            }
                            acc[3] += kq * kq * at(yy, c, 4, xx);
                            acc[4] += kq;
                            add(kq, [1.0, dx as f64, dy as f64], std::array::from_fn(|ch| at(yy, c, ch, xx)));
                        }
                    }
                    let sum_w = h0 + acc[4];
                    let mut rgb: [f32; 3] = std::array::from_fn(|ch| at(y, c, ch, x) + acc[ch] / sum_w);
                    if linear && isg < NOISELESS {
                        let (l0, v0) = (
                            luminance(Vec3::from_array(std::array::from_fn(|ch| at(y, c, ch, x)))),
                            at(y, c, 4, x),
                        );
                        let relative = RIDGE_NOISE as f64 * v0 as f64 / (l0 as f64 * l0 as f64 + 1e-12);
                        let ridge = RIDGE as f64 * sum_w as f64 * (1.0 + relative);
                        normal[1][1] += ridge;
                        normal[2][2] += ridge;
                        let det3 = |m: [[f64; 3]; 3]| {
                            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
                        };
                        for (ch, v) in rgb.iter_mut().enumerate() {
                            // The constant term: the normal matrix with its first column
                            // replaced by the right-hand side.
                            let mut m = normal;
                            for i in 0..3 {
                                m[i][0] = rhs[ch][i];
                            }
                            *v = (det3(m) / det3(normal)) as f32;
                        }
                    }
                    let base = (y * k + c) * PLANES * w + x;
                    for (ch, v) in rgb.iter().enumerate() {
                        next[base + ch * w] = *v;
                    }
                    next[base + 3 * w] = luminance(Vec3::from(rgb));
                    next[base + 4 * w] = (h0 * h0 * at(y, c, 4, x) + acc[3]) / (sum_w * sum_w);
                }
            }
        }
        next
    }

    /// A film of random guides: a few objects, tilted normals, depths, some mixed pixels.
    fn random_film(w: u32, h: u32, seed: u32) -> Film {
        let mut next = stream(seed);
        let mut film = Film::new(w, h);
        for i in 0..(w * h) as usize {
            film.object[i] = (next() * 3.0).floor() - if next() < 0.05 { 5.0 } else { 0.0 };
            film.normal.pixels[i] = Vec3::new(next() - 0.5, next() - 0.5, 2.0).normalize();
            film.depth[i] = 1.0 + next();
            film.coverage[i] = if next() < 0.8 { 1.0 } else { 0.5 };
            film.albedo.pixels[i] = Vec3::new(next(), next(), next());
        }
        film
    }

    /// The working buffer of `k` random layers.
    fn random_planes(w: usize, h: usize, k: usize, seed: u32) -> Vec<f32> {
        let mut next = stream(seed);
        let mut cur = vec![0.0; h * k * PLANES * w];
        for (i, v) in cur.iter_mut().enumerate() {
            let (x, plane, c, y) = (i % w, (i / w) % PLANES, (i / w / PLANES) % k, i / w / PLANES / k);
            // Noiseless regions, which keep their values: a band of columns in even layers, the
            // top rows in odd ones.
            let noiseless = if c % 2 == 0 { 3 * x < w } else { 2 * y < h };
            *v = match plane {
                4 if noiseless => 0.0,
                4 => 0.01 * next(),
                _ => next() * 2.0,
            };
        }
        cur
    }

    #[test]
    fn the_row_kernels_equal_the_definition() {
        for (w, h) in [(1usize, 1usize), (2, 5), (37, 11), (130, 9)] {
            for k in 1..=3 {
                for (taps, pure, linear) in
                    [(5, false, 0), (3, false, 0), (5, true, 0), (3, true, 0), (3, true, 1), (5, false, 2)]
                {
                    let a = Atrous { taps, sigma_l: 2.0, sigma_n: 16.0, linear, ..Atrous::default() };
                    let film = random_film(w as u32, h as u32, (w * 31 + h * 7 + k) as u32);
                    let g = Guides::new(&film, &a, pure);
                    let cur = random_planes(w, h, k, (w + h + k) as u32);
                    // Each layer its own colour stop, then the first two each other's (the
                    // halves of a layer).
                    let own: Vec<usize> = (0..k).collect();
                    let swapped: Vec<usize> =
                        (0..k).map(|c| if c < 2 && k >= 2 { 1 - c } else { c }).collect();
                    let runs = (0..3).flat_map(|p| Isa::all().into_iter().map(move |b| (p, b)));
                    for ((pass, isa), stops_from) in runs.flat_map(|r| [(r, &own), (r, &swapped)]) {
                        let want = pass_by_definition(&a, &g, (w, h, k), pass, &cur, stops_from);
                        let mut got = vec![0.0; cur.len()];
                        let strengths = vec![(a.sigma_l, a.passes); k];
                        run_pass(
                            isa,
                            (&a, &strengths, stops_from),
                            &g,
                            (w, h, k),
                            pass,
                            (0..h, 0),
                            (&cur, &mut got),
                        );
                        for (i, (x, y)) in got.iter().zip(&want).enumerate() {
                            assert!(
                                (x - y).abs() <= if linear > 0 { 1e-4 } else { 1e-5 } * y.abs().max(1e-3),
                                "{w}x{h} k={k} taps={taps} pure={pure} linear={linear} pass {pass} stops from {stops_from:?} at {i}: {x} vs {y}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// One object with flat guides and constant albedo: the film, and its image.
    fn flat(w: u32, h: u32, mut value: impl FnMut(u32, u32) -> Vec3) -> (Film, Image) {
        let mut film = Film::new(w, h);
        let mut image = Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                film.object[i] = 0.0;
                film.normal.pixels[i] = Vec3::Z;
                film.depth[i] = 2.0;
                film.albedo.pixels[i] = Vec3::new(0.8, 0.5, 0.3);
                image.pixels[i] = value(x, y);
            }
        }
        (film, image)
    }

    #[test]
    fn a_constant_image_is_exact() {
        let (film, image) = flat(40, 23, |_, _| Vec3::new(0.3, 1.5, 7.0));
        let variance = vec![0.5; 40 * 23];
        for a in [Atrous::default(), Atrous { taps: 3, passes: 6, sigma_l: 0.5, ..Atrous::default() }] {
            for pure in [false, true] {
                let out = filter(&[FilterInput::new(&image, Some(&variance))], &film, &a, pure);
                assert_eq!(out[0], image, "{a:?}");
            }
        }
    }

    #[test]
    fn a_texture_under_constant_light_stays_sharp() {
        // A checkerboard albedo (with a black channel) times constant light.
        let (mut film, _) = flat(32, 32, |_, _| Vec3::ZERO);
        let mut image = Image::new(32, 32);
        for (i, px) in image.pixels.iter_mut().enumerate() {
            let albedo =
                if (i % 32 / 4 + i / 32 / 4) % 2 == 0 { Vec3::new(0.9, 0.0, 0.2) } else { Vec3::splat(0.05) };
            film.albedo.pixels[i] = albedo;
            *px = albedo * 3.0;
        }
        let variance = vec![1.0; 32 * 32];
        let out = filter(&[FilterInput::new(&image, Some(&variance))], &film, &Atrous::default(), false);
        for (a, b) in out[0].pixels.iter().zip(&image.pixels) {
            assert!(a.is_finite() && (*a - *b).abs().max_element() <= 1e-5 * b.max_element(), "{a} vs {b}");
        }
    }

    /// Beside an object's border the window is one-sided, and a mean pulls a gradient toward
    /// the window's centroid; the plane fit ([`Atrous::linear`]) keeps it.
    #[test]
    fn a_plane_fit_keeps_a_ramp_up_to_a_border() {
        let (w, h) = (48u32, 16u32);
        let ramp = |x: u32| 0.2 + 0.03 * x as f32;
        let (mut film, image) =
            flat(w, h, |x, _| if x < 32 { Vec3::splat(ramp(x)) } else { Vec3::splat(4.0) });
        for (i, o) in film.object.iter_mut().enumerate() {
            *o = if i as u32 % w < 32 { 0.0 } else { 1.0 };
        }
        let variance = vec![0.01; (w * h) as usize];
        // The mean error over the 8 columns before the border, against the ramp.
        let error = |linear: u32| {
            let a = Atrous { taps: 3, passes: 4, linear, ..Atrous::default() };
            let out = filter(&[FilterInput::new(&image, Some(&variance))], &film, &a, false);
            let (mut sum, mut n) = (0.0, 0);
            for y in 0..h {
                for x in 24..32 {
                    sum += (out[0].get(x, y).x - ramp(x)).abs();
                    n += 1;
                }
            }
            sum / n as f32
        };
        // The ridge on the slopes leaves some of the pull (a window of one side's taps has
        // few to fit a slope to), the unfitted passes some more.
        let (mean, from_second, all) = (error(0), error(2), error(1));
        assert!(mean > 0.005, "the mean's pull at the border: {mean}");
        assert!(
            all < from_second && from_second < 0.6 * mean,
            "the plane fit's error from the first pass {all}, from the second {from_second}, against the mean's {mean}"
        );
    }

    #[test]
    fn a_ramp_keeps_its_slope() {
        let (w, h) = (160u32, 9u32);
        let (film, image) = flat(w, h, |x, _| Vec3::splat(1.0 + 0.01 * x as f32));
        let variance = vec![1e-4; (w * h) as usize];
        for a in [Atrous::default(), Atrous { taps: 3, passes: 6, ..Atrous::default() }] {
            let out = filter(&[FilterInput::new(&image, Some(&variance))], &film, &a, false);
            // Away from the left and right borders, farther than the filter reaches (62 pixels
            // for five 5x5 passes, 63 for six 3x3), the symmetric taps cancel.
            for y in 0..h {
                for x in 64..w - 64 {
                    let (got, want) = (out[0].get(x, y), image.get(x, y));
                    assert!((got - want).abs().max_element() < 1e-5, "{a:?} ({x}, {y}): {got} vs {want}");
                }
            }
            let slope = (out[0].get(w - 65, 4).x - out[0].get(64, 4).x) / (w - 129) as f32;
            assert!((slope - 0.01).abs() < 1e-6, "{slope}");
        }
    }

    #[test]
    fn nothing_mixes_across_an_object_border() {
        for seed in 1..20 {
            let mut next = stream(seed);
            let (w, h) = (24u32, 16u32);
            let border = 4 + (next() * 16.0) as u32;
            let (mut film, mut image) = flat(w, h, |_, _| Vec3::ZERO);
            for y in 0..h {
                for x in 0..w {
                    let i = (y * w + x) as usize;
                    let a = x < border;
                    film.object[i] = if a { 0.0 } else { 1.0 };
                    image.pixels[i] = if a { Vec3::splat(0.5 + next()) } else { Vec3::splat(3.0) };
                }
            }
            let variance = vec![0.3; (w * h) as usize];
            let out = filter(&[FilterInput::new(&image, Some(&variance))], &film, &Atrous::default(), false);
            for y in 0..h {
                for x in 0..w {
                    let (got, input) = (out[0].get(x, y), image.get(x, y));
                    if x < border {
                        // A weighted mean of A's own values: inside their range.
                        assert!(got.x >= 0.5 - 1e-5 && got.x <= 1.5 + 1e-5, "seed {seed}: {got}");
                    } else {
                        assert_eq!(got, input, "seed {seed}: B changed at ({x}, {y})");
                    }
                }
            }
        }
    }

    /// With `pure`, mixed pixels (coverage below 1) mix only with each other: a lone one keeps
    /// its value, a column of them is smoothed along itself, and what the pure pixels become
    /// does not depend on the mixed pixels' values.
    #[test]
    fn mixed_pixels_mix_only_among_themselves_when_pure() {
        let mut next = stream(7);
        let (mut film, image) = flat(20, 20, |_, _| Vec3::splat(0.5 + next()));
        film.coverage[210] = 0.5;
        let variance = vec![0.3; 400];
        let layer = [FilterInput::new(&image, Some(&variance))];
        let pure = filter(&layer, &film, &Atrous::default(), true);
        assert_eq!(pure[0].pixels[210], image.pixels[210]);
        let not = filter(&layer, &film, &Atrous::default(), false);
        assert_ne!(not[0].pixels[210], image.pixels[210]);

        film.coverage[210] = 1.0;
        let column: Vec<usize> = (0..20).map(|y| y * 20 + 9).collect();
        column.iter().for_each(|&i| film.coverage[i] = 0.5);
        let pure = filter(&layer, &film, &Atrous::default(), true);
        let mut bright = image.clone();
        column.iter().for_each(|&i| bright.pixels[i] *= 10.0);
        let brighter = filter(&[FilterInput::new(&bright, Some(&variance))], &film, &Atrous::default(), true);
        let spread = |img: &Image| {
            let v: Vec<f32> = column.iter().map(|&i| img.pixels[i].x).collect();
            v.iter().fold(f32::MIN, |a, &b| a.max(b)) - v.iter().fold(f32::MAX, |a, &b| a.min(b))
        };
        assert!(spread(&pure[0]) < 0.8 * spread(&image), "the column was not smoothed along itself");
        for i in (0..400).filter(|i| !column.contains(i)) {
            assert_eq!(pure[0].pixels[i], brighter[0].pixels[i], "pixel {i} took from a mixed pixel");
        }
    }

    #[test]
    fn one_pass_shrinks_a_uniform_variance_by_the_kernel() {
        // No stops: one object, flat guides, equal values; then an interior pixel's variance
        // is that of a weighted mean, (Σ h²)² V with the 1-D B3 weights.
        let (w, h) = (16usize, 16usize);
        let (film, _) = flat(w as u32, h as u32, |_, _| Vec3::ZERO);
        let a = Atrous::default();
        let g = Guides::new(&film, &a, false);
        let mut cur = vec![0.0; h * PLANES * w];
        for y in 0..h {
            for x in 0..w {
                cur[(y * PLANES + 4) * w + x] = 2.0;
            }
        }
        let mut next = vec![0.0; cur.len()];
        run_pass(
            Isa::Portable,
            (&a, &[(a.sigma_l, a.passes)], &[0]),
            &g,
            (w, h, 1),
            0,
            (0..h, 0),
            (&cur, &mut next),
        );
        let sum_h2: f32 = a.kernel().iter().map(|k| k * k).sum();
        assert_eq!(sum_h2, 0.2734375);
        let want = sum_h2 * sum_h2 * 2.0;
        for y in 2..h - 2 {
            for x in 2..w - 2 {
                let v = next[(y * PLANES + 4) * w + x];
                assert!((v - want).abs() < 1e-6, "({x}, {y}): {v} vs {want}");
            }
        }
        // Nowhere does the variance grow.
        assert!((0..h * w).all(|i| next[(i / w * PLANES + 4) * w + i % w] <= 2.0));
    }

    #[test]
    fn the_mean_is_kept_within_the_noise() {
        // Light c with Gaussian-like noise (sum of four uniforms) on one object: the filtered
        // image's mean stays within 4 standard errors of c, the error from the noise itself.
        let (w, h) = (64u32, 64u32);
        let mut next = stream(11);
        let sd = 0.2f32;
        let (film, image) = flat(w, h, |_, _| {
            let g = (next() + next() + next() + next() - 2.0) * (3.0f32).sqrt(); // unit variance
            Vec3::splat(1.0 + sd * g)
        });
        let n = (w * h) as f32;
        let variance = vec![sd * sd; n as usize];
        let out = filter(&[FilterInput::new(&image, Some(&variance))], &film, &Atrous::default(), false);
        let mean = |img: &Image| img.pixels.iter().map(|p| p.x as f64).sum::<f64>() / n as f64;
        let (m_in, m_out) = (mean(&image), mean(&out[0]));
        let tolerance = 4.0 * sd as f64 / (n as f64).sqrt();
        assert!((m_in - 1.0).abs() < tolerance, "the input: {m_in}");
        assert!((m_out - 1.0).abs() < tolerance, "filtered: {m_out} vs 1 ± {tolerance}");
        // And it did smooth: the spread fell.
        let spread = |img: &Image, m: f64| {
            (img.pixels.iter().map(|p| (p.x as f64 - m).powi(2)).sum::<f64>() / n as f64).sqrt()
        };
        assert!(spread(&out[0], m_out) < 0.5 * spread(&image, m_in));
    }

    #[test]
    fn taps_weighed_by_the_other_half_keep_the_mean_of_skewed_noise() {
        // Light 1 seen through skewed noise: each half of a pixel's samples is the mean of 2
        // exponential samples (variance 1/2, most of them below the mean, a few far above).
        // Weighed by its own luminance, a tap far above the centre counts less than one as far
        // below, so the filtered mean falls, by more than the noise explains (4 standard
        // errors of the halves' mean over the image; measured: -3.0%). Weighed by its
        // luminance in the other half, a tap counts whatever it adds, and the mean keeps
        // within the noise (+0.5%). (With the centre's own luminance unblurred in the first
        // pass, a bright centre kept more of itself than a dark one: +1.9%.)
        let (w, h, m) = (96u32, 96u32, 2);
        let mut next = stream(5);
        let mut half = || (0..m).map(|_| -(1.0 - next()).ln()).sum::<f32>() / m as f32;
        let (film, a) = flat(w, h, |_, _| Vec3::splat(half()));
        let b = Image { pixels: a.pixels.iter().map(|_| Vec3::splat(half())).collect(), ..a.clone() };
        let variance = vec![1.0 / m as f32; (w * h) as usize];
        let n = (w * h) as f64;
        let mean = |img: &Image| img.pixels.iter().map(|p| p.x as f64).sum::<f64>() / n;
        let tolerance = 4.0 * (0.5 / m as f64 / n).sqrt();
        let setting = Atrous { taps: 3, passes: 4, sigma_l: 5.0, ..Atrous::default() };
        let halves_mean = |stops_from: [Option<usize>; 2]| {
            let layers = [
                FilterInput { stops_from: stops_from[0], ..FilterInput::new(&a, Some(&variance)) },
                FilterInput { stops_from: stops_from[1], ..FilterInput::new(&b, Some(&variance)) },
            ];
            let out = filter(&layers, &film, &setting, false);
            (mean(&out[0]) + mean(&out[1])) / 2.0
        };
        let unfiltered = (mean(&a) + mean(&b)) / 2.0;
        let (own, other) = (halves_mean([None, None]), halves_mean([Some(1), Some(0)]));
        assert!((unfiltered - 1.0).abs() < tolerance, "the input: {unfiltered}");
        assert!(own < unfiltered - tolerance, "its own stops: {own} vs {unfiltered} ± {tolerance}");
        assert!(
            (other - unfiltered).abs() < tolerance,
            "the other half's taps: {other} vs {unfiltered} ± {tolerance}"
        );
    }

    /// A `w` by `h` layer of uniform random colours from stream `seed`, and a random variance
    /// of up to `scale` for each pixel.
    fn noisy_layer(w: u32, h: u32, seed: u32, scale: f32) -> (Image, Vec<f32>) {
        let mut next = stream(seed);
        let mut image = Image::new(w, h);
        image.pixels.iter_mut().for_each(|p| *p = Vec3::new(next(), next(), next()));
        let variance = (0..w * h).map(|_| scale * next()).collect();
        (image, variance)
    }

    #[test]
    fn the_result_does_not_depend_on_the_thread_count() {
        let film = random_film(57, 33, 3);
        let (image, variance) = noisy_layer(57, 33, 5, 0.1);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a pool");
            pool.install(|| {
                filter(&[FilterInput::new(&image, Some(&variance))], &film, &Atrous::default(), false)
            })
        };
        let one = run(1);
        assert_ne!(one[0], image);
        assert_eq!(one, run(2));
        assert_eq!(one, run(3));
    }

    /// A random film of `w` x `h` and two noisy layers on it, a bright one and a dim one, from
    /// seeds `seed` to `seed + 2`.
    fn film_and_layers(w: u32, h: u32, seed: u32) -> (Film, [(Image, Vec<f32>); 2]) {
        (random_film(w, h, seed), [noisy_layer(w, h, seed + 1, 1.0), noisy_layer(w, h, seed + 2, 0.01)])
    }

    /// The layers of [`film_and_layers`] as inputs, the dim one as the direct light.
    fn inputs(layers: &[(Image, Vec<f32>); 2]) -> [FilterInput<'_>; 2] {
        let [(bright, bright_var), (dim, dim_var)] = layers;
        [
            FilterInput::new(bright, Some(bright_var)),
            FilterInput { component: Some(Component::Direct), ..FilterInput::new(dim, Some(dim_var)) },
        ]
    }

    /// Five passes of five taps, the direct light's two.
    fn strong() -> Atrous {
        Atrous {
            taps: 5,
            passes: 5,
            direct: Strength { sigma_l: Some(1.5), passes: Some(2) },
            ..Atrous::default()
        }
    }

    #[test]
    fn every_build_gives_the_portable_builds_bits() {
        // Every build this CPU runs (AVX2's and AVX-512's where it has them) against the
        // portable one; each build is checked on the machines that run it.
        let (film, layers) = film_and_layers(67, 41, 11);
        let two = inputs(&layers);
        let strong = strong();
        for (layers, a, pure) in
            [(&two[..], &Atrous::default(), false), (&two[..], &strong, true), (&two[..1], &strong, false)]
        {
            let portable = filter_with(Isa::Portable, layers, &film, a, pure);
            assert_ne!(portable[0], *layers[0].image, "the filter changed the layer");
            for isa in Isa::all() {
                assert_eq!(portable, filter_with(isa, layers, &film, a, pure), "{}", isa.name());
            }
        }
    }

    /// Bands of rows give the image filtered whole, bit for bit: bands of one row to more than
    /// the image, with passes that read past several bands (five passes of five taps reach 62
    /// rows), a layer that stops its passes early, plane fits and the clamp.
    #[test]
    fn bands_give_the_whole_images_bits() {
        let (film, layers) = film_and_layers(37, 45, 21);
        let two = inputs(&layers);
        let strong = Atrous { linear: 2, clamp: Some(2.0), ..strong() };
        let denoise = match crate::filter::Setting::denoise().method {
            Some(crate::filter::Method::Atrous(a)) => a,
            _ => unreachable!("--denoise is à-trous"),
        };
        for (a, pure) in [(&Atrous::default(), false), (&strong, true), (&denoise, true)] {
            let whole = filter_in_bands(Isa::best(), &two, &film, a, pure, Some(film.height as usize));
            assert_ne!(whole[0], layers[0].0, "the filter changed the layer");
            for band in [1, 2, 3, 7, 16, 44, 45, 100] {
                let banded = filter_in_bands(Isa::best(), &two, &film, a, pure, Some(band));
                assert!(banded == whole, "bands of {band} rows differ from the whole image ({})", a.name());
            }
        }
    }

    /// `clamp=K` bounds each channel's change by K deviations of the pixel's mean: 0 changes
    /// nothing, a bound the filter never reaches changes nothing either, and in between no
    /// channel moves further than its bound.
    #[test]
    fn clamp_bounds_the_change_by_the_noise() {
        let film = random_film(37, 23, 7);
        let (image, variance) = noisy_layer(37, 23, 17, 0.01);
        let run = |clamp: Option<f32>| {
            let a = Atrous { clamp, ..Atrous::default() };
            filter(&[FilterInput::new(&image, Some(&variance))], &film, &a, false).remove(0)
        };
        let free = run(None);
        assert_ne!(free, image);
        assert_eq!(run(Some(0.0)), image);
        assert_eq!(run(Some(1e9)), free);
        let k = 1.0;
        let bounded = run(Some(k));
        assert!(bounded != free && bounded != image, "the bound bit nowhere, or everywhere");
        for (i, (b, p)) in bounded.pixels.iter().zip(&image.pixels).enumerate() {
            let lum = luminance(*p);
            let scale = if lum > 0.0 { (*p / lum).max(Vec3::ONE) } else { Vec3::ONE };
            let limit = k * variance[i].sqrt() * scale;
            assert!(
                ((*b - *p).abs() - limit).max_element() <= 1e-6,
                "pixel {i}: {b} from {p}, bound {limit}"
            );
        }
        assert_eq!(Atrous::parse("atrous:clamp=2").map(|a| a.clamp), Ok(Some(2.0)));
        assert_eq!(Atrous::parse("atrous:clamp=2").map(|a| a.name()), Ok("atrous:clamp=2".to_string()));
        assert!(Atrous::parse("atrous:clamp=-1").is_err());
    }

    #[test]
    fn each_component_gets_its_own_strength() {
        let film = random_film(41, 29, 11);
        let mut next = stream(13);
        let mut noisy = || {
            let mut image = Image::new(41, 29);
            image.pixels.iter_mut().for_each(|p| *p = Vec3::new(next(), next(), next()));
            image
        };
        let (direct, caustic, indirect) = (noisy(), noisy(), noisy());
        let variance: Vec<f32> = (0..41 * 29).map(|i| 0.02 + 0.001 * (i % 7) as f32).collect();
        // The direct layer ends its passes an even (1 of 5) and an odd (2 of 5) number of
        // passes before the others: its result is read from either buffer.
        for direct_passes in [1, 2] {
            let a = Atrous {
                taps: 3,
                direct: Strength { sigma_l: Some(1.5), passes: Some(direct_passes) },
                caustic: Strength { sigma_l: None, passes: Some(0) },
                ..Atrous::default()
            };
            let layer = |image, component| FilterInput {
                image,
                stops_from: None,
                variance: Some(&variance),
                component: Some(component),
                halves: None,
            };
            let together = filter(
                &[
                    layer(&direct.pixels, Component::Direct),
                    layer(&caustic.pixels, Component::Caustic),
                    layer(&indirect.pixels, Component::Indirect),
                ],
                &film,
                &a,
                true,
            );
            // Each layer as if filtered alone, with its component's settings as the filter's own.
            let alone = |image, sigma_l, passes| {
                filter(
                    &[FilterInput::new(image, Some(&variance))],
                    &film,
                    &Atrous { sigma_l, passes, ..a },
                    true,
                )
                .remove(0)
            };
            assert_eq!(together[0], alone(&direct, 1.5, direct_passes));
            assert_ne!(together[0], alone(&direct, a.sigma_l, a.passes));
            assert_eq!(together[1], caustic, "no passes: left as it is");
            assert_eq!(together[2], alone(&indirect, a.sigma_l, a.passes));
            assert_ne!(together[2], indirect);
        }
    }

    #[test]
    fn settings_parse_and_name_round_trip() {
        assert_eq!(Atrous::parse("atrous"), Ok(Atrous::default()));
        let a = Atrous::parse("atrous:passes=4:sigma_l=8:taps=3").expect("parses");
        assert_eq!((a.passes, a.sigma_l, a.taps), (4, 8.0, 3));
        assert_eq!(a.name(), "atrous:passes=4:sigma_l=8:taps=3");
        assert_eq!(Atrous::parse(&a.name()), Ok(a));
        let own =
            Atrous::parse("atrous:caustic_passes=2:direct_sigma_l=1.5:direct_passes=0").expect("parses");
        assert_eq!(own.direct, Strength { sigma_l: Some(1.5), passes: Some(0) });
        assert_eq!(own.caustic, Strength { sigma_l: None, passes: Some(2) });
        assert_eq!(own.name(), "atrous:direct_sigma_l=1.5:direct_passes=0:caustic_passes=2");
        assert_eq!(Atrous::parse(&own.name()), Ok(own));
        assert_eq!(Atrous::default().name(), "atrous");
        let fit = Atrous::parse("atrous:taps=3:linear=2").expect("parses");
        assert_eq!((fit.linear, fit.name()), (2, "atrous:taps=3:linear=2".to_string()));
        assert_eq!(Atrous::parse(&fit.name()), Ok(fit));
        assert!(Atrous::parse("atrous:linear=1.5").is_err());
        for bad in [
            "atrous:passes=0",
            "atrous:passes=-1",
            "atrous:passes=2.5",
            "atrous:passes=13",
            "atrous:sigma_l=0",
            "atrous:sigma_l=nan",
            "atrous:sigma_n=-1",
            "atrous:taps=4",
            "atrous:radius=2",
            "atrous:passes",
            "atrous:sigma_z=x",
            "atrous:direct_passes=13",
            "atrous:caustic_passes=-1",
            "atrous:direct_sigma_l=0",
            "atrous:caustic_sigma_l=inf",
            "atrous:emitted_passes=1",
        ] {
            assert!(Atrous::parse(bad).is_err(), "{bad}");
        }
    }

    /// The runs of noisy pixels, taken a block at a time where a block is all noisy, are the
    /// runs found pixel by pixel: rows of every length around the block's, with noiseless
    /// pixels alone, in short and long gaps, and at the ends.
    #[test]
    fn active_spans_equal_the_runs_found_pixel_by_pixel() {
        let by_pixel = |isg: &[f32]| {
            let mut spans: Vec<(usize, usize)> = Vec::new();
            for (x, &v) in isg.iter().enumerate() {
                if v < NOISELESS {
                    match spans.last_mut() {
                        Some(last) if x < last.1 + 8 => last.1 = x + 1,
                        _ => spans.push((x, x + 1)),
                    }
                }
            }
            spans
        };
        let mut next = stream(41);
        let mut spans = Vec::new();
        for n in [0, 1, 7, 15, 16, 17, 31, 32, 33, 64, 100, 257] {
            for quiet in [0.0, 0.05, 0.3, 0.9, 1.0] {
                // Noiseless pixels in runs of random length, so gaps below and above 8 occur.
                let mut isg = Vec::with_capacity(n);
                while isg.len() < n {
                    let run = (next() * 20.0) as usize + 1;
                    let v = if next() < quiet { NOISELESS } else { 1.0 };
                    isg.extend(std::iter::repeat_n(v, run.min(n - isg.len())));
                }
                if n > 3 {
                    isg[n / 3] = f32::NAN;
                }
                active_spans(&isg, &mut spans);
                assert_eq!(spans, by_pixel(&isg), "{n} pixels, {quiet} quiet");
            }
        }
    }

    #[test]
    fn exp2_neg_is_close_and_never_negative() {
        for i in 0..=20_000 {
            let t = i as f32 * 0.005;
            let (got, want) = (exp2_neg(t), (-t).exp2());
            assert!((got / want - 1.0).abs() < 2e-4, "{t}: {got} vs {want}");
        }
        assert!(exp2_neg(f32::NAN) >= 0.0 && exp2_neg(f32::NAN) < 1e-30);
        assert!(exp2_neg(f32::INFINITY) < 1e-30);
        assert_eq!(exp2_neg(-1.0), 1.0);
    }
}
