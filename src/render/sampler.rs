//! The random numbers of one path sample. Each (seed, pixel, sample index) has its own numbers,
//! so a pixel's value never depends on which thread rendered it, in what order, or when an
//! adaptive render stopped it.
//!
//! Two samplers:
//! - **independent**: a PCG32 stream per (seed, pixel, sample);
//! - **sobol** (the default): Owen-scrambled Sobol points (Burley 2020, "Practical Hash-based
//!   Owen Scrambling", through the `sobol_burley` crate), shuffled and scrambled per pixel and
//!   per seed, so pixels and seeds are statistically independent while a pixel's samples are
//!   stratified against each other.
//!
//! Dimensions are allocated by purpose, not in draw order ([`Dim`]): the pixel position, then at
//! each bounce the light selection, the light point (one per light when every light is
//! sampled), the lobe choice, the BSDF direction and Russian roulette. Each purpose is its own
//! Sobol sequence, shuffled and scrambled with its own seed (Burley's padding): a 2D draw is the
//! sequence's first two dimensions, a (0, 2)-sequence, and a 1D draw its first, so every draw
//! is stratified on its own and independent of the others. Past [`SOBOL_BOUNCES`] a path draws
//! from its independent stream: there the integrand's effective dimension is high and
//! stratification buys little.
//!
//! Only the sequence's first two dimensions are used, so they are computed directly (the van
//! der Corput sequence and the Pascal matrix) instead of from direction-number tables; a test
//! checks them against `sobol_burley`'s tables, whose hash and scramble they use.

use glam::Vec2;

/// SplitMix64's finaliser: a bijective 64-bit mix.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

pub use crate::scene::SamplerKind;

/// What a number is drawn for at the current bounce.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dim {
    /// Which light next-event estimation samples (1D).
    Select,
    /// The point on light `i` (2D): the light chosen, or light `i` when every light is sampled.
    Light(u32),
    /// Which of a BSDF's lobes to sample (1D).
    Lobe,
    /// The BSDF direction (2D).
    Direction,
    /// Russian roulette (1D).
    Roulette,
    /// Whether the guide or the BSDF picks the direction (1D), at a guided vertex.
    Guide,
}

/// Bounces whose numbers come from the Sobol points; deeper ones draw independent numbers. One:
/// the camera ray's hit (its light sample, lobe and direction). Measured at 128x128, 4 seeds,
/// against 4,096 spp: Sobol numbers at the first 1, 2, 3 and 5 bounces are worth 11.4x, 11.3x,
/// 11.6x and 11.6x the samples at 64 spp on `cornell.toml`, and 5.0x, 5.2x, 5.3x and 5.3x on
/// `paper-sky.toml`, while each further bounce costs about 3.5% in samples per second.
pub const SOBOL_BOUNCES: u32 = 1;

/// Sobol points per sequence (`sobol_burley`'s limit); a pixel's samples past it continue in
/// a differently scrambled sequence.
const SEQUENCE: u32 = 1 << 16;

/// PCG32 (O'Neill 2014): small, fast and statistically sound for path sampling.
#[derive(Clone, Debug)]
struct Pcg {
    state: u64,
    inc: u64,
}

impl Pcg {
    fn new(seed: u64, pixel: u64, sample: u64) -> Self {
        let a = mix(seed ^ 0x9e37_79b9_7f4a_7c15);
        let b = mix(a ^ pixel);
        let c = mix(b.wrapping_add(sample.wrapping_mul(0x632b_e59b_d9b4_e019)));
        let mut s = Pcg { state: 0, inc: (mix(c ^ 0xda94_2042_e4dd_58b5) << 1) | 1 };
        s.state = c.wrapping_add(s.inc);
        s.next_u32();
        s
    }

    /// A stream from a 64-bit key (a Sobol sample's key and index).
    fn keyed(key: u64) -> Self {
        let c = mix(key ^ 0x5851_f42d_4c95_7f2d);
        let mut s = Pcg { state: 0, inc: (mix(c ^ 0xda94_2042_e4dd_58b5) << 1) | 1 };
        s.state = c.wrapping_add(s.inc);
        s.next_u32();
        s
    }

    fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }
}

/// A sequence's shuffle and its two dimensions' scrambles, from its 64-bit seed.
#[derive(Clone, Copy, Debug)]
struct Scrambles {
    shuffle: u32,
    x: u32,
    y: u32,
}

impl Scrambles {
    #[inline(always)]
    fn of(seed: u64) -> Self {
        let hi = (seed >> 32) as u32;
        Scrambles { shuffle: seed as u32, x: hi, y: sobol_burley::parts::hash(hi) }
    }
}

/// The purposes at the camera ray's hit whose scrambles a pixel makes once for all its samples
/// (the others are made when drawn): the pixel position, the light selection, the lobe, the
/// direction, the first light.
const CACHED: [Option<Dim>; 5] =
    [None, Some(Dim::Select), Some(Dim::Lobe), Some(Dim::Direction), Some(Dim::Light(0))];

/// The Sobol state of one sample.
#[derive(Clone, Debug)]
struct Sobol {
    /// The pixel's and seed's (and sequence block's) hash: every purpose's seed derives from it.
    key: u64,
    /// The point's index in the pixel's sequences, bit-reversed.
    index_rev: u32,
    /// The bounce numbers are drawn for.
    bounce: u32,
    /// The scrambles of [`CACHED`], at bounce 0.
    first: [Scrambles; 5],
}

/// The first 16 digits of a Sobol point's first two dimensions, bit-reversed (the first digit
/// in bit 0), from the 16 low bits of its index `i`: dimension 0 is the van der Corput
/// sequence, the index's bits themselves; dimension 1 the Pascal matrix mod 2 (digit m is the
/// XOR of the index bits k whose bits contain m's, by Lucas' theorem), applied as a superset
/// sum.
#[inline(always)]
fn sobol_01_rev(i: u32) -> (u32, u32) {
    let x = i & 0xffff;
    let mut y = x;
    y ^= (y >> 1) & 0x5555_5555;
    y ^= (y >> 2) & 0x3333_3333;
    y ^= (y >> 4) & 0x0f0f_0f0f;
    y ^= (y >> 8) & 0x00ff_00ff;
    (x, y)
}

/// The 16 low bits of the shuffled index of point `index_rev` (bit-reversed) in the sequence
/// shuffled by `shuffle`: a nested uniform scramble of the index, which keeps every
/// power-of-two prefix of the sequence a net.
#[inline(always)]
fn shuffled(index_rev: u32, shuffle: u32) -> u32 {
    let rev = sobol_burley::parts::owen_scramble_rev(index_rev, shuffle);
    // The reversed value's low 16 bits: its high 16, reversed.
    ((rev >> 16) as u16).reverse_bits() as u32
}

/// Point `index_rev` (bit-reversed) of the shuffled, Owen-scrambled Sobol sequence `s`: its
/// first two dimensions.
#[inline(always)]
fn sobol_2d(index_rev: u32, s: Scrambles) -> Vec2 {
    use sobol_burley::parts::{owen_scramble_rev, u32_to_f32_norm};
    let (x, y) = sobol_01_rev(shuffled(index_rev, s.shuffle));
    let (x, y) = (owen_scramble_rev(x, s.x), owen_scramble_rev(y, s.y));
    // Both digit strings reversed at once: x's lands in the high half.
    let both = ((y as u64) << 32 | x as u64).reverse_bits();
    Vec2::new(u32_to_f32_norm((both >> 32) as u32), u32_to_f32_norm(both as u32))
}

/// The first dimension of [`sobol_2d`].
#[inline(always)]
fn sobol_1d(index_rev: u32, s: Scrambles) -> f32 {
    use sobol_burley::parts::{owen_scramble_rev, u32_to_f32_norm};
    u32_to_f32_norm(owen_scramble_rev(shuffled(index_rev, s.shuffle), s.x).reverse_bits())
}

impl Sobol {
    /// The state of pixel `pixel` under `seed`, for its samples in sequence block `block`
    /// (index 0).
    fn new(seed: u64, pixel: u64, block: u64) -> Self {
        let key = mix(mix(mix(seed ^ 0x2545_f491_4f6c_dd1d) ^ pixel) ^ block);
        let mut s = Sobol { key, index_rev: 0, bounce: 0, first: [Scrambles { shuffle: 0, x: 0, y: 0 }; 5] };
        s.first = CACHED.map(|dim| Scrambles::of(s.seed(dim)));
        s
    }

    /// The seed of the sequence `dim` draws from at the current bounce (the pixel position's
    /// for `None`).
    #[inline(always)]
    fn seed(&self, dim: Option<Dim>) -> u64 {
        let purpose = match dim {
            None => 0,
            Some(Dim::Select) => 1,
            Some(Dim::Lobe) => 2,
            Some(Dim::Direction) => 3,
            Some(Dim::Roulette) => 4,
            // Apart from every light's.
            Some(Dim::Guide) => 0x7fff_0000,
            Some(Dim::Light(i)) => 5 + i as u64,
        };
        let at = purpose | (self.bounce as u64) << 32;
        mix(self.key ^ at.wrapping_mul(0x9e37_79b9_7f4a_7c15))
    }

    /// The scrambles of `dim` at the current bounce.
    #[inline(always)]
    fn scrambles(&self, dim: Option<Dim>) -> Scrambles {
        if self.bounce == 0 {
            match dim {
                None => return self.first[0],
                Some(Dim::Select) => return self.first[1],
                Some(Dim::Lobe) => return self.first[2],
                Some(Dim::Direction) => return self.first[3],
                Some(Dim::Light(0)) => return self.first[4],
                _ => {}
            }
        }
        Scrambles::of(self.seed(dim))
    }
}

/// The purpose of the lens's sequence ([`Sampler::lens_2d`]), apart from every bounce's.
const LENS: u64 = 0x6c65_6e73_0000_0001;

/// What every sample of one pixel under one seed shares, made once a pixel: [`Sampler`]s come
/// from it.
#[derive(Clone, Debug)]
pub struct PixelSampler {
    seed: u64,
    pixel: u64,
    /// The Sobol state at index 0 of the first sequence block (`None`: independent).
    sobol: Option<Sobol>,
}

impl PixelSampler {
    pub fn new(kind: SamplerKind, seed: u64, pixel: u64) -> Self {
        let sobol = (kind == SamplerKind::Sobol).then(|| Sobol::new(seed, pixel, 0));
        PixelSampler { seed, pixel, sobol }
    }

    /// The numbers of the pixel's sample `sample`.
    #[inline]
    pub fn sample(&self, sample: u64) -> Sampler {
        let Some(first) = &self.sobol else { return Sampler::new(self.seed, self.pixel, sample) };
        let block = sample / SEQUENCE as u64;
        let mut sobol = if block == 0 { first.clone() } else { Sobol::new(self.seed, self.pixel, block) };
        sobol.index_rev = ((sample % SEQUENCE as u64) as u32).reverse_bits();
        // The independent stream, for bounces past the Sobol ones, is made when first used.
        Sampler { pcg: Pcg { state: 0, inc: 0 }, sobol: Some(sobol) }
    }
}

/// The numbers of one path sample.
#[derive(Clone, Debug)]
pub struct Sampler {
    pcg: Pcg,
    sobol: Option<Sobol>,
}

impl Sampler {
    /// The independent stream of sample `sample` of pixel `pixel` under `seed`.
    pub fn new(seed: u64, pixel: u64, sample: u64) -> Self {
        Sampler { pcg: Pcg::new(seed, pixel, sample), sobol: None }
    }

    /// The numbers of sample `sample` of pixel `pixel` under `seed`, from `kind` (a render
    /// makes a [`PixelSampler`] once a pixel instead).
    pub fn of(kind: SamplerKind, seed: u64, pixel: u64, sample: u64) -> Self {
        PixelSampler::new(kind, seed, pixel).sample(sample)
    }

    /// The next independent 32-bit number.
    pub fn next_u32(&mut self) -> u32 {
        if self.pcg.inc == 0 {
            // A Sobol sample's stream, made from its key when first used.
            self.pcg = Pcg::keyed(self.sobol.as_ref().map_or(0, |s| s.key ^ s.index_rev as u64));
        }
        self.pcg.next_u32()
    }

    /// The next independent number, uniform in [0, 1).
    pub fn next_1d(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// The next two independent numbers, uniform in [0, 1).
    pub fn next_2d(&mut self) -> Vec2 {
        Vec2::new(self.next_1d(), self.next_1d())
    }

    /// The position within the pixel.
    #[inline]
    pub fn pixel_2d(&mut self) -> Vec2 {
        match &mut self.sobol {
            Some(s) => sobol_2d(s.index_rev, s.scrambles(None)),
            None => self.next_2d(),
        }
    }

    /// The point on a thin lens: a sequence of its own, so a lens moves no other number.
    #[inline]
    pub fn lens_2d(&mut self) -> Vec2 {
        match &mut self.sobol {
            Some(s) => sobol_2d(s.index_rev, Scrambles::of(mix(s.key ^ LENS))),
            None => self.next_2d(),
        }
    }

    /// Numbers drawn from now on are for vertex `bounce` of the path (0: the camera ray's hit).
    #[inline(always)]
    pub fn start_bounce(&mut self, bounce: u32) {
        if let Some(s) = &mut self.sobol {
            s.bounce = bounce;
        }
    }

    /// The Sobol state, while the current bounce draws from it.
    #[inline(always)]
    fn sobol(&mut self) -> Option<&mut Sobol> {
        self.sobol.as_mut().filter(|s| s.bounce < SOBOL_BOUNCES)
    }

    /// A number for `dim` at the current bounce, uniform in [0, 1).
    #[inline]
    pub fn get_1d(&mut self, dim: Dim) -> f32 {
        match self.sobol() {
            Some(s) => sobol_1d(s.index_rev, s.scrambles(Some(dim))),
            None => self.next_1d(),
        }
    }

    /// Two numbers for `dim` at the current bounce, uniform in [0, 1)^2.
    #[inline]
    pub fn get_2d(&mut self, dim: Dim) -> Vec2 {
        match self.sobol() {
            Some(s) => sobol_2d(s.index_rev, s.scrambles(Some(dim))),
            None => self.next_2d(),
        }
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

    /// Every 2D draw of the first `n` Sobol samples of pixel `pixel` under `seed`, for `dim` at
    /// `bounce` (`None`: the pixel position).
    fn points(seed: u64, pixel: u64, n: u32, bounce: u32, dim: Option<Dim>) -> Vec<Vec2> {
        (0..n as u64)
            .map(|k| {
                let mut s = Sampler::of(SamplerKind::Sobol, seed, pixel, k);
                s.start_bounce(bounce);
                match dim {
                    Some(dim) => s.get_2d(dim),
                    None => s.pixel_2d(),
                }
            })
            .collect()
    }

    #[test]
    fn the_first_two_dimensions_of_every_2d_draw_are_a_0_2_net() {
        // For every k up to 10 and every split of 2^-k into 2^-a by 2^-b boxes, each elementary
        // interval holds exactly one of the first 2^k points: the pixel position, the light
        // point and the BSDF direction, at the first bounce and the last Sobol one, in three
        // pixels and three seeds.
        let draws = [None, Some(Dim::Light(0)), Some(Dim::Direction), Some(Dim::Light(3))];
        for (seed, pixel, bounce) in [(0, 0, 0), (5, 1234, SOBOL_BOUNCES - 1), (u64::MAX, 7, 0)] {
            for dim in draws {
                for k in 0..=10u32 {
                    let p = points(seed, pixel, 1 << k, bounce, dim);
                    for a in 0..=k {
                        let b = k - a;
                        let mut count = vec![0u32; 1 << k];
                        for q in &p {
                            let (i, j) =
                                ((q.x * (1u32 << a) as f32) as usize, (q.y * (1u32 << b) as f32) as usize);
                            count[(i << b) | j] += 1;
                        }
                        assert!(
                            count.iter().all(|&c| c == 1),
                            "{dim:?} at bounce {bounce}, seed {seed}, pixel {pixel}: 2^{k} points in \
                             2^{a} x 2^{b} boxes are not one a box"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_direct_dimensions_match_sobol_burleys_tables() {
        // Every 16-bit index, and indices with high bits (which the tables ignore).
        for i in (0..1u32 << 16).chain([0xdead_beef, u32::MAX, 1 << 16]) {
            let (x, y) = sobol_01_rev(i);
            let rev = i.reverse_bits();
            assert_eq!(x, sobol_burley::parts::sobol_rev(rev, 0), "dimension 0 of {i}");
            assert_eq!(y, sobol_burley::parts::sobol_rev(rev, 1), "dimension 1 of {i}");
        }
    }

    #[test]
    fn points_match_sobol_burleys_own_with_its_scrambles() {
        // With the crate's shuffle and scrambles for a seed, a 2D draw is the crate's sample
        // in dimensions 0 and 1, bit for bit, and a 1D draw its dimension 0.
        use sobol_burley::parts::hash;
        for seed in [0u32, 1, 7, 0xdead_beef] {
            let mul = seed.wrapping_mul(0x9c8f_2d3b);
            let s = Scrambles {
                shuffle: hash(seed ^ 0x79c6_8e4a),
                x: hash(mul ^ 0x912f_69ba),
                y: hash(mul ^ 0x174f_18ab),
            };
            for i in (0..4096).chain([65_535]) {
                let p = sobol_2d(u32::reverse_bits(i), s);
                let want = Vec2::new(sobol_burley::sample(i, 0, seed), sobol_burley::sample(i, 1, seed));
                assert_eq!(p, want, "point {i}, seed {seed}");
                assert_eq!(sobol_1d(u32::reverse_bits(i), s), want.x);
            }
        }
    }

    #[test]
    fn scrambles_made_once_a_pixel_are_those_made_when_drawn() {
        for (seed, pixel, block) in [(0, 0, 0), (3, 99, 0), (3, 99, 2)] {
            let s = Sobol::new(seed, pixel, block);
            for (i, dim) in CACHED.into_iter().enumerate() {
                let made = Scrambles::of(s.seed(dim));
                let cached = s.first[i];
                assert_eq!((cached.shuffle, cached.x, cached.y), (made.shuffle, made.x, made.y), "{dim:?}");
            }
        }
    }

    #[test]
    fn numbers_are_the_same_whatever_was_drawn_before() {
        // Purposes own their dimensions: drawing a lobe or not does not move the direction.
        let mut a = Sampler::of(SamplerKind::Sobol, 3, 9, 17);
        let mut b = a.clone();
        a.start_bounce(SOBOL_BOUNCES - 1);
        b.start_bounce(SOBOL_BOUNCES - 1);
        let _ = a.get_1d(Dim::Lobe);
        let _ = b.get_2d(Dim::Light(0));
        assert_eq!(a.get_2d(Dim::Direction), b.get_2d(Dim::Direction));
        assert_eq!(a.get_1d(Dim::Roulette), b.get_1d(Dim::Roulette));
    }

    /// The chi-square statistic of `x` in `bins` equal bins.
    fn chi_square(x: impl Iterator<Item = f32>, bins: usize, n: usize) -> f64 {
        let mut count = vec![0usize; bins];
        for v in x {
            assert!((0.0..1.0).contains(&v), "{v} is outside [0, 1)");
            count[((v * bins as f32) as usize).min(bins - 1)] += 1;
        }
        let expected = n as f64 / bins as f64;
        count.iter().map(|&c| (c as f64 - expected).powi(2) / expected).sum()
    }

    #[test]
    fn scrambled_numbers_are_uniform_in_every_dimension_across_pixels() {
        // Dimensions 0 to 7 of a sample (the pixel position, then the first bounce's light and
        // BSDF numbers), each over 4,096 pixels at a non-power-of-two sample count, in 64 bins.
        // Across pixels the points are independent uniforms, so the statistic is chi-square
        // with 63 degrees of freedom: its 99.99th percentile is 117.
        let dims: [(Option<Dim>, usize); 8] = [
            (None, 0),
            (None, 1),
            (Some(Dim::Light(0)), 0),
            (Some(Dim::Light(0)), 1),
            (Some(Dim::Select), 0),
            (Some(Dim::Direction), 0),
            (Some(Dim::Direction), 1),
            (Some(Dim::Lobe), 0),
        ];
        let (pixels, bins) = (4096u64, 64);
        for (d, (dim, i)) in dims.into_iter().enumerate() {
            let x = (0..pixels).map(|p| {
                let mut s = Sampler::of(SamplerKind::Sobol, 11, p, 5);
                match dim {
                    None => s.pixel_2d()[i],
                    Some(Dim::Select | Dim::Lobe) => s.get_1d(dim.unwrap_or(Dim::Lobe)),
                    Some(dim) => s.get_2d(dim)[i],
                }
            });
            let chi = chi_square(x, bins, pixels as usize);
            assert!(chi < 117.0, "dimension {d}: chi-square {chi:.1} over 63 degrees of freedom");
        }
    }

    #[test]
    fn pixels_and_seeds_are_uncorrelated() {
        // The sample correlation of two pixels' (or two seeds') numbers over 4,096 samples: for
        // independent scrambles it is within a few 1/sqrt(n) of zero; shared ones would give 1.
        let n = 4096u64;
        let corr = |a: &dyn Fn(u64) -> f32, b: &dyn Fn(u64) -> f32| {
            let (x, y): (Vec<f64>, Vec<f64>) = (0..n).map(|k| (a(k) as f64, b(k) as f64)).unzip();
            let mean = |v: &[f64]| v.iter().sum::<f64>() / n as f64;
            let (mx, my) = (mean(&x), mean(&y));
            let cov: f64 = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum();
            let var = |v: &[f64], m: f64| v.iter().map(|a| (a - m).powi(2)).sum::<f64>();
            cov / (var(&x, mx) * var(&y, my)).sqrt()
        };
        let draw = |seed: u64, pixel: u64, dim: Dim| {
            move |k: u64| Sampler::of(SamplerKind::Sobol, seed, pixel, k).get_2d(dim).x
        };
        let bound = 4.0 / (n as f64).sqrt();
        for (what, r) in [
            ("neighbouring pixels", corr(&draw(1, 10, Dim::Direction), &draw(1, 11, Dim::Direction))),
            ("two seeds", corr(&draw(1, 10, Dim::Direction), &draw(2, 10, Dim::Direction))),
            ("two purposes", corr(&draw(1, 10, Dim::Direction), &draw(1, 10, Dim::Light(0)))),
        ] {
            assert!(r.abs() < bound, "{what}: correlation {r:.4}, beyond {bound:.4}");
        }
    }

    #[test]
    fn a_smooth_integral_has_less_error_than_with_independent_numbers() {
        // The irradiance at a point under a square light of side 2a at height h, facing it,
        // sampled uniformly by area: L A cos cos' / r^2 = L 4a^2 h^2 / r^4. Exact (the form
        // factor of four a x a rectangles): 4 L X/sqrt(1+X^2) atan(X/sqrt(1+X^2)), X = a/h.
        let (a, h) = (0.5f64, 1.0f64);
        let f = |u: Vec2| {
            let (x, y) = (a * (2.0 * u.x as f64 - 1.0), a * (2.0 * u.y as f64 - 1.0));
            let r2 = x * x + y * y + h * h;
            4.0 * a * a * h * h / (r2 * r2)
        };
        let x = a / h;
        let exact = 4.0 * x / (1.0 + x * x).sqrt() * (x / (1.0 + x * x).sqrt()).atan();
        // The formula, checked by a midpoint rule.
        let m = 1000;
        let grid: f64 = (0..m * m)
            .map(|i| f(Vec2::new(((i % m) as f32 + 0.5) / m as f32, ((i / m) as f32 + 0.5) / m as f32)))
            .sum::<f64>()
            / (m * m) as f64;
        assert!((grid / exact - 1.0).abs() < 1e-5, "{grid} vs {exact}");
        // 256 samples, 32 seeds: the squared errors, paired by seed.
        let err2 = |kind: SamplerKind, seed: u64| {
            let mean =
                (0..256u64).map(|k| f(Sampler::of(kind, seed, 7, k).get_2d(Dim::Light(0)))).sum::<f64>()
                    / 256.0;
            (mean - exact).powi(2)
        };
        let d: Vec<f64> =
            (0..32).map(|s| err2(SamplerKind::Independent, s) - err2(SamplerKind::Sobol, s)).collect();
        let mean = d.iter().sum::<f64>() / 32.0;
        let sd = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / 31.0).sqrt();
        let (ind, sob) = (
            (0..32).map(|s| err2(SamplerKind::Independent, s)).sum::<f64>() / 32.0,
            (0..32).map(|s| err2(SamplerKind::Sobol, s)).sum::<f64>() / 32.0,
        );
        // Sobol's mean squared error is lower by more than three standard errors of the paired
        // difference (and by a large factor, which the message reports).
        assert!(
            mean > 3.0 * sd / 32f64.sqrt(),
            "MSE independent {ind:.3e}, sobol {sob:.3e}: difference {mean:.3e} +- {:.3e}",
            sd / 32f64.sqrt()
        );
        assert!(sob < ind / 10.0, "MSE independent {ind:.3e}, sobol {sob:.3e}");
    }

    #[test]
    fn pixels_seeds_bounces_and_blocks_get_different_points() {
        let first = |seed, pixel, bounce, sample| {
            let mut s = Sampler::of(SamplerKind::Sobol, seed, pixel, sample);
            s.start_bounce(bounce);
            s.get_2d(Dim::Direction)
        };
        let a = first(1, 2, 0, 3);
        assert_eq!(a, first(1, 2, 0, 3));
        for other in
            [first(2, 2, 0, 3), first(1, 3, 0, 3), first(1, 2, 1, 3), first(1, 2, 0, 3 + SEQUENCE as u64)]
        {
            assert_ne!(a, other);
        }
        // Past the Sobol bounces, the sample's independent stream, the same in every run.
        let deep = || {
            let mut s = Sampler::of(SamplerKind::Sobol, 1, 2, 3);
            s.start_bounce(SOBOL_BOUNCES);
            [s.get_2d(Dim::Direction), s.get_2d(Dim::Direction)]
        };
        let [a, b] = deep();
        assert_ne!(a, b);
        assert_eq!([a, b], deep());
        // ... and its own: another sample of the pixel draws other numbers there.
        let mut next = Sampler::of(SamplerKind::Sobol, 1, 2, 4);
        next.start_bounce(SOBOL_BOUNCES);
        assert_ne!(next.get_2d(Dim::Direction), a);
    }
}
