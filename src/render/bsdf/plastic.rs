//! Mitsuba's `plastic` and `roughplastic`: a diffuse base under a dielectric coating, with the
//! light the base sends back up reflected inside the coating again and again (the internal
//! scattering of Mitsuba 3's model: the base's reflectance over 1 - the coating's internal
//! diffuse reflectance). The coating is a delta lobe (smooth) or a microfacet lobe (rough);
//! what it lets through, in and out, is 1 - its Fresnel reflectance (smooth) or its rough
//! transmittance, tabulated by the cosine as Mitsuba tabulates it ([`CoatingTable`]).

use std::f32::consts::FRAC_1_PI;

use glam::{Vec2, Vec3};

use super::microfacet::Microfacet;
use super::{fresnel_dielectric, reflect, refract, Bsdf, BsdfSample, Kinds, Lobe};
use crate::math::{cosine_hemisphere, Frame};
use crate::render::sampler::{Dim, Sampler};

/// How many cosines the rough coating's transmittance is tabulated at (Mitsuba's 64).
pub const TABLE_SIZE: usize = 64;

/// A rough coating's transmittance by the cosine (from 0 to 1, evenly, the first at 1e-6),
/// and its internal reflectance, 2 times the mean of R(mu) mu over the same cosines: what
/// Mitsuba computes when a `roughplastic` is made, integrated here over a 64 x 64 grid of
/// strata of the normals the distribution samples, weighted to the view's visible normals.
#[derive(Clone, Debug, PartialEq)]
pub struct CoatingTable {
    pub transmittance: Vec<f32>,
    pub internal_reflectance: f32,
}

impl CoatingTable {
    pub fn new(facets: &Microfacet, eta: f32) -> CoatingTable {
        let mus: Vec<f32> = (0..TABLE_SIZE).map(|i| (i as f32 / (TABLE_SIZE - 1) as f32).max(1e-6)).collect();
        let transmittance = mus.iter().map(|&mu| coating_integral(facets, mu, eta, false)).collect();
        let internal: f32 = mus.iter().map(|&mu| coating_integral(facets, mu, 1.0 / eta, true) * mu).sum();
        CoatingTable { transmittance, internal_reflectance: 2.0 * internal / TABLE_SIZE as f32 }
    }

    /// The transmittance at cosine `cos`, linearly between the tabulated cosines.
    pub fn at(&self, cos: f32) -> f32 {
        let x = cos.clamp(0.0, 1.0) * (TABLE_SIZE - 1) as f32;
        let i = (x as usize).min(TABLE_SIZE - 2);
        let (a, b) = (self.transmittance.get(i), self.transmittance.get(i + 1));
        match (a, b) {
            (Some(&a), Some(&b)) => a + (b - a) * (x - i as f32),
            _ => 0.0,
        }
    }
}

/// What a rough boundary of relative index `eta` transmits (or, `reflect`, reflects) of light
/// arriving at cosine `mu`, single-scattered: the mean over the view's visible normals of
/// (1 - F) G1 (or F G1) of the scattered direction.
fn coating_integral(facets: &Microfacet, mu: f32, eta: f32, reflected: bool) -> f32 {
    let wi = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let n = 64;
    let mut sum = 0.0f64;
    for k in 0..n * n {
        let u = Vec2::new(((k % n) as f32 + 0.5) / n as f32, ((k / n) as f32 + 0.5) / n as f32);
        let Some(m) = facets.sample(wi, u) else { continue };
        let pdf = facets.pdf(wi, m);
        if pdf.is_nan() || pdf <= 0.0 {
            continue;
        }
        // The visible normals' density over the one sampled.
        let visible = facets.d(m) * facets.g1(wi, m) * wi.dot(m).max(0.0) / wi.z;
        let cos = wi.dot(m);
        let f = fresnel_dielectric(cos, eta);
        let value = if reflected {
            let wr = reflect(wi, m);
            if wr.z <= 0.0 {
                continue;
            }
            f * facets.g1(wr, m)
        } else {
            if f >= 1.0 {
                continue;
            }
            let wt = refract(wi, m, eta, cos);
            if wt.z >= 0.0 {
                continue;
            }
            (1.0 - f) * facets.g1(wt, m)
        };
        sum += (value * visible / pdf) as f64;
    }
    (sum / (n * n) as f64) as f32
}

/// The coating over its base, in `frame`: index ratio `eta`, base `diffuse` already divided by
/// 1 - the internal reflectance (`internal` the factor as Mitsuba applies it), `specular` the
/// coating's tint, `specular_weight` the share of samples Mitsuba gives the coating before
/// Fresnel. Smooth without `facets`; the rough coating's lobe is an S vertex, or D when
/// `rough`; the base is D.
#[derive(Clone, Copy, Debug)]
pub struct Plastic<'a> {
    pub frame: Frame,
    pub eta: f32,
    pub diffuse: Vec3,
    pub specular: Vec3,
    pub specular_weight: f32,
    pub facets: Option<(Microfacet, &'a CoatingTable)>,
    pub rough: bool,
}

impl Plastic<'_> {
    fn coat_tag(&self) -> Lobe {
        match (self.facets.is_some(), self.rough) {
            (false, _) => Lobe::Delta,
            (true, true) => Lobe::Diffuse,
            (true, false) => Lobe::Specular,
        }
    }

    /// What the coating lets through at cosine `cos`.
    fn through(&self, cos: f32) -> f32 {
        match &self.facets {
            Some((_, table)) => table.at(cos),
            None => 1.0 - fresnel_dielectric(cos, self.eta),
        }
    }

    /// The probability of sampling the coating, seen from local `wo`.
    fn p_coat(&self, wo: Vec3) -> f32 {
        let w = self.specular_weight;
        let t = self.through(wo.z);
        let (c, d) = ((1.0 - t) * w, t * (1.0 - w));
        if c + d > 0.0 {
            c / (c + d)
        } else {
            0.0
        }
    }

    /// The base's value toward local `wi`.
    fn base(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.diffuse * (FRAC_1_PI * self.through(wo.z) * self.through(wi.z) / (self.eta * self.eta))
    }

    /// The rough coating's value and density (before the choice of lobe).
    fn coat(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let Some((facets, _)) = &self.facets else { return (Vec3::ZERO, 0.0) };
        let h = (wo + wi).normalize();
        let f =
            fresnel_dielectric(wo.dot(h), self.eta) * facets.d(h) * facets.g(wi, wo, h) / (4.0 * wo.z * wi.z);
        (self.specular * f, facets.pdf(wo, h) / (4.0 * wo.dot(h)))
    }
}

impl Bsdf for Plastic<'_> {
    fn lobe(&self) -> Option<Lobe> {
        None
    }

    fn scatters(&self, wo: Vec3) -> bool {
        self.frame.to_local(wo).z > 0.0
    }

    fn kinds(&self) -> Kinds {
        Kinds::of(Lobe::Diffuse).with(self.coat_tag())
    }

    /// The base's and, when a rough coat counts as diffuse too, the coat's.
    fn kind_albedo(&self, kind: Lobe) -> Vec3 {
        let base = if kind == Lobe::Diffuse { self.diffuse } else { Vec3::ZERO };
        base + if kind == self.coat_tag() { self.specular } else { Vec3::ZERO }
    }

    fn albedo(&self, lobe: Lobe) -> Vec3 {
        if lobe == Lobe::Diffuse {
            self.diffuse
        } else {
            self.specular
        }
    }

    fn sample(&self, wo: Vec3, u: &mut Sampler) -> Option<BsdfSample> {
        let wo_l = self.frame.to_local(wo);
        if wo_l.z <= 0.0 {
            return None;
        }
        let p_coat = self.p_coat(wo_l);
        let coat = u.get_1d(Dim::Lobe) < p_coat;
        let dir = u.get_2d(Dim::Direction);
        if coat && self.facets.is_none() {
            let f = fresnel_dielectric(wo_l.z, self.eta);
            let wi = reflect(wo, self.frame.n);
            return Some(BsdfSample {
                wi,
                weight: self.specular * (f / p_coat),
                pdf: 1.0,
                lobe: Lobe::Delta,
            });
        }
        let (wi_l, lobe) = match (coat, &self.facets) {
            (true, Some((facets, _))) => (reflect(wo_l, facets.sample(wo_l, dir)?), self.coat_tag()),
            _ => (cosine_hemisphere(dir), Lobe::Diffuse),
        };
        if wi_l.z <= 0.0 {
            return None;
        }
        // Each lobe's own value over its own density (its choice's probability included), as
        // the split needs: a lobe's light goes to the component of its kind.
        let (f, pdf) = if lobe == Lobe::Diffuse && !coat {
            (self.base(wo_l, wi_l), (1.0 - p_coat) * wi_l.z * FRAC_1_PI)
        } else {
            let (f, pdf) = self.coat(wo_l, wi_l);
            (f, p_coat * pdf)
        };
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample { wi: self.frame.to_world(wi_l), weight: f * (wi_l.z / pdf), pdf, lobe })
    }

    fn eval_lobes(&self, wo: Vec3, wi: Vec3, mut each: impl FnMut(Lobe, Vec3, f32)) {
        let (wo_l, wi_l) = (self.frame.to_local(wo), self.frame.to_local(wi));
        if wo_l.z <= 0.0 || wi_l.z <= 0.0 {
            return;
        }
        let p_coat = self.p_coat(wo_l);
        if self.facets.is_some() {
            let (f, pdf) = self.coat(wo_l, wi_l);
            each(self.coat_tag(), f, p_coat * pdf);
        }
        each(Lobe::Diffuse, self.base(wo_l, wi_l), (1.0 - p_coat) * wi_l.z * FRAC_1_PI);
    }
}
