//! Ray sets for comparing backends on identical work: primary (camera) rays, shadow rays from the
//! primary hits toward the lights, and incoherent diffuse bounces from the same hits. They are
//! generated once, from the scene and a seed, and fed unchanged to every backend.

use glam::{Vec2, Vec3};

use crate::accel::{Accel, Ray};
use crate::math::{cosine_hemisphere, Frame};
use crate::render::camera::PinholeCamera;
use crate::render::lights::{Lights, ShadowEnd};
use crate::render::sampler::Sampler;
use crate::render::surface::surface;
use crate::scene::Scene;

/// The kinds of ray set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RayKind {
    Primary,
    Shadow,
    Incoherent,
}

impl RayKind {
    pub const ALL: [RayKind; 3] = [RayKind::Primary, RayKind::Shadow, RayKind::Incoherent];

    pub fn name(self) -> &'static str {
        match self {
            RayKind::Primary => "primary",
            RayKind::Shadow => "shadow",
            RayKind::Incoherent => "incoherent",
        }
    }
}

/// Three ray sets of (up to) the same size.
pub struct RaySets {
    pub primary: Vec<Ray>,
    pub shadow: Vec<Ray>,
    pub incoherent: Vec<Ray>,
}

impl RaySets {
    pub fn get(&self, kind: RayKind) -> &[Ray] {
        match kind {
            RayKind::Primary => &self.primary,
            RayKind::Shadow => &self.shadow,
            RayKind::Incoherent => &self.incoherent,
        }
    }

    /// `n` primary rays through random film positions of the scene's camera; shadow and
    /// incoherent rays start at the surfaces those rays hit (found with `accel`), so scenes with
    /// much background get fewer of them.
    pub fn generate<A: Accel>(scene: &Scene, accel: &A, n: usize, seed: u64) -> RaySets {
        let (w, h) = (scene.film.width, scene.film.height);
        let camera = PinholeCamera::new(&scene.camera, w, h);
        let lights = Lights::new(scene, crate::scene::LightSamplerKind::Power);
        let (lo, hi) = scene.bounds();
        let mut sets = RaySets { primary: Vec::with_capacity(n), shadow: Vec::new(), incoherent: Vec::new() };
        for i in 0..n {
            let mut s = Sampler::new(seed, i as u64, 0x5eed);
            let film = Vec2::new(s.next_1d() * w as f32, s.next_1d() * h as f32);
            let ray = camera.ray(film.x as u32, film.y as u32, film.fract());
            sets.primary.push(ray);
            let Some(hit) = accel.intersect(&ray) else {
                continue;
            };
            let surf = surface(scene, &ray, &hit);
            let ng = if surf.ng.dot(ray.dir) <= 0.0 { surf.ng } else { -surf.ng };
            let origin = surf.origin(ng);
            // Shadow: toward a light sample, or a random point of the scene without lights.
            let end = match lights.sample(scene, surf.p, s.next_1d(), s.next_2d()) {
                Some(ls) => match ls.end {
                    ShadowEnd::Point(q) => q,
                    ShadowEnd::Infinite => origin + ls.wi * (hi - lo).length().max(1.0) * 2.0,
                },
                None => lo + (hi - lo) * Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()),
            };
            // As the integrator does, only toward lights on the side the surface faces: a ray
            // into the surface it starts on is no shadow ray.
            if (end - origin).dot(ng) > 0.0 {
                sets.shadow.push(Ray { origin, dir: end - origin, t_max: 1.0 });
            }
            let dir = Frame::new(ng).to_world(cosine_hemisphere(s.next_2d()));
            sets.incoherent.push(Ray::new(origin, dir));
        }
        sets
    }
}
