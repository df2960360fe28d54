//! Light sampling for next-event estimation, and the matching densities for multiple importance
//! sampling: point lights, the sun (a cone of directions), a uniform sky, and emissive shapes
//! (triangle meshes sampled by area, spheres by the cone they subtend). A light is picked in
//! proportion to its power.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use rayon::prelude::*;

use crate::math::{
    luminance, offset_ray_origin, one_minus_cos_between, sphere_magnitude, triangle_magnitude, uniform_cone,
    uniform_sphere, uniform_triangle, Distribution1D, Distribution2D, Frame, FOUR_PI,
};
use crate::scene::sky::CloudySky;
use crate::scene::{Geometry, Light, Mesh, Scene};

/// No light on this shape.
const NONE: u32 = u32::MAX;
/// Scenes with at most this many lights sample all of them at every vertex.
const SAMPLE_ALL: usize = 8;

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
    Mesh {
        shape: u32,
        triangles: Distribution1D,
        area: f32,
        emission: Vec3,
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

/// Every light of a scene and how to pick one.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    pub emitters: Vec<Emitter>,
    /// Whether light `i` is a diffuse source (its light counts as already diffusely reflected).
    pub diffuse_source: Vec<bool>,
    select: Option<Distribution1D>,
    /// For each shape, the index of its emitter, or NONE.
    shape_light: Vec<u32>,
    /// The emitters at infinity (sun, sky), which a ray that escapes the scene sees.
    pub distant: Vec<u32>,
}

impl Lights {
    pub fn new(scene: &Scene) -> Self {
        let (lo, hi) = scene.bounds();
        let radius = 0.5 * (hi - lo).length().max(1e-3);
        let disc = PI * radius * radius;
        let mut lights = Lights { shape_light: vec![NONE; scene.shapes.len()], ..Default::default() };
        let mut power = Vec::new();

        for light in &scene.lights {
            let (emitter, phi, diffuse_source) = match *light {
                Light::Point { position, intensity } => {
                    (Emitter::Point { position, intensity }, FOUR_PI * luminance(intensity), false)
                }
                Light::Spot { position, direction, intensity, cos_total, cos_falloff_start } => {
                    // The power of the cone, taking the smooth falloff as its mean (pbrt's estimate).
                    let cone = 2.0 * PI * (1.0 - 0.5 * (cos_falloff_start + cos_total));
                    let emitter =
                        Emitter::Spot { position, direction, intensity, cos_total, cos_falloff_start };
                    (emitter, cone * luminance(intensity), false)
                }
                Light::Sun { direction, radiance, one_minus_cos, diffuse_source } => {
                    let irradiance = radiance * (2.0 * PI * one_minus_cos);
                    let emitter = Emitter::Sun { frame: Frame::new(direction), radiance, one_minus_cos };
                    (emitter, disc * luminance(irradiance), diffuse_source)
                }
                Light::CloudySky { ref sky, diffuse_source } => {
                    let (table, radiance, mean) = sky_table(sky);
                    let emitter =
                        Emitter::CloudySky { sky: Box::new(sky.clone()), table: Box::new(table), radiance };
                    (emitter, 2.0 * PI * disc * mean, diffuse_source)
                }
                Light::Sky { radiance, diffuse_source } => {
                    (Emitter::Sky { radiance }, FOUR_PI * disc * luminance(radiance), diffuse_source)
                }
            };
            if !light_is_dark(&emitter) {
                if matches!(emitter, Emitter::Sun { .. } | Emitter::Sky { .. } | Emitter::CloudySky { .. }) {
                    lights.distant.push(lights.emitters.len() as u32);
                }
                lights.emitters.push(emitter);
                lights.diffuse_source.push(diffuse_source);
                power.push(phi);
            }
        }

        for (i, shape) in scene.shapes.iter().enumerate() {
            if !shape.is_emissive() {
                continue;
            }
            let (emitter, area) = match &shape.geometry {
                Geometry::Triangles(mesh) => {
                    let areas: Vec<f32> =
                        (0..mesh.indices.len() as u32).map(|t| mesh.triangle_area(t)).collect();
                    let area: f32 = areas.iter().sum();
                    let Some(triangles) = Distribution1D::new(&areas) else {
                        continue;
                    };
                    let emitter =
                        Emitter::Mesh { shape: i as u32, triangles, area, emission: shape.emission };
                    (emitter, area)
                }
                Geometry::Sphere { center, radius } => {
                    if *radius <= 0.0 {
                        continue;
                    }
                    let emitter = Emitter::Sphere {
                        shape: i as u32,
                        center: *center,
                        radius: *radius,
                        emission: shape.emission,
                    };
                    (emitter, FOUR_PI * radius * radius)
                }
            };
            lights.shape_light[i] = lights.emitters.len() as u32;
            lights.emitters.push(emitter);
            lights.diffuse_source.push(false);
            power.push(PI * area * luminance(shape.emission));
        }
        lights.select = Distribution1D::new(&power);
        lights
    }

    pub fn is_empty(&self) -> bool {
        self.select.is_none()
    }

    /// The emitter index of a shape, if it is a light.
    pub fn of_shape(&self, shape: u32) -> Option<u32> {
        match self.shape_light.get(shape as usize) {
            Some(&i) if i != NONE => Some(i),
            _ => None,
        }
    }

    /// The probability of picking light `i`.
    pub fn select_pdf(&self, i: u32) -> f32 {
        if self.sample_all() {
            return 1.0;
        }
        self.select.as_ref().map_or(0.0, |d| d.pdf(i as usize))
    }

    /// With few lights, next-event estimation samples every light at each vertex instead of
    /// picking one: no selection noise (a scene lit by a sun and a sky would otherwise see the
    /// sun only when it is picked), at one shadow ray per light.
    pub fn sample_all(&self) -> bool {
        self.emitters.len() <= SAMPLE_ALL
    }

    /// Samples light `i` as seen from `p` (its selection probability is [`Lights::select_pdf`]).
    pub fn sample_one(&self, scene: &Scene, i: usize, p: Vec3, u: Vec2) -> Option<LightSample> {
        self.sample_emitter(scene, i, self.select_pdf(i as u32), p, u)
    }

    /// Samples a light as seen from `p`, with uniform numbers `u_select` and `u`.
    pub fn sample(&self, scene: &Scene, p: Vec3, u_select: f32, u: Vec2) -> Option<LightSample> {
        let (i, select) = match self.emitters.len() {
            0 => return None,
            1 => (0, 1.0),
            _ => self.select.as_ref()?.sample(u_select),
        };
        self.sample_emitter(scene, i, select, p, u)
    }

    fn sample_emitter(&self, scene: &Scene, i: usize, select: f32, p: Vec3, u: Vec2) -> Option<LightSample> {
        let light = i as u32;
        match &self.emitters[i] {
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
            Emitter::Mesh { shape, triangles, area, emission } => {
                let Geometry::Triangles(mesh) = &scene.shapes[*shape as usize].geometry else {
                    return None;
                };
                // u.x picks the triangle, then, rescaled, the point within it.
                let (t, _, ux) = triangles.sample_reuse(u.x);
                let (q, n, magnitude) = point_on_triangle(mesh, t as u32, Vec2::new(ux, u.y));
                area_sample(p, q, n, magnitude, *emission, select / area, light)
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

    /// The NEE density (selection included) of reaching emissive shape `light` at point `q`
    /// (geometric normal `n`) from `p`: what a BSDF-sampled hit needs for its MIS weight.
    pub fn pdf_shape(&self, light: u32, p: Vec3, q: Vec3, n: Vec3) -> f32 {
        let select = self.select_pdf(light);
        match &self.emitters[light as usize] {
            Emitter::Mesh { area, .. } => {
                let d = q - p;
                let dist2 = d.length_squared();
                let cos = n.dot(d).abs() / dist2.sqrt();
                if cos <= 0.0 {
                    return 0.0;
                }
                select * dist2 / (area * cos)
            }
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

    /// The radiance of distant light `light` along direction `dir` and its NEE density
    /// (selection included). `seen` asks for what the eye sees directly (or through mirrors),
    /// which for a cloudy sky is the exact procedural sky rather than its table.
    pub fn distant(&self, light: u32, dir: Vec3, seen: bool) -> (Vec3, f32) {
        let select = self.select_pdf(light);
        match &self.emitters[light as usize] {
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
}

fn light_is_dark(e: &Emitter) -> bool {
    match e {
        Emitter::Point { intensity, .. } | Emitter::Spot { intensity, .. } => intensity.max_element() <= 0.0,
        Emitter::Sun { radiance, .. } | Emitter::Sky { radiance } => radiance.max_element() <= 0.0,
        Emitter::CloudySky { sky, .. } => sky.zenith.max_element() <= 0.0 && sky.clear.max_element() <= 0.0,
        Emitter::Mesh { emission, .. } | Emitter::Sphere { emission, .. } => emission.max_element() <= 0.0,
    }
}

/// Cells of the cloudy sky's tables: in cos theta (horizon to zenith) and in phi.
const SKY_ROWS: usize = 256;
const SKY_COLUMNS: usize = 1024;

/// The direction of a point of the sky table's square: u = phi / 2 pi, v = cos theta.
fn sky_direction(uv: Vec2) -> Vec3 {
    let phi = 2.0 * PI * uv.x;
    let cos = uv.y;
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    Vec3::new(sin * phi.cos(), cos, sin * phi.sin())
}

/// The radiance of the sky table at a point of its square: bilinear between cell centres,
/// wrapping around in phi and clamped at the horizon and the zenith.
fn sky_lookup(radiance: &[Vec3], uv: Vec2) -> Vec3 {
    let x = uv.x * SKY_COLUMNS as f32 - 0.5;
    let y = (uv.y * SKY_ROWS as f32 - 0.5).clamp(0.0, (SKY_ROWS - 1) as f32);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let col = |c: f32| (c as i64).rem_euclid(SKY_COLUMNS as i64) as usize;
    let (c0, c1) = (col(x0), col(x0 + 1.0));
    let (r0, r1) = (y0 as usize, (y0 as usize + 1).min(SKY_ROWS - 1));
    let at = |r: usize, c: usize| radiance[r * SKY_COLUMNS + c];
    (at(r0, c0) * (1.0 - fx) + at(r0, c1) * fx) * (1.0 - fy)
        + (at(r1, c0) * (1.0 - fx) + at(r1, c1) * fx) * fy
}

/// The tables of a cloudy sky: the sampling distribution (the luminance at each cell's centre,
/// plus a floor of a tenth of the mean so that no direction the sky lights is left out), the
/// radiance at the cell centres, and the mean luminance.
fn sky_table(sky: &CloudySky) -> (Distribution2D, Vec<Vec3>, f32) {
    let radiance: Vec<Vec3> = (0..SKY_ROWS * SKY_COLUMNS)
        .into_par_iter()
        .map(|i| {
            let (col, row) = (i % SKY_COLUMNS, i / SKY_COLUMNS);
            let uv = Vec2::new((col as f32 + 0.5) / SKY_COLUMNS as f32, (row as f32 + 0.5) / SKY_ROWS as f32);
            sky.radiance(sky_direction(uv))
        })
        .collect();
    let lum: Vec<f32> = radiance.iter().map(|&r| luminance(r)).collect();
    let mean = lum.iter().sum::<f32>() / lum.len() as f32;
    let floor = 0.1 * mean.max(1e-12);
    let weights: Vec<f32> = lum.iter().map(|l| l + floor).collect();
    let table = Distribution2D::new(&weights, SKY_COLUMNS, SKY_ROWS).unwrap_or_else(|| {
        Distribution2D::new(&vec![1.0; SKY_ROWS * SKY_COLUMNS], SKY_COLUMNS, SKY_ROWS).expect("uniform")
    });
    (table, radiance, mean)
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

/// A point uniformly on triangle `t`, its geometric normal (by winding) and the magnitude of its
/// coordinates (for [`offset_ray_origin`]).
fn point_on_triangle(mesh: &Mesh, t: u32, u: Vec2) -> (Vec3, Vec3, f32) {
    let [a, b, c] = mesh.triangle(t);
    let bary = uniform_triangle(u);
    let q = a * (1.0 - bary.x - bary.y) + b * bary.x + c * bary.y;
    let n = (b - a).cross(c - a).normalize_or_zero();
    (q, n, triangle_magnitude(a, b, c))
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

/// 1 - cos(theta_max) of the cone a sphere subtends, from sin^2(theta_max), accurate when small.
fn cone_one_minus_cos(sin2: f32) -> f32 {
    let cos = (1.0 - sin2).max(0.0).sqrt();
    sin2 / (1.0 + cos)
}

/// Samples the cone a sphere subtends from outside: solid-angle density, point and normal.
fn sample_sphere_cone(p: Vec3, c: Vec3, r: f32, u: Vec2) -> Option<(f32, Vec3, Vec3)> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampler::Sampler;

    #[test]
    fn sphere_cone_pdf_integrates_to_one_over_its_solid_angle() {
        // Monte Carlo estimate of the cone's solid angle from uniform sphere directions.
        let (p, c, r) = (Vec3::ZERO, Vec3::new(0.0, 0.0, 3.0), 1.0);
        let mut s = Sampler::new(3, 0, 0);
        let n = 200_000;
        let mut inside = 0;
        for _ in 0..n {
            let d = uniform_sphere(s.next_2d());
            // Does the ray hit the sphere?
            let b = d.dot(c - p);
            if b > 0.0 && (c - p).length_squared() - b * b <= r * r {
                inside += 1;
            }
        }
        let solid_angle = FOUR_PI * inside as f32 / n as f32;
        let (pdf, q, _) = sample_sphere_cone(p, c, r, Vec2::new(0.3, 0.6)).expect("outside");
        // Standard error of the fraction estimate, times 4 pi; 5 sigma.
        let frac = inside as f32 / n as f32;
        let sigma = FOUR_PI * (frac * (1.0 - frac) / n as f32).sqrt();
        assert!((1.0 / pdf - solid_angle).abs() < 5.0 * sigma, "{} vs {solid_angle}", 1.0 / pdf);
        assert!(((q - c).length() - r).abs() < 1e-5);
    }

    /// Chi-square tests of the area lights' sampling, seen from the origin, against the density
    /// that MIS uses for a BSDF-sampled hit (`pdf_shape`), found by tracing each direction to the
    /// light: the two must agree for NEE and BSDF sampling to combine without bias.
    mod chi_square {
        use super::*;
        use crate::math::chi_square::z_score;
        use crate::scene::file::parse;

        fn lights_of(text: &str) -> (Scene, Lights) {
            let scene = parse(std::path::Path::new("t.toml"), text).expect("parses");
            let lights = Lights::new(&scene);
            (scene, lights)
        }

        /// The nearest hit of the ray from the origin along `d` on a triangle (Moller-Trumbore).
        fn hit_triangle([a, b, c]: [Vec3; 3], d: Vec3) -> Option<f32> {
            let (e1, e2) = (b - a, c - a);
            let pv = d.cross(e2);
            let det = e1.dot(pv);
            if det.abs() < 1e-12 {
                return None;
            }
            let tv = -a;
            let u = tv.dot(pv) / det;
            let qv = tv.cross(e1);
            let v = d.dot(qv) / det;
            let t = e2.dot(qv) / det;
            (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0).then_some(t)
        }

        const CAMERA: &str = "[camera]\nposition = [0, 0, -5]\nlook_at = [0, 0, 0]\n";

        #[test]
        fn mesh_light_sampling_matches_its_mis_density() {
            // An irregular quad (two triangles of different areas) facing the origin.
            let text = format!(
                "{CAMERA}[[shape]]\ntype = \"quad\"\nemission = [1, 1, 1]\n\
                 vertices = [[-2, -1, 1], [-1, 1.5, 1], [2, 2, 1], [1.5, -2, 1]]\n"
            );
            let (scene, lights) = lights_of(&text);
            let Geometry::Triangles(mesh) = &scene.shapes[0].geometry else { panic!("a mesh") };
            let pdf = |d: Vec3| {
                (0..mesh.indices.len() as u32)
                    .find_map(|t| {
                        let tri = mesh.triangle(t);
                        let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
                        hit_triangle(tri, d).map(|h| lights.pdf_shape(0, Vec3::ZERO, d * h, n))
                    })
                    .unwrap_or(0.0)
            };
            let z = z_score(|s| lights.sample_one(&scene, 0, Vec3::ZERO, s.next_2d()).map(|l| l.wi), pdf);
            assert!(z < 4.0, "z = {z}");
        }

        #[test]
        fn sphere_light_sampling_matches_its_mis_density() {
            let text = format!(
                "{CAMERA}[[shape]]\ntype = \"sphere\"\nemission = [1, 1, 1]\ncenter = [0.5, 0.3, 2]\nradius = 1\n"
            );
            let (scene, lights) = lights_of(&text);
            let c = Vec3::new(0.5, 0.3, 2.0);
            // The density of the cone of a sphere of radius r around c, traced.
            let pdf = |d: Vec3, r: f32| {
                let b = d.dot(c);
                let disc = b * b - (c.length_squared() - r * r);
                if disc < 0.0 || b <= 0.0 {
                    return 0.0;
                }
                let q = d * (b - disc.sqrt());
                let dc2 = c.length_squared();
                if r == 1.0 {
                    lights.pdf_shape(0, Vec3::ZERO, q, (q - c) / r)
                } else {
                    1.0 / (2.0 * PI * cone_one_minus_cos(r * r / dc2))
                }
            };
            let sample =
                |s: &mut Sampler| lights.sample_one(&scene, 0, Vec3::ZERO, s.next_2d()).map(|l| l.wi);
            let z = z_score(sample, |d| pdf(d, 1.0));
            assert!(z < 4.0, "z = {z}");
            // The test has power: judged by the cone of a sphere 5% larger, the samples fail.
            let z = z_score(sample, |d| pdf(d, 1.05));
            assert!(z > 10.0, "z = {z}");
        }
    }

    #[test]
    fn spot_falloff_matches_its_definition_at_centre_edge_and_outside() {
        let text = "[camera]\nposition = [0, 0, -5]\nlook_at = [0, 0, 0]\n[[light]]\ntype = \"spot\"\n\
                    position = [0, 4, 0]\ndirection = [0, -1, 0]\nintensity = [8, 8, 8]\n\
                    cone_angle = 30\nfalloff_start = 20\n";
        let scene = crate::scene::file::parse(std::path::Path::new("t.toml"), text).expect("parses");
        let lights = Lights::new(&scene);
        // The intensity a receiver at angle `deg` from the axis, 2 units from the light, gets.
        let at = |deg: f32| {
            let t = deg.to_radians();
            let p = Vec3::new(0.0, 4.0, 0.0) + 2.0 * Vec3::new(t.sin(), -t.cos(), 0.0);
            lights.sample_one(&scene, 0, p, Vec2::splat(0.5)).map_or(0.0, |l| l.radiance.x * 4.0)
        };
        assert!((at(0.0) - 8.0).abs() < 1e-4, "centre {}", at(0.0));
        assert!((at(19.9) - 8.0).abs() < 1e-4, "inside the inner cone {}", at(19.9));
        assert!(at(30.0) < 1e-6, "edge {}", at(30.0));
        assert_eq!(at(30.5), 0.0, "just outside");
        assert_eq!(at(60.0), 0.0, "outside");
        // Between: the smoothstep of the cosine, decreasing.
        let (c, lo, hi) = (25f32.to_radians().cos(), 30f32.to_radians().cos(), 20f32.to_radians().cos());
        let t = (c - lo) / (hi - lo);
        assert!((at(25.0) - 8.0 * t * t * (3.0 - 2.0 * t)).abs() < 1e-3, "{}", at(25.0));
        assert!(at(22.0) > at(25.0) && at(25.0) > at(28.0) && at(28.0) > 0.0);
    }

    #[test]
    fn cloudy_sky_sampling_matches_its_density() {
        use crate::math::chi_square::z_score;
        let text = "[camera]\nposition = [0, 0, -5]\nlook_at = [0, 0, 0]\n[[light]]\ntype = \"sky\"\n\
                    zenith = [1, 1, 1]\nclear = [0.1, 0.2, 0.5]\ncloud_cover = 0.5\ncloud_scale = 0.3\n";
        let scene = crate::scene::file::parse(std::path::Path::new("t.toml"), text).expect("parses");
        let lights = Lights::new(&scene);
        let z = z_score(
            |s| lights.sample_one(&scene, 0, Vec3::ZERO, s.next_2d()).map(|l| l.wi),
            |d| lights.distant(0, d, false).1,
        );
        assert!(z < 4.0, "z = {z}");
        // The table follows the sky: NEE samples carry more light than uniform directions do.
        let mut s = Sampler::new(9, 9, 9);
        let (mut sampled, mut uniform) = (0.0, 0.0);
        for _ in 0..20_000 {
            sampled += lights.sample_one(&scene, 0, Vec3::ZERO, s.next_2d()).map_or(0.0, |l| l.radiance.x);
            uniform += lights.distant(0, uniform_sphere(s.next_2d()), false).0.x;
        }
        assert!(sampled > 2.0 * uniform, "{sampled} vs {uniform}");
    }
}
