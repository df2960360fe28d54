//! Primary rays of a pinhole or an orthographic camera. Pixel (0, 0) is the top-left corner of
//! the image.

use std::sync::Arc;

use glam::{DMat4, DVec3, DVec4, Vec2, Vec3};

use crate::accel::Ray;
use crate::scene::{Camera, FilmSettings, PixelFilter, FILTER_STEPS};

/// A camera resolved for one image size.
#[derive(Clone, Debug)]
pub struct PinholeCamera {
    origin: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    width: f32,
    height: f32,
    /// Orthographic: the rays start across the film (`right` and `up` its half extents) and
    /// all run along `forward`.
    orthographic: bool,
    /// A thin lens: the unit vectors across the view times its radius, and its focus
    /// distance.
    lens: Option<(Vec3, Vec3, f32)>,
    /// A reconstruction filter other than the pixel's own box: each sample's position in the
    /// film is drawn from it.
    filter: Option<Arc<FilterTable>>,
    /// A crop: where the image's top-left pixel lies on the film, and the image's size.
    shift: Vec2,
    image: (u32, u32),
}

impl PinholeCamera {
    pub fn new(camera: &Camera, width: u32, height: u32) -> Self {
        let forward = (camera.look_at - camera.position).normalize();
        // Right-handed: with y up and the view along +z, +x is on the left of the image.
        let right = forward.cross(camera.up).normalize();
        let up = right.cross(forward);
        // The film's half height: at unit distance for a pinhole, in scene units for an
        // orthographic camera.
        let half = match camera.orthographic {
            Some(h) => 0.5 * h,
            None => (camera.fov.to_radians() * 0.5).tan(),
        };
        let aspect = width as f32 / height as f32;
        PinholeCamera {
            origin: camera.position,
            forward,
            right: right * half * aspect,
            up: up * half,
            width: width as f32,
            height: height as f32,
            orthographic: camera.orthographic.is_some(),
            lens: camera.lens.map(|l| (right * l.radius, up * l.radius, l.focus_distance)),
            filter: None,
            shift: Vec2::ZERO,
            image: (width, height),
        }
    }

    /// The camera of `film`'s image rendered at `width` x `height`: its reconstruction filter,
    /// and its crop window when the image has the film's own size (another size is the whole
    /// film, resized).
    pub fn of_film(camera: &Camera, film: &FilmSettings, width: u32, height: u32) -> Self {
        let window = film.window.filter(|_| (width, height) == (film.width, film.height));
        let mut c = match window {
            Some(w) => PinholeCamera::new(camera, w.film_width, w.film_height),
            None => PinholeCamera::new(camera, width, height),
        };
        if let Some(w) = window {
            c.shift = Vec2::new(w.x as f32, w.y as f32);
        }
        c.image = (width, height);
        if !film.pixel_filter.is_pixel_box() {
            c.filter = Some(Arc::new(FilterTable::new(film.pixel_filter)));
        }
        c
    }

    /// The ray of a path sample through pixel `(x, y)`: its position in the pixel from
    /// `sampler`, and with a lens the point on the lens too (two more numbers).
    #[inline]
    pub fn generate(&self, x: u32, y: u32, sampler: &mut crate::render::sampler::Sampler) -> Ray {
        let mut offset = sampler.pixel_2d();
        if let Some(f) = &self.filter {
            offset = Vec2::new(f.offset(offset.x, x, self.image.0), f.offset(offset.y, y, self.image.1));
        }
        match self.lens {
            None => self.ray(x, y, offset),
            Some(lens) => self.lens_ray(self.ray(x, y, offset), lens, sampler.lens_2d()),
        }
    }

    /// The pinhole ray `pinhole` as it leaves `lens` (the vectors across it, its focus distance)
    /// at `u` (in [0, 1)^2, mapped to the disc by Shirley and Chiu's concentric map): it passes
    /// where the pinhole ray meets the plane of focus, so that plane is sharp (pbrt's thin lens).
    fn lens_ray(&self, pinhole: Ray, (across, up, focus): (Vec3, Vec3, f32), u: Vec2) -> Ray {
        // The pinhole ray's point on the plane of focus, `focus` along the view.
        let target = pinhole.at(focus / pinhole.dir.dot(self.forward));
        let d = crate::math::concentric_disk(u);
        let origin = pinhole.origin + across * d.x + up * d.y;
        Ray::new(origin, (target - origin).normalize())
    }

    /// The ray through the film position `pixel + offset` (offset in [0, 1)^2 within the pixel;
    /// a filter's reach beyond).
    pub fn ray(&self, x: u32, y: u32, offset: Vec2) -> Ray {
        let sx = 2.0 * (x as f32 + self.shift.x + offset.x) / self.width - 1.0;
        let sy = 1.0 - 2.0 * (y as f32 + self.shift.y + offset.y) / self.height;
        if self.orthographic {
            return Ray::new(self.origin + sx * self.right + sy * self.up, self.forward);
        }
        let dir = (self.forward + sx * self.right + sy * self.up).normalize();
        Ray::new(self.origin, dir)
    }

    /// The unit view direction through the image centre.
    pub fn forward(&self) -> Vec3 {
        self.forward
    }
}

/// Bins of a filter's distribution along one axis: its steps on either side of the centre.
const FILTER_BINS: usize = 2 * FILTER_STEPS;

/// A separable reconstruction filter tabulated for sampling along one axis: its distribution
/// over [-radius, radius] as a cumulative table of its [`FILTER_BINS`] steps
/// ([`PixelFilter::eval`] is constant on each), so a position drawn from it has the filter's
/// density exactly.
#[derive(Debug)]
pub struct FilterTable {
    radius: f32,
    /// `cdf[i]`: the mass of bins `0..i`, `cdf[FILTER_BINS]` = 1.
    cdf: Vec<f64>,
}

impl FilterTable {
    pub fn new(filter: PixelFilter) -> Self {
        let r = filter.radius() as f64;
        let h = 2.0 * r / FILTER_BINS as f64;
        let mut cdf = Vec::with_capacity(FILTER_BINS + 1);
        let mut total = 0.0;
        cdf.push(0.0);
        for i in 0..FILTER_BINS {
            total += filter.eval(-r + (i as f64 + 0.5) * h) * h;
            cdf.push(total);
        }
        for c in &mut cdf {
            *c /= total;
        }
        FilterTable { radius: filter.radius(), cdf }
    }

    /// The cumulative mass below offset `x` (clamped to the radius).
    fn cdf_at(&self, x: f64) -> f64 {
        let r = self.radius as f64;
        let p = ((x + r) / (2.0 * r) * FILTER_BINS as f64).clamp(0.0, FILTER_BINS as f64);
        let i = (p as usize).min(FILTER_BINS - 1);
        self.cdf[i] + (p - i as f64) * (self.cdf[i + 1] - self.cdf[i])
    }

    /// The offset (from the pixel's corner, as [`PinholeCamera::ray`] takes it) of the
    /// sample `u` in [0, 1) of pixel `pixel` of an image `size` pixels across: drawn from the
    /// filter restricted to the image.
    pub fn offset(&self, u: f32, pixel: u32, size: u32) -> f32 {
        let centre = pixel as f64 + 0.5;
        let (lo, hi) = (self.cdf_at(-centre), self.cdf_at(size as f64 - centre));
        let t = lo + u as f64 * (hi - lo);
        // The bin holding t (the last whose cdf is at most t), inverted linearly within it.
        let i = self.cdf.partition_point(|&c| c <= t).clamp(1, FILTER_BINS) - 1;
        let mass = self.cdf[i + 1] - self.cdf[i];
        let within = if mass > 0.0 { ((t - self.cdf[i]) / mass).clamp(0.0, 1.0) } else { 0.5 };
        let r = self.radius as f64;
        let x = -r + 2.0 * r * (i as f64 + within) / FILTER_BINS as f64;
        // Kept strictly inside the image, as a box sample is.
        (0.5 + x).clamp(-centre + 1e-6, size as f64 - centre - 1e-6) as f32
    }
}

/// A matrix's values row by row, in f32.
fn rows(m: DMat4) -> [f32; 16] {
    m.transpose().to_cols_array().map(|v| v as f32)
}

/// The near and far planes of [`exr_matrices`]' NDC depth, as pbrt-v4's perspective camera has.
const NEAR: f64 = 1e-2;
const FAR: f64 = 1e3;

/// The camera's matrices as pbrt-v4 writes them into an EXR header (`worldToCamera` and
/// `worldToNDC`): row-major, applied to column vectors (`M p`), in the scene file's world (the
/// scene's `origin` added back in f64). Camera space has x towards the image's right, y up and
/// z along the view (left-handed, as pbrt's); in NDC, after the division by w, x and y run over
/// [0, 1] from the image's left and bottom edges, and z over [0, 1] from a near plane at 0.01
/// to a far one at 1000.
pub fn exr_matrices(camera: &Camera, origin: DVec3, width: u32, height: u32) -> ([f32; 16], [f32; 16]) {
    let eye = origin + camera.position.as_dvec3();
    let forward = (camera.look_at - camera.position).as_dvec3().normalize();
    let right = forward.cross(camera.up.as_dvec3()).normalize();
    let up = right.cross(forward);
    // Rows: right, up, forward; then the eye moved to the origin.
    let rotation =
        DMat4::from_cols(right.extend(0.0), up.extend(0.0), forward.extend(0.0), DVec4::W).transpose();
    let world_to_camera = rotation * DMat4::from_translation(-eye);
    let aspect = width as f64 / height as f64;
    if let Some(h) = camera.orthographic {
        // x and y over the view's extent to [0, 1], z from the near plane to the far one.
        let half = 0.5 * h as f64;
        let ndc_from_camera = DMat4::from_cols_array(&[
            0.5 / (half * aspect),
            0.0,
            0.0,
            0.5,
            0.0,
            0.5 / half,
            0.0,
            0.5,
            0.0,
            0.0,
            1.0 / (FAR - NEAR),
            -NEAR / (FAR - NEAR),
            0.0,
            0.0,
            0.0,
            1.0,
        ])
        .transpose();
        return (rows(world_to_camera), rows(ndc_from_camera * world_to_camera));
    }
    let t = (0.5 * (camera.fov as f64).to_radians()).tan();
    let ndc_from_camera = DMat4::from_cols_array(&[
        0.5 / (t * aspect),
        0.0,
        0.5,
        0.0,
        0.0,
        0.5 / t,
        0.5,
        0.0,
        0.0,
        0.0,
        FAR / (FAR - NEAR),
        -FAR * NEAR / (FAR - NEAR),
        0.0,
        0.0,
        1.0,
        0.0,
    ])
    .transpose();
    (rows(world_to_camera), rows(ndc_from_camera * world_to_camera))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point seen through a pixel's centre lands at that pixel in NDC; the eye is camera
    /// space's origin and the view its +z; at 1e8 from the world's origin as at the origin.
    #[test]
    fn exr_matrices_map_pixels_to_ndc() {
        let cam = Camera {
            position: Vec3::ZERO,
            look_at: Vec3::new(0.3, -0.2, 1.0),
            up: Vec3::Y,
            fov: 50.0,
            orthographic: None,
            lens: None,
        };
        let (w, h) = (64u32, 48u32);
        let pinhole = PinholeCamera::new(&cam, w, h);
        for origin in [DVec3::ZERO, DVec3::new(1e3, -2e3, 5e2)] {
            let (to_camera, to_ndc) = exr_matrices(&cam, origin, w, h);
            let apply = |m: [f32; 16], p: DVec3| {
                let m = DMat4::from_cols_array(&m.map(f64::from)).transpose();
                m * p.extend(1.0)
            };
            let eye = apply(to_camera, origin);
            assert!(eye.truncate().length() < 1e-3, "{eye}");
            let ahead = apply(to_camera, origin + 2.0 * pinhole.forward().as_dvec3());
            assert!((ahead.truncate() - DVec3::new(0.0, 0.0, 2.0)).length() < 1e-3, "{ahead}");
            for (x, y) in [(0, 0), (63, 0), (10, 40), (32, 24)] {
                let ray = pinhole.ray(x, y, Vec2::splat(0.5));
                let p = origin + (ray.dir * 7.0).as_dvec3();
                let q = apply(to_ndc, p);
                let (nx, ny, nz) = (q.x / q.w, q.y / q.w, q.z / q.w);
                let want = ((x as f64 + 0.5) / w as f64, 1.0 - (y as f64 + 0.5) / h as f64);
                assert!(
                    (nx - want.0).abs() < 1e-4 && (ny - want.1).abs() < 1e-4,
                    "pixel ({x}, {y}): {nx} {ny}"
                );
                assert!(nz > 0.0 && nz < 1.0, "{nz}");
            }
        }
    }

    /// Positions drawn from a filter have its density: a histogram of many offsets against the
    /// filter's own integral over each bin, within the binomial noise (6 standard deviations),
    /// for a pixel far from the edges; at an edge pixel none falls outside the image.
    #[test]
    fn filter_offsets_follow_the_filter() {
        for filter in [
            PixelFilter::Tent { radius: 1.0 },
            PixelFilter::Gaussian { stddev: 0.5 },
            PixelFilter::Box { radius: 1.5 },
        ] {
            let table = FilterTable::new(filter);
            let r = filter.radius() as f64;
            let (n, bins) = (200_000u32, 16usize);
            let mut counts = vec![0u32; bins];
            for k in 0..n {
                let u = (k as f32 + 0.5) / n as f32;
                // Pixel 10 of 100: its offset from the centre.
                let x = table.offset(u, 10, 100) as f64 - 0.5;
                assert!(x.abs() <= r + 1e-6, "{filter:?}: {x}");
                counts[(((x + r) / (2.0 * r) * bins as f64) as usize).min(bins - 1)] += 1;
            }
            let integral = |a: f64, b: f64| {
                let m = 2000;
                (0..m).map(|i| filter.eval(a + (b - a) * (i as f64 + 0.5) / m as f64)).sum::<f64>() * (b - a)
                    / m as f64
            };
            let total = integral(-r, r);
            for (b, &c) in counts.iter().enumerate() {
                let a = -r + 2.0 * r * b as f64 / bins as f64;
                let p = integral(a, a + 2.0 * r / bins as f64) / total;
                let sigma = (n as f64 * p * (1.0 - p)).sqrt().max(1.0);
                assert!(
                    (c as f64 - n as f64 * p).abs() < 6.0 * sigma,
                    "{filter:?} bin {b}: {c} for {}",
                    n as f64 * p
                );
            }
            for (pixel, size) in [(0u32, 100u32), (99, 100)] {
                for k in 0..1000 {
                    let o = table.offset((k as f32 + 0.5) / 1000.0, pixel, size);
                    let at = pixel as f32 + o;
                    assert!(at > 0.0 && at < size as f32, "{filter:?}: pixel {pixel} at {at}");
                }
            }
        }
    }

    /// A crop's pixel looks where the same pixel of the whole film does.
    #[test]
    fn a_crop_window_is_part_of_the_film() {
        let cam = Camera {
            position: Vec3::ZERO,
            look_at: Vec3::Z,
            up: Vec3::Y,
            fov: 60.0,
            orthographic: None,
            lens: None,
        };
        let mut film = FilmSettings::new(20, 10, 1);
        film.window = Some(crate::scene::Window { film_width: 64, film_height: 48, x: 30, y: 5 });
        let crop = PinholeCamera::of_film(&cam, &film, 20, 10);
        let whole = PinholeCamera::new(&cam, 64, 48);
        let (a, b) = (crop.ray(3, 4, Vec2::splat(0.5)).dir, whole.ray(33, 9, Vec2::splat(0.5)).dir);
        assert!((a - b).length() < 1e-6, "{a} {b}");
    }

    #[test]
    fn centre_and_corners() {
        let cam = Camera {
            position: Vec3::ZERO,
            look_at: Vec3::Z,
            up: Vec3::Y,
            fov: 90.0,
            orthographic: None,
            lens: None,
        };
        let c = PinholeCamera::new(&cam, 100, 50);
        let centre = c.ray(50, 25, Vec2::ZERO);
        assert!((centre.dir - Vec3::Z).length() < 1e-6);
        // Top-left: up is +y, and right-handed with view +z puts image-right at -x.
        let tl = c.ray(0, 0, Vec2::ZERO).dir;
        assert!(tl.y > 0.0 && tl.x > 0.0, "{tl}");
        // Vertical fov 90: the top edge is at 45 degrees.
        let top = c.ray(50, 0, Vec2::ZERO).dir;
        assert!((top.y / top.z - 1.0).abs() < 1e-5, "{top}");
    }
}
