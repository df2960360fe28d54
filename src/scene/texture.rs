//! Textures: constant, a 3D checker, solid noise textures from Perlin noise (plain, fBm,
//! turbulence and marble, after Perlin's "An Image Synthesizer", 1985) and images looked up by
//! the surface's (u, v). A texture gives a colour, and a scalar in [0, 1] that bump mapping reads
//! as a height.

use std::f32::consts::PI;
use std::sync::Arc;

use glam::{DVec3, Vec2, Vec3};

use super::image::Image;
use super::noise::{fbm, perlin, turbulence};
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

/// How an image repeats outside [0, 1] along one of its axes (glTF's sampler wrap modes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Wrap {
    #[default]
    Repeat,
    /// The edge texels extend outwards.
    Clamp,
    /// Every other repeat is mirrored.
    Mirror,
}

/// How an image is read: its wrap modes along u and v, nearest or bilinear lookup, and which
/// set of the mesh's texture coordinates it reads (0, or a glTF's `TEXCOORD_1`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Sampling {
    pub wrap: [Wrap; 2],
    /// The texel the point falls in, not a bilinear blend of four (glTF's `NEAREST`).
    pub nearest: bool,
    /// The set of texture coordinates: 0 or 1.
    pub set: u8,
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
    /// one, maps (u, v) first (a glTF texture's `KHR_texture_transform`, in these coordinates);
    /// `sampling` says how it is looked up.
    Image {
        image: Arc<Image>,
        repeat: Vec2,
        transform: Option<glam::Affine2>,
        sampling: Sampling,
        /// The image's mipmaps, halving down to one texel ([`Texture::image`]; none for a
        /// `nearest` sampler, whose texels stay crisp).
        mips: Mips,
    },
}

/// An image's mipmaps: levels 1, 2, ... of its pyramid (level 0 is the image), each a box
/// filter of the one before, its size halved (rounded up) down to one texel.
#[derive(Clone, Debug)]
pub struct Mips(Arc<[Image]>);

impl Default for Mips {
    fn default() -> Self {
        Mips(Arc::from(Vec::new()))
    }
}

impl PartialEq for Mips {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0) || self.0 == other.0
    }
}

impl Mips {
    /// The pyramid of `image`: each level's texel the mean of the two by two texels it covers
    /// (one or two at an odd edge). On the calling thread: a level is a third of the image's
    /// texels at most, about 0.1 s for an 8192^2 image, and threads of their own would each
    /// reserve memory (a malloc arena) that a limit on address space counts.
    pub fn of(image: &Image) -> Mips {
        let mut levels: Vec<Image> = Vec::new();
        let mut last = image;
        while last.width > 1 || last.height > 1 {
            let (w, h) = (last.width.div_ceil(2), last.height.div_ceil(2));
            let mut next = Image::new(w, h);
            next.pixels.chunks_mut(w as usize).enumerate().for_each(|(y, row)| {
                let ys = [2 * y as u32, (2 * y as u32 + 1).min(last.height - 1)];
                for (x, out) in row.iter_mut().enumerate() {
                    let xs = [2 * x as u32, (2 * x as u32 + 1).min(last.width - 1)];
                    *out = 0.25
                        * (last.get(xs[0], ys[0])
                            + last.get(xs[1], ys[0])
                            + last.get(xs[0], ys[1])
                            + last.get(xs[1], ys[1]));
                }
            });
            levels.push(next);
            last = levels.last().unwrap_or(image);
        }
        Mips(Arc::from(levels))
    }

    /// How many levels past the image itself.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Level `k` (1 or more).
    pub fn level(&self, k: usize) -> Option<&Image> {
        self.0.get(k.checked_sub(1)?)
    }
}

impl Texture {
    /// An image texture, its mipmaps made (unless its sampler is `nearest`).
    pub fn image(
        image: Arc<Image>,
        repeat: Vec2,
        transform: Option<glam::Affine2>,
        sampling: Sampling,
    ) -> Texture {
        let mips = if sampling.nearest { Mips::default() } else { Mips::of(&image) };
        Texture::Image { image, repeat, transform, sampling, mips }
    }

    /// How many texels of the image's finest level one unit of texture coordinates spans at
    /// most, through its repeat and transform (1 for anything but an image).
    fn texels_per_unit(&self) -> f32 {
        match self {
            Texture::Image { image, repeat, transform, .. } => {
                let stretch =
                    transform.map_or(1.0, |t| t.matrix2.x_axis.length().max(t.matrix2.y_axis.length()));
                (image.width as f32 * image.height as f32).sqrt() * repeat.max_element() * stretch
            }
            _ => 1.0,
        }
    }

    /// The mip level of a lookup whose footprint is `width` wide in texture coordinates: the
    /// log2 of its width in texels of the finest level, 0 (the image itself) for a footprint
    /// within one texel.
    pub fn level(&self, width: f32) -> f32 {
        (width * self.texels_per_unit()).max(1.0).log2()
    }

    /// [`Texture::color`] over a footprint `width` wide in texture coordinates: an image's
    /// trilinear lookup between the two mip levels around [`Texture::level`]; for a footprint
    /// within a texel (or zero: a point) and anything but an image, `color` itself.
    #[inline]
    pub fn color_over(&self, p: DVec3, uv: Vec2, width: f32) -> Vec3 {
        let Texture::Image { image, repeat, transform, sampling, mips } = self else {
            return self.color(p, uv);
        };
        let level = self.level(width);
        if level <= 0.0 || mips.is_empty() {
            return self.color(p, uv);
        }
        let at = transform.map_or(uv, |t| t.transform_point2(uv)) * *repeat;
        let k = (level.floor() as usize).min(mips.len());
        let f = if k == mips.len() { 0.0 } else { level - k as f32 };
        let of = |k: usize| if k == 0 { image.as_ref() } else { mips.level(k).unwrap_or(image) };
        let lo = lookup(of(k), at, sampling);
        if f == 0.0 {
            return lo;
        }
        lo * (1.0 - f) + lookup(of(k + 1), at, sampling) * f
    }

    /// Half the size of a texel in texture coordinates (an image's; 1 for anything else).
    pub fn texel(&self) -> f32 {
        match self {
            Texture::Image { image, repeat, transform, .. } => {
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
            Texture::Image { image, repeat, transform, sampling, .. } => {
                lookup(image, transform.map_or(uv, |t| t.transform_point2(uv)) * *repeat, sampling)
            }
        }
    }

    /// The set of the mesh's texture coordinates it reads (0 but for an image that says 1).
    #[inline(always)]
    pub fn set(&self) -> u8 {
        match self {
            Texture::Image { sampling, .. } => sampling.set,
            _ => 0,
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

/// Where coordinate `x` (in texels, of `n` of them) falls under `wrap`, kept to a few periods
/// of the image first so that it converts to an integer exactly.
fn wrapped(x: f32, n: i64, wrap: Wrap) -> f32 {
    let n = n as f32;
    match wrap {
        Wrap::Repeat => x.rem_euclid(n),
        Wrap::Mirror => x.rem_euclid(2.0 * n),
        Wrap::Clamp => x.clamp(-1.0, n + 1.0),
    }
}

/// Texel `i` of a row or column of `n` under `wrap`.
fn texel_index(i: i64, n: i64, wrap: Wrap) -> i64 {
    match wrap {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Mirror => {
            let k = i.rem_euclid(2 * n);
            if k < n {
                k
            } else {
                2 * n - 1 - k
            }
        }
    }
}

/// The image at `uv` (v = 0 at the bottom row), bilinear or nearest, wrapped by `sampling`.
fn lookup(image: &Image, uv: Vec2, sampling: &Sampling) -> Vec3 {
    let (w, h) = (image.width as i64, image.height as i64);
    if w == 0 || h == 0 || !uv.is_finite() {
        return Vec3::ZERO;
    }
    let [wu, wv] = sampling.wrap;
    // The image's rows run down: row coordinate (1 - v) h. Wrapping in it is wrapping in glTF's
    // t = 1 - v, whose mirror and clamp are glTF's.
    let x = wrapped(uv.x * w as f32, w, wu);
    let y = wrapped((1.0 - uv.y) * h as f32, h, wv);
    let at = |i: i64, j: i64| image.pixels[(texel_index(j, h, wv) * w + texel_index(i, w, wu)) as usize];
    if sampling.nearest {
        return at(x.floor() as i64, y.floor() as i64);
    }
    let (x, y) = (x - 0.5, y - 0.5);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (i, j) = (x0 as i64, y0 as i64);
    (at(i, j) * (1.0 - fx) + at(i + 1, j) * fx) * (1.0 - fy)
        + (at(i, j + 1) * (1.0 - fx) + at(i + 1, j + 1) * fx) * fy
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

    /// A checker image of `n` x `n` texels, checks of `check` texels, 1 and 0.
    fn checker(n: u32, check: u32) -> Texture {
        let mut img = Image::new(n, n);
        for y in 0..n {
            for x in 0..n {
                img.set(x, y, Vec3::splat(((x / check + y / check) % 2) as f32));
            }
        }
        Texture::image(Arc::new(img), Vec2::ONE, None, Sampling::default())
    }

    #[test]
    fn the_mip_level_is_the_log2_of_the_footprint_in_texels() {
        let t = checker(256, 1);
        // Within a texel (or a point): the image itself; 4 texels: level 2; 64: level 6.
        assert_eq!(t.level(0.0), 0.0);
        assert_eq!(t.level(1.0 / 256.0), 0.0);
        assert_eq!(t.level(4.0 / 256.0), 2.0);
        assert_eq!(t.level(64.0 / 256.0), 6.0);
        // A repeat of 4 makes each unit of (u, v) four times the texels.
        let Texture::Image { image, .. } = &t else { unreachable!() };
        let repeated = Texture::image(image.clone(), Vec2::splat(4.0), None, Sampling::default());
        assert_eq!(repeated.level(4.0 / 256.0), 4.0);
        // A nearest sampler keeps no mipmaps and reads the texel whatever the footprint.
        let nearest =
            Texture::image(image.clone(), Vec2::ONE, None, Sampling { nearest: true, ..Default::default() });
        let uv = Vec2::new(0.5 / 256.0, 1.0 - 0.5 / 256.0);
        assert_eq!(nearest.color_over(DVec3::ZERO, uv, 0.5), nearest.color(DVec3::ZERO, uv));
    }

    #[test]
    fn mipmaps_halve_to_one_texel_and_keep_the_mean() {
        let t = checker(256, 1);
        let Texture::Image { mips, image, .. } = &t else { unreachable!() };
        assert_eq!(mips.len(), 8);
        for k in 1..=8 {
            let level = mips.level(k).expect("level");
            assert_eq!((level.width, level.height), (256 >> k, 256 >> k));
            assert!((level.mean() - image.mean()).abs().max_element() < 1e-6, "level {k}");
        }
        // Level 1 of a one-texel checker is grey everywhere: the mean of each 2 x 2 block.
        assert!(mips.level(1).expect("1").pixels.iter().all(|p| (p.x - 0.5).abs() < 1e-6));
        // Odd sizes round up, the edge texel counted twice: 5 x 3, 3 x 2, 2 x 1, 1 x 1.
        let odd = Mips::of(&Image::new(5, 3));
        let sizes: Vec<(u32, u32)> =
            (1..=odd.len()).map(|k| odd.level(k).map_or((0, 0), |l| (l.width, l.height))).collect();
        assert_eq!(sizes, [(3, 2), (2, 1), (1, 1)]);
    }

    #[test]
    fn a_lookup_over_a_footprint_blends_its_levels_and_a_small_one_is_the_point() {
        let t = checker(256, 4);
        let uv = Vec2::new(0.3, 0.6);
        // Within a texel: the point lookup, bit for bit (near textures keep their detail).
        assert_eq!(t.color_over(DVec3::ZERO, uv, 0.5 / 256.0), t.color(DVec3::ZERO, uv));
        // Wider than the checks: their mean, 0.5.
        let wide = t.color_over(DVec3::ZERO, uv, 32.0 / 256.0);
        assert!((wide.x - 0.5).abs() < 1e-3, "{wide}");
        // Between levels 1 and 2, trilinear: the levels' values blended by the fraction.
        let Texture::Image { mips, sampling, .. } = &t else { unreachable!() };
        let (l1, l2) = (
            lookup(mips.level(1).expect("1"), uv, sampling),
            lookup(mips.level(2).expect("2"), uv, sampling),
        );
        let mid = t.color_over(DVec3::ZERO, uv, 2f32.powf(1.25) / 256.0);
        assert!((mid - (l1 * 0.75 + l2 * 0.25)).abs().max_element() < 1e-5, "{mid} {l1} {l2}");
    }

    #[test]
    fn images_wrap_and_v_runs_up() {
        let mut img = Image::new(2, 2);
        img.set(0, 0, Vec3::new(1.0, 0.0, 0.0)); // top left
        img.set(0, 1, Vec3::new(0.0, 1.0, 0.0)); // bottom left
        let t = Texture::image(Arc::new(img), Vec2::ONE, None, Sampling::default());
        // Pixel centres: (0.25, 0.75) is the top-left pixel, (0.25, 0.25) the bottom-left.
        assert_eq!(t.color(DVec3::ZERO, Vec2::new(0.25, 0.75)), Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(t.color(DVec3::ZERO, Vec2::new(0.25, 0.25)), Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(t.color(DVec3::ZERO, Vec2::new(1.25, -0.75)), Vec3::new(0.0, 1.0, 0.0));
    }

    #[test]
    fn wrap_modes_and_nearest_lookup_follow_gltf() {
        // A row of three texels, 0, 1 and 2 (left to right), one row high.
        let mut img = Image::new(3, 1);
        for i in 0..3 {
            img.set(i, 0, Vec3::splat(i as f32));
        }
        let image = Arc::new(img);
        let at = |wrap: Wrap, nearest: bool, u: f32| {
            let sampling = Sampling { wrap: [wrap, wrap], nearest, set: 0 };
            lookup(&image, Vec2::new(u, 0.5), &sampling).x
        };
        // Texel centres at u = 1/6, 1/2, 5/6; one past the right edge, at u = 7/6:
        let past = 7.0 / 6.0;
        assert_eq!(at(Wrap::Repeat, true, past), 0.0);
        assert_eq!(at(Wrap::Clamp, true, past), 2.0);
        assert_eq!(at(Wrap::Mirror, true, past), 2.0);
        // Two past: repeat is texel 1, mirror texel 1, clamp still the edge.
        let two = 1.5;
        assert_eq!(at(Wrap::Repeat, true, two), 1.0);
        assert_eq!(at(Wrap::Mirror, true, two), 1.0);
        assert_eq!(at(Wrap::Clamp, true, -5.0), 0.0);
        // Mirrored, u in [1, 2] reads the image backwards: 5/6 past 1 is the first texel.
        assert_eq!(at(Wrap::Mirror, true, 1.0 + 5.0 / 6.0), 0.0);
        // Bilinear halfway between texel 0 and 1, and at the right edge: repeat blends the last
        // texel with the first, clamp and mirror hold the edge's value.
        assert!((at(Wrap::Repeat, false, 1.0 / 3.0) - 0.5).abs() < 1e-5);
        assert!((at(Wrap::Repeat, false, 1.0) - 1.0).abs() < 1e-5);
        assert!((at(Wrap::Clamp, false, 1.0) - 2.0).abs() < 1e-5);
        assert!((at(Wrap::Mirror, false, 1.0) - 2.0).abs() < 1e-5);
        // Nearest does not blend: just right of the centre of texel 0, still 0.
        assert_eq!(at(Wrap::Repeat, true, 0.3), 0.0);
        assert!(at(Wrap::Repeat, false, 0.3) > 0.0);
    }
}
