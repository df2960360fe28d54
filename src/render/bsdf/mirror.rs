//! A perfect mirror: one delta lobe.

use glam::Vec3;

use super::{reflect, Bsdf, BsdfSample, Lobe};
use crate::render::sampler::Sampler;

/// Perfect specular reflection about the shading normal `n`, tinted by `color`: one delta lobe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mirror {
    pub color: Vec3,
    pub n: Vec3,
}

impl Bsdf for Mirror {
    fn lobe(&self) -> Option<Lobe> {
        Some(Lobe::Delta)
    }

    fn albedo(&self, _: Lobe) -> Vec3 {
        self.color
    }

    fn sample(&self, wo: Vec3, _: &mut Sampler) -> Option<BsdfSample> {
        Some(BsdfSample { wi: reflect(wo, self.n), weight: self.color, pdf: 1.0, lobe: Lobe::Delta })
    }
}
