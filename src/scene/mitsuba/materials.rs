//! The materials of Mitsuba's BSDF plugins that lightsplit's own materials cannot stand for:
//! conductors, dielectrics with their own tints and thin sheets, and plastics. Their BSDFs are
//! in `render/bsdf/` (`conductor.rs`, `dielectric.rs`, `plastic.rs`).

use std::sync::Arc;

use glam::Vec3;

use crate::render::bsdf::microfacet::Microfacet;
use crate::render::bsdf::plastic::CoatingTable;

/// Mitsuba's `conductor` (no `facets`) and `roughconductor`.
#[derive(Clone, Debug, PartialEq)]
pub struct ConductorMaterial {
    pub eta: Vec3,
    pub k: Vec3,
    pub specular: Vec3,
    pub facets: Option<Microfacet>,
}

/// Mitsuba's `dielectric` and `thindielectric`: `eta` the interior's index over the
/// exterior's.
#[derive(Clone, Debug, PartialEq)]
pub struct DielectricMaterial {
    pub eta: f32,
    pub reflectance: Vec3,
    pub transmittance: Vec3,
    pub thin: bool,
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
