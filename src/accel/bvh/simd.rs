//! The one module of the BVH with `unsafe`: the eight-box slab test written with x86 intrinsics
//! in two kernels, [`Avx2`] and [`Avx512`] (the same AVX2 arithmetic, its comparison straight
//! into an AVX-512 mask register), each with the entry points that run a whole traversal
//! compiled for its features (AVX-512's 32 vector registers keep the ray's values beside the
//! triangle test's). A kernel's value exists only after `is_x86_feature_detected!` found its
//! features on this CPU, so every `unsafe` block here relies on that one check; [`Isa::best`]
//! picks AVX-512, else AVX2, else [`Portable`], once per tree. [`Portable`] is the same test
//! through the `wide` crate (SSE2 on x86-64, NEON on ARM); the tests check each kernel against
//! it bit for bit. [`Isa::run`] lends each build to other code (the path loop, the light
//! tree's walks, the à-trous filter's passes, the noise), so that its `unsafe` calls stay here.
#![allow(unsafe_code)]

use wide::f32x8;

use super::wide::{Bvh8, Node8};
use super::Filter;
use crate::accel::{Hit, Ray};

/// Ize's factor: the far slab distance grows by 2 gamma(3) to cover rounding (see `RayBox`).
const FAR_SCALE: f32 = super::FAR_SCALE;

/// Per-ray values of the eight-box slab test, the same for every kernel.
pub struct RayBox8 {
    origin: [f32; 3],
    inv_dir: [f32; 3],
    /// For each axis, the rows of a node's bounds that hold the near and the far planes (they
    /// swap where the ray runs towards negative values).
    near: [usize; 3],
    far: [usize; 3],
}

impl RayBox8 {
    pub fn new(ray: &Ray) -> Self {
        // A zero direction component becomes a tiny one, so 1/d is huge but finite and no
        // 0 * inf NaN can arise in the slab test.
        let safe = |d: f32| if d.abs() < 1e-30 { 1e-30f32.copysign(d) } else { d };
        let inv = [1.0 / safe(ray.dir.x), 1.0 / safe(ray.dir.y), 1.0 / safe(ray.dir.z)];
        let negative = inv.map(|i| i < 0.0);
        RayBox8 {
            origin: ray.origin.to_array(),
            inv_dir: inv,
            near: std::array::from_fn(|a| if negative[a] { 3 + a } else { a }),
            far: std::array::from_fn(|a| if negative[a] { a } else { 3 + a }),
        }
    }
}

/// A slab test of a node's eight child boxes.
pub trait BoxTest: Copy {
    /// Entry distances of the eight children, and a bit mask of those the ray meets within
    /// [0, t_max]: `(b - o) * (1 / d)` per plane, no fused multiply-add, so the rounding is the
    /// one Ize's factor covers.
    fn hit(self, rb: &RayBox8, node: &Node8, t_max: f32) -> ([f32; 8], u32);

    /// Asks the CPU to bring `item` into the cache, where the kernel can (a hint: it changes
    /// no result). Traversal calls it for children it will visit after the nearest one.
    #[inline(always)]
    fn prefetch<T>(self, _item: &T) {}
}

/// The slab test through the `wide` crate: runs on every CPU.
#[derive(Clone, Copy, Debug)]
pub struct Portable;

impl BoxTest for Portable {
    #[inline(always)]
    fn hit(self, rb: &RayBox8, node: &Node8, t_max: f32) -> ([f32; 8], u32) {
        let mut t_near = f32x8::splat(0.0);
        let mut t_far = f32x8::splat(t_max);
        for axis in 0..3 {
            let o = f32x8::splat(rb.origin[axis]);
            let inv = f32x8::splat(rb.inv_dir[axis]);
            let a = (f32x8::new(node.bounds[rb.near[axis]]) - o) * inv;
            let b = (f32x8::new(node.bounds[rb.far[axis]]) - o) * inv;
            t_near = t_near.fast_max(a);
            t_far = t_far.fast_min(b);
        }
        let mask = t_near.simd_le(t_far * f32x8::splat(FAR_SCALE)).to_bitmask();
        (t_near.to_array(), mask)
    }
}

/// Proof that this CPU has AVX, AVX2 and FMA: obtained only from [`Avx2::detect`]. (Every CPU
/// with AVX2 has FMA; the builds use it only where code asks for `mul_add`, which the portable
/// build computes by a call, to the same bits.)
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
pub struct Avx2 {
    _detected: (),
}

#[cfg(target_arch = "x86_64")]
impl Avx2 {
    /// The proof, when this CPU has the features.
    pub fn detect() -> Option<Avx2> {
        (std::is_x86_feature_detected!("avx")
            && std::is_x86_feature_detected!("avx2")
            && std::is_x86_feature_detected!("fma"))
        .then_some(Avx2 { _detected: () })
    }

    /// Whether this CPU runs 256-bit vectors at full width ([`runs_256_bits_whole`]).
    pub fn full_width() -> bool {
        use std::arch::x86_64::__cpuid;
        let vendor = __cpuid(0);
        runs_256_bits_whole([vendor.ebx, vendor.edx, vendor.ecx], __cpuid(1).eax)
    }

    /// The closest hit, by a traversal compiled for AVX2.
    pub fn intersect<const N: usize>(self, bvh: &Bvh8, ray: &Ray, filter: Filter) -> Option<Hit> {
        // SAFETY: `self` exists only when `detect` found AVX, AVX2 and FMA, all that
        // `intersect_avx2` is compiled for.
        unsafe { intersect_avx2::<N>(self, bvh, ray, filter) }
    }

    /// Any hit, by a traversal compiled for AVX2.
    pub fn occluded<const N: usize>(self, bvh: &Bvh8, ray: &Ray, filter: Filter) -> bool {
        // SAFETY: as in `intersect`: AVX, AVX2 and FMA were detected.
        unsafe { occluded_avx2::<N>(self, bvh, ray, filter) }
    }
}

/// CPUID leaf 0's vendor, "AuthenticAMD" and "HygonGenuine", four bytes a register (ebx, edx,
/// ecx).
#[cfg(target_arch = "x86_64")]
const AMD: [u32; 3] = [0x6874_7541, 0x6974_6e65, 0x444d_4163];
#[cfg(target_arch = "x86_64")]
const HYGON: [u32; 3] = [0x6f67_7948, 0x6e65_476e, 0x656e_6975];

/// Whether a CPU of this vendor (CPUID leaf 0's ebx, edx, ecx) and signature (leaf 1's eax)
/// runs 256-bit vectors at full width: every x86-64 CPU with AVX2 but AMD's and Hygon's before
/// Zen 2, which split each 256-bit operation into two 128-bit halves (families 0x15 and 0x16,
/// Zen 1 and Zen+ as family 0x17 below model 0x30, Hygon's Zen 1 as family 0x18).
#[cfg(target_arch = "x86_64")]
fn runs_256_bits_whole(vendor: [u32; 3], signature: u32) -> bool {
    let family = ((signature >> 8) & 0xf) + ((signature >> 20) & 0xff);
    let model = ((signature >> 4) & 0xf) | ((signature >> 12) & 0xf0);
    let halves = family < 0x17 || family == 0x18 || (family == 0x17 && model < 0x30);
    !((vendor == AMD || vendor == HYGON) && halves)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma")]
fn intersect_avx2<const N: usize>(k: Avx2, bvh: &Bvh8, ray: &Ray, filter: Filter) -> Option<Hit> {
    bvh.intersect_with::<Avx2, N>(ray, filter, k)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma")]
fn occluded_avx2<const N: usize>(k: Avx2, bvh: &Bvh8, ray: &Ray, filter: Filter) -> bool {
    bvh.occluded_with::<Avx2, N>(ray, filter, k)
}

/// The slab arithmetic of both x86 kernels: each child's entry distance and its exit distance
/// grown by Ize's factor, for the kernel's comparison.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn slab8(
    _proof: Avx2,
    rb: &RayBox8,
    node: &Node8,
    t_max: f32,
) -> (std::arch::x86_64::__m256, std::arch::x86_64::__m256) {
    use std::arch::x86_64::*;
    // SAFETY: `_proof` shows the CPU has AVX (`Avx2::detect`). The loads read whole rows of
    // `node.bounds`, eight f32 each, in bounds; `loadu` needs no alignment.
    unsafe {
        let mut t_near = _mm256_setzero_ps();
        let mut t_far = _mm256_set1_ps(t_max);
        for axis in 0..3 {
            let o = _mm256_set1_ps(rb.origin[axis]);
            let inv = _mm256_set1_ps(rb.inv_dir[axis]);
            let lo = _mm256_loadu_ps(node.bounds[rb.near[axis]].as_ptr());
            let hi = _mm256_loadu_ps(node.bounds[rb.far[axis]].as_ptr());
            // max and min return their second operand when one is NaN, as `wide`'s fast_max
            // and fast_min do; none arises (finite 1/d, see RayBox8::new).
            t_near = _mm256_max_ps(t_near, _mm256_mul_ps(_mm256_sub_ps(lo, o), inv));
            t_far = _mm256_min_ps(t_far, _mm256_mul_ps(_mm256_sub_ps(hi, o), inv));
        }
        (t_near, _mm256_mul_ps(t_far, _mm256_set1_ps(FAR_SCALE)))
    }
}

#[cfg(target_arch = "x86_64")]
impl BoxTest for Avx2 {
    #[inline(always)]
    fn hit(self, rb: &RayBox8, node: &Node8, t_max: f32) -> ([f32; 8], u32) {
        use std::arch::x86_64::*;
        let (t_near, far) = slab8(self, rb, node, t_max);
        // SAFETY: `self` proves the CPU has AVX (`Avx2::detect`); the store writes the eight
        // f32 of `out`.
        unsafe {
            let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_near, far)) as u32;
            let mut out = [0.0f32; 8];
            _mm256_storeu_ps(out.as_mut_ptr(), t_near);
            (out, mask)
        }
    }

    #[inline(always)]
    fn prefetch<T>(self, item: &T) {
        use std::arch::x86_64::*;
        let start = (item as *const T).cast::<i8>();
        for offset in (0..std::mem::size_of::<T>()).step_by(64) {
            // SAFETY: `self` proves the CPU has SSE (a part of AVX). A prefetch reads nothing
            // the program sees and cannot fault; the address stays within `item`.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(offset)) };
        }
    }
}

/// Proof that this CPU has AVX-512 F and VL besides AVX, AVX2 and FMA: obtained only from
/// [`Avx512::detect`].
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
pub struct Avx512 {
    avx2: Avx2,
}

#[cfg(target_arch = "x86_64")]
impl Avx512 {
    /// The proof, when this CPU has the features.
    pub fn detect() -> Option<Avx512> {
        let avx2 = Avx2::detect()?;
        (std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("avx512vl"))
            .then_some(Avx512 { avx2 })
    }

    /// The closest hit, by a traversal compiled for AVX-512 (32 vector registers, so the
    /// ray's values stay in registers beside the triangle test's).
    pub fn intersect<const N: usize>(self, bvh: &Bvh8, ray: &Ray, filter: Filter) -> Option<Hit> {
        // SAFETY: `self` exists only when `detect` found AVX, AVX2, FMA, AVX-512 F and VL, all
        // that `intersect_avx512` is compiled for.
        unsafe { intersect_avx512::<N>(self, bvh, ray, filter) }
    }

    /// Any hit, by a traversal compiled for AVX-512.
    pub fn occluded<const N: usize>(self, bvh: &Bvh8, ray: &Ray, filter: Filter) -> bool {
        // SAFETY: as in `intersect`: AVX, AVX2, FMA, AVX-512 F and VL were detected.
        unsafe { occluded_avx512::<N>(self, bvh, ray, filter) }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma,avx512f,avx512vl")]
fn intersect_avx512<const N: usize>(k: Avx512, bvh: &Bvh8, ray: &Ray, filter: Filter) -> Option<Hit> {
    bvh.intersect_with::<Avx512, N>(ray, filter, k)
}

/// Work that [`Isa::run`] compiles for the instructions it chose. `run` must be
/// `#[inline(always)]`: its body is then compiled inside the dispatching function, with that
/// function's instructions (a closure in its place was compiled apart, for the portable build,
/// once it grew as large as the path loop).
pub trait Inlined {
    type Output;
    fn run(self) -> Self::Output;
}

#[cfg(target_arch = "x86_64")]
impl Avx2 {
    /// `job`, compiled for AVX, AVX2 and FMA as far as it inlines (see [`Inlined`]).
    #[inline(always)]
    pub fn run<J: Inlined>(self, job: J) -> J::Output {
        // SAFETY: `self` exists only when `detect` found AVX, AVX2 and FMA, all that `run_avx2` is
        // compiled for.
        unsafe { run_avx2(job) }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma")]
fn run_avx2<J: Inlined>(job: J) -> J::Output {
    job.run()
}

#[cfg(target_arch = "x86_64")]
impl Avx512 {
    /// `job`, compiled for AVX-512 F and VL as far as it inlines: the path loop runs through
    /// it ([`Isa`]), where 32 vector registers hold what 16 spill to the stack. The
    /// arithmetic is the same (fused only where the code asks for `mul_add`, which the
    /// portable build computes to the same bits), so the results equal the portable build's
    /// bit for bit.
    #[inline(always)]
    pub fn run<J: Inlined>(self, job: J) -> J::Output {
        // SAFETY: `self` exists only when `detect` found AVX, AVX2, FMA, AVX-512 F and VL, all that
        // `run_avx512` is compiled for.
        unsafe { run_avx512(job) }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma,avx512f,avx512vl")]
fn run_avx512<J: Inlined>(job: J) -> J::Output {
    job.run()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma,avx512f,avx512vl")]
fn occluded_avx512<const N: usize>(k: Avx512, bvh: &Bvh8, ray: &Ray, filter: Filter) -> bool {
    bvh.occluded_with::<Avx512, N>(ray, filter, k)
}

#[cfg(target_arch = "x86_64")]
impl BoxTest for Avx512 {
    /// The AVX2 test's arithmetic, its comparison into a mask register.
    #[inline(always)]
    fn hit(self, rb: &RayBox8, node: &Node8, t_max: f32) -> ([f32; 8], u32) {
        use std::arch::x86_64::*;
        let (t_near, far) = slab8(self.avx2, rb, node, t_max);
        // SAFETY: `self` proves the CPU has AVX, AVX-512 F and VL (`Avx512::detect`); the
        // store writes the eight f32 of `out`.
        unsafe {
            let mask = u32::from(_mm256_cmp_ps_mask::<_CMP_LE_OQ>(t_near, far));
            let mut out = [0.0f32; 8];
            _mm256_storeu_ps(out.as_mut_ptr(), t_near);
            (out, mask)
        }
    }

    #[inline(always)]
    fn prefetch<T>(self, item: &T) {
        self.avx2.prefetch(item)
    }
}

/// A build chosen at run time: the BVH's kernels (the tree's, chosen once per tree), and the
/// build other code runs a job in ([`Isa::run`]: the job inlined into a function compiled for
/// the build's features; a job, never a closure, whose body the compiler may leave outlined in
/// the portable build). One binary for every x86-64 CPU; every build gives the same bits
/// (Rust contracts no multiply-add), which the users' tests compare.
///
/// Which builds a user offers is its own measured choice (docs/RESULTS.md): the path loop and
/// the light tree's walks the best, except AVX2 on CPUs that split 256-bit vectors into halves
/// ([`Isa::for_loops`]: AVX2 was slower than portable on a Zen 1 machine, faster on a Zen 3
/// one; `render-regression`), the à-trous filter's passes, the noise and the BVH the best.
#[derive(Clone, Copy, Debug, Default)]
pub enum Isa {
    #[default]
    Portable,
    #[cfg(target_arch = "x86_64")]
    Avx2(Avx2),
    #[cfg(target_arch = "x86_64")]
    Avx512(Avx512),
}

impl Isa {
    /// AVX-512 where this CPU has it, else AVX2, else portable.
    pub fn best() -> Isa {
        #[cfg(target_arch = "x86_64")]
        if let Some(k) = Avx512::detect() {
            return Isa::Avx512(k);
        }
        Isa::avx2().unwrap_or(Isa::Portable)
    }

    /// The AVX2 kernels, where this CPU has them (tests and benchmarks compare them with the
    /// others on a CPU that also has AVX-512).
    pub fn avx2() -> Option<Isa> {
        #[cfg(target_arch = "x86_64")]
        if let Some(k) = Avx2::detect() {
            return Some(Isa::Avx2(k));
        }
        None
    }

    /// Every build this CPU runs: the portable one, AVX2's, and AVX-512's (for tests that
    /// compare each with the portable build's bits).
    pub fn all() -> Vec<Isa> {
        let mut all = vec![Isa::Portable];
        all.extend(Isa::avx2());
        #[cfg(target_arch = "x86_64")]
        all.extend(Avx512::detect().map(Isa::Avx512));
        all
    }

    /// The kernels called `name` ("portable", "avx2" or "avx512"), where this CPU runs them.
    pub fn named(name: &str) -> Option<Isa> {
        match name {
            "portable" => Some(Isa::Portable),
            "avx2" => Isa::avx2(),
            #[cfg(target_arch = "x86_64")]
            "avx512" => Avx512::detect().map(Isa::Avx512),
            _ => None,
        }
    }

    /// The build the path loop and the light tree's walks run in: AVX-512 where this CPU has
    /// it; else AVX2 where the CPU runs 256-bit vectors at full width ([`Avx2::full_width`]);
    /// else portable. The AVX2 build was slower than the portable one on a Zen 1 machine, whose
    /// units are 128 bits wide, and faster on a Zen 3 one (docs/RESULTS.md, `render-regression`).
    pub fn for_loops() -> Isa {
        #[cfg(target_arch = "x86_64")]
        if let Some(k) = Avx512::detect() {
            return Isa::Avx512(k);
        }
        #[cfg(target_arch = "x86_64")]
        if let Some(k) = Avx2::detect().filter(|_| Avx2::full_width()) {
            return Isa::Avx2(k);
        }
        Isa::Portable
    }

    /// The kernels' name, as reports print it.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Portable => "portable",
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(_) => "avx2",
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(_) => "avx512",
        }
    }

    /// `job`, in this build.
    #[inline(always)]
    pub fn run<J: Inlined>(self, job: J) -> J::Output {
        match self {
            Isa::Portable => job.run(),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(k) => k.run(job),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(k) => k.run(job),
        }
    }
}

impl BoxTest for Isa {
    /// The chosen kernel (a match per call: for tests, not for traversal loops).
    fn hit(self, rb: &RayBox8, node: &Node8, t_max: f32) -> ([f32; 8], u32) {
        match self {
            Isa::Portable => Portable.hit(rb, node, t_max),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(k) => k.hit(rb, node, t_max),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(k) => k.hit(rb, node, t_max),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampler::Sampler;

    /// Kernels named are those of that name where this CPU runs them, and none otherwise.
    #[test]
    fn kernels_named_are_the_ones_this_cpu_runs() {
        assert_eq!(Isa::named("portable").map(Isa::name), Some("portable"));
        assert_eq!(Isa::named("avx2").map(Isa::name), Isa::avx2().map(Isa::name));
        let best = Isa::best().name();
        assert_eq!(Isa::named(best).map(Isa::name), Some(best));
        assert!(Isa::named("sse9").is_none() && Isa::named("AVX2").is_none());
    }

    /// The CPUs whose 256-bit vectors run in two halves, from their CPUID signatures: AMD's
    /// Zen 1, Zen+ and Excavator and Hygon's Dhyana; not Zen 2, Zen 3, Zen 4 or Intel's.
    #[test]
    #[cfg(target_arch = "x86_64")]
    fn cpus_that_split_256_bit_vectors_are_known() {
        const INTEL: [u32; 3] = [0x756e_6547, 0x4965_6e69, 0x6c65_746e]; // "GenuineIntel"
        for (what, vendor, signature, whole) in [
            ("Zen 1 (EPYC 7001)", AMD, 0x0080_0f12, false),
            ("Zen+ (Ryzen 2000)", AMD, 0x0080_0f82, false),
            ("Excavator", AMD, 0x0066_0f01, false),
            ("Hygon Dhyana", HYGON, 0x0090_0f01, false),
            ("Zen 2 (EPYC 7002)", AMD, 0x0083_0f10, true),
            ("Zen 3 (EPYC 7003)", AMD, 0x00a0_0f11, true),
            ("Zen 4 (EPYC 9004)", AMD, 0x00a1_0f11, true),
            ("Haswell", INTEL, 0x0003_06c3, true),
            ("Ice Lake server", INTEL, 0x0006_06a6, true),
        ] {
            assert_eq!(runs_256_bits_whole(vendor, signature), whole, "{what}");
        }
    }

    /// The AVX2 slab test gives the portable test's distances and masks bit for bit.
    #[test]
    fn avx2_box_test_equals_the_portable_one() {
        #[cfg(target_arch = "x86_64")]
        match Avx2::detect() {
            Some(k) => equals_the_portable_box_test(k),
            None => eprintln!("no AVX2 on this CPU: only the portable kernel runs here"),
        }
    }

    /// The AVX-512 slab test gives the portable test's distances and masks bit for bit.
    #[test]
    fn avx512_box_test_equals_the_portable_one() {
        #[cfg(target_arch = "x86_64")]
        match Avx512::detect() {
            Some(k) => equals_the_portable_box_test(k),
            None => eprintln!("no AVX-512 on this CPU: its kernel is not checked here"),
        }
    }

    /// Kernel `kernel` against the portable one, on random boxes (some empty, some thin, some
    /// behind the ray) and random rays, including rays with zero direction components and rays
    /// starting on a box's planes.
    #[cfg(target_arch = "x86_64")]
    fn equals_the_portable_box_test(kernel: impl BoxTest + std::fmt::Debug) {
        let mut rng = Sampler::new(7, 1, 0);
        let mut f = |scale: f32| (rng.next_1d() * 2.0 - 1.0) * scale;
        let mut checked = 0;
        for case in 0..20_000 {
            let mut node = Node8::EMPTY;
            for slot in 0..8 {
                if (case + slot) % 5 == 0 {
                    continue; // an empty slot: its inverted box stays
                }
                let thin = (case + slot) % 7 == 0;
                for a in 0..3 {
                    let lo = f(10.0);
                    let extent = if thin && a == 1 { 0.0 } else { f(4.0).abs() };
                    node.bounds[a][slot] = lo;
                    node.bounds[3 + a][slot] = lo + extent;
                }
            }
            let mut origin = glam::Vec3::new(f(12.0), f(12.0), f(12.0));
            if case % 11 == 0 {
                origin.x = node.bounds[0][1]; // on a plane
            }
            // Aimed near the centre of one slot's box, so most boxes are met or just missed.
            let slot = case % 8;
            let centre = glam::Vec3::from_array(std::array::from_fn(|a| {
                0.5 * (node.bounds[a][slot] + node.bounds[3 + a][slot])
            }));
            let aim = if centre.is_finite() { centre } else { glam::Vec3::ZERO };
            let mut dir = aim - origin + glam::Vec3::new(f(1.0), f(1.0), f(1.0));
            if case % 13 == 0 {
                dir.y = 0.0;
            }
            let t_max = if case % 3 == 0 { f32::INFINITY } else { f(20.0).abs() };
            let ray = Ray { origin, dir, t_max };
            let rb = RayBox8::new(&ray);
            let (tp, mp) = Portable.hit(&rb, &node, t_max);
            let (ta, ma) = kernel.hit(&rb, &node, t_max);
            assert_eq!(mp, ma, "{kernel:?}: masks differ for {ray:?}");
            for s in 0..8 {
                if mp & (1 << s) != 0 {
                    assert_eq!(tp[s].to_bits(), ta[s].to_bits(), "slot {s} of {ray:?}");
                }
            }
            checked += mp.count_ones();
        }
        // Enough boxes were hit for the comparison of distances to mean something.
        assert!(checked > 8_000, "only {checked} boxes hit");
    }
}
