//! Textures: constant, a 3D checker, solid noise textures from Perlin noise (plain, fBm,
//! turbulence and marble, after Perlin's "An Image Synthesizer", 1985) and images looked up by
//! the surface's (u, v). A texture gives a colour, and a scalar in [0, 1] that bump mapping reads
//! as a height.

use std::f32::consts::PI;
use std::sync::Arc;

use glam::{DVec3, Vec2, Vec3};

use super::image::Image;
use super::noise::{fbm, perlin};
use crate::math::Frame;

/// The pattern of a solid noise texture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pattern {
    /// One octave of Perlin noise.
    Perlin,
    /// Fractional Brownian motion: octaves of noise summed.
    Fbm,
    /// Octaves of the absolute value of noise summed: creases, like carpet or cloud.
    Turbulence,
    /// Veins: a sine along x whose phase turbulence disturbs.
    Marble,
}

/// A texture.
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    Constant(Vec3),
    /// Cubes of side `size` alternating between `a` and `b`.
    Checker {
        a: Vec3,
        b: Vec3,
        size: f32,
    },
    /// A solid noise pattern at `frequency` features a unit, blending `a` (at 0) to `b` (at 1).
    Noise {
        pattern: Pattern,
        a: Vec3,
        b: Vec3,
        frequency: f32,
        octaves: u32,
        seed: u32,
    },
    /// An image (linear RGB, top row first) over the unit square of (u, v), repeated `repeat`
    /// times in each direction; v = 0 is the image's bottom row. `transform`, when there is
    /// one, maps (u, v) first (a glTF texture's `KHR_texture_transform`, in these coordinates).
    Image {
        image: Arc<Image>,
        repeat: Vec2,
        transform: Option<glam::Affine2>,
    },
}

/// Octaves of |noise|, normalised to [0, 1].
fn turbulence(seed: u32, p: Vec3, octaves: u32) -> f32 {
    let (mut sum, mut amp, mut norm, mut q) = (0.0, 1.0, 0.0, p);
    for o in 0..octaves.max(1) {
        sum += amp * perlin(seed.wrapping_add(o), q).abs();
        norm += amp;
        amp *= 0.5;
        q *= 2.0;
    }
    sum / norm
}

impl Texture {
    /// Half the size of a texel in texture coordinates (an image's; 1 for anything else).
    pub fn texel(&self) -> f32 {
        match self {
            Texture::Image { image, repeat, transform } => {
                // How much the transform stretches (u, v) at most.
                let stretch =
                    transform.map_or(1.0, |t| t.matrix2.x_axis.length().max(t.matrix2.y_axis.length()));
                0.5 / (image.width.max(image.height) as f32 * (repeat.max_element() * stretch).max(1e-6))
                    .max(1.0)
            }
            _ => 1.0,
        }
    }

    /// The scalar in [0, 1] of a pattern texture at `p`, or the luminance of a colour.
    ///
    /// `p` is the point in the scene file's own coordinates (f64, not camera-relative): a solid
    /// pattern is fixed in the world, and a point exact where the geometry is exact (see
    /// [`Scene::solid_point`](super::Scene::solid_point)) picks the same cell for every sample
    /// of a plane on a cell boundary.
    pub fn scalar(&self, p: DVec3, uv: Vec2) -> f32 {
        match self {
            Texture::Checker { size, .. } => {
                let c = (p / size.max(1e-12) as f64).floor();
                ((c.x + c.y + c.z) as i64).rem_euclid(2) as f32
            }
            Texture::Noise { pattern, frequency, octaves, seed, .. } => {
                let q = (p * *frequency as f64).as_vec3();
                let t = match pattern {
                    Pattern::Perlin => 0.5 + 0.5 * perlin(*seed, q),
                    Pattern::Fbm => 0.5 + 0.5 * fbm(*seed, q, *octaves, 0.5),
                    Pattern::Turbulence => turbulence(*seed, q, *octaves),
                    Pattern::Marble => 0.5 + 0.5 * (PI * q.x + 8.0 * turbulence(*seed, q, *octaves)).sin(),
                };
                t.clamp(0.0, 1.0)
            }
            Texture::Constant(_) | Texture::Image { .. } => crate::math::luminance(self.color(p, uv)),
        }
    }

    /// The colour at point `p` (in the scene file's coordinates, as for [`Texture::scalar`])
    /// with surface parameters `uv`.
    pub fn color(&self, p: DVec3, uv: Vec2) -> Vec3 {
        match self {
            Texture::Constant(c) => *c,
            Texture::Checker { a, b, .. } | Texture::Noise { a, b, .. } => a.lerp(*b, self.scalar(p, uv)),
            Texture::Image { image, repeat, transform } => {
                bilinear(image, transform.map_or(uv, |t| t.transform_point2(uv)) * *repeat)
            }
        }
    }

    /// Whether the texture is defined in space (and so has a gradient there, for bump mapping).
    pub fn is_solid(&self) -> bool {
        matches!(self, Texture::Checker { .. } | Texture::Noise { .. })
    }

    /// The spacing for finite differences of this texture: well under its smallest feature.
    fn step(&self) -> f32 {
        match self {
            Texture::Noise { frequency, octaves, .. } => {
                1e-2 / (frequency * (1u32 << (*octaves).clamp(1, 16).saturating_sub(1)) as f32)
            }
            Texture::Checker { size, .. } => 1e-3 * size,
            _ => 1e-3,
        }
    }

    /// The normal `n` bent by this texture read as a height field of amplitude `height` along
    /// the normal (Blinn 1978): the height's gradient in the tangent plane tilts the normal.
    /// The result is unit length and kept on the side of the geometric normal `ng`.
    pub fn bump(&self, height: f32, p: DVec3, uv: Vec2, n: Vec3, ng: Vec3) -> Vec3 {
        let d = self.step();
        let h = |q: DVec3| self.scalar(q, uv);
        // Only the gradient along the surface bends the normal: forward differences along two
        // tangents, three lookups.
        let frame = Frame::new(n);
        let h0 = h(p);
        let step = |t: Vec3| h(p + (t * d).as_dvec3()) - h0;
        let tangential = (frame.s * step(frame.s) + frame.t * step(frame.t)) * (height / d);
        let bent = (n - tangential).normalize_or(n);
        // A steep bump must not turn the shading normal below the surface.
        if bent.dot(ng) > 0.05 {
            bent
        } else {
            n
        }
    }
}

/// Bilinear lookup with wrap-around; v = 0 at the bottom row.
fn bilinear(image: &Image, uv: Vec2) -> Vec3 {
    let (w, h) = (image.width as i64, image.height as i64);
    if w == 0 || h == 0 {
        return Vec3::ZERO;
    }
    let x = uv.x.rem_euclid(1.0) * w as f32 - 0.5;
    let y = (1.0 - uv.y.rem_euclid(1.0)) * h as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let at = |i: f32, j: f32| {
        let (i, j) = ((i as i64).rem_euclid(w), (j as i64).rem_euclid(h));
        image.pixels[(j * w + i) as usize]
    };
    (at(x0, y0) * (1.0 - fx) + at(x0 + 1.0, y0) * fx) * (1.0 - fy)
        + (at(x0, y0 + 1.0) * (1.0 - fx) + at(x0 + 1.0, y0 + 1.0) * fx) * fy
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(pattern: Pattern) -> Texture {
        Texture::Noise { pattern, a: Vec3::ZERO, b: Vec3::ONE, frequency: 3.0, octaves: 5, seed: 4 }
    }

    #[test]
    fn patterns_are_deterministic_in_range_and_vary() {
        for pattern in [Pattern::Perlin, Pattern::Fbm, Pattern::Turbulence, Pattern::Marble] {
            let t = noise(pattern);
            let (mut lo, mut hi) = (1.0f32, 0.0f32);
            for i in 0..5000 {
                let p = DVec3::new(i as f64 * 0.0731, (i % 71) as f64 * 0.113, (i % 17) as f64 * 0.29);
                let s = t.scalar(p, Vec2::ZERO);
                assert_eq!(s, t.scalar(p, Vec2::ZERO));
                assert!((0.0..=1.0).contains(&s), "{pattern:?}: {s}");
                lo = lo.min(s);
                hi = hi.max(s);
            }
            assert!(hi - lo > 0.4, "{pattern:?} hardly varies: [{lo}, {hi}]");
        }
    }

    #[test]
    fn bumped_normals_are_unit_and_on_the_geometric_side() {
        let t = noise(Pattern::Turbulence);
        let mut tilted = 0;
        for i in 0..2000 {
            let p = DVec3::new(i as f64 * 0.013, 0.0, (i % 37) as f64 * 0.021);
            // A shading normal a little off the geometric one, as on a smooth mesh.
            let ng = Vec3::Y;
            let n = Vec3::new(0.1 * ((i % 7) as f32 - 3.0) / 3.0, 1.0, 0.0).normalize();
            for height in [0.01f32, 0.1, 10.0] {
                let b = t.bump(height, p, Vec2::ZERO, n, ng);
                assert!((b.length() - 1.0).abs() < 1e-5, "{b}");
                assert!(b.dot(ng) > 0.0, "{b} below the surface");
                tilted += (b.dot(n) < 0.9999) as u32;
            }
        }
        assert!(tilted > 1000, "the bump hardly bends anything ({tilted})");
        // A constant texture has no gradient: the normal is unchanged.
        let flat = Texture::Constant(Vec3::ONE).bump(1.0, DVec3::ONE, Vec2::ZERO, Vec3::Y, Vec3::Y);
        assert_eq!(flat, Vec3::Y);
    }

    #[test]
    fn images_wrap_and_v_runs_up() {
        let mut img = Image::new(2, 2);
        img.set(0, 0, Vec3::new(1.0, 0.0, 0.0)); // top left
        img.set(0, 1, Vec3::new(0.0, 1.0, 0.0)); // bottom left
        let t = Texture::Image { image: Arc::new(img), repeat: Vec2::ONE, transform: None };
        // Pixel centres: (0.25, 0.75) is the top-left pixel, (0.25, 0.25) the bottom-left.
        assert_eq!(t.color(DVec3::ZERO, Vec2::new(0.25, 0.75)), Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(t.color(DVec3::ZERO, Vec2::new(0.25, 0.25)), Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(t.color(DVec3::ZERO, Vec2::new(1.25, -0.75)), Vec3::new(0.0, 1.0, 0.0));
    }
}
