//! lightsplit's own BVH, in pure Rust. A binned-SAH build (parallel with rayon, `build.rs`) over
//! triangles and analytic spheres makes a binary tree of 32-byte nodes, two children side by
//! side, and collapses it into the 8-wide tree that rays traverse (`wide.rs`, its SIMD kernels in
//! `simd.rs`); the binary tree is then dropped unless the tests keep it (`keep_binary`) for the
//! reference traversal and [`Bvh::validate`]. The binary traversals here (`closest`, `any`) also
//! lead rays through the instance level (`instances.rs`): a binary tree over the boxes of placed
//! meshes, each mesh with its own wide tree. Every level tests triangles watertight (Woop,
//! Benthin & Wald, JCGT 2013) and boxes conservatively (Ize 2013), so no ray slips through a
//! shared edge.

mod build;
mod instances;
mod intersect;
pub(crate) mod pages;
pub mod simd;
pub mod wide;

use glam::{Vec3, Vec3A};

use super::{Accel, Hit, Ray};
use crate::scene::cutout::Cutouts;
use crate::scene::{Geometry, Scene};
use intersect::{prim_hit, RayTri};

/// Maximum traversal stack depth. The build caps the tree depth below this.
const STACK: usize = 64;

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3A,
    pub max: Vec3A,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb { min: Vec3A::splat(f32::INFINITY), max: Vec3A::splat(f32::NEG_INFINITY) };

    pub fn grow(&self, p: Vec3A) -> Aabb {
        Aabb { min: self.min.min(p), max: self.max.max(p) }
    }

    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    /// Half the surface area (enough for SAH ratios); 0 for an empty box.
    pub fn half_area(&self) -> f32 {
        let d = (self.max - self.min).max(Vec3A::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }

    pub fn centroid(&self) -> Vec3A {
        (self.min + self.max) * 0.5
    }
}

/// A flattened node: an inner node's two children are `first` and `first + 1`; a leaf holds
/// `count` primitives from `first` on.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub struct Node {
    pub min: [f32; 3],
    pub first: u32,
    pub max: [f32; 3],
    pub count: u32,
}

impl Node {
    /// A leaf of the `count` primitives from `first` on, in `bounds`.
    fn leaf(bounds: &Aabb, first: usize, count: usize) -> Node {
        Node { min: bounds.min.into(), first: first as u32, max: bounds.max.into(), count: count as u32 }
    }

    /// An inner node whose children are `first` and `first + 1`.
    fn inner(bounds: &Aabb, first: usize) -> Node {
        Node { min: bounds.min.into(), first: first as u32, max: bounds.max.into(), count: 0 }
    }

    fn bounds(&self) -> Aabb {
        Aabb { min: Vec3A::from(self.min), max: Vec3A::from(self.max) }
    }

    fn is_leaf(&self) -> bool {
        self.count > 0
    }

    /// A leaf's primitives: their positions in the leaf order.
    fn prims(&self) -> std::ops::Range<usize> {
        self.first as usize..(self.first + self.count) as usize
    }
}

/// A primitive, stored in leaf order with what its test needs.
#[derive(Clone, Copy, Debug)]
pub enum Prim {
    /// Vertices of triangle `prim` of shape `shape`.
    Triangle { v: [Vec3; 3], shape: u32, prim: u32 },
    /// Sphere `shape` (its primitive index is 0, as in Embree).
    Sphere { center: Vec3, radius: f32, shape: u32 },
    /// Triangles `prim` and `prim + 1` of shape `shape`, which share an edge: the first is
    /// `v[0], v[1], v[2]`, the second `v[0], v[2], v[3]`, each its own vertices rotated (vertex
    /// k here is its own vertex (k + r) % 3, r being `rot & 3` for the first and `rot >> 2` for
    /// the second). One lane of a leaf block tests both, the four vertices transformed once.
    Quad { v: [Vec3; 4], shape: u32, prim: u32, rot: u8 },
}

impl Prim {
    /// Triangles `prim` and `prim + 1` as one [`Prim::Quad`] when they share an edge that they
    /// run along in opposite directions (a consistently wound mesh), the same vertices bit for
    /// bit, and neither is degenerate; `None` otherwise.
    pub fn quad(a: [Vec3; 3], b: [Vec3; 3], shape: u32, prim: u32) -> Option<Prim> {
        if degenerate(&a) || degenerate(&b) {
            return None;
        }
        let same = |p: Vec3, q: Vec3| p.to_array().map(f32::to_bits) == q.to_array().map(f32::to_bits);
        for i in 0..3 {
            for j in 0..3 {
                if same(a[i], b[(j + 1) % 3]) && same(a[(i + 1) % 3], b[j]) {
                    // The shared edge is a's edge i (a[i] to a[i + 1]), b's edge j backwards:
                    // a starts at a[i + 1] so that the edge is its last, b at b[j] = a[i + 1].
                    let v = [a[(i + 1) % 3], a[(i + 2) % 3], a[i], b[(j + 2) % 3]];
                    return Some(Prim::Quad { v, shape, prim, rot: (((i + 1) % 3) | (j << 2)) as u8 });
                }
            }
        }
        None
    }

    /// A quad's two triangles with their vertices in their own order (as the scene has them).
    pub fn quad_triangles(v: &[Vec3; 4], rot: u8) -> [[Vec3; 3]; 2] {
        let own = |t: [Vec3; 3], r: usize| std::array::from_fn(|k| t[(k + 3 - r) % 3]);
        [own([v[0], v[1], v[2]], (rot & 3) as usize), own([v[0], v[2], v[3]], (rot >> 2) as usize)]
    }
}

/// Whether a triangle has no area: the watertight test never hits it.
pub(super) fn degenerate(v: &[Vec3; 3]) -> bool {
    (v[1] - v[0]).cross(v[2] - v[0]) == Vec3::ZERO
}

/// The fewest triangles in one tree for which its meshes are paired into quads
/// ([`mesh_prims`]). A block of quads holds eight triangles in four cache lines, where two
/// blocks of triangles take six, but its test is two triangle tests where a block of four takes one:
/// fewer bytes pay where the tree does not fit in the caches, more arithmetic costs where it
/// does. Measured with `bench-accel` on the terrain at several sizes (one thread, AVX2, an
/// Intel Xeon with 2 MB of L2 a core): primary rays about 10% slower at 10,000 triangles,
/// about even at 50,000 and 200,000, 5% to 8% faster at 500,000 and 1,000,000
/// (docs/RESULTS.md, the BVH's section).
pub const QUAD_MIN: usize = 1 << 18;

/// The build settings for a tree of `prims`, which may hold quads: keeps the quads where at
/// least two thirds of the triangles are in one (a quad lane takes 64 bytes, a triangle's 48:
/// at half the triangles paired the bytes are even, and each block of quads tests twice), with
/// the traversal cost halved (a block of quads costs two triangle tests, so a traversal step
/// costs half as much beside it); otherwise splits them back into triangles and keeps
/// `options`.
pub(super) fn settle_quads(prims: &mut Vec<Prim>, options: BuildOptions) -> BuildOptions {
    let with_quads = BuildOptions { traversal_cost: options.traversal_cost * 0.5, ..options };
    let (mut quads, mut triangles) = (0usize, 0usize);
    for p in prims.iter() {
        match p {
            Prim::Quad { .. } => quads += 1,
            Prim::Triangle { .. } => triangles += 1,
            Prim::Sphere { .. } => {}
        }
    }
    if quads == 0 {
        return options;
    }
    // 2 quads / (2 quads + triangles) >= 2 / 3.
    if quads >= triangles {
        return with_quads;
    }
    *prims = prims
        .iter()
        .flat_map(|p| {
            let mut out = arrayvec::ArrayVec::<Prim, 2>::new();
            match *p {
                Prim::Quad { ref v, shape, prim, rot } => {
                    let [a, b] = Prim::quad_triangles(v, rot);
                    out.push(Prim::Triangle { v: a, shape, prim });
                    out.push(Prim::Triangle { v: b, shape, prim: prim + 1 });
                }
                other => out.push(other),
            }
            out
        })
        .collect();
    options
}

/// The triangles of a mesh of `count` triangles (`triangle(t)` the vertices of triangle `t`) as
/// primitives of shape `shape`, in order: with `pair`, each even triangle and the next as a
/// [`Prim::Quad`] where they share an edge, as meshes made of quads have them.
pub(super) fn mesh_prims(
    count: u32,
    shape: u32,
    pair: bool,
    triangle: impl Fn(u32) -> [Vec3; 3] + Sync + Send,
) -> impl rayon::iter::ParallelIterator<Item = Prim> {
    use rayon::prelude::*;
    (0..count.div_ceil(2)).into_par_iter().flat_map_iter(move |pair_index| {
        let t = 2 * pair_index;
        let mut out = arrayvec::ArrayVec::<Prim, 2>::new();
        let a = triangle(t);
        let b = (t + 1 < count).then(|| triangle(t + 1));
        match b.and_then(|b| if pair { Prim::quad(a, b, shape, t) } else { None }) {
            Some(q) => out.push(q),
            None => {
                out.push(Prim::Triangle { v: a, shape, prim: t });
                if let Some(b) = b {
                    out.push(Prim::Triangle { v: b, shape, prim: t + 1 });
                }
            }
        }
        out
    })
}

/// The BVH over a scene: the binary SAH tree and its 8-wide collapse, which rays traverse.
/// Immutable once built, so it is `Send + Sync`.
pub struct Bvh {
    /// The binary tree and its primitives in leaf order: empty unless the options keep them.
    nodes: Vec<Node>,
    prims: Vec<Prim>,
    /// The box of every primitive (of the first level), if there are any.
    bounds: Option<Aabb>,
    wide: wide::Bvh8,
    /// Shapes that place a shared mesh: the second level.
    instances: Option<Box<instances::Instances>>,
    /// The scene's cut-outs, when it has any: the hits the traversal asks about.
    cutouts: Option<std::sync::Arc<Cutouts>>,
}

/// What a traversal asks about a hit on a lane marked as a cut-out: whether it counts, by the
/// scene's [`Cutouts`]; the hits of an instanced mesh (shape 0 in its own tree) are asked
/// about as the instance's shape.
#[derive(Clone, Copy)]
pub struct Filter<'a> {
    cutouts: Option<&'a Cutouts>,
    shape: Option<u32>,
}

impl Filter<'_> {
    /// No cut-outs: every hit counts.
    pub const NONE: Filter<'static> = Filter { cutouts: None, shape: None };

    /// Whether the hit at `(u, v)` of triangle `prim` of shape `shape` counts.
    #[inline]
    fn keeps(&self, shape: u32, prim: u32, u: f32, v: f32) -> bool {
        match self.cutouts {
            None => true,
            Some(c) => c.keeps(self.shape.unwrap_or(shape), prim, u, v),
        }
    }
}

/// A scene with more primitives than the BVH's 30-bit child references can reach.
#[derive(Debug, thiserror::Error)]
#[error("the scene has {0} primitives; lightsplit's BVH holds at most {max} (use --accel embree)", max = wide::MAX_PRIMS)]
pub struct TooLarge(pub usize);

/// Build settings; the defaults are what the benchmarks chose.
#[derive(Clone, Copy, Debug)]
pub struct BuildOptions {
    /// Leaves hold at most this many primitives.
    pub max_leaf: usize,
    /// SAH cost of one traversal step relative to one leaf test (of a block of primitives).
    pub traversal_cost: f32,
    /// Centroid bins per axis.
    pub bins: usize,
    /// The SAH counts a leaf's primitives in blocks of this many: the leaf test's width, so a
    /// leaf of four primitives (triangles or quads) costs what a leaf of one does.
    pub block: usize,
    /// Keep the binary tree and its primitives after collapsing it (the reference traversal
    /// and [`Bvh::validate`] need them; rays do not).
    pub keep_binary: bool,
    /// Pair the triangles of a tree of at least this many into quads ([`QUAD_MIN`]).
    pub quad_min: usize,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            max_leaf: 8,
            traversal_cost: 1.0,
            bins: 16,
            block: 4,
            keep_binary: false,
            quad_min: QUAD_MIN,
        }
    }
}

impl Bvh {
    /// Builds over every shape of `scene`; degenerate triangles and empty spheres are dropped.
    pub fn new(scene: &Scene) -> Result<Bvh, TooLarge> {
        Self::with_options(scene, BuildOptions::default())
    }

    /// [`Bvh::new`], keeping the binary tree for the reference traversal and the checks.
    #[cfg(test)]
    pub(crate) fn with_reference(scene: &Scene) -> Result<Bvh, TooLarge> {
        Self::with_options(scene, BuildOptions { keep_binary: true, ..BuildOptions::default() })
    }

    /// [`Bvh::with_reference`] of both kinds of tree, whatever the scene's size: of triangles
    /// alone, and of quads where pairs share an edge ([`QUAD_MIN`]).
    #[cfg(test)]
    pub(crate) fn both_kinds(scene: &Scene) -> [(&'static str, Bvh); 2] {
        [("triangles", usize::MAX), ("quads", 0)].map(|(name, quad_min)| {
            let options = BuildOptions { keep_binary: true, quad_min, ..BuildOptions::default() };
            (name, Self::with_options(scene, options).expect("builds"))
        })
    }

    pub fn with_options(scene: &Scene, options: BuildOptions) -> Result<Bvh, TooLarge> {
        let mut prims = Vec::new();
        let triangles: usize = (scene.shapes.iter())
            .filter_map(|shape| match &shape.geometry {
                Geometry::Triangles(mesh) if mesh.instance.is_none() => Some(mesh.indices.len()),
                _ => None,
            })
            .sum();
        let pair = triangles >= options.quad_min;
        for (s, shape) in scene.shapes.iter().enumerate() {
            match &shape.geometry {
                Geometry::Sphere { center, radius } => {
                    if *radius > 0.0 {
                        prims.push(Prim::Sphere { center: *center, radius: *radius, shape: s as u32 });
                    }
                }
                // Instances go to the second level.
                Geometry::Triangles(mesh) if mesh.instance.is_some() => {}
                Geometry::Triangles(mesh) => {
                    // Every triangle, paired where it can be, written in place; the build
                    // leaves out the degenerate ones.
                    use rayon::prelude::*;
                    prims.par_extend(mesh_prims(mesh.indices.len() as u32, s as u32, pair, |t| {
                        mesh.triangle(t)
                    }));
                }
            }
        }
        if prims.len() > wide::MAX_PRIMS as usize {
            return Err(TooLarge(prims.len()));
        }
        let options =
            BuildOptions { max_leaf: options.max_leaf.clamp(1, wide::MAX_LEAF as usize), ..options };
        let cutouts = Cutouts::new(scene).map(std::sync::Arc::new);
        let instances = instances::Instances::new(scene, options, cutouts.as_deref())?.map(Box::new);
        let first = if pair { settle_quads(&mut prims, options) } else { options };
        let mut bvh = Bvh { instances, ..build::build(prims, first) };
        if let Some(c) = &cutouts {
            bvh.wide.mark_cutouts(|shape| c.cuts(shape));
        }
        bvh.cutouts = cutouts;
        Ok(bvh)
    }

    /// Number of binary nodes, of wide nodes and of primitives (of the first level).
    pub fn size(&self) -> (usize, usize, usize) {
        (self.nodes.len(), self.wide.node_count(), self.prims.len())
    }

    /// Counts and sizes of the wide tree rays traverse (the first level).
    pub fn stats(&self) -> wide::WideStats {
        self.wide.stats()
    }

    /// Bytes held, exactly: the wide tree, the binary tree and primitives kept beside it (the
    /// reference traversal and the checks read them), and the instance level.
    pub fn bytes(&self) -> usize {
        self.wide.bytes()
            + self.nodes.len() * std::mem::size_of::<Node>()
            + self.prims.len() * std::mem::size_of::<Prim>()
            + self.instances.as_ref().map_or(0, |i| i.bytes())
    }

    /// The slab test rays use (AVX2 or portable, chosen at run time).
    pub fn isa(&self) -> simd::Isa {
        self.wide.isa()
    }

    /// The same tree, traversed with the portable slab test whatever the CPU has (for tests and
    /// benchmarks; the instance level keeps its meshes' choice).
    pub fn portable(self) -> Bvh {
        self.with_isa(simd::Isa::Portable)
    }

    /// The same tree, traversed with kernels `isa` (for tests and benchmarks).
    pub fn with_isa(self, isa: simd::Isa) -> Bvh {
        Bvh { wide: self.wide.with_isa(isa), ..self }
    }

    /// How many shapes place a shared mesh, and how many distinct meshes they place.
    pub fn instance_counts(&self) -> (usize, usize) {
        self.instances.as_ref().map_or((0, 0), |i| i.counts())
    }

    /// Checks the tree's invariants: every primitive in exactly one leaf, children inside their
    /// parents' boxes, leaves within their size. Returns a description of the first violation.
    pub fn validate(&self, max_leaf: usize) -> Result<(), String> {
        if self.nodes.is_empty() && self.bounds.is_some() {
            return Err("the binary tree was not kept (build with keep_binary)".into());
        }
        let mut seen = vec![false; self.prims.len()];
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i];
            let bounds = n.bounds();
            if n.is_leaf() {
                if n.count as usize > max_leaf {
                    return Err(format!("leaf {i} holds {} primitives", n.count));
                }
                let range = n.prims();
                for (p, prim) in range.clone().zip(&self.prims[range]) {
                    if std::mem::replace(&mut seen[p], true) {
                        return Err(format!("primitive {p} is in two leaves"));
                    }
                    let b = prim_bounds(prim);
                    if b.min.cmplt(bounds.min).any() || b.max.cmpgt(bounds.max).any() {
                        return Err(format!("primitive {p} sticks out of leaf {i}"));
                    }
                }
            } else {
                for c in [n.first as usize, n.first as usize + 1] {
                    let cn = &self.nodes[c];
                    if Vec3A::from(cn.min).cmplt(bounds.min).any()
                        || Vec3A::from(cn.max).cmpgt(bounds.max).any()
                    {
                        return Err(format!("child {c} sticks out of node {i}"));
                    }
                    stack.push(c);
                }
            }
        }
        match seen.iter().position(|s| !s) {
            Some(p) if !self.prims.is_empty() => Err(format!("primitive {p} is in no leaf")),
            _ => Ok(()),
        }
    }
}

fn prim_bounds(p: &Prim) -> Aabb {
    match p {
        Prim::Triangle { v, .. } => Aabb::EMPTY.grow(v[0].into()).grow(v[1].into()).grow(v[2].into()),
        Prim::Quad { v, .. } => v.iter().fold(Aabb::EMPTY, |b, p| b.grow((*p).into())),
        Prim::Sphere { center, radius, .. } => {
            let c = Vec3A::from(*center);
            Aabb { min: c - Vec3A::splat(*radius), max: c + Vec3A::splat(*radius) }
        }
    }
}

/// Per-ray values for the box test (Ize 2013, "Robust BVH Ray Traversal"): the far distance of
/// every slab is scaled up by 1 + 2 gamma(3), which covers the rounding of the slab computation.
struct RayBox {
    origin: Vec3A,
    inv_dir: Vec3A,
}

const FAR_SCALE: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

impl RayBox {
    fn new(ray: &Ray) -> Self {
        RayBox { origin: ray.origin.into(), inv_dir: Vec3A::ONE / Vec3A::from(ray.dir) }
    }

    /// Entry distance into the node's box if the ray meets it within [0, t_max].
    #[inline(always)]
    fn hit(&self, n: &Node, t_max: f32) -> Option<f32> {
        let t0 = (Vec3A::from(n.min) - self.origin) * self.inv_dir;
        let t1 = (Vec3A::from(n.max) - self.origin) * self.inv_dir;
        // min/max that ignore NaN (0 * inf when the origin lies on a slab plane).
        let near = t0.min(t1);
        let far = t0.max(t1);
        let t_near = near.x.max(near.y).max(near.z).max(0.0);
        let t_far = far.x.min(far.y).min(far.z).min(t_max) * FAR_SCALE;
        (t_near <= t_far).then_some(t_near)
    }
}

impl Bvh {
    /// Closest hit along `ray`.
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let filter = self.filter();
        let hit = self.wide.intersect(ray, filter);
        match &self.instances {
            None => hit,
            Some(instances) => instances.intersect(ray, hit, filter),
        }
    }

    /// Whether anything lies along `ray` within [0, t_max]: stops at the first hit found.
    pub fn occluded(&self, ray: &Ray) -> bool {
        let filter = self.filter();
        self.wide.occluded(ray, filter) || self.instances.as_ref().is_some_and(|i| i.occluded(ray, filter))
    }

    /// The filter of this tree's cut-outs.
    #[inline(always)]
    fn filter(&self) -> Filter<'_> {
        Filter { cutouts: self.cutouts.as_deref(), shape: None }
    }

    /// Closest hit by the binary tree (the reference the wide tree is tested against; `None`
    /// unless the tree was built with `keep_binary`).
    pub fn intersect_binary(&self, ray: &Ray) -> Option<Hit> {
        let rt = RayTri::new(ray);
        closest(&self.nodes, ray, ray.t_max, None, |range, t_max| {
            let mut best = None;
            for p in &self.prims[range] {
                if let Some(h) = prim_hit(p, ray, &rt, *t_max) {
                    *t_max = h.t;
                    best = Some(h);
                }
            }
            best
        })
    }

    /// Any hit by the binary tree.
    pub fn occluded_binary(&self, ray: &Ray) -> bool {
        let rt = RayTri::new(ray);
        any(&self.nodes, ray, |range| {
            self.prims[range].iter().any(|p| prim_hit(p, ray, &rt, ray.t_max).is_some())
        })
    }
}

/// Ordered closest-hit traversal of a binary tree, nearer child first, from the hit `best`
/// found so far (nothing beyond `t_max`, its distance). `leaf` tests the items of a leaf's range
/// nearer than its `t_max`, lowering it to each hit it finds, and returns the nearest.
#[inline(always)]
fn closest(
    nodes: &[Node],
    ray: &Ray,
    mut t_max: f32,
    mut best: Option<Hit>,
    mut leaf: impl FnMut(std::ops::Range<usize>, &mut f32) -> Option<Hit>,
) -> Option<Hit> {
    let rb = RayBox::new(ray);
    if nodes.is_empty() || rb.hit(&nodes[0], t_max).is_none() {
        return best;
    }
    let mut stack = [0u32; STACK];
    let mut sp = 0usize;
    let mut node = 0usize;
    loop {
        let n = &nodes[node];
        if n.is_leaf() {
            if let Some(h) = leaf(n.prims(), &mut t_max) {
                best = Some(h);
            }
        } else {
            let (a, b) = (n.first as usize, n.first as usize + 1);
            match (rb.hit(&nodes[a], t_max), rb.hit(&nodes[b], t_max)) {
                (Some(ta), Some(tb)) => {
                    let (near, far) = if ta <= tb { (a, b) } else { (b, a) };
                    stack[sp] = far as u32;
                    sp += 1;
                    node = near;
                    continue;
                }
                (Some(_), None) => {
                    node = a;
                    continue;
                }
                (None, Some(_)) => {
                    node = b;
                    continue;
                }
                (None, None) => {}
            }
        }
        // Pop, skipping nodes that the current closest hit has made too far.
        loop {
            if sp == 0 {
                return best;
            }
            sp -= 1;
            let candidate = stack[sp] as usize;
            if rb.hit(&nodes[candidate], t_max).is_some() {
                node = candidate;
                break;
            }
        }
    }
}

/// Any-hit traversal of a binary tree within [0, ray.t_max]: whether `leaf` finds a hit in the
/// range of some leaf the ray reaches.
#[inline(always)]
fn any(nodes: &[Node], ray: &Ray, mut leaf: impl FnMut(std::ops::Range<usize>) -> bool) -> bool {
    let rb = RayBox::new(ray);
    let t_max = ray.t_max;
    if nodes.is_empty() || rb.hit(&nodes[0], t_max).is_none() {
        return false;
    }
    let mut stack = [0u32; STACK];
    let mut sp = 0usize;
    let mut node = 0usize;
    loop {
        let n = &nodes[node];
        if n.is_leaf() {
            if leaf(n.prims()) {
                return true;
            }
        } else {
            let (a, b) = (n.first as usize, n.first as usize + 1);
            match (rb.hit(&nodes[a], t_max).is_some(), rb.hit(&nodes[b], t_max).is_some()) {
                (true, true) => {
                    stack[sp] = b as u32;
                    sp += 1;
                    node = a;
                    continue;
                }
                (true, false) => {
                    node = a;
                    continue;
                }
                (false, true) => {
                    node = b;
                    continue;
                }
                (false, false) => {}
            }
        }
        if sp == 0 {
            return false;
        }
        sp -= 1;
        node = stack[sp] as usize;
    }
}

impl Accel for Bvh {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        Bvh::intersect(self, ray)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        Bvh::occluded(self, ray)
    }
}

#[cfg(test)]
mod proptests;
#[cfg(test)]
mod tests;
