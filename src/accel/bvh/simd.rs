//! The one module of the BVH with `unsafe`: the eight-box slab test written with AVX2
//! intrinsics, and the entry points that run a whole traversal compiled for AVX2. An [`Avx2`]
//! value exists only after `is_x86_feature_detected!` found the features on this CPU, so every
//! `unsafe` block here relies on that one check. [`Portable`] is the same test through the
//! `wide` crate (SSE2 on x86-64, NEON on ARM); the tests check the two against each other.
#![allow(unsafe_code)]

use wide::f32x8;

use super::intersect::gamma;
use super::wide::{Bvh8, Leaf4, Node8, RayTri4};
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

    /// The watertight test of two blocks side by side, both against `t_max`: the nearest hit
    /// `(t, lane, u, v)`, lanes 4 to 7 naming the second block's, the lowest lane winning ties.
    /// By default the four-lane test twice ([`RayTri4::hit_pair`]); a kernel may run all eight
    /// lanes at once, with the same arithmetic lane by lane.
    #[inline(always)]
    fn leaf_pair(self, rt: &RayTri4, a: &Leaf4, b: &Leaf4, t_max: f32) -> Option<(f32, usize, f32, f32)> {
        rt.hit_pair(a, b, t_max)
    }
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

/// Proof that this CPU has AVX and AVX2: obtained only from [`Avx2::detect`].
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
pub struct Avx2 {
    _detected: (),
}

#[cfg(target_arch = "x86_64")]
impl Avx2 {
    /// The proof, when this CPU has the features.
    pub fn detect() -> Option<Avx2> {
        (std::is_x86_feature_detected!("avx") && std::is_x86_feature_detected!("avx2"))
            .then_some(Avx2 { _detected: () })
    }

    /// The closest hit, by a traversal compiled for AVX2.
    pub fn intersect(self, bvh: &Bvh8, ray: &Ray) -> Option<Hit> {
        // SAFETY: `self` exists only when `detect` found AVX and AVX2, all that
        // `intersect_avx2` is compiled for.
        unsafe { intersect_avx2(self, bvh, ray) }
    }

    /// Any hit, by a traversal compiled for AVX2.
    pub fn occluded(self, bvh: &Bvh8, ray: &Ray) -> bool {
        // SAFETY: as in `intersect`: AVX and AVX2 were detected.
        unsafe { occluded_avx2(self, bvh, ray) }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2")]
fn intersect_avx2(k: Avx2, bvh: &Bvh8, ray: &Ray) -> Option<Hit> {
    bvh.intersect_with(ray, k)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2")]
fn occluded_avx2(k: Avx2, bvh: &Bvh8, ray: &Ray) -> bool {
    bvh.occluded_with(ray, k)
}

#[cfg(target_arch = "x86_64")]
impl BoxTest for Avx2 {
    #[inline(always)]
    fn hit(self, rb: &RayBox8, node: &Node8, t_max: f32) -> ([f32; 8], u32) {
        use std::arch::x86_64::*;
        // SAFETY: `self` proves the CPU has AVX (`Avx2::detect`). The loads read whole rows
        // of `node.bounds`, eight f32 each, in bounds; `loadu` needs no alignment.
        unsafe {
            let mut t_near = _mm256_setzero_ps();
            let mut t_far = _mm256_set1_ps(t_max);
            for axis in 0..3 {
                let o = _mm256_set1_ps(rb.origin[axis]);
                let inv = _mm256_set1_ps(rb.inv_dir[axis]);
                let lo = _mm256_loadu_ps(node.bounds[rb.near[axis]].as_ptr());
                let hi = _mm256_loadu_ps(node.bounds[rb.far[axis]].as_ptr());
                // max and min return their second operand when one is NaN, as `wide`'s
                // fast_max and fast_min do; none arises (finite 1/d, see RayBox8::new).
                t_near = _mm256_max_ps(t_near, _mm256_mul_ps(_mm256_sub_ps(lo, o), inv));
                t_far = _mm256_min_ps(t_far, _mm256_mul_ps(_mm256_sub_ps(hi, o), inv));
            }
            let far = _mm256_mul_ps(t_far, _mm256_set1_ps(FAR_SCALE));
            let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_near, far)) as u32;
            let mut out = [0.0f32; 8];
            _mm256_storeu_ps(out.as_mut_ptr(), t_near);
            (out, mask)
        }
    }

    /// The four-lane test's formulas on eight lanes at once (see `RayTri4::hit`): the same
    /// operations in the same order, no fused multiply-add, so every lane's values equal the
    /// four-lane test's bit for bit; the double-precision retry runs per block of four, as there.
    #[inline(always)]
    fn leaf_pair(self, rt: &RayTri4, a: &Leaf4, b: &Leaf4, t_max: f32) -> Option<(f32, usize, f32, f32)> {
        use std::arch::x86_64::*;
        // SAFETY: `self` proves the CPU has AVX (`Avx2::detect`). Every load reads one row of
        // a block, four f32 in bounds (`loadu` needs no alignment); stores write local arrays
        // of eight f32.
        unsafe {
            let row = |r: usize| {
                _mm256_insertf128_ps::<1>(
                    _mm256_castps128_ps256(_mm_loadu_ps(a.v[r].as_ptr())),
                    _mm_loadu_ps(b.v[r].as_ptr()),
                )
            };
            let [kx, ky, kz] = rt.k;
            let rel = |vertex: usize, axis: usize| {
                _mm256_sub_ps(row(3 * vertex + axis), _mm256_set1_ps(rt.o[axis]))
            };
            let (sx, sy, sz) =
                (_mm256_set1_ps(rt.shear[0]), _mm256_set1_ps(rt.shear[1]), _mm256_set1_ps(rt.shear[2]));
            let (mul, sub, add) =
                (|x, y| _mm256_mul_ps(x, y), |x, y| _mm256_sub_ps(x, y), |x, y| _mm256_add_ps(x, y));
            let (az, bz, cz) = (rel(0, kz), rel(1, kz), rel(2, kz));
            let ax = sub(rel(0, kx), mul(sx, az));
            let ay = sub(rel(0, ky), mul(sy, az));
            let bx = sub(rel(1, kx), mul(sx, bz));
            let by = sub(rel(1, ky), mul(sy, bz));
            let cx = sub(rel(2, kx), mul(sx, cz));
            let cy = sub(rel(2, ky), mul(sy, cz));
            let mut u = sub(mul(cx, by), mul(cy, bx));
            let mut v = sub(mul(ax, cy), mul(ay, cx));
            let mut w = sub(mul(bx, ay), mul(by, ax));
            let zero = _mm256_setzero_ps();
            let cmp_eq = |x| _mm256_cmp_ps::<_CMP_EQ_OQ>(x, zero);
            let on_edge = _mm256_movemask_ps(_mm256_or_ps(_mm256_or_ps(cmp_eq(u), cmp_eq(v)), cmp_eq(w)));
            if on_edge != 0 {
                // On an edge: decide in f64, every lane of each block that has such a lane.
                let store = |x: __m256| {
                    let mut out = [0.0f32; 8];
                    _mm256_storeu_ps(out.as_mut_ptr(), x);
                    out
                };
                let (ax, ay, bx, by, cx, cy) =
                    (store(ax), store(ay), store(bx), store(by), store(cx), store(cy));
                let (mut uu, mut vv, mut ww) = (store(u), store(v), store(w));
                for l in 0..8 {
                    if on_edge & (0xf << (l & 4)) != 0 {
                        let (ax, ay, bx, by, cx, cy) = (
                            ax[l] as f64,
                            ay[l] as f64,
                            bx[l] as f64,
                            by[l] as f64,
                            cx[l] as f64,
                            cy[l] as f64,
                        );
                        uu[l] = (cx * by - cy * bx) as f32;
                        vv[l] = (ax * cy - ay * cx) as f32;
                        ww[l] = (bx * ay - by * ax) as f32;
                    }
                }
                (u, v, w) = (
                    _mm256_loadu_ps(uu.as_ptr()),
                    _mm256_loadu_ps(vv.as_ptr()),
                    _mm256_loadu_ps(ww.as_ptr()),
                );
            }
            let all = |x, y, z| _mm256_and_ps(_mm256_and_ps(x, y), z);
            let ge = |x| _mm256_cmp_ps::<_CMP_GE_OQ>(x, zero);
            let le = |x| _mm256_cmp_ps::<_CMP_LE_OQ>(x, zero);
            // All three edge functions of one sign (or zero): false for NaN (unused) lanes.
            let inside = _mm256_or_ps(all(ge(u), ge(v), ge(w)), all(le(u), le(v), le(w)));
            if _mm256_movemask_ps(inside) == 0 {
                return None;
            }
            let det = add(add(u, v), w);
            let t_scaled = add(add(mul(u, mul(sz, az)), mul(v, mul(sz, bz))), mul(w, mul(sz, cz)));
            let sign = _mm256_and_ps(det, _mm256_set1_ps(-0.0));
            let (t_signed, det_abs) = (_mm256_xor_ps(t_scaled, sign), _mm256_xor_ps(det, sign));
            let in_range = all(
                _mm256_and_ps(inside, _mm256_cmp_ps::<_CMP_NEQ_UQ>(det, zero)),
                _mm256_cmp_ps::<_CMP_GT_OQ>(t_signed, zero),
                _mm256_cmp_ps::<_CMP_LE_OQ>(t_signed, mul(_mm256_set1_ps(t_max), det_abs)),
            );
            if _mm256_movemask_ps(in_range) == 0 {
                return None;
            }
            let bound = {
                let abs = |x| _mm256_andnot_ps(_mm256_set1_ps(-0.0), x);
                let max3 = |x, y, z| _mm256_max_ps(_mm256_max_ps(abs(x), abs(y)), abs(z));
                let (max_x, max_y) = (max3(ax, bx, cx), max3(ay, by, cy));
                let max_z = max3(mul(sz, az), mul(sz, bz), mul(sz, cz));
                let max_e = max3(u, v, w);
                let g = |n: f32| _mm256_set1_ps(gamma(n));
                let delta_x = mul(g(5.0), add(max_x, max_z));
                let delta_y = mul(g(5.0), add(max_y, max_z));
                let delta_z = mul(g(3.0), max_z);
                let delta_e = mul(
                    _mm256_set1_ps(2.0),
                    add(add(mul(mul(g(2.0), max_x), max_y), mul(delta_y, max_x)), mul(delta_x, max_y)),
                );
                mul(
                    _mm256_set1_ps(3.0),
                    add(add(mul(mul(g(3.0), max_e), max_z), mul(delta_e, max_z)), mul(delta_z, max_e)),
                )
            };
            let valid = _mm256_and_ps(in_range, _mm256_cmp_ps::<_CMP_GT_OQ>(t_signed, bound));
            let mut mask = _mm256_movemask_ps(valid) as u32;
            if mask == 0 {
                return None;
            }
            let inv = _mm256_div_ps(_mm256_set1_ps(1.0), det);
            let (mut t, mut uo, mut vo) = ([0.0f32; 8], [0.0f32; 8], [0.0f32; 8]);
            _mm256_storeu_ps(t.as_mut_ptr(), mul(t_scaled, inv));
            _mm256_storeu_ps(uo.as_mut_ptr(), mul(v, inv));
            _mm256_storeu_ps(vo.as_mut_ptr(), mul(w, inv));
            let mut best = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            while mask != 0 {
                let l = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if t[l] < t[best] {
                    best = l;
                }
            }
            Some((t[best], best, uo[best], vo[best]))
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

/// The kernels this CPU runs best, chosen once per tree.
#[derive(Clone, Copy, Debug)]
pub enum Isa {
    Portable,
    #[cfg(target_arch = "x86_64")]
    Avx2(Avx2),
}

impl Isa {
    /// AVX2 where this CPU has it, else portable.
    pub fn best() -> Isa {
        #[cfg(target_arch = "x86_64")]
        if let Some(k) = Avx2::detect() {
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
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampler::Sampler;

    /// The AVX2 slab test gives the portable test's distances and masks bit for bit, on random
    /// boxes (some empty, some thin, some behind the ray) and random rays, including rays with
    /// zero direction components and rays starting on a box's planes.
    #[test]
    fn avx2_box_test_equals_the_portable_one() {
        #[cfg(target_arch = "x86_64")]
        {
            let Some(avx2) = Avx2::detect() else {
                eprintln!("no AVX2 on this CPU: only the portable kernel runs here");
                return;
            };
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
                let (ta, ma) = avx2.hit(&rb, &node, t_max);
                assert_eq!(mp, ma, "masks differ for {ray:?}");
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

    /// The eight-lane leaf test gives the four-lane test's answer bit for bit (distance, lane,
    /// u and v): on random triangles, on triangles of whole coordinates met by rays through
    /// their vertices and along their edges (where the edge functions are zero and the
    /// double-precision retry runs), and on the same triangle in both blocks (a tie).
    #[test]
    fn avx2_leaf_pair_equals_the_portable_one() {
        #[cfg(target_arch = "x86_64")]
        {
            let Some(avx2) = Avx2::detect() else {
                eprintln!("no AVX2 on this CPU: only the portable kernel runs here");
                return;
            };
            let mut rng = Sampler::new(11, 1, 0);
            let mut f = |scale: f32| (rng.next_1d() * 2.0 - 1.0) * scale;
            let (mut hits, mut second, mut on_grid) = (0, 0, 0);
            for case in 0..20_000usize {
                let grid = case % 4 == 0;
                let count = 1 + case % 8;
                let mut blocks = [Leaf4::EMPTY; 2];
                let mut vertices = Vec::new();
                for i in 0..count {
                    let tri: [[f32; 3]; 3] = if grid {
                        std::array::from_fn(|_| [f(4.0).round(), f(4.0).round(), f(4.0).round()])
                    } else {
                        std::array::from_fn(|_| [f(5.0), f(5.0), f(5.0)])
                    };
                    let tri = if case % 5 == 0 && i == 4 { vertices[0] } else { tri };
                    for (k, vertex) in tri.iter().enumerate() {
                        for (a, &x) in vertex.iter().enumerate() {
                            blocks[i / 4].v[3 * k + a][i % 4] = x;
                        }
                    }
                    vertices.push(tri);
                }
                let target = vertices[case % count];
                let ray = if grid {
                    // Along an axis, through a vertex or the middle of an edge: exact zeros.
                    let p = if case % 8 == 0 {
                        glam::Vec3::from(target[0])
                    } else {
                        (glam::Vec3::from(target[0]) + glam::Vec3::from(target[1])) * 0.5
                    };
                    let axis = case % 3;
                    let mut dir = glam::Vec3::ZERO;
                    dir[axis] = if case % 6 < 3 { 1.0 } else { -1.0 };
                    Ray { origin: p - dir * 10.0, dir, t_max: f32::INFINITY }
                } else {
                    let w = [f(1.0).abs(), f(1.0).abs(), f(1.0).abs()];
                    let sum = w[0] + w[1] + w[2] + 1e-6;
                    let aim = (0..3)
                        .fold(glam::Vec3::ZERO, |acc, k| acc + glam::Vec3::from(target[k]) * (w[k] / sum));
                    let origin = glam::Vec3::new(f(12.0), f(12.0), f(12.0));
                    let t_max = if case % 3 == 0 { f(30.0).abs() } else { f32::INFINITY };
                    Ray { origin, dir: aim - origin, t_max }
                };
                let rt = RayTri4::new(&ray);
                let portable = rt.hit_pair(&blocks[0], &blocks[1], ray.t_max);
                let eight = avx2.leaf_pair(&rt, &blocks[0], &blocks[1], ray.t_max);
                let bits = |h: Option<(f32, usize, f32, f32)>| {
                    h.map(|(t, l, u, v)| (t.to_bits(), l, u.to_bits(), v.to_bits()))
                };
                assert_eq!(bits(portable), bits(eight), "case {case}: {ray:?}");
                if let Some((_, lane, _, _)) = portable {
                    hits += 1;
                    second += usize::from(lane >= 4);
                    on_grid += usize::from(grid);
                }
            }
            // Both blocks' lanes and the exact edge cases were met often enough to mean something.
            assert!(
                hits > 10_000 && second > 2_000 && on_grid > 1_000,
                "{hits} hits, {second} in the second block, {on_grid} on the grid"
            );
        }
    }
}
