//! Lambertian reflection: one D lobe, sampled by the cosine.

use std::f32::consts::FRAC_1_PI;

use glam::Vec3;

use super::{Bsdf, BsdfSample, Lobe};
use crate::math::{cosine_hemisphere, Frame};
use crate::render::sampler::{Dim, Sampler};

/// Lambertian reflection of `albedo` about the shading normal `n`: one D lobe, sampled by the
/// cosine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diffuse {
    pub albedo: Vec3,
    pub n: Vec3,
}

impl Bsdf for Diffuse {
    fn lobe(&self) -> Option<Lobe> {
        Some(Lobe::Diffuse)
    }

    fn albedo(&self, _: Lobe) -> Vec3 {
        self.albedo
    }

    #[inline(always)]
    fn sample(&self, _wo: Vec3, u: &mut Sampler) -> Option<BsdfSample> {
        let local = cosine_hemisphere(u.get_2d(Dim::Direction));
        let wi = Frame::new(self.n).to_world(local);
        // f cos / pdf of a Lambertian lobe is its albedo.
        Some(BsdfSample { wi, weight: self.albedo, pdf: local.z * FRAC_1_PI, lobe: Lobe::Diffuse })
    }

    #[inline(always)]
    fn eval_lobes(&self, _wo: Vec3, wi: Vec3, mut each: impl FnMut(Lobe, Vec3, f32)) {
        let cos = self.n.dot(wi);
        if cos > 0.0 {
            each(Lobe::Diffuse, self.albedo * FRAC_1_PI, cos * FRAC_1_PI);
        }
    }
}
