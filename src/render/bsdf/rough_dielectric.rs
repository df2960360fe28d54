//! Mitsuba's `roughdielectric`: a rough boundary between two indices (Walter et al. 2007, with
//! the solid-angle compression of radiance crossing it), reflecting and refracting through one
//! microfacet normal drawn from the visible normals, as Mitsuba 3 evaluates and samples it.

use glam::Vec3;

use super::microfacet::Microfacet;
use super::{fresnel_dielectric, reflect, refract, Bsdf, BsdfSample, Kinds, Lobe};
use crate::math::Frame;
use crate::render::sampler::{Dim, Sampler};

/// A rough dielectric boundary of relative index `eta` (inside over outside) about `frame`
/// (its normal on the viewer's side), `entering` when the path arrives from outside, with
/// Mitsuba's reflectance and transmittance tints. The reflection is an S vertex (a D vertex
/// when `rough`, as wide as a glossy lobe the split counts diffuse); the transmission is a
/// [`Lobe::Delta`] vertex, as every transmission is to next-event estimation, which never
/// looks through a surface.
#[derive(Clone, Copy, Debug)]
pub struct RoughDielectric {
    pub frame: Frame,
    pub eta: f32,
    pub reflectance: Vec3,
    pub transmittance: Vec3,
    pub facets: Microfacet,
    pub entering: bool,
    pub rough: bool,
}

impl RoughDielectric {
    /// The index ratio across the boundary as the path crosses it (transmitted over incident).
    fn eta_path(&self) -> f32 {
        if self.entering {
            self.eta
        } else {
            1.0 / self.eta
        }
    }

    fn reflection_tag(&self) -> Lobe {
        if self.rough {
            Lobe::Diffuse
        } else {
            Lobe::Specular
        }
    }

    /// The reflection's value and density for local directions, both above the surface.
    fn reflection(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let m = (wo + wi).normalize();
        let f = &self.facets;
        let fresnel = fresnel_dielectric(wo.dot(m).clamp(0.0, 1.0), self.eta_path());
        let value = self.reflectance * (fresnel * f.d(m) * f.g(wo, wi, m) / (4.0 * wo.z * wi.z));
        (value, f.pdf(wo, m) * fresnel / (4.0 * wi.dot(m)))
    }

    /// The transmission's value f cos(wi) and density for local directions, `wo` above and `wi`
    /// below, radiance divided by eta^2 as it crosses (the two cancel in the value, as in
    /// Mitsuba's).
    pub fn transmission(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z <= 0.0 || wi.z >= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let eta = self.eta_path();
        let mut m = (wo + eta * wi).normalize();
        if m.z < 0.0 {
            m = -m;
        }
        let (om, im) = (wo.dot(m), wi.dot(m));
        let f = &self.facets;
        if om <= 0.0 || im >= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let fresnel = fresnel_dielectric(om, eta);
        let denom = (om + eta * im) * (om + eta * im);
        let value = (1.0 - fresnel) * f.d(m) * f.g(wo, wi, m) * om * -im / (wo.z * denom);
        let pdf = f.pdf(wo, m) * (1.0 - fresnel) * eta * eta * -im / denom;
        (self.transmittance * value, pdf)
    }

    /// The density of sampling the world direction `wi` through the surface (for tests).
    pub fn transmission_pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.transmission(self.frame.to_local(wo), self.frame.to_local(wi)).1
    }
}

impl Bsdf for RoughDielectric {
    fn lobe(&self) -> Option<Lobe> {
        None
    }

    /// One kind for its albedo, the transmittance (its reflection's colour is white).
    fn kinds(&self) -> Kinds {
        Kinds::of(Lobe::Delta)
    }

    fn albedo(&self, _: Lobe) -> Vec3 {
        self.transmittance
    }

    fn sample(&self, wo: Vec3, u: &mut Sampler) -> Option<BsdfSample> {
        let wo_l = self.frame.to_local(wo);
        let m = self.facets.sample(wo_l, u.get_2d(Dim::Direction))?;
        let om = wo_l.dot(m);
        if om <= 0.0 {
            return None;
        }
        let eta = self.eta_path();
        let fresnel = fresnel_dielectric(om.clamp(0.0, 1.0), eta);
        // The weight is the value over the density, whichever way the normal was drawn (the
        // visible normals of GGX, Beckmann's by D cos).
        if u.get_1d(Dim::Lobe) < fresnel {
            let wi = reflect(wo_l, m);
            let (value, pdf) = self.reflection(wo_l, wi);
            if pdf.is_nan() || pdf <= 0.0 {
                return None;
            }
            let weight = value * (wi.z / pdf);
            return Some(BsdfSample {
                wi: self.frame.to_world(wi),
                weight,
                pdf,
                lobe: self.reflection_tag(),
            });
        }
        let wi = refract(wo_l, m, eta, om);
        let (value, pdf) = self.transmission(wo_l, wi);
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample { wi: self.frame.to_world(wi), weight: value / pdf, pdf, lobe: Lobe::Delta })
    }

    fn eval_lobes(&self, wo: Vec3, wi: Vec3, mut each: impl FnMut(Lobe, Vec3, f32)) {
        let (value, pdf) = self.reflection(self.frame.to_local(wo), self.frame.to_local(wi));
        if pdf > 0.0 {
            each(self.reflection_tag(), value, pdf);
        }
    }
}
