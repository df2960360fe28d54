//! Ray/primitive tests of the BVH: the watertight triangle test and a precise sphere test.

use glam::Vec3;

use crate::accel::Ray;

/// The per-ray part of the watertight ray/triangle test (Woop, Benthin & Wald, "Watertight
/// Ray/Triangle Intersection", JCGT 2013): the ray is sheared so that it points along +z, and
/// the 2D edge functions decide containment. Edges shared by two triangles are tested with the
/// same arithmetic from both sides, so a ray can never fall between them.
pub struct RayTri {
    origin: Vec3,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

impl RayTri {
    pub fn new(ray: &Ray) -> Self {
        let d = ray.dir;
        let a = d.abs();
        let kz = if a.x > a.y {
            if a.x > a.z {
                0
            } else {
                2
            }
        } else if a.y > a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding: swap when the dominant direction is negative.
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        RayTri {
            origin: ray.origin,
            kx,
            ky,
            kz,
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
        }
    }

    /// The hit with triangle `v` within [0, t_max]: `(t, u, v)` with `u`, `v` the barycentric
    /// weights of the second and third vertices (Embree's convention).
    #[inline(always)]
    pub fn hit(&self, v: &[Vec3; 3], t_max: f32) -> Option<(f32, f32, f32)> {
        let a = v[0] - self.origin;
        let b = v[1] - self.origin;
        let c = v[2] - self.origin;
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let ax = a[kx] - self.sx * a[kz];
        let ay = a[ky] - self.sy * a[kz];
        let bx = b[kx] - self.sx * b[kz];
        let by = b[ky] - self.sy * b[kz];
        let cx = c[kx] - self.sx * c[kz];
        let cy = c[ky] - self.sy * c[kz];
        let mut u = cx * by - cy * bx;
        let mut w = ax * cy - ay * cx;
        let mut x = bx * ay - by * ax;
        // On an edge the f32 products can round to exactly zero: decide in f64 instead.
        if u == 0.0 || w == 0.0 || x == 0.0 {
            let (ax, ay, bx, by, cx, cy) = (
                ax as f64, ay as f64, bx as f64, by as f64, cx as f64, cy as f64,
            );
            u = (cx * by - cy * bx) as f32;
            w = (ax * cy - ay * cx) as f32;
            x = (bx * ay - by * ax) as f32;
        }
        if (u < 0.0 || w < 0.0 || x < 0.0) && (u > 0.0 || w > 0.0 || x > 0.0) {
            return None;
        }
        let det = u + w + x;
        if det == 0.0 {
            return None;
        }
        let az = self.sz * a[kz];
        let bz = self.sz * b[kz];
        let cz = self.sz * c[kz];
        let t_scaled = u * az + w * bz + x * cz;
        // t = t_scaled / det must lie in [0, t_max]; compare without dividing, by det's sign.
        if det > 0.0 {
            if t_scaled < 0.0 || t_scaled > t_max * det {
                return None;
            }
        } else if t_scaled > 0.0 || t_scaled < t_max * det {
            return None;
        }
        let inv = 1.0 / det;
        Some((t_scaled * inv, w * inv, x * inv))
    }
}

/// The nearest hit of `ray` with a sphere within [0, t_max], from outside or inside. Uses the
/// formulation of Haines et al. ("Precision Improvements for Ray/Sphere Intersection", Ray
/// Tracing Gems ch. 7): the discriminant from the perpendicular distance, and the two roots from
/// q without cancellation.
#[inline(always)]
pub fn sphere(ray: &Ray, center: Vec3, radius: f32, t_max: f32) -> Option<f32> {
    let f = ray.origin - center;
    let d = ray.dir;
    let a = d.length_squared();
    let b = -f.dot(d);
    let l = f + (b / a) * d;
    let disc = radius * radius - l.length_squared();
    if disc < 0.0 {
        return None;
    }
    let c = f.length_squared() - radius * radius;
    let q = b + b.signum() * (a * disc).sqrt();
    if q == 0.0 {
        return None;
    }
    let (t0, t1) = (c / q, q / a);
    let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    if near >= 0.0 && near <= t_max {
        Some(near)
    } else if far >= 0.0 && far <= t_max {
        Some(far)
    } else {
        None
    }
}
