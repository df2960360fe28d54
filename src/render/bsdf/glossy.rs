//! The glossy material: a GGX microfacet lobe (Walter et al. 2007, "Microfacet Models for
//! Refraction through Rough Surfaces") with Schlick's Fresnel, over an optional diffuse base:
//! Ashikhmin and Shirley's coupled diffuse term (2000, "An Anisotropic Phong BRDF Model"), which
//! is reciprocal and gives the base only the light the coating lets through. The lobes
//! themselves are [`GlossyLobes`], in `ggx.rs`.

use glam::Vec3;

use super::{Bsdf, BsdfSample, GlossyLobes, Lobe};
use crate::math::Frame;
use crate::render::sampler::{Dim, Sampler};

/// The glossy material: [`GlossyLobes`] in the shading frame `frame`. Its GGX lobe is an S
/// vertex, its base a D vertex; which one a path went through is known only once sampled.
#[derive(Clone, Copy, Debug)]
pub struct Glossy {
    pub lobes: GlossyLobes,
    pub frame: Frame,
}

impl Bsdf for Glossy {
    fn lobe(&self) -> Option<Lobe> {
        None
    }

    fn scatters(&self, wo: Vec3) -> bool {
        self.frame.to_local(wo).z > 0.0
    }

    fn albedo(&self, lobe: Lobe) -> Vec3 {
        if lobe == Lobe::Diffuse {
            self.lobes.base
        } else {
            self.lobes.specular
        }
    }

    fn sample(&self, wo: Vec3, u: &mut Sampler) -> Option<BsdfSample> {
        let g = &self.lobes;
        let wo_l = self.frame.to_local(wo);
        let p_spec = g.specular_probability(wo_l);
        let (wi_l, lobe) = g.sample(wo_l, u.get_1d(Dim::Lobe), u.get_2d(Dim::Direction));
        if wi_l.z <= 0.0 {
            return None;
        }
        let (weight, pdf) = match lobe {
            Lobe::Diffuse => {
                let pdf = (1.0 - p_spec) * g.pdf_base(wi_l);
                (g.eval_base(wo_l, wi_l) * (wi_l.z / pdf), pdf)
            }
            _ => (g.specular_weight(wo_l, wi_l) / p_spec, p_spec * g.pdf_specular(wo_l, wi_l)),
        };
        Some(BsdfSample { wi: self.frame.to_world(wi_l), weight, pdf, lobe })
    }

    fn eval_lobes(&self, wo: Vec3, wi: Vec3, mut each: impl FnMut(Lobe, Vec3, f32)) {
        let g = &self.lobes;
        let (wo_l, wi_l) = (self.frame.to_local(wo), self.frame.to_local(wi));
        let p_spec = g.specular_probability(wo_l);
        each(Lobe::Specular, g.eval_specular(wo_l, wi_l), p_spec * g.pdf_specular(wo_l, wi_l));
        each(Lobe::Diffuse, g.eval_base(wo_l, wi_l), (1.0 - p_spec) * g.pdf_base(wi_l));
    }
}
