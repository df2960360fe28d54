//! Mitsuba's `conductor` and `roughconductor`: a metal of complex index of refraction, smooth
//! (one delta lobe) or rough (a microfacet lobe, [`Microfacet`]), as Mitsuba 3 evaluates them.

use glam::Vec3;

use super::microfacet::{fresnel_conductor, Microfacet};
use super::{reflect, Bsdf, BsdfSample, Lobe};
use crate::math::Frame;
use crate::render::sampler::{Dim, Sampler};

/// A conductor of index `eta + i k` (per RGB channel) times `specular`, about `frame`: a mirror
/// without `facets`, a microfacet lobe with. The rough lobe is an S vertex, or a D vertex
/// when `rough` (as wide as a glossy lobe the split counts diffuse).
#[derive(Clone, Copy, Debug)]
pub struct Conductor {
    pub frame: Frame,
    pub eta: Vec3,
    pub k: Vec3,
    pub specular: Vec3,
    pub facets: Option<Microfacet>,
    pub rough: bool,
}

impl Conductor {
    fn tag(&self) -> Lobe {
        match (self.facets, self.rough) {
            (None, _) => Lobe::Delta,
            (Some(_), true) => Lobe::Diffuse,
            (Some(_), false) => Lobe::Specular,
        }
    }

    /// The rough lobe's value and density for local directions.
    fn lobe(facets: &Microfacet, c: &Conductor, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let h = (wo + wi).normalize();
        let d = facets.d(h);
        let f = fresnel_conductor(wo.dot(h), c.eta, c.k) * c.specular * (d * facets.g(wi, wo, h))
            / (4.0 * wo.z * wi.z);
        (f, facets.pdf(wo, h) / (4.0 * wo.dot(h)))
    }
}

impl Bsdf for Conductor {
    fn lobe(&self) -> Option<Lobe> {
        Some(self.tag())
    }

    fn scatters(&self, wo: Vec3) -> bool {
        self.frame.to_local(wo).z > 0.0
    }

    fn albedo(&self, _: Lobe) -> Vec3 {
        fresnel_conductor(1.0, self.eta, self.k) * self.specular
    }

    fn sample(&self, wo: Vec3, u: &mut Sampler) -> Option<BsdfSample> {
        let wo_l = self.frame.to_local(wo);
        let Some(facets) = &self.facets else {
            let weight = fresnel_conductor(wo_l.z, self.eta, self.k) * self.specular;
            return Some(BsdfSample { wi: reflect(wo, self.frame.n), weight, pdf: 1.0, lobe: Lobe::Delta });
        };
        let m = facets.sample(wo_l, u.get_2d(Dim::Direction))?;
        let wi_l = reflect(wo_l, m);
        if wi_l.z <= 0.0 {
            return None;
        }
        let (f, pdf) = Self::lobe(facets, self, wo_l, wi_l);
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample { wi: self.frame.to_world(wi_l), weight: f * (wi_l.z / pdf), pdf, lobe: self.tag() })
    }

    fn eval_lobes(&self, wo: Vec3, wi: Vec3, mut each: impl FnMut(Lobe, Vec3, f32)) {
        if let Some(facets) = &self.facets {
            let (f, pdf) = Self::lobe(facets, self, self.frame.to_local(wo), self.frame.to_local(wi));
            each(self.tag(), f, pdf);
        }
    }
}
