//! The path integrator, shaped as pbrt-v4's `PathIntegrator::Li`: at every vertex, emission;
//! next-event estimation with multiple importance sampling (power heuristic) at non-delta
//! vertices; a BSDF sample, classified by its lobe's tag alone; one Russian roulette; and a
//! depth limit. It never names a material: [`super::material`] makes a hit's BSDF. Generic over the
//! accelerator, so each backend gets its own monomorphised copy and no dynamic dispatch per ray,
//! and over the [`Features`] a render needs (a const bit set), so a feature the scene and its
//! outputs cannot use is compiled out of that render's copy, not skipped by a branch.
//!
//! [`Features`]: super::features::Features

use glam::Vec3;

use super::bsdf::{Bsdf, BsdfSample, Lobe};
use super::features::{GUIDES, MIS, SPLIT, TEXTURES};
use super::lights::{LightSample, Lights, ShadowEnd, Strategy};
use super::material::{Shading, UseBsdf};
use super::sampler::{Dim, Sampler};
use super::surface::{surface_with, valid_reflection, FaceNormals, Surface};
use crate::accel::{Accel, Hit, Ray};
use crate::component::{Component, Split};
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
    /// The camera rays' cone, for the footprint of texture lookups ([`Cone`]).
    pub cone: Cone,
}

/// A ray cone (Akenine-Möller et al., "Texture Level of Detail Strategies for Real-Time Ray
/// Tracing", 2019): a camera ray's footprint is `width + spread * distance` across, at
/// distance `distance` from the eye. It is followed through specular-like vertices (ignoring
/// their curvature, as pbrt-v4's camera approximation does) and dropped at the first diffuse
/// one, past which lookups are points again. Zero: every lookup a point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Cone {
    pub width: f32,
    pub spread: f32,
}

impl Cone {
    /// A camera's cone for an image `height` pixels high at `spp` samples a pixel: a pixel's
    /// width at unit distance (a pinhole's; the thin lens's the same, ignoring the lens) or
    /// across the view (an orthographic camera's), scaled, as pbrt-v4 scales its camera's ray
    /// differentials, by 1 / sqrt(spp) (at least 1/8): the samples spread over the pixel
    /// already, and a cone a pixel wide would blur twice.
    pub fn of_camera(camera: &crate::scene::Camera, height: u32, spp: u32) -> Cone {
        let scale = (1.0 / (spp.max(1) as f32).sqrt()).max(0.125) / height.max(1) as f32;
        match camera.orthographic {
            Some(h) => Cone { width: h * scale, spread: 0.0 },
            None => Cone { width: 0.0, spread: 2.0 * (0.5 * camera.fov.to_radians()).tan() * scale },
        }
    }
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
    /// Where the last bounce left from, and its shading normal there (the light tree's
    /// probabilities depend on both).
    prev_p: Vec3,
    prev_n: Vec3,
    /// Distance from the eye along the path.
    travelled: f32,
}

impl PathState {
    /// Follows a sampled direction: false when it cannot carry light (no density, or a zero
    /// throughput: nothing more can reach the eye along it).
    fn scatter(&mut self, bs: &BsdfSample, p: Vec3, n: Vec3) -> bool {
        if bs.pdf <= 0.0 {
            return false;
        }
        self.beta *= bs.weight;
        self.after_delta = bs.lobe.is_delta();
        self.bsdf_pdf = bs.pdf;
        self.prev_p = p;
        self.prev_n = n;
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

    /// The path from `ray`, whose closest hit is `first` when already traced: at each vertex,
    /// its emission, then scattering through its material (next-event estimation, a BSDF
    /// sample, Russian roulette), until the path leaves the scene, ends or reaches the depth
    /// limit.
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
        let mut walk = Walk {
            out: PathSample::default(),
            path: PathState {
                beta: Vec3::ONE,
                class: PathClass::default(),
                after_delta: true,
                bsdf_pdf: 0.0,
                prev_p: ray.origin,
                prev_n: Vec3::ZERO,
                travelled: 0.0,
            },
            sampler,
            rays,
        };
        for depth in 0.. {
            walk.sampler.start_bounce(depth);
            *walk.rays += 1;
            let hit = match first.take() {
                Some(hit) => hit,
                None => self.accel.intersect(&ray),
            };
            let Some(hit) = hit else {
                record.escaped(depth, ray.dir, walk.path.beta);
                self.escaped(&mut walk.out, &walk.path, ray.dir);
                break;
            };
            let s = surface_with(scene, self.faces, &ray, &hit, F & TEXTURES != 0);
            let shape = &scene.shapes[hit.shape as usize];
            record.vertex(depth, &shape.name, s.p, walk.path.beta, walk.out.beauty);
            let wo = -ray.dir;
            let distance = hit.t * ray.dir.length();
            walk.path.travelled += distance;
            // A hit from inside an absorbing object: the segment ran through its volume.
            if s.ng.dot(wo) < 0.0 {
                if let Some(sigma) = scene.absorption(shape.material) {
                    walk.path.beta *= (-sigma * distance).exp();
                }
            }
            self.emitted(&mut walk.out, &walk.path, &hit, shape, &s, wo);
            if depth >= self.max_depth {
                break;
            }
            // Without a light a path can hit, the ray after the last vertex could only find one:
            // not traced.
            let last = F & MIS == 0 && depth + 1 >= self.max_depth;
            let vertex = Vertex { shape, s: &s, wo, depth, last };
            match self.scatter_at(&mut walk, &vertex) {
                Some(next) => ray = next,
                None => break,
            }
        }
        walk.out
    }

    /// Scatters the path at a hit through its material's BSDF, with the shading and geometric
    /// normals both turned to the side the path came from (surfaces are two-sided), the
    /// shading one bent by the material's maps.
    #[inline(always)]
    fn scatter_at(&self, walk: &mut Walk, v: &Vertex) -> Option<Ray> {
        let s = v.s;
        let ng = if s.ng.dot(v.wo) >= 0.0 { s.ng } else { -s.ng };
        let mut shading = Shading::new(self.scene, v.shape, s, F & TEXTURES != 0);
        if F & TEXTURES != 0 && walk.path.class.diffuse == 0 {
            // The cone across the surface: its width over the cosine, the footprint's long
            // axis (an isotropic lookup as wide as the footprint is long).
            let width = self.cone.width + self.cone.spread * walk.path.travelled;
            shading.set_footprint(width / ng.dot(v.wo).abs().max(1e-3));
        }
        // Raised where its reflection of the view would fall below the surface (Cycles' bump-map
        // correction): a bent normal turned away from the viewer must not end the path.
        let bent = shading.normal(ng);
        let ns = valid_reflection(ng, v.wo, bent);
        // Every ray leaving a reflecting point (shadow or bounce) goes to the side of `ng`.
        let at = Reflecting { p: s.p, origin: s.origin(ng), ns, ng, wo: v.wo, object: v.shape.object };
        // Entering when the ray meets the outside, the side the geometric normal points to.
        let entering = s.ng.dot(v.wo) > 0.0;
        shading.with_bsdf(ns, bent, v.wo, entering, Scatter { integrator: self, walk, at: &at, v })
    }

    /// Scatters the path at a reflecting vertex through `bsdf`: the vertex's bookkeeping,
    /// next-event estimation at a non-delta vertex, a BSDF sample classified by its lobe, one
    /// Russian roulette. The next ray, or `None` where the path ends; `v.last` ends it after
    /// next-event estimation.
    #[inline(always)]
    fn scatter<B: Bsdf>(&self, walk: &mut Walk, bsdf: &B, at: &Reflecting, v: &Vertex) -> Option<Ray> {
        if !bsdf.scatters(at.wo) {
            return None;
        }
        let before = walk.path.class;
        // A BSDF of one kind of lobe makes its vertex's kind known now, so the guides see it
        // even when the path ends here; one of several lobes, once a lobe is sampled.
        let travelled = walk.path.travelled;
        let vertex = |out: &mut PathSample, class: &mut PathClass, lobe: Lobe| {
            out.vertex::<F>(class, lobe, at.object, at.ns, travelled, bsdf.albedo(lobe));
        };
        if let Some(lobe) = bsdf.lobe() {
            vertex(&mut walk.out, &mut walk.path.class, lobe);
        }
        if bsdf.lobe() != Some(Lobe::Delta) {
            self.next_event(walk, before, bsdf, at);
        }
        if v.last {
            return None;
        }

        let bs = bsdf.sample(at.wo, walk.sampler)?;
        // A non-delta direction under the geometric surface is an artefact of the shading
        // normal: dropped. A delta one is exact (and glass transmits).
        if !bs.wi.is_finite() || (!bs.lobe.is_delta() && at.ng.dot(bs.wi) <= 0.0) {
            return None;
        }
        if bsdf.lobe().is_none() {
            vertex(&mut walk.out, &mut walk.path.class, bs.lobe);
        }
        if !walk.path.scatter(&bs, at.p, at.ns) {
            return None;
        }
        // Russian roulette once the path has had a chance to gather light, after non-delta
        // bounces only: a delta bounce draws no random number and keeps its throughput.
        if !bs.lobe.is_delta() && v.depth >= 2 && !walk.path.survives(walk.sampler) {
            return None;
        }
        let origin = if bs.wi.dot(at.ng) > 0.0 { at.origin } else { v.s.origin(-at.ng) };
        Some(Ray::new(origin, bs.wi))
    }

    /// Emission at a hit on `shape`, on its front side only (a scene without
    /// MIS has no light a path can hit), weighted against light sampling's chance of finding the
    /// same point.
    #[inline(always)]
    fn emitted(
        &self,
        out: &mut PathSample,
        path: &PathState,
        hit: &Hit,
        shape: &Shape,
        s: &Surface,
        wo: Vec3,
    ) {
        let (emission, lights) = (shape.emission, self.lights);
        if F & MIS == 0 || emission.max_element() <= 0.0 || s.ng.dot(wo) <= 0.0 {
            return;
        }
        let light = lights.of_shape(hit.shape);
        let w = match light {
            Some(light) if !path.after_delta => {
                let pdf = lights.pdf_shape(light, hit.prim, path.prev_p, path.prev_n, s.p, s.ng);
                power_heuristic(path.bsdf_pdf, pdf)
            }
            _ => 1.0,
        };
        let source = light.is_some_and(|i| lights.diffuse_source[i as usize]);
        let emission =
            if F & TEXTURES != 0 { self.scene.emission_at(shape, [s.uv, s.uv1]) } else { emission };
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
    /// else one picked from the table, or each light at infinity and one bounded light picked
    /// by the tree; gathers what each sample sends through the BSDF's lobes. `before` is the
    /// path's class before this vertex.
    #[inline(always)]
    fn next_event<B: Bsdf>(&self, walk: &mut Walk, before: PathClass, bsdf: &B, at: &Reflecting) {
        let (scene, lights) = (self.scene, self.lights);
        match lights.strategy() {
            Strategy::All => {
                for i in 0..lights.emitters.len() {
                    let u = walk.sampler.get_2d(Dim::Light(i as u32));
                    if let Some(ls) = lights.sample_one(scene, i, at.p, u) {
                        self.gather(walk, before, bsdf, at, &ls);
                    }
                }
            }
            Strategy::One => {
                let (select, u) = (walk.sampler.get_1d(Dim::Select), walk.sampler.get_2d(Dim::Light(0)));
                if let Some(ls) = lights.sample(scene, at.p, select, u) {
                    self.gather(walk, before, bsdf, at, &ls);
                }
            }
            Strategy::Tree => {
                for (k, &i) in lights.distant.iter().enumerate() {
                    let u = walk.sampler.get_2d(Dim::Light(1 + k as u32));
                    if let Some(ls) = lights.sample_one(scene, i as usize, at.p, u) {
                        self.gather(walk, before, bsdf, at, &ls);
                    }
                }
                let (select, u) = (walk.sampler.get_1d(Dim::Select), walk.sampler.get_2d(Dim::Light(0)));
                if let Some(ls) = lights.sample_tree(scene, at.p, at.ns, select, u) {
                    self.gather(walk, before, bsdf, at, &ls);
                }
            }
        }
    }

    /// What light sample `ls` sends toward the eye through each lobe of `bsdf`, if it can
    /// reflect (it arrives above both normals) and a shadow ray finds nothing in between. Light
    /// through each lobe goes to the component that lobe makes, with its own MIS weight, so the
    /// split stays exact in expectation.
    #[inline(always)]
    fn gather<B: Bsdf>(
        &self,
        walk: &mut Walk,
        before: PathClass,
        bsdf: &B,
        at: &Reflecting,
        ls: &LightSample,
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
        *walk.rays += 1;
        if self.accel.occluded(&shadow) {
            return;
        }
        let source = self.lights.diffuse_source[ls.light as usize];
        let (out, beta) = (&mut walk.out, walk.path.beta);
        bsdf.eval_lobes(at.wo, ls.wi, |lobe, f, pdf| {
            if f != Vec3::ZERO {
                let w = if F & MIS == 0 || ls.delta { 1.0 } else { power_heuristic(ls.pdf, pdf) };
                let c = beta * f * ls.radiance * (cos * w / ls.pdf);
                out.add::<F>(c, before.through(lobe).component(source));
            }
        });
    }
}

/// One path being traced: what it has gathered, where it is, the numbers it draws and the count
/// of rays it traced.
struct Walk<'s> {
    out: PathSample,
    path: PathState,
    sampler: &'s mut Sampler,
    rays: &'s mut u64,
}

/// A hit the path scatters at: its shape and surface, the direction back toward the eye, the
/// path's depth there, and whether the path ends after next-event estimation.
struct Vertex<'v> {
    shape: &'v Shape,
    s: &'v Surface,
    wo: Vec3,
    depth: u32,
    last: bool,
}

/// Scattering through whichever BSDF the vertex's material has ([`UseBsdf`]).
struct Scatter<'i, 'w, 's, 'v, A: Accel, const F: u8> {
    integrator: &'i Integrator<'i, A, F>,
    walk: &'w mut Walk<'s>,
    at: &'v Reflecting,
    v: &'v Vertex<'v>,
}

impl<A: Accel, const F: u8> UseBsdf for Scatter<'_, '_, '_, '_, A, F> {
    type Output = Option<Ray>;

    #[inline(always)]
    fn with<B: Bsdf>(self, bsdf: &B) -> Option<Ray> {
        self.integrator.scatter(self.walk, bsdf, self.at, self.v)
    }
}
