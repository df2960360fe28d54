//! The lights of a scene ready to sample: each [`Emitter`] samples a direction toward itself from
//! a receiving point and gives the density of that choice for multiple importance sampling.
//! Point and spot lights, the sun (a cone of directions), a uniform or cloudy sky, an
//! environment map, and emissive
//! shapes (triangle meshes sampled by area, spheres by the cone they subtend).

use std::f32::consts::PI;

use std::sync::Arc;

use glam::{Vec2, Vec3};

use super::sky_table::{sky_direction, sky_lookup};
use crate::math::{
    offset_ray_origin, one_minus_cos_between, sphere_magnitude, uniform_cone, uniform_sphere,
    uniform_triangle, Distribution1D, Distribution2D, Frame, FOUR_PI,
};
use crate::scene::environment::EnvironmentMap;
use crate::scene::sky::CloudySky;
use crate::scene::{Geometry, Light, Mesh, Scene};

/// One light, ready to sample.
#[derive(Clone, Debug)]
pub enum Emitter {
    Point {
        position: Vec3,
        intensity: Vec3,
    },
    Spot {
        position: Vec3,
        direction: Vec3,
        intensity: Vec3,
        cos_total: f32,
        cos_falloff_start: f32,
    },
    Sun {
        frame: Frame,
        radiance: Vec3,
        one_minus_cos: f32,
    },
    Sky {
        radiance: Vec3,
    },
    /// A sky whose radiance varies with direction, importance-sampled from a table over
    /// (phi / 2 pi, cos theta) of the upper hemisphere: cells of equal solid angle.
    /// Light it sheds is looked up bilinearly in a radiance table of the same cells (the
    /// procedural clouds cost too much to evaluate at every vertex); what the eye sees directly
    /// or through mirrors is the exact procedural sky.
    CloudySky {
        sky: Box<CloudySky>,
        table: Box<Distribution2D>,
        radiance: Vec<Vec3>,
    },
    /// An environment map, sampled by its pixels' luminance times the solid angle each covers.
    /// Light it sheds is the pixel's, constant over the pixel as the density is; what the eye
    /// sees directly (or through mirrors) is interpolated between pixels.
    Environment {
        map: Arc<EnvironmentMap>,
        table: Box<Distribution2D>,
    },
    Mesh {
        shape: u32,
        triangles: Distribution1D,
        area: f32,
        emission: Vec3,
        /// The scene's cut-outs, when this shape has one: a point sampled on it emits times
        /// its coverage there ([`Cutouts::coverage`]), what a ray finding it sees on average.
        cutouts: Option<std::sync::Arc<crate::scene::cutout::Cutouts>>,
    },
    Sphere {
        shape: u32,
        center: Vec3,
        radius: f32,
        emission: Vec3,
    },
}

/// Where a shadow ray toward a light sample ends.
#[derive(Clone, Copy, Debug)]
pub enum ShadowEnd {
    /// A point (already moved off the light's surface toward the receiver).
    Point(Vec3),
    /// Infinitely far along the sampled direction.
    Infinite,
}

/// A sampled light direction at a receiving point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Incident radiance along `wi` if unoccluded (intensity / r^2 for a point light).
    pub radiance: Vec3,
    pub wi: Vec3,
    /// Solid-angle density including the light's selection probability (the selection
    /// probability alone for a point light).
    pub pdf: f32,
    /// Point lights cannot be hit by a BSDF sample, so they take no MIS weight.
    pub delta: bool,
    pub end: ShadowEnd,
    /// Which light: for the component split's diffuse-source test.
    pub light: u32,
}

impl Emitter {
    /// Samples this light, emitter number `light` picked with probability `select`, as seen
    /// from `p`.
    pub fn sample(&self, scene: &Scene, light: u32, select: f32, p: Vec3, u: Vec2) -> Option<LightSample> {
        match self {
            Emitter::Point { position, intensity } => {
                point_sample(p, *position, select, light, |_| *intensity)
            }
            Emitter::Spot { position, direction, intensity, cos_total, cos_falloff_start } => {
                point_sample(p, *position, select, light, |wi| {
                    *intensity * Light::spot_falloff(-wi.dot(*direction), *cos_total, *cos_falloff_start)
                })
            }
            Emitter::Sun { frame, radiance, one_minus_cos } => Some(LightSample {
                radiance: *radiance,
                wi: frame.to_world(uniform_cone(u, *one_minus_cos)),
                pdf: select / (2.0 * PI * one_minus_cos),
                delta: false,
                end: ShadowEnd::Infinite,
                light,
            }),
            Emitter::Sky { radiance } => Some(LightSample {
                radiance: *radiance,
                wi: uniform_sphere(u),
                pdf: select / FOUR_PI,
                delta: false,
                end: ShadowEnd::Infinite,
                light,
            }),
            Emitter::CloudySky { table, radiance, .. } => {
                let (uv, pdf) = table.sample(u);
                let wi = sky_direction(uv);
                Some(LightSample {
                    radiance: sky_lookup(radiance, uv),
                    wi,
                    pdf: select * pdf / (2.0 * PI),
                    delta: false,
                    end: ShadowEnd::Infinite,
                    light,
                })
            }
            Emitter::Environment { map, table } => {
                let (uv, pdf) = table.sample(u);
                let (wi, sin) = map.direction(uv);
                if sin <= 0.0 || pdf <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    radiance: map.pixel(uv),
                    wi,
                    pdf: select * pdf / (2.0 * PI * PI * sin),
                    delta: false,
                    end: ShadowEnd::Infinite,
                    light,
                })
            }
            Emitter::Mesh { triangles, area, .. } => {
                // u.x picks the triangle, then, rescaled, the point within it.
                let (t, _, ux) = triangles.sample_reuse(u.x);
                self.sample_triangle(scene, light, t as u32, select / area, p, Vec2::new(ux, u.y))
            }
            Emitter::Sphere { center, radius, emission, .. } => {
                let (pdf, q, n) = sample_sphere_cone(p, *center, *radius, u)?;
                let cos_l = n.dot(p - q);
                if cos_l <= 0.0 {
                    return None;
                }
                let d = q - p;
                Some(LightSample {
                    radiance: *emission,
                    wi: d.normalize(),
                    pdf: select * pdf,
                    delta: false,
                    end: ShadowEnd::Point(offset_ray_origin(q, n, sphere_magnitude(*center, *radius))),
                    light,
                })
            }
        }
    }

    /// Samples a point of triangle `t` of this mesh emitter (number `light`), uniformly by
    /// area with density `pdf_area` (its selection included), as seen from `p`.
    pub fn sample_triangle(
        &self,
        scene: &Scene,
        light: u32,
        t: u32,
        pdf_area: f32,
        p: Vec3,
        u: Vec2,
    ) -> Option<LightSample> {
        let Emitter::Mesh { shape, emission, cutouts, .. } = self else { return None };
        let Geometry::Triangles(mesh) = &scene.shapes[*shape as usize].geometry else {
            return None;
        };
        let (q, n, magnitude, bary) = point_on_triangle(mesh, t, u);
        let shape_index = *shape;
        let shape = &scene.shapes[*shape as usize];
        let radiance = match scene.maps(shape.material).emission {
            Some(texture) => match mesh.uv(scene.textures[texture as usize].set(), t, bary.into()) {
                Some(uv) => scene.emission_at(shape, [uv, uv]),
                None => *emission,
            },
            None => *emission,
        };
        let radiance = match cutouts {
            Some(c) => radiance * c.coverage(shape_index, t, bary.x, bary.y),
            None => radiance,
        };
        area_sample(p, q, n, magnitude, radiance, pdf_area, light)
    }

    /// The NEE density of reaching this emissive shape at point `q` (geometric normal `n`)
    /// from `p`, with `select` the probability of picking it.
    pub fn pdf_shape(&self, select: f32, p: Vec3, q: Vec3, n: Vec3) -> f32 {
        match self {
            Emitter::Mesh { area, .. } => area_pdf(select / area, p, q, n),
            Emitter::Sphere { center, radius, .. } => {
                let dc2 = (*center - p).length_squared();
                let r2 = radius * radius;
                if dc2 <= r2 {
                    return 0.0;
                }
                select / (2.0 * PI * cone_one_minus_cos(r2 / dc2))
            }
            _ => 0.0,
        }
    }

    /// The radiance of this distant light along direction `dir` and its NEE density, with
    /// `select` the probability of picking it. `seen` asks for what the eye sees directly (or
    /// through mirrors), which for a cloudy sky is the exact procedural sky rather than its table.
    pub fn distant(&self, select: f32, dir: Vec3, seen: bool) -> (Vec3, f32) {
        match self {
            Emitter::Sky { radiance } => (*radiance, select / FOUR_PI),
            Emitter::CloudySky { sky, table, radiance } => {
                if dir.y <= 0.0 {
                    return (Vec3::ZERO, 0.0);
                }
                let phi = dir.z.atan2(dir.x).rem_euclid(2.0 * PI);
                let uv = Vec2::new(phi / (2.0 * PI), dir.y);
                let le = if seen { sky.radiance(dir) } else { sky_lookup(radiance, uv) };
                (le, select * table.pdf(uv) / (2.0 * PI))
            }
            Emitter::Environment { map, table } => {
                let uv = map.uv(dir);
                let sin = (1.0 - dir.y * dir.y).max(0.0).sqrt();
                let le = if seen { map.smooth(uv) } else { map.pixel(uv) };
                let pdf = if sin > 0.0 { select * table.pdf(uv) / (2.0 * PI * PI * sin) } else { 0.0 };
                (le, pdf)
            }
            Emitter::Sun { frame, radiance, one_minus_cos } => {
                if one_minus_cos_between(dir, frame.n) <= *one_minus_cos {
                    (*radiance, select / (2.0 * PI * one_minus_cos))
                } else {
                    (Vec3::ZERO, 0.0)
                }
            }
            _ => (Vec3::ZERO, 0.0),
        }
    }

    /// Whether it is at infinity (sun, sky, environment): what a ray leaving the scene sees.
    pub fn is_distant(&self) -> bool {
        matches!(
            self,
            Emitter::Sun { .. }
                | Emitter::Sky { .. }
                | Emitter::CloudySky { .. }
                | Emitter::Environment { .. }
        )
    }

    /// Whether it sends no light at all.
    pub fn is_dark(&self) -> bool {
        match self {
            Emitter::Point { intensity, .. } | Emitter::Spot { intensity, .. } => {
                intensity.max_element() <= 0.0
            }
            Emitter::Sun { radiance, .. } | Emitter::Sky { radiance } => radiance.max_element() <= 0.0,
            Emitter::CloudySky { sky, .. } => {
                sky.zenith.max_element() <= 0.0 && sky.clear.max_element() <= 0.0
            }
            Emitter::Environment { map, .. } => map.image.pixels.iter().all(|p| p.max_element() <= 0.0),
            Emitter::Mesh { emission, .. } | Emitter::Sphere { emission, .. } => {
                emission.max_element() <= 0.0
            }
        }
    }
}

/// The sample of a light at the point `position` whose intensity toward the receiver at `p`
/// (`wi` points from `p` to the light) is `intensity(wi)`; `None` when it sends nothing.
fn point_sample(
    p: Vec3,
    position: Vec3,
    select: f32,
    light: u32,
    intensity: impl Fn(Vec3) -> Vec3,
) -> Option<LightSample> {
    let d = position - p;
    let dist2 = d.length_squared();
    if dist2 == 0.0 {
        return None;
    }
    let wi = d / dist2.sqrt();
    let i = intensity(wi);
    if i == Vec3::ZERO {
        return None;
    }
    Some(LightSample {
        radiance: i / dist2,
        wi,
        pdf: select,
        delta: true,
        end: ShadowEnd::Point(position),
        light,
    })
}

/// A point uniformly on triangle `t`, its geometric normal (by winding), the magnitude of its
/// coordinates (for [`offset_ray_origin`]) and its barycentric weights of the second and third
/// corners.
fn point_on_triangle(mesh: &Mesh, t: u32, u: Vec2) -> (Vec3, Vec3, f32, Vec2) {
    let [a, b, c] = mesh.triangle(t);
    let bary = uniform_triangle(u);
    let q = a * (1.0 - bary.x - bary.y) + b * bary.x + c * bary.y;
    let n = (b - a).cross(c - a).normalize_or_zero();
    (q, n, mesh.magnitude(t, [a, b, c]), bary)
}

/// Turns an area sample `q` (normal `n`, coordinates of `magnitude`, one-sided emission
/// `emission`, area density `pdf_area`) into a solid-angle sample at `p`.
fn area_sample(
    p: Vec3,
    q: Vec3,
    n: Vec3,
    magnitude: f32,
    emission: Vec3,
    pdf_area: f32,
    light: u32,
) -> Option<LightSample> {
    let d = q - p;
    let dist2 = d.length_squared();
    if dist2 == 0.0 {
        return None;
    }
    let wi = d / dist2.sqrt();
    let cos_l = -n.dot(wi);
    if cos_l <= 0.0 {
        return None; // the back of a one-sided emitter
    }
    Some(LightSample {
        radiance: emission,
        wi,
        pdf: pdf_area * dist2 / cos_l,
        delta: false,
        end: ShadowEnd::Point(offset_ray_origin(q, n, magnitude)),
        light,
    })
}

/// The solid-angle density at `p` of a point `q` (normal `n`) of a surface sampled by area
/// with density `pdf_area`.
pub fn area_pdf(pdf_area: f32, p: Vec3, q: Vec3, n: Vec3) -> f32 {
    let d = q - p;
    let dist2 = d.length_squared();
    let cos = n.dot(d).abs() / dist2.sqrt();
    if cos <= 0.0 {
        return 0.0;
    }
    pdf_area * dist2 / cos
}

/// 1 - cos(theta_max) of the cone a sphere subtends, from sin^2(theta_max), accurate when small.
pub(super) fn cone_one_minus_cos(sin2: f32) -> f32 {
    let cos = (1.0 - sin2).max(0.0).sqrt();
    sin2 / (1.0 + cos)
}

/// Samples the cone a sphere subtends from outside: solid-angle density, point and normal.
pub(super) fn sample_sphere_cone(p: Vec3, c: Vec3, r: f32, u: Vec2) -> Option<(f32, Vec3, Vec3)> {
    let to_c = c - p;
    let dc2 = to_c.length_squared();
    let r2 = r * r;
    if dc2 <= r2 {
        return None; // inside a one-sided (outward) emitter: nothing to see
    }
    let dc = dc2.sqrt();
    let omc = cone_one_minus_cos(r2 / dc2);
    let frame = Frame::new(to_c / dc);
    let local = uniform_cone(u, omc);
    let wi = frame.to_world(local);
    // The nearer intersection of the ray p + t wi with the sphere.
    let cos_t = local.z;
    let sin2_t = (1.0 - cos_t * cos_t).max(0.0);
    let t = dc * cos_t - (r2 - dc2 * sin2_t).max(0.0).sqrt();
    let q0 = p + wi * t;
    let n = (q0 - c).normalize_or_zero();
    let q = c + n * r;
    Some((1.0 / (2.0 * PI * omc), q, n))
}
