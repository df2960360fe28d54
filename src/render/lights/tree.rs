//! A light tree for next-event estimation among many lights (Conty Estevez & Kulla, "Importance
//! Sampling of Many Lights with Adaptive Tree Splitting", 2018; as pbrt-v4's `BVHLightSampler`).
//! Every bounded emitter (a point, a spot, a sphere, each triangle of an emissive mesh, each
//! instance's own) is a leaf; a node bounds its leaves' positions, their summed intensity and
//! the cone of directions they shine into. At a shading point a light is picked by descending
//! from the root, choosing each child in proportion to an upper bound of what it can send to
//! that point (`Bound::importance`); the probability of any leaf at any point is found
//! again, exactly, by following its parents back to the root ([`LightTree::pmf`]), which is
//! what multiple importance sampling needs for a light a BSDF sample hits.
//!
//! Intensity, not power: a leaf's `phi` is the most radiant intensity it sends in one direction
//! (a point's `I`, a Lambertian triangle's `L A`), so `phi cos / d^2` bounds the irradiance it
//! gives. pbrt-v4 uses power (`4 pi I` for a point, `pi L A` for an area), which weighs a point
//! light four times an area light of the same irradiance.

use glam::{Quat, Vec3};

use crate::accel::bvh::simd::{Inlined, Isa};

/// A sample down the tree from `p` (normal `n`) with the uniform number `u`, as a job the
/// tree's [`Isa`] compiles.
struct SampleWalk<'t> {
    tree: &'t LightTree,
    p: Vec3,
    n: Vec3,
    u: f32,
}

impl Inlined for SampleWalk<'_> {
    type Output = Option<(u32, f32, f32)>;

    #[inline(always)]
    fn run(self) -> Self::Output {
        self.tree.sample_in(self.p, self.n, self.u)
    }
}

/// Item `item`'s probability, up the tree from `p` (normal `n`), as a job likewise.
struct PmfWalk<'t> {
    tree: &'t LightTree,
    item: u32,
    p: Vec3,
    n: Vec3,
}

impl Inlined for PmfWalk<'_> {
    type Output = f32;

    #[inline(always)]
    fn run(self) -> f32 {
        self.tree.pmf_in(self.item, self.p, self.n)
    }
}

/// No node: the root's parent.
const NONE: u32 = u32::MAX;
/// The largest float below one, for rescaling a number through the descent.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;
/// Buckets of centroids per axis when choosing a split.
const BUCKETS: usize = 12;

/// What a set of lights can send: where they are, how much, and toward where.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightBounds {
    pub lo: Vec3,
    pub hi: Vec3,
    /// The most radiant intensity (luminance, W/sr) the set sends in one direction, summed
    /// over its lights.
    pub phi: f32,
    /// The axis of the cone of the lights' normals (or spot directions).
    pub w: Vec3,
    /// The cosine of the cone's half angle (-1: every direction).
    pub cos_o: f32,
    /// The cosine of the angle beyond the normals' cone that the lights still shine into (0
    /// for a Lambertian surface: 90 degrees).
    pub cos_e: f32,
}

impl LightBounds {
    /// A light at a point that shines every way (a point light, or a sphere's box).
    pub fn omni(lo: Vec3, hi: Vec3, phi: f32) -> LightBounds {
        LightBounds { lo, hi, phi, w: Vec3::Z, cos_o: -1.0, cos_e: -1.0 }
    }

    /// The union of two sets; a set of no intensity adds nothing.
    pub fn union(&self, o: &LightBounds) -> LightBounds {
        if self.phi <= 0.0 {
            return *o;
        }
        if o.phi <= 0.0 {
            return *self;
        }
        let (w, cos_o) = cone_union((self.w, self.cos_o), (o.w, o.cos_o));
        LightBounds {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
            phi: self.phi + o.phi,
            w,
            cos_o,
            cos_e: self.cos_e.min(o.cos_e),
        }
    }

    fn centroid(&self) -> Vec3 {
        0.5 * (self.lo + self.hi)
    }

    /// pbrt-v4's cost of a node for the split heuristic: its intensity times the solid angle
    /// its cone (widened by `theta_e`) covers, times its surface area, the box made
    /// regular along `axis` (`kr`).
    fn cost(&self, axis: usize) -> f32 {
        let theta_o = self.cos_o.clamp(-1.0, 1.0).acos();
        let theta_e = self.cos_e.clamp(-1.0, 1.0).acos();
        let theta_w = (theta_o + theta_e).min(std::f32::consts::PI);
        let sin_o = (1.0 - self.cos_o * self.cos_o).max(0.0).sqrt();
        let pi = std::f32::consts::PI;
        let m_omega = 2.0 * pi * (1.0 - self.cos_o)
            + pi / 2.0
                * (2.0 * theta_w * sin_o - (theta_o - 2.0 * theta_w).cos() - 2.0 * theta_o * sin_o
                    + self.cos_o);
        let d = self.hi - self.lo;
        let kr = if d[axis] > 0.0 { d.max_element() / d[axis] } else { 1.0 };
        let area = 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
        // A point (area 0) still costs by its intensity and cone.
        self.phi * m_omega * kr * area.max(1e-12)
    }
}

/// What the descent reads of a node's [`LightBounds`], made once: its box as a sphere, and its
/// cone's sine beside its cosine.
#[derive(Clone, Copy, Debug)]
struct Bound {
    centre: Vec3,
    /// The squared radius of the box's bounding sphere (half its diagonal).
    r2: f32,
    phi: f32,
    w: Vec3,
    cos_o: f32,
    sin_o: f32,
    cos_e: f32,
}

impl Bound {
    fn of(b: &LightBounds) -> Bound {
        Bound {
            centre: b.centroid(),
            r2: 0.25 * (b.hi - b.lo).length_squared(),
            phi: b.phi,
            w: b.w,
            cos_o: b.cos_o,
            sin_o: (1.0 - b.cos_o * b.cos_o).max(0.0).sqrt(),
            cos_e: b.cos_e,
        }
    }

    /// An upper bound of the irradiance these lights can give at `p` on a surface of normal
    /// `n` (one-sided: light from below `n` counts nothing; no normal, `n` zero, counts all),
    /// up to a common factor: pbrt-v4's `LightBounds::Importance` with the receiver's cosine
    /// taken on its front side only, as next-event estimation gathers light there only.
    #[inline(always)]
    fn importance(&self, p: Vec3, n: Vec3) -> f32 {
        if self.phi <= 0.0 {
            return 0.0;
        }
        let v = p - self.centre;
        let dist2 = v.length_squared();
        // Within the bounding sphere every direction is possible, and the distance is clamped.
        let (d2, sin_b, cos_b) = if dist2 <= self.r2 {
            (self.r2.max(f32::MIN_POSITIVE), 0.0, -1.0)
        } else {
            let sin2 = self.r2 / dist2;
            (dist2, sin2.sqrt(), (1.0 - sin2).sqrt())
        };
        let wi = if dist2 > 0.0 { v * dist2.sqrt().recip() } else { Vec3::ZERO };
        // The angle between the lights' axis and the direction to p, less the cone's spread
        // and the box's: the smallest angle any light of the set can see p at.
        let cos_w = self.w.dot(wi);
        let sin_w = (1.0 - cos_w * cos_w).max(0.0).sqrt();
        let (sin_x, cos_x) = sub_clamped((sin_w, cos_w), (self.sin_o, self.cos_o));
        let (_, cos_p) = sub_clamped((sin_x, cos_x), (sin_b, cos_b));
        if cos_p <= self.cos_e {
            return 0.0;
        }
        let mut importance = self.phi * cos_p / d2;
        if n != Vec3::ZERO {
            // The receiver's cosine, at the most favourable direction within the box.
            let cos_i = -wi.dot(n);
            let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
            let (_, cos_pi) = sub_clamped((sin_i, cos_i), (sin_b, cos_b));
            importance *= cos_pi.max(0.0);
        }
        importance.max(0.0)
    }
}

/// cos and sin of max(0, a - b) for angles a, b in [0, pi] given by their sines and cosines.
#[inline(always)]
fn sub_clamped((sin_a, cos_a): (f32, f32), (sin_b, cos_b): (f32, f32)) -> (f32, f32) {
    if cos_a > cos_b {
        return (0.0, 1.0);
    }
    (sin_a * cos_b - cos_a * sin_b, cos_a * cos_b + sin_a * sin_b)
}

/// The smallest cone (axis, cosine) holding both cones (pbrt-v4's `Union` of `DirectionCone`s).
fn cone_union(a: (Vec3, f32), b: (Vec3, f32)) -> (Vec3, f32) {
    let pi = std::f32::consts::PI;
    let theta_a = a.1.clamp(-1.0, 1.0).acos();
    let theta_b = b.1.clamp(-1.0, 1.0).acos();
    let theta_d = a.0.dot(b.0).clamp(-1.0, 1.0).acos();
    if (theta_d + theta_b).min(pi) <= theta_a {
        return a;
    }
    if (theta_d + theta_a).min(pi) <= theta_b {
        return b;
    }
    let theta_o = 0.5 * (theta_a + theta_d + theta_b);
    if theta_o >= pi {
        return (Vec3::Z, -1.0);
    }
    let axis = a.0.cross(b.0);
    if axis.length_squared() < 1e-12 {
        return (Vec3::Z, -1.0);
    }
    let w = Quat::from_axis_angle(axis.normalize(), theta_o - theta_a) * a.0;
    (w.normalize(), theta_o.cos())
}

/// A node: its bounds, its place, and its children or leaf.
#[derive(Clone, Debug)]
struct Node {
    bounds: Bound,
    /// Interior: the second child (the first is the next node). Leaf: the leaf's item.
    second_or_item: u32,
    leaf: bool,
    parent: u32,
}

/// The tree over a scene's bounded lights, each an item numbered by the caller.
#[derive(Clone, Debug, Default)]
pub struct LightTree {
    nodes: Vec<Node>,
    /// For each item, its leaf.
    leaf_of: Vec<u32>,
    /// The build [`LightTree::sample`] and [`LightTree::pmf`] run in: their walks down and up
    /// the tree took half of a many-light render's time, a third less in AVX-512's build.
    isa: Isa,
}

impl LightTree {
    /// The tree over `items` (item `i` is `items[i]`); empty when there are none.
    pub fn new(items: &[LightBounds]) -> LightTree {
        let mut tree = LightTree {
            nodes: Vec::with_capacity(2 * items.len()),
            leaf_of: vec![NONE; items.len()],
            isa: Isa::for_loops(),
        };
        if items.is_empty() {
            return tree;
        }
        let mut order: Vec<u32> = (0..items.len() as u32).collect();
        tree.build(items, &mut order, NONE);
        tree
    }

    /// Whether the tree holds no light.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Builds the subtree over `order`'s items under `parent`; its root's index.
    fn build(&mut self, items: &[LightBounds], order: &mut [u32], parent: u32) -> u32 {
        let at = self.nodes.len() as u32;
        let bounds = order.iter().skip(1).fold(items[order[0] as usize], |b, &i| b.union(&items[i as usize]));
        self.nodes.push(Node { bounds: Bound::of(&bounds), second_or_item: 0, leaf: false, parent });
        if let [item] = order {
            self.nodes[at as usize].leaf = true;
            self.nodes[at as usize].second_or_item = *item;
            self.leaf_of[*item as usize] = at;
            return at;
        }
        let mid = split(items, order);
        let (below, above) = order.split_at_mut(mid);
        self.build(items, below, at);
        let second = self.build(items, above, at);
        self.nodes[at as usize].second_or_item = second;
        at
    }

    /// The children of interior node `at` and the probability of descending into the first,
    /// seen from `p` (normal `n`): in proportion to their importances; `None` when neither
    /// lets any light through.
    #[inline(always)]
    fn children(&self, at: usize, p: Vec3, n: Vec3) -> Option<(usize, usize, f32)> {
        let (a, b) = (at + 1, self.nodes[at].second_or_item as usize);
        let (ia, ib) = (self.nodes[a].bounds.importance(p, n), self.nodes[b].bounds.importance(p, n));
        if ia <= 0.0 && ib <= 0.0 {
            return None;
        }
        Some((a, b, ia / (ia + ib)))
    }

    /// Picks an item as seen from `p` (surface normal `n`) with the uniform number `u`: the
    /// item, its probability and `u` rescaled for reuse. `None` when no light can reach `p`.
    pub fn sample(&self, p: Vec3, n: Vec3, u: f32) -> Option<(u32, f32, f32)> {
        self.isa.run(SampleWalk { tree: self, p, n, u })
    }

    /// [`LightTree::sample`] in the build it runs in.
    #[inline(always)]
    fn sample_in(&self, p: Vec3, n: Vec3, mut u: f32) -> Option<(u32, f32, f32)> {
        let root = self.nodes.first()?;
        if root.leaf {
            return (root.bounds.importance(p, n) > 0.0).then_some((root.second_or_item, 1.0, u));
        }
        let (mut at, mut pmf) = (0usize, 1.0f32);
        loop {
            let node = &self.nodes[at];
            if node.leaf {
                return Some((node.second_or_item, pmf, u));
            }
            let (a, b, pa) = self.children(at, p, n)?;
            if u < pa {
                at = a;
                pmf *= pa;
                u = (u / pa).min(ONE_MINUS_EPSILON);
            } else {
                at = b;
                pmf *= 1.0 - pa;
                u = ((u - pa) / (1.0 - pa)).min(ONE_MINUS_EPSILON);
            }
        }
    }

    /// The probability that [`LightTree::sample`] picks `item` from `p` (normal `n`).
    pub fn pmf(&self, item: u32, p: Vec3, n: Vec3) -> f32 {
        self.isa.run(PmfWalk { tree: self, item, p, n })
    }

    /// [`LightTree::pmf`] in the build it runs in.
    #[inline(always)]
    fn pmf_in(&self, item: u32, p: Vec3, n: Vec3) -> f32 {
        let Some(&leaf) = self.leaf_of.get(item as usize) else { return 0.0 };
        if leaf == NONE {
            return 0.0;
        }
        let mut at = leaf as usize;
        if at == 0 {
            return if self.nodes[0].bounds.importance(p, n) > 0.0 { 1.0 } else { 0.0 };
        }
        let mut pmf = 1.0f32;
        while self.nodes[at].parent != NONE {
            let parent = self.nodes[at].parent as usize;
            let Some((a, _, pa)) = self.children(parent, p, n) else { return 0.0 };
            pmf *= if at == a { pa } else { 1.0 - pa };
            at = parent;
        }
        pmf
    }

    /// The probability that [`LightTree::sample`] finds no light from `p` (normal `n`): that
    /// it reaches a node whose bound lets some light through but whose children's both say
    /// none (their bounds are tighter), or that the root's bound lets none through. With the
    /// items' probabilities it sums to one.
    #[cfg(test)]
    fn no_light(&self, p: Vec3, n: Vec3) -> f32 {
        fn below(tree: &LightTree, at: usize, p: Vec3, n: Vec3) -> f32 {
            if tree.nodes[at].leaf {
                return 0.0;
            }
            let Some((a, b, pa)) = tree.children(at, p, n) else { return 1.0 };
            pa * below(tree, a, p, n) + (1.0 - pa) * below(tree, b, p, n)
        }
        match self.nodes.first() {
            None => 1.0,
            Some(root) if root.leaf => (root.bounds.importance(p, n) <= 0.0) as u32 as f32,
            Some(_) => below(self, 0, p, n),
        }
    }

    /// The number of nodes (for `info` and tests).
    pub fn nodes(&self) -> usize {
        self.nodes.len()
    }

    /// The depth of the deepest leaf (the root's is 0) and the mean depth of the leaves.
    pub fn depth(&self) -> (usize, f32) {
        let depths: Vec<usize> = self
            .leaf_of
            .iter()
            .map(|&leaf| {
                let (mut at, mut d) = (leaf, 0);
                while at != NONE && self.nodes[at as usize].parent != NONE {
                    at = self.nodes[at as usize].parent;
                    d += 1;
                }
                d
            })
            .collect();
        let mean = depths.iter().sum::<usize>() as f32 / depths.len().max(1) as f32;
        (depths.iter().copied().max().unwrap_or(0), mean)
    }
}

/// Orders `order` and returns where it splits in two, by pbrt-v4's cost over buckets of the
/// items' centroids along each axis; items whose centroids coincide split in the middle.
fn split(items: &[LightBounds], order: &mut [u32]) -> usize {
    let (mut clo, mut chi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for &i in order.iter() {
        let c = items[i as usize].centroid();
        clo = clo.min(c);
        chi = chi.max(c);
    }
    let extent = chi - clo;
    let mut best: Option<(f32, usize, usize)> = None; // cost, axis, last bucket below
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let bucket = |i: u32| bucket_of(items[i as usize].centroid()[axis], clo[axis], extent[axis]);
        let mut buckets: [Option<LightBounds>; BUCKETS] = [None; BUCKETS];
        for &i in order.iter() {
            let b = &mut buckets[bucket(i)];
            *b = Some(match b {
                Some(x) => x.union(&items[i as usize]),
                None => items[i as usize],
            });
        }
        let cost_of = |range: &[Option<LightBounds>]| {
            range
                .iter()
                .flatten()
                .fold(None::<LightBounds>, |acc, b| Some(acc.map_or(*b, |a| a.union(b))))
                .map_or(0.0, |b| b.cost(axis))
        };
        for cut in 0..BUCKETS - 1 {
            let cost = cost_of(&buckets[..=cut]) + cost_of(&buckets[cut + 1..]);
            if best.is_none_or(|(c, ..)| cost < c) {
                best = Some((cost, axis, cut));
            }
        }
    }
    let mid = match best {
        Some((_, axis, cut)) => {
            let below =
                |i: &u32| bucket_of(items[*i as usize].centroid()[axis], clo[axis], extent[axis]) <= cut;
            partition(order, below)
        }
        None => 0,
    };
    if mid == 0 || mid == order.len() {
        // All on one side (equal centroids): halves in a fixed order.
        order.sort_unstable();
        return order.len() / 2;
    }
    mid
}

/// The bucket of a centroid at `c` along an axis whose centroids span `lo` to `lo + extent`.
fn bucket_of(c: f32, lo: f32, extent: f32) -> usize {
    (((c - lo) / extent * BUCKETS as f32) as usize).min(BUCKETS - 1)
}

/// Moves the items for which `below` holds to the front, keeping each side's order (the tree
/// is the same for the same items); how many they are.
fn partition(order: &mut [u32], below: impl Fn(&u32) -> bool) -> usize {
    let (mut front, back): (Vec<u32>, Vec<u32>) = order.iter().partition(|i| below(i));
    let mid = front.len();
    front.extend(back);
    order.copy_from_slice(&front);
    mid
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampler::Sampler;

    /// Lights of varied intensity and orientation scattered over a plane, some points.
    fn field(n: usize) -> Vec<LightBounds> {
        let mut s = Sampler::new(5, 1, 2);
        (0..n)
            .map(|i| {
                let u = s.next_2d();
                let v = s.next_2d();
                let p = Vec3::new(40.0 * u.x - 20.0, 3.0 * v.x, 40.0 * u.y - 20.0);
                let phi = 10f32.powf(3.0 * v.y);
                if i % 3 == 0 {
                    LightBounds::omni(p, p, phi)
                } else {
                    let w = Vec3::new(v.x - 0.5, -1.0, u.x - 0.5).normalize();
                    let h = Vec3::splat(0.1);
                    LightBounds { lo: p - h, hi: p + h, phi, w, cos_o: 1.0, cos_e: 0.0 }
                }
            })
            .collect()
    }

    /// Receivers above, below and among the lights, facing several ways.
    fn receivers() -> Vec<(Vec3, Vec3)> {
        let mut s = Sampler::new(8, 3, 1);
        (0..40)
            .map(|_| {
                let u = s.next_2d();
                let v = s.next_2d();
                let p = Vec3::new(50.0 * u.x - 25.0, 6.0 * v.x - 2.0, 50.0 * u.y - 25.0);
                (p, crate::math::uniform_sphere(s.next_2d()) * (v.y > 0.1) as u32 as f32)
            })
            .collect()
    }

    /// The walks in every build this CPU runs (AVX2's and AVX-512's, whichever
    /// [`Isa::for_loops`] picks) give the portable build's samples and probabilities bit for bit.
    #[test]
    fn the_walks_in_any_build_give_the_same_bits() {
        let items = field(300);
        let portable = LightTree { isa: Isa::Portable, ..LightTree::new(&items) };
        let mut s = Sampler::new(4, 1, 7);
        let bits = |x: Option<(u32, f32, f32)>| x.map(|(i, p, u)| (i, p.to_bits(), u.to_bits()));
        let trees: Vec<LightTree> =
            Isa::all().into_iter().skip(1).map(|isa| LightTree { isa, ..portable.clone() }).collect();
        for ((p, n), tree) in receivers().into_iter().flat_map(|r| trees.iter().map(move |t| (r, t))) {
            for _ in 0..100 {
                let u = s.next_1d();
                assert_eq!(bits(tree.sample(p, n, u)), bits(portable.sample(p, n, u)), "{}", tree.isa.name());
            }
            for i in 0..items.len() as u32 {
                assert_eq!(tree.pmf(i, p, n).to_bits(), portable.pmf(i, p, n).to_bits());
            }
        }
    }

    #[test]
    fn the_pmf_sums_to_one_and_matches_what_sampling_picks() {
        let items = field(300);
        let tree = LightTree::new(&items);
        assert_eq!(tree.nodes(), 2 * items.len() - 1);
        let mut s = Sampler::new(1, 2, 3);
        let mut count = 0;
        for (p, n) in receivers() {
            let total: f32 = (0..items.len() as u32).map(|i| tree.pmf(i, p, n)).sum();
            // With the chance of finding no light, the items' probabilities sum to one.
            let none = tree.no_light(p, n);
            assert!((total + none - 1.0).abs() < 1e-4, "sum {total} + {none} at {p} {n}");
            // Some receivers see no light at all (every light behind them): then nothing.
            if total == 0.0 {
                assert!((0..64).all(|_| tree.sample(p, n, s.next_1d()).is_none()));
                continue;
            }
            count += 1;
            // The probability sampling reports is the one `pmf` gives for that item.
            for _ in 0..200 {
                let Some((item, pmf, u)) = tree.sample(p, n, s.next_1d()) else { continue };
                let again = tree.pmf(item, p, n);
                assert!((pmf - again).abs() <= 1e-5 * again, "{pmf} vs {again}");
                assert!((0.0..1.0).contains(&u));
            }
        }
        assert!(count > 20, "{count} receivers see light");
    }

    #[test]
    fn sampling_frequencies_follow_the_pmf() {
        let items = field(40);
        let tree = LightTree::new(&items);
        let (p, n) = (Vec3::new(1.0, 0.0, 2.0), Vec3::Y);
        let mut counts = vec![0u32; items.len()];
        let mut s = Sampler::new(4, 4, 4);
        let draws = 400_000;
        for _ in 0..draws {
            if let Some((i, ..)) = tree.sample(p, n, s.next_1d()) {
                counts[i as usize] += 1;
            }
        }
        // Chi-square over the items, pooling those expected fewer than 5 times.
        let (mut chi2, mut dof) = (0.0f64, 0usize);
        let (mut pool_o, mut pool_e) = (0.0f64, 0.0f64);
        for (i, &c) in counts.iter().enumerate() {
            let e = tree.pmf(i as u32, p, n) as f64 * draws as f64;
            if e < 5.0 {
                pool_o += c as f64;
                pool_e += e;
            } else {
                chi2 += (c as f64 - e).powi(2) / e;
                dof += 1;
            }
        }
        if pool_e >= 5.0 {
            chi2 += (pool_o - pool_e).powi(2) / pool_e;
            dof += 1;
        }
        let z = (chi2 - dof as f64) / (2.0 * dof as f64).sqrt();
        assert!(dof > 10 && z < 4.0, "z = {z} over {dof}");
    }

    #[test]
    fn a_control_that_breaks_the_pmf_fails() {
        // A pmf that forgets the receiver's normal no longer sums to one where it matters:
        // the tests above would catch an evaluation that differs from sampling.
        let items = field(100);
        let tree = LightTree::new(&items);
        let (p, n) = (Vec3::new(0.0, 1.0, 0.0), Vec3::X);
        let wrong: f32 = (0..items.len() as u32).map(|i| tree.pmf(i, p, Vec3::ZERO)).sum();
        let right: f32 = (0..items.len() as u32).map(|i| tree.pmf(i, p, n)).sum();
        assert!((right + tree.no_light(p, n) - 1.0).abs() < 1e-4);
        let mut s = Sampler::new(2, 2, 2);
        let picked: Vec<(u32, f32)> =
            (0..200).filter_map(|_| tree.sample(p, n, s.next_1d())).map(|(i, pmf, _)| (i, pmf)).collect();
        let mismatched =
            picked.iter().filter(|(i, pmf)| (tree.pmf(*i, p, Vec3::ZERO) - pmf).abs() > 1e-3 * pmf);
        assert!(picked.len() > 150 && mismatched.count() > 100, "sum without the normal {wrong}");
    }

    #[test]
    fn nearer_and_brighter_lights_are_picked_more() {
        // Two equal lights, one near, one far; then a bright far one against a dim near one.
        let near = LightBounds::omni(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 0.0), 1.0);
        let far = LightBounds::omni(Vec3::new(0.0, 10.0, 0.0), Vec3::new(0.0, 10.0, 0.0), 1.0);
        let tree = LightTree::new(&[near, far]);
        let p = Vec3::ZERO;
        assert!((tree.pmf(0, p, Vec3::Y) / tree.pmf(1, p, Vec3::Y) - 100.0).abs() < 1e-2);
        // Behind the receiver: nothing.
        assert_eq!(tree.pmf(0, p, -Vec3::Y), 0.0);
        assert!(tree.sample(p, -Vec3::Y, 0.3).is_none());
        // A triangle facing away from the receiver sends it nothing.
        let away = LightBounds {
            lo: Vec3::new(-0.1, 2.0, -0.1),
            hi: Vec3::new(0.1, 2.0, 0.1),
            phi: 5.0,
            w: Vec3::Y,
            cos_o: 1.0,
            cos_e: 0.0,
        };
        let tree = LightTree::new(&[near, away]);
        assert_eq!(tree.pmf(1, p, Vec3::Y), 0.0);
        assert_eq!(tree.pmf(0, p, Vec3::Y), 1.0);
    }

    #[test]
    fn cone_union_holds_both_cones() {
        let mut s = Sampler::new(7, 7, 7);
        for _ in 0..500 {
            let a = crate::math::uniform_sphere(s.next_2d());
            let b = crate::math::uniform_sphere(s.next_2d());
            let (ca, cb) = (s.next_1d() * 2.0 - 1.0, s.next_1d() * 2.0 - 1.0);
            let (w, c) = cone_union((a, ca), (b, cb));
            // Each cone's axis, and its rim in the plane of the two axes, lies inside.
            for (axis, cos) in [(a, ca), (b, cb)] {
                let angle = axis.dot(w).clamp(-1.0, 1.0).acos() + cos.clamp(-1.0, 1.0).acos();
                assert!(angle.min(std::f32::consts::PI) <= c.clamp(-1.0, 1.0).acos() + 1e-3);
            }
        }
    }
}
