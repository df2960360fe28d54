//! The surface at a hit, computed once from the scene (not from the backend), so both backends
//! shade the same point the same way.

use glam::Vec3;

use crate::accel::{Hit, Ray};
use crate::scene::{Geometry, Scene};

/// Position, geometric normal (by winding, or outward for spheres; never flipped) and shading
/// normal of a hit.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    pub p: Vec3,
    pub ng: Vec3,
    pub ns: Vec3,
}

pub fn surface(scene: &Scene, ray: &Ray, hit: &Hit) -> Surface {
    let fallback = -ray.dir.normalize_or_zero();
    match &scene.shapes[hit.shape as usize].geometry {
        Geometry::Sphere { center, radius } => {
            // Re-project the hit onto the sphere: tighter than o + t d alone.
            let n = (ray.at(hit.t) - *center).normalize_or(fallback);
            Surface { p: *center + n * *radius, ng: n, ns: n }
        }
        Geometry::Triangles(mesh) => {
            let [a, b, c] = mesh.triangle(hit.prim);
            let (u, v) = (hit.u, hit.v);
            // Barycentric interpolation keeps the point's error small relative to its magnitude,
            // which the ray-origin offset relies on.
            let p = a * (1.0 - u - v) + b * u + c * v;
            let ng = (b - a).cross(c - a).normalize_or(fallback);
            let ns = match &mesh.normals {
                Some(normals) => {
                    let [ia, ib, ic] = mesh.indices[hit.prim as usize];
                    let n = normals[ia as usize] * (1.0 - u - v)
                        + normals[ib as usize] * u
                        + normals[ic as usize] * v;
                    n.normalize_or(ng)
                }
                None => ng,
            };
            Surface { p, ng, ns }
        }
    }
}
