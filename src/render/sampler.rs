//! The random numbers of one path sample. Each (seed, pixel, sample index) starts its own stream,
//! so a pixel's value never depends on which thread rendered it or in what order.

use glam::Vec2;

/// SplitMix64's finaliser: a bijective 64-bit mix.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// PCG32 (O'Neill 2014): small, fast and statistically sound for path sampling.
#[derive(Clone, Debug)]
pub struct Sampler {
    state: u64,
    inc: u64,
}

impl Sampler {
    /// The stream of sample `sample` of pixel `pixel` under `seed`.
    pub fn new(seed: u64, pixel: u64, sample: u64) -> Self {
        let a = mix(seed ^ 0x9e37_79b9_7f4a_7c15);
        let b = mix(a ^ pixel);
        let c = mix(b.wrapping_add(sample.wrapping_mul(0x632b_e59b_d9b4_e019)));
        let mut s = Sampler { state: 0, inc: (mix(c ^ 0xda94_2042_e4dd_58b5) << 1) | 1 };
        s.state = c.wrapping_add(s.inc);
        s.next_u32();
        s
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1).
    pub fn next_1d(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Two uniform numbers in [0, 1).
    pub fn next_2d(&mut self) -> Vec2 {
        Vec2::new(self.next_1d(), self.next_1d())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: Vec<u32> = (0..8)
            .map({
                let mut s = Sampler::new(1, 2, 3);
                move |_| s.next_u32()
            })
            .collect();
        let b: Vec<u32> = (0..8)
            .map({
                let mut s = Sampler::new(1, 2, 3);
                move |_| s.next_u32()
            })
            .collect();
        assert_eq!(a, b);
        for other in [Sampler::new(0, 2, 3), Sampler::new(1, 3, 3), Sampler::new(1, 2, 4)] {
            let mut other = other;
            let c: Vec<u32> = (0..8).map(|_| other.next_u32()).collect();
            assert_ne!(a, c);
        }
    }

    #[test]
    fn uniform_mean_and_range() {
        let mut s = Sampler::new(7, 0, 0);
        let n = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let x = s.next_1d();
            assert!((0.0..1.0).contains(&x));
            sum += x as f64;
        }
        // The mean of n uniforms has standard deviation sqrt(1/12/n) = 0.0009; allow 5 sigma.
        assert!((sum / n as f64 - 0.5).abs() < 5.0 * (1.0 / 12.0 / n as f64).sqrt());
    }
}
