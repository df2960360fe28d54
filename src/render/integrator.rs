//! The path integrator: next-event estimation with multiple importance sampling (power
//! heuristic) for area lights, the sun and the sky, Russian roulette, and a depth limit. Generic
//! over the accelerator, so each backend gets its own monomorphised copy and no dynamic dispatch
//! per ray.

use std::f32::consts::FRAC_1_PI;

use glam::Vec3;

use super::lights::{Lights, ShadowEnd};
use super::sampler::Sampler;
use super::surface::surface;
use crate::accel::{Accel, Ray};
use crate::math::{cosine_hemisphere, offset_ray_origin, Frame};
use crate::scene::{Material, Scene};

/// What the integrator reads for every path: the scene, its accelerator and its lights.
pub struct Integrator<'a, A: Accel> {
    pub scene: &'a Scene,
    pub accel: &'a A,
    pub lights: &'a Lights,
    pub max_depth: u32,
}

/// Veach's power heuristic with exponent 2.
fn power_heuristic(pdf: f32, other: f32) -> f32 {
    let (a, b) = (pdf * pdf, other * other);
    if a + b == 0.0 {
        0.0
    } else {
        a / (a + b)
    }
}

impl<A: Accel> Integrator<'_, A> {
    /// The radiance arriving along `ray` (one path sample). `rays` counts traced rays.
    pub fn radiance(&self, mut ray: Ray, sampler: &mut Sampler, rays: &mut u64) -> Vec3 {
        let scene = self.scene;
        let lights = self.lights;
        let mut l = Vec3::ZERO;
        let mut beta = Vec3::ONE;
        // The camera counts as a specular vertex: emission seen directly takes no MIS weight.
        let mut specular = true;
        let mut bsdf_pdf = 0.0f32;
        let mut prev_p = ray.origin;

        for depth in 0.. {
            *rays += 1;
            let Some(hit) = self.accel.intersect(&ray) else {
                for &i in &lights.distant {
                    let (le, light_pdf) = lights.distant(i, ray.dir);
                    if le != Vec3::ZERO {
                        let w = if specular { 1.0 } else { power_heuristic(bsdf_pdf, light_pdf) };
                        l += beta * le * w;
                    }
                }
                break;
            };
            let s = surface(scene, &ray, &hit);
            let shape = &scene.shapes[hit.shape as usize];
            let wo = -ray.dir;

            // Emission, on the front side only.
            if shape.is_emissive() && s.ng.dot(wo) > 0.0 {
                let w = match (specular, lights.of_shape(hit.shape)) {
                    (false, Some(light)) => {
                        power_heuristic(bsdf_pdf, lights.pdf_shape(light, prev_p, s.p, s.ng))
                    }
                    _ => 1.0,
                };
                l += beta * shape.emission * w;
            }
            if depth >= self.max_depth {
                break;
            }

            // Both normals on the side the ray came from (surfaces are two-sided).
            let ng = if s.ng.dot(wo) >= 0.0 { s.ng } else { -s.ng };
            let ns = if s.ns.dot(ng) >= 0.0 { s.ns } else { -s.ns };
            let Material::Diffuse { albedo } = scene.materials[shape.material as usize];
            // Every ray leaving this point (shadow or bounce) goes to the side of `ng`.
            let origin = offset_ray_origin(s.p, ng);

            // Next-event estimation.
            if let Some(ls) = lights.sample(scene, s.p, sampler.next_1d(), sampler.next_2d()) {
                let cos = ns.dot(ls.wi);
                if cos > 0.0 && ng.dot(ls.wi) > 0.0 && ls.pdf > 0.0 {
                    let shadow = match ls.end {
                        // Unnormalised direction: t in [0, 1] ends exactly at the light point.
                        ShadowEnd::Point(q) => Ray { origin, dir: q - origin, t_max: 1.0 },
                        ShadowEnd::Infinite => Ray::new(origin, ls.wi),
                    };
                    *rays += 1;
                    if !self.accel.occluded(&shadow) {
                        let f = albedo * FRAC_1_PI;
                        let w = if ls.delta { 1.0 } else { power_heuristic(ls.pdf, cos * FRAC_1_PI) };
                        l += beta * f * ls.radiance * (cos * w / ls.pdf);
                    }
                }
            }

            // Continue the path by sampling the BSDF.
            let local = cosine_hemisphere(sampler.next_2d());
            let wi = Frame::new(ns).to_world(local);
            bsdf_pdf = local.z * FRAC_1_PI;
            if bsdf_pdf <= 0.0 || ng.dot(wi) <= 0.0 {
                break;
            }
            beta *= albedo; // f cos / pdf for a Lambertian lobe
            if beta == Vec3::ZERO {
                break; // nothing more can reach the eye along this path
            }
            specular = false;
            prev_p = s.p;

            // Russian roulette once the path has had a chance to gather light.
            if depth >= 2 {
                let survive = beta.max_element();
                if survive < 1.0 {
                    if sampler.next_1d() >= survive {
                        break;
                    }
                    beta /= survive;
                }
            }
            ray = Ray::new(origin, wi);
        }
        l
    }
}
