//! Error metrics behind `compare` and `converge`: the paper's sum of squared differences, RMSE
//! and relative MSE, each also with the worst 0.1% of pixels dropped.

pub mod regions;

use glam::Vec3;

use crate::error::InputError;
use crate::film::Image;

/// How far a test image is from a reference.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Errors {
    /// The paper's metric: the sum over pixels (and channels) of the squared difference.
    pub sse: f64,
    pub rmse: f64,
    /// Mean of (x - y)^2 / (y^2 + 0.01) over pixels and channels.
    pub relmse: f64,
    pub rmse_trimmed: f64,
    pub relmse_trimmed: f64,
    pub width: u32,
    pub height: u32,
}

/// Compares `test` with `reference`; they must have the same size.
pub fn compare(test: &Image, reference: &Image) -> Result<Errors, InputError> {
    if (test.width, test.height) != (reference.width, reference.height) {
        return Err(InputError(format!(
            "the images differ in size: {}x{} against a {}x{} reference",
            test.width, test.height, reference.width, reference.height
        )));
    }
    // A NaN or an infinity makes every figure NaN or infinite: say where, rather than print it.
    for (name, image) in [("the image", test), ("the reference", reference)] {
        let bad = image.pixels.iter().filter(|p| !p.is_finite()).count();
        if bad > 0 {
            return Err(InputError(format!(
                "{name} has {bad} of {} pixels that are not finite (NaN or infinite): no error can be measured",
                image.pixels.len()
            )));
        }
    }
    // Per pixel: squared error and relative squared error, summed over channels.
    let per_pixel: Vec<(f64, f64)> = test
        .pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(x, y)| {
            let (x, y) = (x.as_dvec3(), y.as_dvec3());
            let d = x - y;
            let sq = d * d;
            let rel = sq / (y * y + glam::DVec3::splat(0.01));
            (sq.element_sum(), rel.element_sum())
        })
        .collect();
    let n = per_pixel.len().max(1) as f64;
    let sse: f64 = per_pixel.iter().map(|p| p.0).sum();
    let rel: f64 = per_pixel.iter().map(|p| p.1).sum();
    // Drop the worst 0.1% of pixels by squared error (by relative error for relMSE).
    let drop = per_pixel.len() / 1000;
    let trimmed = |key: fn(&(f64, f64)) -> f64| -> f64 {
        let mut v: Vec<f64> = per_pixel.iter().map(key).collect();
        // Only the split between the kept and the dropped matters: a selection, not a sort.
        let keep = v.len() - drop;
        if drop > 0 {
            v.select_nth_unstable_by(keep, f64::total_cmp);
        }
        let kept = &v[..keep];
        kept.iter().sum::<f64>() / (3.0 * kept.len().max(1) as f64)
    };
    Ok(Errors {
        sse,
        rmse: (sse / (3.0 * n)).sqrt(),
        relmse: rel / (3.0 * n),
        rmse_trimmed: trimmed(|p| p.0).sqrt(),
        relmse_trimmed: trimmed(|p| p.1),
        width: test.width,
        height: test.height,
    })
}

/// The RMSE over the pixels where `mask` is true (0 when there are none).
pub fn rmse_masked(test: &Image, reference: &Image, mask: &[bool]) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for ((x, y), &m) in test.pixels.iter().zip(&reference.pixels).zip(mask) {
        if m {
            let d = x.as_dvec3() - y.as_dvec3();
            sum += d.length_squared();
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        (sum / (3.0 * n as f64)).sqrt()
    }
}

/// Pixels on an object border: one of their eight neighbours shows another object.
pub fn object_borders(object: &[f32], width: u32, height: u32) -> Vec<bool> {
    let (w, h) = (width as i64, height as i64);
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let c = object[i as usize];
            (-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    let (nx, ny) = (x + dx, y + dy);
                    nx >= 0 && ny >= 0 && nx < w && ny < h && object[(ny * w + nx) as usize] != c
                })
            })
        })
        .collect()
}

/// A brightened difference image in the manner of the paper's Figure 6: white where the images
/// agree, darker where they differ, scaled so that the 99th percentile of the difference is black.
pub fn difference_image(test: &Image, reference: &Image) -> Image {
    difference_image_scaled(test, reference, difference_scale(test, reference))
}

/// The 99th percentile of the per-pixel difference: the scale of [`difference_image`]. Several
/// images drawn at one scale (the unfiltered one's) can be compared by eye.
pub fn difference_scale(test: &Image, reference: &Image) -> f32 {
    let mut diffs = differences(test, reference);
    let k = (diffs.len() * 99 / 100).min(diffs.len().saturating_sub(1));
    if diffs.is_empty() {
        return f32::MIN_POSITIVE;
    }
    diffs.select_nth_unstable_by(k, f32::total_cmp);
    diffs[k].max(f32::MIN_POSITIVE)
}

/// A difference image with black at a difference of `scale`.
pub fn difference_image_scaled(test: &Image, reference: &Image, scale: f32) -> Image {
    let mut out = Image::new(test.width, test.height);
    for (o, d) in out.pixels.iter_mut().zip(differences(test, reference)) {
        *o = Vec3::splat(1.0 - (d / scale).min(1.0));
    }
    out
}

fn differences(test: &Image, reference: &Image) -> Vec<f32> {
    test.pixels.iter().zip(&reference.pixels).map(|(a, b)| (*a - *b).abs().max_element()).collect()
}

/// How two renders of one scene by two programs agree: their channel means, and the worst
/// block of `size` x `size` pixels (blocks tile the image from the top left; those at the right
/// and bottom edges are what is left).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Agreement {
    /// The test image's mean R, G, B.
    pub test_means: [f64; 3],
    /// The reference's.
    pub reference_means: [f64; 3],
    /// The largest |test / reference - 1| of the three channel means.
    pub means_difference: f64,
    /// The block side.
    pub block: u32,
    /// The worst block's top-left pixel.
    pub worst_block_at: (u32, u32),
    /// Its difference: the largest over channels of |mean_t - mean_r| / (mean_r + floor),
    /// where the floor is 1% of the reference's mean of that channel over the whole image (so
    /// a block that is nearly black does not count tiny values as large ratios).
    pub worst_block_difference: f64,
}

/// [`Agreement`] of `test` with `reference` (the same size, checked by [`compare`] first).
pub fn agreement(test: &Image, reference: &Image, block: u32) -> Agreement {
    let mean = |image: &Image, x0: u32, y0: u32, w: u32, h: u32| -> glam::DVec3 {
        let mut sum = glam::DVec3::ZERO;
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                sum += image.pixels[(y * image.width + x) as usize].as_dvec3();
            }
        }
        sum / (w as f64 * h as f64).max(1.0)
    };
    let (w, h) = (test.width, test.height);
    let (t, r) = (mean(test, 0, 0, w, h), mean(reference, 0, 0, w, h));
    let ratio = |a: f64, b: f64| {
        if b > 0.0 {
            (a / b - 1.0).abs()
        } else if a == 0.0 {
            0.0
        } else {
            f64::INFINITY
        }
    };
    let means_difference = ratio(t.x, r.x).max(ratio(t.y, r.y)).max(ratio(t.z, r.z));
    let floor = 0.01 * r;
    let block = block.max(1);
    let (mut worst, mut at) = (0.0f64, (0, 0));
    for y0 in (0..h).step_by(block as usize) {
        for x0 in (0..w).step_by(block as usize) {
            let (bw, bh) = (block.min(w - x0), block.min(h - y0));
            let (bt, br) = (mean(test, x0, y0, bw, bh), mean(reference, x0, y0, bw, bh));
            let d = (bt - br).abs() / (br + floor).max(glam::DVec3::splat(f64::MIN_POSITIVE));
            if d.max_element() > worst {
                (worst, at) = (d.max_element(), (x0, y0));
            }
        }
    }
    Agreement {
        test_means: t.to_array(),
        reference_means: r.to_array(),
        means_difference,
        block,
        worst_block_at: at,
        worst_block_difference: worst,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One block 10% brighter in red is the worst, at its place; the means move by its share.
    #[test]
    fn agreement_finds_the_worst_block() {
        let mut reference = Image::new(64, 48);
        for p in &mut reference.pixels {
            *p = Vec3::new(0.5, 0.25, 1.0);
        }
        let mut test = reference.clone();
        for y in 32..48 {
            for x in 32..64 {
                test.pixels[y * 64 + x].x *= 1.1;
            }
        }
        let a = agreement(&test, &reference, 32);
        assert_eq!(a.worst_block_at, (32, 32));
        assert!((a.worst_block_difference - 0.1 / 1.01).abs() < 1e-6, "{a:?}");
        // 512 of 3072 pixels 10% brighter.
        assert!((a.means_difference - 0.1 * 512.0 / 3072.0).abs() < 1e-6, "{a:?}");
        assert_eq!(agreement(&reference, &reference, 32).worst_block_difference, 0.0);
    }

    #[test]
    fn metrics_of_a_known_difference() {
        let reference = Image::new(10, 100);
        let mut test = reference.clone();
        // One pixel off by 3 in every channel: sse 27, rmse sqrt(27 / 3000).
        test.pixels[5] = Vec3::splat(3.0);
        let e = compare(&test, &reference).expect("same size");
        assert!((e.sse - 27.0).abs() < 1e-9);
        assert!((e.rmse - (27.0f64 / 3000.0).sqrt()).abs() < 1e-12);
        assert!((e.relmse - 3.0 * 9.0 / 0.01 / 3000.0).abs() < 1e-6);
        // 1000 pixels: the worst one is dropped.
        assert_eq!(e.rmse_trimmed, 0.0);
        assert_eq!(compare(&reference, &reference).expect("same").sse, 0.0);
        assert!(compare(&Image::new(3, 3), &reference).is_err());
    }

    #[test]
    fn non_finite_pixels_are_an_error_that_counts_them() {
        let reference = Image::new(4, 4);
        let mut test = reference.clone();
        test.pixels[1] = Vec3::new(f32::NAN, 0.0, 0.0);
        test.pixels[2] = Vec3::splat(f32::INFINITY);
        let e = compare(&test, &reference).expect_err("NaN and inf");
        assert!(e.0.contains("the image has 2 of 16 pixels"), "{e}");
        let e = compare(&reference, &test).expect_err("NaN and inf");
        assert!(e.0.contains("the reference has 2 of 16"), "{e}");
    }

    #[test]
    fn difference_image_is_white_where_equal() {
        let a = Image::new(4, 4);
        let mut b = a.clone();
        b.pixels[3] = Vec3::ONE;
        let d = difference_image(&b, &a);
        assert_eq!(d.pixels[0], Vec3::ONE);
        assert_eq!(d.pixels[3], Vec3::ZERO);
    }
}
