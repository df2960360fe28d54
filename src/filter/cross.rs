//! The à-trous filter checked against the render's own noise: each half of a layer's samples
//! ([`crate::film::half_of`]) is filtered on its own, and each half's filtered image is compared
//! with the other half's unfiltered one. That measures the filtered image's error (its bias and
//! the noise it leaves) against the unfiltered image's noise, and the filtered image is kept
//! only where it wins, down to not at all. The filtered image is the filtered halves weighted by
//! their shares of the samples, `F = (1 - s) F_A + s F_B`: two runs of the filter, not three.
//! Each half's colour stop compares the centre with its taps' luminance in the other half
//! (`FilterInput::stops_from`): a tap's weight then does not depend on the value it adds, so
//! the mean is not pulled toward the common side of skewed noise, and the filtered half at a
//! pixel stays independent of the other half there, which the estimates below assume.
//!
//! Per pixel, with `A` and `B` the halves' means, `s` the second half's share of the samples,
//! `F_A`, `F_B` the filtered halves, and squares summed over the channels:
//! - the unfiltered image's error is its variance, `e_U = |A - B|² s (1 - s)` (the variance
//!   of a mean of independent samples; [`crate::film::variance_of_halves`] for the luminance);
//! - each filtered half's error against the truth is its distance from the other half less
//!   that half's variance: `e_A = |F_A - B|² - |A - B|² (1 - s)`, `e_B = |F_B - A|² - |A - B|² s`;
//! - their noise is what `F_A` and `F_B` disagree by, `D = |F_A - F_B|²`, of which the mix `F`
//!   keeps `D s (1 - s)` (each half's noise variance is inversely proportional to its share),
//!   so `e_F = (e_A - D s + e_B - D (1 - s)) / 2 + D s (1 - s)`: both brackets are the bias.
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
use rayon::prelude::*;

use super::pool::{Pixels, Plane};

/// The window's half-width: 15x15 pixels (of 9 and 15, and of four weightings, the one never
/// above the unfiltered error on the four models; docs/RESULTS.md).
pub const RADIUS: usize = 7;

/// A layer's two halves' means from its mean `u`, its second half's share of the mean `half`
/// (its sum over the second half's samples, divided by all the samples) and that half's share
/// of the samples `share`: `(A, B)`. A pixel whose halves are not both sampled gets its mean
/// in both.
pub fn halves(u: &[Vec3], half: &[Vec3], share: &[f32]) -> (Pixels, Pixels) {
    // Both written in one parallel step (not two copies of the mean made first, one thread's
    // copying while the other waited).
    let (mut a, mut b) = (Pixels::overwritten(u.len()), Pixels::overwritten(u.len()));
    a.par_iter_mut().zip(b.par_iter_mut()).zip(u).zip(half).zip(share).for_each(
        |((((a, b), &u), &h), &s)| {
            (*a, *b) = if s > 0.0 && s < 1.0 { ((u - h) / (1.0 - s), h / s) } else { (u, u) };
        },
    );
    (a, b)
}

/// The estimated errors `(e_U, e_F)` of a pixel (module docs), from the halves `a`, `b`, their
/// filtered `fa`, `fb` and the second half's share `s`; none when a half has no samples or an
/// error is not finite. In f32: the same loop in f64 took twice as long (the window's sums
/// are of these, in f32 too: [`window_sums`]).
#[inline(always)]
fn errors(a: Vec3, b: Vec3, fa: Vec3, fb: Vec3, s: f32) -> Option<(f32, f32)> {
    let sq = |v: Vec3| v.length_squared();
    let ab = sq(a - b);
    let d = sq(fa - fb);
    let e_a = sq(fa - b) - ab * (1.0 - s);
    let e_b = sq(fb - a) - ab * s;
    let e_f = (e_a - d * s + e_b - d * (1.0 - s)) / 2.0 + d * s * (1.0 - s);
    let e_u = ab * s * (1.0 - s);
    (s > 0.0 && s < 1.0 && e_u.is_finite() && e_f.is_finite()).then_some((e_u, e_f))
}

/// Sums of each plane of `v` (row-major, `w` by `h`) over the window around each pixel,
/// clipped at the borders, handed row by row to `row(sums, out)` with the row of `out`, in f32.
///
/// Each window is summed from its own pixels only (no running sums, whose subtraction would
/// carry one bright pixel's rounding across the image), with three additions a pixel and a
/// direction instead of the window's fifteen (van Herk's split): along a line cut into blocks
/// of the window's length, a window is the suffix of one block plus the prefix of the next,
/// and every block's suffix and prefix sums come from one pass each. Rows are taken in bands of
/// one block, in parallel, each band with its own scratch.
fn window_sums<const N: usize>(
    v: [&[f32]; N],
    w: usize,
    h: usize,
    out: &mut [f32],
    row: impl Fn([&[f32]; N], &mut [f32]) + Sync,
) {
    const L: usize = 2 * RADIUS + 1;
    if w == 0 {
        return;
    }
    // In padded coordinates (RADIUS zeros before the image), the window of output row y is
    // rows y..y + L, block y / L's suffix from y and block y / L + 1's prefix to y + L - 1.
    let plane_row =
        |k: usize, p: usize| (p >= RADIUS && p - RADIUS < h).then(|| &v[k][(p - RADIUS) * w..][..w]);
    out.par_chunks_mut(L * w).enumerate().for_each_init(
        || (vec![0.0f32; L * N * w], vec![0.0f32; L * N * w], Line::new(N, w)),
        |(suffix, prefix, line), (band, rows)| {
            let (first, n) = (band * L, rows.len() / w);
            let at = |i: usize, k: usize| (i * N + k) * w;
            // Suffixes of block `band`, from its last row up; prefixes of the next block.
            for i in (0..L).rev() {
                let (this, next) = suffix.split_at_mut(at(i + 1, 0));
                for k in 0..N {
                    let before = (i + 1 < L).then(|| &next[k * w..(k + 1) * w]);
                    add_row(&mut this[at(i, k)..at(i, k) + w], before, plane_row(k, first + i));
                }
            }
            for i in 0..n.saturating_sub(1) {
                let (before, this) = prefix.split_at_mut(at(i, 0));
                for k in 0..N {
                    let before = i.checked_sub(1).map(|j| &before[at(j, k)..at(j, k) + w]);
                    add_row(&mut this[k * w..(k + 1) * w], before, plane_row(k, first + L + i));
                }
            }
            for (t, o) in rows.chunks_mut(w).enumerate() {
                for k in 0..N {
                    let column = line.column(k);
                    column.copy_from_slice(&suffix[at(t, k)..at(t, k) + w]);
                    if t > 0 {
                        column.iter_mut().zip(&prefix[at(t - 1, k)..]).for_each(|(c, &p)| *c += p);
                    }
                }
                line.sum();
                row(std::array::from_fn(|k| &line.sums[k * w..(k + 1) * w]), o);
            }
        },
    );
}

/// `out = before + row`, either absent counting as zeros.
fn add_row(out: &mut [f32], before: Option<&[f32]>, row: Option<&[f32]>) {
    match (before, row) {
        (Some(b), Some(r)) => out.iter_mut().zip(b).zip(r).for_each(|((o, &b), &r)| *o = b + r),
        (Some(b), None) => out.copy_from_slice(b),
        (None, Some(r)) => out.copy_from_slice(r),
        (None, None) => out.fill(0.0),
    }
}

/// One output row's scratch in [`window_sums`]: the window's columns summed down (each plane
/// with RADIUS zeros either side), and their sums along the row.
struct Line {
    n: usize,
    w: usize,
    columns: Vec<f32>,
    suffix: Vec<f32>,
    prefix: Vec<f32>,
    sums: Vec<f32>,
}

impl Line {
    fn new(n: usize, w: usize) -> Line {
        let padded = w + 2 * RADIUS;
        Line {
            n,
            w,
            columns: vec![0.0; n * padded],
            suffix: vec![0.0; padded + 1],
            prefix: vec![0.0; padded],
            sums: vec![0.0; n * w],
        }
    }

    /// Plane `k`'s columns, without the zeros either side.
    fn column(&mut self, k: usize) -> &mut [f32] {
        let padded = self.w + 2 * RADIUS;
        &mut self.columns[k * padded + RADIUS..][..self.w]
    }

    /// `sums` from the columns, plane by plane, by blocks of the window's length along the row.
    fn sum(&mut self) {
        const L: usize = 2 * RADIUS + 1;
        let (w, padded) = (self.w, self.w + 2 * RADIUS);
        for k in 0..self.n {
            let column = &self.columns[k * padded..(k + 1) * padded];
            // Within each block: suffix[q] sums q to the block's end, prefix[q] its start to q
            // (block by block, not a remainder per pixel: an integer division each).
            self.suffix[padded] = 0.0;
            for (block, column) in self.suffix[..padded].chunks_mut(L).zip(column.chunks(L)) {
                let mut sum = 0.0;
                for (s, &c) in block.iter_mut().zip(column).rev() {
                    sum += c;
                    *s = sum;
                }
            }
            for (block, column) in self.prefix.chunks_mut(L).zip(column.chunks(L)) {
                let mut sum = 0.0;
                for (p, &c) in block.iter_mut().zip(column) {
                    sum += c;
                    *p = sum;
                }
            }
            // Centre x's window is padded x..x + L: a block's suffix from x, and unless x starts
            // a block, the next block's prefix to x + L - 1.
            let sums = &mut self.sums[k * w..(k + 1) * w];
            for (start, out) in (0..w).step_by(L).zip(sums.chunks_mut(L)) {
                out[0] = self.suffix[start];
                for (i, s) in out.iter_mut().enumerate().skip(1) {
                    *s = self.suffix[start + i] + self.prefix[start + i + L - 1];
                }
            }
        }
    }
}

/// The filtered layer kept where the halves say it beats the unfiltered `u` (module docs):
/// `u + w (F - u)` per pixel with `F = (1 - s) F_A + s F_B`, from the halves `a`, `b`, their
/// filtered images `fa`, `fb` and the second half's share of the samples `share`. Written
/// over `fa`, whose buffer is the result: a fresh image's pages were a fault each to write,
/// a third of this step's time.
pub fn blend(
    u: &[Vec3],
    (a, b): (&[Vec3], &[Vec3]),
    (fa, fb): (Pixels, &[Vec3]),
    share: &[f32],
    w: u32,
) -> Pixels {
    let weights = weights(w as usize, (a, b), (&fa, fb), share);
    let mut out = fa;
    out.par_iter_mut().enumerate().for_each(|(i, o)| {
        let s = share[i].clamp(0.0, 1.0);
        let u = u[i];
        // (1 - s) F_A + s F_B, exactly F_A where the two agree.
        let f = *o + s * (fb[i] - *o);
        // All of the filtered image exactly where it is kept whole.
        *o = if weights[i] == 1.0 { f } else { u + weights[i] * (f - u) };
    });
    out
}

/// Each pixel's weight of the filtered image ([`blend`]): 0 in a window without a pixel of two
/// sampled halves (adaptive sampling stopped them early: the check cannot speak there, and the
/// pixels it stopped were the clean ones).
fn weights(w: usize, (a, b): (&[Vec3], &[Vec3]), (fa, fb): (&[Vec3], &[Vec3]), share: &[f32]) -> Plane {
    let h = a.len() / w.max(1);
    // Per pixel e_U, e_F and whether it counts (module docs), plane by plane, row by row.
    let (mut e_u, mut e_f, mut checked) =
        (Plane::overwritten(w * h), Plane::overwritten(w * h), Plane::overwritten(w * h));
    let rows = e_u.par_chunks_mut(w).zip(e_f.par_chunks_mut(w)).zip(checked.par_chunks_mut(w));
    rows.enumerate().for_each(|(y, ((eu, ef), c))| {
        let r = y * w..(y + 1) * w;
        let (a, b, share) = (&a[r.clone()], &b[r.clone()], &share[r.clone()]);
        let (fa, fb) = (&fa[r.clone()], &fb[r]);
        for x in 0..eu.len() {
            (eu[x], ef[x], c[x]) = match errors(a[x], b[x], fa[x], fb[x], share[x]) {
                Some((u, f)) => (u, f, 1.0),
                None => (0.0, 0.0, 0.0),
            };
        }
    });
    let mut weights = Plane::overwritten(w * h);
    window_sums([&e_u, &e_f, &checked], w, h, &mut weights, |[u, f, checked], out| {
        for (((o, &u), &f), &checked) in out.iter_mut().zip(u).zip(f).zip(checked) {
            *o = match (checked > 0.0, u > 0.0) {
                (false, _) => 0.0,
                // Sums past the largest float (errors of radiance near 1e18) can give
                // infinity over infinity: the unfiltered image there.
                (true, true) => {
                    let weight = 2.0 * (1.0 - f / u);
                    if weight.is_nan() {
                        0.0
                    } else {
                        weight.clamp(0.0, 1.0)
                    }
                }
                (true, false) => 1.0,
            };
        }
    });
    weights
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(usize) -> Vec3) -> Pixels {
        Pixels::copy_of(&(0..(w * h) as usize).map(f).collect::<Vec<_>>())
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
        assert!(ha[0].abs_diff_eq(a, 1e-5) && hb[0].abs_diff_eq(b, 1e-5));
        // No second half: the mean in both.
        assert_eq!((ha[1], hb[1]), (u[1], u[1]));
    }

    #[test]
    fn a_filter_that_removes_noise_is_kept_and_one_that_adds_error_is_not() {
        let (w, h) = (32u32, 32u32);
        let truth = |i: usize| Vec3::splat(1.0 + 0.5 * ((i % 32) as f32 / 31.0));
        // Halves of equal size, each the truth plus independent noise.
        let a = image(w, h, |i| truth(i) + Vec3::splat(noise(i, 1)));
        let b = image(w, h, |i| truth(i) + Vec3::splat(noise(i, 2)));
        let u = image(w, h, |i| (a[i] + b[i]) / 2.0);
        let share = vec![0.5; (w * h) as usize];
        // A perfect filter: the truth, from either half.
        let t = image(w, h, truth);
        let kept = blend(&u, (&a, &b), (t.clone(), &t), &share, w);
        assert_eq!(kept, t, "a filter that removes all the noise is kept whole");
        // A filter that returns a constant far from the truth (all bias).
        let off = image(w, h, |_| Vec3::splat(3.0));
        assert_eq!(blend(&u, (&a, &b), (off.clone(), &off), &share, w), u, "all bias: not kept");
        // Without measured noise (equal halves), the filtered image is kept.
        let same = blend(&t, (&t, &t), (off.clone(), &off), &share, w);
        assert_eq!(same, off);
        // Without a pixel of two sampled halves the check cannot speak: the unfiltered image.
        let none = vec![0.0; share.len()];
        assert_eq!(blend(&u, (&a, &b), (t.clone(), &t), &none, w), u);
    }

    #[test]
    fn weights_follow_the_windows_errors_with_and_without_unchecked_pixels() {
        let (w, h) = (29usize, 23usize);
        let truth = |i: usize| Vec3::splat(1.0 + (i % 7) as f32 / 7.0);
        let a = image(w as u32, h as u32, |i| truth(i) + Vec3::splat(noise(i, 5)));
        let b = image(w as u32, h as u32, |i| truth(i) + Vec3::splat(noise(i, 6)));
        // A filter that halves the noise, with a little bias.
        let fa = image(w as u32, h as u32, |i| truth(i) + Vec3::splat(0.5 * noise(i, 5) + 0.02));
        let fb = image(w as u32, h as u32, |i| truth(i) + Vec3::splat(0.5 * noise(i, 6) + 0.02));
        // Every pixel checked, then a band of pixels whose second half is empty.
        for unchecked in [0, 9] {
            let share: Vec<f32> = (0..w * h).map(|i| if i % w < unchecked { 0.0 } else { 0.5 }).collect();
            let got = weights(w, (&a, &b), (&fa, &fb), &share);
            for y in 0..h {
                for x in 0..w {
                    let (mut u, mut f, mut n) = (0.0f64, 0.0f64, 0);
                    for yy in y.saturating_sub(RADIUS)..(y + RADIUS + 1).min(h) {
                        for xx in x.saturating_sub(RADIUS)..(x + RADIUS + 1).min(w) {
                            let i = yy * w + xx;
                            if let Some((eu, ef)) = errors(a[i], b[i], fa[i], fb[i], share[i]) {
                                (u, f, n) = (u + eu as f64, f + ef as f64, n + 1);
                            }
                        }
                    }
                    let want = match (n > 0, u > 0.0) {
                        (false, _) => 0.0,
                        (true, true) => (2.0 * (1.0 - f / u)).clamp(0.0, 1.0),
                        (true, false) => 1.0,
                    };
                    let at = got[y * w + x] as f64;
                    assert!(
                        (at - want).abs() < 1e-4,
                        "({x}, {y}) with {unchecked} columns unchecked: {at} against {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn windows_whose_sums_pass_the_largest_float_keep_the_image_finite() {
        let (w, h) = (20u32, 20u32);
        let share = vec![0.5; (w * h) as usize];
        // Halves about 2e18 apart in every channel: each pixel's errors fit in f32 (about
        // 3e36), a window's sums of them do not.
        let a = image(w, h, |i| Vec3::splat(1e18 * (1.0 + noise(i, 7))));
        let b = image(w, h, |i| -a[i]);
        let u = image(w, h, |i| (a[i] + b[i]) / 2.0);
        let f = image(w, h, |_| Vec3::ONE);
        let got = weights(w as usize, (&a, &b), (&f, &f), &share);
        assert!(got.iter().all(|w| (0.0..=1.0).contains(w)), "every weight in [0, 1]");
        let out = blend(&u, (&a, &b), (f.clone(), &f), &share, w);
        assert!(out.iter().all(|p| p.is_finite()), "every pixel finite");
    }

    #[test]
    fn window_sums_equal_a_direct_sum() {
        // Sizes below, at and across the window's length (and its bands), a single column and a
        // single row; every pixel of both planes.
        for (w, h) in [(23usize, 17usize), (5, 3), (1, 20), (15, 15), (16, 31), (47, 46), (30, 1)] {
            let planes: Vec<Vec<f32>> =
                (0..2).map(|k| (0..w * h).map(|i| noise(i, 3 + k)).collect()).collect();
            for which in 0..2 {
                let mut sums = vec![0.0f32; w * h];
                window_sums([&planes[0], &planes[1]], w, h, &mut sums, |s: [&[f32]; 2], out| {
                    out.iter_mut().zip(s[which]).for_each(|(o, s)| *o = *s)
                });
                for y in 0..h {
                    for x in 0..w {
                        let mut want = 0.0f64;
                        for yy in y.saturating_sub(RADIUS)..(y + RADIUS + 1).min(h) {
                            for xx in x.saturating_sub(RADIUS)..(x + RADIUS + 1).min(w) {
                                want += planes[which][yy * w + xx] as f64;
                            }
                        }
                        assert!(
                            (sums[y * w + x] as f64 - want).abs() < 1e-5,
                            "{w}x{h} ({x}, {y}) plane {which}"
                        );
                    }
                }
            }
        }
    }
}
