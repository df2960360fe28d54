//! glTF's whole material model as one layered BSDF, stacked as Blender's Principled BSDF and the
//! glTF specification stack it. From the top:
//! - a clearcoat (`KHR_materials_clearcoat`): GGX with the Fresnel of an index of 1.5;
//! - sheen (`KHR_materials_sheen`): the Charlie lobe of [`SheenLobe`];
//! - the specular lobe: GGX with Schlick's Fresnel from f0 to f90 (`KHR_materials_specular`,
//!   `KHR_materials_ior`; the base colour for a metal), its multiple scattering restored
//!   (Turquin 2019);
//! - under the dielectric part, a Lambertian base or, by `transmission`
//!   (`KHR_materials_transmission`), the light that crosses the surface: refracted through a
//!   GGX microfacet, or straight through a thin wall.
//!
//! Each layer passes down what it does not reflect, seen from the view direction (albedo
//! scaling, as Blender's and the Khronos viewer's layers do): a layer of directional albedo E
//! over what is below leaves (1 - E) of the light to it. A white, non-absorbing material so
//! reflects and transmits all the light, to the accuracy of the albedo tables.
//!
//! Seen from inside a closed transmissive object the surface is a rough dielectric boundary:
//! Fresnel reflection back inside or refraction out, through a sampled microfacet, the light a
//! single facet loses restored by the interaction's albedo ([`InsideAlbedo`]).
//!
//! Component tags: the diffuse base and sheen are D; the specular lobe and the clearcoat are S,
//! or D from the roughness at which a rough lobe counts as diffuse; transmission, and every
//! lobe seen from inside, are delta, since light sampling cannot reach through the surface.

use std::f32::consts::FRAC_1_PI;

use glam::{Vec2, Vec3};

use super::ggx::schlick_to;
use super::sheen::{SheenAlbedo, SheenLobe};
use super::{
    fresnel_dielectric, reflect, refract, Bsdf, BsdfSample, GlossyLobes, Kinds, Lobe, SpecularAlbedo,
};
use crate::math::{cosine_hemisphere, luminance, Frame};
use crate::render::sampler::{Dim, Sampler};

/// The clearcoat's reflectance at normal incidence: an index of 1.5, as glTF fixes it.
const COAT_F0: f32 = 0.04;

/// The dielectric reflectance at normal incidence and at grazing of `KHR_materials_specular`
/// and `KHR_materials_ior`: f0 = ((ior - 1) / (ior + 1))^2 times the specular colour (at most
/// 1), both times the specular factor.
pub fn dielectric_f0(ior: f32, specular: f32, color: Vec3) -> (Vec3, f32) {
    let r = (ior - 1.0) / (ior + 1.0);
    ((Vec3::splat(r * r) * color).min(Vec3::ONE) * specular, specular)
}

/// The layered BSDF at one shading point (see the module's notes).
#[derive(Clone, Copy, Debug)]
pub struct Principled {
    pub frame: Frame,
    /// The clearcoat's own frame, when its normal map bends it away from `frame`'s.
    pub coat_frame: Option<Frame>,
    /// The diffuse base's own frame where it differs from `frame`: the normal map's bent
    /// normal, when the shading normal was raised so that the glossy lobes' reflection of the
    /// view stays above the surface (Cycles raises it for its glossy lobes only).
    pub base_frame: Option<Frame>,
    /// Whether the path arrived from outside (the side the geometric normal points to).
    pub entering: bool,
    /// The base colour: the Lambertian base's albedo, a metal's f0, transmission's tint.
    pub color: Vec3,
    pub metallic: f32,
    /// GGX alpha of the specular lobe and of transmission.
    pub alpha: f32,
    /// The dielectric part's Fresnel: f0 and f90.
    pub f0: Vec3,
    pub f90: f32,
    /// The fraction of the dielectric part's base that is transmitted instead of diffused.
    pub transmission: f32,
    pub ior: f32,
    /// A thin wall: transmitted light leaves on the other side without bending.
    pub thin: bool,
    pub coat: f32,
    pub coat_alpha: f32,
    /// The sheen lobe and its perceptual roughness (the albedo table's index).
    pub sheen: SheenLobe,
    pub sheen_roughness: f32,
    /// Whether the specular lobe and the clearcoat count as diffuse (D) vertices.
    pub rough: bool,
    pub coat_rough: bool,
}

/// The lobes in their order of [`Weights::p`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Which {
    Coat,
    Sheen,
    Specular,
    Diffuse,
    Transmission,
}

const LOBES: [Which; 5] = [Which::Coat, Which::Sheen, Which::Specular, Which::Diffuse, Which::Transmission];

/// What each layer weighs seen from one view direction.
#[derive(Clone, Copy, Debug)]
struct Weights {
    /// The sheen lobe's colour, dimmed by the clearcoat.
    sheen: Vec3,
    /// The specular lobe's Fresnel factors: the dielectric's and the metal's (each with its
    /// multiple-scattering compensation and its share), dimmed by the layers above.
    spec_dielectric: Vec3,
    spec_metal: Vec3,
    /// The Lambertian base's albedo, and the transmitted fraction, as they arrive below.
    diffuse: Vec3,
    through: Vec3,
    /// The probability of sampling each lobe, in proportion to its directional albedo.
    p: [f32; 5],
}

impl Principled {
    fn coat_lobe(&self) -> GlossyLobes {
        GlossyLobes { specular: Vec3::splat(COAT_F0), alpha: self.coat_alpha, base: Vec3::ZERO }
    }

    /// The specular lobe's geometry (its Fresnel is applied by [`Principled::fresnel`]).
    fn spec_lobe(&self) -> GlossyLobes {
        GlossyLobes { specular: Vec3::ONE, alpha: self.alpha, base: Vec3::ZERO }
    }

    fn weights(&self, wo: Vec3) -> Weights {
        let table = SpecularAlbedo::get();
        let cos = wo.z;
        // A coat bent by its own normal map reflects by its own cosine (nothing when the view
        // is below its horizon).
        let coat_cos = match self.coat_frame {
            None => cos,
            Some(coat) => coat.to_local(self.frame.to_world(wo)).z,
        };
        let coat_albedo = match self.coat > 0.0 && coat_cos > 0.0 {
            true => {
                let (a, b) = table.at(coat_cos, self.coat_alpha);
                self.coat * (COAT_F0 * a + b)
            }
            false => 0.0,
        };
        let below_coat = (1.0 - coat_albedo).max(0.0);
        let sheen_albedo = match self.sheen.color.max_element() > 0.0 {
            true => SheenAlbedo::get().at(cos, self.sheen_roughness),
            false => 0.0,
        };
        let sheen = self.sheen.color * below_coat;
        let below_sheen = below_coat * (1.0 - self.sheen.color.max_element() * sheen_albedo).max(0.0);
        // One lookup of the specular table serves the dielectric's and the metal's lobes.
        let (a, b, e_avg) = table.lookup(cos, self.alpha);
        let ms_dielectric = table.compensation(self.f0, a + b, e_avg);
        let ms_metal = table.compensation(self.color, a + b, e_avg);
        let spec_dielectric = ms_dielectric * ((1.0 - self.metallic) * below_sheen);
        let spec_metal = ms_metal * (self.metallic * below_sheen);
        let e_dielectric = (self.f0 * a + Vec3::splat(self.f90 * b)) * ms_dielectric;
        let e_metal = (self.color * a + Vec3::splat(b)) * ms_metal;
        let below = (Vec3::ONE - e_dielectric).max(Vec3::ZERO) * ((1.0 - self.metallic) * below_sheen);
        let diffuse = below * self.color * (1.0 - self.transmission);
        let through = below * self.color * self.transmission;
        let albedo = [
            coat_albedo,
            luminance(sheen * sheen_albedo),
            luminance(
                e_dielectric * (1.0 - self.metallic) * below_sheen + e_metal * (self.metallic * below_sheen),
            ),
            luminance(diffuse),
            luminance(through),
        ];
        let total: f32 = albedo.iter().sum();
        let p = match total > 0.0 {
            true => albedo.map(|a| a / total),
            // Black: the base is sampled, and weighs nothing.
            false => [0.0, 0.0, 0.0, 1.0, 0.0],
        };
        Weights { sheen, spec_dielectric, spec_metal, diffuse, through, p }
    }

    fn tag(&self, which: Which) -> Lobe {
        let specular = |rough: bool| if rough { Lobe::Diffuse } else { Lobe::Specular };
        match which {
            Which::Coat => specular(self.coat_rough),
            Which::Sheen | Which::Diffuse => Lobe::Diffuse,
            Which::Specular => specular(self.rough),
            Which::Transmission => Lobe::Delta,
        }
    }

    /// Whether the path is inside a closed transmissive object, where only the dielectric
    /// boundary scatters.
    fn inside(&self) -> bool {
        !self.entering && !self.thin && self.transmission > 0.0
    }

    /// The specular lobe's Fresnel factor at the cosine `cos_h` between view and half vector.
    fn fresnel(&self, w: &Weights, cos_h: f32) -> Vec3 {
        w.spec_dielectric * schlick_to(self.f0, Vec3::splat(self.f90), cos_h)
            + w.spec_metal * schlick_to(self.color, Vec3::ONE, cos_h)
    }

    /// A reflecting lobe's BRDF and sampling density (its probability included), local
    /// directions both above the surface.
    fn lobe_value(&self, which: Which, w: &Weights, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let p = w.p[which as usize];
        match which {
            Which::Coat => {
                let g = self.coat_lobe();
                match self.coat_frame {
                    None => (g.eval_specular(wo, wi) * self.coat, p * g.pdf_specular(wo, wi)),
                    Some(coat) => {
                        // In the coat's frame, its cosine in place of the shading normal's
                        // (which the caller multiplies by): a density is the same in any frame.
                        let to = |v: Vec3| coat.to_local(self.frame.to_world(v));
                        let (cwo, cwi) = (to(wo), to(wi));
                        if cwo.z <= 0.0 || cwi.z <= 0.0 {
                            return (Vec3::ZERO, 0.0);
                        }
                        let f = g.eval_specular(cwo, cwi) * (self.coat * cwi.z / wi.z.max(1e-6));
                        (f, p * g.pdf_specular(cwo, cwi))
                    }
                }
            }
            Which::Sheen => (w.sheen * self.sheen.value(wo, wi), p * self.sheen.pdf(wi)),
            Which::Specular => {
                let g = self.spec_lobe();
                let h = (wo + wi).normalize_or_zero();
                let f = self.fresnel(w, wo.dot(h)) * g.eval_specular(wo, wi).x;
                (f, p * g.pdf_specular(wo, wi))
            }
            Which::Diffuse => match self.base_frame {
                None => (w.diffuse * FRAC_1_PI, p * wi.z * FRAC_1_PI),
                // In its own frame, its cosine in place of the shading normal's.
                Some(base) => match base.to_local(self.frame.to_world(wi)).z {
                    cos if cos > 0.0 => (w.diffuse * (FRAC_1_PI * cos / wi.z.max(1e-6)), p * cos * FRAC_1_PI),
                    _ => (Vec3::ZERO, 0.0),
                },
            },
            Which::Transmission => (Vec3::ZERO, 0.0),
        }
    }

    /// The shadowing of a reflection `wo` -> `r` off a visible microfacet of the specular lobe,
    /// over the lobe's albedo: on average 1 over the reflections that stay above the surface.
    fn shadowing(&self, wo: Vec3, r: Vec3) -> f32 {
        let g = self.spec_lobe();
        let (a, b) = SpecularAlbedo::get().at(wo.z, self.alpha);
        g.g2(wo, r) / g.g1(wo) / (a + b).max(1e-3)
    }

    /// A transmitted direction through a microfacet normal seen from `wo` (local), and its
    /// weight's factor beyond the layer weight: 1 / ior^2 when the light is squeezed into the
    /// denser medium; through a thin wall, the microfacet's shadowing over the lobe's albedo.
    fn transmit(&self, wo: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        let m = self.spec_lobe().visible_normal(wo, u);
        let cos_m = wo.dot(m);
        if cos_m <= 0.0 {
            return None;
        }
        if self.thin {
            // The mirror image of a reflection off the microfacet, weighted by its shadowing
            // and normalised by the lobe's albedo (what reflection off the same facets would
            // keep), so that a clear thin wall passes all the light.
            let r = reflect(wo, m);
            return (r.z > 0.0).then_some((Vec3::new(r.x, r.y, -r.z), self.shadowing(wo, r)));
        }
        let t = refract(wo, m, self.ior, cos_m);
        (t.z < 0.0).then_some((t, 1.0 / (self.ior * self.ior)))
    }

    /// The density of the transmitted directions of [`Principled::sample`] (the lobe's
    /// probability included), at local `wo`, `wt` (below the surface).
    #[cfg(test)]
    pub fn transmission_pdf(&self, wo: Vec3, wt: Vec3) -> f32 {
        let (wo, wt) = (self.frame.to_local(wo), self.frame.to_local(wt));
        if wo.z <= 0.0 || wt.z >= 0.0 || self.inside() {
            return 0.0;
        }
        let p = self.weights(wo).p[Which::Transmission as usize];
        let g = self.spec_lobe();
        if self.thin {
            let r = Vec3::new(wt.x, wt.y, -wt.z);
            return p * g.pdf_specular(wo, r);
        }
        let eta = self.ior;
        let mut h = -(wo + eta * wt).normalize_or_zero();
        if h.z < 0.0 {
            h = -h;
        }
        let (oh, th) = (wo.dot(h), wt.dot(h));
        if oh <= 0.0 || th >= 0.0 {
            return 0.0;
        }
        let visible = g.g1(wo) * oh * g.d(h) / wo.z;
        let jacobian = eta * eta * th.abs() / (oh + eta * th).powi(2);
        p * visible * jacobian
    }

    /// The two ways out of an interaction from inside at the microfacet sampled by `u` from `wo`
    /// (local): the Fresnel reflectance of the facet, the reflection back in with its shadowing
    /// over the lobe's albedo, and the refraction out; either `None` where its direction falls
    /// on the wrong side of the surface (light that would scatter again among the facets).
    fn inside_ways(&self, wo: Vec3, u: Vec2) -> Option<InsideWays> {
        let m = self.spec_lobe().visible_normal(wo, u);
        let cos_m = wo.dot(m);
        if cos_m <= 0.0 {
            return None;
        }
        let eta = 1.0 / self.ior;
        let r = reflect(wo, m);
        let reflected = (r.z > 0.0).then(|| (r, self.shadowing(wo, r)));
        let fresnel = fresnel_dielectric(cos_m, eta);
        let refracted = match fresnel < 1.0 {
            true => Some(refract(wo, m, eta, cos_m)).filter(|t| t.z < 0.0),
            false => None,
        };
        Some(InsideWays { fresnel, reflected, refracted })
    }

    /// Scattering from inside: reflection back in by the dielectric Fresnel at a sampled
    /// microfacet (weighted by its shadowing over the lobe's albedo, so that total internal
    /// reflection keeps all the light), or refraction out, tinted, with the radiance scaling
    /// ior^2 of leaving the denser medium. The light a single facet loses (directions that would
    /// scatter again among the facets: up to a quarter of it for a rough, high index) is
    /// restored by dividing by the interaction's albedo ([`InsideAlbedo`], Turquin's scaling).
    fn sample_inside(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let InsideWays { fresnel, reflected, refracted } = self.inside_ways(wo, u)?;
        let kept = InsideAlbedo::get().at(wo.z, self.alpha, self.ior).max(0.05);
        let (wi, weight) = if u_lobe < fresnel {
            let (r, shadowing) = reflected?;
            (r, Vec3::splat(shadowing / kept))
        } else {
            (refracted?, self.color * (self.ior * self.ior / kept))
        };
        Some(BsdfSample { wi: self.frame.to_world(wi), weight, pdf: 1.0, lobe: Lobe::Delta })
    }
}

/// [`Principled::inside_ways`]: the facet's Fresnel reflectance, the reflection back in (its
/// direction and its shadowing over the lobe's albedo) and the refraction out.
struct InsideWays {
    fresnel: f32,
    reflected: Option<(Vec3, f32)>,
    refracted: Option<Vec3>,
}

/// The albedo of [`Principled::sample_inside`] for a white boundary (the expected weight, the
/// radiance scaling of refraction left out): what one interaction from inside keeps, by view
/// cosine, GGX alpha and index of refraction. Stored as `tables/inside-albedo.bin`
/// (little-endian f32, index by index, alpha row by row, sqrt(cos) column by column), checked
/// against [`InsideAlbedo::build`] by a test.
pub struct InsideAlbedo {
    table: Vec<f32>,
}

impl InsideAlbedo {
    const N: usize = 32;
    /// Indices of refraction from 1 to `MAX_IOR` in `IORS` steps.
    const IORS: usize = 16;
    const MAX_IOR: f32 = 3.0;

    pub fn get() -> &'static InsideAlbedo {
        static TABLE: std::sync::OnceLock<InsideAlbedo> = std::sync::OnceLock::new();
        TABLE.get_or_init(|| InsideAlbedo {
            table: super::stored_table(include_bytes!("tables/inside-albedo.bin")),
        })
    }

    #[cfg(test)]
    pub(super) fn values(&self) -> Vec<f32> {
        self.table.clone()
    }

    /// The table integrated: each cell over a 32x32 grid of visible-normal samples, both ways
    /// out weighted by the Fresnel reflectance.
    #[cfg(test)]
    pub(super) fn build() -> InsideAlbedo {
        let (n, k) = (Self::N, 32);
        let mut table = Vec::with_capacity(n * n * Self::IORS);
        for e in 0..Self::IORS {
            let ior = 1.0 + (Self::MAX_IOR - 1.0) * e as f32 / (Self::IORS - 1) as f32;
            for j in 0..n {
                let r = j as f32 / (n - 1) as f32;
                let b = Principled { alpha: (r * r).max(super::MIN_ALPHA), ior, ..Self::boundary() };
                for i in 0..n {
                    let x = i as f32 / (n - 1) as f32;
                    let cos = (x * x).max(1e-4);
                    let wo = Vec3::new((1.0 - cos * cos).max(0.0).sqrt(), 0.0, cos);
                    let mut sum = 0.0f64;
                    for a in 0..k {
                        for c in 0..k {
                            let u = Vec2::new((a as f32 + 0.5) / k as f32, (c as f32 + 0.5) / k as f32);
                            if let Some(w) = b.inside_ways(wo, u) {
                                sum += (w.fresnel * w.reflected.map_or(0.0, |(_, s)| s)) as f64;
                                sum += ((1.0 - w.fresnel) * w.refracted.map_or(0.0, |_| 1.0)) as f64;
                            }
                        }
                    }
                    table.push((sum / (k * k) as f64) as f32);
                }
            }
        }
        InsideAlbedo { table }
    }

    /// A clear boundary seen from inside, for [`InsideAlbedo::build`].
    #[cfg(test)]
    fn boundary() -> Principled {
        Principled {
            frame: Frame::new(Vec3::Z),
            coat_frame: None,
            base_frame: None,
            entering: false,
            color: Vec3::ONE,
            metallic: 0.0,
            alpha: 0.1,
            f0: Vec3::splat(0.04),
            f90: 1.0,
            transmission: 1.0,
            ior: 1.5,
            thin: false,
            coat: 0.0,
            coat_alpha: 0.1,
            sheen: SheenLobe::new(Vec3::ZERO, 0.5),
            sheen_roughness: 0.5,
            rough: false,
            coat_rough: false,
        }
    }

    /// The albedo at view cosine `cos`, GGX alpha `alpha` and index `ior`, trilinearly.
    pub fn at(&self, cos: f32, alpha: f32, ior: f32) -> f32 {
        let (n, m) = (Self::N, Self::IORS);
        let coord = |v: f32, cells: usize| {
            let x = (v * (cells - 1) as f32).clamp(0.0, (cells - 1) as f32 - 1e-4);
            (x as usize, x - x.floor())
        };
        let (i, fx) = coord(cos.clamp(0.0, 1.0).sqrt(), n);
        let (j, fy) = coord(alpha.clamp(0.0, 1.0).sqrt(), n);
        let (e, fz) = coord((ior - 1.0) / (Self::MAX_IOR - 1.0), m);
        let t = |i: usize, j: usize, e: usize| self.table.get((e * n + j) * n + i).copied().unwrap_or(1.0);
        let lerp = |p: f32, q: f32, f: f32| p + (q - p) * f;
        let plane = |e: usize| {
            lerp(lerp(t(i, j, e), t(i + 1, j, e), fx), lerp(t(i, j + 1, e), t(i + 1, j + 1, e), fx), fy)
        };
        lerp(plane(e), plane(e + 1), fz)
    }
}

impl Bsdf for Principled {
    fn lobe(&self) -> Option<Lobe> {
        self.inside().then_some(Lobe::Delta)
    }

    fn scatters(&self, wo: Vec3) -> bool {
        self.frame.to_local(wo).z > 0.0
    }

    fn kinds(&self) -> Kinds {
        match self.lobe() {
            Some(l) => Kinds::of(l),
            None => LOBES.iter().fold(Kinds::default(), |k, &w| k.with(self.tag(w))),
        }
    }

    fn albedo(&self, lobe: Lobe) -> Vec3 {
        if self.inside() {
            return if lobe == Lobe::Delta { self.color } else { Vec3::ZERO };
        }
        let w = self.weights(Vec3::Z);
        let mut albedo = Vec3::ZERO;
        for which in LOBES {
            if self.tag(which) == lobe {
                albedo += match which {
                    Which::Coat => Vec3::splat(self.coat * COAT_F0),
                    Which::Sheen => w.sheen,
                    Which::Specular => w.spec_dielectric * self.f0 + w.spec_metal * self.color,
                    Which::Diffuse => w.diffuse,
                    Which::Transmission => w.through,
                };
            }
        }
        albedo
    }

    fn sample(&self, wo: Vec3, u: &mut Sampler) -> Option<BsdfSample> {
        let wo_l = self.frame.to_local(wo);
        if wo_l.z <= 0.0 {
            return None;
        }
        let (u_lobe, u2) = (u.get_1d(Dim::Lobe), u.get_2d(Dim::Direction));
        if self.inside() {
            return self.sample_inside(wo_l, u_lobe, u2);
        }
        let w = self.weights(wo_l);
        let mut which = Which::Diffuse;
        let mut sum = 0.0;
        for lobe in LOBES {
            sum += w.p[lobe as usize];
            if w.p[lobe as usize] > 0.0 {
                which = lobe;
                if u_lobe < sum {
                    break;
                }
            }
        }
        let p = w.p[which as usize];
        if p <= 0.0 {
            return None;
        }
        let wi = match which {
            Which::Coat => match self.coat_frame {
                None => self.coat_lobe().sample_specular(wo_l, u2),
                Some(coat) => {
                    let cwo = coat.to_local(wo);
                    if cwo.z <= 0.0 {
                        return None;
                    }
                    self.frame.to_local(coat.to_world(self.coat_lobe().sample_specular(cwo, u2)))
                }
            },
            Which::Specular => self.spec_lobe().sample_specular(wo_l, u2),
            Which::Sheen => cosine_hemisphere(u2),
            Which::Diffuse => match self.base_frame {
                None => cosine_hemisphere(u2),
                Some(base) => self.frame.to_local(base.to_world(cosine_hemisphere(u2))),
            },
            Which::Transmission => {
                let (wt, scale) = self.transmit(wo_l, u2)?;
                let weight = w.through * (scale / p);
                return Some(BsdfSample { wi: self.frame.to_world(wt), weight, pdf: 1.0, lobe: Lobe::Delta });
            }
        };
        if wi.z <= 0.0 {
            return None;
        }
        let (f, pdf) = self.lobe_value(which, &w, wo_l, wi);
        if pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample { wi: self.frame.to_world(wi), weight: f * (wi.z / pdf), pdf, lobe: self.tag(which) })
    }

    fn eval_lobes(&self, wo: Vec3, wi: Vec3, mut each: impl FnMut(Lobe, Vec3, f32)) {
        let (wo, wi) = (self.frame.to_local(wo), self.frame.to_local(wi));
        if self.inside() || wo.z <= 0.0 || wi.z <= 0.0 {
            return;
        }
        let w = self.weights(wo);
        for which in [Which::Coat, Which::Sheen, Which::Specular, Which::Diffuse] {
            if w.p[which as usize] > 0.0 {
                let (f, pdf) = self.lobe_value(which, &w, wo, wi);
                each(self.tag(which), f, pdf);
            }
        }
    }
}
