//! The glossy material: a GGX microfacet lobe (Walter et al. 2007, "Microfacet Models for
//! Refraction through Rough Surfaces") with Schlick's Fresnel and the height-correlated
//! shadowing-masking term, sampled by its distribution of visible normals (Heitz 2018, "Sampling
//! the GGX Distribution of Visible Normals"), over an optional diffuse base: Ashikhmin and
//! Shirley's coupled diffuse term (2000, "An Anisotropic Phong BRDF Model"), which is reciprocal
//! and gives the base only the light the coating lets through.
//!
//! Everything here works in the local shading frame, z along the shading normal.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

use crate::math::{cosine_hemisphere, luminance};

/// The smallest GGX alpha: below it the lobe is a mirror for every practical purpose and its
/// density overflows f32 near the peak.
pub const MIN_ALPHA: f32 = 1e-3;

/// The GGX alpha of a material's roughness (as the scene file gives it, in [0, 1]): its square,
/// kept above [`MIN_ALPHA`].
pub fn alpha(roughness: f32) -> f32 {
    (roughness * roughness).max(MIN_ALPHA)
}

/// The two lobes of a glossy surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lobe {
    /// The GGX lobe: a specular-like (S) vertex for the component split.
    Specular,
    /// The diffuse base: a diffuse-like (D) vertex.
    Base,
}

/// A GGX lobe with reflectance `specular` at normal incidence, over a diffuse `base`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Glossy {
    pub specular: Vec3,
    pub alpha: f32,
    pub base: Vec3,
}

/// Schlick's approximation of the Fresnel reflectance.
fn schlick(f0: Vec3, cos: f32) -> Vec3 {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m2 = m * m;
    f0 + (Vec3::ONE - f0) * (m2 * m2 * m)
}

impl Glossy {
    /// GGX normal distribution of microfacet normal `m`.
    fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let t = m.z * m.z * (a2 - 1.0) + 1.0;
        a2 / (PI * t * t)
    }

    /// Smith's Lambda for direction `w`.
    fn lambda(&self, w: Vec3) -> f32 {
        let c2 = w.z * w.z;
        if c2 == 0.0 {
            return f32::INFINITY;
        }
        let tan2 = (1.0 - c2).max(0.0) / c2;
        0.5 * ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0)
    }

    fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking and shadowing.
    fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// The probability of sampling the GGX lobe rather than the base, seen from `wo`: in
    /// proportion to the light each reflects, so a dark base takes few samples.
    pub fn specular_probability(&self, wo: Vec3) -> f32 {
        let spec = luminance(schlick(self.specular, wo.z));
        let base = luminance(self.base * (Vec3::ONE - self.specular));
        if base <= 0.0 {
            1.0
        } else if spec <= 0.0 {
            0.0
        } else {
            spec / (spec + base)
        }
    }

    /// The GGX lobe's BRDF (zero unless both directions are above the surface).
    pub fn eval_specular(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let h = (wo + wi).normalize_or_zero();
        let f = schlick(self.specular, wo.dot(h));
        f * (self.d(h) * self.g2(wo, wi) / (4.0 * wo.z * wi.z))
    }

    /// The density of [`Glossy::sample_specular`] in solid angle (defined below the horizon
    /// too, where visible-normal sampling can send a direction).
    pub fn pdf_specular(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 {
            return 0.0;
        }
        let h = (wo + wi).normalize_or_zero();
        if wo.dot(h) <= 0.0 {
            return 0.0;
        }
        self.g1(wo) * self.d(h) / (4.0 * wo.z)
    }

    /// A direction from the GGX lobe by sampling a visible microfacet normal and reflecting.
    pub fn sample_specular(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let a = self.alpha;
        // The view direction in the hemisphere configuration (alpha = 1).
        let vh = Vec3::new(a * wo.x, a * wo.y, wo.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt() } else { Vec3::X };
        let t2 = vh.cross(t1);
        // A point on the projected half disk.
        let r = u.x.sqrt();
        let phi = TAU * u.y;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        // Back to the ellipsoid configuration.
        let m = Vec3::new(a * nh.x, a * nh.y, nh.z.max(0.0)).normalize();
        2.0 * wo.dot(m) * m - wo
    }

    /// The GGX lobe's f cos / pdf for a direction it sampled: F G2 / G1 (D cancels).
    pub fn specular_weight(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let h = (wo + wi).normalize_or_zero();
        schlick(self.specular, wo.dot(h)) * (self.g2(wo, wi) / self.g1(wo))
    }

    /// The diffuse base's BRDF (Ashikhmin-Shirley): what the coating lets through, twice.
    pub fn eval_base(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let through = |c: f32| {
            let m = 1.0 - 0.5 * c;
            let m2 = m * m;
            1.0 - m2 * m2 * m
        };
        self.base * (Vec3::ONE - self.specular) * (28.0 / (23.0 * PI) * through(wo.z) * through(wi.z))
    }

    /// The base is sampled by the cosine.
    pub fn pdf_base(&self, wi: Vec3) -> f32 {
        wi.z.max(0.0) / PI
    }

    pub fn sample_base(&self, u: Vec2) -> Vec3 {
        cosine_hemisphere(u)
    }

    /// The whole BRDF.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_specular(wo, wi) + self.eval_base(wo, wi)
    }

    /// The density of [`Glossy::sample`], both lobes together.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let p = self.specular_probability(wo);
        p * self.pdf_specular(wo, wi) + (1.0 - p) * self.pdf_base(wi)
    }

    /// Picks a lobe with `u_lobe`, then a direction from it.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> (Vec3, Lobe) {
        if u_lobe < self.specular_probability(wo) {
            (self.sample_specular(wo, u), Lobe::Specular)
        } else {
            (self.sample_base(u), Lobe::Base)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::chi_square::z_score;

    fn wo(theta_deg: f32) -> Vec3 {
        let t = theta_deg.to_radians();
        Vec3::new(t.sin(), 0.0, t.cos())
    }

    #[test]
    fn alpha_is_the_square_of_roughness_above_the_floor() {
        assert_eq!(alpha(0.5), 0.25);
        assert_eq!(alpha(1.0), 1.0);
        assert_eq!(alpha(0.0), MIN_ALPHA);
    }

    #[test]
    fn ggx_visible_normal_sampling_matches_its_density() {
        for (alpha, theta) in [(0.3, 0.0), (0.3, 60.0), (0.6, 30.0), (1.0, 80.0)] {
            let g = Glossy { specular: Vec3::splat(0.9), alpha, base: Vec3::ZERO };
            let wo = wo(theta);
            let z = z_score(|s| Some(g.sample_specular(wo, s.next_2d())), |d| g.pdf_specular(wo, d));
            assert!(z < 4.0, "alpha {alpha}, theta {theta}: z = {z}");
        }
    }

    #[test]
    fn both_lobes_together_match_the_mixture_density() {
        let g = Glossy { specular: Vec3::splat(0.04), alpha: 0.4, base: Vec3::new(0.7, 0.2, 0.1) };
        let wo = wo(45.0);
        let p = g.specular_probability(wo);
        assert!(p > 0.0 && p < 1.0, "{p}");
        let z = z_score(|s| Some(g.sample(wo, s.next_1d(), s.next_2d()).0), |d| g.pdf(wo, d));
        assert!(z < 4.0, "z = {z}");
    }

    #[test]
    fn a_wrong_ggx_density_fails() {
        // The test has power: a lobe judged by the density of a rougher one must fail.
        let g = Glossy { specular: Vec3::ONE, alpha: 0.3, base: Vec3::ZERO };
        let rough = Glossy { alpha: 0.36, ..g };
        let wo = wo(30.0);
        let z = z_score(|s| Some(g.sample_specular(wo, s.next_2d())), |d| rough.pdf_specular(wo, d));
        assert!(z > 10.0, "z = {z}");
    }

    #[test]
    fn the_sampling_weight_is_f_cos_over_pdf() {
        let g = Glossy { specular: Vec3::new(0.9, 0.5, 0.2), alpha: 0.25, base: Vec3::ZERO };
        let wo = wo(50.0);
        let mut s = crate::render::sampler::Sampler::new(1, 2, 3);
        for _ in 0..1000 {
            let wi = g.sample_specular(wo, s.next_2d());
            if wi.z <= 1e-3 {
                continue;
            }
            let direct = g.eval_specular(wo, wi) * wi.z / g.pdf_specular(wo, wi);
            let weight = g.specular_weight(wo, wi);
            assert!((direct - weight).abs().max_element() < 1e-4 * (1.0 + weight.max_element()), "{wi}");
        }
    }

    #[test]
    fn reciprocal_and_energy_bounded() {
        let mut s = crate::render::sampler::Sampler::new(4, 5, 6);
        // Reciprocity, f(a, b) = f(b, a), for smooth to rough lobes, with and without a base,
        // dielectric and metallic F0; grazing directions included.
        for (alpha, f0, base) in [
            (0.001, 0.04, Vec3::ONE),
            (0.05, 0.04, Vec3::splat(0.5)),
            (0.3, 0.04, Vec3::ONE),
            (0.3, 0.95, Vec3::ZERO),
            (1.0, 0.5, Vec3::new(0.8, 0.2, 0.1)),
        ] {
            let g = Glossy { specular: Vec3::splat(f0), alpha, base };
            for i in 0..2000 {
                let a = if i % 10 == 0 { wo(89.9) } else { cosine_hemisphere(s.next_2d()) };
                let b = cosine_hemisphere(s.next_2d());
                let (ab, ba) = (g.eval(a, b), g.eval(b, a));
                assert!(ab.is_finite() && ab.min_element() >= 0.0, "alpha {alpha}: f({a}, {b}) = {ab}");
                assert!(
                    (ab - ba).abs().max_element() <= 1e-4 * ab.max_element().max(1.0),
                    "alpha {alpha}: {a} {b}: {ab} vs {ba}"
                );
            }
        }
        let g = Glossy { specular: Vec3::splat(0.04), alpha: 0.3, base: Vec3::ONE };
        // Directional albedo (the integral of f cos over the hemisphere) stays at or under 1, by
        // importance sampling the mixture with many samples.
        for theta in [0.0f32, 45.0, 75.0, 89.0] {
            let wo = wo(theta);
            let n = 200_000;
            let mut sum = 0.0f64;
            for _ in 0..n {
                let (wi, _) = g.sample(wo, s.next_1d(), s.next_2d());
                let pdf = g.pdf(wo, wi);
                if pdf > 0.0 && wi.z > 0.0 {
                    sum += (g.eval(wo, wi).max_element() * wi.z / pdf) as f64;
                }
            }
            let albedo = sum / n as f64;
            // Standard error well under 0.005 at 200k samples. Single-scattering GGX loses the
            // light that would bounce between microfacets, most at grazing angles (0.22 at 89
            // degrees here), but near the normal almost nothing is lost.
            assert!(albedo <= 1.0 + 0.01, "theta {theta}: albedo {albedo}");
            if theta == 0.0 {
                assert!(albedo > 0.9, "albedo {albedo}");
            }
        }
    }
}
