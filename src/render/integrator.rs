//! The path integrator, shaped as pbrt-v4's `PathIntegrator::Li`: at every vertex, emission;
//! next-event estimation with multiple importance sampling (power heuristic) at non-delta
//! vertices; a BSDF sample, classified by its lobe's tag alone; one Russian roulette; and a
//! depth limit. It never names a material: scattering is [`super::bsdf`]'s. Generic over the
//! accelerator, so each backend gets its own monomorphised copy and no dynamic dispatch per ray,
//! and over the [`Features`] a render needs (a const bit set), so a feature the scene and its
//! outputs cannot use is compiled out of that render's copy, not skipped by a branch.
//!
//! [`Features`]: super::features::Features

use glam::{DVec3, Vec2, Vec3};

use super::bsdf::{with_bsdf, Bsdf, BsdfSample, Lobe};
use super::features::{GUIDES, MIS, SPLIT, TEXTURES};
use super::lights::{LightSample, Lights, ShadowEnd};
use super::sampler::{Dim, Sampler};
use super::surface::{apply_height, apply_normal_map, surface_with, FaceNormals, Surface};
use crate::accel::{Accel, Hit, Ray};
use crate::component::{Component, Split};
use crate::scene::texture::Texture;
use crate::scene::{Scene, Shape};

/// What the integrator reads for every path: the scene, its accelerator and its lights. `F` is
/// the [`super::features::Features`] bit set this copy computes; the default is all of them.
pub struct Integrator<'a, A: Accel, const F: u8 = { super::features::ALL }> {
    pub scene: &'a Scene,
    pub accel: &'a A,
    pub lights: &'a Lights,
    /// The scene's triangle normals, made once (`FaceNormals::new`).
    pub faces: &'a FaceNormals,
    pub max_depth: u32,
}

/// What one path sample found: its radiance, the same split by light path, and the guide
/// values at the first diffuse vertex `x` (or the last vertex of an all-specular path).
#[derive(Clone, Copy, Debug, Default)]
pub struct PathSample {
    pub beauty: Vec3,
    /// The same split by light path: the components sum to `beauty` up to float rounding.
    pub components: Split<Vec3>,
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
    fn component(self, diffuse_source: bool) -> Component {
        match self.diffuse {
            0 => Component::Emitted,
            // A diffuse source's light counts as already diffusely reflected once.
            _ if diffuse_source => Component::Indirect,
            1 if self.specular_after_first => Component::Caustic,
            1 => Component::Direct,
            _ => Component::Indirect,
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

    /// The class after a vertex of this lobe's kind.
    fn through(self, lobe: Lobe) -> Self {
        if lobe.is_specular() {
            self.through_specular()
        } else {
            self.through_diffuse()
        }
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

/// Veach's power heuristic with exponent 2.
fn power_heuristic(pdf: f32, other: f32) -> f32 {
    let (a, b) = (pdf * pdf, other * other);
    if a + b == 0.0 {
        0.0
    } else {
        a / (a + b)
    }
}

/// A reflecting vertex: the point, where rays leave it, the shading and geometric normals (both
/// on the side the path came from) and the direction back toward the eye.
#[derive(Clone, Copy, Debug)]
struct Reflecting {
    p: Vec3,
    origin: Vec3,
    ns: Vec3,
    ng: Vec3,
    wo: Vec3,
    /// The object the guide buffers name.
    object: u32,
}

/// What a path carries from one vertex to the next, besides what it has gathered.
#[derive(Clone, Copy, Debug)]
struct PathState {
    /// Throughput: the product of the BSDF weights so far.
    beta: Vec3,
    class: PathClass,
    /// The last bounce was a delta one (the camera counts as one): emission found next takes
    /// no MIS weight, since light sampling could not have found it.
    after_delta: bool,
    /// The density of the last bounce's direction, for the MIS weight of emission found next.
    bsdf_pdf: f32,
    /// Where the last bounce left from.
    prev_p: Vec3,
    /// Distance from the eye along the path.
    travelled: f32,
}

impl PathState {
    /// Follows a sampled direction: false when it cannot carry light (no density, or a zero
    /// throughput: nothing more can reach the eye along it).
    fn scatter(&mut self, bs: &BsdfSample, p: Vec3) -> bool {
        if bs.pdf <= 0.0 {
            return false;
        }
        self.beta *= bs.weight;
        self.after_delta = bs.lobe.is_delta();
        self.bsdf_pdf = bs.pdf;
        self.prev_p = p;
        self.beta != Vec3::ZERO
    }

    /// Russian roulette: false when the path ends here, else the survivor's weight goes up.
    fn survives(&mut self, sampler: &mut Sampler) -> bool {
        let survive = self.beta.max_element();
        if survive < 1.0 {
            if sampler.get_1d(Dim::Roulette) >= survive {
                return false;
            }
            self.beta /= survive;
        }
        true
    }
}

impl PathSample {
    /// Adds a contribution to the beauty and to its component (the split only when `F` has it).
    #[inline(always)]
    fn add<const F: u8>(&mut self, c: Vec3, component: Component) {
        self.beauty += c;
        if F & SPLIT != 0 {
            self.components[component] += c;
        }
    }

    /// Bookkeeping of a vertex whose lobe is known: while the path is still all-specular, the
    /// guide buffers follow it (the first D vertex is `x`, the last vertex of an all-specular
    /// path is what the pixel shows); then the class moves on by the lobe's tag alone.
    #[inline(always)]
    fn vertex<const F: u8>(
        &mut self,
        class: &mut PathClass,
        lobe: Lobe,
        object: u32,
        n: Vec3,
        depth: f32,
        albedo: Vec3,
    ) {
        if class.diffuse == 0 {
            self.guide::<F>(object, n, depth, albedo);
        }
        *class = class.through(lobe);
    }
}

impl<A: Accel, const F: u8> Integrator<'_, A, F> {
    /// One path sample of the radiance arriving along `ray`, split by light path. `rays` counts
    /// traced rays.
    pub fn sample(&self, ray: Ray, sampler: &mut Sampler, rays: &mut u64) -> PathSample {
        self.sample_recorded(ray, sampler, rays, &mut ())
    }

    /// [`Integrator::sample`] of a camera ray already traced: `hit` is its closest hit (from a
    /// packet of camera rays).
    pub fn sample_from(
        &self,
        ray: Ray,
        hit: Option<Hit>,
        sampler: &mut Sampler,
        rays: &mut u64,
    ) -> PathSample {
        self.trace(ray, Some(hit), sampler, rays, &mut ())
    }

    /// [`Integrator::sample`], reporting each vertex to `record` (nothing, for `()`).
    pub fn sample_recorded<R: Record>(
        &self,
        ray: Ray,
        sampler: &mut Sampler,
        rays: &mut u64,
        record: &mut R,
    ) -> PathSample {
        self.trace(ray, None, sampler, rays, record)
    }

    /// The path from `ray`, whose closest hit is `first` when already traced.
    #[inline(always)]
    fn trace<R: Record>(
        &self,
        mut ray: Ray,
        mut first: Option<Option<Hit>>,
        sampler: &mut Sampler,
        rays: &mut u64,
        record: &mut R,
    ) -> PathSample {
        let scene = self.scene;
        let mut out = PathSample::default();
        let mut path = PathState {
            beta: Vec3::ONE,
            class: PathClass::default(),
            after_delta: true,
            bsdf_pdf: 0.0,
            prev_p: ray.origin,
            travelled: 0.0,
        };
        for depth in 0.. {
            sampler.start_bounce(depth);
            *rays += 1;
            let hit = match first.take() {
                Some(hit) => hit,
                None => self.accel.intersect(&ray),
            };
            let Some(hit) = hit else {
                record.escaped(depth, ray.dir, path.beta);
                self.escaped(&mut out, &path, ray.dir);
                break;
            };
            let s = surface_with(scene, self.faces, &ray, &hit);
            let shape = &scene.shapes[hit.shape as usize];
            record.vertex(depth, &shape.name, s.p, path.beta, out.beauty);
            let wo = -ray.dir;
            path.travelled += hit.t * ray.dir.length();
            self.emitted(&mut out, &path, hit.shape, shape, &s, wo);
            if depth >= self.max_depth {
                break;
            }

            // Without a light a path can hit, the ray after the last vertex could only find one:
            // not traced.
            let last = F & MIS == 0 && depth + 1 >= self.max_depth;
            match self.scatter_at(shape, &s, wo, &mut out, &mut path, last, depth, sampler, rays) {
                Some(next) => ray = next,
                None => break,
            }
        }
        out
    }

    /// Scatters the path at a reflecting vertex through `bsdf`: the vertex's bookkeeping,
    /// next-event estimation at a non-delta vertex, a BSDF sample classified by its lobe, one
    /// Russian roulette. The next ray, or `None` where the path ends; `last` ends it after
    /// next-event estimation.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn scatter<B: Bsdf>(
        &self,
        bsdf: &B,
        out: &mut PathSample,
        path: &mut PathState,
        at: &Reflecting,
        s: &Surface,
        last: bool,
        depth: u32,
        sampler: &mut Sampler,
        rays: &mut u64,
    ) -> Option<Ray> {
        if !bsdf.scatters(at.wo) {
            return None;
        }
        let before = path.class;
        // A BSDF of one kind of lobe makes its vertex's kind known now, so the guides see it
        // even when the path ends here; one of several lobes, once a lobe is sampled.
        let travelled = path.travelled;
        let vertex = |out: &mut PathSample, class: &mut PathClass, lobe: Lobe| {
            out.vertex::<F>(class, lobe, at.object, at.ns, travelled, bsdf.albedo(lobe));
        };
        if let Some(lobe) = bsdf.lobe() {
            vertex(out, &mut path.class, lobe);
        }
        if bsdf.lobe() != Some(Lobe::Delta) {
            self.next_event(out, path, before, bsdf, at, sampler, rays);
        }
        if last {
            return None;
        }

        let bs = bsdf.sample(at.wo, sampler)?;
        // A non-delta direction under the geometric surface is an artefact of the shading
        // normal: dropped. A delta one is exact (and glass transmits).
        if !bs.wi.is_finite() || (!bs.lobe.is_delta() && at.ng.dot(bs.wi) <= 0.0) {
            return None;
        }
        if bsdf.lobe().is_none() {
            vertex(out, &mut path.class, bs.lobe);
        }
        if !path.scatter(&bs, at.p) {
            return None;
        }
        // Russian roulette once the path has had a chance to gather light, after non-delta
        // bounces only: a delta bounce draws no random number and keeps its throughput.
        if !bs.lobe.is_delta() && depth >= 2 && !path.survives(sampler) {
            return None;
        }
        let origin = if bs.wi.dot(at.ng) > 0.0 { at.origin } else { s.origin(-at.ng) };
        Some(Ray::new(origin, bs.wi))
    }

    /// Scatters the path at a hit on `shape` through its material's BSDF, with the shading and
    /// geometric normals both turned to the side the path came from (surfaces are two-sided),
    /// the shading one bumped and the material's colour textured where the material says so.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn scatter_at(
        &self,
        shape: &Shape,
        s: &Surface,
        wo: Vec3,
        out: &mut PathSample,
        path: &mut PathState,
        last: bool,
        depth: u32,
        sampler: &mut Sampler,
        rays: &mut u64,
    ) -> Option<Ray> {
        let scene = self.scene;
        let ng = if s.ng.dot(wo) >= 0.0 { s.ng } else { -s.ng };
        let mut ns = if s.ns.dot(ng) >= 0.0 { s.ns } else { -s.ns };
        let maps = if F & TEXTURES != 0 { scene.maps(shape.material) } else { Default::default() };
        // Where a solid texture is read (in f64, exact on planes the scene file makes exact);
        // an image texture reads only `s.uv`.
        let point = |t: &Texture| match t.is_solid() {
            true => scene.solid_point(&shape.geometry, s.prim, s.bary, s.p),
            false => DVec3::ZERO,
        };
        if let Some((t, height)) = maps.bump {
            let texture = &scene.textures[t as usize];
            ns = texture.bump(height, point(texture), s.uv, ns, ng);
        }
        if let Some((t, scale)) = maps.height {
            // Central differences of the height, half a texel (at most 1/1024) either side: the
            // bilinear lookup is linear within a texel, so this is the local slope.
            let texture = &scene.textures[t as usize];
            let d = texture.texel().min(1.0 / 1024.0);
            let p = point(texture);
            let h = |du: f32, dv: f32| scale * texture.scalar(p, s.uv + Vec2::new(du, dv));
            let (dhdu, dhdv) = ((h(d, 0.0) - h(-d, 0.0)) / (2.0 * d), (h(0.0, d) - h(0.0, -d)) / (2.0 * d));
            let bent = apply_height(ns, s.dpdu, s.dpdv, dhdu, dhdv);
            ns = if bent.dot(ng) > 1e-3 { bent } else { ns };
        }
        if let Some((t, scale)) = maps.normal {
            let texture = &scene.textures[t as usize];
            let c = texture.color(point(texture), s.uv) * 2.0 - Vec3::ONE;
            let bent = apply_normal_map(ns, s.dpdu, s.dpdv, Vec3::new(c.x * scale, c.y * scale, c.z));
            // A normal bent below the surface would reflect from under it: kept above.
            ns = if bent.dot(ng) > 1e-3 { bent } else { ns };
        }
        let textured = |constant: Vec3| match maps.color {
            Some(t) => {
                let texture = &scene.textures[t as usize];
                texture.color(point(texture), s.uv)
            }
            None => constant,
        };
        // Every ray leaving a reflecting point (shadow or bounce) goes to the side of `ng`.
        let at = Reflecting { p: s.p, origin: s.origin(ng), ns, ng, wo, object: shape.object };
        // Entering when the ray meets the outside, the side the geometric normal points to.
        let entering = s.ng.dot(wo) > 0.0;
        let material = &scene.materials[shape.material as usize];
        let metal_rough = |metallic: f32, roughness: f32| match maps.metal_rough {
            Some(t) => {
                let texture = &scene.textures[t as usize];
                let c = texture.color(point(texture), s.uv);
                (metallic * c.z, roughness * c.y)
            }
            None => (metallic, roughness),
        };
        with_bsdf!(material, textured, metal_rough, ns, entering, b => {
            self.scatter(b, out, path, &at, s, last, depth, sampler, rays)
        })
    }

    /// Emission at a hit on `shape` (number `index`), on its front side only (a scene without
    /// MIS has no light a path can hit), weighted against light sampling's chance of finding the
    /// same point.
    #[inline(always)]
    fn emitted(
        &self,
        out: &mut PathSample,
        path: &PathState,
        index: u32,
        shape: &Shape,
        s: &Surface,
        wo: Vec3,
    ) {
        let (emission, lights) = (shape.emission, self.lights);
        if F & MIS == 0 || emission.max_element() <= 0.0 || s.ng.dot(wo) <= 0.0 {
            return;
        }
        let light = lights.of_shape(index);
        let w = match light {
            Some(light) if !path.after_delta => {
                power_heuristic(path.bsdf_pdf, lights.pdf_shape(light, path.prev_p, s.p, s.ng))
            }
            _ => 1.0,
        };
        let source = light.is_some_and(|i| lights.diffuse_source[i as usize]);
        out.add::<F>(path.beta * emission * w, path.class.component(source));
    }

    /// What a path that left the scene along `dir` sees of the sun and the sky (nothing in a
    /// scene without them).
    #[inline(always)]
    fn escaped(&self, out: &mut PathSample, path: &PathState, dir: Vec3) {
        if F & MIS == 0 {
            return;
        }
        let lights = self.lights;
        for &i in &lights.distant {
            let (le, light_pdf) = lights.distant(i, dir, path.after_delta);
            if le != Vec3::ZERO {
                let w = if path.after_delta { 1.0 } else { power_heuristic(path.bsdf_pdf, light_pdf) };
                let component = path.class.component(lights.diffuse_source[i as usize]);
                out.add::<F>(path.beta * le * w, component);
            }
        }
    }

    /// Next-event estimation at a reflecting vertex: samples every light when there are few,
    /// else one picked by power, and gathers what each sample sends through the BSDF's lobes.
    /// `before` is the path's class before this vertex.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn next_event<B: Bsdf>(
        &self,
        out: &mut PathSample,
        path: &PathState,
        before: PathClass,
        bsdf: &B,
        at: &Reflecting,
        sampler: &mut Sampler,
        rays: &mut u64,
    ) {
        let (scene, lights) = (self.scene, self.lights);
        if lights.sample_all() {
            for i in 0..lights.emitters.len() {
                if let Some(ls) = lights.sample_one(scene, i, at.p, sampler.get_2d(Dim::Light(i as u32))) {
                    self.gather(out, path, before, bsdf, at, &ls, rays);
                }
            }
        } else if let Some(ls) =
            lights.sample(scene, at.p, sampler.get_1d(Dim::Select), sampler.get_2d(Dim::Light(0)))
        {
            self.gather(out, path, before, bsdf, at, &ls, rays);
        }
    }

    /// What light sample `ls` sends toward the eye through each lobe of `bsdf`, if it can
    /// reflect (it arrives above both normals) and a shadow ray finds nothing in between. Light
    /// through each lobe goes to the component that lobe makes, with its own MIS weight, so the
    /// split stays exact in expectation.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn gather<B: Bsdf>(
        &self,
        out: &mut PathSample,
        path: &PathState,
        before: PathClass,
        bsdf: &B,
        at: &Reflecting,
        ls: &LightSample,
        rays: &mut u64,
    ) {
        let cos = at.ns.dot(ls.wi);
        if !(cos > 0.0 && at.ng.dot(ls.wi) > 0.0 && ls.pdf > 0.0) {
            return;
        }
        let shadow = match ls.end {
            // Unnormalised direction: t in [0, 1] ends exactly at the light point.
            ShadowEnd::Point(q) => Ray { origin: at.origin, dir: q - at.origin, t_max: 1.0 },
            ShadowEnd::Infinite => Ray::new(at.origin, ls.wi),
        };
        *rays += 1;
        if self.accel.occluded(&shadow) {
            return;
        }
        let source = self.lights.diffuse_source[ls.light as usize];
        bsdf.eval_lobes(at.wo, ls.wi, |lobe, f, pdf| {
            if f != Vec3::ZERO {
                let w = if F & MIS == 0 || ls.delta { 1.0 } else { power_heuristic(ls.pdf, pdf) };
                let c = path.beta * f * ls.radiance * (cos * w / ls.pdf);
                out.add::<F>(c, before.through(lobe).component(source));
            }
        });
    }
}
