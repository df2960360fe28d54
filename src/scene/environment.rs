//! An environment map: radiance at infinity from a latitude-longitude image (an HDRI), the way
//! most scenes are lit. The image's rows run from straight up (top) to straight down (bottom);
//! its columns go once around the up axis (y), with the image's centre looking along +x and the
//! left edge along -x, turning from +x toward +z as the column grows: the orientation Blender
//! gives a map on the world of a glTF file it imports (its glTF importer turns y up into z up).
//! `rotate` turns the map about +y by the right-hand rule.

use std::f32::consts::PI;
use std::path::Path;

use glam::{Vec2, Vec3};

use crate::math::luminance;
use crate::scene::image::{self, Image};

/// A latitude-longitude map of radiance, already scaled, and how it is turned.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    /// Radiance, row-major from the top row (up) down; twice as wide as high.
    pub image: Image,
    /// The turn about +y, as (sin, cos) of its angle.
    pub turn: (f32, f32),
    /// Sample directions uniformly over the sphere instead of by the map's light (for
    /// comparison: `sampling = "uniform"`).
    pub uniform: bool,
}

/// The largest sum of an environment map's sampling weights (luminance times the sine of the
/// row's angle): two orders of magnitude inside f32, in which the sampling tables add them.
const OVERFLOW: f64 = 1e36;

impl EnvironmentMap {
    /// Reads a lat-long map (`.exr`, `.hdr`, `.pfm`; anything else as 8-bit sRGB) and scales it.
    /// It must be non-empty, exactly twice as wide as high, and finite and non-negative
    /// everywhere: a map that breaks any of these is refused, with what was wrong.
    pub fn load(path: &Path, scale: f32, rotate_degrees: f32) -> Result<Self, String> {
        let image = image::read(path)?;
        Self::new(image, scale, rotate_degrees).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// A map from an image already read (the checks of [`EnvironmentMap::load`]).
    pub fn new(mut image: Image, scale: f32, rotate_degrees: f32) -> Result<Self, String> {
        let (w, h) = (image.width, image.height);
        if w == 0 || h == 0 || image.pixels.is_empty() {
            return Err("the environment map has no pixels".into());
        }
        if w != 2 * h {
            return Err(format!(
                "an environment map is a latitude-longitude image, twice as wide as high; this one is \
                 {w}x{h}"
            ));
        }
        let bad = image.pixels.iter().filter(|p| !p.is_finite() || p.min_element() < 0.0).count();
        if bad > 0 {
            return Err(format!(
                "{bad} of the environment map's {} pixels are negative, NaN or infinite",
                image.pixels.len()
            ));
        }
        image.pixels.iter_mut().for_each(|p| *p *= scale);
        if image.pixels.iter().any(|p| !p.is_finite()) {
            return Err(format!("`scale` {scale} makes the environment map overflow"));
        }
        let a = rotate_degrees.to_radians();
        let map = EnvironmentMap { image, turn: (a.sin(), a.cos()), uniform: false };
        // Sampling sums the weights of each row and then of the rows in f32: a map whose sum
        // overflows there (every RGBE pixel `ff ff ff ff`, 1.7e38) would be sampled as black.
        let total: f64 = map.weights(false).iter().map(|&x| x as f64).sum();
        if total > OVERFLOW {
            return Err(format!(
                "the environment map's pixels sum to {total:.2e}, beyond the {OVERFLOW:e} its sampling can add up: scale it down"
            ));
        }
        Ok(map)
    }

    /// The point of the map's unit square (u across, v down) that direction `dir` (unit, in the
    /// scene) looks at.
    pub fn uv(&self, dir: Vec3) -> Vec2 {
        // Into the map's frame: the turn undone.
        let (s, c) = self.turn;
        let x = c * dir.x - s * dir.z;
        let z = s * dir.x + c * dir.z;
        let u = 0.5 + z.atan2(x) / (2.0 * PI);
        let v = dir.y.clamp(-1.0, 1.0).acos() / PI;
        Vec2::new(u.rem_euclid(1.0), v)
    }

    /// The direction (unit, in the scene) that point `uv` of the map's square looks at, and the
    /// sine of its angle from the up axis.
    pub fn direction(&self, uv: Vec2) -> (Vec3, f32) {
        // phi = 2 pi (u - 1/2), theta = pi v: half a turn.
        let (sin_p, cos_p) = crate::math::sin_cos_turn(uv.x - 0.5);
        let (sin_t, cos_t) = crate::math::sin_cos_turn(0.5 * uv.y);
        let (x, z) = (sin_t * cos_p, sin_t * sin_p);
        let (s, c) = self.turn;
        (Vec3::new(c * x + s * z, cos_t, -s * x + c * z), sin_t)
    }

    /// The radiance of the pixel that holds `uv`: what light shed on the scene reads, constant
    /// over each pixel as the sampling density is.
    pub fn pixel(&self, uv: Vec2) -> Vec3 {
        let (w, h) = (self.image.width, self.image.height);
        let x = ((uv.x * w as f32) as u32).min(w - 1);
        let y = ((uv.y * h as f32) as u32).min(h - 1);
        self.image.get(x, y)
    }

    /// The radiance at `uv` interpolated bilinearly between pixel centres (wrapping around the
    /// up axis, clamped at the poles): what the eye sees directly, without blocks.
    pub fn smooth(&self, uv: Vec2) -> Vec3 {
        let (w, h) = (self.image.width as i64, self.image.height as i64);
        let x = uv.x * w as f32 - 0.5;
        let y = (uv.y * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let col = |c: f32| (c as i64).rem_euclid(w) as u32;
        let (c0, c1) = (col(x0), col(x0 + 1.0));
        let (r0, r1) = (y0 as u32, (y0 as i64 + 1).min(h - 1) as u32);
        let at = |r: u32, c: u32| self.image.get(c, r);
        (at(r0, c0) * (1.0 - fx) + at(r0, c1) * fx) * (1.0 - fy)
            + (at(r1, c0) * (1.0 - fx) + at(r1, c1) * fx) * fy
    }

    /// The sampling weight of each pixel: its luminance times the sine of its row's polar angle
    /// (the solid angle a pixel covers), so that samples follow the light.
    /// With `uniform`, every pixel's weight is its solid angle alone: directions uniform over
    /// the sphere, for comparison.
    pub fn weights(&self, uniform: bool) -> Vec<f32> {
        let (w, h) = (self.image.width as usize, self.image.height as usize);
        (0..w * h)
            .map(|i| {
                let sin = (PI * ((i / w) as f32 + 0.5) / h as f32).sin();
                if uniform {
                    sin
                } else {
                    luminance(self.image.pixels[i]) * sin
                }
            })
            .collect()
    }

    /// The mean luminance over the sphere of directions (each pixel weighted by its solid angle).
    pub fn mean_luminance(&self) -> f32 {
        let weights = self.weights(false);
        let (w, h) = (self.image.width as f64, self.image.height as f64);
        // A pixel covers (2 pi / w) (pi / h) sin(theta) of the sphere's 4 pi.
        let total: f64 = weights.iter().map(|&x| x as f64).sum();
        (total * (2.0 * std::f64::consts::PI / w) * (std::f64::consts::PI / h) / (4.0 * std::f64::consts::PI))
            as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(w: u32, h: u32, rotate: f32) -> EnvironmentMap {
        let pixels = (0..w * h).map(|i| Vec3::splat(i as f32)).collect();
        EnvironmentMap::new(Image { width: w, height: h, pixels }, 1.0, rotate).expect("a map")
    }

    #[test]
    fn directions_and_points_of_the_square_are_inverse() {
        for rotate in [0.0, 30.0, -125.0] {
            let m = map(8, 4, rotate);
            for uv in [Vec2::new(0.1, 0.2), Vec2::new(0.5, 0.5), Vec2::new(0.93, 0.81), Vec2::new(0.3, 0.02)]
            {
                let (d, sin) = m.direction(uv);
                assert!((d.length() - 1.0).abs() < 1e-5);
                assert!((sin - (1.0 - d.y * d.y).sqrt()).abs() < 1e-4);
                let back = m.uv(d);
                assert!((back - uv).length() < 1e-5, "{rotate}: {uv} -> {d} -> {back}");
            }
        }
    }

    #[test]
    fn the_centre_looks_along_x_the_top_up_and_rotate_turns_by_the_right_hand_rule() {
        let m = map(8, 4, 0.0);
        assert!((m.direction(Vec2::new(0.5, 0.5)).0 - Vec3::X).length() < 1e-6);
        assert!((m.direction(Vec2::new(0.75, 0.5)).0 - Vec3::Z).length() < 1e-6);
        assert!((m.direction(Vec2::new(0.0, 0.5)).0 + Vec3::X).length() < 1e-6);
        assert!(m.direction(Vec2::new(0.3, 0.0)).0.y > 0.999);
        // Turned by 90 degrees about +y: the centre moves from +x to -z.
        let m = map(8, 4, 90.0);
        assert!((m.direction(Vec2::new(0.5, 0.5)).0 - Vec3::NEG_Z).length() < 1e-6);
    }

    #[test]
    fn lookups_read_the_right_pixels() {
        let m = map(8, 4, 0.0);
        // Pixel (3, 1) holds 1 * 8 + 3 = 11.
        assert_eq!(m.pixel(Vec2::new(3.5 / 8.0, 1.5 / 4.0)), Vec3::splat(11.0));
        assert_eq!(m.smooth(Vec2::new(3.5 / 8.0, 1.5 / 4.0)), Vec3::splat(11.0));
        // Half way between pixels (3, 1) and (4, 1); and across the seam, (7, 1) and (0, 1).
        assert!((m.smooth(Vec2::new(4.0 / 8.0, 1.5 / 4.0)).x - 11.5).abs() < 1e-5);
        assert!((m.smooth(Vec2::new(0.0, 1.5 / 4.0)).x - 11.5).abs() < 1e-5);
        assert_eq!(m.pixel(Vec2::new(1.0, 1.0)), Vec3::splat(31.0));
    }

    #[test]
    fn bad_maps_are_refused_with_the_reason() {
        let image =
            |w: u32, h: u32, p: Vec3| Image { width: w, height: h, pixels: vec![p; (w * h) as usize] };
        let e = EnvironmentMap::new(image(6, 4, Vec3::ONE), 1.0, 0.0).expect_err("aspect");
        assert!(e.contains("twice as wide as high") && e.contains("6x4"), "{e}");
        let e = EnvironmentMap::new(image(0, 0, Vec3::ONE), 1.0, 0.0).expect_err("empty");
        assert!(e.contains("no pixels"), "{e}");
        let e = EnvironmentMap::new(image(4, 2, Vec3::NAN), 1.0, 0.0).expect_err("nan");
        assert!(e.contains("8 of the environment map's 8 pixels"), "{e}");
        let e = EnvironmentMap::new(image(4, 2, Vec3::splat(-1.0)), 1.0, 0.0).expect_err("negative");
        assert!(e.contains("negative"), "{e}");
        let e = EnvironmentMap::new(image(4, 2, Vec3::splat(1e30)), 1e30, 0.0).expect_err("overflow");
        assert!(e.contains("overflow"), "{e}");
    }

    #[test]
    fn the_mean_of_a_constant_map_is_its_value() {
        let m = EnvironmentMap::new(Image { width: 64, height: 32, pixels: vec![Vec3::ONE; 2048] }, 2.0, 0.0)
            .expect("a map");
        // The sum of sines over rows approximates the integral to about 1e-4 at 32 rows.
        assert!((m.mean_luminance() - 2.0).abs() < 2e-3, "{}", m.mean_luminance());
    }
}
