//! Cut-outs: the surfaces a ray passes through where a material's alpha (coverage) says so.
//! glTF's `alphaMode` MASK keeps a hit where alpha reaches the cutoff; BLEND, and an OBJ's `d`
//! and `map_d`, keep it with probability alpha (stochastic transparency: on average a hit
//! counts alpha of the time, which is alpha blending in the mean). Both accelerators ask
//! [`Cutouts::keeps`] about every candidate hit on a shape that has alpha, camera and shadow
//! rays alike, so a cut-out's shadow is cut out too; shapes without alpha are never asked.
//!
//! The stochastic choice is a hash of the hit itself (shape, triangle and barycentrics): the
//! same hit gets the same answer on every query and thread, and, unlike a hash of the ray, in
//! an instanced mesh's coordinates as in the scene's, so both backends and any number of
//! threads agree.

use std::sync::Arc;

use glam::{DVec3, Vec2};

use super::texture::Texture;
use super::{Geometry, Scene};

/// How a material's alpha cuts its surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    /// A hit counts where alpha is at least the cutoff (glTF's MASK, cutoff 0.5 by default).
    Mask(f32),
    /// A hit counts with probability alpha (glTF's BLEND; an OBJ's `d` and `map_d`).
    Blend,
}

/// A material's alpha: its mode, its factor and the texture that multiplies it (an image's
/// alpha channel, in all three channels), read at the texture's own coordinates. A mesh's
/// vertex alpha ([`super::Attributes::alpha`]) multiplies it too.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Alpha {
    pub mode: AlphaMode,
    pub factor: f32,
    pub texture: Option<u32>,
}

impl Alpha {
    /// Whether this alpha can cut anything: a mask whose cutoff is above 0, or a blend with a
    /// factor below 1 or a texture (a mask of cutoff 0 and a blend of factor 1 without a
    /// texture keep every hit, and need no test).
    pub fn cuts(&self, vertex_alpha: bool) -> bool {
        match self.mode {
            AlphaMode::Mask(cutoff) => {
                cutoff > 0.0 && (self.factor < cutoff || self.texture.is_some() || vertex_alpha)
            }
            AlphaMode::Blend => self.factor < 1.0 || self.texture.is_some() || vertex_alpha,
        }
    }
}

/// One shape's cut-out: what [`Cutouts::keeps`] reads at a hit.
#[derive(Clone, Debug)]
struct Cutout {
    mode: AlphaMode,
    factor: f32,
    /// The alpha texture and the coordinates it reads.
    texture: Option<(Texture, Arc<[Vec2]>)>,
    vertex_alpha: Option<Arc<[f32]>>,
    indices: Arc<[[u32; 3]]>,
}

impl Cutout {
    /// The alpha at barycentrics `(u, v)` of triangle `prim`.
    #[inline]
    fn alpha(&self, prim: u32, u: f32, v: f32) -> f32 {
        let Some(&[a, b, c]) = self.indices.get(prim as usize) else { return 1.0 };
        let at = |values: &[f32]| -> f32 {
            let get = |i: u32| values.get(i as usize).copied().unwrap_or(1.0);
            get(a) * (1.0 - u - v) + get(b) * u + get(c) * v
        };
        let mut alpha = self.factor;
        if let Some(values) = &self.vertex_alpha {
            alpha *= at(values);
        }
        if let Some((texture, uvs)) = &self.texture {
            let get = |i: u32| uvs.get(i as usize).copied().unwrap_or(Vec2::ZERO);
            let uv = get(a) * (1.0 - u - v) + get(b) * u + get(c) * v;
            alpha *= texture.color(DVec3::ZERO, uv).x;
        }
        alpha
    }
}

/// The cut-outs of a scene's shapes, by shape index.
#[derive(Clone, Debug, Default)]
pub struct Cutouts {
    shapes: Vec<Option<Cutout>>,
}

impl Cutouts {
    /// The cut-outs of `scene`, or `None` when no shape has one (then no accelerator tests
    /// anything). Only triangle meshes are cut: a sphere's hit carries no surface coordinates.
    pub fn new(scene: &Scene) -> Option<Cutouts> {
        let shapes: Vec<Option<Cutout>> = scene
            .shapes
            .iter()
            .map(|shape| {
                let Geometry::Triangles(mesh) = &shape.geometry else { return None };
                let alpha = scene.maps(shape.material).alpha?;
                let vertex_alpha = mesh.attributes.as_ref().and_then(|a| a.alpha.clone());
                if !alpha.cuts(vertex_alpha.is_some()) {
                    return None;
                }
                let texture = alpha.texture.and_then(|t| {
                    let texture = scene.textures.get(t as usize)?.clone();
                    let uvs = match texture.set() {
                        0 => mesh.uvs.clone(),
                        _ => mesh.attributes.as_ref().and_then(|a| a.uv1.clone()),
                    }?;
                    Some((texture, uvs))
                });
                Some(Cutout {
                    mode: alpha.mode,
                    factor: alpha.factor,
                    texture,
                    vertex_alpha,
                    indices: mesh.indices.clone(),
                })
            })
            .collect();
        shapes.iter().any(Option::is_some).then_some(Cutouts { shapes })
    }

    /// Whether shape `shape` has a cut-out (its hits are tested).
    #[inline]
    pub fn cuts(&self, shape: u32) -> bool {
        self.shapes.get(shape as usize).is_some_and(Option::is_some)
    }

    /// Whether the hit at barycentrics `(u, v)` of triangle `prim` of shape `shape` counts
    /// (true for a shape without a cut-out).
    #[inline]
    pub fn keeps(&self, shape: u32, prim: u32, u: f32, v: f32) -> bool {
        let Some(Some(cut)) = self.shapes.get(shape as usize) else { return true };
        let alpha = cut.alpha(prim, u, v);
        match cut.mode {
            AlphaMode::Mask(cutoff) => alpha >= cutoff,
            AlphaMode::Blend => hit_hash(shape, prim, u, v) < alpha,
        }
    }

    /// The fraction of rays that stop at this point of shape `shape` (1 for a shape without a
    /// cut-out): a mask's 0 or 1, a blend's alpha. Light sampled on a cut-out emitter is
    /// weighted by it, so that it agrees with what rays that hit the emitter see.
    pub fn coverage(&self, shape: u32, prim: u32, u: f32, v: f32) -> f32 {
        match self.shapes.get(shape as usize) {
            Some(Some(cut)) => {
                let alpha = cut.alpha(prim, u, v);
                match cut.mode {
                    AlphaMode::Mask(cutoff) => f32::from(u8::from(alpha >= cutoff)),
                    AlphaMode::Blend => alpha.clamp(0.0, 1.0),
                }
            }
            _ => 1.0,
        }
    }
}

/// A number in [0, 1) from a hit: the shape, triangle and the bits of its barycentrics, mixed
/// by the finaliser of MurmurHash3 (every input bit reaches every output bit). A ray's hit
/// falls at its own barycentrics, so over the rays through a region the numbers are uniform.
#[inline]
pub fn hit_hash(shape: u32, prim: u32, u: f32, v: f32) -> f32 {
    let mut h = (shape as u64) << 32 | prim as u64;
    h ^= (u.to_bits() as u64) << 32 | v.to_bits() as u64;
    h = h.wrapping_add(0x9e37_79b9_7f4a_7c15);
    h ^= h >> 33;
    h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
    h ^= h >> 33;
    h = h.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
    h ^= h >> 33;
    (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hit_hash_is_uniform() {
        // 64 bins of 64,000 hashes of neighbouring barycentrics: each bin's count within five
        // standard deviations of the mean (binomial, p = 1/64).
        let (n, bins) = (64_000usize, 64usize);
        let mut count = vec![0usize; bins];
        for i in 0..n {
            let u = (i % 400) as f32 / 400.0 * 0.5;
            let v = (i / 400) as f32 / 160.0 * 0.5;
            let x = hit_hash(3, 7, u, v);
            assert!((0.0..1.0).contains(&x));
            count[(x * bins as f32) as usize] += 1;
        }
        let mean = n as f64 / bins as f64;
        let sd = (n as f64 * (1.0 / bins as f64) * (1.0 - 1.0 / bins as f64)).sqrt();
        for (b, &c) in count.iter().enumerate() {
            assert!((c as f64 - mean).abs() < 5.0 * sd, "bin {b}: {c} against {mean}");
        }
    }

    #[test]
    fn what_cuts_and_what_needs_no_test() {
        let a = |mode, factor, texture| Alpha { mode, factor, texture };
        assert!(!a(AlphaMode::Mask(0.5), 1.0, None).cuts(false));
        assert!(a(AlphaMode::Mask(0.5), 0.4, None).cuts(false));
        assert!(a(AlphaMode::Mask(0.5), 1.0, Some(0)).cuts(false));
        assert!(!a(AlphaMode::Mask(0.0), 1.0, Some(0)).cuts(true));
        assert!(!a(AlphaMode::Blend, 1.0, None).cuts(false));
        assert!(a(AlphaMode::Blend, 1.0, None).cuts(true));
        assert!(a(AlphaMode::Blend, 0.9, None).cuts(false));
    }
}
