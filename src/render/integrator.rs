//! The path integrator, shaped as pbrt-v4's `PathIntegrator::Li`: at every vertex, emission;
//! next-event estimation with multiple importance sampling (power heuristic) at non-delta
//! vertices; a BSDF sample, classified by its lobe's tag alone; one Russian roulette; and a
//! depth limit. It never names a material: [`super::material`] makes a hit's BSDF. Generic over the
//! accelerator, so each backend gets its own monomorphised copy and no dynamic dispatch per ray,
//! and over the [`Features`] a render needs (a const bit set), so a feature the scene and its
//! outputs cannot use is compiled out of that render's copy, not skipped by a branch.
//!
//! [`Features`]: super::features::Features

use glam::{Vec2, Vec3};

use arrayvec::ArrayVec;

use super::bsdf::{reflect, Bsdf, BsdfSample, Lobe};
use super::features::{GUIDES, MIS, SPLIT, TEXTURES};
use super::guide::{Directions, Guide, RadianceRecord};
use super::lights::{LightSample, Lights, ShadowEnd, Strategy};
use super::material::{Shading, UseBsdf};
use super::paths::PathExprs;
use super::sampler::{Dim, Sampler};
use super::surface::{surface_with, valid_reflection, FaceNormals, Surface};
use crate::accel::bvh::simd::{Inlined, Isa};
use crate::accel::{Accel, Hit, Ray};
use crate::component::{Component, Split};
use crate::lpe::State;
use crate::math::luminance;
use crate::scene::{Scene, Shape};

/// What the integrator reads for every path: the scene, its accelerator and its lights. `F` is
/// the [`super::features::Features`] bit set this copy computes; the default is all of them.
pub struct Integrator<'a, A: Accel, const F: u8 = { super::features::ALL }> {
    pub scene: &'a Scene,
    pub accel: &'a A,
    pub lights: &'a Lights,
    /// The light path expressions that split each contribution among the components.
    pub paths: &'a PathExprs,
    /// The scene's triangle normals, made once (`FaceNormals::new`).
    pub faces: &'a FaceNormals,
    pub max_depth: u32,
    /// The camera rays' cone, for the footprint of texture lookups ([`Cone`]).
    pub cone: Cone,
    /// The learned incident light that guides directions at diffuse-like vertices, when the
    /// render is guided ([`super::guide`]).
    pub guide: Option<&'a Guide>,
    /// The build the path loop runs in ([`Isa::for_loops`]; the same results in any).
    pub isa: Isa,
}

/// The guide's share of the directions at a vertex whose lobes are all diffuse-like (Müller et
/// al.'s fixed one-sample mixture of guide and BSDF); less where the BSDF also reflects
/// specularly, in proportion to its diffuse albedo.
pub const GUIDE_SHARE: f32 = 0.5;

/// Guided bounces a training path records at most (the first ones: light found deeper adds
/// little to the guide for its cost in records).
const GUIDE_BOUNCES: usize = 4;

/// What the guide learns from: the radiance a bounce brings (`All`), or only what arrives
/// after a further bounce, leaving out light sources the bounce finds directly, which
/// next-event estimation samples already (`Indirect`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Learns {
    All,
    Indirect,
}

/// A training path's guided bounces, turned into the guide's records when it ends.
#[derive(Debug)]
pub struct GuidePath {
    learns: Learns,
    bounces: ArrayVec<GuideBounce, GUIDE_BOUNCES>,
    /// The last bounce was made at the vertex before the current one.
    pending: bool,
    /// The records of every path so far, in the order the paths were traced.
    pub records: Vec<RadianceRecord>,
}

#[derive(Clone, Copy, Debug)]
struct GuideBounce {
    p: Vec3,
    dir: Vec3,
    pdf: f32,
    /// The throughput after the bounce (its roulette included).
    beta: Vec3,
    /// The path's radiance before this bounce's own light: what it gathered at the bounce
    /// (`Learns::All`), or after the next vertex's emission (`Learns::Indirect`).
    before: Vec3,
}

impl GuidePath {
    pub fn new(learns: Learns) -> GuidePath {
        GuidePath { learns, bounces: ArrayVec::new(), pending: false, records: Vec::new() }
    }

    /// A path starts.
    fn start(&mut self) {
        self.bounces.clear();
        self.pending = false;
    }

    /// The path found the light of the vertex the last bounce led to (its emission, or what it
    /// sees at infinity), and `beauty` is its radiance now.
    fn found_direct(&mut self, beauty: Vec3) {
        if self.pending && self.learns == Learns::Indirect {
            if let Some(b) = self.bounces.last_mut() {
                b.before = beauty;
            }
        }
        self.pending = false;
    }

    /// The path ends with radiance `beauty`: each bounce's record is the radiance it brought,
    /// over its throughput (the incident radiance along its direction, averaged over the
    /// channels), over its density.
    fn finish(&mut self, beauty: Vec3) {
        for b in self.bounces.drain(..) {
            let gathered = beauty - b.before;
            let incident = Vec3::select(b.beta.cmpgt(Vec3::ZERO), gathered / b.beta, Vec3::ZERO);
            let value = incident.element_sum() / 3.0 / b.pdf;
            // A zero counts too: where paths go, the guide's cells are finer.
            if value.is_finite() && value >= 0.0 {
                self.records.push(RadianceRecord::new(b.p, b.dir, value));
            }
        }
    }
}

/// The guide at one vertex: its directions there, its share of the mixture, and the shading
/// normal, above which it samples.
struct Guided<'g> {
    dirs: Directions<'g>,
    share: f32,
    n: Vec3,
}

impl Guided<'_> {
    /// A direction from the guide, one below the surface reflected across it. The guide spans
    /// the sphere; unfolded, half of its directions where light comes from all around (a
    /// furnace) fell below the surface and ended their paths, and the mixture's weights
    /// ρ p_bsdf / (½ p_bsdf + ½ p_guide) had a second moment of 1.40 ρ² a bounce (1.10 ρ²
    /// folded), so that in a furnace of albedo 0.9 it grew along the path.
    fn sample(&self, u: Vec2) -> Vec3 {
        let d = self.dirs.sample(u).0;
        if self.n.dot(d) < 0.0 {
            -reflect(d, self.n)
        } else {
            d
        }
    }

    /// The density of [`Guided::sample`]'s directions: the guide's at `wi` and at its mirror
    /// image below the surface; none below it.
    fn pdf(&self, wi: Vec3) -> f32 {
        if self.n.dot(wi) <= 0.0 {
            return 0.0;
        }
        self.dirs.pdf(wi) + self.dirs.pdf(-reflect(wi, self.n))
    }

    /// The density with which the mixture picks direction `wi` (where the guide's density is
    /// `guide`) and counts it as lobe kind `k` of `lobes` (diffuse, specular: their values and
    /// densities at `wi`), choosing the kind of a guided direction in proportion to the
    /// lobes' values.
    fn density(&self, lobes: &[(Vec3, f32); 2], k: usize, guide: f32) -> f32 {
        let total = luminance(lobes[0].0) + luminance(lobes[1].0);
        let pick = if total > 0.0 { luminance(lobes[k].0) / total } else { 0.0 };
        (1.0 - self.share) * lobes[k].1 + self.share * guide * pick
    }
}

/// A direction from the one-sample mixture of the guide (its share) and the BSDF, weighted
/// by the mixture's density; its lobe kind, for the component split, is the BSDF's when
/// the BSDF sampled it, else one chosen in proportion to the lobes' values there. A delta
/// direction (only the BSDF samples those) keeps no density and its weight over the BSDF's
/// share.
#[inline(always)]
fn sample_guided<B: Bsdf>(
    bsdf: &B,
    wo: Vec3,
    ns: Vec3,
    g: &Guided,
    sampler: &mut Sampler,
) -> Option<BsdfSample> {
    let (wi, lobe) = if sampler.get_1d(Dim::Guide) < g.share {
        (g.sample(sampler.get_2d(Dim::Direction)), None)
    } else {
        let bs = bsdf.sample(wo, sampler)?;
        if bs.lobe.is_delta() {
            return Some(BsdfSample { weight: bs.weight / (1.0 - g.share), ..bs });
        }
        (bs.wi, Some(bs.lobe))
    };
    let cos = ns.dot(wi);
    if cos <= 0.0 {
        return None;
    }
    let lobes = lobes_by_kind(bsdf, wo, wi);
    let k = match lobe {
        Some(lobe) => lobe.is_specular() as usize,
        None => {
            let (d, s) = (luminance(lobes[0].0), luminance(lobes[1].0));
            if d + s <= 0.0 {
                return None;
            }
            (sampler.get_1d(Dim::Lobe) * (d + s) >= d) as usize
        }
    };
    let pdf = g.density(&lobes, k, g.pdf(wi));
    if pdf <= 0.0 || lobes[k].0 == Vec3::ZERO {
        return None;
    }
    Some(BsdfSample { wi, weight: lobes[k].0 * (cos / pdf), pdf, lobe: kind(k) })
}

/// The values and densities of a BSDF's diffuse and its specular lobes toward `wi`.
#[inline(always)]
fn lobes_by_kind<B: Bsdf>(bsdf: &B, wo: Vec3, wi: Vec3) -> [(Vec3, f32); 2] {
    let mut kinds = [(Vec3::ZERO, 0.0); 2];
    bsdf.eval_lobes(wo, wi, |lobe, f, pdf| {
        let k = &mut kinds[lobe.is_specular() as usize];
        k.0 += f;
        k.1 += pdf;
    });
    kinds
}

/// The lobe kind of index `k` in [`lobes_by_kind`].
fn kind(k: usize) -> Lobe {
    if k == 0 {
        Lobe::Diffuse
    } else {
        Lobe::Specular
    }
}

/// How much of a BSDF is diffuse-like: all of a diffuse one, none of a specular or delta one,
/// and a mixed one's share of diffuse albedo.
#[inline(always)]
fn diffuse_fraction<B: Bsdf>(bsdf: &B) -> f32 {
    match bsdf.lobe() {
        Some(Lobe::Diffuse) => 1.0,
        Some(_) => 0.0,
        None => {
            let d = luminance(bsdf.albedo(Lobe::Diffuse));
            let s = luminance(bsdf.albedo(Lobe::Specular));
            if d + s > 0.0 {
                d / (d + s)
            } else {
                0.0
            }
        }
    }
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

/// How many D vertices the eye path has passed: the guide buffers follow the path until the
/// first. (Which component its light goes to is the light path expressions' state.)
#[derive(Clone, Copy, Debug, Default)]
struct PathClass {
    diffuse: u32,
}

impl PathClass {
    /// The class after a vertex of this lobe's kind.
    fn through(self, lobe: Lobe) -> Self {
        PathClass { diffuse: self.diffuse + u32::from(!lobe.is_specular()) }
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
    /// Where the path is in the light path expressions (the split's automaton).
    lpe: State,
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
    #[inline(always)]
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
    #[inline(always)]
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
    /// Adds a contribution to the beauty, to the components whose expressions its path
    /// matches (`mask`, [`PathExprs::light`]) and to the AOVs it matches, in `aovs` (the split
    /// and the AOVs only when `F` has the split).
    #[inline(always)]
    fn add<const F: u8>(&mut self, c: Vec3, mask: u64, aovs: &mut [Vec3]) {
        self.beauty += c;
        if F & SPLIT != 0 {
            let mut m = mask & super::paths::COMPONENT_BITS;
            while m != 0 {
                self.components[Component::ALL[m.trailing_zeros() as usize]] += c;
                m &= m - 1;
            }
            let mut m = mask >> Component::ALL.len();
            while m != 0 {
                if let Some(a) = aovs.get_mut(m.trailing_zeros() as usize) {
                    *a += c;
                }
                m &= m - 1;
            }
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

impl<'a, A: Accel, const F: u8> Integrator<'a, A, F> {
    /// The integrator of `scene` as its file sets it up (its depth, the camera's cone for the
    /// film's height at `spp`, no guide), the path loop in the best build this CPU runs: for
    /// benchmarks and tests that trace paths without a render's options.
    pub fn of_scene(
        scene: &'a Scene,
        accel: &'a A,
        lights: &'a Lights,
        paths: &'a PathExprs,
        faces: &'a FaceNormals,
        spp: u32,
    ) -> Self {
        Integrator {
            scene,
            accel,
            lights,
            paths,
            faces,
            max_depth: scene.render.max_depth,
            cone: Cone::of_camera(&scene.camera, scene.film.height, spp),
            guide: None,
            isa: Isa::for_loops(),
        }
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
        self.trace(ray, Some(hit), sampler, rays, &mut (), &mut [])
    }

    /// [`Integrator::sample_from`], adding each AOV's light to `aovs` (one value an AOV, in
    /// the order of [`PathExprs::with_aovs`]; zero them before).
    pub fn sample_from_into(
        &self,
        ray: Ray,
        hit: Option<Hit>,
        sampler: &mut Sampler,
        rays: &mut u64,
        aovs: &mut [Vec3],
    ) -> PathSample {
        self.isa.run(PathJob { integrator: self, ray, hit, sampler, rays, aovs })
    }

    /// [`Integrator::sample`] of a training path: its guided bounces become the guide's
    /// records in `path`.
    pub fn sample_training(
        &self,
        ray: Ray,
        sampler: &mut Sampler,
        rays: &mut u64,
        path: &mut GuidePath,
    ) -> PathSample {
        self.trace_with(ray, None, sampler, rays, &mut (), (&mut [], Some(path)))
    }

    /// [`Integrator::sample`], reporting each vertex to `record` (nothing, for `()`).
    pub fn sample_recorded<R: Record>(
        &self,
        ray: Ray,
        sampler: &mut Sampler,
        rays: &mut u64,
        record: &mut R,
    ) -> PathSample {
        self.trace(ray, None, sampler, rays, record, &mut [])
    }

    /// The path from `ray`, whose closest hit is `first` when already traced: at each vertex,
    /// its emission, then scattering through its material (next-event estimation, a BSDF
    /// sample, Russian roulette), until the path leaves the scene, ends or reaches the depth
    /// limit.
    #[inline(always)]
    fn trace<R: Record>(
        &self,
        ray: Ray,
        first: Option<Option<Hit>>,
        sampler: &mut Sampler,
        rays: &mut u64,
        record: &mut R,
        aovs: &mut [Vec3],
    ) -> PathSample {
        self.trace_with(ray, first, sampler, rays, record, (aovs, None))
    }

    /// [`Integrator::trace`], adding to `aovs` and following the path's guided bounces in
    /// `training` when it is a training path.
    #[inline(always)]
    fn trace_with<R: Record>(
        &self,
        mut ray: Ray,
        mut first: Option<Option<Hit>>,
        sampler: &mut Sampler,
        rays: &mut u64,
        record: &mut R,
        (aovs, mut training): (&mut [Vec3], Option<&mut GuidePath>),
    ) -> PathSample {
        if let Some(t) = training.as_deref_mut() {
            t.start();
        }
        let scene = self.scene;
        let mut walk = Walk {
            out: PathSample::default(),
            path: PathState {
                beta: Vec3::ONE,
                class: PathClass::default(),
                lpe: self.paths.start(),
                after_delta: true,
                bsdf_pdf: 0.0,
                prev_p: ray.origin,
                prev_n: Vec3::ZERO,
                travelled: 0.0,
            },
            sampler,
            rays,
            aovs,
            training,
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
                self.escaped(&mut walk.out, walk.aovs, &walk.path, ray.dir);
                if let Some(t) = walk.training.as_deref_mut() {
                    t.found_direct(walk.out.beauty);
                }
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
            self.emitted((&mut walk.out, walk.aovs), &walk.path, &hit, shape, &s, wo);
            if let Some(t) = walk.training.as_deref_mut() {
                t.found_direct(walk.out.beauty);
            }
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
        if let Some(t) = walk.training {
            t.finish(walk.out.beauty);
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
        let before = walk.path.lpe;
        // AOVs of albedo events (`C[DGSV]A`): each kind of lobe here reports its albedo, times
        // the throughput to here, to the AOVs an `A` after it completes. Not light: the beauty
        // and the components take nothing.
        if F & SPLIT != 0 && self.paths.has_albedo() {
            for kind in bsdf.kinds().iter() {
                let mut m = self.paths.albedo(before, kind) >> Component::ALL.len();
                while m != 0 {
                    if let Some(a) = walk.aovs.get_mut(m.trailing_zeros() as usize) {
                        *a += walk.path.beta * bsdf.kind_albedo(kind);
                    }
                    m &= m - 1;
                }
            }
        }
        // A BSDF of one kind of lobe makes its vertex's kind known now, so the guides see it
        // even when the path ends here; one of several lobes, once a lobe is sampled.
        let travelled = walk.path.travelled;
        let vertex = |out: &mut PathSample, class: &mut PathClass, lobe: Lobe| {
            out.vertex::<F>(class, lobe, at.object, at.ns, travelled, bsdf.albedo(lobe));
        };
        if let Some(lobe) = bsdf.lobe() {
            vertex(&mut walk.out, &mut walk.path.class, lobe);
        }
        // The guide's directions here, where the BSDF is diffuse-like.
        let guided = self.guide.and_then(|g| {
            let share = GUIDE_SHARE * diffuse_fraction(bsdf);
            (share > 0.0).then(|| Guided { dirs: g.at(at.p), share, n: at.ns })
        });
        if bsdf.lobe() != Some(Lobe::Delta) {
            self.next_event(walk, before, bsdf, at, guided.as_ref());
        }
        if v.last {
            return None;
        }

        let bs = match &guided {
            Some(g) => sample_guided(bsdf, at.wo, at.ns, g, walk.sampler)?,
            None => bsdf.sample(at.wo, walk.sampler)?,
        };
        // A non-delta direction under the geometric surface is an artefact of the shading
        // normal: dropped. A delta one is exact (and glass transmits).
        if !bs.wi.is_finite() || (!bs.lobe.is_delta() && at.ng.dot(bs.wi) <= 0.0) {
            return None;
        }
        if bsdf.lobe().is_none() {
            vertex(&mut walk.out, &mut walk.path.class, bs.lobe);
        }
        if F & SPLIT != 0 {
            walk.path.lpe = self.paths.scatter(before, bs.lobe, bs.wi.dot(at.ng) <= 0.0);
        }
        if !walk.path.scatter(&bs, at.p, at.ns) {
            return None;
        }
        // Russian roulette once the path has had a chance to gather light, after non-delta
        // bounces only: a delta bounce draws no random number and keeps its throughput.
        if !bs.lobe.is_delta() && v.depth >= 2 && !walk.path.survives(walk.sampler) {
            return None;
        }
        if let Some(t) = walk.training.as_deref_mut() {
            if !bs.lobe.is_delta() && !t.bounces.is_full() {
                let b = GuideBounce {
                    p: at.p,
                    dir: bs.wi,
                    pdf: bs.pdf,
                    beta: walk.path.beta,
                    before: walk.out.beauty,
                };
                t.bounces.push(b);
                t.pending = true;
            }
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
        (out, aovs): (&mut PathSample, &mut [Vec3]),
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
        let mask = if F & SPLIT != 0 { self.paths.light(path.lpe, light) } else { 0 };
        let emission =
            if F & TEXTURES != 0 { self.scene.emission_at(shape, [s.uv, s.uv1]) } else { emission };
        out.add::<F>(path.beta * emission * w, mask, aovs);
    }

    /// What a path that left the scene along `dir` sees of the sun and the sky (nothing in a
    /// scene without them).
    #[inline(always)]
    fn escaped(&self, out: &mut PathSample, aovs: &mut [Vec3], path: &PathState, dir: Vec3) {
        if F & MIS == 0 {
            return;
        }
        let lights = self.lights;
        for &i in &lights.distant {
            let (le, light_pdf) = lights.distant(i, dir, path.after_delta);
            if le != Vec3::ZERO {
                let w = if path.after_delta { 1.0 } else { power_heuristic(path.bsdf_pdf, light_pdf) };
                let mask = if F & SPLIT != 0 { self.paths.light(path.lpe, Some(i)) } else { 0 };
                out.add::<F>(path.beta * le * w, mask, aovs);
            }
        }
    }

    /// Next-event estimation at a reflecting vertex: samples every light when there are few,
    /// else one picked from the table, or each light at infinity and one bounded light picked
    /// by the tree; gathers what each sample sends through the BSDF's lobes. `before` is the
    /// path's state in the light path expressions before this vertex.
    #[inline(always)]
    fn next_event<B: Bsdf>(
        &self,
        walk: &mut Walk,
        before: State,
        bsdf: &B,
        at: &Reflecting,
        guided: Option<&Guided>,
    ) {
        let (scene, lights) = (self.scene, self.lights);
        match lights.strategy() {
            Strategy::All => {
                for i in 0..lights.emitters.len() {
                    let u = walk.sampler.get_2d(Dim::Light(i as u32));
                    if let Some(ls) = lights.sample_one(scene, i, at.p, u) {
                        self.gather(walk, before, bsdf, at, &ls, guided);
                    }
                }
            }
            Strategy::One => {
                let (select, u) = (walk.sampler.get_1d(Dim::Select), walk.sampler.get_2d(Dim::Light(0)));
                if let Some(ls) = lights.sample(scene, at.p, select, u) {
                    self.gather(walk, before, bsdf, at, &ls, guided);
                }
            }
            Strategy::Tree => {
                for (k, &i) in lights.distant.iter().enumerate() {
                    let u = walk.sampler.get_2d(Dim::Light(1 + k as u32));
                    if let Some(ls) = lights.sample_one(scene, i as usize, at.p, u) {
                        self.gather(walk, before, bsdf, at, &ls, guided);
                    }
                }
                let (select, u) = (walk.sampler.get_1d(Dim::Select), walk.sampler.get_2d(Dim::Light(0)));
                if let Some(ls) = lights.sample_tree(scene, at.p, at.ns, select, u) {
                    self.gather(walk, before, bsdf, at, &ls, guided);
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
        before: State,
        bsdf: &B,
        at: &Reflecting,
        ls: &LightSample,
        guided: Option<&Guided>,
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
        let paths = self.paths;
        // The expressions light through a lobe of this kind matches (a light sample reflects).
        let mask = |lobe| {
            if F & SPLIT != 0 {
                paths.light(paths.scatter(before, lobe, false), Some(ls.light))
            } else {
                0
            }
        };
        let (out, aovs, beta) = (&mut walk.out, &mut *walk.aovs, walk.path.beta);
        if let Some(g) = guided {
            // Weighed against the mixture's density of the direction, lobe kind by kind.
            let lobes = lobes_by_kind(bsdf, at.wo, ls.wi);
            let guide = if ls.delta { 0.0 } else { g.pdf(ls.wi) };
            for (k, &(f, _)) in lobes.iter().enumerate() {
                if f != Vec3::ZERO {
                    let w = if F & MIS == 0 || ls.delta {
                        1.0
                    } else {
                        power_heuristic(ls.pdf, g.density(&lobes, k, guide))
                    };
                    let c = beta * f * ls.radiance * (cos * w / ls.pdf);
                    out.add::<F>(c, mask(kind(k)), aovs);
                }
            }
            return;
        }
        bsdf.eval_lobes(at.wo, ls.wi, |lobe, f, pdf| {
            if f != Vec3::ZERO {
                let w = if F & MIS == 0 || ls.delta { 1.0 } else { power_heuristic(ls.pdf, pdf) };
                let c = beta * f * ls.radiance * (cos * w / ls.pdf);
                out.add::<F>(c, mask(lobe), aovs);
            }
        });
    }
}

/// [`Integrator::sample_from_into`]'s path, as a job [`Isa::run`] compiles for
/// the instructions it chose (the whole path loop inlines into it).
struct PathJob<'s, 'i, A: Accel, const F: u8> {
    integrator: &'s Integrator<'i, A, F>,
    ray: Ray,
    hit: Option<Hit>,
    sampler: &'s mut Sampler,
    rays: &'s mut u64,
    aovs: &'s mut [Vec3],
}

impl<A: Accel, const F: u8> Inlined for PathJob<'_, '_, A, F> {
    type Output = PathSample;

    #[inline(always)]
    fn run(self) -> PathSample {
        let PathJob { integrator, ray, hit, sampler, rays, aovs } = self;
        integrator.trace(ray, Some(hit), sampler, rays, &mut (), aovs)
    }
}

/// One path being traced: what it has gathered, where it is, the numbers it draws and the count
/// of rays it traced.
struct Walk<'s> {
    out: PathSample,
    path: PathState,
    sampler: &'s mut Sampler,
    rays: &'s mut u64,
    /// What the path adds to each AOV (empty without AOVs).
    aovs: &'s mut [Vec3],
    /// A training path's guided bounces.
    training: Option<&'s mut GuidePath>,
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

#[cfg(test)]
mod tests {
    use std::f32::consts::PI;

    use super::*;
    use crate::math::chi_square::z_score;
    use crate::math::{uniform_sphere, Frame};
    use crate::render::bsdf::{Diffuse, Glossy, GlossyLobes};

    /// The path loop in every build this CPU runs (AVX2's and AVX-512's, whichever
    /// [`Isa::for_loops`] picks) gives the portable build's path samples bit for bit: every
    /// component and guide value, over scenes of every material kind and area, sky and sun
    /// lights.
    #[test]
    fn the_path_loop_in_any_build_gives_the_same_bits() {
        for name in ["materials", "cornell", "sky-sphere"] {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}.toml"));
            let scene = crate::scene::load(&path).expect("scene loads");
            let accel = crate::accel::build_embree(&scene, None).expect("embree builds");
            let lights = Lights::new(&scene, scene.render.light_sampler);
            let faces = FaceNormals::new(&scene);
            let paths = PathExprs::new(&lights);
            let (w, h) = (24, 24);
            let camera = crate::render::camera::PinholeCamera::new(&scene.camera, w, h);
            let integrator: Integrator<'_, _> =
                Integrator::of_scene(&scene, &accel, &lights, &paths, &faces, 4);
            let portable = Integrator { isa: Isa::Portable, ..integrator };
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            let builds = &Isa::all()[1..];
            for (x, y, k, &isa) in (0..w * h)
                .flat_map(|i| (0..4).map(move |k| (i % w, i / w, k)))
                .flat_map(|(x, y, k)| builds.iter().map(move |isa| (x, y, k, isa)))
            {
                let integrator = Integrator { isa, ..integrator };
                let run = |it: &Integrator<'_, _>| {
                    let mut sampler = Sampler::new(5, (y * w + x) as u64, k);
                    let ray = camera.generate(x, y, &mut sampler);
                    let hit = accel.intersect(&ray);
                    it.sample_from_into(ray, hit, &mut sampler, &mut 0, &mut [])
                };
                let (a, b) = (run(&integrator), run(&portable));
                let all = |s: &PathSample| {
                    let mut v: Vec<[u32; 3]> = s.components.iter().map(|&c| bits(c)).collect();
                    v.extend([bits(s.beauty), bits(s.normal), bits(s.albedo)]);
                    (v, s.object, s.depth.to_bits())
                };
                assert_eq!(
                    all(&a),
                    all(&b),
                    "{name}: pixel ({x}, {y}), sample {k}, {}",
                    integrator.isa.name()
                );
            }
        }
    }

    /// A guide of the unit box trained, four iterations, on light 50 times brighter within a
    /// small cone around `toward` than elsewhere.
    fn trained(toward: Vec3) -> Guide {
        let mut s = Sampler::new(3, 1, 4);
        let mut guide = Guide::new(Vec3::ZERO, Vec3::ONE);
        for _ in 0..4 {
            let records: Vec<RadianceRecord> = (0..20_000)
                .map(|_| {
                    let p = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d());
                    let d = uniform_sphere(s.next_2d());
                    let radiance = if d.dot(toward) > 0.95 { 50.0 } else { 1.0 };
                    RadianceRecord::new(p, d, radiance * 4.0 * PI)
                })
                .collect();
            guide = guide.train(&records);
        }
        guide
    }

    /// The density of the directions [`sample_guided`] gives: both lobe kinds' mixture
    /// densities, where the surface reflects.
    fn density<B: Bsdf>(bsdf: &B, wo: Vec3, n: Vec3, wi: Vec3, g: &Guided) -> f32 {
        if n.dot(wi) <= 0.0 {
            return 0.0;
        }
        let lobes = lobes_by_kind(bsdf, wo, wi);
        let guide = g.pdf(wi);
        g.density(&lobes, 0, guide) + g.density(&lobes, 1, guide)
    }

    /// The mean and standard error of the red weight of `n` samples.
    fn mean_weight(n: usize, mut sample: impl FnMut(&mut Sampler) -> Option<BsdfSample>) -> (f64, f64) {
        let mut s = Sampler::new(11, 2, 3);
        let w: Vec<f64> = (0..n).map(|_| sample(&mut s).map_or(0.0, |b| b.weight.x as f64)).collect();
        let mean = w.iter().sum::<f64>() / n as f64;
        let var = w.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        (mean, (var / n as f64).sqrt())
    }

    /// A chi-square test of the guided directions against the mixture's density (which MIS
    /// weighs with), at a Lambertian and at a glossy vertex; judged by the BSDF's density
    /// alone the samples fail. And the weights keep the energy: their mean is the surface's
    /// albedo (the unguided BSDF's mean weight) within the noise.
    #[test]
    fn guided_directions_follow_the_mixture_density_and_keep_the_energy() {
        let toward = Vec3::new(0.4, 0.3, 0.8).normalize();
        let guide = trained(toward);
        let (n, wo) = (Vec3::Z, Vec3::new(0.3, 0.0, 1.0).normalize());
        let g = Guided { dirs: guide.at(Vec3::splat(0.5)), share: GUIDE_SHARE, n };
        assert!(g.dirs.pdf(toward) > 10.0 / (4.0 * PI), "the guide learned the bright cone");
        let diffuse = Diffuse { albedo: Vec3::splat(0.8), n };
        let glossy = Glossy {
            lobes: GlossyLobes { specular: Vec3::splat(0.3), alpha: 0.3, base: Vec3::splat(0.5) },
            frame: Frame::new(n),
        };
        let z = z_score(
            |s| sample_guided(&diffuse, wo, n, &g, s).map(|b| b.wi),
            |d| density(&diffuse, wo, n, d, &g),
        );
        assert!(z < 4.0, "diffuse: z = {z}");
        let z = z_score(|s| sample_guided(&diffuse, wo, n, &g, s).map(|b| b.wi), |d| diffuse.pdf(wo, d));
        assert!(z > 10.0, "diffuse against the BSDF alone: z = {z}");
        let z = z_score(
            |s| sample_guided(&glossy, wo, n, &g, s).map(|b| b.wi),
            |d| density(&glossy, wo, n, d, &g),
        );
        assert!(z < 4.0, "glossy: z = {z}");

        let (mean, se) = mean_weight(200_000, |s| sample_guided(&diffuse, wo, n, &g, s));
        assert!((mean - 0.8).abs() < 4.0 * se, "diffuse: mean weight {mean} (standard error {se})");
        let (guided, se_g) = mean_weight(200_000, |s| sample_guided(&glossy, wo, n, &g, s));
        let (plain, se_p) = mean_weight(200_000, |s| glossy.sample(wo, s));
        let se = (se_g * se_g + se_p * se_p).sqrt();
        assert!(
            (guided - plain).abs() < 4.0 * se,
            "glossy: {guided} guided, {plain} not (standard error {se})"
        );
    }
}
