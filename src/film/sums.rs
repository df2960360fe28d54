//! A render's per-pixel sums while it accumulates ([`Sums`]): what a part or checkpoint file
//! keeps, what a merge adds up, and what becomes a [`Film`] of means at the end.

use glam::Vec3;

use super::layers::{self, Buffer, Mean};
use super::{variance_of_halves, variance_of_mean, Film, Image};
use crate::component::{Component, Split};

/// A render's per-pixel sums, what a part or checkpoint file keeps: [`Sums::add`] merges
/// parts exactly (in float, up to summation order), and a render resumes from it.
#[derive(Clone, Debug, PartialEq)]
pub struct Sums {
    /// The film in sums: the beauty, the components, the albedo, the normal (not normalised)
    /// and the depth summed over the samples; `object` the object of each pixel's sample 0
    /// (-1 for none), `coverage` how many samples saw it, `alpha` how many hit a surface. Its
    /// variance layers are empty: the sums of squares they come from are [`Sums::squares`].
    pub film: Film,
    /// The sums of the squared sample luminances, with the split (empty without).
    pub squares: Squares,
    /// The samples each pixel has taken.
    pub samples: Vec<u32>,
    /// With a reconstruction filter wider than the pixel (splatted, as Mitsuba's film does):
    /// each pixel's sum of the filter weights of the samples around it, by which its beauty
    /// and components (then sums of weighted samples) are divided. Empty otherwise: the beauty
    /// is the sum of the pixel's own samples, divided by their count.
    pub weights: Vec<f32>,
}

/// Each pixel's sum of its squared sample luminances, of the beauty and of each component, from
/// which [`Sums::into_means`] estimates the variance of the mean. Kept in f64 from the
/// first sample to the part file: a finite 32-bit sample's square overflows 32 bits from about
/// 1.8e19 (a point light of 1e30 made whole variance layers infinite), and f64 holds the square
/// of any finite 32-bit value, summed over any spp.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Squares {
    /// Of the beauty.
    pub beauty: Vec<f64>,
    /// Of each component.
    pub components: Split<Vec<f64>>,
}

impl Squares {
    /// `n` zeros in each, or nothing at all.
    fn zeros(n: usize, on: bool) -> Squares {
        let n = if on { n } else { 0 };
        Squares { beauty: vec![0.0; n], components: Split::from_fn(|_| vec![0.0; n]) }
    }

    /// Whether there are any (a render with the split).
    pub fn is_empty(&self) -> bool {
        self.beauty.is_empty()
    }

    /// The sums of the beauty, then of each component.
    pub fn layers(&self) -> impl Iterator<Item = &Vec<f64>> {
        std::iter::once(&self.beauty).chain(self.components.iter())
    }

    fn layers_mut(&mut self) -> impl Iterator<Item = &mut Vec<f64>> {
        std::iter::once(&mut self.beauty).chain(self.components.iter_mut())
    }

    /// Bytes of their buffers.
    fn bytes(&self) -> u64 {
        self.layers().map(|l| (l.capacity() * size_of::<f64>()) as u64).sum()
    }
}

impl Sums {
    /// The fewest and the most samples a pixel took ((0, 0) for no pixels).
    pub fn spp_range(&self) -> (u32, u32) {
        let (lo, hi) = (self.samples.iter().copied().min(), self.samples.iter().copied().max());
        (lo.unwrap_or(0), hi.unwrap_or(0))
    }

    /// Nothing yet: `film`'s buffers zeroed (the object unknown); with weights when `splat`.
    pub fn empty(width: u32, height: u32, split: bool, guides: bool, splat: bool) -> Sums {
        let mut film = Film::with_buffers(width, height, split, guides);
        for layer in &layers::LAYERS {
            match (layer.mean, layer.rule) {
                // The variances come of the squares, at the end.
                (Mean::FromSquares, _) => film.set_values(layer.buffer, Vec::new()),
                // Counts of samples: none yet.
                (_, layers::Rule::Count) => film.values_mut(layer.buffer).fill(0.0),
                _ => {}
            }
        }
        if splat {
            // The halves are of each pixel's own samples, and a splatted beauty is not.
            for layer in layers::LAYERS.iter().filter(|l| l.group == layers::Group::Halves) {
                film.set_values(layer.buffer, Vec::new());
            }
        }
        let n = width as usize * height as usize;
        let weights = if splat { vec![0.0; n] } else { Vec::new() };
        Sums { film, squares: Squares::zeros(n, split), samples: vec![0; n], weights }
    }

    /// Bytes of its buffers.
    pub fn bytes(&self) -> u64 {
        self.film.bytes()
            + self.squares.bytes()
            + (self.samples.capacity() * size_of::<u32>()) as u64
            + (self.weights.capacity() * size_of::<f32>()) as u64
    }

    /// The film of means, with each pixel's variance of the mean from the sums of squares (at
    /// most the largest 32-bit float: a spread too wide for 32 bits is written as that, finite).
    /// Each layer's sums become values as its row says ([`layers::Mean`]).
    pub fn into_means(self) -> Film {
        let Sums { mut film, squares, samples, weights } = self;
        if !squares.is_empty() {
            // From the sums, before they become means: from the two halves where the film
            // has them and both halves have samples, else from the sums of squares.
            let variance = |n: u32, sum: Vec3, sum_sq: f64, half: Option<(f32, Vec3)>| {
                let lum = |v: Vec3| crate::math::luminance(v) as f64;
                let v = half
                    .and_then(|(n_b, b)| variance_of_halves(n, n_b.round() as u32, lum(sum), lum(b)))
                    .unwrap_or_else(|| variance_of_mean(n, lum(sum), sum_sq));
                v.min(f32::MAX as f64) as f32
            };
            let of = |sums: &Image, squares: &[f64], half: &Image| -> Vec<f32> {
                samples
                    .iter()
                    .zip(&sums.pixels)
                    .zip(squares)
                    .enumerate()
                    .map(|(i, ((&n, &s), &q))| {
                        let h = half.pixels.get(i).zip(film.half_share.get(i)).map(|(&b, &n_b)| (n_b, b));
                        variance(n, s, q, h)
                    })
                    .collect()
            };
            film.variance = of(&film.raw, &squares.beauty, &film.half);
            for c in Component::ALL {
                film.component_variance[c] =
                    of(&film.components[c], &squares.components[c], &film.component_half[c]);
            }
        }
        let inv: Vec<f32> = samples.iter().map(|&n| if n > 0 { 1.0 / n as f32 } else { 0.0 }).collect();
        let inv_weight: Vec<f32> = weights.iter().map(|&w| if w > 0.0 { 1.0 / w } else { 0.0 }).collect();
        for layer in &layers::LAYERS {
            let width = layer.width();
            let splatted = matches!(layer.buffer, Buffer::Raw | Buffer::Component(_)) && !weights.is_empty();
            let values = film.values_mut(layer.buffer);
            match layer.mean {
                Mean::Average => {
                    let inv = if splatted { &inv_weight } else { &inv };
                    for (pixel, &inv) in values.chunks_exact_mut(width).zip(inv) {
                        pixel.iter_mut().for_each(|v| *v *= inv);
                    }
                }
                Mean::Normalise => {
                    for pixel in values.chunks_exact_mut(width) {
                        pixel.copy_from_slice(&Vec3::from_slice(pixel).normalize_or_zero().to_array());
                    }
                }
                Mean::First | Mean::FromSquares => {}
            }
        }
        // The AOVs are light, as the components: splatted with them.
        let inv = if weights.is_empty() { &inv } else { &inv_weight };
        for aov in &mut film.aovs {
            aov.image.pixels.iter_mut().zip(inv).for_each(|(p, &inv)| *p *= inv);
        }
        film
    }

    /// Adds the samples of `other`, a render of other samples of the same pixels (another part):
    /// every sum adds, sample counts too. The object of sample 0 is the same in both wherever
    /// both have samples (a pixel's sample 0 is traced by every part); where they disagree the
    /// parts are not of one render.
    pub fn add(&mut self, other: &Sums) -> Result<(), String> {
        let (a, b) = (&mut self.film, &other.film);
        if (a.width, a.height) != (b.width, b.height) {
            return Err(format!("{}x{} against {}x{}", b.width, b.height, a.width, a.height));
        }
        if (a.has_split(), a.has_guides()) != (b.has_split(), b.has_guides())
            || self.squares.is_empty() != other.squares.is_empty()
        {
            return Err("one has the component split or the guide buffers and the other not".into());
        }
        if a.has_halves() != b.has_halves() {
            // A part written before the halves existed: the sum has none (its variance comes
            // of the squares, and the filter runs unchecked).
            for layer in layers::LAYERS.iter().filter(|l| l.group == layers::Group::Halves) {
                a.set_values(layer.buffer, Vec::new());
            }
        }
        if self.weights.is_empty() != other.weights.is_empty() {
            return Err("one has splatted filter weights and the other not".into());
        }
        if super::aov_list(&a.aovs) != super::aov_list(&b.aovs) {
            return Err(format!(
                "one has the AOVs [{}] and the other [{}]",
                super::aov_list(&a.aovs),
                super::aov_list(&b.aovs)
            ));
        }
        for (x, y) in a.aovs.iter_mut().zip(&b.aovs) {
            x.image.pixels.iter_mut().zip(&y.image.pixels).for_each(|(p, q)| *p += *q);
        }
        let kinds = |f: &Film| f.mattes.iter().map(|m| m.kind.as_str()).collect::<Vec<_>>().join(",");
        if kinds(a) != kinds(b) {
            return Err(format!("one has the Cryptomatte types [{}] and the other [{}]", kinds(a), kinds(b)));
        }
        for (x, y) in a.mattes.iter_mut().zip(&b.mattes) {
            if x.manifest != y.manifest {
                return Err(format!("their `{}` manifests differ (not of one scene)", x.kind));
            }
            match (x.coverage_mut(), y.coverage()) {
                (Some(x), Some(y)) => x.iter_mut().zip(y).for_each(|(p, q)| p.merge(q)),
                _ => return Err("a Cryptomatte read from an image cannot be summed".into()),
            }
        }
        let width = a.width;
        for layer in &layers::LAYERS {
            let (x, y) = (a.values_mut(layer.buffer), b.values(layer.buffer));
            match layer.mean {
                Mean::Average | Mean::Normalise => x.iter_mut().zip(y).for_each(|(p, q)| *p += *q),
                Mean::First => {
                    for (i, (&o, &n)) in y.iter().zip(&other.samples).enumerate() {
                        if n == 0 {
                            continue;
                        }
                        if self.samples[i] > 0 && x[i] != o {
                            let (px, py) = (i as u32 % width, i as u32 / width);
                            return Err(format!(
                                "pixel ({px}, {py}) shows object {o} in one and {} in the other",
                                x[i]
                            ));
                        }
                        x[i] = o;
                    }
                }
                Mean::FromSquares => {}
            }
        }
        for (x, y) in self.squares.layers_mut().zip(other.squares.layers()) {
            x.iter_mut().zip(y).for_each(|(p, q)| *p += *q);
        }
        for (n, m) in self.samples.iter_mut().zip(&other.samples) {
            *n += m;
        }
        for (w, v) in self.weights.iter_mut().zip(&other.weights) {
            *w += v;
        }
        Ok(())
    }
}
