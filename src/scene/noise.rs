//! Gradient noise (Perlin's improved noise, 2002, with gradients chosen by an integer hash so any
//! seed gives its own field) and fractal sums of it. Deterministic, with values in [-1, 1].

use glam::Vec3;

use crate::accel::bvh::simd::{Inlined, Isa};

/// A 32-bit integer hash (lowbias32, Wellons 2018).
fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// Perlin's 12 edge gradients, with four of them repeated to make 16 (his 2002 trick), so a
/// hash's low four bits pick one without a branch ([`gradient`] reads it as two bit masks).
const GRADIENTS: [[f32; 3]; 16] = [
    [1.0, 1.0, 0.0],
    [-1.0, 1.0, 0.0],
    [1.0, -1.0, 0.0],
    [-1.0, -1.0, 0.0],
    [1.0, 0.0, 1.0],
    [-1.0, 0.0, 1.0],
    [1.0, 0.0, -1.0],
    [-1.0, 0.0, -1.0],
    [0.0, 1.0, 1.0],
    [0.0, -1.0, 1.0],
    [0.0, 1.0, -1.0],
    [0.0, -1.0, -1.0],
    [1.0, 1.0, 0.0],
    [-1.0, 1.0, 0.0],
    [0.0, -1.0, 1.0],
    [0.0, -1.0, -1.0],
];

/// Bit `i` set where component `c` of gradient `i` is non-zero (`negative` false) or negative.
const fn gradient_bits(c: usize, negative: bool) -> u32 {
    let (mut bits, mut i) = (0, 0);
    while i < 16 {
        let g = GRADIENTS[i][c];
        if (negative && g < 0.0) || (!negative && g != 0.0) {
            bits |= 1 << i;
        }
        i += 1;
    }
    bits
}

const NONZERO: [u32; 3] = [gradient_bits(0, false), gradient_bits(1, false), gradient_bits(2, false)];
const NEGATIVE: [u32; 3] = [gradient_bits(0, true), gradient_bits(1, true), gradient_bits(2, true)];

/// Component `c` of the gradient that hash `h` picks (`GRADIENTS[h & 15][c]`, bit for bit), by
/// shifts of two masks instead of a table lookup: eight lanes of it vectorise.
#[inline(always)]
fn gradient(c: usize, h: u32) -> f32 {
    let i = h & 15;
    f32::from_bits((((NONZERO[c] >> i) & 1) * 0x3F80_0000) | (((NEGATIVE[c] >> i) & 1) << 31))
}

fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lerp(t: f32, a: f32, b: f32) -> f32 {
    a + t * (b - a)
}

/// Perlin noise at `p`, in [-1, 1], zero at every lattice point.
pub fn perlin(seed: u32, p: Vec3) -> f32 {
    run(Octaves { seed, p, octaves: 1, gain: 1.0, sum: Sum::One })
}

/// Fractional Brownian motion: `octaves` octaves of Perlin noise, each at twice the frequency and
/// `gain` times the amplitude of the last, normalised back to [-1, 1].
pub fn fbm(seed: u32, p: Vec3, octaves: u32, gain: f32) -> f32 {
    run(Octaves { seed, p, octaves, gain, sum: Sum::Noise })
}

/// Turbulence: `octaves` octaves of |Perlin noise|, each at twice the frequency and half the
/// amplitude of the last, normalised to [0, 1].
pub fn turbulence(seed: u32, p: Vec3, octaves: u32) -> f32 {
    run(Octaves { seed, p, octaves, gain: 0.5, sum: Sum::Magnitude })
}

/// `job` in the best build this CPU has (detected once): its lanes with AVX2 or AVX-512, else
/// the scalar form (the same bits).
fn run(job: Octaves) -> f32 {
    static BEST: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
    match *BEST.get_or_init(Isa::best) {
        Isa::Portable => octaves_scalar(job),
        isa => isa.run(job),
    }
}

/// What [`Octaves`] adds up.
#[derive(Clone, Copy, PartialEq)]
enum Sum {
    /// One octave's noise as it is (no sum: -0.0 stays -0.0).
    One,
    /// The noise (fBm).
    Noise,
    /// Its magnitude (turbulence).
    Magnitude,
}

/// A sum of octaves of noise, as a job: compiled in the best build the CPU has ([`Isa::best`],
/// AVX2 or AVX-512), where the eight corners' hashes are a few vector multiplies (a CPU without
/// AVX2 runs [`octaves_scalar`] instead); the same bits in any. The noise is latency-bound
/// (four hashes in a chain), so independent octaves are evaluated together, four at a time,
/// then two, then one: their chains interleave.
struct Octaves {
    seed: u32,
    p: Vec3,
    octaves: u32,
    gain: f32,
    sum: Sum,
}

impl Inlined for Octaves {
    type Output = f32;

    #[inline(always)]
    fn run(self) -> f32 {
        let Octaves { seed, p, octaves, gain, sum: kind } = self;
        if kind == Sum::One {
            let [n] = perlin_lanes([seed], [p]);
            return n;
        }
        let seed = |o: u32| seed.wrapping_add(o);
        let (mut sum, mut amp, mut norm) = (0.0f32, 1.0f32, 0.0f32);
        let mut add = |n: &[f32]| {
            for &n in n {
                sum += amp * if kind == Sum::Magnitude { n.abs() } else { n };
                norm += amp;
                amp *= gain;
            }
        };
        let (octaves, mut o, mut q) = (octaves.max(1), 0, p);
        while o + 3 < octaves {
            let (q2, q4) = (q * 2.0, q * 4.0);
            add(&perlin_lanes([seed(o), seed(o + 1), seed(o + 2), seed(o + 3)], [q, q2, q4, q4 * 2.0]));
            q = q4 * 4.0;
            o += 4;
        }
        if o + 1 < octaves {
            add(&perlin_lanes([seed(o), seed(o + 1)], [q, q * 2.0]));
            q *= 4.0;
            o += 2;
        }
        if o < octaves {
            add(&perlin_lanes([seed(o)], [q]));
        }
        sum / norm
    }
}

/// Perlin noise at each of the `P` points `p` (of seeds `seed`): each cube's eight corners as
/// eight lanes (corner `i + 2j + 4k` at offset `(i, j, k)`), each hashed to a gradient dotted
/// with the offset from it, then blended by the faded fractions. The hashes nest so that each z
/// and (y, z) is hashed once. Several points interleave their chains of dependent hashes.
#[inline(always)]
fn perlin_lanes<const P: usize>(seed: [u32; P], p: [Vec3; P]) -> [f32; P] {
    let mut out = [0.0f32; P];
    let mut g = [[0.0f32; 8]; P];
    let mut fades = [Vec3::ZERO; P];
    for k in 0..P {
        let f = p[k].floor();
        let (x0, y0, z0) = (f.x as i32, f.y as i32, f.z as i32);
        let d = p[k] - f;
        fades[k] = Vec3::new(fade(d.x), fade(d.y), fade(d.z));
        let hz = [hash(z0 as u32), hash(z0.wrapping_add(1) as u32)];
        let (y1, x1) = (y0.wrapping_add(1) as u32, x0.wrapping_add(1) as u32);
        let hy = [hash(y0 as u32 ^ hz[0]), hash(y1 ^ hz[0]), hash(y0 as u32 ^ hz[1]), hash(y1 ^ hz[1])];
        let xs = [x0 as u32, x1, x0 as u32, x1, x0 as u32, x1, x0 as u32, x1];
        let hys = [hy[0], hy[0], hy[1], hy[1], hy[2], hy[2], hy[3], hy[3]];
        let (dx0, dx1, dy0, dy1, dz0, dz1) = (d.x, d.x - 1.0, d.y, d.y - 1.0, d.z, d.z - 1.0);
        let dx = [dx0, dx1, dx0, dx1, dx0, dx1, dx0, dx1];
        let dy = [dy0, dy0, dy1, dy1, dy0, dy0, dy1, dy1];
        let dz = [dz0, dz0, dz0, dz0, dz1, dz1, dz1, dz1];
        for l in 0..8 {
            let h = hash(seed[k] ^ hash(xs[l] ^ hys[l]));
            g[k][l] = gradient(0, h) * dx[l] + gradient(1, h) * dy[l] + gradient(2, h) * dz[l];
        }
    }
    for k in 0..P {
        let (g, f) = (g[k], fades[k]);
        let a = [lerp(f.x, g[0], g[1]), lerp(f.x, g[2], g[3]), lerp(f.x, g[4], g[5]), lerp(f.x, g[6], g[7])];
        let n = lerp(f.z, lerp(f.y, a[0], a[1]), lerp(f.y, a[2], a[3]));
        // The 12-gradient form stays within about [-1.04, 1.04]; clamp to the documented range.
        out[k] = n.clamp(-1.0, 1.0);
    }
    out
}

/// Perlin noise at `p`, one corner at a time with the table of gradients: the form for the
/// portable build, where the lanes' multiplies and variable shifts of 32-bit integers have
/// no SSE2 instruction and took 1.5x as long. The lanes give its bits (tested).
fn perlin_scalar(seed: u32, p: Vec3) -> f32 {
    let f = p.floor();
    let (x0, y0, z0) = (f.x as i32, f.y as i32, f.z as i32);
    let d = p - f;
    let (u, v, w) = (fade(d.x), fade(d.y), fade(d.z));
    // The corners' hashes, nested so that each z and (y, z) is hashed once: 14 hashes, not 32.
    let hz = [hash(z0 as u32), hash(z0.wrapping_add(1) as u32)];
    let hyz = |j: i32, k: usize| hash(y0.wrapping_add(j) as u32 ^ hz[k]);
    let hy = [[hyz(0, 0), hyz(0, 1)], [hyz(1, 0), hyz(1, 1)]];
    let g = |i: i32, j: i32, k: i32| {
        let h = hash(seed ^ hash(x0.wrapping_add(i) as u32 ^ hy[j as usize][k as usize]));
        let [gx, gy, gz] = GRADIENTS[(h & 15) as usize];
        gx * (d.x - i as f32) + gy * (d.y - j as f32) + gz * (d.z - k as f32)
    };
    let n = lerp(
        w,
        lerp(v, lerp(u, g(0, 0, 0), g(1, 0, 0)), lerp(u, g(0, 1, 0), g(1, 1, 0))),
        lerp(v, lerp(u, g(0, 0, 1), g(1, 0, 1)), lerp(u, g(0, 1, 1), g(1, 1, 1))),
    );
    n.clamp(-1.0, 1.0)
}

/// [`Octaves`] one octave at a time in [`perlin_scalar`]: the portable build's form.
fn octaves_scalar(Octaves { seed, p, octaves, gain, sum: kind }: Octaves) -> f32 {
    if kind == Sum::One {
        return perlin_scalar(seed, p);
    }
    let (mut sum, mut amp, mut norm, mut q) = (0.0, 1.0, 0.0, p);
    for o in 0..octaves.max(1) {
        let n = perlin_scalar(seed.wrapping_add(o), q);
        sum += amp * if kind == Sum::Magnitude { n.abs() } else { n };
        norm += amp;
        amp *= gain;
        q *= 2.0;
    }
    sum / norm
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradients_by_shifts_are_the_table() {
        for h in 0..64u32 {
            for (c, g) in GRADIENTS[(h & 15) as usize].into_iter().enumerate() {
                assert_eq!(gradient(c, h).to_bits(), g.to_bits(), "{h} {c}");
            }
        }
    }

    /// Octaves four, two and one at a time, in the portable build, the AVX2 one and the widest
    /// one, give the bits of the first form: points on and off the lattice, negative, far out.
    #[test]
    fn the_lanes_give_the_first_forms_bits_in_every_build() {
        let mut checked = 0;
        for i in 0..4000 {
            let t = i as f32;
            let p = match i % 4 {
                0 => Vec3::new(t * 0.137 - 200.0, (i % 97) as f32 * -0.31, (i % 13) as f32 * 0.77),
                1 => Vec3::new((i % 11) as f32 - 5.0, (i % 7) as f32, -((i % 5) as f32)),
                2 => Vec3::new(t * 1e3, -t * 7e2, t * 0.5),
                _ => Vec3::new(-0.0, t * 1e-6, -t * 1e-7),
            };
            for (octaves, sum) in [
                (1, Sum::One),
                (1, Sum::Noise),
                (3, Sum::Noise),
                (6, Sum::Magnitude),
                (7, Sum::Noise),
                (10, Sum::Noise),
            ] {
                let gain = if sum == Sum::Magnitude { 0.5 } else { 0.45 };
                let job = || Octaves { seed: i, p, octaves, gain, sum };
                let want = octaves_scalar(job());
                for (name, got) in Isa::all().into_iter().map(|k| (k.name(), k.run(job()))) {
                    assert_eq!(
                        got.to_bits(),
                        want.to_bits(),
                        "{name}: {p} {octaves} octaves: {got} against {want}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked >= 4000 * 6 * 2);
    }

    #[test]
    fn noise_is_deterministic_in_range_and_varies() {
        let mut min: f32 = 1.0;
        let mut max: f32 = -1.0;
        for i in 0..20_000 {
            let p = Vec3::new(i as f32 * 0.137, (i % 97) as f32 * 0.31, (i % 13) as f32 * 0.77);
            let n = perlin(7, p);
            assert_eq!(n, perlin(7, p));
            assert!((-1.0..=1.0).contains(&n));
            let f = fbm(7, p, 6, 0.5);
            assert!((-1.0..=1.0).contains(&f));
            min = min.min(n);
            max = max.max(n);
        }
        assert!(min < -0.5 && max > 0.5, "range [{min}, {max}] too narrow");
        assert_eq!(perlin(7, Vec3::new(3.0, -2.0, 5.0)), 0.0);
        assert_ne!(perlin(7, Vec3::splat(0.5)), perlin(8, Vec3::splat(0.5)));
    }
}
