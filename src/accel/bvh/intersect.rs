//! Ray/primitive tests of the BVH: the watertight triangle test and a precise sphere test.

use glam::{Mat3, Vec3};

use super::Prim;
use crate::accel::{Hit, Ray};

/// The per-ray part of the watertight ray/triangle test (Woop, Benthin & Wald, "Watertight
/// Ray/Triangle Intersection", JCGT 2013): the ray is sheared so that it points along +z, and
/// the 2D edge functions decide containment. Edges shared by two triangles are tested with the
/// same arithmetic from both sides, so a ray can never fall between them.
pub struct RayTri {
    origin: Vec3,
    /// Rows: e_kx - Sx e_kz, e_ky - Sy e_kz, Sz e_kz. Applied to a vertex (relative to the
    /// origin) it gives Woop's sheared coordinates with the same roundings as the paper's
    /// formulas (the other products are by exact 0 and 1), and each vertex is transformed the
    /// same way whichever triangle it belongs to, which is what keeps shared edges watertight.
    /// As a matrix it avoids indexing vectors by run-time axis numbers per triangle.
    shear: Mat3,
}

impl RayTri {
    /// The axes `[kx, ky, kz]` (kz the dominant direction) and shear `[Sx, Sy, Sz]` of a ray.
    pub fn axes(ray: &Ray) -> ([usize; 3], [f32; 3]) {
        let d = ray.dir;
        let a = d.abs();
        let kz = if a.x > a.y && a.x > a.z {
            0
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
        ([kx, ky, kz], [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]])
    }

    pub fn new(ray: &Ray) -> Self {
        let ([kx, ky, kz], [sx, sy, sz]) = Self::axes(ray);
        let mut rows = [[0.0f32; 3]; 3];
        rows[0][kx] = 1.0;
        rows[0][kz] = -sx;
        rows[1][ky] = 1.0;
        rows[1][kz] = -sy;
        rows[2][kz] = sz;
        RayTri { origin: ray.origin, shear: Mat3::from_cols_array_2d(&rows).transpose() }
    }

    /// The hit with triangle `v` within [0, t_max]: `(t, u, v)` with `u`, `v` the barycentric
    /// weights of the second and third vertices (Embree's convention).
    #[inline(always)]
    pub fn hit(&self, v: &[Vec3; 3], t_max: f32) -> Option<(f32, f32, f32)> {
        let a = self.shear * (v[0] - self.origin);
        let b = self.shear * (v[1] - self.origin);
        let c = self.shear * (v[2] - self.origin);
        let mut u = c.x * b.y - c.y * b.x;
        let mut w = a.x * c.y - a.y * c.x;
        let mut x = b.x * a.y - b.y * a.x;
        // On an edge the f32 products can round to exactly zero: decide in f64 instead.
        if u == 0.0 || w == 0.0 || x == 0.0 {
            let (ax, ay, bx, by, cx, cy) =
                (a.x as f64, a.y as f64, b.x as f64, b.y as f64, c.x as f64, c.y as f64);
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
        let t_scaled = u * a.z + w * b.z + x * c.z;
        // t = t_scaled / det must lie in (error bound, t_max]; compare without dividing, with
        // det's sign folded into both sides.
        let (t_signed, det_abs) = if det < 0.0 { (-t_scaled, -det) } else { (t_scaled, det) };
        let bound = t_error_bound([a.x, b.x, c.x], [a.y, b.y, c.y], [a.z, b.z, c.z], [u, w, x]);
        if t_signed <= bound || t_signed > t_max * det_abs {
            return None;
        }
        let inv = 1.0 / det;
        Some((t_scaled * inv, w * inv, x * inv))
    }
}

/// gamma(n) of Higham's error analysis: a bound on the relative error of n roundings.
pub const fn gamma(n: f32) -> f32 {
    let u = f32::EPSILON * 0.5;
    n * u / (1.0 - n * u)
}

/// A conservative bound on the rounding error of the watertight test's scaled distance (t times
/// det), from the sheared vertex coordinates and the edge functions (Pharr, Jakob & Humphreys,
/// pbrt 3rd ed., section 3.9.6). A hit closer than this may really lie behind the origin: near a
/// surface, a ray leaving it could otherwise hit the surface it starts on, because t is computed
/// from vertices that may be far from the origin.
#[inline(always)]
pub fn t_error_bound(x: [f32; 3], y: [f32; 3], z: [f32; 3], e: [f32; 3]) -> f32 {
    let max = |v: [f32; 3]| v[0].abs().max(v[1].abs()).max(v[2].abs());
    let (max_x, max_y, max_z, max_e) = (max(x), max(y), max(z), max(e));
    let delta_x = gamma(5.0) * (max_x + max_z);
    let delta_y = gamma(5.0) * (max_y + max_z);
    let delta_z = gamma(3.0) * max_z;
    let delta_e = 2.0 * (gamma(2.0) * max_x * max_y + delta_y * max_x + delta_x * max_y);
    3.0 * (gamma(3.0) * max_e * max_z + delta_e * max_z + delta_z * max_e)
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

/// One primitive's hit within [0, t_max], as a [`Hit`].
#[inline(always)]
pub fn prim_hit(p: &Prim, ray: &Ray, rt: &RayTri, t_max: f32) -> Option<Hit> {
    match *p {
        Prim::Triangle { ref v, shape, prim } => {
            rt.hit(v, t_max).map(|(t, u, w)| Hit { t, shape, prim, u, v: w })
        }
        Prim::Sphere { center, radius, shape } => {
            sphere(ray, center, radius, t_max).map(|t| Hit { t, shape, prim: 0, u: 0.0, v: 0.0 })
        }
        Prim::Quad { ref v, shape, prim, rot } => {
            // The first triangle, then the second within the first's distance (a tie goes to
            // the second, as in the leaf test).
            let [a, b] = Prim::quad_triangles(v, rot);
            let first = rt.hit(&a, t_max).map(|(t, u, w)| Hit { t, shape, prim, u, v: w });
            let second = rt.hit(&b, first.map_or(t_max, |h| h.t));
            second.map(|(t, u, w)| Hit { t, shape, prim: prim + 1, u, v: w }).or(first)
        }
    }
}
