//! Microfacet distributions as Mitsuba 3 defines them (`include/mitsuba/render/microfacet.h`),
//! for the materials read from its scene files: Beckmann and GGX, isotropic or anisotropic
//! (alpha along the shading frame's s and t axes), with Smith's separable shadowing-masking
//! G1(wi) G1(wo) (the Beckmann G1 by Walter et al.'s rational fit, as Mitsuba evaluates it), so
//! that the values agree with Mitsuba's. Normals are sampled from GGX's visible normals (Heitz
//! 2018) and from Beckmann's D(m) cos(m); only the variance depends on that choice.
//!
//! Directions are local: +z is the shading normal.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

/// Which normal distribution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Distribution {
    Beckmann,
    Ggx,
}

/// A microfacet distribution: its kind and widths along s and t.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    pub kind: Distribution,
    pub alpha_u: f32,
    pub alpha_v: f32,
}

impl Microfacet {
    /// The smallest width: below it the densities overflow f32 near the peak.
    pub const MIN_ALPHA: f32 = 1e-4;

    pub fn new(kind: Distribution, alpha_u: f32, alpha_v: f32) -> Microfacet {
        Microfacet { kind, alpha_u: alpha_u.max(Self::MIN_ALPHA), alpha_v: alpha_v.max(Self::MIN_ALPHA) }
    }

    pub fn is_isotropic(&self) -> bool {
        self.alpha_u == self.alpha_v
    }

    /// The density of microfacet normals D(m), per unit solid angle of m, projected: the
    /// integral of D(m) cos(m) over the hemisphere is 1.
    pub fn d(&self, m: Vec3) -> f32 {
        let (au, av) = (self.alpha_u, self.alpha_v);
        let cos2 = m.z * m.z;
        if m.z <= 0.0 {
            return 0.0;
        }
        let r = match self.kind {
            Distribution::Beckmann => {
                let e = ((m.x / au).powi(2) + (m.y / av).powi(2)) / cos2;
                (-e).exp() / (PI * au * av * cos2 * cos2)
            }
            Distribution::Ggx => {
                let q = (m.x / au).powi(2) + (m.y / av).powi(2) + cos2;
                1.0 / (PI * au * av * q * q)
            }
        };
        if (r * m.z).is_finite() && r * m.z > 1e-20 {
            r
        } else {
            0.0
        }
    }

    /// Smith's masking of direction `v` on facets of normal `m`: 0 where `v` sees a facet's
    /// back.
    pub fn g1(&self, v: Vec3, m: Vec3) -> f32 {
        if v.dot(m) * v.z <= 0.0 {
            return 0.0;
        }
        let xy = (self.alpha_u * v.x).powi(2) + (self.alpha_v * v.y).powi(2);
        if xy == 0.0 {
            return 1.0;
        }
        let tan2 = xy / (v.z * v.z);
        match self.kind {
            Distribution::Beckmann => {
                let a = 1.0 / tan2.sqrt();
                if a >= 1.6 {
                    1.0
                } else {
                    (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)
                }
            }
            Distribution::Ggx => 2.0 / (1.0 + (1.0 + tan2).sqrt()),
        }
    }

    /// Shadowing and masking of a pair of directions.
    pub fn g(&self, wi: Vec3, wo: Vec3, m: Vec3) -> f32 {
        self.g1(wi, m) * self.g1(wo, m)
    }

    /// A facet normal for the view `wo` (above the surface) and its density per solid angle
    /// of the normal ([`Microfacet::pdf`]).
    pub fn sample(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        if wo.z <= 0.0 {
            return None;
        }
        let m = match self.kind {
            Distribution::Ggx => self.sample_visible_ggx(wo, u),
            Distribution::Beckmann => self.sample_beckmann(u),
        };
        (m.is_finite() && m.z > 0.0).then_some(m)
    }

    /// The density of [`Microfacet::sample`] giving normal `m` for view `wo`.
    pub fn pdf(&self, wo: Vec3, m: Vec3) -> f32 {
        match self.kind {
            Distribution::Ggx if wo.z > 0.0 => self.d(m) * self.g1(wo, m) * wo.dot(m).max(0.0) / wo.z,
            Distribution::Ggx => 0.0,
            Distribution::Beckmann => self.d(m) * m.z.max(0.0),
        }
    }

    /// GGX's visible normals, stretched to the unit width and back (Heitz 2018).
    fn sample_visible_ggx(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let (au, av) = (self.alpha_u, self.alpha_v);
        let vh = Vec3::new(au * wo.x, av * wo.y, wo.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt() } else { Vec3::X };
        let t2 = vh.cross(t1);
        let r = u.x.sqrt();
        let (sin, cos) = crate::math::sin_cos_turn(u.y);
        let (p1, mut p2) = (r * cos, r * sin);
        let s = 0.5 * (1.0 + vh.z);
        p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        Vec3::new(au * nh.x, av * nh.y, nh.z.max(0.0)).normalize()
    }

    /// Beckmann's normals by D(m) cos(m) (Mitsuba's non-visible sampling).
    fn sample_beckmann(&self, u: Vec2) -> Vec3 {
        let (au, av) = (self.alpha_u, self.alpha_v);
        let (sin_phi, cos_phi, alpha2) = if self.is_isotropic() {
            let (s, c) = crate::math::sin_cos_turn(u.y);
            (s, c, au * au)
        } else {
            let tmp = av / au * (TAU * u.y).tan();
            let cos_phi = (1.0 / (tmp * tmp + 1.0).sqrt()).copysign((u.y - 0.5).abs() - 0.25);
            let sin_phi = cos_phi * tmp;
            (sin_phi, cos_phi, 1.0 / ((cos_phi / au).powi(2) + (sin_phi / av).powi(2)))
        };
        let cos_theta = 1.0 / (1.0 - alpha2 * (1.0 - u.x).max(1e-12).ln()).sqrt();
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        Vec3::new(cos_phi * sin_theta, sin_phi * sin_theta, cos_theta)
    }
}

/// Fresnel reflectance of a conductor of complex index `eta + i k` (per channel) at incidence
/// cosine `cos` (Mitsuba's `fresnel_conductor`).
pub fn fresnel_conductor(cos: f32, eta: Vec3, k: Vec3) -> Vec3 {
    let c = cos.clamp(0.0, 1.0);
    let c2 = c * c;
    let s2 = 1.0 - c2;
    let s4 = s2 * s2;
    let one = |eta: f32, k: f32| {
        let t1 = eta * eta - k * k - s2;
        let a2b2 = (t1 * t1 + 4.0 * k * k * eta * eta).max(0.0).sqrt();
        let a = (0.5 * (a2b2 + t1)).max(0.0).sqrt();
        let term1 = a2b2 + c2;
        let term2 = 2.0 * c * a;
        let rs = (term1 - term2) / (term1 + term2);
        let term3 = a2b2 * c2 + s4;
        let term4 = term2 * s2;
        let rp = rs * (term3 - term4) / (term3 + term4);
        let r = 0.5 * (rs + rp);
        if r.is_finite() {
            r
        } else {
            1.0
        }
    };
    Vec3::new(one(eta.x, k.x), one(eta.y, k.y), one(eta.z, k.z))
}

/// Mitsuba's fit of a dielectric boundary's diffuse (hemispherically averaged) Fresnel
/// reflectance, seen from the side where the index ratio is `eta`.
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let inv = 1.0 / eta;
    if eta < 1.0 {
        0.0636 * inv + eta * (eta * -1.4399 + 0.7099) + 0.6681
    } else {
        let c = [0.919317, -3.4793, 6.75335, -7.80989, 4.98554, -1.36881];
        c.iter().rev().fold(0.0f32, |acc, &k| acc * inv + k)
    }
}
