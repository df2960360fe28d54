//! Every material's scattering behind one interface, as pbrt-v4's `BSDF` and Mitsuba 3's
//! `BSDFFlags`: a material is one type, in a file of its own here, implementing [`Bsdf`], and
//! every lobe it samples or evaluates carries a [`Lobe`] tag (D, S or delta) from which the
//! path's component class alone is updated. The path integrator never names a material;
//! [`super::material`] turns a scene's material into its BSDF. Adding a material is a file here
//! and one arm there.
//!
//! Directions are in world space, unit, pointing away from the surface; a BSDF is built at one
//! shading point with its shading normal already on the side the path arrived from.

mod conductor;
mod dielectric;
mod diffuse;
mod ggx;
mod glass;
mod glossy;
pub mod microfacet;
mod mirror;
mod pbr;
pub mod plastic;
mod principled;
mod rough_dielectric;
mod sheen;
#[cfg(test)]
mod tests;

pub use conductor::Conductor;
pub use dielectric::Dielectric;
pub use diffuse::Diffuse;
pub use ggx::{GlossyLobes, SpecularAlbedo};
pub use glass::Glass;
pub use glossy::Glossy;
pub use mirror::Mirror;
pub use pbr::Pbr;
pub use plastic::Plastic;
pub use principled::{dielectric_f0, InsideAlbedo, Principled};
pub use rough_dielectric::RoughDielectric;
pub use sheen::SheenLobe;

use glam::Vec3;

use super::sampler::Sampler;

/// The smallest GGX alpha: below it the lobe is a mirror for every practical purpose and its
/// density overflows f32 near the peak.
pub const MIN_ALPHA: f32 = 1e-3;

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
    /// Specular-like (S) that light sampling cannot see: in one direction only (a mirror,
    /// glass), or through the surface (transmission, which next-event estimation never
    /// reaches). Emission found after it takes no MIS weight.
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

/// A set of lobe kinds ([`Bsdf::kinds`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Kinds(u8);

impl Kinds {
    pub fn of(lobe: Lobe) -> Kinds {
        Kinds(1 << lobe as u8)
    }

    pub fn with(self, lobe: Lobe) -> Kinds {
        Kinds(self.0 | 1 << lobe as u8)
    }

    /// The kinds in the set, in [`Lobe`] order.
    pub fn iter(self) -> impl Iterator<Item = Lobe> {
        [Lobe::Diffuse, Lobe::Specular, Lobe::Delta].into_iter().filter(move |&l| self.0 & 1 << l as u8 != 0)
    }
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

    /// The kinds of its lobes, whose albedos ([`Bsdf::albedo`]) light path expressions' `A`
    /// events report: its one kind, or (several lobes) a diffuse base and a glossy lobe.
    fn kinds(&self) -> Kinds {
        self.lobe().map_or(Kinds::of(Lobe::Diffuse).with(Lobe::Specular), Kinds::of)
    }

    /// The albedo of all its lobes of kind `kind`, which an `A` event reports (by default
    /// [`Bsdf::albedo`]).
    fn kind_albedo(&self, kind: Lobe) -> Vec3 {
        self.albedo(kind)
    }

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

/// Nothing: the back of a one-sided material, where a path ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Black;

impl Bsdf for Black {
    fn lobe(&self) -> Option<Lobe> {
        Some(Lobe::Diffuse)
    }

    fn scatters(&self, _wo: Vec3) -> bool {
        false
    }

    fn albedo(&self, _: Lobe) -> Vec3 {
        Vec3::ZERO
    }

    fn sample(&self, _wo: Vec3, _u: &mut Sampler) -> Option<BsdfSample> {
        None
    }
}

/// A stored table's little-endian f32 values.
fn stored_table(bytes: &[u8]) -> Vec<f32> {
    bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
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
