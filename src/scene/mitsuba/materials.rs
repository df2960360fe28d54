//! The materials of Mitsuba's BSDF plugins that lightsplit's own materials cannot stand for:
//! conductors, dielectrics with their own tints and thin sheets, and plastics. Their BSDFs are
//! in `render/bsdf/` (`conductor.rs`, `dielectric.rs`, `plastic.rs`).

use std::sync::Arc;

use glam::Vec3;

use crate::math::Frame;
use crate::render::bsdf::microfacet::{fresnel_diffuse_reflectance, Microfacet};
use crate::render::bsdf::plastic::{CoatingTable, Plastic};
use crate::render::bsdf::Conductor;

/// Mitsuba's `conductor` (no `facets`) and `roughconductor`.
#[derive(Clone, Debug, PartialEq)]
pub struct ConductorMaterial {
    pub eta: Vec3,
    pub k: Vec3,
    pub specular: Vec3,
    pub facets: Option<Microfacet>,
}

impl ConductorMaterial {
    /// The BSDF about `frame` (along the surface's first tangent when anisotropic); its rough
    /// lobe counted diffuse in the split when `rough`.
    pub fn bsdf(&self, frame: Frame, rough: bool) -> Conductor {
        Conductor { frame, eta: self.eta, k: self.k, specular: self.specular, facets: self.facets, rough }
    }
}

/// Mitsuba's `dielectric`, `thindielectric` and `roughdielectric` (with `facets`): `eta` the
/// interior's index over the exterior's.
#[derive(Clone, Debug, PartialEq)]
pub struct DielectricMaterial {
    pub eta: f32,
    pub reflectance: Vec3,
    pub transmittance: Vec3,
    pub thin: bool,
    pub facets: Option<Microfacet>,
}

/// Mitsuba's `plastic` (no `facets`) and `roughplastic`.
#[derive(Clone, Debug, PartialEq)]
pub struct PlasticMaterial {
    pub eta: f32,
    pub diffuse: Vec3,
    pub specular: Vec3,
    /// The base's reflectance is divided by 1 - this (times the reflectance itself when
    /// `nonlinear`): the coating's internal diffuse reflectance.
    pub internal: f32,
    pub nonlinear: bool,
    /// The share of samples Mitsuba gives the coating, before Fresnel: the specular tint's
    /// mean over it and the diffuse reflectance's (the texture's mean where it has one).
    pub specular_weight: f32,
    pub facets: Option<(Microfacet, Arc<CoatingTable>)>,
}

impl PlasticMaterial {
    /// A plastic of relative index `eta`, diffuse reflectance `diffuse` (its mean `diffuse_mean`:
    /// a texture's, where it has one) and coating tint `specular`, smooth without `facets`, as
    /// Mitsuba makes one: the coating's internal reflectance (the rough one's tabulated with its
    /// transmittance), and the share of samples the coating gets.
    pub fn new(
        eta: f32,
        diffuse: Vec3,
        diffuse_mean: f32,
        specular: Vec3,
        nonlinear: bool,
        facets: Option<Microfacet>,
    ) -> Self {
        let s_mean = specular.element_sum() / 3.0;
        let specular_weight =
            if diffuse_mean + s_mean > 0.0 { s_mean / (diffuse_mean + s_mean) } else { 1.0 };
        let (facets, internal) = match facets {
            Some(f) => {
                let table = CoatingTable::new(&f, eta);
                let internal = table.internal_reflectance;
                (Some((f, Arc::new(table))), internal)
            }
            None => (None, fresnel_diffuse_reflectance(1.0 / eta)),
        };
        PlasticMaterial { eta, diffuse, specular, internal, nonlinear, specular_weight, facets }
    }

    /// The BSDF about `frame` for the base colour `diffuse` (the material's, or its texture's
    /// value here); the rough coating counted diffuse in the split when `rough`.
    pub fn bsdf(&self, diffuse: Vec3, frame: Frame, rough: bool) -> Plastic<'_> {
        let internal = if self.nonlinear { diffuse * self.internal } else { Vec3::splat(self.internal) };
        Plastic {
            frame,
            eta: self.eta,
            diffuse: diffuse / (Vec3::ONE - internal).max(Vec3::splat(1e-6)),
            specular: self.specular,
            specular_weight: self.specular_weight,
            facets: self.facets.as_ref().map(|(f, table)| (*f, table.as_ref())),
            rough,
        }
    }
}

/// Mitsuba's `blendbsdf`: its two BSDFs and the weight of the second.
#[derive(Clone, Debug, PartialEq)]
pub struct BlendMaterial {
    pub a: crate::scene::Material,
    pub b: crate::scene::Material,
    pub weight: f32,
}
