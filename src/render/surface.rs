//! The surface at a hit, computed once from the scene (not from the backend), so both backends
//! shade the same point the same way.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

use crate::accel::{Hit, Ray};
use crate::math::{offset_ray_origin, sphere_magnitude, triangle_magnitude};
use crate::scene::{Geometry, Scene};

/// Position, geometric normal (by winding, or outward for spheres; never flipped), shading
/// normal and texture coordinates of a hit.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    pub p: Vec3,
    pub ng: Vec3,
    pub ns: Vec3,
    /// The mesh's texture coordinates interpolated, else the barycentrics; on a sphere,
    /// longitude and latitude over [0, 1] (v = 1 at the +y pole).
    pub uv: Vec2,
    /// The largest absolute coordinate `p` was computed from, for [`offset_ray_origin`].
    pub magnitude: f32,
}

impl Surface {
    /// The origin of a ray leaving this point to the side of `n` (`ng` or `-ng`).
    pub fn origin(&self, n: Vec3) -> Vec3 {
        offset_ray_origin(self.p, n, self.magnitude)
    }
}

pub fn surface(scene: &Scene, ray: &Ray, hit: &Hit) -> Surface {
    // Only for a degenerate primitive, so computed only then.
    let fallback = || -ray.dir.normalize_or_zero();
    match &scene.shapes[hit.shape as usize].geometry {
        Geometry::Sphere { center, radius } => {
            // Re-project the hit onto the sphere: tighter than o + t d alone.
            let n = (ray.at(hit.t) - *center).try_normalize().unwrap_or_else(fallback);
            let uv = Vec2::new(n.z.atan2(n.x).rem_euclid(TAU) / TAU, 1.0 - n.y.clamp(-1.0, 1.0).acos() / PI);
            Surface {
                p: *center + n * *radius,
                ng: n,
                ns: n,
                uv,
                magnitude: sphere_magnitude(*center, *radius),
            }
        }
        Geometry::Triangles(mesh) => {
            let [a, b, c] = mesh.triangle(hit.prim);
            let (u, v) = (hit.u, hit.v);
            // Barycentric interpolation keeps the point's error small relative to its magnitude,
            // which the ray-origin offset relies on.
            let p = a * (1.0 - u - v) + b * u + c * v;
            let ng = (b - a).cross(c - a).try_normalize().unwrap_or_else(fallback);
            let [ia, ib, ic] = mesh.indices[hit.prim as usize].map(|i| i as usize);
            let ns = match &mesh.normals {
                Some(normals) => {
                    let n = normals[ia] * (1.0 - u - v) + normals[ib] * u + normals[ic] * v;
                    n.normalize_or(ng)
                }
                None => ng,
            };
            let uv = match &mesh.uvs {
                Some(uvs) => uvs[ia] * (1.0 - u - v) + uvs[ib] * u + uvs[ic] * v,
                None => Vec2::new(u, v),
            };
            Surface { p, ng, ns, uv, magnitude: triangle_magnitude(a, b, c) }
        }
    }
}
