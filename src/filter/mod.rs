//! The paper's noise-reduction filters (section 3): box3 (filter A), weighted3 (B), median3 (C),
//! box5 and any odd square kernel. Weights are divided by the sum of the weights actually used,
//! borders replicate the edge pixels, and in edge-aware mode (the paper's closing suggestion) a
//! neighbour counts only if it shows the same object as the centre, optionally also a similar
//! normal and depth. Linear in the pixel count and parallel over rows.

use glam::Vec3;
use rayon::prelude::*;

use crate::film::{Film, Image};

/// A filter kernel.
#[derive(Clone, Debug, PartialEq)]
pub enum Kernel {
    /// Weighted average over a `size` x `size` window (row-major weights).
    Convolution { size: usize, weights: Vec<f32> },
    /// Per-channel median over a 3x3 window (the paper's filter C).
    Median3,
}

impl Kernel {
    /// A kernel by name: `box3`, `weighted3`, `median3`, `box5`, or a custom odd square kernel
    /// written as comma-separated weights (`1,2,1,2,4,2,1,2,1`).
    pub fn parse(name: &str) -> Result<Kernel, String> {
        match name {
            "box3" => Ok(Kernel::Convolution { size: 3, weights: vec![1.0; 9] }),
            "weighted3" => {
                Ok(Kernel::Convolution { size: 3, weights: vec![1., 2., 1., 2., 4., 2., 1., 2., 1.] })
            }
            "box5" => Ok(Kernel::Convolution { size: 5, weights: vec![1.0; 25] }),
            "median3" => Ok(Kernel::Median3),
            custom => {
                let weights: Result<Vec<f32>, _> =
                    custom.split(',').map(|w| w.trim().parse::<f32>()).collect();
                let weights = weights.map_err(|_| {
                    format!("unknown filter `{custom}` (box3, weighted3, median3, box5, or comma-separated weights)")
                })?;
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
                Ok(Kernel::Convolution { size, weights })
            }
        }
    }
}

/// What the filter is applied to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Target {
    /// Only L_r,d,d, then added back (the paper's method).
    Indirect,
    /// The whole image (the paper's Figure 3(c) baseline).
    Image,
    /// Nothing.
    None,
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
}

impl EdgeStops {
    fn any(&self) -> bool {
        self.object || self.normal_degrees.is_some() || self.depth_relative.is_some()
    }
}

/// Filters `image`; with `stops`, neighbours are tested against the guide buffers of `film`.
pub fn filter(image: &Image, kernel: &Kernel, film: &Film, stops: &EdgeStops) -> Image {
    let (w, h) = (image.width as i64, image.height as i64);
    let radius = match kernel {
        Kernel::Convolution { size, .. } => (*size / 2) as i64,
        Kernel::Median3 => 1,
    };
    let cos_min = stops.normal_degrees.map(|d| d.to_radians().cos());
    let edge_aware = stops.any();
    let same_surface = |c: usize, n: usize| -> bool {
        if !edge_aware {
            return true;
        }
        if stops.object && film.object[c] != film.object[n] {
            return false;
        }
        if let Some(cos_min) = cos_min {
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
    };
    let mut out = Image::new(image.width, image.height);
    out.pixels.par_chunks_mut(image.width as usize).enumerate().for_each(|(y, row)| {
        let y = y as i64;
        // Borders replicate the edge pixels: clamped rows once per row, clamped columns only
        // near the left and right edges.
        let row_starts: Vec<usize> =
            (-radius..=radius).map(|dy| ((y + dy).clamp(0, h - 1) * w) as usize).collect();
        let mut window: Vec<Vec3> = Vec::with_capacity(((2 * radius + 1) * (2 * radius + 1)) as usize);
        for (x, px) in row.iter_mut().enumerate() {
            let x = x as i64;
            let centre = (y * w + x) as usize;
            let interior = x >= radius && x < w - radius;
            let column =
                |dx: i64| if interior { (x + dx) as usize } else { (x + dx).clamp(0, w - 1) as usize };
            *px = match kernel {
                Kernel::Convolution { weights, .. } => {
                    let (mut acc, mut weight_sum, mut k) = (Vec3::ZERO, 0.0f32, 0);
                    for &start in &row_starts {
                        for dx in -radius..=radius {
                            let n = start + column(dx);
                            let weight = weights[k];
                            k += 1;
                            if same_surface(centre, n) {
                                acc += image.pixels[n] * weight;
                                weight_sum += weight;
                            }
                        }
                    }
                    // Divided by the weights actually used, so energy is kept at edges.
                    if weight_sum > 0.0 {
                        acc / weight_sum
                    } else {
                        image.pixels[centre]
                    }
                }
                Kernel::Median3 => {
                    window.clear();
                    for &start in &row_starts {
                        for dx in -radius..=radius {
                            let n = start + column(dx);
                            if same_surface(centre, n) {
                                window.push(image.pixels[n]);
                            }
                        }
                    }
                    median(&mut window)
                }
            };
        }
    });
    out
}

/// The median of nine values by Paeth's 19-exchange network ("Median Finding on a 3x3 Grid",
/// Graphics Gems, 1990, the paper's reference [Paet90]), on all three channels at once.
fn median9(v: &[Vec3]) -> Vec3 {
    let mut p: [Vec3; 9] = [v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]];
    let mut s = |a: usize, b: usize| {
        let (lo, hi) = (p[a].min(p[b]), p[a].max(p[b]));
        p[a] = lo;
        p[b] = hi;
    };
    s(1, 2);
    s(4, 5);
    s(7, 8);
    s(0, 1);
    s(3, 4);
    s(6, 7);
    s(1, 2);
    s(4, 5);
    s(7, 8);
    s(0, 3);
    s(5, 8);
    s(4, 7);
    s(3, 6);
    s(1, 4);
    s(2, 5);
    s(4, 7);
    s(4, 2);
    s(6, 4);
    s(4, 2);
    p[4]
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

/// The final image of a film: the components with `kernel` applied to `target`.
pub fn composite(
    film: &Film,
    kernel: Option<&Kernel>,
    target: Target,
    stops: &EdgeStops,
) -> (Image, Option<Image>) {
    match (kernel, target) {
        (Some(k), Target::Indirect) => {
            let filtered = filter(film.indirect(), k, film, stops);
            let mut out = Image::new(film.width, film.height);
            for (i, px) in out.pixels.iter_mut().enumerate() {
                let [e, d, c, _] = film.components.each_ref().map(|l| l.pixels[i]);
                *px = e + d + c + filtered.pixels[i];
            }
            (out, Some(filtered))
        }
        (Some(k), Target::Image) => (filter(&film.raw, k, film, stops), None),
        _ => (film.raw.clone(), None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn film_of(image: &Image) -> Film {
        let mut f = Film::new(image.width, image.height);
        f.object.iter_mut().for_each(|o| *o = 0.0);
        f
    }

    fn kernels() -> Vec<Kernel> {
        ["box3", "weighted3", "median3", "box5", "1,1,1,1,9,1,1,1,1"]
            .iter()
            .map(|k| Kernel::parse(k).expect("kernel"))
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
            filter(&img, &Kernel::parse("weighted3").expect("k"), &film_of(&img), &EdgeStops::default());
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
        let out = filter(&img, &Kernel::Median3, &film_of(&img), &EdgeStops::default());
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
        let out = filter(&img, &Kernel::parse("box3").expect("k"), &film_of(&img), &EdgeStops::default());
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
            if k != Kernel::Median3 {
                let blurred = filter(&img, &k, &film, &EdgeStops::default());
                assert_ne!(blurred, img, "{k:?}: without stops the step must blur");
            }
        }
    }

    #[test]
    fn bad_kernels_are_errors() {
        assert!(Kernel::parse("gauss").is_err());
        assert!(Kernel::parse("1,2,3,4").is_err());
        assert!(Kernel::parse("0,0,0,0,0,0,0,0,0").is_err());
        assert!(Kernel::parse("1,1,1,1,-1,1,1,1,1").is_err());
        assert_eq!(Kernel::parse("1").expect("1x1"), Kernel::Convolution { size: 1, weights: vec![1.0] });
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
