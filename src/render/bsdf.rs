//! Every material's scattering behind one interface, as pbrt-v4's `BSDF` and Mitsuba 3's
//! `BSDFFlags`: a material is one type here implementing [`Bsdf`], and every lobe it samples or
//! evaluates carries a [`Lobe`] tag (D, S or delta) from which the path's component class alone
//! is updated. The path integrator never names a material; adding one means adding its type
//! here and an arm of [`with_bsdf`], which hands the integrator each material's type.
//!
//! The glossy model: a GGX microfacet lobe (Walter et al. 2007, "Microfacet Models for
//! Refraction through Rough Surfaces") with Schlick's Fresnel and the height-correlated
//! shadowing-masking term, sampled by its distribution of visible normals (Heitz 2018, "Sampling
//! the GGX Distribution of Visible Normals"), over an optional diffuse base: Ashikhmin and
//! Shirley's coupled diffuse term (2000, "An Anisotropic Phong BRDF Model"), which is reciprocal
//! and gives the base only the light the coating lets through.
//!
//! Directions are in world space, unit, pointing away from the surface; a BSDF is built at one
//! shading point with its shading normal already on the side the path arrived from.

use std::f32::consts::{FRAC_1_PI, PI, TAU};

use glam::{Vec2, Vec3};

use super::sampler::{Dim, Sampler};
use crate::math::{cosine_hemisphere, luminance, Frame};

/// The smallest GGX alpha: below it the lobe is a mirror for every practical purpose and its
/// density overflows f32 near the peak.
pub const MIN_ALPHA: f32 = 1e-3;

/// The roughness from which a metallic-roughness material's GGX lobe counts as a D vertex in the
/// component split (its light then goes to the filtered indirect-diffuse component): chosen by
/// measurement (`docs/scene-format.md`, "glTF files"): on `scenes/gltf-hdri.toml` (roughness 0.2,
/// 0.35, 0.5 and 0.9), every lobe counted D gave the lowest error at 16, 64 and 256 spp with
/// the paper's box filter and with the à-trous one.
pub const DIFFUSE_ROUGHNESS: f32 = 0.2;

/// GGX alpha of a perceptual roughness in [0, 1] (squared, as Burley's and glTF's models do).
pub fn alpha(roughness: f32) -> f32 {
    (roughness * roughness).max(MIN_ALPHA)
}

/// What kind of vertex a lobe makes in the paper's component split (Heckbert's notation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lobe {
    /// Diffuse-like (D): Lambertian reflection, a glossy surface's base.
    Diffuse,
    /// Specular-like (S) with a density: a glossy surface's GGX lobe. Light sampling sees it.
    Specular,
    /// Specular-like (S) in one direction only: a mirror, glass. Light sampling cannot see it,
    /// and emission found after it takes no MIS weight.
    Delta,
}

impl Lobe {
    /// Whether the component split counts it as an S vertex.
    pub fn is_specular(self) -> bool {
        self != Lobe::Diffuse
    }

    pub fn is_delta(self) -> bool {
        self == Lobe::Delta
    }
}

/// A direction a BSDF sampled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    pub wi: Vec3,
    /// f cos / pdf: what the path throughput is multiplied by.
    pub weight: Vec3,
    /// The density in solid angle of sampling `wi` (the chosen lobe's probability included);
    /// 1 for a delta lobe, where it has no meaning.
    pub pdf: f32,
    pub lobe: Lobe,
}

/// One material's scattering at one shading point.
pub trait Bsdf {
    /// The kind of every direction it scatters into, when it has one kind; `None` when it has
    /// several lobes, whose kind is known only once a direction has been sampled.
    fn lobe(&self) -> Option<Lobe>;

    /// Whether any light leaves toward `wo` at all; when not, the path ends here.
    fn scatters(&self, _wo: Vec3) -> bool {
        true
    }

    /// The colour a lobe reflects, for the albedo guide buffer.
    fn albedo(&self, lobe: Lobe) -> Vec3;

    /// A direction toward which light arriving along `-wo` leaves, or `None` when none can be
    /// used. Draws from `u` only the numbers it needs (a mirror none), so the dimensions a path
    /// uses depend only on the surfaces it meets.
    fn sample(&self, wo: Vec3, u: &mut Sampler) -> Option<BsdfSample>;

    /// The BSDF value `f` and sampling density `pdf` of each non-delta lobe for light arriving
    /// from `wi` and leaving toward `wo`, handed to `each` lobe by lobe (nothing for a delta
    /// BSDF): light sampling needs them apart, since each lobe makes its own component.
    fn eval_lobes(&self, _wo: Vec3, _wi: Vec3, _each: impl FnMut(Lobe, Vec3, f32)) {}

    /// The whole BSDF value, all lobes together.
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let mut f = Vec3::ZERO;
        self.eval_lobes(wo, wi, |_, lobe_f, _| f += lobe_f);
        f
    }

    /// The density of [`Bsdf::sample`] choosing `wi`, all lobes together.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let mut pdf = 0.0;
        self.eval_lobes(wo, wi, |_, _, lobe_pdf| pdf += lobe_pdf);
        pdf
    }
}

/// The mirror direction of `wo` about `n`.
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    2.0 * wo.dot(n) * n - wo
}

/// The refracted direction of `wo` (on `n`'s side, cos_i = n.wo) through a boundary with index
/// ratio `eta` (transmitted over incident); only called below total internal reflection.
pub fn refract(wo: Vec3, n: Vec3, eta: f32, cos_i: f32) -> Vec3 {
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    (-wo / eta + (cos_i / eta - cos_t) * n).normalize()
}

/// Unpolarised Fresnel reflectance of a dielectric boundary (1 under total internal reflection).
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    0.5 * (rs * rs + rp * rp)
}

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

    fn sample(&self, _wo: Vec3, u: &mut Sampler) -> Option<BsdfSample> {
        let local = cosine_hemisphere(u.get_2d(Dim::Direction));
        let wi = Frame::new(self.n).to_world(local);
        // f cos / pdf of a Lambertian lobe is its albedo.
        Some(BsdfSample { wi, weight: self.albedo, pdf: local.z * FRAC_1_PI, lobe: Lobe::Diffuse })
    }

    fn eval_lobes(&self, _wo: Vec3, wi: Vec3, mut each: impl FnMut(Lobe, Vec3, f32)) {
        let cos = self.n.dot(wi);
        if cos > 0.0 {
            each(Lobe::Diffuse, self.albedo * FRAC_1_PI, cos * FRAC_1_PI);
        }
    }
}

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

/// Evaluates `$body` with `$b` bound to (a reference to) the BSDF of the scene material
/// `$material` at a shading point with normal `$n` (on the side the path arrived from),
/// `$entering` when it arrived from the outside; `$color` maps a textured material's constant
/// colour to its texture's, `$metal_rough` a metallic-roughness material's factors (metallic,
/// roughness) to the textured ones. Each material's BSDF is its own type, so code generic over [`Bsdf`]
/// is compiled once per material and the material is chosen once, here. A new material is a
/// new type above and one arm here.
macro_rules! with_bsdf {
    ($material:expr, $color:expr, $metal_rough:expr, $n:expr, $entering:expr, $b:ident => $body:expr) => {{
        use $crate::render::bsdf::{Diffuse, Glass, Glossy, GlossyLobes, Mirror, Pbr};
        use $crate::scene::Material;
        let (n, entering) = ($n, $entering);
        match *$material {
            Material::Diffuse { albedo } => {
                let $b = &Diffuse { albedo: ($color)(albedo), n };
                $body
            }
            Material::Mirror { color } => {
                let $b = &Mirror { color, n };
                $body
            }
            Material::Glass { ior, color } => {
                let $b = &Glass { ior, color, n, entering };
                $body
            }
            Material::Glossy { specular, roughness, base } => {
                let lobes = GlossyLobes {
                    specular,
                    alpha: $crate::render::bsdf::alpha(roughness),
                    base: ($color)(base),
                };
                let $b = &Glossy { lobes, frame: $crate::math::Frame::new(n) };
                $body
            }
            Material::Pbr { base_color, metallic, roughness, diffuse_from } => {
                let (metallic, roughness): (f32, f32) = ($metal_rough)(metallic, roughness);
                let color: glam::Vec3 = base_color * ($color)(glam::Vec3::ONE);
                let lobes = GlossyLobes {
                    specular: glam::Vec3::splat(0.04).lerp(color, metallic),
                    alpha: $crate::render::bsdf::alpha(roughness),
                    base: glam::Vec3::ZERO,
                };
                let $b = &Pbr {
                    lobes,
                    base: color * (1.0 - metallic),
                    frame: $crate::math::Frame::new(n),
                    rough: roughness >= diffuse_from,
                };
                $body
            }
        }
    }};
}
pub(crate) use with_bsdf;

/// glTF's metallic-roughness material, layered as Blender's Principled BSDF and the glTF
/// specification's dielectric layer are: the GGX lobe (reflectance `specular` at normal
/// incidence, Schlick's Fresnel) over a Lambertian base that receives what the lobe does not
/// reflect, `base / pi` times 1 - E(wo), E being the lobe's directional albedo (from
/// [`SpecularAlbedo`]). The GGX lobe is an S vertex, or a D vertex when `rough` (its roughness at
/// least the material's `diffuse_from`); the base is D.
#[derive(Clone, Copy, Debug)]
pub struct Pbr {
    /// The GGX lobe (its `base` unused: the base is Lambertian here).
    pub lobes: GlossyLobes,
    pub base: Vec3,
    pub frame: Frame,
    pub rough: bool,
}

impl Pbr {
    /// The lobe a GGX sample makes in the split.
    fn tag(&self) -> Lobe {
        if self.rough {
            Lobe::Diffuse
        } else {
            Lobe::Specular
        }
    }

    /// The GGX lobe's directional albedo seen from `wo` (local).
    fn specular_albedo(&self, wo: Vec3) -> Vec3 {
        let (a, b) = SpecularAlbedo::get().at(wo.z, self.lobes.alpha);
        self.lobes.specular * a + Vec3::splat(b)
    }

    /// The base's weight seen from `wo` (local): 1 - the GGX lobe's directional albedo.
    fn through(&self, wo: Vec3) -> Vec3 {
        (Vec3::ONE - self.specular_albedo(wo)).max(Vec3::ZERO)
    }

    /// The probability of sampling the GGX lobe from `wo` (local): in proportion to what each
    /// reflects.
    fn specular_probability(&self, wo: Vec3) -> f32 {
        let e = self.specular_albedo(wo);
        let spec = luminance(e);
        let base = luminance(self.base * (Vec3::ONE - e).max(Vec3::ZERO));
        if base <= 0.0 {
            1.0
        } else if spec <= 0.0 {
            0.0
        } else {
            spec / (spec + base)
        }
    }

    fn eval_base(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        self.base * self.through(wo) * FRAC_1_PI
    }
}

impl Bsdf for Pbr {
    fn lobe(&self) -> Option<Lobe> {
        self.rough.then_some(Lobe::Diffuse)
    }

    fn scatters(&self, wo: Vec3) -> bool {
        self.frame.to_local(wo).z > 0.0
    }

    fn albedo(&self, lobe: Lobe) -> Vec3 {
        if self.rough {
            self.base + self.lobes.specular
        } else if lobe == Lobe::Diffuse {
            self.base
        } else {
            self.lobes.specular
        }
    }

    fn sample(&self, wo: Vec3, u: &mut Sampler) -> Option<BsdfSample> {
        let g = &self.lobes;
        let wo_l = self.frame.to_local(wo);
        let p_spec = self.specular_probability(wo_l);
        let (wi_l, specular) = if u.get_1d(Dim::Lobe) < p_spec {
            (g.sample_specular(wo_l, u.get_2d(Dim::Direction)), true)
        } else {
            (cosine_hemisphere(u.get_2d(Dim::Direction)), false)
        };
        if wi_l.z <= 0.0 {
            return None;
        }
        let (weight, pdf, lobe) = if specular {
            (g.specular_weight(wo_l, wi_l) / p_spec, p_spec * g.pdf_specular(wo_l, wi_l), self.tag())
        } else {
            let pdf = (1.0 - p_spec) * wi_l.z * FRAC_1_PI;
            (self.eval_base(wo_l, wi_l) * (wi_l.z / pdf), pdf, Lobe::Diffuse)
        };
        Some(BsdfSample { wi: self.frame.to_world(wi_l), weight, pdf, lobe })
    }

    fn eval_lobes(&self, wo: Vec3, wi: Vec3, mut each: impl FnMut(Lobe, Vec3, f32)) {
        let g = &self.lobes;
        let (wo_l, wi_l) = (self.frame.to_local(wo), self.frame.to_local(wi));
        let p_spec = self.specular_probability(wo_l);
        each(self.tag(), g.eval_specular(wo_l, wi_l), p_spec * g.pdf_specular(wo_l, wi_l));
        each(Lobe::Diffuse, self.eval_base(wo_l, wi_l), (1.0 - p_spec) * wi_l.z.max(0.0) * FRAC_1_PI);
    }
}

/// The directional albedo of a GGX lobe with Schlick's Fresnel, split as f0 A + B (the
/// "split-sum" table of real-time rendering): A and B by the cosine of the view and the GGX
/// alpha, 32 x 32 cells, integrated once by sampling visible normals (256 stratified points a
/// cell) and read bilinearly.
pub struct SpecularAlbedo {
    table: Vec<(f32, f32)>,
}

impl SpecularAlbedo {
    const N: usize = 32;

    /// The table, built on first use.
    pub fn get() -> &'static SpecularAlbedo {
        static TABLE: std::sync::OnceLock<SpecularAlbedo> = std::sync::OnceLock::new();
        TABLE.get_or_init(SpecularAlbedo::build)
    }

    fn build() -> SpecularAlbedo {
        let n = Self::N;
        let mut table = Vec::with_capacity(n * n);
        for j in 0..n {
            let alpha = (j as f32 / (n - 1) as f32).max(MIN_ALPHA);
            for i in 0..n {
                let cos = (i as f32 / (n - 1) as f32).max(1e-3);
                let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                let g = GlossyLobes { specular: Vec3::ONE, alpha, base: Vec3::ZERO };
                let (mut a, mut b) = (0.0f64, 0.0f64);
                let k = 16;
                for s in 0..k * k {
                    let u = Vec2::new(((s % k) as f32 + 0.5) / k as f32, ((s / k) as f32 + 0.5) / k as f32);
                    let wi = g.sample_specular(wo, u);
                    if wi.z <= 0.0 {
                        continue;
                    }
                    let h = (wo + wi).normalize_or_zero();
                    let w = (g.g2(wo, wi) / g.g1(wo)) as f64;
                    let m = (1.0 - wo.dot(h)).clamp(0.0, 1.0) as f64;
                    let fresnel = m.powi(5);
                    a += w * (1.0 - fresnel);
                    b += w * fresnel;
                }
                let total = (k * k) as f64;
                table.push(((a / total) as f32, (b / total) as f32));
            }
        }
        SpecularAlbedo { table }
    }

    /// (A, B) at view cosine `cos` and alpha `alpha`, bilinearly.
    pub fn at(&self, cos: f32, alpha: f32) -> (f32, f32) {
        let n = Self::N;
        let x = (cos.clamp(0.0, 1.0) * (n - 1) as f32).min((n - 1) as f32 - 1e-4);
        let y = (alpha.clamp(0.0, 1.0) * (n - 1) as f32).min((n - 1) as f32 - 1e-4);
        let (i, j) = (x as usize, y as usize);
        let (fx, fy) = (x - i as f32, y - j as f32);
        let t = |i: usize, j: usize| self.table[j * n + i];
        let lerp = |p: (f32, f32), q: (f32, f32), f: f32| (p.0 + (q.0 - p.0) * f, p.1 + (q.1 - p.1) * f);
        lerp(lerp(t(i, j), t(i + 1, j), fx), lerp(t(i, j + 1), t(i + 1, j + 1), fx), fy)
    }
}

/// The glossy model in the local shading frame (z along the normal): a GGX lobe with
/// reflectance `specular` at normal incidence, over a diffuse `base`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlossyLobes {
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

impl GlossyLobes {
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

    /// The density of [`GlossyLobes::sample_specular`] in solid angle (defined below the horizon
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

    /// The density of [`GlossyLobes::sample`], both lobes together.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let p = self.specular_probability(wo);
        p * self.pdf_specular(wo, wi) + (1.0 - p) * self.pdf_base(wi)
    }

    /// Picks a lobe with `u_lobe`, then a direction from it.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> (Vec3, Lobe) {
        if u_lobe < self.specular_probability(wo) {
            (self.sample_specular(wo, u), Lobe::Specular)
        } else {
            (self.sample_base(u), Lobe::Diffuse)
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

    /// Checks a non-delta BSDF through the interface the integrator uses, at normal `n`: the
    /// directions `sample` gives follow `pdf` (restricted to above the surface, where `sample`
    /// gives directions), and each sample's pdf and weight are its lobe's pdf and f cos / pdf.
    fn check_through_the_interface<B: Bsdf>(name: &str, b: &B, wo: Vec3, n: Vec3) {
        let z =
            z_score(|s| b.sample(wo, s).map(|bs| bs.wi), |d| if n.dot(d) > 0.0 { b.pdf(wo, d) } else { 0.0 });
        assert!(z < 4.0, "{name}: z = {z}");
        let mut s = crate::render::sampler::Sampler::new(3, 1, 4);
        let mut checked = 0;
        for _ in 0..2000 {
            let Some(bs) = b.sample(wo, &mut s) else { continue };
            let cos = n.dot(bs.wi);
            if cos <= 1e-3 || bs.pdf <= 1e-3 {
                continue;
            }
            let mut lobe = None;
            b.eval_lobes(wo, bs.wi, |l, f, pdf| {
                if l == bs.lobe {
                    lobe = Some((f, pdf));
                }
            });
            let Some((f, pdf)) = lobe else { panic!("{name}: sampled lobe {:?} has no value", bs.lobe) };
            assert!((bs.pdf - pdf).abs() <= 1e-3 * pdf, "{name}: pdf {} vs {pdf}", bs.pdf);
            let weight = f * cos / pdf;
            let tolerance = 1e-3 * (1.0 + weight.max_element());
            assert!(
                (bs.weight - weight).abs().max_element() <= tolerance,
                "{name}: {} vs {weight}",
                bs.weight
            );
            checked += 1;
        }
        assert!(checked > 1000, "{name}: {checked} samples checked");
    }

    #[test]
    fn diffuse_and_glossy_sample_their_density_at_a_tilted_normal() {
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let wo = Vec3::new(-0.2, 0.4, 0.9).normalize();
        check_through_the_interface("diffuse", &Diffuse { albedo: Vec3::new(0.7, 0.5, 0.2), n }, wo, n);
        let lobes = GlossyLobes { specular: Vec3::splat(0.04), alpha: 0.3, base: Vec3::new(0.6, 0.3, 0.2) };
        check_through_the_interface("glossy", &Glossy { lobes, frame: Frame::new(n) }, wo, n);
    }

    #[test]
    fn a_wrong_density_through_the_interface_fails() {
        // The check has power: a Lambertian judged by a density tilted the other way fails.
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let wo = n;
        let b = Diffuse { albedo: Vec3::ONE, n };
        let other = Diffuse { n: Vec3::new(-0.3, -0.5, 0.8).normalize(), ..b };
        let z = z_score(
            |s| b.sample(wo, s).map(|bs| bs.wi),
            |d| if n.dot(d) > 0.0 { other.pdf(wo, d) } else { 0.0 },
        );
        assert!(z > 10.0, "z = {z}");
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
            let g = GlossyLobes { specular: Vec3::splat(0.9), alpha, base: Vec3::ZERO };
            let wo = wo(theta);
            let z = z_score(|s| Some(g.sample_specular(wo, s.next_2d())), |d| g.pdf_specular(wo, d));
            assert!(z < 4.0, "alpha {alpha}, theta {theta}: z = {z}");
        }
    }

    #[test]
    fn both_lobes_together_match_the_mixture_density() {
        let g = GlossyLobes { specular: Vec3::splat(0.04), alpha: 0.4, base: Vec3::new(0.7, 0.2, 0.1) };
        let wo = wo(45.0);
        let p = g.specular_probability(wo);
        assert!(p > 0.0 && p < 1.0, "{p}");
        let z = z_score(|s| Some(g.sample(wo, s.next_1d(), s.next_2d()).0), |d| g.pdf(wo, d));
        assert!(z < 4.0, "z = {z}");
    }

    #[test]
    fn a_wrong_ggx_density_fails() {
        // The test has power: a lobe judged by the density of a rougher one must fail.
        let g = GlossyLobes { specular: Vec3::ONE, alpha: 0.3, base: Vec3::ZERO };
        let rough = GlossyLobes { alpha: 0.36, ..g };
        let wo = wo(30.0);
        let z = z_score(|s| Some(g.sample_specular(wo, s.next_2d())), |d| rough.pdf_specular(wo, d));
        assert!(z > 10.0, "z = {z}");
    }

    #[test]
    fn the_sampling_weight_is_f_cos_over_pdf() {
        let g = GlossyLobes { specular: Vec3::new(0.9, 0.5, 0.2), alpha: 0.25, base: Vec3::ZERO };
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
            let g = GlossyLobes { specular: Vec3::splat(f0), alpha, base };
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
        let g = GlossyLobes { specular: Vec3::splat(0.04), alpha: 0.3, base: Vec3::ONE };
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

    #[test]
    fn fresnel_at_normal_incidence_grazing_and_beyond_the_critical_angle() {
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert!((fresnel_dielectric(1e-4, 1.5) - 1.0).abs() < 1e-2);
        // From inside glass (eta = 1/1.5) beyond asin(1/1.5) = 41.8 degrees: total reflection.
        assert_eq!(fresnel_dielectric(43f32.to_radians().cos(), 1.0 / 1.5), 1.0);
        assert!(fresnel_dielectric(40f32.to_radians().cos(), 1.0 / 1.5) < 1.0);
        // The same boundary crossed either way reflects the same fraction.
        for cos_i in [0.2f32, 0.5, 0.9] {
            let sin_t = (1.0 - cos_i * cos_i).sqrt() / 1.5;
            let cos_t = (1.0 - sin_t * sin_t).sqrt();
            assert!((fresnel_dielectric(cos_i, 1.5) - fresnel_dielectric(cos_t, 1.0 / 1.5)).abs() < 1e-5);
        }
    }

    /// Mirror and glass are delta BSDFs: reciprocity means each specular map is reversible (the
    /// light can run the path backwards) with the same weight. Reflection is an involution; a
    /// refracted direction refracted back from the other side is the incident one; and Fresnel
    /// reflectance is the same from both sides of a boundary (Stokes), so the transmitted
    /// weights (1 - F) / eta^2 and (1 - F) eta^2 of the two directions differ exactly by the
    /// radiance scaling 1 / eta^2 that makes the pair adjoint.
    #[test]
    fn mirror_and_glass_are_reciprocal() {
        let n = Vec3::Z;
        let mut s = crate::render::sampler::Sampler::new(9, 9, 9);
        let mut refracted = 0;
        for _ in 0..2000 {
            let wo = cosine_hemisphere(s.next_2d());
            let wr = reflect(wo, n);
            assert!((reflect(wr, n) - wo).length() < 1e-5 && (wr.z - wo.z).abs() < 1e-6, "{wo}");
            for eta in [1.5f32, 1.0 / 1.5, 2.42, 1.0 / 1.33] {
                let cos_i = wo.z;
                let f = fresnel_dielectric(cos_i, eta);
                if f >= 1.0 {
                    continue; // total internal reflection: only the mirror map, tested above
                }
                refracted += 1;
                let wt = refract(wo, n, eta, cos_i);
                // Backwards: wt, now the direction away from the surface on the other side.
                let cos_t = wt.dot(-n);
                let back = refract(wt, -n, 1.0 / eta, cos_t);
                assert!((back - wo).length() < 1e-4, "eta {eta}: {wo} -> {wt} -> {back}");
                let f_back = fresnel_dielectric(cos_t, 1.0 / eta);
                assert!((f - f_back).abs() < 1e-4, "eta {eta}, cos {cos_i}: F {f} vs {f_back}");
            }
        }
        assert!(refracted > 6000, "{refracted} refractions tested");
    }

    #[test]
    fn refraction_obeys_snell() {
        let n = Vec3::Z;
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let wt = refract(wo, n, 1.5, wo.dot(n));
        let sin_i = 0.6;
        let sin_t = (1.0 - wt.z * wt.z).sqrt();
        assert!((sin_i - 1.5 * sin_t).abs() < 1e-5, "{wt}");
        assert!(wt.z < 0.0 && wt.x < 0.0, "goes through, on the far side of the normal: {wt}");
        assert!((reflect(wo, n) - Vec3::new(-0.6, 0.0, 0.8)).length() < 1e-6);
    }

    /// The metallic-roughness BSDF samples what it evaluates; its GGX lobe is tagged S when
    /// smooth and D when rough, the values and densities unchanged; and it conserves energy: a
    /// white dielectric reflects all the light (the base takes what the lobe does not), within
    /// the loss of GGX's single scattering.
    #[test]
    fn the_pbr_bsdf_samples_its_density_tags_its_lobe_and_keeps_energy() {
        let lobes = GlossyLobes { specular: Vec3::splat(0.04), alpha: alpha(0.7), base: Vec3::ZERO };
        let pbr = |base: Vec3, rough: bool| Pbr { lobes, base, frame: Frame::new(Vec3::Z), rough };
        let (smooth, rough) = (pbr(Vec3::splat(0.5), false), pbr(Vec3::splat(0.5), true));
        for theta in [10.0, 45.0, 75.0] {
            check_through_the_interface("smooth pbr", &smooth, wo(theta), Vec3::Z);
        }
        assert_eq!((smooth.lobe(), rough.lobe()), (None, Some(Lobe::Diffuse)));
        let mut s = crate::render::sampler::Sampler::new(5, 2, 1);
        let (mut specular, mut diffuse) = (0, 0);
        for _ in 0..500 {
            let mut t = s.clone();
            let (a, b) = (smooth.sample(wo(35.0), &mut s), rough.sample(wo(35.0), &mut t));
            let (Some(a), Some(b)) = (a, b) else { continue };
            assert_eq!((a.wi, a.weight, a.pdf), (b.wi, b.weight, b.pdf));
            assert_eq!(b.lobe, Lobe::Diffuse);
            match a.lobe {
                Lobe::Specular => specular += 1,
                _ => diffuse += 1,
            }
            let (mut fa, mut fb) = (Vec3::ZERO, Vec3::ZERO);
            smooth.eval_lobes(wo(35.0), a.wi, |_, f, _| fa += f);
            rough.eval_lobes(wo(35.0), a.wi, |l, f, _| {
                assert_eq!(l, Lobe::Diffuse);
                fb += f
            });
            assert_eq!(fa, fb);
        }
        assert!(specular > 10 && diffuse > 100, "both lobes sampled: {specular} S, {diffuse} D");
        // A white base under the dielectric lobe: the albedo (the mean sample weight) is one
        // at every angle, the lobe's and the base's shares summing to it.
        let white = pbr(Vec3::ONE, false);
        for theta in [0.0, 40.0, 70.0, 85.0] {
            let mut s = crate::render::sampler::Sampler::new(9, 1, 3);
            let n = 40_000;
            let total: f32 = (0..n).filter_map(|_| white.sample(wo(theta), &mut s)).map(|b| b.weight.x).sum();
            let albedo = total / n as f32;
            assert!((albedo - 1.0).abs() < 0.02, "albedo {albedo} at {theta} degrees");
        }
    }
}
