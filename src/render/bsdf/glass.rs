//! A smooth dielectric: Fresnel reflection or refraction, both delta.

use glam::Vec3;

use super::{fresnel_dielectric, reflect, refract, Bsdf, BsdfSample, Lobe};
use crate::render::sampler::{Dim, Sampler};

/// A smooth dielectric of index `ior` tinted by `color`: Fresnel reflection or refraction about
/// the shading normal `n`, chosen by the reflectance, both delta.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Glass {
    pub ior: f32,
    pub color: Vec3,
    pub n: Vec3,
    /// Whether the path arrived from outside (the side the geometric normal points to).
    pub entering: bool,
}

impl Bsdf for Glass {
    fn lobe(&self) -> Option<Lobe> {
        Some(Lobe::Delta)
    }

    fn albedo(&self, _: Lobe) -> Vec3 {
        self.color
    }

    fn sample(&self, wo: Vec3, u: &mut Sampler) -> Option<BsdfSample> {
        // eta is the ratio of the indices across the boundary.
        let eta = if self.entering { self.ior } else { 1.0 / self.ior };
        let cos_i = self.n.dot(wo).clamp(0.0, 1.0);
        let reflectance = fresnel_dielectric(cos_i, eta);
        let (wi, weight) = if u.get_1d(Dim::Lobe) < reflectance {
            (reflect(wo, self.n), self.color)
        } else {
            // Radiance is squeezed into the denser medium's smaller solid angle.
            (refract(wo, self.n, eta, cos_i), self.color / (eta * eta))
        };
        Some(BsdfSample { wi, weight, pdf: 1.0, lobe: Lobe::Delta })
    }
}
