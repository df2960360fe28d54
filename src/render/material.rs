//! A scene material at a surface point, made a BSDF: its textures looked up, its shading normal
//! bent by its bump, height and normal maps, and the BSDF of its kind built from them. The
//! integrator asks for the shading normal and says what to do with the BSDF ([`UseBsdf`]); it
//! never names a material. Adding a material is its BSDF in `bsdf/` and one arm of
//! `Shading::material_bsdf` (for a plain kind, which the path loop scatters inline, of
//! `Shading::plain_bsdf` instead).

use glam::{DVec3, Vec2, Vec3};

use super::bsdf::microfacet::Microfacet;
use super::bsdf::{
    alpha, dielectric_f0, Black, Bsdf, Dielectric, Diffuse, Glass, Glossy, GlossyLobes, Mirror, Pbr,
    Principled, RoughDielectric, SheenLobe,
};
use super::surface::{apply_height, apply_normal_map, valid_reflection, Surface};
use crate::math::Frame;
use crate::scene::texture::Texture;
use crate::scene::{Maps, Material, Scene, Shape};

/// What to do with a BSDF, whatever its type: generic over it, so that code using a BSDF is
/// compiled once for each material, the material being chosen once, in [`Shading::with_bsdf`].
pub trait UseBsdf {
    type Output;
    fn with<B: Bsdf>(self, bsdf: &B) -> Self::Output;
}

/// The material of a hit on a shape, with the textures it reads.
pub struct Shading<'a> {
    scene: &'a Scene,
    shape: &'a Shape,
    s: &'a Surface,
    maps: &'a Maps,
    /// The width that an image lookup covers in each set of texture coordinates (0 and 1): 0
    /// for a point.
    footprint: [f32; 2],
}

impl<'a> Shading<'a> {
    /// The material of `shape` at `s`; with `textured` false (a render that reads no textures)
    /// its constants alone.
    #[inline(always)]
    pub fn new(scene: &'a Scene, shape: &'a Shape, s: &'a Surface, textured: bool) -> Self {
        let maps = if textured { scene.maps(shape.material) } else { &Maps::NONE };
        Shading { scene, shape, s, maps, footprint: [0.0; 2] }
    }

    /// Image lookups cover `width` (scene units) across the surface, filtered by their mipmaps
    /// (as a path's cone sees it: [`crate::render::integrator::Cone`]): in each set of texture
    /// coordinates, the width times the triangle's coordinates per unit length (the square root
    /// of its area in (u, v) over its area in the scene), once for every lookup of the hit; 0 on
    /// a sphere or without coordinates (point lookups).
    #[inline(always)]
    pub fn set_footprint(&mut self, width: f32) {
        // A material that reads no texture makes no lookup.
        if *self.maps == Maps::NONE {
            return;
        }
        let crate::scene::Geometry::Triangles(mesh) = &self.shape.geometry else { return };
        let Some(&[ia, ib, ic]) = mesh.indices.get(self.s.prim as usize) else { return };
        let [p, q, r] = mesh.triangle(self.s.prim);
        let area = (q - p).cross(r - p).length();
        if !(width > 0.0 && area > 0.0) {
            return;
        }
        for (set, out) in self.footprint.iter_mut().enumerate() {
            let Some(uvs) = mesh.uvs(set as u8) else { continue };
            let uv = |i: u32| uvs.get(i as usize).copied().unwrap_or(Vec2::ZERO);
            let (a, b, c) = (uv(ia), uv(ib), uv(ic));
            let uv_area = (b - a).perp_dot(c - a).abs();
            if uv_area.is_finite() {
                *out = width * (uv_area / area).sqrt();
            }
        }
    }

    /// Where texture `t` is read: a solid one at the point in f64 (exact on planes the scene
    /// file makes exact); an image only by `s.uv`.
    #[inline(always)]
    fn point(&self, t: &Texture) -> DVec3 {
        match t.is_solid() {
            true => self.scene.solid_point(&self.shape.geometry, self.s.prim, self.s.bary, self.s.p),
            false => DVec3::ZERO,
        }
    }

    fn texture(&self, t: u32) -> &'a Texture {
        &self.scene.textures[t as usize]
    }

    /// The texture coordinates texture `t` reads.
    #[inline(always)]
    fn uv(&self, t: &Texture) -> Vec2 {
        if t.set() == 1 {
            self.s.uv1
        } else {
            self.s.uv
        }
    }

    /// Texture `t`'s colour here.
    #[inline(always)]
    fn read(&self, t: u32) -> Vec3 {
        let texture = self.texture(t);
        let width = self.footprint[usize::from(texture.set() == 1)];
        match width > 0.0 && matches!(texture, Texture::Image { .. }) {
            true => texture.color_over(self.point(texture), self.uv(texture), width),
            false => texture.color(self.point(texture), self.uv(texture)),
        }
    }

    /// The shading normal turned to the side of `ng` (the geometric normal, already on the side
    /// the path came from: surfaces are two-sided), bent by the material's maps. A bump or height
    /// map that would bend it below the surface leaves it unbent; a normal map's bent normal is
    /// kept ([`Shading::normal_mapped`]).
    #[inline(always)]
    pub fn normal(&self, ng: Vec3) -> Vec3 {
        let s = self.s;
        let mut ns = if s.ns.dot(ng) >= 0.0 { s.ns } else { -s.ns };
        if let Some((t, height)) = self.maps.bump {
            let texture = self.texture(t);
            ns = texture.bump(height, self.point(texture), s.uv, ns, ng);
        }
        if let Some((t, scale)) = self.maps.height {
            // Central differences of the height, half a texel (at most 1/1024) either side: the
            // bilinear lookup is linear within a texel, so this is the local slope.
            let texture = self.texture(t);
            let d = texture.texel().min(1.0 / 1024.0);
            let p = self.point(texture);
            let h = |du: f32, dv: f32| scale * texture.scalar(p, s.uv + Vec2::new(du, dv));
            let (dhdu, dhdv) = ((h(d, 0.0) - h(-d, 0.0)) / (2.0 * d), (h(0.0, d) - h(0.0, -d)) / (2.0 * d));
            let bent = apply_height(ns, s.dpdu, s.dpdv, dhdu, dhdv);
            ns = if bent.dot(ng) > 1e-3 { bent } else { ns };
        }
        if let Some(map) = self.maps.normal {
            ns = self.normal_mapped(ns, map);
        }
        ns
    }

    /// `ns` bent by normal map `(t, scale)`, kept even where it falls below the surface (its
    /// diffuse base is then dark, as in Cycles; the glossy lobes raise it: [`valid_reflection`]).
    #[inline(always)]
    fn normal_mapped(&self, ns: Vec3, (t, scale): (u32, f32)) -> Vec3 {
        let c = self.read(t) * 2.0 - Vec3::ONE;
        apply_normal_map(ns, self.s.dpdu, self.s.dpdv, Vec3::new(c.x * scale, c.y * scale, c.z))
    }

    /// The shading frame at normal `n`: along the surface's u direction where the material is
    /// anisotropic (Mitsuba's frame, its s axis along dp/du), any frame otherwise.
    #[inline(always)]
    fn frame(&self, n: Vec3, aligned: bool) -> Frame {
        let s = self.s.dpdu - n * n.dot(self.s.dpdu);
        match aligned && s.length_squared() > 0.0 {
            true => {
                let s = s.normalize();
                Frame { s, t: n.cross(s), n }
            }
            false => Frame::new(n),
        }
    }

    /// Whether a microfacet lobe is wide enough to count as a D vertex in the split: as wide as
    /// a glossy lobe of the scene's diffuse roughness ([`crate::scene::DIFFUSE_ROUGHNESS`],
    /// alpha being roughness squared).
    #[inline(always)]
    fn counts_diffuse(&self, f: Microfacet) -> bool {
        f.alpha_u.max(f.alpha_v).sqrt() >= crate::scene::DIFFUSE_ROUGHNESS
    }

    /// The material's colour: its texture's where it has one, else `constant`; times the
    /// vertex colour.
    #[inline(always)]
    fn color(&self, constant: Vec3) -> Vec3 {
        let c = match self.maps.color {
            Some(t) => self.read(t),
            None => constant,
        };
        c * self.s.color
    }

    /// A metallic-roughness material's factors, times its texture's blue and green.
    #[inline(always)]
    fn metal_rough(&self, metallic: f32, roughness: f32) -> (f32, f32) {
        match self.maps.metal_rough {
            Some(t) => {
                let c = self.read(t);
                (metallic * c.z, roughness * c.y)
            }
            None => (metallic, roughness),
        }
    }

    /// The material's BSDF at shading normal `n` (on the side the path arrived from), handed to
    /// `u`; `bent` the normal the maps made, of which `n` is the raised form
    /// ([`valid_reflection`]) that glossy lobes use (a diffuse base keeps `bent`), `wo` the
    /// direction to the viewer, `entering` when the path arrived from the outside (the side
    /// the geometric normal points to).
    #[inline(always)]
    pub fn with_bsdf<U: UseBsdf>(&self, n: Vec3, bent: Vec3, wo: Vec3, entering: bool, u: U) -> U::Output {
        let material = &self.scene.materials[self.shape.material as usize];
        // The four plain kinds are scattered inline in the caller's path loop; the others and
        // the wrappers in one outlined function (recursive, for the wrappers), whose every
        // arm would otherwise be copied into each loop. Measured on Embree's Cornell box:
        // docs/RESULTS.md, `render-regression`.
        match self.plain_bsdf(material, n, entering, u) {
            Ok(out) => out,
            Err(u) => self.material_bsdf(material, n, bent, wo, entering, u),
        }
    }

    /// The BSDF of a plain kind (diffuse, mirror, glass, glossy) handed to `u`; `u` back for
    /// any other kind.
    #[inline(always)]
    fn plain_bsdf<U: UseBsdf>(
        &self,
        material: &Material,
        n: Vec3,
        entering: bool,
        u: U,
    ) -> Result<U::Output, U> {
        Ok(match *material {
            Material::Diffuse { albedo } => u.with(&Diffuse { albedo: self.color(albedo), n }),
            Material::Mirror { color } => u.with(&Mirror { color, n }),
            Material::Glass { ior, color } => u.with(&Glass { ior, color, n, entering }),
            Material::Glossy { specular, roughness, base } => {
                let lobes = GlossyLobes { specular, alpha: alpha(roughness), base: self.color(base) };
                u.with(&Glossy { lobes, frame: Frame::new(n) })
            }
            _ => return Err(u),
        })
    }

    /// [`Shading::with_bsdf`] of material `material` (the shape's, or one it wraps): every
    /// kind, the plain ones through [`Shading::plain_bsdf`] for the wrappers.
    #[inline(never)]
    fn material_bsdf<U: UseBsdf>(
        &self,
        material: &Material,
        n: Vec3,
        bent: Vec3,
        wo: Vec3,
        entering: bool,
        u: U,
    ) -> U::Output {
        let u = match self.plain_bsdf(material, n, entering, u) {
            Ok(out) => return out,
            Err(u) => u,
        };
        // (Made only for the materials with a diffuse base under glossy lobes.)
        let base_frame = || (bent != n).then(|| Frame::new(bent));
        match material {
            Material::Diffuse { .. }
            | Material::Mirror { .. }
            | Material::Glass { .. }
            | Material::Glossy { .. } => {
                unreachable!("the plain kinds are scattered by plain_bsdf above")
            }
            Material::Front(inner) => match entering {
                true => self.material_bsdf(inner, n, bent, wo, entering, u),
                false => u.with(&Black),
            },
            Material::Blend(blend) => {
                // Of the hit point's bits (a sphere's hits have no barycentrics), keyed by the
                // material with its top bit set, as no cut-out is keyed.
                let p = self.s.p;
                let key = self.shape.material | 0x8000_0000;
                let pick = crate::scene::cutout::hit_hash(key, self.s.prim ^ p.x.to_bits(), p.y, p.z);
                let chosen = if pick < blend.weight { &blend.b } else { &blend.a };
                self.material_bsdf(chosen, n, bent, wo, entering, u)
            }
            Material::Conductor(c) => u.with(&c.bsdf(
                self.frame(n, c.facets.is_some_and(|f| !f.is_isotropic())),
                c.facets.is_some_and(|f| self.counts_diffuse(f)),
            )),
            Material::Dielectric(d) => match d.facets {
                Some(facets) => u.with(&RoughDielectric {
                    frame: self.frame(n, !facets.is_isotropic()),
                    eta: d.eta,
                    reflectance: d.reflectance,
                    transmittance: d.transmittance,
                    facets,
                    entering,
                    rough: self.counts_diffuse(facets),
                }),
                None => u.with(&Dielectric {
                    eta: d.eta,
                    reflectance: d.reflectance,
                    transmittance: d.transmittance,
                    n,
                    entering,
                    thin: d.thin,
                }),
            },
            Material::Plastic(p) => u.with(&p.bsdf(
                self.color(p.diffuse),
                Frame::new(n),
                p.facets.as_ref().is_some_and(|(f, _)| self.counts_diffuse(*f)),
            )),
            &Material::Pbr { base_color, metallic, roughness, diffuse_from } => {
                let (metallic, roughness) = self.metal_rough(metallic, roughness);
                let color = base_color * self.color(Vec3::ONE);
                let lobes = GlossyLobes {
                    specular: Vec3::splat(0.04).lerp(color, metallic),
                    alpha: alpha(roughness),
                    base: Vec3::ZERO,
                };
                u.with(&Pbr {
                    lobes,
                    base: color * (1.0 - metallic),
                    frame: Frame::new(n),
                    base_frame: base_frame(),
                    rough: roughness >= diffuse_from,
                    metallic,
                    metal: color,
                })
            }
            Material::Layered(l) => {
                let (metallic, roughness) = self.metal_rough(l.metallic, l.roughness);
                let layers = &l.layers;
                let (f0, roughness) = match self.maps.spec_gloss {
                    Some((color, gloss)) => {
                        let glossiness = (1.0 - roughness) * self.read(gloss).x;
                        ((layers.f0 * self.read(color)).min(Vec3::ONE), 1.0 - glossiness)
                    }
                    None => (layers.f0, roughness),
                };
                let lm = &self.maps.layer;
                // A texture's value at the point (1 without one).
                let at = |t: Option<u32>| t.map_or(Vec3::ONE, |t| self.read(t));
                let (f0, f90) = match (lm.specular, lm.specular_color) {
                    (None, None) => (f0, layers.f90),
                    (s, c) => {
                        dielectric_f0(layers.ior, layers.specular * at(s).x, layers.specular_color * at(c))
                    }
                };
                let coat = layers.clearcoat * at(lm.clearcoat).x;
                let coat_roughness = layers.clearcoat_roughness * at(lm.clearcoat_roughness).y;
                let sheen_color = layers.sheen_color * at(lm.sheen_color);
                let sheen_roughness = layers.sheen_roughness * at(lm.sheen_roughness).x;
                // The clearcoat's own normal map bends the interpolated normal (on the side of
                // `n`), not the base's; raised as the base's is where it would reflect the view
                // below the surface.
                let coat_frame = lm.clearcoat_normal.filter(|_| coat > 0.0).map(|map| {
                    let ng = if self.s.ng.dot(wo) >= 0.0 { self.s.ng } else { -self.s.ng };
                    let ns = if self.s.ns.dot(ng) >= 0.0 { self.s.ns } else { -self.s.ns };
                    Frame::new(valid_reflection(ng, wo, self.normal_mapped(ns, map)))
                });
                u.with(&Principled {
                    frame: Frame::new(n),
                    coat_frame,
                    base_frame: base_frame(),
                    entering,
                    color: l.base_color * self.color(Vec3::ONE),
                    metallic,
                    alpha: alpha(roughness),
                    f0,
                    f90,
                    transmission: layers.transmission * at(self.maps.transmission).x,
                    ior: layers.ior,
                    thin: layers.thin,
                    coat,
                    coat_alpha: alpha(coat_roughness),
                    sheen: SheenLobe::new(sheen_color, sheen_roughness),
                    sheen_roughness,
                    rough: roughness >= l.diffuse_from,
                    coat_rough: coat_roughness >= l.diffuse_from,
                })
            }
        }
    }
}
