//! The surface at a hit, computed once from the scene (not from the backend), so both backends
//! shade the same point the same way.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;

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
    /// longitude and latitude over [0, 1] (v = 1 at the +y pole). In a render without textures,
    /// the hit's barycentrics.
    pub uv: Vec2,
    /// The second set of texture coordinates (a glTF's `TEXCOORD_1`), else `uv`.
    pub uv1: Vec2,
    /// The vertex colour (a glTF's `COLOR_0`), else white.
    pub color: Vec3,
    /// The largest absolute coordinate `p` was computed from, for [`offset_ray_origin`].
    pub magnitude: f32,
    /// dp/du and dp/dv of the triangle's texture coordinates (those its normal map reads), only
    /// where the material has a normal or height map (zero elsewhere); with a mesh's tangents,
    /// the tangent and the bitangent (`cross(ns, tangent) * w`) instead.
    pub dpdu: Vec3,
    pub dpdv: Vec3,
    /// The hit's primitive and barycentrics, for [`Scene::solid_point`].
    pub prim: u32,
    pub bary: (f32, f32),
}

impl Surface {
    /// The origin of a ray leaving this point to the side of `n` (`ng` or `-ng`).
    pub fn origin(&self, n: Vec3) -> Vec3 {
        offset_ray_origin(self.p, n, self.magnitude)
    }
}

/// Every triangle's unit geometric normal (zero for a degenerate one) and the magnitude of its
/// corners' coordinates, made once a render: a hit reads them with one load instead of a cross
/// product, a square root and a division on the path from the hit to everything after it. Only
/// for meshes of at most [`FaceNormals::MAX_TRIANGLES`]: a larger table no longer stays in the
/// cache, and a miss costs more than the arithmetic it saves (measured on the terrain).
pub struct FaceNormals {
    /// Per shape (empty for a sphere or a large mesh), per triangle: `(n, magnitude)`.
    shapes: Vec<Vec<Vec4>>,
}

impl FaceNormals {
    /// The largest mesh given a table: 1 MiB of it, what a core's L2 cache holds.
    pub const MAX_TRIANGLES: usize = 1 << 16;

    pub fn new(scene: &Scene) -> FaceNormals {
        let shapes = scene
            .shapes
            .iter()
            .map(|shape| match &shape.geometry {
                // An instance's triangles are shared with other shapes: a table per shape would
                // copy what instancing saves.
                Geometry::Triangles(mesh)
                    if mesh.indices.len() <= Self::MAX_TRIANGLES && mesh.instance.is_none() =>
                {
                    (0..mesh.indices.len() as u32)
                        .into_par_iter()
                        .map(|prim| {
                            let [a, b, c] = mesh.triangle(prim);
                            let n = face_normal(a, b, c).unwrap_or(Vec3::ZERO);
                            n.extend(triangle_magnitude(a, b, c))
                        })
                        .collect()
                }
                _ => Vec::new(),
            })
            .collect();
        FaceNormals { shapes }
    }

    /// Bytes of the table.
    pub fn bytes(&self) -> u64 {
        self.shapes.iter().map(|s| s.capacity() * size_of::<Vec4>()).sum::<usize>() as u64
    }
}

/// dp/du and dp/dv of a triangle with corners `p` and texture coordinates `t`: zero when its
/// texture coordinates are degenerate.
pub fn uv_derivatives(p: [Vec3; 3], t: [Vec2; 3]) -> (Vec3, Vec3) {
    let (d1, d2) = (t[1] - t[0], t[2] - t[0]);
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let det = d1.x * d2.y - d1.y * d2.x;
    if det.abs() < 1e-20 || !det.is_finite() {
        return (Vec3::ZERO, Vec3::ZERO);
    }
    ((e1 * d2.y - e2 * d1.y) / det, (e2 * d1.x - e1 * d2.x) / det)
}

/// The shading normal `n` (unit) bent by a tangent-space normal `m` (x along dp/du, y along
/// dp/dv, z along `n`, as glTF's normal maps are): the frame is dp/du made orthogonal to `n`, and
/// the bitangent on the side dp/dv is. `n` itself when the derivatives are degenerate.
pub fn apply_normal_map(n: Vec3, dpdu: Vec3, dpdv: Vec3, m: Vec3) -> Vec3 {
    let Some(t) = (dpdu - n * n.dot(dpdu)).try_normalize() else { return n };
    let b = n.cross(t);
    let b = if b.dot(dpdv) < 0.0 { -b } else { b };
    (t * m.x + b * m.y + n * m.z).try_normalize().unwrap_or(n)
}

/// The shading normal `n` raised toward the geometric normal `ng` just enough that the mirror
/// reflection of `wo` about it stays above the surface (`ng`, `wo` and `n` unit, `wo` on `ng`'s
/// side), as Cycles' bump-map correction does: a normal map or a smooth mesh's interpolated
/// normal that turns away from the viewer would otherwise leave the view below the shading
/// hemisphere, where the path ends black. `n` itself when its reflection is already at least
/// `min(0.9 cos, 0.01)` above the surface (`cos` the view's geometric cosine).
///
/// The raised normal stays in the plane of `ng` and `n`, at angle `theta` from `ng`: with `wo`
/// at `(x, z)` in that plane's axes (`x` along `n`'s tangential part), the reflection's height
/// is `z cos 2 theta + x sin 2 theta`, so `2 theta = atan2(x, z) + acos(t / |(x, z)|)`.
#[inline(always)]
pub fn valid_reflection(ng: Vec3, wo: Vec3, n: Vec3) -> Vec3 {
    let z = wo.dot(ng);
    let threshold = (0.9 * z).min(0.01);
    let r = n * (2.0 * n.dot(wo)) - wo;
    if r.dot(ng) >= threshold || z <= 0.0 {
        return n;
    }
    let Some(axis) = (n - ng * n.dot(ng)).try_normalize() else { return n };
    let x = wo.dot(axis);
    let length = (x * x + z * z).sqrt();
    let theta = 0.5 * (x.atan2(z) + (threshold / length).clamp(-1.0, 1.0).acos());
    (ng * theta.cos() + axis * theta.sin()).normalize_or(n)
}

/// The shading normal `n` (unit) of a surface displaced along it by the height field `h` of the
/// texture coordinates: the normal of dp/du + n dh/du and dp/dv + n dh/dv (pbrt's bump mapping,
/// the normal's own change left out), turned to `n`'s side. `n` itself when the derivatives are
/// degenerate.
pub fn apply_height(n: Vec3, dpdu: Vec3, dpdv: Vec3, dhdu: f32, dhdv: f32) -> Vec3 {
    let bent = (dpdu + n * dhdu).cross(dpdv + n * dhdv);
    match bent.try_normalize() {
        Some(b) if dpdu.cross(dpdv).dot(n) >= 0.0 => b,
        Some(b) => -b,
        None => n,
    }
}

/// The unit normal of a triangle by its winding, `None` when it is degenerate.
fn face_normal(a: Vec3, b: Vec3, c: Vec3) -> Option<Vec3> {
    (b - a).cross(c - a).try_normalize()
}

/// The surface at `hit`, its triangle's normal computed from its corners.
pub fn surface(scene: &Scene, ray: &Ray, hit: &Hit) -> Surface {
    surface_from(scene, ray, hit, true, None)
}

/// The surface at `hit`, its triangle's normal read from `faces` where it has a table (the same
/// values as [`surface`], bit for bit). With `textured` false (a render that reads no texture
/// and no vertex colour) the texture coordinates are the barycentrics, the colour white and
/// the normal-map frame zero: none of them is computed.
#[inline(always)]
pub fn surface_with(scene: &Scene, faces: &FaceNormals, ray: &Ray, hit: &Hit, textured: bool) -> Surface {
    surface_from(scene, ray, hit, textured, Some(faces))
}

#[inline(always)]
fn surface_from(scene: &Scene, ray: &Ray, hit: &Hit, textured: bool, faces: Option<&FaceNormals>) -> Surface {
    // Only for a degenerate primitive, so computed only then.
    let fallback = || -ray.dir.normalize_or_zero();
    match &scene.shapes[hit.shape as usize].geometry {
        Geometry::Sphere { center, radius } => {
            // Re-project the hit onto the sphere: tighter than o + t d alone.
            let n = (ray.at(hit.t) - *center).try_normalize().unwrap_or_else(fallback);
            let uv = match textured {
                true => {
                    Vec2::new(n.z.atan2(n.x).rem_euclid(TAU) / TAU, 1.0 - n.y.clamp(-1.0, 1.0).acos() / PI)
                }
                false => Vec2::new(hit.u, hit.v),
            };
            Surface {
                p: *center + n * *radius,
                ng: n,
                ns: n,
                uv,
                uv1: uv,
                color: Vec3::ONE,
                magnitude: sphere_magnitude(*center, *radius),
                dpdu: Vec3::ZERO,
                dpdv: Vec3::ZERO,
                prim: hit.prim,
                bary: (hit.u, hit.v),
            }
        }
        Geometry::Triangles(mesh) => {
            let [a, b, c] = mesh.triangle(hit.prim);
            let (u, v) = (hit.u, hit.v);
            // Barycentric interpolation keeps the point's error small relative to its magnitude,
            // which the ray-origin offset relies on.
            let p = a * (1.0 - u - v) + b * u + c * v;
            // The triangle's normal and magnitude from the table, where it has one.
            let (ng, magnitude) =
                match faces.and_then(|f| f.shapes[hit.shape as usize].get(hit.prim as usize)) {
                    Some(f) => {
                        let n = f.truncate();
                        ((n != Vec3::ZERO).then_some(n), f.w)
                    }
                    None => (face_normal(a, b, c), triangle_magnitude(a, b, c)),
                };
            let magnitude = match &mesh.instance {
                None => magnitude,
                Some(i) => magnitude.max(i.magnitude(mesh.local_triangle(hit.prim))),
            };
            let ng = ng.unwrap_or_else(fallback);
            let [ia, ib, ic] = mesh.indices[hit.prim as usize].map(|i| i as usize);
            let ns = match &mesh.normals {
                Some(normals) => {
                    let n = normals[ia] * (1.0 - u - v) + normals[ib] * u + normals[ic] * v;
                    match &mesh.instance {
                        None => n.normalize_or(ng),
                        Some(i) => (i.normals * n).normalize_or(ng),
                    }
                }
                None => ng,
            };
            if !textured {
                let (uv, zero) = (Vec2::new(u, v), Vec3::ZERO);
                let (dpdu, dpdv, color) = (zero, zero, Vec3::ONE);
                return Surface {
                    p,
                    ng,
                    ns,
                    uv,
                    uv1: uv,
                    color,
                    magnitude,
                    dpdu,
                    dpdv,
                    prim: hit.prim,
                    bary: (u, v),
                };
            }
            let uv = mesh.uv(0, hit.prim, (u, v)).unwrap_or(Vec2::new(u, v));
            let shape = &scene.shapes[hit.shape as usize];
            let (mut uv1, mut color) = (uv, Vec3::ONE);
            let mut tangents = None;
            if let Some(at) = &mesh.attributes {
                uv1 = mesh.uv(1, hit.prim, (u, v)).unwrap_or(uv);
                color = at.colors.as_deref().map_or(color, |c| mesh.interpolate(c, hit.prim, (u, v)));
                tangents = at.tangents.as_deref();
            }
            let bumped = || {
                let maps = scene.maps(shape.material);
                (maps.normal.is_some() || maps.height.is_some() || maps.layer.clearcoat_normal.is_some())
                    .then_some(maps)
            };
            // (The maps are looked up only for a mesh that could carry a frame.)
            let frame = mesh.uvs.is_some() || mesh.attributes.is_some();
            let (dpdu, dpdv) = match (frame.then(bumped).flatten(), tangents) {
                (None, _) => (Vec3::ZERO, Vec3::ZERO),
                (Some(_), Some(tangents)) => {
                    let t = mesh.interpolate(tangents, hit.prim, (u, v));
                    let dir = match &mesh.instance {
                        None => t.truncate(),
                        Some(i) => i.to_world.transform_vector3(t.truncate()),
                    };
                    (dir, ns.cross(dir) * if t.w < 0.0 { -1.0 } else { 1.0 })
                }
                (Some(maps), None) => {
                    let normal = maps.normal.or(maps.layer.clearcoat_normal);
                    let set = normal.map_or(0, |(t, _)| scene.textures[t as usize].set());
                    match mesh.uvs(set) {
                        Some(uvs) => uv_derivatives([a, b, c], [uvs[ia], uvs[ib], uvs[ic]]),
                        None => (Vec3::ZERO, Vec3::ZERO),
                    }
                }
            };
            Surface { p, ng, ns, uv, uv1, color, magnitude, dpdu, dpdv, prim: hit.prim, bary: (u, v) }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic spread of unit vectors (a Fibonacci sphere).
    fn directions(n: usize) -> impl Iterator<Item = Vec3> {
        (0..n).map(move |i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let phi = i as f32 * 2.399_963;
            let r = (1.0 - z * z).sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
    }

    #[test]
    fn a_raised_normal_reflects_the_view_above_the_surface_and_a_valid_one_is_kept() {
        let ng = Vec3::Z;
        let (mut raised, mut kept) = (0, 0);
        for wo in directions(400).filter(|w| w.z > 0.02) {
            for n in directions(400).filter(|n| n.z > 0.05) {
                let m = valid_reflection(ng, wo, n);
                let threshold = (0.9 * wo.z).min(0.01);
                let r = n * (2.0 * n.dot(wo)) - wo;
                if r.z >= threshold {
                    assert_eq!(m, n, "a valid normal is kept");
                    kept += 1;
                    continue;
                }
                raised += 1;
                assert!((m.length() - 1.0).abs() < 1e-5, "{m}");
                let rm = m * (2.0 * m.dot(wo)) - wo;
                assert!(
                    (rm.z - threshold).abs() < 2e-3,
                    "wo {wo} n {n}: reflection height {} for {threshold}",
                    rm.z
                );
                assert!(m.dot(wo) > 0.0, "the view is above the raised normal");
                // Raised toward ng, in the plane of ng and n, never past it.
                assert!(m.z > n.z - 1e-6, "{m} is lower than {n}");
                let (tn, tm) = (n.truncate().normalize(), m.truncate());
                assert!(
                    tm.length() < 1e-4 || (tm.normalize() - tn).length() < 1e-3,
                    "{m} left the plane of {n}"
                );
            }
        }
        assert!(raised > 1000 && kept > 1000, "raised {raised}, kept {kept}");
    }
}
