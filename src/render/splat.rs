//! A reconstruction filter wider than the pixel, splatted as Mitsuba's film does: each sample,
//! at a uniform position in its pixel, adds its beauty and components times the filter's
//! weight to every pixel whose centre lies within the filter's radius, and the weights too;
//! a pixel's value is the ratio. A tile keeps the splats of one pass over its pixels and the
//! margin around them; after the pass the tiles add theirs to the film one after another in
//! tile order, so the image is the same on any number of threads. Parts split each pixel's
//! samples, so every part splats into the whole image and a merge adds sums and weights.

use glam::{Vec2, Vec3};

use crate::component::Split;
use crate::film::cryptomatte::Coverage;
use crate::film::Sums;
use crate::scene::{PixelFilter, FILTER_STEPS};

/// The filter's values at the steps of its radius (Mitsuba's `eval_discretized`): the weight at
/// offset `x` is `steps[min(floor(|x| / radius * FILTER_STEPS), FILTER_STEPS)]`, 0 at the
/// radius and beyond.
#[derive(Clone, Copy, Debug)]
pub struct Weights {
    radius: f32,
    /// Pixels on either side of a sample's own whose centres it may reach.
    pub margin: u32,
    steps: [f32; FILTER_STEPS + 1],
}

impl Weights {
    pub fn new(filter: PixelFilter) -> Self {
        let radius = filter.radius();
        let steps = std::array::from_fn(|k| filter.step_value(k) as f32);
        let margin = (radius - 0.5).max(0.0).ceil() as u32;
        Weights { radius, margin, steps }
    }

    /// The weight at offset `x` (pixels) along one axis.
    #[inline]
    pub fn at(&self, x: f32) -> f32 {
        let k = (x.abs() / self.radius * FILTER_STEPS as f32) as usize;
        self.steps[k.min(FILTER_STEPS)]
    }
}

/// One tile's splats of a pass: sums over the tile's pixels and a margin around them (clipped
/// to the image), in the film's layout for that rectangle.
#[derive(Clone, Debug)]
pub struct TileSplat {
    x0: u32,
    y0: u32,
    w: u32,
    h: u32,
    beauty: Vec<Vec3>,
    components: Vec<Split<Vec3>>,
    /// Each pixel's AOVs, `naovs` a pixel.
    aovs: Vec<Vec3>,
    naovs: usize,
    /// Each pixel's coverage in each Cryptomatte type, `nmattes` a pixel.
    mattes: Vec<Coverage>,
    nmattes: usize,
    weight: Vec<f32>,
    /// Whether anything was added since the last [`TileSplat::flush`].
    touched: bool,
}

impl TileSplat {
    /// The splats of the tile at (`x0`, `y0`), `w` x `h` pixels, in an image of `width` x
    /// `height`, for `weights`; with the components when `split`, `naovs` AOVs and `nmattes`
    /// Cryptomatte types.
    pub fn new(
        tile: (u32, u32, u32, u32),
        (width, height): (u32, u32),
        weights: &Weights,
        split: bool,
        (naovs, nmattes): (usize, usize),
    ) -> Self {
        let (tx, ty, tw, th) = tile;
        let m = weights.margin;
        let (x0, y0) = (tx.saturating_sub(m), ty.saturating_sub(m));
        let (x1, y1) = ((tx + tw + m).min(width), (ty + th + m).min(height));
        let n = ((x1 - x0) * (y1 - y0)) as usize;
        TileSplat {
            x0,
            y0,
            w: x1 - x0,
            h: y1 - y0,
            beauty: vec![Vec3::ZERO; n],
            components: if split { vec![Split::default(); n] } else { Vec::new() },
            aovs: vec![Vec3::ZERO; n * naovs],
            naovs,
            mattes: vec![Coverage::new(); n * nmattes],
            nmattes,
            weight: vec![0.0; n],
            touched: false,
        }
    }

    /// Splats a sample of pixel `at` at `offset` in it ([0, 1)^2): its beauty and, with the
    /// split, its components and its AOVs.
    #[inline]
    pub fn add(
        &mut self,
        at: (u32, u32),
        offset: Vec2,
        weights: &Weights,
        beauty: Vec3,
        components: Option<&Split<Vec3>>,
        aovs: &[Vec3],
    ) {
        self.touched = true;
        let area = (self.x0, self.y0, self.w, self.h);
        reach(area, at, offset, weights, |i, w| {
            self.beauty[i] += w * beauty;
            self.weight[i] += w;
            if let (Some(sum), Some(c)) = (self.components.get_mut(i), components) {
                for (a, &c) in sum.iter_mut().zip(c.iter()) {
                    *a += w * c;
                }
            }
            if self.naovs > 0 {
                let sum = &mut self.aovs[i * self.naovs..(i + 1) * self.naovs];
                for (a, &v) in sum.iter_mut().zip(aovs) {
                    *a += w * v;
                }
            }
        });
    }

    /// Splats a sample of pixel `at` at `offset` in it into the Cryptomatte coverage: the ids
    /// of what its camera ray hit first (`None`: nothing), with the filter's weights.
    pub fn add_matte(&mut self, at: (u32, u32), offset: Vec2, weights: &Weights, ids: Option<&[u32; 2]>) {
        self.touched = true;
        let area = (self.x0, self.y0, self.w, self.h);
        reach(area, at, offset, weights, |i, w| {
            let mattes = &mut self.mattes[i * self.nmattes..(i + 1) * self.nmattes];
            for (k, c) in mattes.iter_mut().enumerate() {
                match ids {
                    Some(ids) => c.add(ids[k], w),
                    None => c.add_none(w),
                }
            }
        });
    }

    /// Adds the pass's splats to the render's sums and clears them for the next pass.
    pub fn flush(&mut self, sums: &mut Sums) {
        if !self.touched {
            return;
        }
        let width = sums.film.width as usize;
        for row in 0..self.h as usize {
            for col in 0..self.w as usize {
                let i = row * self.w as usize + col;
                let at = (self.y0 as usize + row) * width + self.x0 as usize + col;
                sums.film.raw.pixels[at] += self.beauty[i];
                sums.weights[at] += self.weight[i];
                if let Some(c) = self.components.get(i) {
                    for (layer, &c) in sums.film.components.iter_mut().zip(c.iter()) {
                        layer.pixels[at] += c;
                    }
                }
                let aovs = self.aovs.get(i * self.naovs..(i + 1) * self.naovs).unwrap_or(&[]);
                for (layer, &v) in sums.film.aovs.iter_mut().zip(aovs) {
                    layer.image.pixels[at] += v;
                }
                let mattes = self.mattes.get(i * self.nmattes..(i + 1) * self.nmattes).unwrap_or(&[]);
                for (matte, c) in sums.film.mattes.iter_mut().zip(mattes) {
                    if let Some(m) = matte.coverage_mut() {
                        m[at].merge(c);
                    }
                }
            }
        }
        self.beauty.fill(Vec3::ZERO);
        self.aovs.fill(Vec3::ZERO);
        self.mattes.fill(Coverage::new());
        self.weight.fill(0.0);
        self.components.fill(Split::default());
        self.touched = false;
    }

    pub fn bytes(&self) -> u64 {
        (self.beauty.capacity() * size_of::<Vec3>()
            + self.components.capacity() * size_of::<Split<Vec3>>()
            + self.aovs.capacity() * size_of::<Vec3>()
            + self.mattes.capacity() * size_of::<Coverage>()
            + self.weight.capacity() * size_of::<f32>()) as u64
    }
}

/// Calls `f` with the index in a tile's splats (over `area`: its corner, width and height) and
/// the filter's weight of every pixel that a sample of pixel (`x`, `y`) at `offset` in it
/// reaches with a weight other than 0.
#[inline(always)]
fn reach(
    (x0, y0, width, height): (u32, u32, u32, u32),
    (x, y): (u32, u32),
    offset: Vec2,
    weights: &Weights,
    mut f: impl FnMut(usize, f32),
) {
    let m = weights.margin as i64;
    let (px, py) = (x as f32 + offset.x, y as f32 + offset.y);
    let (lo_x, hi_x) = ((x as i64 - m).max(x0 as i64), (x as i64 + m).min((x0 + width) as i64 - 1));
    let (lo_y, hi_y) = ((y as i64 - m).max(y0 as i64), (y as i64 + m).min((y0 + height) as i64 - 1));
    for qy in lo_y..=hi_y {
        let wy = weights.at(py - (qy as f32 + 0.5));
        if wy == 0.0 {
            continue;
        }
        for qx in lo_x..=hi_x {
            let w = wy * weights.at(px - (qx as f32 + 0.5));
            if w != 0.0 {
                f(((qy - y0 as i64) * width as i64 + (qx - x0 as i64)) as usize, w);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table is the filter's steps: a Gaussian's weight at 0, between steps, and at and
    /// past its radius; the margin is the pixels a sample reaches beyond its own.
    #[test]
    fn weights_are_the_filters_steps() {
        let g = PixelFilter::Gaussian { stddev: 0.5 };
        let w = Weights::new(g);
        assert_eq!(w.margin, 2);
        assert_eq!(w.at(0.0), g.eval(0.0) as f32);
        let step = 2.0 / FILTER_STEPS as f32;
        assert_eq!(w.at(1.5 * step), g.step_value(1) as f32);
        assert!(w.at(1.5 * step) < w.at(0.5 * step), "the second step is lower");
        assert_eq!(w.at(-1.5 * step), w.at(1.5 * step));
        assert_eq!(w.at(2.0), 0.0);
        assert_eq!(w.at(7.0), 0.0);
        assert_eq!(Weights::new(PixelFilter::Tent { radius: 1.0 }).margin, 1);
    }

    /// A splat adds w and w times the sample to the pixels within reach, clipped to the image:
    /// a constant image stays constant (each pixel's sums over its weights), and a sample in a
    /// corner pixel reaches only pixels inside.
    #[test]
    fn splats_sum_weights_and_clip_at_the_edges() {
        let weights = Weights::new(PixelFilter::Tent { radius: 1.5 });
        let (width, height) = (6u32, 5u32);
        let mut sums = Sums::empty(width, height, false, false, true);
        let mut tile = TileSplat::new((0, 0, 4, 4), (width, height), &weights, false, (0, 0));
        for y in 0..4 {
            for x in 0..4 {
                tile.add((x, y), Vec2::new(0.3, 0.7), &weights, Vec3::splat(2.0), None, &[]);
            }
        }
        tile.flush(&mut sums);
        for (p, &w) in sums.film.raw.pixels.iter().zip(&sums.weights) {
            assert!((p.x - 2.0 * w).abs() < 1e-5, "{p} {w}");
        }
        // Pixel (5, 4) is beyond every splat of the tile's pixels but (3, 3)'s reach of 2.
        assert_eq!(sums.weights[(4 * width + 5) as usize], 0.0);
        assert!(sums.weights[(4 * width + 4) as usize] > 0.0);
    }
}
