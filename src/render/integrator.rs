//! The path integrator: next-event estimation with multiple importance sampling (power
//! heuristic) for area lights, the sun and the sky, Russian roulette, and a depth limit. Generic
//! over the accelerator, so each backend gets its own monomorphised copy and no dynamic dispatch
//! per ray, and over the [`Features`] a render needs (a const bit set), so a feature the scene
//! and its outputs cannot use is compiled out of that render's copy, not skipped by a branch.

use std::f32::consts::FRAC_1_PI;

use glam::Vec3;

use super::bsdf::{Glossy, Lobe};
use super::features::{GUIDES, MIS, SPLIT, TEXTURES};
use super::lights::{LightSample, Lights, ShadowEnd};
use super::sampler::Sampler;
use super::surface::surface;
use crate::accel::{Accel, Ray};
use crate::math::{cosine_hemisphere, Frame};
use crate::scene::{Material, Scene};

/// What the integrator reads for every path: the scene, its accelerator and its lights. `F` is
/// the [`super::features::Features`] bit set this copy computes; the default is all of them.
pub struct Integrator<'a, A: Accel, const F: u8 = { super::features::ALL }> {
    pub scene: &'a Scene,
    pub accel: &'a A,
    pub lights: &'a Lights,
    pub max_depth: u32,
}

/// The paper's light-path components (section 2), indices into [`PathSample::components`].
pub const EMITTED: usize = 0;
/// L_r,d,l: E S* D L.
pub const DIRECT: usize = 1;
/// L_r,d,s: E S* D S+ L.
pub const CAUSTIC: usize = 2;
/// L_r,d,d: a D vertex after the first one (or a diffuse source's light at the first).
pub const INDIRECT: usize = 3;

/// What one path sample found: its radiance, the same split by light path, and the guide
/// values at the first diffuse vertex `x` (or the last vertex of an all-specular path).
#[derive(Clone, Copy, Debug, Default)]
pub struct PathSample {
    pub beauty: Vec3,
    /// emitted, direct, caustic, indirect: they sum to `beauty` up to float rounding.
    pub components: [Vec3; 4],
    /// The object at `x`, or `None` when the path left the scene first.
    pub object: Option<u32>,
    pub normal: Vec3,
    /// Distance travelled from the eye to `x`.
    pub depth: f32,
    pub albedo: Vec3,
}

impl PathSample {
    /// Sets the guide buffers to the vertex the pixel shows (nothing when `F` has no guides).
    #[inline(always)]
    fn guide<const F: u8>(&mut self, object: u32, normal: Vec3, depth: f32, albedo: Vec3) {
        if F & GUIDES == 0 {
            return;
        }
        self.object = Some(object);
        self.normal = normal;
        self.depth = depth;
        self.albedo = albedo;
    }
}

/// Where the eye path is in Heckbert's notation: how many D vertices it has passed, and whether
/// an S vertex followed the first D. That is all the component split needs.
#[derive(Clone, Copy, Debug, Default)]
struct PathClass {
    diffuse: u32,
    specular_after_first: bool,
}

impl PathClass {
    /// The component of light that reaches the eye along the path so far: from a light hit
    /// after the last vertex, or found by NEE at the current D vertex (already counted).
    fn component(self, diffuse_source: bool) -> usize {
        match self.diffuse {
            0 => EMITTED,
            // A diffuse source's light counts as already diffusely reflected once.
            _ if diffuse_source => INDIRECT,
            1 if self.specular_after_first => CAUSTIC,
            1 => DIRECT,
            _ => INDIRECT,
        }
    }

    /// The class after one more D vertex.
    fn through_diffuse(self) -> Self {
        PathClass { diffuse: self.diffuse + 1, ..self }
    }

    /// The class after one more S vertex: after the first D vertex, light arriving next is a
    /// caustic.
    fn through_specular(self) -> Self {
        PathClass { specular_after_first: self.specular_after_first || self.diffuse == 1, ..self }
    }
}

/// What a path sample tells of itself, for `--debug-nonfinite`. `()` records nothing and
/// compiles away; a `Vec<String>` keeps one line a vertex.
pub trait Record {
    /// The path reached `shape` at `p` after `depth` bounces with throughput `beta`, having
    /// gathered `beauty` so far.
    fn vertex(&mut self, depth: u32, shape: &str, p: Vec3, beta: Vec3, beauty: Vec3);
    /// The path left the scene along `dir`.
    fn escaped(&mut self, depth: u32, dir: Vec3, beta: Vec3);
}

impl Record for () {
    #[inline(always)]
    fn vertex(&mut self, _: u32, _: &str, _: Vec3, _: Vec3, _: Vec3) {}
    #[inline(always)]
    fn escaped(&mut self, _: u32, _: Vec3, _: Vec3) {}
}

impl Record for Vec<String> {
    fn vertex(&mut self, depth: u32, shape: &str, p: Vec3, beta: Vec3, beauty: Vec3) {
        self.push(format!("  {depth}: hit `{shape}` at {p}, throughput {beta}, radiance so far {beauty}"));
    }
    fn escaped(&mut self, depth: u32, dir: Vec3, beta: Vec3) {
        self.push(format!("  {depth}: left the scene along {dir}, throughput {beta}"));
    }
}

/// The mirror direction of `wo` about `n`.
fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    2.0 * wo.dot(n) * n - wo
}

/// The refracted direction of `wo` (on `n`'s side, cos_i = n.wo) through a boundary with index
/// ratio `eta` (transmitted over incident); only called below total internal reflection.
fn refract(wo: Vec3, n: Vec3, eta: f32, cos_i: f32) -> Vec3 {
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    (-wo / eta + (cos_i / eta - cos_t) * n).normalize()
}

/// Unpolarised Fresnel reflectance of a dielectric boundary (1 under total internal reflection).
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    0.5 * (rs * rs + rp * rp)
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

impl<A: Accel, const F: u8> Integrator<'_, A, F> {
    /// Bookkeeping of an S vertex: before any D vertex the guide buffers follow the specular
    /// chain (the last vertex of an all-specular path is what a pixel shows); after the first D
    /// vertex an S bounce makes light arriving next a caustic. Returns false when the new
    /// direction is unusable.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn specular_bounce(
        &self,
        out: &mut PathSample,
        class: &mut PathClass,
        object: u32,
        normal: Vec3,
        travelled: f32,
        color: Vec3,
        wi: Vec3,
        side: Vec3,
    ) -> bool {
        if class.diffuse == 0 {
            out.guide::<F>(object, normal, travelled, color);
        }
        *class = class.through_specular();
        wi.is_finite() && side.is_finite()
    }

    /// Next-event estimation at a reflecting vertex at `p` (shading normal `ns`, geometric `ng`,
    /// both on the side the path came from): samples every light when there are few, else one
    /// picked by power, traces a shadow ray from `origin` for each sample that can reflect, and
    /// hands the unoccluded ones to `gather` with their cosine at `ns`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn next_event(
        &self,
        p: Vec3,
        origin: Vec3,
        ns: Vec3,
        ng: Vec3,
        sampler: &mut Sampler,
        rays: &mut u64,
        mut gather: impl FnMut(&LightSample, f32),
    ) {
        let mut trace = |ls: LightSample, rays: &mut u64| {
            let cos = ns.dot(ls.wi);
            if cos > 0.0 && ng.dot(ls.wi) > 0.0 && ls.pdf > 0.0 {
                let shadow = match ls.end {
                    // Unnormalised direction: t in [0, 1] ends exactly at the light point.
                    ShadowEnd::Point(q) => Ray { origin, dir: q - origin, t_max: 1.0 },
                    ShadowEnd::Infinite => Ray::new(origin, ls.wi),
                };
                *rays += 1;
                if !self.accel.occluded(&shadow) {
                    gather(&ls, cos);
                }
            }
        };
        let (scene, lights) = (self.scene, self.lights);
        if lights.sample_all() {
            for i in 0..lights.emitters.len() {
                if let Some(ls) = lights.sample_one(scene, i, p, sampler.next_2d()) {
                    trace(ls, rays);
                }
            }
        } else if let Some(ls) = lights.sample(scene, p, sampler.next_1d(), sampler.next_2d()) {
            trace(ls, rays);
        }
    }

    /// One path sample of the radiance arriving along `ray`, split by light path. `rays` counts
    /// traced rays.
    pub fn sample(&self, ray: Ray, sampler: &mut Sampler, rays: &mut u64) -> PathSample {
        self.sample_recorded(ray, sampler, rays, &mut ())
    }

    /// [`Integrator::sample`], reporting each vertex to `record` (nothing, for `()`).
    pub fn sample_recorded<R: Record>(
        &self,
        mut ray: Ray,
        sampler: &mut Sampler,
        rays: &mut u64,
        record: &mut R,
    ) -> PathSample {
        let scene = self.scene;
        let lights = self.lights;
        let mut out = PathSample::default();
        let mut class = PathClass::default();
        let mut travelled = 0.0f32;
        // Adds a contribution to the beauty and to its component.
        let add = |out: &mut PathSample, c: Vec3, component: usize| {
            out.beauty += c;
            if F & SPLIT != 0 {
                out.components[component] += c;
            }
        };
        let mut beta = Vec3::ONE;
        // The camera counts as a specular vertex: emission seen directly takes no MIS weight.
        let mut specular = true;
        let mut bsdf_pdf = 0.0f32;
        let mut prev_p = ray.origin;

        for depth in 0.. {
            *rays += 1;
            let Some(hit) = self.accel.intersect(&ray) else {
                record.escaped(depth, ray.dir, beta);
                if F & MIS == 0 {
                    break; // no sun or sky to see
                }
                for &i in &lights.distant {
                    let (le, light_pdf) = lights.distant(i, ray.dir, specular);
                    if le != Vec3::ZERO {
                        let w = if specular { 1.0 } else { power_heuristic(bsdf_pdf, light_pdf) };
                        let component = class.component(lights.diffuse_source[i as usize]);
                        add(&mut out, beta * le * w, component);
                    }
                }
                break;
            };
            let s = surface(scene, &ray, &hit);
            let shape = &scene.shapes[hit.shape as usize];
            record.vertex(depth, &shape.name, s.p, beta, out.beauty);
            let wo = -ray.dir;
            travelled += hit.t * ray.dir.length();

            // Emission, on the front side only (a scene without MIS has no hittable light).
            if F & MIS != 0 && shape.is_emissive() && s.ng.dot(wo) > 0.0 {
                let w = match (specular, lights.of_shape(hit.shape)) {
                    (false, Some(light)) => {
                        power_heuristic(bsdf_pdf, lights.pdf_shape(light, prev_p, s.p, s.ng))
                    }
                    _ => 1.0,
                };
                let source = lights.of_shape(hit.shape).is_some_and(|i| lights.diffuse_source[i as usize]);
                add(&mut out, beta * shape.emission * w, class.component(source));
            }
            if depth >= self.max_depth {
                break;
            }

            // Both normals on the side the ray came from (surfaces are two-sided).
            let ng = if s.ng.dot(wo) >= 0.0 { s.ng } else { -s.ng };
            let mut ns = if s.ns.dot(ng) >= 0.0 { s.ns } else { -s.ns };
            let maps = if F & TEXTURES != 0 { scene.maps(shape.material) } else { Default::default() };
            if let Some((t, height)) = maps.bump {
                ns = scene.textures[t as usize].bump(height, s.p, s.uv, ns, ng);
            }
            // The albedo of a diffuse material or a glossy one's base, textured or constant.
            let textured = |constant: Vec3| match maps.color {
                Some(t) => scene.textures[t as usize].color(s.p, s.uv),
                None => constant,
            };
            // Every ray leaving a reflecting point (shadow or bounce) goes to the side of `ng`.
            let origin = s.origin(ng);
            // Without a light a path can hit, the ray after the last vertex could only find one:
            // not traced.
            let last = F & MIS == 0 && depth + 1 >= self.max_depth;
            let wi = match scene.materials[shape.material as usize] {
                Material::Diffuse { albedo } => {
                    let albedo = textured(albedo);
                    // A diffuse (D) vertex; the first one is `x`, where the guide buffers look.
                    class = class.through_diffuse();
                    if class.diffuse == 1 {
                        out.guide::<F>(shape.object, ns, travelled, albedo);
                    }
                    let f = albedo * FRAC_1_PI;
                    self.next_event(s.p, origin, ns, ng, sampler, rays, |ls, cos| {
                        let w = if F & MIS == 0 || ls.delta {
                            1.0
                        } else {
                            power_heuristic(ls.pdf, cos * FRAC_1_PI)
                        };
                        let component = class.component(lights.diffuse_source[ls.light as usize]);
                        add(&mut out, beta * f * ls.radiance * (cos * w / ls.pdf), component);
                    });
                    if last {
                        break;
                    }

                    // Continue the path by sampling the BSDF.
                    let local = cosine_hemisphere(sampler.next_2d());
                    let wi = Frame::new(ns).to_world(local);
                    bsdf_pdf = local.z * FRAC_1_PI;
                    if bsdf_pdf <= 0.0 || ng.dot(wi) <= 0.0 {
                        break;
                    }
                    beta *= albedo; // f cos / pdf for a Lambertian lobe
                    wi
                }
                Material::Glossy { specular, roughness, base } => {
                    // Each lobe is its own vertex type: the GGX lobe S, the base D. Light found
                    // through each lobe goes to the component that lobe makes, with its own MIS
                    // weight, so the split stays exact in expectation.
                    let g = Glossy { specular, alpha: super::bsdf::alpha(roughness), base: textured(base) };
                    let frame = Frame::new(ns);
                    let wo_l = frame.to_local(wo);
                    if wo_l.z <= 0.0 {
                        break;
                    }
                    let p_spec = g.specular_probability(wo_l);
                    let (spec_class, base_class) = (class.through_specular(), class.through_diffuse());
                    self.next_event(s.p, origin, ns, ng, sampler, rays, |ls, _| {
                        let wi_l = frame.to_local(ls.wi);
                        let source = lights.diffuse_source[ls.light as usize];
                        let lobes = [
                            (g.eval_specular(wo_l, wi_l), p_spec * g.pdf_specular(wo_l, wi_l), spec_class),
                            (g.eval_base(wo_l, wi_l), (1.0 - p_spec) * g.pdf_base(wi_l), base_class),
                        ];
                        for (f, pdf, lobe_class) in lobes {
                            if f != Vec3::ZERO {
                                let w =
                                    if F & MIS == 0 || ls.delta { 1.0 } else { power_heuristic(ls.pdf, pdf) };
                                let c = beta * f * ls.radiance * (wi_l.z * w / ls.pdf);
                                add(&mut out, c, lobe_class.component(source));
                            }
                        }
                    });
                    if last {
                        break;
                    }

                    let (wi_l, lobe) = g.sample(wo_l, sampler.next_1d(), sampler.next_2d());
                    let wi = frame.to_world(wi_l);
                    if wi_l.z <= 0.0 || ng.dot(wi) <= 0.0 || !wi.is_finite() {
                        break;
                    }
                    match lobe {
                        Lobe::Specular => {
                            self.specular_bounce(
                                &mut out,
                                &mut class,
                                shape.object,
                                ns,
                                travelled,
                                specular,
                                wi,
                                ng,
                            );
                            bsdf_pdf = p_spec * g.pdf_specular(wo_l, wi_l);
                            beta *= g.specular_weight(wo_l, wi_l) / p_spec;
                        }
                        Lobe::Base => {
                            class = base_class;
                            if class.diffuse == 1 {
                                out.guide::<F>(shape.object, ns, travelled, g.base);
                            }
                            bsdf_pdf = (1.0 - p_spec) * g.pdf_base(wi_l);
                            beta *= g.eval_base(wo_l, wi_l) * (wi_l.z / bsdf_pdf);
                        }
                    }
                    if bsdf_pdf <= 0.0 {
                        break;
                    }
                    wi
                }
                Material::Mirror { color } => {
                    let wi = reflect(wo, ns);
                    if !self.specular_bounce(&mut out, &mut class, shape.object, ns, travelled, color, wi, ng)
                        || last
                    {
                        break;
                    }
                    beta *= color;
                    ray = Ray::new(origin, wi);
                    specular = true;
                    continue;
                }
                Material::Glass { ior, color } => {
                    // Entering when the ray meets the outside (the side the geometric normal
                    // points to); eta is the ratio of the indices across the boundary.
                    if last {
                        // The guides still show this vertex, as they do when the ray is traced.
                        let _ = self.specular_bounce(
                            &mut out,
                            &mut class,
                            shape.object,
                            ns,
                            travelled,
                            color,
                            wo,
                            ng,
                        );
                        break;
                    }
                    let entering = s.ng.dot(wo) > 0.0;
                    let eta = if entering { ior } else { 1.0 / ior };
                    let cos_i = ns.dot(wo).clamp(0.0, 1.0);
                    let reflectance = fresnel_dielectric(cos_i, eta);
                    let (wi, scale) = if sampler.next_1d() < reflectance {
                        (reflect(wo, ns), color)
                    } else {
                        // Radiance is squeezed into the denser medium's smaller solid angle.
                        (refract(wo, ns, eta, cos_i), color / (eta * eta))
                    };
                    if !self.specular_bounce(&mut out, &mut class, shape.object, ns, travelled, color, wi, wi)
                    {
                        break;
                    }
                    beta *= scale;
                    let side = if wi.dot(ng) > 0.0 { ng } else { -ng };
                    ray = Ray::new(s.origin(side), wi);
                    specular = true;
                    if beta == Vec3::ZERO {
                        break;
                    }
                    continue;
                }
            };
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
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_at_normal_incidence_grazing_and_beyond_the_critical_angle() {
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert!((fresnel_dielectric(1e-4, 1.5) - 1.0).abs() < 1e-2);
        // From inside glass (eta = 1/1.5) beyond asin(1/1.5) = 41.8 degrees: total reflection.
        assert_eq!(fresnel_dielectric(43f32.to_radians().cos(), 1.0 / 1.5), 1.0);
        assert!(fresnel_dielectric(40f32.to_radians().cos(), 1.0 / 1.5) < 1.0);
        // The same boundary crossed either way reflects the same fraction.
        for cos_i in [0.2f32, 0.5, 0.9] {
            let sin_t = (1.0 - cos_i * cos_i).sqrt() / 1.5;
            let cos_t = (1.0 - sin_t * sin_t).sqrt();
            assert!((fresnel_dielectric(cos_i, 1.5) - fresnel_dielectric(cos_t, 1.0 / 1.5)).abs() < 1e-5);
        }
    }

    /// Mirror and glass are delta BSDFs: reciprocity means each specular map is reversible (the
    /// light can run the path backwards) with the same weight. Reflection is an involution; a
    /// refracted direction refracted back from the other side is the incident one; and Fresnel
    /// reflectance is the same from both sides of a boundary (Stokes), so the transmitted
    /// weights (1 - F) / eta^2 and (1 - F) eta^2 of the two directions differ exactly by the
    /// radiance scaling 1 / eta^2 that makes the pair adjoint.
    #[test]
    fn mirror_and_glass_are_reciprocal() {
        let n = Vec3::Z;
        let mut s = crate::render::sampler::Sampler::new(9, 9, 9);
        let mut refracted = 0;
        for _ in 0..2000 {
            let wo = cosine_hemisphere(s.next_2d());
            let wr = reflect(wo, n);
            assert!((reflect(wr, n) - wo).length() < 1e-5 && (wr.z - wo.z).abs() < 1e-6, "{wo}");
            for eta in [1.5f32, 1.0 / 1.5, 2.42, 1.0 / 1.33] {
                let cos_i = wo.z;
                let f = fresnel_dielectric(cos_i, eta);
                if f >= 1.0 {
                    continue; // total internal reflection: only the mirror map, tested above
                }
                refracted += 1;
                let wt = refract(wo, n, eta, cos_i);
                // Backwards: wt, now the direction away from the surface on the other side.
                let cos_t = wt.dot(-n);
                let back = refract(wt, -n, 1.0 / eta, cos_t);
                assert!((back - wo).length() < 1e-4, "eta {eta}: {wo} -> {wt} -> {back}");
                let f_back = fresnel_dielectric(cos_t, 1.0 / eta);
                assert!((f - f_back).abs() < 1e-4, "eta {eta}, cos {cos_i}: F {f} vs {f_back}");
            }
        }
        assert!(refracted > 6000, "{refracted} refractions tested");
    }

    #[test]
    fn refraction_obeys_snell() {
        let n = Vec3::Z;
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let wt = refract(wo, n, 1.5, wo.dot(n));
        let sin_i = 0.6;
        let sin_t = (1.0 - wt.z * wt.z).sqrt();
        assert!((sin_i - 1.5 * sin_t).abs() < 1e-5, "{wt}");
        assert!(wt.z < 0.0 && wt.x < 0.0, "goes through, on the far side of the normal: {wt}");
        assert!((reflect(wo, n) - Vec3::new(-0.6, 0.0, 0.8)).length() < 1e-6);
    }
}
