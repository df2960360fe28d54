//! The paper's noise-reduction filters (section 3): box3 (filter A), weighted3 (B), median3 (C),
//! box5 and any odd square kernel. Weights are divided by the sum of the weights actually used,
//! borders replicate the edge pixels, and in edge-aware mode (the paper's closing suggestion) a
//! neighbour counts only if it shows the same object as the centre, optionally also a similar
//! normal and depth. Linear in the pixel count and parallel over rows.
//!
//! Beyond the paper: the variance-guided à-trous filter ([`atrous`]), and the `components`
//! target, which filters direct, caustic and indirect light each on its own.

pub mod atrous;
pub mod cross;
mod pool;
mod section;

use std::borrow::Cow;

use glam::Vec3;
use rayon::prelude::*;

pub use atrous::{Atrous, FilterInput, Strength};
pub use pool::Pixels;
pub use section::Overrides;

use crate::component::Component::{self, Caustic, Direct, Emitted, Indirect};
use crate::film::{Film, Image};

/// A filter method: a convolution or the median over a window (the paper's filters), or the
/// à-trous wavelet filter, which reads each pixel's variance. [`Method::reads`] says what each
/// needs besides the image.
#[derive(Clone, Debug, PartialEq)]
pub enum Method {
    /// Weighted average over a `size` x `size` window (row-major weights).
    Convolution { size: usize, weights: Vec<f32> },
    /// Per-channel median over a 3x3 window (the paper's filter C).
    Median3,
    /// Beyond the paper: the variance-guided edge-avoiding à-trous wavelet filter.
    Atrous(Atrous),
}

/// What a filter reads besides the image it filters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Reads {
    /// The guide buffers (object, coverage, normal, depth, albedo).
    pub guides: bool,
    /// Each pixel's variance (kept with the component split).
    pub variance: bool,
}

impl Method {
    /// What this method, with `stops`, reads: the guides when an edge stop is on (à-trous
    /// always stops at objects and reads the albedo), the variance for à-trous.
    pub fn reads(&self, stops: &EdgeStops) -> Reads {
        match self {
            Method::Atrous(_) => Reads { guides: true, variance: true },
            Method::Convolution { .. } | Method::Median3 => Reads { guides: stops.any(), variance: false },
        }
    }

    /// A method by name: `box3`, `weighted3`, `median3`, `box5`, `atrous` (with settings:
    /// `atrous:passes=4:sigma_l=8`), or a custom odd square kernel written as comma-separated
    /// weights (`1,2,1,2,4,2,1,2,1`).
    pub fn parse(name: &str) -> Result<Method, String> {
        match name {
            atrous if atrous == "atrous" || atrous.starts_with("atrous:") => {
                Ok(Method::Atrous(Atrous::parse(atrous)?))
            }
            "box3" => Ok(Method::Convolution { size: 3, weights: vec![1.0; 9] }),
            "weighted3" => {
                Ok(Method::Convolution { size: 3, weights: vec![1., 2., 1., 2., 4., 2., 1., 2., 1.] })
            }
            "box5" => Ok(Method::Convolution { size: 5, weights: vec![1.0; 25] }),
            "median3" => Ok(Method::Median3),
            custom => {
                let weights: Result<Vec<f32>, _> =
                    custom.split(',').map(|w| w.trim().parse::<f32>()).collect();
                let weights = weights.map_err(|_| {
                    format!(
                        "unknown filter `{custom}` (box3, weighted3, median3, box5, atrous, or comma-separated weights)"
                    )
                })?;
                Method::custom(weights)
            }
        }
    }

    /// The name [`Method::parse`] reads back: a named kernel's name, else the weights.
    pub fn name(&self) -> String {
        for name in ["box3", "weighted3", "median3", "box5"] {
            if Method::parse(name).as_ref() == Ok(self) {
                return name.to_string();
            }
        }
        match self {
            Method::Convolution { weights, .. } => {
                weights.iter().map(|w| w.to_string()).collect::<Vec<_>>().join(",")
            }
            Method::Median3 => "median3".to_string(),
            Method::Atrous(a) => a.name(),
        }
    }

    /// An odd square kernel from its weights, row by row.
    pub fn custom(weights: Vec<f32>) -> Result<Method, String> {
        let side = crate::scene::limits::MAX_KERNEL;
        if weights.len() > side * side {
            return Err(format!("a custom kernel has at most {side}x{side} weights, not {}", weights.len()));
        }
        let size = (weights.len() as f64).sqrt() as usize;
        if size * size != weights.len() || size.is_multiple_of(2) {
            return Err(format!(
                "a custom kernel needs an odd square number of weights, not {}",
                weights.len()
            ));
        }
        if weights.iter().any(|w| !w.is_finite() || *w < 0.0) || weights.iter().sum::<f32>() <= 0.0 {
            return Err("kernel weights must be finite, not negative, and not all zero".into());
        }
        Ok(Method::Convolution { size, weights })
    }
}

/// A whole filter setting, as a scene file's `[filter]` or the command line gives it.
#[derive(Clone, Debug, PartialEq)]
pub struct Setting {
    pub method: Option<Method>,
    pub target: Target,
    pub stops: EdgeStops,
}

impl Default for Setting {
    fn default() -> Self {
        Setting { method: None, target: Target::None, stops: EdgeStops::default() }
    }
}

impl Setting {
    /// What `--denoise` asks for: the setting with the least error measured on the three
    /// scenes of docs/RESULTS.md ("Denoising", `scripts/bench-denoise.sh`) within the time
    /// budget.
    pub fn denoise() -> Setting {
        Setting {
            method: Some(Method::Atrous(Atrous {
                taps: 3,
                passes: 4,
                // 5 since each half's colour stop is the other half's (6 before: RESULTS).
                sigma_l: 5.0,
                sigma_n: 32.0,
                sigma_z: 2.0,
                // The direct light is the least noisy: a light touch, one pass. The caustic
                // light is the noisiest: a loose stop.
                direct: Strength { sigma_l: Some(1.5), passes: Some(1) },
                caustic: Strength { sigma_l: Some(24.0), passes: None },
                clamp: None,
                cross: true,
                // A plane fitted in each pass from the second on.
                linear: 2,
            })),
            target: Target::Components,
            stops: EdgeStops { pure: true, ..EdgeStops::default() },
        }
    }
}

/// What the filter is applied to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// Only L_r,d,d, then added back (the paper's method).
    Indirect,
    /// The whole image (the paper's Figure 3(c) baseline).
    Image,
    /// Beyond the paper: direct, caustic and indirect light, each filtered on its own (with
    /// the strength its own variance calls for, under `atrous`); emitted light never.
    Components,
    /// Nothing.
    None,
    /// An AOV of the render (a light path expression's layer): the image is the beauty less
    /// the AOV plus the AOV filtered. An AOV has no variance layer of its own: `atrous` reads
    /// the beauty's.
    Aov(AovName),
}

impl Target {
    /// The targets that are not AOVs.
    pub const NAMED: [Target; 4] = [Target::Indirect, Target::Image, Target::Components, Target::None];

    /// The name the command line, scene files and `results.csv` use.
    pub fn name(&self) -> &str {
        match self {
            Target::Indirect => "indirect",
            Target::Image => "image",
            Target::Components => "components",
            Target::None => "none",
            Target::Aov(name) => name.as_str(),
        }
    }

    /// The target of a name, as [`Target::name`] writes it: one of [`Target::NAMED`], else an
    /// AOV's name (whether the render has that AOV is checked where the film is known).
    pub fn from_name(name: &str) -> Option<Target> {
        Target::NAMED.into_iter().find(|t| t.name() == name).or_else(|| AovName::new(name).map(Target::Aov))
    }
}

/// An AOV's name as a filter target, kept inline so that a target stays `Copy`: letters,
/// digits and `_`, not starting with a digit, at most [`AovName::MAX`] bytes (as
/// [`crate::scene::Aov::new`] requires of every AOV's name).
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct AovName {
    len: u8,
    bytes: [u8; AovName::MAX],
}

impl AovName {
    pub const MAX: usize = 63;

    /// The name, if it can be an AOV's.
    pub fn new(name: &str) -> Option<AovName> {
        let valid = name.len() <= Self::MAX
            && name.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !valid {
            return None;
        }
        let mut bytes = [0; Self::MAX];
        bytes[..name.len()].copy_from_slice(name.as_bytes());
        Some(AovName { len: name.len() as u8, bytes })
    }

    pub fn as_str(&self) -> &str {
        // ASCII by construction.
        std::str::from_utf8(&self.bytes[..usize::from(self.len)]).unwrap_or_default()
    }
}

impl std::fmt::Debug for AovName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}", self.as_str())
    }
}

/// When neighbours are left out: across objects, and optionally across creases and depth steps.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EdgeStops {
    /// Only neighbours showing the centre's object.
    pub object: bool,
    /// Only neighbours whose normal is within this many degrees of the centre's.
    pub normal_degrees: Option<f32>,
    /// Only neighbours whose depth differs from the centre's by at most this fraction.
    pub depth_relative: Option<f32>,
    /// Beyond the paper: pixels whose samples saw more than one object (antialiased borders,
    /// coverage below 1) are left unfiltered and out of their neighbours' windows.
    pub pure: bool,
}

impl EdgeStops {
    /// Checks the tolerances: a normal angle in (0, 180] degrees, a non-negative depth ratio.
    pub fn check(&self) -> Result<(), String> {
        if let Some(d) = self.normal_degrees {
            if !(d.is_finite() && d > 0.0 && d <= 180.0) {
                return Err("the edge normal angle must lie in (0, 180] degrees".into());
            }
        }
        if let Some(r) = self.depth_relative {
            if !(r.is_finite() && r >= 0.0) {
                return Err("the edge depth tolerance must be a non-negative number".into());
            }
        }
        Ok(())
    }

    fn any(&self) -> bool {
        self.object || self.normal_degrees.is_some() || self.depth_relative.is_some() || self.pure
    }
}

/// Filters `image` by `method`; with `stops`, neighbours are tested against the guide buffers
/// of `film`. À-trous reads no variance here (an image alone has none): it is the layers'
/// filter, [`filter_layers`].
pub fn filter(image: &Image, method: &Method, film: &Film, stops: &EdgeStops) -> Image {
    match Plan::of(method) {
        Plan::Local(window) => {
            // Written straight into the image returned (not a pooled one copied).
            let mut out = Image::new(image.width, image.height);
            let size = (image.width, image.height);
            local_into(&image.pixels, size, &window, film, stops, bytemuck::cast_slice_mut(&mut out.pixels));
            out
        }
        Plan::Wavelet(a) => {
            let mut out = atrous::filter(&[FilterInput::new(image, None)], film, a, stops.pure);
            out.pop().map_or_else(|| image.clone(), |p| p.to_image(image.width, image.height))
        }
    }
}

/// Filters each layer: the paper's filters one by one, à-trous with each layer's variance and
/// the guides' geometry shared (its object stop is always on; `stops.pure` also applies).
pub fn filter_layers(layers: &[FilterInput], method: &Method, film: &Film, stops: &EdgeStops) -> Vec<Pixels> {
    match Plan::of(method) {
        Plan::Local(window) => {
            layers.iter().map(|l| local(l.image, (film.width, film.height), &window, film, stops)).collect()
        }
        Plan::Wavelet(a) if a.cross && layers.iter().any(|l| l.halves.is_some()) => {
            checked(layers, film, a, stops)
        }
        Plan::Wavelet(a) => atrous::filter(layers, film, a, stops.pure),
    }
}

/// À-trous on `layers`, each layer with halves filtered half by half and kept only where that
/// says it lowers the error ([`cross`]). All the images are filtered in one call.
fn checked(layers: &[FilterInput], film: &Film, a: &Atrous, stops: &EdgeStops) -> Vec<Pixels> {
    // Each half's variance: the whole's over the half's share of the samples.
    let scaled = |variance: Option<&[f32]>, share: &[f32], second: bool| -> Option<pool::Plane> {
        let v = variance?;
        let mut out = pool::Plane::overwritten(v.len());
        out.par_iter_mut().zip(v).zip(share).for_each(|((o, &v), &s)| {
            let part = if second { s } else { 1.0 - s };
            *o = if part > 0.0 && part < 1.0 { v / part } else { v };
        });
        Some(out)
    };
    struct Halved<'a> {
        layer: usize,
        halves: (Pixels, Pixels),
        variances: (Option<pool::Plane>, Option<pool::Plane>),
        share: &'a [f32],
    }
    let halved: Vec<Halved> = layers
        .iter()
        .enumerate()
        .filter_map(|(i, l)| {
            // Without a pixel of two sampled halves (1 spp) there is nothing to check; a layer
            // the filter does not change ([`Atrous::changes`]: zero everywhere, or no passes)
            // is left as it is, unhalved.
            let (half, share) = l.halves.filter(|(_, share)| share.iter().any(|&s| s > 0.0 && s < 1.0))?;
            if !a.changes(l) {
                return None;
            }
            Some(Halved {
                layer: i,
                halves: cross::halves(l.image, half, share),
                variances: (scaled(l.variance, share, false), scaled(l.variance, share, true)),
                share,
            })
        })
        .collect();
    // The layers without halves are filtered whole. Those with halves are filtered only half by
    // half, and their whole is the filtered halves weighted by their shares of the samples (the
    // check's estimate is that mix's error: [`cross`]).
    let whole: Vec<usize> = (0..layers.len()).filter(|&i| !halved.iter().any(|h| h.layer == i)).collect();
    let mut inputs: Vec<FilterInput> =
        whole.iter().map(|&i| FilterInput { halves: None, stops_from: None, ..layers[i] }).collect();
    // Each half's colour stop reads its taps' luminance in the other half: weights made from
    // the values they average favour the taps whose noise agrees with the centre's, which
    // pulls the mean toward the common side of skewed noise (docs/RESULTS.md, "Denoising").
    for h in &halved {
        let component = layers[h.layer].component;
        let first = inputs.len();
        for (i, (image, variance)) in
            [(&h.halves.0, &h.variances.0), (&h.halves.1, &h.variances.1)].into_iter().enumerate()
        {
            let stops_from = Some(first + 1 - i);
            inputs.push(FilterInput {
                image,
                variance: variance.as_deref(),
                component,
                halves: None,
                stops_from,
            });
        }
    }
    let mut filtered = atrous::filter(&inputs, film, a, stops.pure).into_iter();
    let mut whole = filtered.by_ref().take(whole.len()).collect::<Vec<_>>().into_iter();
    // Each halved layer (in layer order) with its pair of filtered halves, blended when its
    // layer comes.
    let pairs = std::iter::from_fn(|| Some((filtered.next()?, filtered.next()?)));
    let mut checked = halved.iter().zip(pairs).peekable();
    layers
        .iter()
        .enumerate()
        .map(|(i, l)| match checked.next_if(|(h, _)| h.layer == i) {
            Some((h, (fa, fb))) => {
                cross::blend(l.image, (&h.halves.0, &h.halves.1), (fa, &fb), h.share, film.width)
            }
            None => whole.next().unwrap_or_else(|| Pixels::copy_of(l.image)),
        })
        .collect()
}

/// How a method runs: over a local window, pixel by pixel (the paper's filters), or as the
/// à-trous wavelet filter's passes.
enum Plan<'a> {
    Local(Window),
    Wavelet(&'a Atrous),
}

impl<'a> Plan<'a> {
    fn of(method: &'a Method) -> Plan<'a> {
        match method {
            Method::Convolution { size, weights } => {
                Plan::Local(Window::Convolution { radius: *size / 2, weights: scaled_weights(weights) })
            }
            Method::Median3 => Plan::Local(Window::Median3),
            Method::Atrous(a) => Plan::Wavelet(a),
        }
    }
}

/// The window of a local filter: a convolution's weights, scaled by the power of two that
/// brings their sum into (1/2, 1] ([`scaled_weights`]), or the 3x3 median.
enum Window {
    Convolution { radius: usize, weights: Vec<f32> },
    Median3,
}

impl Window {
    fn radius(&self) -> usize {
        match self {
            Window::Convolution { radius, .. } => *radius,
            Window::Median3 => 1,
        }
    }
}

/// Filters `image` by a local `window`.
///
/// Rows run in parallel. Away from the left and right borders a row is computed on its floats
/// (RGB interleaved, so a neighbour `dx` pixels away is `3 dx` floats away): one multiply-add
/// pass over the row per kernel tap, or one median network over nine shifted rows, loops the
/// compiler vectorises. The border columns, and the edge-aware median, go pixel by pixel through
/// [`Filter::pixel`], the plain definition that tests compare the fast paths with.
fn local(image: &[Vec3], size: (u32, u32), window: &Window, film: &Film, stops: &EdgeStops) -> Pixels {
    let mut out = Pixels::overwritten(image.len());
    local_into(image, size, window, film, stops, out.floats_mut());
    out
}

/// [`local`] into `out`, three floats a pixel, every one written.
fn local_into(
    image: &[Vec3],
    (w, h): (u32, u32),
    window: &Window,
    film: &Film,
    stops: &EdgeStops,
    out: &mut [f32],
) {
    let f = Filter::new(image, (w as usize, h as usize), window, film, stops);
    let w = w as usize;
    if w == 0 {
        return;
    }
    out.par_chunks_mut(3 * w).enumerate().for_each_init(
        || (Vec::new(), Vec::new()),
        |(scratch, count), (y, row)| f.row(y, row, scratch, count),
    );
}

/// One pass of a local filter, ready to run row by row.
struct Filter<'a> {
    image: &'a [Vec3],
    /// The image's width and height.
    w: usize,
    h: usize,
    flat: &'a [f32],
    window: &'a Window,
    film: &'a Film,
    stops: EdgeStops,
    cos_min: Option<f32>,
    edge_aware: bool,
    radius: usize,
}

impl<'a> Filter<'a> {
    fn new(
        image: &'a [Vec3],
        (w, h): (usize, usize),
        window: &'a Window,
        film: &'a Film,
        stops: &EdgeStops,
    ) -> Self {
        Filter {
            image,
            w,
            h,
            flat: bytemuck::cast_slice(image),
            window,
            film,
            stops: *stops,
            cos_min: stops.normal_degrees.map(|d| d.to_radians().cos()),
            edge_aware: stops.any(),
            radius: window.radius(),
        }
    }

    /// Whether neighbour pixel `n` may contribute to centre pixel `c`.
    #[inline(always)]
    fn same_surface(&self, c: usize, n: usize) -> bool {
        let (film, stops) = (self.film, &self.stops);
        if c == n {
            return true; // the centre always counts
        }
        if stops.pure && (film.coverage[c] < 1.0 || film.coverage[n] < 1.0) {
            return false;
        }
        if stops.object && film.object[c] != film.object[n] {
            return false;
        }
        if let Some(cos_min) = self.cos_min {
            if film.normal.pixels[c].dot(film.normal.pixels[n]) < cos_min {
                return false;
            }
        }
        if let Some(rel) = stops.depth_relative {
            let (a, b) = (film.depth[c], film.depth[n]);
            if (a - b).abs() > rel * a.abs().max(b.abs()) {
                return false;
            }
        }
        true
    }

    /// Into `weight`: `wk` for each of the `weight.len()` centres from pixel `c0` on whose
    /// neighbour (from pixel `n0` on) passes the stops, else 0. One simple loop per stop.
    fn stop_weights(&self, wk: f32, c0: usize, n0: usize, weight: &mut [f32]) {
        let (film, n) = (self.film, weight.len());
        weight.fill(wk);
        if self.stops.object {
            let (oc, on) = (&film.object[c0..c0 + n], &film.object[n0..n0 + n]);
            for ((wt, a), b) in weight.iter_mut().zip(oc).zip(on) {
                *wt = if a == b { *wt } else { 0.0 };
            }
        }
        if let Some(cos_min) = self.cos_min {
            let (nc, nn) = (&film.normal.pixels[c0..c0 + n], &film.normal.pixels[n0..n0 + n]);
            for ((wt, a), b) in weight.iter_mut().zip(nc).zip(nn) {
                *wt = if a.dot(*b) < cos_min { 0.0 } else { *wt };
            }
        }
        if self.stops.pure && c0 != n0 {
            let (cc, cn) = (&film.coverage[c0..c0 + n], &film.coverage[n0..n0 + n]);
            for ((wt, a), b) in weight.iter_mut().zip(cc).zip(cn) {
                *wt = if *a < 1.0 || *b < 1.0 { 0.0 } else { *wt };
            }
        }
        if let Some(rel) = self.stops.depth_relative {
            let (dc, dn) = (&film.depth[c0..c0 + n], &film.depth[n0..n0 + n]);
            for ((wt, a), b) in weight.iter_mut().zip(dc).zip(dn) {
                *wt = if (a - b).abs() > rel * a.abs().max(b.abs()) { 0.0 } else { *wt };
            }
        }
    }

    /// The filtered value of pixel (x, y), by the definition: every neighbour of the window
    /// (borders replicated) that passes the stops, weighted, divided by the weights used.
    fn pixel(&self, x: usize, y: usize) -> Vec3 {
        let (w, h) = (self.w as i64, self.h as i64);
        let r = self.radius as i64;
        let centre = y * w as usize + x;
        let mut window = [Vec3::ZERO; 9];
        let (mut acc, mut weight_sum, mut used) = (Vec3::ZERO, 0.0f32, 0);
        let mut k = 0;
        for dy in -r..=r {
            let yy = (y as i64 + dy).clamp(0, h - 1);
            for dx in -r..=r {
                let n = (yy * w + (x as i64 + dx).clamp(0, w - 1)) as usize;
                let take = !self.edge_aware || self.same_surface(centre, n);
                match self.window {
                    Window::Convolution { weights, .. } if take => {
                        acc += self.image[n] * weights[k];
                        weight_sum += weights[k];
                    }
                    Window::Median3 if take => {
                        window[used] = self.image[n];
                        used += 1;
                    }
                    _ => {}
                }
                k += 1;
            }
        }
        match self.window {
            // Divided by the weights actually used, so energy is kept at edges.
            Window::Convolution { .. } if weight_sum > 0.0 => acc / weight_sum,
            Window::Convolution { .. } => self.image[centre],
            Window::Median3 => median(&mut window[..used]),
        }
    }

    /// Output row `y` (as floats), with scratch buffers for the edge-aware stops.
    fn row(&self, y: usize, out: &mut [f32], scratch: &mut Vec<f32>, count: &mut Vec<f32>) {
        let (w, h) = (self.w, self.h);
        let r = self.radius;
        // The pixels that the fast path computes: a full window without clamping columns.
        let interior = if w > 2 * r { r..w - r } else { 0..0 };
        for x in (0..interior.start).chain(interior.end.max(interior.start)..w) {
            out[3 * x..3 * x + 3].copy_from_slice(&self.pixel(x, y).to_array());
        }
        if interior.is_empty() {
            return;
        }
        // Rows y - r ..= y + r, clamped (the border rows replicate).
        let rows: Vec<&[f32]> = (0..=2 * r)
            .map(|k| {
                let yy = (y + k).saturating_sub(r).min(h - 1);
                &self.flat[3 * w * yy..3 * w * (yy + 1)]
            })
            .collect();
        let n = interior.len();
        let dst = &mut out[3 * r..3 * (r + n)];
        match self.window {
            Window::Convolution { weights, .. } => {
                // With every weight used (the window never leaves the image) one sum divides.
                dst.fill(0.0);
                for (k, row) in rows.iter().enumerate() {
                    for dx in 0..=2 * r {
                        let wk = weights[k * (2 * r + 1) + dx];
                        for (o, i) in dst.iter_mut().zip(&row[3 * dx..3 * (dx + n)]) {
                            *o += wk * i;
                        }
                    }
                }
                let sum: f32 = weights.iter().sum();
                dst.iter_mut().for_each(|o| *o /= sum);
            }
            Window::Median3 => {
                let len = dst.len();
                let s: [&[f32]; 9] = std::array::from_fn(|i| &rows[i / 3][3 * (i % 3)..3 * (i % 3) + len]);
                let [s0, s1, s2, s3, s4, s5, s6, s7, s8] = s.map(|s| &s[..len]);
                for j in 0..len {
                    let v = [s0[j], s1[j], s2[j], s3[j], s4[j], s5[j], s6[j], s7[j], s8[j]];
                    dst[j] = median9_by(v, f32::min, f32::max);
                }
            }
        }
        if self.edge_aware {
            // Where a stop leaves a neighbour out, the pixel is computed again by the definition.
            // Elsewhere the whole window counts, and the result above is exactly that one.
            scratch.resize(n, 0.0);
            count.clear();
            count.resize(n, 0.0);
            for k in 0..=2 * r {
                let yy = (y + k).saturating_sub(r).min(h - 1);
                for dx in 0..=2 * r {
                    let (c0, n0) = (y * w + r, yy * w + dx);
                    if self.cos_min.is_none() && self.stops.depth_relative.is_none() && !self.stops.pure {
                        // Objects only (the paper's edge-aware mode): one pass.
                        let (oc, on) = (&self.film.object[c0..c0 + n], &self.film.object[n0..n0 + n]);
                        for ((c, a), b) in count.iter_mut().zip(oc).zip(on) {
                            *c += if a == b { 1.0 } else { 0.0 };
                        }
                    } else {
                        self.stop_weights(1.0, c0, n0, scratch);
                        count.iter_mut().zip(scratch.iter()).for_each(|(c, s)| *c += s);
                    }
                }
            }
            let taps = ((2 * r + 1) * (2 * r + 1)) as f32;
            for (i, _) in count.iter().enumerate().filter(|(_, c)| **c < taps) {
                let x = r + i;
                out[3 * x..3 * x + 3].copy_from_slice(&self.pixel(x, y).to_array());
            }
        }
    }
}

/// A convolution's weights scaled by the power of two that brings their sum into (1/2, 1]. A
/// weighted sum then never exceeds the largest value it sums, so it cannot overflow where the
/// mean it makes is finite (nine values of 3e38 summed by box3 were infinite), and a kernel of
/// weights near the largest float works; and scaling by a power of two is exact, so the mean,
/// divided by the scaled weights' sum, is bit for bit what the weights as given make.
fn scaled_weights(weights: &[f32]) -> Vec<f32> {
    let sum: f64 = weights.iter().map(|&w| w as f64).sum();
    if !(sum > 0.0 && sum.is_finite()) {
        return weights.to_vec();
    }
    let scale = 2f64.powi(-(sum.log2().ceil() as i32));
    weights.iter().map(|&w| (w as f64 * scale) as f32).collect()
}

/// The median of nine values by Paeth's 19-exchange network ("Median Finding on a 3x3 Grid",
/// Graphics Gems, 1990, the paper's reference [Paet90]), for any type with a min and a max: one
/// float, or all three channels of a pixel at once.
#[inline(always)]
fn median9_by<T: Copy>(p: [T; 9], min: impl Fn(T, T) -> T, max: impl Fn(T, T) -> T) -> T {
    let [mut p0, mut p1, mut p2, mut p3, mut p4, mut p5, mut p6, mut p7, mut p8] = p;
    // Compare-exchange in named variables, so the network unrolls into straight min/max code.
    macro_rules! s {
        ($a:ident, $b:ident) => {
            let lo = min($a, $b);
            $b = max($a, $b);
            $a = lo;
        };
    }
    s!(p1, p2);
    s!(p4, p5);
    s!(p7, p8);
    s!(p0, p1);
    s!(p3, p4);
    s!(p6, p7);
    s!(p1, p2);
    s!(p4, p5);
    s!(p7, p8);
    s!(p0, p3);
    s!(p5, p8);
    s!(p4, p7);
    s!(p3, p6);
    s!(p1, p4);
    s!(p2, p5);
    s!(p4, p7);
    s!(p4, p2);
    s!(p6, p4);
    s!(p4, p2);
    let _ = (p0, p1, p2, p3, p5, p6, p7, p8);
    p4
}

fn median9(v: &[Vec3]) -> Vec3 {
    median9_by(std::array::from_fn(|i| v[i]), Vec3::min, Vec3::max)
}

/// Per-channel median (the mean of the two middle values for an even count).
fn median(values: &mut [Vec3]) -> Vec3 {
    if values.len() == 9 {
        return median9(values);
    }
    let n = values.len();
    let mut channel = [0.0f32; 25];
    let mut out = [0.0f32; 3];
    for (c, o) in out.iter_mut().enumerate() {
        for (slot, v) in channel.iter_mut().zip(values.iter()) {
            *slot = v[c];
        }
        let ch = &mut channel[..n];
        ch.sort_unstable_by(f32::total_cmp);
        *o = if !n.is_multiple_of(2) { ch[n / 2] } else { 0.5 * (ch[n / 2 - 1] + ch[n / 2]) };
    }
    Vec3::from(out)
}

/// The final image of a film: the components with `kernel` applied to `target`; without a
/// kernel, the film's own beauty (borrowed, not copied). With it, also the filtered indirect
/// component when the target filters it (`indirect` or `components`).
///
/// - `indirect`: emitted + direct + caustic + filtered indirect (the paper's method);
/// - `components`: emitted + the filtered direct, caustic and indirect;
/// - `image`: the beauty filtered whole.
///
/// A film without the split filters its beauty whatever the target. Each layer is filtered
/// with its own variance, when the film has it.
pub fn composite<'a>(
    film: &'a Film,
    kernel: Option<&Method>,
    target: Target,
    stops: &EdgeStops,
) -> (Cow<'a, Image>, Option<Pixels>) {
    let Some(kernel) = kernel else { return (Cow::Borrowed(&film.raw), None) };
    let layer = |c: Component| FilterInput {
        image: &film.components[c].pixels,
        variance: (!film.component_variance[c].is_empty()).then(|| film.component_variance[c].as_slice()),
        component: Some(c),
        halves: film.has_halves().then(|| (&film.component_half[c].pixels[..], film.half_share.as_slice())),
        stops_from: None,
    };
    let filtered: &[Component] = match target {
        Target::None => return (Cow::Borrowed(&film.raw), None),
        Target::Aov(name) => {
            // A film without that AOV (which the callers refuse first) is left unfiltered.
            let Some(aov) = film.aovs.iter().find(|a| a.name == name.as_str()) else {
                return (Cow::Borrowed(&film.raw), None);
            };
            let variance = (!film.variance.is_empty()).then_some(film.variance.as_slice());
            let mut out = filter_layers(&[FilterInput::new(&aov.image, variance)], kernel, film, stops);
            let filtered = out.pop().unwrap_or_else(|| Pixels::copy_of(&aov.image.pixels));
            let mut image = film.raw.clone();
            for ((o, a), f) in image.pixels.iter_mut().zip(&aov.image.pixels).zip(filtered.iter()) {
                *o += *f - *a;
            }
            return (Cow::Owned(image), None);
        }
        _ if !film.has_split() => &[],
        Target::Image => &[],
        Target::Indirect => &[Indirect],
        Target::Components => &[Direct, Caustic, Indirect],
    };
    if filtered.is_empty() {
        let variance = (!film.variance.is_empty()).then_some(film.variance.as_slice());
        let halves = film.has_halves().then_some((&film.half.pixels[..], film.half_share.as_slice()));
        let input = FilterInput { halves, ..FilterInput::new(&film.raw, variance) };
        let mut out = filter_layers(&[input], kernel, film, stops);
        let image =
            out.pop().map_or_else(|| film.raw.clone(), |p| p.to_image(film.raw.width, film.raw.height));
        return (Cow::Owned(image), None);
    }
    let layers: Vec<FilterInput> = filtered.iter().map(|&c| layer(c)).collect();
    let mut images = filter_layers(&layers, kernel, film, stops);
    let [direct, caustic, indirect] = [Direct, Caustic, Indirect].map(|c| {
        filtered.iter().position(|&f| f == c).map_or(&film.components[c].pixels[..], |i| &images[i][..])
    });
    // The sum in one parallel step, in the order emitted, direct, caustic, indirect.
    let emitted = &film.components[Emitted];
    let out = Image {
        width: emitted.width,
        height: emitted.height,
        pixels: (0..emitted.pixels.len())
            .into_par_iter()
            .map(|i| emitted.pixels[i] + direct[i] + caustic[i] + indirect[i])
            .collect(),
    };
    // The filtered indirect layer is handed out, not copied.
    let indirect = filtered.iter().position(|&f| f == Indirect).map(|i| images.swap_remove(i));
    (Cow::Owned(out), indirect)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn film_of(image: &Image) -> Film {
        let mut f = Film::new(image.width, image.height);
        f.object.iter_mut().for_each(|o| *o = 0.0);
        f
    }

    fn kernels() -> Vec<Method> {
        ["box3", "weighted3", "median3", "box5", "1,1,1,1,9,1,1,1,1"]
            .iter()
            .map(|k| Method::parse(k).expect("kernel"))
            .collect()
    }

    #[test]
    fn a_constant_image_is_unchanged() {
        let mut img = Image::new(9, 7);
        img.pixels.iter_mut().for_each(|p| *p = Vec3::new(0.3, 1.5, 7.0));
        for k in kernels() {
            let out = filter(&img, &k, &film_of(&img), &EdgeStops::default());
            // Up to the rounding of a weighted mean (a few ulps).
            for (a, b) in out.pixels.iter().zip(&img.pixels) {
                assert!(
                    (*a - *b).abs().max_element() <= 4.0 * f32::EPSILON * b.abs().max_element(),
                    "{k:?}: {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn a_bright_pixel_spreads_by_the_kernel_weights() {
        let mut img = Image::new(9, 9);
        img.set(4, 4, Vec3::splat(16.0));
        let out =
            filter(&img, &Method::parse("weighted3").expect("k"), &film_of(&img), &EdgeStops::default());
        let expect = [[1., 2., 1.], [2., 4., 2.], [1., 2., 1.]];
        for dy in 0..3 {
            for dx in 0..3 {
                assert_eq!(out.get(3 + dx, 3 + dy).x, expect[dy as usize][dx as usize], "({dx}, {dy})");
            }
        }
        assert_eq!(out.get(1, 1), Vec3::ZERO);
        // Energy is kept away from the border.
        let total: f32 = out.pixels.iter().map(|p| p.x).sum();
        assert!((total - 16.0).abs() < 1e-5);
    }

    #[test]
    fn median_removes_an_isolated_spike() {
        let mut img = Image::new(5, 5);
        img.pixels.iter_mut().for_each(|p| *p = Vec3::ONE);
        img.set(2, 2, Vec3::splat(1000.0));
        let out = filter(&img, &Method::Median3, &film_of(&img), &EdgeStops::default());
        assert!(out.pixels.iter().all(|p| *p == Vec3::ONE));
    }

    #[test]
    fn borders_replicate() {
        // A ramp in x: at the left border the replicated column makes box3 see x = 0, 0, 1.
        let mut img = Image::new(4, 3);
        for y in 0..3 {
            for x in 0..4 {
                img.set(x, y, Vec3::splat(x as f32));
            }
        }
        let out = filter(&img, &Method::parse("box3").expect("k"), &film_of(&img), &EdgeStops::default());
        assert!((out.get(0, 0).x - 1.0 / 3.0).abs() < 1e-6);
        assert!((out.get(3, 2).x - 8.0 / 3.0).abs() < 1e-6);
        assert!((out.get(1, 1).x - 1.0).abs() < 1e-6);
    }

    #[test]
    fn edge_aware_filtering_keeps_a_two_object_step() {
        let mut img = Image::new(8, 4);
        let mut film = Film::new(8, 4);
        for y in 0..4 {
            for x in 0..8 {
                img.set(x, y, Vec3::splat(if x < 4 { 1.0 } else { 5.0 }));
                film.object[(y * 8 + x) as usize] = if x < 4 { 0.0 } else { 1.0 };
            }
        }
        let stops = EdgeStops { object: true, ..Default::default() };
        for k in kernels() {
            let out = filter(&img, &k, &film, &stops);
            assert_eq!(out, img, "{k:?} blurred the step");
            // Without stops the linear kernels blur it (a median keeps a straight step anyway).
            if k != Method::Median3 {
                let blurred = filter(&img, &k, &film, &EdgeStops::default());
                assert_ne!(blurred, img, "{k:?}: without stops the step must blur");
            }
        }
    }

    /// Numbers in [0, 1) from a xorshift generator.
    fn stream(seed: u32) -> impl FnMut() -> f32 {
        let mut state = seed;
        move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state >> 8) as f32 / 16_777_216.0
        }
    }

    /// The row-vectorised fast paths against the per-pixel definition, on random images with
    /// random objects, normals and depths, for every kernel and every combination of stops, on
    /// sizes below, at and above the kernel width.
    #[test]
    fn fast_paths_equal_the_definition() {
        let mut next = stream(0x1234_5678);
        for (w, h) in [(1, 1), (2, 5), (5, 3), (6, 6), (37, 11)] {
            let mut img = Image::new(w, h);
            let mut film = Film::new(w, h);
            for i in 0..(w * h) as usize {
                img.pixels[i] = Vec3::new(next(), 10.0 * next(), next() * next());
                film.object[i] = (next() * 3.0).floor();
                film.normal.pixels[i] = Vec3::new(next() - 0.5, next() - 0.5, 1.0).normalize();
                film.depth[i] = 1.0 + next();
                film.coverage[i] = if next() < 0.8 { 1.0 } else { 0.5 };
            }
            let stop_sets = [
                EdgeStops::default(),
                EdgeStops { object: true, ..Default::default() },
                EdgeStops { normal_degrees: Some(20.0), ..Default::default() },
                EdgeStops {
                    object: true,
                    normal_degrees: Some(30.0),
                    depth_relative: Some(0.2),
                    pure: false,
                },
                EdgeStops { object: true, pure: true, ..Default::default() },
            ];
            for k in kernels() {
                for stops in &stop_sets {
                    let fast = filter(&img, &k, &film, stops);
                    let Plan::Local(window) = Plan::of(&k) else { panic!("{k:?} is not local") };
                    let f = Filter::new(&img.pixels, (w as usize, h as usize), &window, &film, stops);
                    for y in 0..h as usize {
                        for x in 0..w as usize {
                            let want = f.pixel(x, y);
                            let got = fast.pixels[y * w as usize + x];
                            assert_eq!(got, want, "{w}x{h} {k:?} {stops:?} at ({x}, {y})");
                        }
                    }
                }
            }
        }
    }

    /// An antialiased border pixel (coverage below 1) between two objects: the paper's edge-aware
    /// filter averages it with its own object's pixels; with `pure` it keeps its value, and its
    /// neighbours leave it out.
    #[test]
    fn pure_stops_leave_mixed_pixels_alone() {
        let (w, h) = (7u32, 3u32);
        let mut img = Image::new(w, h);
        let mut film = Film::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                let (value, object) = match x {
                    0..=2 => (1.0, 0.0),
                    3 => (3.0, 0.0), // half object 0 (1.0), half object 1 (5.0)
                    _ => (5.0, 1.0),
                };
                img.pixels[i] = Vec3::splat(value);
                film.object[i] = object;
                film.coverage[i] = if x == 3 { 0.5 } else { 1.0 };
            }
        }
        let k = Method::parse("box3").expect("k");
        let paper = filter(&img, &k, &film, &EdgeStops { object: true, ..Default::default() });
        // The mixed pixel (3.0, labelled object 0) is averaged with object 0's pixels (1.0).
        assert!((paper.get(3, 1).x - 2.0).abs() < 1e-6, "{}", paper.get(3, 1));
        assert!((paper.get(2, 1).x - 5.0 / 3.0).abs() < 1e-6, "the mixed pixel pulls its neighbour up");
        let pure = filter(&img, &k, &film, &EdgeStops { object: true, pure: true, ..Default::default() });
        assert_eq!(pure.get(3, 1).x, 3.0);
        assert_eq!(pure.get(2, 1).x, 1.0);
    }

    /// `components` filters direct, caustic and indirect light and never emitted light: with only
    /// emitted light in the film the final image is it, bit for bit, whatever the kernel; and
    /// each filtered component lands in the sum.
    #[test]
    fn components_leave_emitted_light_alone() {
        let (w, h) = (21u32, 13u32);
        let mut next = stream(99);
        let mut film = Film::new(w, h);
        for i in 0..(w * h) as usize {
            film.object[i] = (i % 7 / 4) as f32;
            film.normal.pixels[i] = Vec3::Z;
            film.depth[i] = 1.0;
            film.albedo.pixels[i] = Vec3::splat(0.5);
            film.components[Emitted].pixels[i] = Vec3::new(next(), next(), next()) * 4.0;
            for c in [Direct, Caustic, Indirect] {
                film.component_variance[c][i] = 0.1;
            }
        }
        film.raw = film.components[Emitted].clone();
        for name in ["box3", "median3", "atrous", "atrous:taps=3"] {
            let k = Method::parse(name).expect("kernel");
            let (out, indirect) = composite(&film, Some(&k), Target::Components, &EdgeStops::default());
            assert_eq!(*out, film.components[Emitted], "{name}");
            assert!(indirect.is_some(), "{name}: the filtered indirect layer");
        }
        // Noisy direct and indirect light: filtered, and added to the untouched emitted light.
        let mut noisy = film.clone();
        for i in 0..(w * h) as usize {
            noisy.components[Direct].pixels[i] = Vec3::splat(next());
            noisy.components[Indirect].pixels[i] = Vec3::splat(next());
        }
        let k = Method::parse("atrous").expect("kernel");
        let (out, indirect) = composite(&noisy, Some(&k), Target::Components, &EdgeStops::default());
        let indirect = indirect.expect("filtered indirect");
        let direct = filter_layers(
            &[FilterInput::new(&noisy.components[Direct], Some(&noisy.component_variance[Direct]))],
            &k,
            &noisy,
            &EdgeStops::default(),
        );
        assert_ne!(indirect, noisy.components[Indirect]);
        assert_ne!(direct[0], noisy.components[Direct]);
        for i in 0..(w * h) as usize {
            let want = noisy.components[Emitted].pixels[i] + direct[0][i] + indirect[i];
            assert!((out.pixels[i] - want).abs().max_element() < 1e-5, "{i}");
        }
    }

    /// A layer given no passes (`direct_passes=0`) comes back as it went in, bit for bit, though
    /// it has halves (it is neither filtered nor checked), while the indirect light beside it
    /// is filtered.
    #[test]
    fn a_layer_with_no_passes_is_left_as_it_is() {
        let (w, h) = (24u32, 20u32);
        let n = (w * h) as usize;
        let mut next = stream(7);
        let mut film = Film::new(w, h);
        // The second half's share of the samples, from a fifth to four fifths.
        film.half_share = (0..n).map(|_| 0.2 + 0.6 * next()).collect();
        for c in [Direct, Indirect] {
            film.component_half[c] = Image::new(w, h);
        }
        for i in 0..n {
            film.object[i] = (i % 5 / 3) as f32;
            film.normal.pixels[i] = Vec3::Z;
            film.depth[i] = 1.0;
            film.coverage[i] = 1.0;
            film.albedo.pixels[i] = Vec3::new(0.7, 0.5, 0.3);
            let s = film.half_share[i];
            for c in [Direct, Indirect] {
                let (a, b) = (Vec3::new(next(), next(), next()), Vec3::new(next(), next(), next()));
                film.components[c].pixels[i] = (1.0 - s) * a + s * b;
                film.component_half[c].pixels[i] = s * b;
                film.component_variance[c][i] = 0.05;
            }
        }
        let layer = |c: Component| FilterInput {
            image: &film.components[c].pixels,
            variance: Some(&film.component_variance[c]),
            component: Some(c),
            halves: Some((&film.component_half[c].pixels, &film.half_share)),
            stops_from: None,
        };
        let k = Method::parse("atrous:taps=3:passes=2:direct_passes=0").expect("kernel");
        let out = filter_layers(&[layer(Direct), layer(Indirect)], &k, &film, &EdgeStops::default());
        assert_eq!(out[0], film.components[Direct]);
        assert_ne!(out[1], film.components[Indirect]);
    }

    /// The weights are scaled by a power of two before they sum (L4): weights of 1e38, whose
    /// sums overflowed, give the image their ratios give, bit for bit, and so do values near
    /// the largest float, whose weighted sums overflowed (a constant 3e38 came out infinite).
    #[test]
    fn weights_and_values_near_the_largest_float_filter_exactly() {
        let mut img = Image::new(7, 5);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = Vec3::new(i as f32, 1.0 + (i % 3) as f32, 0.25 * i as f32);
        }
        let film = film_of(&img);
        let ratios = Method::parse("1,2,1,2,4,2,1,2,1").expect("kernel");
        let huge =
            Method::custom([1., 2., 1., 2., 4., 2., 1., 2., 1.].map(|w: f32| w * 2f32.powi(100)).to_vec())
                .expect("kernel");
        for stops in [EdgeStops::default(), EdgeStops { object: true, ..Default::default() }] {
            let want = filter(&img, &ratios, &film, &stops);
            assert_eq!(filter(&img, &huge, &film, &stops), want);
            assert!(want.pixels.iter().all(|p| p.is_finite()));
        }
        let mut big = Image::new(7, 5);
        big.pixels.iter_mut().for_each(|p| *p = Vec3::splat(3e38));
        for k in kernels() {
            let out = filter(&big, &k, &film_of(&big), &EdgeStops::default());
            assert!(out.pixels.iter().all(|p| p.is_finite() && (p.x / 3e38 - 1.0).abs() < 1e-6), "{k:?}");
        }
        assert_eq!(scaled_weights(&[1.0; 9]), vec![0.0625; 9]);
    }

    #[test]
    fn bad_kernels_are_errors() {
        assert!(Method::parse("gauss").is_err());
        assert!(Method::parse("1,2,3,4").is_err());
        assert!(Method::parse("0,0,0,0,0,0,0,0,0").is_err());
        assert!(Method::parse("1,1,1,1,-1,1,1,1,1").is_err());
        assert_eq!(Method::parse("1").expect("1x1"), Method::Convolution { size: 1, weights: vec![1.0] });
    }
}

#[cfg(test)]
mod median_tests {
    use super::*;

    #[test]
    fn the_network_agrees_with_sorting() {
        let mut state = 12345u32;
        for _ in 0..2000 {
            let v: Vec<Vec3> = (0..9)
                .map(|_| {
                    let mut next = || {
                        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                        (state >> 20) as f32
                    };
                    Vec3::new(next(), next(), next())
                })
                .collect();
            let mut sorted = v.clone();
            let want = {
                let mut out = [0.0; 3];
                for (c, o) in out.iter_mut().enumerate() {
                    let mut ch: Vec<f32> = sorted.iter_mut().map(|p| p[c]).collect();
                    ch.sort_by(f32::total_cmp);
                    *o = ch[4];
                }
                Vec3::from(out)
            };
            assert_eq!(median9(&v), want);
        }
    }
}
