//! Light sampling for next-event estimation: the registry of a scene's lights ([`Lights`]), how
//! one is picked (all of them when there are few; else by a light tree, by power or uniformly),
//! and the matching densities for multiple importance sampling. The lights themselves are in
//! [`emitter`], the tree in [`tree`], the cloudy sky's table in [`sky_table`].

pub mod emitter;
pub mod sky_table;
pub mod tree;

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

pub use emitter::{Emitter, LightSample, ShadowEnd};
use sky_table::sky_table;
use tree::{LightBounds, LightTree};

use crate::math::{luminance, Distribution1D, Distribution2D, Frame, FOUR_PI};
use crate::scene::{Geometry, Light, LightSamplerKind, Scene};

/// No light on this shape; no item of an emitter; a whole emitter rather than one triangle.
const NONE: u32 = u32::MAX;
/// Scenes with at most this many lights sample all of them at every vertex.
const SAMPLE_ALL: usize = 8;
/// Above this many emissive triangles in all, a mesh is one leaf of the light tree (sampled by
/// area within) rather than one leaf a triangle: the tree's memory stays bounded.
const MAX_TREE_TRIANGLES: usize = 1 << 20;

/// Every light of a scene and how to pick one.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    pub emitters: Vec<Emitter>,
    /// Whether light `i` is a diffuse source (its light counts as already diffusely reflected).
    pub diffuse_source: Vec<bool>,
    /// The light group of light `i` ([`crate::scene::LightGroups`]): its index + 1, 0 for none
    /// (a label of the light path expressions).
    pub group: Vec<u16>,
    selection: Selection,
    /// The lights by power (or uniform, for that light sampler): next-event estimation's
    /// table when it picks one light from it, and [`Lights::sample`]'s always.
    table: Option<Distribution1D>,
    /// For each shape, the index of its emitter, or NONE.
    shape_light: Vec<u32>,
    /// The emitters at infinity (sun, sky, environment), which a ray that escapes the scene sees.
    pub distant: Vec<u32>,
}

/// How next-event estimation picks among the lights.
#[derive(Clone, Debug, Default)]
enum Selection {
    /// Every light at every vertex (few lights).
    #[default]
    All,
    /// One light from the table over all of them (by power, or uniform).
    Table,
    /// The bounded lights by a light tree, those at infinity each beside it.
    Tree(Box<TreeLights>),
}

/// The light tree's leaves: an emitter, or one triangle of a mesh emitter.
#[derive(Clone, Debug)]
struct TreeLights {
    tree: LightTree,
    items: Vec<Item>,
    /// For each emitter, its first item (a mesh's triangles follow it), or NONE at infinity.
    first: Vec<u32>,
}

/// One leaf of the light tree.
#[derive(Clone, Copy, Debug)]
struct Item {
    emitter: u32,
    /// The mesh's triangle, or NONE for the whole emitter.
    triangle: u32,
    /// The triangle's area.
    area: f32,
}

/// What next-event estimation does at a vertex ([`Lights::strategy`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Strategy {
    /// Sample every light.
    All,
    /// Sample one light, picked from the table.
    One,
    /// Sample each light at infinity, and one picked by the tree ([`Lights::sample_tree`]).
    Tree,
}

impl Lights {
    /// The lights of `scene`, picked as `kind` says when there are more than a few.
    pub fn new(scene: &Scene, kind: LightSamplerKind) -> Self {
        let (lo, hi) = scene.bounds();
        let radius = 0.5 * (hi - lo).length().max(1e-3);
        let disc = PI * radius * radius;
        let mut lights = Lights { shape_light: vec![NONE; scene.shapes.len()], ..Default::default() };
        let mut power = Vec::new();
        let cutouts = crate::scene::cutout::Cutouts::new(scene).map(std::sync::Arc::new);

        // Each light's and shape's group, looked up once (a linear search each was quadratic).
        let groups = &scene.light_groups;
        let of_light: std::collections::HashMap<u32, u32> = groups.lights.iter().copied().collect();
        let of_shape: std::collections::HashMap<u32, u32> = groups.shapes.iter().copied().collect();
        let label = |g: Option<&u32>| g.map_or(0, |&g| u16::try_from(g + 1).unwrap_or(0));
        for (l, light) in scene.lights.iter().enumerate() {
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
                Light::Environment { ref map, diffuse_source } => {
                    let table = Distribution2D::new(
                        &map.weights(map.uniform),
                        map.image.width as usize,
                        map.image.height as usize,
                    );
                    let Some(table) = table else {
                        continue; // a black map
                    };
                    let emitter = Emitter::Environment { map: map.clone(), table: Box::new(table) };
                    (emitter, FOUR_PI * disc * map.mean_luminance(), diffuse_source)
                }
                Light::Sky { radiance, diffuse_source } => {
                    (Emitter::Sky { radiance }, FOUR_PI * disc * luminance(radiance), diffuse_source)
                }
            };
            if !emitter.is_dark() {
                if emitter.is_distant() {
                    lights.distant.push(lights.emitters.len() as u32);
                }
                lights.emitters.push(emitter);
                lights.diffuse_source.push(diffuse_source);
                lights.group.push(label(of_light.get(&(l as u32))));
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
                    let cutouts = cutouts.clone().filter(|c| c.cuts(i as u32));
                    let emitter =
                        Emitter::Mesh { shape: i as u32, triangles, area, emission: shape.emission, cutouts };
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
            lights.group.push(label(of_shape.get(&(i as u32))));
            power.push(PI * area * luminance(scene.mean_emission(shape)));
        }
        lights.table = match kind {
            LightSamplerKind::Uniform => Distribution1D::new(&vec![1.0; power.len()]),
            _ => Distribution1D::new(&power),
        };
        lights.selection = match kind {
            _ if lights.sample_all() => Selection::All,
            LightSamplerKind::Power | LightSamplerKind::Uniform => Selection::Table,
            LightSamplerKind::Tree => Selection::Tree(Box::new(TreeLights::new(scene, &lights.emitters))),
        };
        lights
    }

    /// The emitter index of a shape, if it is a light.
    pub fn of_shape(&self, shape: u32) -> Option<u32> {
        match self.shape_light.get(shape as usize) {
            Some(&i) if i != NONE => Some(i),
            _ => None,
        }
    }

    /// What next-event estimation does at each vertex.
    pub fn strategy(&self) -> Strategy {
        match self.selection {
            Selection::All => Strategy::All,
            Selection::Table => Strategy::One,
            Selection::Tree(_) => Strategy::Tree,
        }
    }

    /// The probability of picking light `i` where it does not depend on the shading point:
    /// every light when all are sampled, a table's, a light at infinity beside the tree.
    pub fn select_pdf(&self, i: u32) -> f32 {
        match &self.selection {
            Selection::All | Selection::Tree(_) => 1.0,
            Selection::Table => self.table.as_ref().map_or(0.0, |d| d.pdf(i as usize)),
        }
    }

    /// With few lights, next-event estimation samples every light at each vertex instead of
    /// picking one: no selection noise (a scene lit by a sun and a sky would otherwise see the
    /// sun only when it is picked), at one shadow ray per light.
    pub fn sample_all(&self) -> bool {
        self.emitters.len() <= SAMPLE_ALL
    }

    /// Samples light `i` as seen from `p` (its selection probability is [`Lights::select_pdf`]).
    pub fn sample_one(&self, scene: &Scene, i: usize, p: Vec3, u: Vec2) -> Option<LightSample> {
        self.emitters[i].sample(scene, i as u32, self.select_pdf(i as u32), p, u)
    }

    /// Samples a light picked from the table, as seen from `p`, with uniform numbers `u_select`
    /// and `u` (its density is the table's whatever the selection: next-event estimation calls
    /// it only when it picks from the table).
    pub fn sample(&self, scene: &Scene, p: Vec3, u_select: f32, u: Vec2) -> Option<LightSample> {
        let (i, select) = match self.emitters.len() {
            0 => return None,
            1 => (0, 1.0),
            _ => self.table.as_ref()?.sample(u_select),
        };
        self.emitters[i].sample(scene, i as u32, select, p, u)
    }

    /// Samples a bounded light picked by the tree for a surface at `p` of normal `n`, with
    /// uniform numbers `u_select` and `u`.
    pub fn sample_tree(
        &self,
        scene: &Scene,
        p: Vec3,
        n: Vec3,
        u_select: f32,
        u: Vec2,
    ) -> Option<LightSample> {
        let Selection::Tree(t) = &self.selection else { return None };
        let (item, pmf, _) = t.tree.sample(p, n, u_select)?;
        let item = t.items[item as usize];
        let emitter = &self.emitters[item.emitter as usize];
        if item.triangle == NONE {
            emitter.sample(scene, item.emitter, pmf, p, u)
        } else {
            emitter.sample_triangle(scene, item.emitter, item.triangle, pmf / item.area, p, u)
        }
    }

    /// The NEE density (selection included) of reaching emissive shape `light` at point `q`
    /// (geometric normal `n`, on triangle `prim` of a mesh) from `p`, a surface of normal
    /// `np`: what a BSDF-sampled hit needs for its MIS weight.
    pub fn pdf_shape(&self, light: u32, prim: u32, p: Vec3, np: Vec3, q: Vec3, n: Vec3) -> f32 {
        let emitter = &self.emitters[light as usize];
        let Selection::Tree(t) = &self.selection else {
            return emitter.pdf_shape(self.select_pdf(light), p, q, n);
        };
        let first = t.first[light as usize];
        let whole = t.items.get(first as usize).is_none_or(|i| i.triangle == NONE);
        let item = if whole { first } else { first + prim };
        let pmf = t.tree.pmf(item, p, np);
        match t.items.get(item as usize) {
            Some(i) if !whole => emitter::area_pdf(pmf / i.area, p, q, n),
            _ => emitter.pdf_shape(pmf, p, q, n),
        }
    }

    /// The radiance of distant light `light` along direction `dir` and its NEE density
    /// (selection included); `seen` as in [`Emitter::distant`].
    pub fn distant(&self, light: u32, dir: Vec3, seen: bool) -> (Vec3, f32) {
        self.emitters[light as usize].distant(self.select_pdf(light), dir, seen)
    }

    /// How next-event estimation picks lights, in words (for `info`).
    pub fn describe(&self) -> String {
        match &self.selection {
            Selection::All => {
                format!("every light at each vertex ({} at most {SAMPLE_ALL})", self.emitters.len())
            }
            Selection::Table => format!("one of {} lights from a table", self.emitters.len()),
            Selection::Tree(t) => format!(
                "one of {} bounded lights by a light tree ({} nodes, depth {} at most, {:.1} on average){}",
                t.items.len(),
                t.tree.nodes(),
                t.tree.depth().0,
                t.tree.depth().1,
                match self.distant.len() {
                    0 => String::new(),
                    n => format!(", and each of {n} at infinity"),
                }
            ),
        }
    }
}

impl TreeLights {
    /// The leaves of the bounded `emitters` of `scene`, and their tree.
    fn new(scene: &Scene, emitters: &[Emitter]) -> TreeLights {
        let triangles: usize = emitters
            .iter()
            .map(|e| match e {
                Emitter::Mesh { triangles, .. } => triangles.len(),
                _ => 0,
            })
            .sum();
        let per_triangle = triangles <= MAX_TREE_TRIANGLES;
        let (mut items, mut bounds, mut first) = (Vec::new(), Vec::new(), Vec::new());
        for (i, e) in emitters.iter().enumerate() {
            let i = i as u32;
            let whole = |bounds: &mut Vec<LightBounds>, items: &mut Vec<Item>, b: LightBounds| {
                bounds.push(b);
                items.push(Item { emitter: i, triangle: NONE, area: 0.0 });
            };
            first.push(if e.is_distant() { NONE } else { items.len() as u32 });
            match e {
                Emitter::Point { position, intensity } => whole(
                    &mut bounds,
                    &mut items,
                    LightBounds::omni(*position, *position, luminance(*intensity)),
                ),
                Emitter::Spot { position, direction, intensity, cos_total, cos_falloff_start } => {
                    let spread =
                        cos_total.clamp(-1.0, 1.0).acos() - cos_falloff_start.clamp(-1.0, 1.0).acos();
                    let b = LightBounds {
                        lo: *position,
                        hi: *position,
                        phi: luminance(*intensity),
                        w: *direction,
                        cos_o: *cos_falloff_start,
                        cos_e: spread.max(0.0).cos(),
                    };
                    whole(&mut bounds, &mut items, b)
                }
                Emitter::Sphere { shape, center, radius, .. } => {
                    let le = luminance(scene.mean_emission(&scene.shapes[*shape as usize]));
                    let r = Vec3::splat(*radius);
                    whole(
                        &mut bounds,
                        &mut items,
                        LightBounds::omni(center - r, center + r, le * PI * radius * radius),
                    )
                }
                Emitter::Mesh { shape, .. } => {
                    let shape = &scene.shapes[*shape as usize];
                    let Geometry::Triangles(mesh) = &shape.geometry else { continue };
                    let le = luminance(scene.mean_emission(shape));
                    let tri = |t: u32| {
                        let [a, b, c] = mesh.triangle(t);
                        let cross = (b - a).cross(c - a);
                        let area = 0.5 * cross.length();
                        let b = LightBounds {
                            lo: a.min(b).min(c),
                            hi: a.max(b).max(c),
                            phi: le * area,
                            w: cross.normalize_or_zero(),
                            cos_o: 1.0,
                            cos_e: 0.0,
                        };
                        (b, area)
                    };
                    let count = mesh.indices.len() as u32;
                    if per_triangle {
                        for t in 0..count {
                            let (b, area) = tri(t);
                            bounds.push(b);
                            items.push(Item { emitter: i, triangle: t, area });
                        }
                    } else {
                        let all = (1..count).fold(tri(0).0, |acc, t| acc.union(&tri(t).0));
                        whole(&mut bounds, &mut items, all)
                    }
                }
                Emitter::Sun { .. }
                | Emitter::Sky { .. }
                | Emitter::CloudySky { .. }
                | Emitter::Environment { .. } => {}
            }
        }
        TreeLights { tree: LightTree::new(&bounds), items, first }
    }
}

#[cfg(test)]
mod tests {
    use super::emitter::{cone_one_minus_cos, sample_sphere_cone};
    use super::*;
    use crate::math::uniform_sphere;
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
            let lights = Lights::new(&scene, LightSamplerKind::Power);
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
                        hit_triangle(tri, d).map(|h| lights.pdf_shape(0, t, Vec3::ZERO, Vec3::ZERO, d * h, n))
                    })
                    .unwrap_or(0.0)
            };
            let z = z_score(|s| lights.sample_one(&scene, 0, Vec3::ZERO, s.next_2d()).map(|l| l.wi), pdf);
            assert!(z < 4.0, "z = {z}");
        }

        /// Twelve small emissive quads of varied emission around the origin, some turned away
        /// (more than eight lights: the tree picks one): the tree's samples from a surface at
        /// the origin follow the density MIS gives a BSDF-sampled hit on any of them, its
        /// selection included; with the selection evaluated without the surface's normal, they
        /// fail.
        #[test]
        fn tree_sampling_matches_its_mis_density() {
            let mut text = String::from(CAMERA);
            let mut s = Sampler::new(6, 6, 6);
            for i in 0..12 {
                let u = crate::math::uniform_sphere(s.next_2d());
                let c = u * 3.0;
                // Facing the origin, or turned 70 degrees from it.
                let facing =
                    if i % 4 == 3 { (-u + 2.7 * Frame::new(u).to_world(Vec3::X)).normalize() } else { -u };
                let t = Frame::new(facing).to_world(Vec3::X) * 0.25;
                let b = facing.cross(t);
                let v = [c - t - b, c + t - b, c + t + b, c - t + b];
                let e = 1.0 + 9.0 * s.next_1d();
                let f = |p: Vec3| format!("[{}, {}, {}]", p.x, p.y, p.z);
                text.push_str(&format!(
                    "[[shape]]\ntype = \"quad\"\nemission = [{e}, {e}, {e}]\nvertices = [{}, {}, {}, {}]\n",
                    f(v[0]),
                    f(v[1]),
                    f(v[2]),
                    f(v[3])
                ));
            }
            let scene = parse(std::path::Path::new("t.toml"), &text).expect("parses");
            let lights = Lights::new(&scene, LightSamplerKind::Tree);
            assert_eq!(lights.strategy(), Strategy::Tree);
            let o = -scene.origin.as_vec3();
            let n = Vec3::new(0.3, 1.0, -0.2).normalize();
            // The first emissive triangle along d, traced, and the density MIS gives it.
            let pdf = |d: Vec3, np: Vec3| {
                let mut best: Option<(f32, f32)> = None;
                for (i, shape) in scene.shapes.iter().enumerate() {
                    let Geometry::Triangles(mesh) = &shape.geometry else { continue };
                    for t in 0..mesh.indices.len() as u32 {
                        let tri = mesh.triangle(t).map(|p| p - o);
                        let Some(h) = hit_triangle(tri, d) else { continue };
                        if best.is_some_and(|(near, _)| near <= h) {
                            continue;
                        }
                        let ng = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
                        let light = lights.of_shape(i as u32).expect("a light");
                        let p = if ng.dot(d) < 0.0 {
                            lights.pdf_shape(light, t, o, np, o + d * h, ng)
                        } else {
                            0.0
                        };
                        best = Some((h, p));
                    }
                }
                best.map_or(0.0, |(_, p)| p)
            };
            let sample =
                |s: &mut Sampler| lights.sample_tree(&scene, o, n, s.next_1d(), s.next_2d()).map(|l| l.wi);
            let z = z_score(sample, |d| pdf(d, n));
            assert!(z < 4.0, "z = {z}");
            let z = z_score(sample, |d| pdf(d, Vec3::ZERO));
            assert!(z > 10.0, "without the normal: z = {z}");
        }

        #[test]
        fn sphere_light_sampling_matches_its_mis_density() {
            let text = format!(
                "{CAMERA}[[shape]]\ntype = \"sphere\"\nemission = [1, 1, 1]\ncenter = [0.5, 0.3, 2]\nradius = 1\n"
            );
            let (scene, lights) = lights_of(&text);
            // The centre seen from the shading point `o`, the world's origin (the scene stores
            // points relative to its camera).
            let c = Vec3::new(0.5, 0.3, 2.0);
            let o = -scene.origin.as_vec3();
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
                    lights.pdf_shape(0, 0, o, Vec3::ZERO, o + q, (q - c) / r)
                } else {
                    1.0 / (2.0 * PI * cone_one_minus_cos(r * r / dc2))
                }
            };
            let sample = |s: &mut Sampler| lights.sample_one(&scene, 0, o, s.next_2d()).map(|l| l.wi);
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
        let lights = Lights::new(&scene, LightSamplerKind::Power);
        // The intensity a receiver at angle `deg` from the axis, 2 units from the light, gets.
        let at = |deg: f32| {
            let t = deg.to_radians();
            // The receiver as the scene stores points: relative to the camera.
            let p =
                Vec3::new(0.0, 4.0, 0.0) - scene.origin.as_vec3() + 2.0 * Vec3::new(t.sin(), -t.cos(), 0.0);
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
        let lights = Lights::new(&scene, LightSamplerKind::Power);
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

    /// An environment map with a gradient, a bright small sun and a black band, turned: its
    /// sampling follows the density MIS uses for a BSDF-sampled direction, and it follows the
    /// light (NEE samples carry far more of it than uniform directions do). The sun is 100 times
    /// the sky, not the 1e4 of a real one: the test's quadrature of the density over its bins is
    /// not fine enough for a brighter one (at ten times this, z reached 4.4 in release builds and
    /// 2.4 in debug ones: with most samples in a few bins, small errors of the quadrature at the
    /// sun's edges decide the statistic).
    #[test]
    fn environment_sampling_matches_its_density() {
        use crate::film::Image;
        use crate::math::chi_square::z_score;
        use crate::scene::environment::EnvironmentMap;
        use std::sync::Arc;
        let (w, h) = (64u32, 32u32);
        let pixels = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if (20..23).contains(&x) && (5..7).contains(&y) {
                    Vec3::new(50.0, 45.0, 40.0)
                } else if y == 20 {
                    Vec3::ZERO
                } else {
                    Vec3::new(0.2, 0.3, 0.5) * (1.0 + x as f32 / w as f32)
                }
            })
            .collect();
        let map = EnvironmentMap::new(Image { width: w, height: h, pixels }, 1.0, 37.0).expect("a map");
        let text = "[camera]\nposition = [0, 0, -5]\nlook_at = [0, 0, 0]\n";
        let mut scene = crate::scene::file::parse(std::path::Path::new("t.toml"), text).expect("parses");
        scene.lights.push(Light::Environment { map: Arc::new(map), diffuse_source: false });
        let lights = Lights::new(&scene, LightSamplerKind::Power);
        let z = z_score(
            |s| lights.sample_one(&scene, 0, Vec3::ZERO, s.next_2d()).map(|l| l.wi),
            |d| lights.distant(0, d, false).1,
        );
        assert!(z < 4.0, "z = {z}");
        // The density a sample reports is the one MIS looks up, and its radiance the pixel's.
        let mut s = Sampler::new(4, 4, 4);
        for _ in 0..1000 {
            let l = lights.sample_one(&scene, 0, Vec3::ZERO, s.next_2d()).expect("a sample");
            let (le, pdf) = lights.distant(0, l.wi, false);
            assert!((pdf / l.pdf - 1.0).abs() < 1e-3, "{pdf} vs {}", l.pdf);
            assert!((le - l.radiance).length() <= 1e-4 * le.length().max(1.0), "{le} vs {}", l.radiance);
        }
        let (mut sampled, mut uniform) = (0.0, 0.0);
        for _ in 0..20_000 {
            sampled += lights.sample_one(&scene, 0, Vec3::ZERO, s.next_2d()).map_or(0.0, |l| l.radiance.x);
            uniform += lights.distant(0, uniform_sphere(s.next_2d()), false).0.x;
        }
        assert!(sampled > 2.0 * uniform, "{sampled} vs {uniform}");
    }
}
