//! Small geometric and sampling helpers shared by the scene, the integrator and the lights.

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// An orthonormal frame around a unit normal (Duff et al. 2017, "Building an Orthonormal Basis,
/// Revisited"): continuous and without a division by a small number.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
}

impl Frame {
    pub fn new(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    /// From frame coordinates to world.
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }

    /// From world coordinates to the frame's.
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(self.s.dot(v), self.t.dot(v), self.n.dot(v))
    }
}

/// Cosine-weighted direction on the hemisphere around +z; pdf = cos(theta) / pi. Always
/// inlined, the concentric disk with it: called apart, it ran in the portable build even from
/// the path loop's AVX-512 build (`Isa::for_loops`), 7% of the Cornell box's time.
#[inline(always)]
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Shirley-Chiu concentric map of the unit square onto the unit disk. Its angle is a quarter
/// turn's `a` in [-pi/4, pi/4] from an axis, so its sine and cosine are [`sin_cos_quarter`]'s.
#[inline(always)]
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    if o.x.abs() > o.y.abs() {
        // theta = a
        let (sin, cos) = sin_cos_quarter(FRAC_PI_4 * (o.y / o.x));
        o.x * Vec2::new(cos, sin)
    } else {
        // theta = pi/2 - a: its cosine is sin(a), its sine cos(a)
        let (sin, cos) = sin_cos_quarter(FRAC_PI_4 * (o.x / o.y));
        o.y * Vec2::new(sin, cos)
    }
}

/// `(sin x, cos x)` for |x| <= pi/4, by polynomials of degree 7 and 8: no range reduction, no
/// branch, no call. Their coefficients were fitted to f64's sine and cosine on [0, pi/4] (least
/// squares reweighted toward the smallest largest relative error); evaluated in f32 they are
/// within 0.8 ulp (sine) and 1.3 ulp (cosine) of the true values (tested), where glibc's
/// `sinf` and `cosf` are within 0.6 and 0.9. The sampling warps' angles come through here:
/// libm's `sincosf` was 3% to 5% of a render's time.
#[inline(always)]
pub fn sin_cos_quarter(x: f32) -> (f32, f32) {
    let z = x * x;
    let sin = x + x * z * (-0.166_666_55 + z * (0.008_332_161 + z * -0.000_195_153_86));
    let cos = 1.0 - 0.5 * z + z * z * (0.041_666_646 + z * (-0.001_388_731_6 + z * 2.443_323_7e-5));
    (sin, cos)
}

/// `(sin, cos)` of the angle `2 pi t`, `t` turns (finite, |t| <= 1): the nearest quarter turn is
/// taken off exactly (`4 t` and its distance to the nearest whole number are exact in f32),
/// the rest's sine and cosine are [`sin_cos_quarter`]'s, turned by that many quarters.
#[inline(always)]
pub fn sin_cos_turn(t: f32) -> (f32, f32) {
    let v = 4.0 * t;
    // The nearest whole number of quarter turns (a truncation of a positive number, so no call
    // to `roundf` on a CPU without SSE4.1).
    let q = (v + 4.5) as i32 - 4;
    let (s, c) = sin_cos_quarter((v - q as f32) * FRAC_PI_2);
    match q & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// Uniform direction on the unit sphere; pdf = 1 / (4 pi).
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (sin, cos) = sin_cos_turn(u.y);
    Vec3::new(r * cos, r * sin, z)
}

/// Uniform direction in the cone around +z whose solid angle is `2 pi one_minus_cos`. Taking
/// 1 - cos(theta_max) rather than cos(theta_max) keeps tiny cones (the sun: about 2e-5) exact in
/// f32. pdf = 1 / (2 pi one_minus_cos).
pub fn uniform_cone(u: Vec2, one_minus_cos: f32) -> Vec3 {
    let omc = u.x * one_minus_cos; // 1 - cos(theta), exact for small angles
    let cos_theta = 1.0 - omc;
    let sin_theta = (omc * (2.0 - omc)).max(0.0).sqrt();
    let (sin, cos) = sin_cos_turn(u.y);
    Vec3::new(sin_theta * cos, sin_theta * sin, cos_theta)
}

/// 1 - cos of the angle between two unit vectors, accurate near 0 (|a - b|^2 = 2 (1 - cos)).
pub fn one_minus_cos_between(a: Vec3, b: Vec3) -> f32 {
    0.5 * (a - b).length_squared()
}

/// Uniform barycentric weights of a triangle's second and third vertices (pbrt-v4's
/// equal-area square-to-triangle map).
pub fn uniform_triangle(u: Vec2) -> Vec2 {
    if u.x < u.y {
        let b0 = u.x / 2.0;
        Vec2::new(b0, u.y - b0)
    } else {
        let b1 = u.y / 2.0;
        Vec2::new(u.x - b1, b1)
    }
}

/// Moves a ray origin off the surface at `p` with geometric normal `n`, to the side of `n`, by
/// whole float ulps scaled with the magnitude of `p` (Wächter & Binder, "A Fast and Robust Method
/// for Avoiding Self-Intersection", Ray Tracing Gems, ch. 6). No epsilon in t.
///
/// `magnitude` is the largest absolute coordinate of what `p` was computed from (a triangle's
/// corners, a sphere's centre plus its radius): the rounding error of `p`, and of the next
/// intersection test near it, is a few ulps of that, whatever `p`'s own coordinates are. So a
/// coordinate at least half the magnitude moves by `OFFSET_ULPS` of its own ulps (W&B's integer
/// step), and a smaller one (near a zero crossing, where its own ulps are too fine) by as many of
/// half the magnitude's. W&B take a fixed 1/65536 there, and 256 ulps everywhere, which is right
/// for hit points computed as o + t d in scenes of unit size; here every hit point is rebuilt
/// from the primitive (barycentric, or projected onto the sphere) and the offset follows the
/// scene's scale. `lightsplit stress` measures the choice: self-hits appear at 2 ulps and are
/// gone at 4 on every row; 8 leaves a factor of 2.
pub fn offset_ray_origin(p: Vec3, n: Vec3, magnitude: f32) -> Vec3 {
    let small = 0.5 * magnitude.max(f32::MIN_POSITIVE);
    let float_step = small * OFFSET_ULPS * f32::EPSILON;
    let of_i = (n * OFFSET_ULPS).as_ivec3();
    let step = |p: f32, o: i32, n: f32| {
        if p.abs() < small {
            return p + float_step * n;
        }
        let bits = p.to_bits() as i32;
        f32::from_bits((if p < 0.0 { bits - o } else { bits + o }) as u32)
    };
    Vec3::new(step(p.x, of_i.x, n.x), step(p.y, of_i.y, n.y), step(p.z, of_i.z, n.z))
}

/// How many ulps [`offset_ray_origin`] moves a coordinate along a unit normal component.
pub const OFFSET_ULPS: f32 = 8.0;

/// The largest absolute coordinate of a triangle's corners (see [`offset_ray_origin`]).
pub fn triangle_magnitude(a: Vec3, b: Vec3, c: Vec3) -> f32 {
    a.abs().max(b.abs()).max(c.abs()).max_element()
}

/// The largest absolute coordinate of a sphere's points, bounded (see [`offset_ray_origin`]).
pub fn sphere_magnitude(center: Vec3, radius: f32) -> f32 {
    center.abs().max_element() + radius
}

/// Rec. 709 luminance of a linear RGB value.
#[inline(always)]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// A discrete distribution over `n` items by weight, sampled by inverting its CDF.
#[derive(Clone, Debug, Default)]
pub struct Distribution1D {
    cdf: Vec<f32>,
    pdf: Vec<f32>,
}

impl Distribution1D {
    /// A distribution proportional to `weights` (negative or non-finite weights count as zero).
    /// Returns `None` when no weight is positive.
    pub fn new(weights: &[f32]) -> Option<Self> {
        let clean = |w: f32| {
            if w.is_finite() && w > 0.0 {
                w as f64
            } else {
                0.0
            }
        };
        let total: f64 = weights.iter().map(|&w| clean(w)).sum();
        if total <= 0.0 {
            return None;
        }
        let mut acc = 0.0f64;
        let mut cdf = Vec::with_capacity(weights.len());
        let mut pdf = Vec::with_capacity(weights.len());
        for &w in weights {
            acc += clean(w);
            cdf.push((acc / total) as f32);
            pdf.push((clean(w) / total) as f32);
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        Some(Distribution1D { cdf, pdf })
    }

    /// Picks an item for `u` in [0, 1); returns its index and probability.
    pub fn sample(&self, u: f32) -> (usize, f32) {
        let i = self.cdf.partition_point(|&c| c <= u).min(self.cdf.len() - 1);
        // Skip zero-probability items that share a CDF value with their neighbour.
        let i = (i..self.pdf.len()).find(|&j| self.pdf[j] > 0.0).unwrap_or(i);
        (i, self.pdf[i])
    }

    /// Like [`Distribution1D::sample`], and also returns `u` rescaled to [0, 1) within the
    /// chosen item's CDF interval, so that one uniform number can drive a second choice.
    pub fn sample_reuse(&self, u: f32) -> (usize, f32, f32) {
        let (i, p) = self.sample(u);
        let lo = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        (i, p, ((u - lo) / p).clamp(0.0, 1.0 - f32::EPSILON / 2.0))
    }

    /// The probability of item `i`.
    pub fn pdf(&self, i: usize) -> f32 {
        self.pdf.get(i).copied().unwrap_or(0.0)
    }

    pub fn len(&self) -> usize {
        self.pdf.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pdf.is_empty()
    }
}

/// A piecewise-constant density over the unit square, `nu` x `nv` cells (row-major, rows along
/// v), sampled by its marginal over rows and then the row's conditional (pbrt's 2D
/// distribution).
#[derive(Clone, Debug)]
pub struct Distribution2D {
    marginal: Distribution1D,
    rows: Vec<Distribution1D>,
    nu: usize,
    nv: usize,
}

impl Distribution2D {
    /// `None` when no weight is positive.
    pub fn new(weights: &[f32], nu: usize, nv: usize) -> Option<Self> {
        assert_eq!(weights.len(), nu * nv, "weights must fill the grid");
        let row_sums: Vec<f32> = weights.chunks(nu).map(|r| r.iter().map(|w| w.max(0.0)).sum()).collect();
        let marginal = Distribution1D::new(&row_sums)?;
        let rows = weights
            .chunks(nu)
            .map(|r| {
                Distribution1D::new(r)
                    .unwrap_or_else(|| Distribution1D::new(&vec![1.0; nu]).unwrap_or_default())
            })
            .collect();
        Some(Distribution2D { marginal, rows, nu, nv })
    }

    /// A point of the unit square and its density.
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (row, pm, uv) = self.marginal.sample_reuse(u.y);
        let (col, pc, uu) = self.rows[row].sample_reuse(u.x);
        let p = Vec2::new((col as f32 + uu) / self.nu as f32, (row as f32 + uv) / self.nv as f32);
        (p, pm * pc * (self.nu * self.nv) as f32)
    }

    /// The density at a point of the unit square.
    pub fn pdf(&self, p: Vec2) -> f32 {
        let col = ((p.x * self.nu as f32) as usize).min(self.nu - 1);
        let row = ((p.y * self.nv as f32) as usize).min(self.nv - 1);
        self.marginal.pdf(row) * self.rows[row].pdf(col) * (self.nu * self.nv) as f32
    }
}

/// The solid angle of the unit sphere.
pub const FOUR_PI: f32 = 4.0 * PI;

/// FNV-1a, 64 bits: a stable hash for cache names and run keys (std's hasher may change between
/// releases).
pub struct Fnv(pub u64);

impl Default for Fnv {
    fn default() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The quarter turn's polynomials against f64's sine and cosine, in units in the last place
    /// of the true value, over 2^20 + 1 points of [-pi/4, pi/4]: within their stated bounds.
    #[test]
    fn quarter_turn_sine_and_cosine_are_within_their_ulps() {
        let ulp = |t: f64| (t.abs() as f32).to_bits().wrapping_add(1);
        let ulp = |t: f64| (f32::from_bits(ulp(t)) - t.abs() as f32) as f64;
        let n = 1 << 20;
        let (mut worst_sin, mut worst_cos) = (0.0f64, 0.0f64);
        for i in 0..=n {
            let x = (-FRAC_PI_4 as f64 + (FRAC_PI_2 as f64) * i as f64 / n as f64) as f32;
            let (s, c) = sin_cos_quarter(x);
            let (ts, tc) = (x as f64).sin_cos();
            if ts != 0.0 {
                worst_sin = worst_sin.max((s as f64 - ts).abs() / ulp(ts));
            }
            worst_cos = worst_cos.max((c as f64 - tc).abs() / ulp(tc));
        }
        assert!(worst_sin <= 0.8 && worst_cos <= 1.3, "sin {worst_sin} ulp, cos {worst_cos} ulp");
    }

    /// A turn's sine and cosine: exact at the quarter turns, and within 1.5e-7 of f64's over
    /// [-1, 1] turns (the reduction adds one rounding of the angle).
    #[test]
    fn sine_and_cosine_of_turns() {
        for (t, want) in [(0.0, (0.0, 1.0)), (0.25, (1.0, 0.0)), (0.5, (0.0, -1.0)), (0.75, (-1.0, 0.0))] {
            assert_eq!(sin_cos_turn(t), want, "{t}");
            assert_eq!(sin_cos_turn(t - 1.0), want, "{t} - 1");
        }
        let n = 1 << 20;
        let mut worst = 0.0f64;
        for i in 0..=n {
            let t = (-1.0 + 2.0 * i as f64 / n as f64) as f32;
            let (s, c) = sin_cos_turn(t);
            let (ts, tc) = (std::f64::consts::TAU * t as f64).sin_cos();
            worst = worst.max((s as f64 - ts).abs()).max((c as f64 - tc).abs());
        }
        assert!(worst <= 1.5e-7, "{worst}");
    }

    #[test]
    fn frame_is_orthonormal() {
        for n in [Vec3::Z, -Vec3::Z, Vec3::X, Vec3::new(0.3, -0.5, 0.8).normalize()] {
            let f = Frame::new(n);
            assert!((f.s.length() - 1.0).abs() < 1e-5 && (f.t.length() - 1.0).abs() < 1e-5);
            assert!(f.s.dot(f.t).abs() < 1e-5 && f.s.dot(n).abs() < 1e-5 && f.t.dot(n).abs() < 1e-5);
            assert!((f.s.cross(f.t) - n).length() < 1e-5);
        }
    }

    #[test]
    fn cone_keeps_tiny_angles() {
        // The sun: 0.53 degrees across. In f32, cos(half angle) rounds; 1 - cos must not.
        let half = (0.53f64 / 2.0).to_radians();
        let omc = (2.0 * (half / 2.0).sin().powi(2)) as f32;
        for u in [Vec2::new(0.0, 0.3), Vec2::new(0.999, 0.7), Vec2::new(0.5, 0.1)] {
            let d = uniform_cone(u, omc);
            assert!((d.length() - 1.0).abs() < 1e-6);
            let got = one_minus_cos_between(d, Vec3::Z);
            assert!(got <= omc * 1.0001, "{got} > {omc}");
            assert!((got - u.x * omc).abs() <= 1e-3 * omc, "{got} vs {}", u.x * omc);
        }
    }

    #[test]
    fn offset_leaves_the_surface_on_the_normal_side() {
        for p in [Vec3::ZERO, Vec3::new(1e6, -3.0, 0.01), Vec3::new(-123.4, 5e-3, 7e4), Vec3::splat(-2e-7)] {
            for n in [Vec3::Y, -Vec3::Y, Vec3::new(0.6, 0.0, -0.8)] {
                // The magnitude of a primitive around p: p's own, or a larger one.
                for m in [p.abs().max_element(), p.abs().max_element() + 1.0] {
                    let o = offset_ray_origin(p, n, m);
                    assert!((o - p).dot(n) > 0.0, "{p} {n} {m} -> {o}");
                    // At most OFFSET_ULPS ulps of the magnitude on each axis.
                    let bound = 3f32.sqrt() * OFFSET_ULPS * f32::EPSILON * m.max(f32::MIN_POSITIVE);
                    assert!((o - p).length() <= bound, "{p} {n} {m} -> {o}");
                }
            }
        }
        // Scale-invariant: a scene scaled by a power of two moves its origins by the same factor.
        let (p, n) = (Vec3::new(0.3, 0.0, -0.7), Vec3::new(0.0, 0.8, 0.6));
        let o = offset_ray_origin(p, n, 1.0) - p;
        for s in [2f32.powi(-20), 2f32.powi(17)] {
            assert_eq!(offset_ray_origin(p * s, n, s) - p * s, o * s);
        }
    }

    #[test]
    fn distribution_matches_weights() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0]).expect("positive weights");
        assert_eq!(d.pdf(0), 0.25);
        assert_eq!(d.pdf(1), 0.0);
        assert_eq!(d.sample(0.1), (0, 0.25));
        assert_eq!(d.sample(0.25), (2, 0.75));
        assert_eq!(d.sample(0.999_999), (2, 0.75));
        assert!(Distribution1D::new(&[0.0, f32::NAN]).is_none());
    }

    #[test]
    fn triangle_samples_stay_inside() {
        for i in 0..100 {
            let u = Vec2::new((i % 10) as f32 / 10.0 + 0.05, (i / 10) as f32 / 10.0 + 0.05);
            let b = uniform_triangle(u);
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6, "{b}");
        }
    }
}

/// Chi-square tests of the direction sampling routines against their densities (as pbrt does):
/// directions binned in (cos theta, phi), expected counts from integrating the pdf over each bin,
/// bins with fewer than 5 expected samples pooled, and the statistic's tail probability from the
/// Wilson-Hilferty normal approximation. The samplers are seeded, so the tests are repeatable.
#[cfg(test)]
pub(crate) mod chi_square {
    use super::*;
    use crate::render::sampler::Sampler;
    use std::f32::consts::TAU;

    const THETA: usize = 16;
    const PHI: usize = 32;
    const SAMPLES: usize = 200_000;

    fn bin(d: Vec3) -> usize {
        let t = (((d.z.clamp(-1.0, 1.0) + 1.0) * 0.5 * THETA as f32) as usize).min(THETA - 1);
        let phi = d.y.atan2(d.x).rem_euclid(TAU);
        let p = ((phi / TAU * PHI as f32) as usize).min(PHI - 1);
        t * PHI + p
    }

    /// The z-score of the chi-square statistic of `SAMPLES` calls of `sample` (a call may give
    /// no direction: the pdf then integrates to less than one) against `pdf`; tests fail above 4
    /// (p below about 3e-5).
    pub fn z_score(mut sample: impl FnMut(&mut Sampler) -> Option<Vec3>, pdf: impl Fn(Vec3) -> f32) -> f64 {
        let mut observed = vec![0.0f64; THETA * PHI];
        let mut s = Sampler::new(17, 3, 5);
        for _ in 0..SAMPLES {
            let Some(d) = sample(&mut s) else { continue };
            assert!((d.length() - 1.0).abs() < 1e-4, "not a unit direction: {d}");
            observed[bin(d)] += 1.0;
        }
        // Expected: the pdf integrated over each bin (midpoint rule, 32x32 per bin, fine enough
        // for densities with edges inside a bin).
        let mut expected = vec![0.0f64; THETA * PHI];
        let sub = 32;
        for t in 0..THETA * sub {
            let z = -1.0 + (t as f64 + 0.5) / (THETA * sub) as f64 * 2.0;
            for p in 0..PHI * sub {
                let phi = (p as f64 + 0.5) / (PHI * sub) as f64 * std::f64::consts::TAU;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let d = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                let area = 2.0 / (THETA * sub) as f64 * std::f64::consts::TAU / (PHI * sub) as f64;
                expected[(t / sub) * PHI + p / sub] += pdf(d) as f64 * area * SAMPLES as f64;
            }
        }
        let (mut chi2, mut dof, mut pool_o, mut pool_e) = (0.0, 0usize, 0.0, 0.0);
        for (o, e) in observed.iter().zip(&expected) {
            if *e < 5.0 {
                pool_o += o;
                pool_e += e;
            } else {
                chi2 += (o - e) * (o - e) / e;
                dof += 1;
            }
        }
        if pool_e >= 5.0 {
            chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
            dof += 1;
        } else {
            // Bins with almost no expected samples: a density edge that grazes a bin can put a
            // few samples where the quadrature sees next to nothing.
            let slack = 1e-4 * SAMPLES as f64;
            assert!(pool_o <= slack + 5.0 * pool_e, "{pool_o} samples where the pdf expects {pool_e}");
        }
        let k = (dof - 1) as f64;
        ((chi2 / k).cbrt() - (1.0 - 2.0 / (9.0 * k))) / (2.0 / (9.0 * k)).sqrt()
    }

    #[test]
    fn cosine_hemisphere_matches_cos_over_pi() {
        let z = z_score(|s| Some(cosine_hemisphere(s.next_2d())), |d| d.z.max(0.0) / PI);
        assert!(z < 4.0, "z = {z}");
    }

    #[test]
    fn uniform_sphere_matches_one_over_four_pi() {
        let z = z_score(|s| Some(uniform_sphere(s.next_2d())), |_| 1.0 / FOUR_PI);
        assert!(z < 4.0, "z = {z}");
    }

    #[test]
    fn uniform_cone_matches_its_density() {
        // The cone edge on a bin edge (cos theta = 0.75), so bins are either in or out.
        let omc = 0.25;
        let z = z_score(
            |s| Some(uniform_cone(s.next_2d(), omc)),
            |d| if 1.0 - d.z <= omc { 1.0 / (TAU * omc) } else { 0.0 },
        );
        assert!(z < 4.0, "z = {z}");
    }

    #[test]
    fn a_wrong_density_fails() {
        // The test has power: cosine samples judged against a uniform hemisphere must fail.
        let z =
            z_score(|s| Some(cosine_hemisphere(s.next_2d())), |d| if d.z > 0.0 { 1.0 / TAU } else { 0.0 });
        assert!(z > 10.0, "z = {z}");
    }
}
