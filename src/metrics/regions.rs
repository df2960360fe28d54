//! Errors per region of an image: per object (by the object-ID layer of a render), or per named
//! group of objects. Behind `compare --by-object` and `--region`, which the comparison scripts
//! call (Blender's import against lightsplit's render; the denoisers on textured regions).
//!
//! Per region:
//! - `pixels`: the pixels showing one of its objects; `rmse` and `relmse` over them, with the
//!   formulas of [`super::compare`].
//! - `inner`: those whose four neighbours (inside the image) show one of its objects too. A
//!   border pixel mixes the region with its neighbours, differently in each renderer, so the
//!   means and the detail are taken over the inner pixels alone.
//! - `test_mean`, `reference_mean`: the mean colour of each image there; `ratio` the test's
//!   mean luminance over the reference's.
//! - `detail`: how much of the reference's fine detail the test keeps: the correlation of the
//!   two images' high-pass (each minus its 3x3 box blur, the image's edge repeated) over the
//!   inner pixels. 1 is all of it, 0 none (a blur); noise lowers it too.

use glam::{DVec3, Vec3};

use crate::error::InputError;
use crate::film::Image;
use crate::math::luminance;

/// A region: a name and the object IDs it gathers (-1 is the background).
#[derive(Clone, Debug, PartialEq)]
pub struct Region {
    pub name: String,
    pub ids: Vec<i64>,
}

impl Region {
    /// `NAME=ID,ID,...` (the IDs whole numbers from -1).
    pub fn parse(text: &str) -> Result<Region, InputError> {
        let bad = || InputError(format!("`{text}` is not a region NAME=ID[,ID...] (IDs from -1)"));
        let (name, ids) = text.split_once('=').ok_or_else(bad)?;
        let ids: Vec<i64> = ids
            .split(',')
            .map(|i| i.trim().parse::<i64>().ok().filter(|&i| i >= -1))
            .collect::<Option<_>>()
            .ok_or_else(bad)?;
        if name.trim().is_empty() || ids.is_empty() {
            return Err(bad());
        }
        Ok(Region { name: name.trim().to_string(), ids })
    }

    /// One region per object the ID layer shows, in the order of their IDs (the background,
    /// -1, first, named `background`; the others `object N`).
    pub fn each_object(object: &[f32]) -> Vec<Region> {
        let mut ids: Vec<i64> = object.iter().map(|&o| o as i64).collect();
        ids.sort_unstable();
        ids.dedup();
        ids.into_iter()
            .map(|id| Region {
                name: if id < 0 { "background".into() } else { format!("object {id}") },
                ids: vec![id],
            })
            .collect()
    }
}

/// The errors of one region.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RegionErrors {
    pub name: String,
    pub ids: Vec<i64>,
    pub pixels: usize,
    pub inner: usize,
    pub rmse: f64,
    pub relmse: f64,
    pub test_mean: [f64; 3],
    pub reference_mean: [f64; 3],
    /// `None` when the reference's mean luminance there is zero.
    pub ratio: Option<f64>,
    /// `None` with fewer than two inner pixels or no detail in either image.
    pub detail: Option<f64>,
}

/// Each image minus its 3x3 box blur (the edge repeated).
fn high_pass(image: &Image) -> Vec<DVec3> {
    let (w, h) = (image.width as i64, image.height as i64);
    let at = |x: i64, y: i64| image.pixels[(y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize].as_dvec3();
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let mut blur = DVec3::ZERO;
            for dy in -1..=1 {
                for dx in -1..=1 {
                    blur += at(x + dx, y + dy);
                }
            }
            at(x, y) - blur / 9.0
        })
        .collect()
}

/// The errors of `test` against `reference` in each of `regions`, by `object` (the ID of the
/// object each pixel shows, as a render's `objectid.ID` layer holds it). The three must have the
/// same size.
pub fn by_region(
    test: &Image,
    reference: &Image,
    object: &[f32],
    regions: &[Region],
) -> Result<Vec<RegionErrors>, InputError> {
    super::compare(test, reference)?;
    let n = test.pixels.len();
    if object.len() != n {
        return Err(InputError(format!(
            "the object IDs are of {} pixels and the images of {n}: not the same render",
            object.len()
        )));
    }
    let (w, h) = (test.width as i64, test.height as i64);
    let (hp_test, hp_reference) = (high_pass(test), high_pass(reference));
    let mut out = Vec::new();
    for region in regions {
        let inside: Vec<bool> = object.iter().map(|&o| region.ids.contains(&(o as i64))).collect();
        let inner = |i: usize| {
            let (x, y) = (i as i64 % w, i as i64 / w);
            inside[i]
                && [(1, 0), (-1, 0), (0, 1), (0, -1)].iter().all(|&(dx, dy)| {
                    let (nx, ny) = (x + dx, y + dy);
                    nx < 0 || ny < 0 || nx >= w || ny >= h || inside[(ny * w + nx) as usize]
                })
        };
        let (mut sq, mut rel, mut pixels) = (0.0, 0.0, 0usize);
        let (mut sum_test, mut sum_reference, mut inner_count) = (DVec3::ZERO, DVec3::ZERO, 0usize);
        let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
        for i in (0..n).filter(|&i| inside[i]) {
            let (x, y) = (test.pixels[i].as_dvec3(), reference.pixels[i].as_dvec3());
            let d = (x - y) * (x - y);
            sq += d.element_sum();
            rel += (d / (y * y + DVec3::splat(0.01))).element_sum();
            pixels += 1;
            if inner(i) {
                sum_test += x;
                sum_reference += y;
                inner_count += 1;
                let (a, b) = (hp_test[i], hp_reference[i]);
                ab += a.dot(b);
                aa += a.dot(a);
                bb += b.dot(b);
            }
        }
        let channels = 3.0 * pixels.max(1) as f64;
        let mean = |s: DVec3| (s / inner_count.max(1) as f64).to_array();
        let (test_mean, reference_mean) = (mean(sum_test), mean(sum_reference));
        let lum = |m: [f64; 3]| luminance(Vec3::new(m[0] as f32, m[1] as f32, m[2] as f32)) as f64;
        let reference_lum = lum(reference_mean);
        out.push(RegionErrors {
            name: region.name.clone(),
            ids: region.ids.clone(),
            pixels,
            inner: inner_count,
            rmse: (sq / channels).sqrt(),
            relmse: rel / channels,
            test_mean,
            reference_mean,
            ratio: (reference_lum > 0.0).then(|| lum(test_mean) / reference_lum),
            detail: (inner_count >= 2 && aa > 0.0 && bb > 0.0).then(|| ab / (aa * bb).sqrt()),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 6x4 image: object 0 on the left half, object 1 on the right, a checker of `a` and `b`.
    fn halves(a: f32, b: f32) -> (Image, Vec<f32>) {
        let mut image = Image::new(6, 4);
        for (i, p) in image.pixels.iter_mut().enumerate() {
            *p = Vec3::splat(if (i % 6 + i / 6) % 2 == 0 { a } else { b });
        }
        let object = (0..24).map(|i| if i % 6 < 3 { 0.0 } else { 1.0 }).collect();
        (image, object)
    }

    #[test]
    fn each_region_sees_only_its_pixels() {
        let (reference, object) = halves(1.0, 0.0);
        let mut test = reference.clone();
        // Object 1 twice as bright; object 0 unchanged.
        for (p, &o) in test.pixels.iter_mut().zip(&object) {
            if o == 1.0 {
                *p *= 2.0;
            }
        }
        let regions = Region::each_object(&object);
        assert_eq!(regions.iter().map(|r| r.name.as_str()).collect::<Vec<_>>(), ["object 0", "object 1"]);
        let e = by_region(&test, &reference, &object, &regions).expect("same size");
        assert_eq!((e[0].pixels, e[1].pixels), (12, 12));
        assert_eq!(e[0].rmse, 0.0);
        assert!(e[0].detail.is_some_and(|d| (d - 1.0).abs() < 1e-12), "{:?}", e[0].detail);
        // Half of object 1's pixels are 2 against 1: a squared error of 1 in each channel.
        assert!((e[1].rmse - 0.5f64.sqrt()).abs() < 1e-12, "{}", e[1].rmse);
        let ratio = e[1].ratio.expect("a lit reference");
        assert!((ratio - 2.0).abs() < 1e-6, "{ratio}");
        // The columns on the border between the objects are not inner.
        assert_eq!((e[0].inner, e[1].inner), (8, 8));
    }

    #[test]
    fn a_blur_keeps_no_detail_and_regions_parse() {
        let (reference, object) = halves(1.0, 0.0);
        let flat = Image { pixels: vec![Vec3::splat(0.5); 24], ..reference.clone() };
        let all = [Region::parse("all=0,1").expect("a region")];
        let e = by_region(&flat, &reference, &object, &all).expect("same size");
        assert_eq!(e[0].detail, None, "a flat image has no detail to correlate");
        assert_eq!(e[0].pixels, 24);
        for bad in ["all", "=1", "a=", "a=x", "a=-2"] {
            assert!(Region::parse(bad).is_err(), "{bad}");
        }
        let other = Image::new(3, 3);
        assert!(by_region(&other, &reference, &object, &all).is_err());
    }
}
