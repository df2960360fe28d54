//! Primary rays of a pinhole or an orthographic camera. Pixel (0, 0) is the top-left corner of
//! the image.

use glam::{DMat4, DVec3, DVec4, Vec2, Vec3};

use crate::accel::Ray;
use crate::scene::{Camera, FilmSettings};

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
    /// A crop: where the image's top-left pixel lies on the film.
    shift: Vec2,
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
            shift: Vec2::ZERO,
        }
    }

    /// The camera of `film`'s image rendered at `width` x `height`: its crop window when the
    /// image has the film's own size (another size is the whole film, resized).
    pub fn of_film(camera: &Camera, film: &FilmSettings, width: u32, height: u32) -> Self {
        let window = film.window.filter(|_| (width, height) == (film.width, film.height));
        let mut c = match window {
            Some(w) => PinholeCamera::new(camera, w.film_width, w.film_height),
            None => PinholeCamera::new(camera, width, height),
        };
        if let Some(w) = window {
            c.shift = Vec2::new(w.x as f32, w.y as f32);
        }
        c
    }

    /// The ray of a path sample through pixel `(x, y)`: its position in the pixel from
    /// `sampler`, and with a lens the point on the lens too (two more numbers).
    #[inline]
    pub fn generate(&self, x: u32, y: u32, sampler: &mut crate::render::sampler::Sampler) -> Ray {
        self.generate_at(x, y, sampler).0
    }

    /// [`PinholeCamera::generate`], and the sample's position in the pixel ([0, 1)^2), which a
    /// splatted filter weighs.
    #[inline]
    pub fn generate_at(&self, x: u32, y: u32, sampler: &mut crate::render::sampler::Sampler) -> (Ray, Vec2) {
        let offset = sampler.pixel_2d();
        let ray = match self.lens {
            None => self.ray(x, y, offset),
            Some(lens) => self.lens_ray(self.ray(x, y, offset), lens, sampler.lens_2d()),
        };
        (ray, offset)
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

    /// The ray through the film position `pixel + offset` (offset in [0, 1)^2 within the pixel).
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
