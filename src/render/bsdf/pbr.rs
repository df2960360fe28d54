//! glTF's metallic-roughness material, as Blender's Principled BSDF and the glTF specification
//! layer it: a GGX lobe over a Lambertian base that receives what the lobe does not reflect.

use std::f32::consts::FRAC_1_PI;

use glam::Vec3;

use super::{Bsdf, BsdfSample, GlossyLobes, Lobe, SpecularAlbedo};
use crate::math::{cosine_hemisphere, luminance, Frame};
use crate::render::sampler::{Dim, Sampler};

/// glTF's metallic-roughness material, layered as Blender's Principled BSDF and the glTF
/// specification's dielectric layer are: the GGX lobe (reflectance `specular` at normal
/// incidence, Schlick's Fresnel) over a Lambertian base that receives what the lobe does not
/// reflect, `base / pi` times 1 - E(wo), E being the lobe's directional albedo (from
/// [`SpecularAlbedo`]). The lobe's multiple scattering is restored (Turquin 2019), so a white
/// rough metal reflects all the light, as Cycles' multiscatter GGX does. The GGX lobe is an S vertex, or a D vertex when `rough` (its roughness at
/// least the material's `diffuse_from`); the base is D.
#[derive(Clone, Copy, Debug)]
pub struct Pbr {
    /// The GGX lobe (its `base` unused: the base is Lambertian here).
    pub lobes: GlossyLobes,
    pub base: Vec3,
    pub frame: Frame,
    /// The base's own frame where it differs from `frame`: the normal map's bent normal, when
    /// the shading normal was raised so that the lobe's reflection of the view stays above the
    /// surface (Cycles raises it for its glossy lobes only, and so it is here).
    pub base_frame: Option<Frame>,
    pub rough: bool,
    /// The metallic blend: the lobe's multiple scattering is that of the dielectric's (f0
    /// 0.04) and the metal's (f0 `metal`) lobes, mixed by it.
    pub metallic: f32,
    pub metal: Vec3,
}

/// glTF's dielectric reflectance at normal incidence (an index of 1.5).
const DIELECTRIC_F0: f32 = 0.04;

impl Pbr {
    /// The lobe a GGX sample makes in the split.
    fn tag(&self) -> Lobe {
        if self.rough {
            Lobe::Diffuse
        } else {
            Lobe::Specular
        }
    }

    /// What the layers weigh seen from `wo` (local), from one lookup of the albedo table.
    /// The GGX lobe's multiple scattering is restored as the mix of the dielectric's and the
    /// metal's compensated lobes (the compensation is not linear in f0, so a part-metal is
    /// compensated as the mix of its two lobes, as Blender mixes them), over the single
    /// scattering lobe of the mixed f0. The base is the dielectric part's alone (`base` already
    /// carries the 1 - metallic of the blend) and receives 1 - the dielectric lobe's albedo,
    /// so what a part-metal's lobe reflects as a metal does not darken it: glTF's (and
    /// Blender's) mix of a dielectric and a metal BSDF. The GGX lobe is sampled in proportion
    /// to what it reflects against the base.
    fn view(&self, wo: Vec3) -> View {
        let table = SpecularAlbedo::get();
        let (a, b, e_avg) = table.lookup(wo.z, self.lobes.alpha);
        let albedo = |f0: Vec3| f0 * a + Vec3::splat(b);
        let m = self.metallic;
        let dielectric = Vec3::splat(DIELECTRIC_F0);
        let e_dielectric = albedo(dielectric) * table.compensation(dielectric, a + b, e_avg);
        let spec =
            e_dielectric * (1.0 - m) + albedo(self.metal) * table.compensation(self.metal, a + b, e_avg) * m;
        let multiscatter = spec / albedo(self.lobes.specular).max(Vec3::splat(1e-6));
        let through = (Vec3::ONE - e_dielectric).max(Vec3::ZERO);
        let (spec, base) = (luminance(spec), luminance(self.base * through));
        let p_spec = if base <= 0.0 {
            1.0
        } else if spec <= 0.0 {
            0.0
        } else {
            spec / (spec + base)
        };
        View { multiscatter, through, p_spec }
    }

    /// The base's BRDF toward local `wi_l` (`wi` in world space) and its sampling density (its
    /// probability included). In its own frame, its cosine there in place of the shading
    /// normal's (which the caller multiplies by).
    fn base_value(&self, view: &View, wo: Vec3, wi: Vec3, wi_l: Vec3) -> (Vec3, f32) {
        let cos = match self.base_frame {
            None => wi_l.z,
            Some(b) => b.to_local(wi).z,
        };
        if wo.z <= 0.0 || wi_l.z <= 0.0 || cos <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let f = self.base * view.through * (FRAC_1_PI * cos / wi_l.z);
        (f, (1.0 - view.p_spec) * cos * FRAC_1_PI)
    }
}

/// [`Pbr::view`]: the GGX lobe's multiple-scattering factor, the base's weight, and the
/// probability of sampling the lobe.
struct View {
    multiscatter: Vec3,
    through: Vec3,
    p_spec: f32,
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
        let view = self.view(wo_l);
        let p_spec = view.p_spec;
        if u.get_1d(Dim::Lobe) < p_spec {
            let wi_l = g.sample_specular(wo_l, u.get_2d(Dim::Direction));
            if wi_l.z <= 0.0 {
                return None;
            }
            let weight = g.specular_weight(wo_l, wi_l) * view.multiscatter / p_spec;
            let pdf = p_spec * g.pdf_specular(wo_l, wi_l);
            return Some(BsdfSample { wi: self.frame.to_world(wi_l), weight, pdf, lobe: self.tag() });
        }
        let local = cosine_hemisphere(u.get_2d(Dim::Direction));
        let wi = self.base_frame.unwrap_or(self.frame).to_world(local);
        let wi_l = self.frame.to_local(wi);
        let (f, pdf) = self.base_value(&view, wo_l, wi, wi_l);
        if pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample { wi, weight: f * (wi_l.z / pdf), pdf, lobe: Lobe::Diffuse })
    }

    fn eval_lobes(&self, wo: Vec3, wi: Vec3, mut each: impl FnMut(Lobe, Vec3, f32)) {
        let g = &self.lobes;
        let (wo_l, wi_l) = (self.frame.to_local(wo), self.frame.to_local(wi));
        let view = self.view(wo_l);
        let p_spec = view.p_spec;
        let f = g.eval_specular(wo_l, wi_l) * view.multiscatter;
        each(self.tag(), f, p_spec * g.pdf_specular(wo_l, wi_l));
        let (f, pdf) = self.base_value(&view, wo_l, wi, wi_l);
        each(Lobe::Diffuse, f, pdf);
    }
}
