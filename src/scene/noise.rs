//! Gradient noise (Perlin's improved noise, 2002, with gradients chosen by an integer hash so any
//! seed gives its own field) and fractal sums of it. Deterministic, with values in [-1, 1].

use glam::Vec3;

/// A 32-bit integer hash (lowbias32, Wellons 2018).
fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// Perlin's 12 edge gradients, with four of them repeated to make 16 (his 2002 trick), so a
/// hash picks one with a mask and a table lookup instead of a branch.
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

/// Dot product of the gradient that hash `h` picks with (x, y, z).
fn grad(h: u32, x: f32, y: f32, z: f32) -> f32 {
    let [gx, gy, gz] = GRADIENTS[(h & 15) as usize];
    gx * x + gy * y + gz * z
}

fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lerp(t: f32, a: f32, b: f32) -> f32 {
    a + t * (b - a)
}

/// Perlin noise at `p`, in [-1, 1], zero at every lattice point.
pub fn perlin(seed: u32, p: Vec3) -> f32 {
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
        grad(h, d.x - i as f32, d.y - j as f32, d.z - k as f32)
    };
    let n = lerp(
        w,
        lerp(v, lerp(u, g(0, 0, 0), g(1, 0, 0)), lerp(u, g(0, 1, 0), g(1, 1, 0))),
        lerp(v, lerp(u, g(0, 0, 1), g(1, 0, 1)), lerp(u, g(0, 1, 1), g(1, 1, 1))),
    );
    // The 12-gradient form stays within about [-1.04, 1.04]; clamp to the documented range.
    n.clamp(-1.0, 1.0)
}

/// Fractional Brownian motion: `octaves` octaves of Perlin noise, each at twice the frequency and
/// `gain` times the amplitude of the last, normalised back to [-1, 1].
pub fn fbm(seed: u32, p: Vec3, octaves: u32, gain: f32) -> f32 {
    let (mut sum, mut amp, mut norm, mut q) = (0.0, 1.0, 0.0, p);
    for o in 0..octaves.max(1) {
        sum += amp * perlin(seed.wrapping_add(o), q);
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
