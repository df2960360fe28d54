//! The à-trous filter checked against the render's own noise: each layer is filtered three
//! times, whole and each half of its samples on its own ([`crate::film::half_of`]), and each
//! half's filtered image is compared with the other half's unfiltered one. That measures the
//! filtered image's error (its bias and the noise it leaves) against the unfiltered image's
//! noise, and the filtered image is kept only where it wins, down to not at all.
//!
//! Per pixel, with `A` and `B` the halves' means, `s` the second half's share of the samples,
//! `F_A`, `F_B` and `F` the filtered halves and whole, and squares summed over the channels:
//! - the unfiltered image's error is its variance, `e_U = |A - B|² s (1 - s)` (the variance
//!   of a mean of independent samples; [`crate::film::variance_of_halves`] for the luminance);
//! - each filtered half's error against the truth is its distance from the other half less
//!   that half's variance: `e_A = |F_A - B|² - |A - B|² (1 - s)`, `e_B = |F_B - A|² - |A - B|² s`;
//! - their noise is what `F_A` and `F_B` disagree by, `D = |F_A - F_B|²`, of which the whole
//!   keeps `D s (1 - s)`, so `e_F = (e_A - D s + e_B - D (1 - s)) / 2 + D s (1 - s)`.
//!
//! Single pixels' estimates are noise, so both are summed over a window (`2 RADIUS + 1`
//! pixels square) and the filtered image's weight is `w = clamp(2 (1 - Σe_F / Σe_U), 0, 1)`:
//! all of it where filtering halves the error or better, none where it does not lower it, and
//! the output is `U + w (F - U)`. Pixels whose halves are not both sampled (adaptive sampling
//! stopped them before the second half) count in no sum, and a window of only such pixels
//! keeps the unfiltered image. A window of checked pixels without measured noise keeps the
//! filtered image (the filter changes nothing there that noise would call for). Measured on four Khronos models and the denoising scenes in
//! docs/RESULTS.md ("Denoising third-party models").

use glam::Vec3;

use crate::film::Image;

/// The window's half-width: 15x15 pixels (of 9 and 15, and of four weightings, the one never
/// above the unfiltered error on the four models; docs/RESULTS.md).
pub const RADIUS: usize = 7;

/// A layer's two halves' means from its mean `u`, its second half's share of the mean `half`
/// (its sum over the second half's samples, divided by all the samples) and that half's share
/// of the samples `share`: `(A, B)`. A pixel whose halves are not both sampled gets its mean
/// in both.
pub fn halves(u: &Image, half: &Image, share: &[f32]) -> (Image, Image) {
    let (mut a, mut b) = (u.clone(), u.clone());
    for (((a, b), &h), &s) in a.pixels.iter_mut().zip(&mut b.pixels).zip(&half.pixels).zip(share) {
        if s > 0.0 && s < 1.0 {
            *b = h / s;
            *a = (*a - h) / (1.0 - s);
        }
    }
    (a, b)
}

/// The estimated errors `(e_U, e_F)` of a pixel (module docs), from the halves `a`, `b`, their
/// filtered `fa`, `fb` and the second half's share `s`; none when a half has no samples.
fn errors(a: Vec3, b: Vec3, fa: Vec3, fb: Vec3, s: f32) -> Option<(f64, f64)> {
    if !(s > 0.0 && s < 1.0) {
        return None;
    }
    let sq = |v: Vec3| v.as_dvec3().length_squared();
    let s = s as f64;
    let ab = sq(a - b);
    let d = sq(fa - fb);
    let e_a = sq(fa - b) - ab * (1.0 - s);
    let e_b = sq(fb - a) - ab * s;
    let e_f = (e_a - d * s + e_b - d * (1.0 - s)) / 2.0 + d * s * (1.0 - s);
    let e_u = ab * s * (1.0 - s);
    (e_u.is_finite() && e_f.is_finite()).then_some((e_u, e_f))
}

/// Sums of `v` (row-major, `w` by `h`) over the window around each pixel, clipped at the
/// borders: a sum along each row, then along each column, each of the window's own pixels (no
/// running sums, whose rounding would carry one bright pixel's error across the image).
fn window_sums(v: &[f64], w: usize, h: usize) -> Vec<f64> {
    let mut rows = vec![0.0; w * h];
    for y in 0..h {
        let row = &v[y * w..(y + 1) * w];
        for x in 0..w {
            rows[y * w + x] = row[x.saturating_sub(RADIUS)..(x + RADIUS + 1).min(w)].iter().sum();
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for yy in y.saturating_sub(RADIUS)..(y + RADIUS + 1).min(h) {
            let (o, r) = (&mut out[y * w..(y + 1) * w], &rows[yy * w..(yy + 1) * w]);
            o.iter_mut().zip(r).for_each(|(o, r)| *o += r);
        }
    }
    out
}

/// The filtered layer `f` kept where the halves say it beats the unfiltered `u` (module docs):
/// `u + w (f - u)` per pixel, from the halves `a`, `b`, their filtered images `fa`, `fb` and
/// the second half's share of the samples `share`.
pub fn blend(
    u: &Image,
    f: &Image,
    (a, b): (&Image, &Image),
    (fa, fb): (&Image, &Image),
    share: &[f32],
) -> Image {
    let weights = weights(u.width as usize, u.height as usize, (a, b), (fa, fb), share);
    let mut out = u.clone();
    for ((o, &f), &w) in out.pixels.iter_mut().zip(&f.pixels).zip(&weights) {
        *o += w * (f - *o);
    }
    out
}

/// Each pixel's weight of the filtered image ([`blend`]): 0 in a window without a pixel of two
/// sampled halves (adaptive sampling stopped them early: the check cannot speak there, and the
/// pixels it stopped were the clean ones).
fn weights(
    w: usize,
    h: usize,
    (a, b): (&Image, &Image),
    (fa, fb): (&Image, &Image),
    share: &[f32],
) -> Vec<f32> {
    let n = w * h;
    let (mut e_u, mut e_f, mut checked) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for i in 0..n {
        if let Some((u, f)) = errors(a.pixels[i], b.pixels[i], fa.pixels[i], fb.pixels[i], share[i]) {
            (e_u[i], e_f[i], checked[i]) = (u, f, 1.0);
        }
    }
    let (e_u, e_f, checked) = (window_sums(&e_u, w, h), window_sums(&e_f, w, h), window_sums(&checked, w, h));
    e_u.iter()
        .zip(&e_f)
        .zip(&checked)
        .map(|((&u, &f), &c)| match (c > 0.0, u > 0.0) {
            (false, _) => 0.0,
            (true, true) => (2.0 * (1.0 - f / u)).clamp(0.0, 1.0) as f32,
            (true, false) => 1.0,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(usize) -> Vec3) -> Image {
        Image { width: w, height: h, pixels: (0..(w * h) as usize).map(f).collect() }
    }

    /// A small generator for noise.
    fn noise(i: usize, seed: u64) -> f32 {
        let mut z = (i as u64).wrapping_add(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    }

    #[test]
    fn halves_come_back_from_the_mean_and_the_second_halfs_share() {
        let (a, b) = (Vec3::new(1.0, 2.0, 3.0), Vec3::new(5.0, 0.0, 1.0));
        // 3 samples in the first half, 1 in the second: the mean is (3a + b) / 4.
        let u = image(2, 1, |_| (3.0 * a + b) / 4.0);
        let half = image(2, 1, |_| b / 4.0);
        let (ha, hb) = halves(&u, &half, &[0.25, 0.0]);
        assert!(ha.pixels[0].abs_diff_eq(a, 1e-5) && hb.pixels[0].abs_diff_eq(b, 1e-5));
        // No second half: the mean in both.
        assert_eq!((ha.pixels[1], hb.pixels[1]), (u.pixels[1], u.pixels[1]));
    }

    #[test]
    fn a_filter_that_removes_noise_is_kept_and_one_that_adds_error_is_not() {
        let (w, h) = (32u32, 32u32);
        let truth = |i: usize| Vec3::splat(1.0 + 0.5 * ((i % 32) as f32 / 31.0));
        // Halves of equal size, each the truth plus independent noise.
        let a = image(w, h, |i| truth(i) + Vec3::splat(noise(i, 1)));
        let b = image(w, h, |i| truth(i) + Vec3::splat(noise(i, 2)));
        let u = image(w, h, |i| (a.pixels[i] + b.pixels[i]) / 2.0);
        let share = vec![0.5; (w * h) as usize];
        // A perfect filter: the truth, from either half.
        let t = image(w, h, truth);
        let kept = blend(&u, &t, (&a, &b), (&t, &t), &share);
        assert_eq!(kept, t, "a filter that removes all the noise is kept whole");
        // A filter that returns a constant far from the truth (all bias).
        let off = image(w, h, |_| Vec3::splat(3.0));
        assert_eq!(blend(&u, &off, (&a, &b), (&off, &off), &share), u, "all bias: not kept");
        // Without measured noise (equal halves), the filtered image is kept.
        let same = blend(&t, &off, (&t, &t), (&off, &off), &share);
        assert_eq!(same, off);
        // Without a pixel of two sampled halves the check cannot speak: the unfiltered image.
        let none = vec![0.0; share.len()];
        assert_eq!(blend(&u, &t, (&a, &b), (&t, &t), &none), u);
    }

    #[test]
    fn window_sums_equal_a_direct_sum() {
        let (w, h) = (23usize, 17usize);
        let v: Vec<f64> = (0..w * h).map(|i| noise(i, 3) as f64).collect();
        let sums = window_sums(&v, w, h);
        for (x, y) in [(0usize, 0usize), (5, 9), (22, 16), (11, 3)] {
            let mut want = 0.0;
            for yy in y.saturating_sub(RADIUS)..(y + RADIUS + 1).min(h) {
                for xx in x.saturating_sub(RADIUS)..(x + RADIUS + 1).min(w) {
                    want += v[yy * w + xx];
                }
            }
            assert!((sums[y * w + x] - want).abs() < 1e-9, "({x}, {y})");
        }
    }
}
