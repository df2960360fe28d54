//! Primary rays of a pinhole camera. Pixel (0, 0) is the top-left corner of the image.

use glam::{Vec2, Vec3};

use crate::accel::Ray;
use crate::scene::Camera;

/// A camera resolved for one image size.
#[derive(Clone, Copy, Debug)]
pub struct PinholeCamera {
    origin: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    width: f32,
    height: f32,
}

impl PinholeCamera {
    pub fn new(camera: &Camera, width: u32, height: u32) -> Self {
        let forward = (camera.look_at - camera.position).normalize();
        // Right-handed: with y up and the view along +z, +x is on the left of the image.
        let right = forward.cross(camera.up).normalize();
        let up = right.cross(forward);
        let tan_half = (camera.fov.to_radians() * 0.5).tan();
        let aspect = width as f32 / height as f32;
        PinholeCamera {
            origin: camera.position,
            forward,
            right: right * tan_half * aspect,
            up: up * tan_half,
            width: width as f32,
            height: height as f32,
        }
    }

    /// The ray through the film position `pixel + offset` (offset in [0, 1)^2 within the pixel).
    pub fn ray(&self, x: u32, y: u32, offset: Vec2) -> Ray {
        let sx = 2.0 * (x as f32 + offset.x) / self.width - 1.0;
        let sy = 1.0 - 2.0 * (y as f32 + offset.y) / self.height;
        let dir = (self.forward + sx * self.right + sy * self.up).normalize();
        Ray::new(self.origin, dir)
    }

    /// The unit view direction through the image centre.
    pub fn forward(&self) -> Vec3 {
        self.forward
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_and_corners() {
        let cam = Camera { position: Vec3::ZERO, look_at: Vec3::Z, up: Vec3::Y, fov: 90.0 };
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
