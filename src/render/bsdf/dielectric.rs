//! Mitsuba's `dielectric` and `thindielectric`: a smooth boundary between two indices, with
//! its own reflectance and transmittance tints, refracting, or (thin) passing light straight
//! through a sheet after its internal reflections. Both lobes are delta.

use glam::Vec3;

use super::{fresnel_dielectric, reflect, refract, Bsdf, BsdfSample, Lobe};
use crate::render::sampler::{Dim, Sampler};

/// A smooth dielectric boundary of relative index `eta` (inside over outside) at shading normal
/// `n` (on the viewer's side), `entering` when the path arrives from outside; `thin` a sheet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dielectric {
    pub eta: f32,
    pub reflectance: Vec3,
    pub transmittance: Vec3,
    pub n: Vec3,
    pub entering: bool,
    pub thin: bool,
}

impl Bsdf for Dielectric {
    fn lobe(&self) -> Option<Lobe> {
        Some(Lobe::Delta)
    }

    fn albedo(&self, _: Lobe) -> Vec3 {
        self.transmittance
    }

    fn sample(&self, wo: Vec3, u: &mut Sampler) -> Option<BsdfSample> {
        let cos_i = self.n.dot(wo).clamp(0.0, 1.0);
        if self.thin {
            // The sheet's two boundaries and every bounce between them (Mitsuba's sum).
            let mut r = fresnel_dielectric(cos_i, self.eta);
            if r < 1.0 {
                r += (1.0 - r) * (1.0 - r) * r / (1.0 - r * r);
            }
            let (wi, weight) = if u.get_1d(Dim::Lobe) < r {
                (reflect(wo, self.n), self.reflectance)
            } else {
                (-wo, self.transmittance)
            };
            return Some(BsdfSample { wi, weight, pdf: 1.0, lobe: Lobe::Delta });
        }
        let eta = if self.entering { self.eta } else { 1.0 / self.eta };
        let r = fresnel_dielectric(cos_i, eta);
        let (wi, weight) = if u.get_1d(Dim::Lobe) < r {
            (reflect(wo, self.n), self.reflectance)
        } else {
            // Radiance is squeezed into the denser medium's smaller solid angle.
            (refract(wo, self.n, eta, cos_i), self.transmittance / (eta * eta))
        };
        Some(BsdfSample { wi, weight, pdf: 1.0, lobe: Lobe::Delta })
    }
}
