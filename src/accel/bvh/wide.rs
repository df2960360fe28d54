//! The 4-wide BVH that rays actually traverse: the binary SAH tree collapsed so that each node
//! holds up to four children, their boxes stored axis by axis so one SIMD slab test (the `wide`
//! crate's `f32x4`: SSE on x86-64, NEON on ARM, no `unsafe`) checks all four at once.

use wide::f32x4;

use super::intersect::{prim_hit, RayTri};
use super::{Node, Prim};
use crate::accel::{Hit, Ray};

/// A reference to a child: an inner node, a leaf, or nothing, packed in 32 bits so a node's
/// four children take 16 bytes: an inner node is its index (top bit clear); a leaf sets the top
/// bit, keeps its primitive count in the next 3 bits and its first primitive in the other 28.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Child(u32);

const LEAF: u32 = 1 << 31;
const COUNT_SHIFT: u32 = 28;
/// The most primitives a leaf can hold, and the most a tree can hold.
pub const MAX_LEAF: u32 = 7;
pub const MAX_PRIMS: u32 = 1 << COUNT_SHIFT;

impl Child {
    const EMPTY: Child = Child(u32::MAX);

    fn inner(index: u32) -> Child {
        debug_assert!(index < LEAF);
        Child(index)
    }

    fn leaf(first: u32, count: u32) -> Child {
        debug_assert!((1..=MAX_LEAF).contains(&count) && first < MAX_PRIMS);
        Child(LEAF | count << COUNT_SHIFT | first)
    }

    /// Whether this is a leaf (EMPTY, never traversed, also has the top bit set).
    #[inline(always)]
    fn is_leaf(self) -> bool {
        self.0 & LEAF != 0
    }

    /// The primitive range of a leaf.
    #[inline(always)]
    fn range(self) -> std::ops::Range<usize> {
        let first = (self.0 & (MAX_PRIMS - 1)) as usize;
        first..first + ((self.0 >> COUNT_SHIFT) & MAX_LEAF) as usize
    }
}

/// Four children's boxes, axis by axis (empty slots hold an inverted box that no ray meets),
/// and what each child is: 112 bytes, padded to two cache lines.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct Node4 {
    /// min x, min y, min z, max x, max y, max z of the four children.
    bounds: [[f32; 4]; 6],
    children: [Child; 4],
}

pub struct Bvh4 {
    nodes: Vec<Node4>,
    root: Child,
}

/// Traversal stack depth. Collapsing never deepens the binary tree, which the build bounds.
const STACK: usize = 3 * super::STACK;

impl Bvh4 {
    /// Collapses a binary tree: each wide node takes its binary node's children, then keeps
    /// opening the inner child of largest area until it has four.
    pub fn collapse(binary: &[Node]) -> Bvh4 {
        let mut bvh = Bvh4 { nodes: Vec::with_capacity(binary.len() / 2 + 1), root: Child::EMPTY };
        if binary.is_empty() {
            return bvh;
        }
        bvh.root = bvh.add(binary, 0);
        bvh
    }

    fn add(&mut self, binary: &[Node], index: usize) -> Child {
        let n = &binary[index];
        if n.count > 0 {
            return Child::leaf(n.first, n.count);
        }
        let area = |i: usize| {
            let b = &binary[i];
            let d = [b.max[0] - b.min[0], b.max[1] - b.min[1], b.max[2] - b.min[2]];
            d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
        };
        let mut kids: Vec<usize> = vec![n.first as usize, n.first as usize + 1];
        while kids.len() < 4 {
            let open = kids
                .iter()
                .enumerate()
                .filter(|(_, &k)| binary[k].count == 0)
                .max_by(|a, b| area(*a.1).total_cmp(&area(*b.1)));
            let Some((slot, &k)) = open else { break };
            let first = binary[k].first as usize;
            kids[slot] = first;
            kids.push(first + 1);
        }
        let at = self.nodes.len();
        self.nodes.push(Node4 {
            bounds: [
                [f32::INFINITY; 4],
                [f32::INFINITY; 4],
                [f32::INFINITY; 4],
                [f32::NEG_INFINITY; 4],
                [f32::NEG_INFINITY; 4],
                [f32::NEG_INFINITY; 4],
            ],
            children: [Child::EMPTY; 4],
        });
        for (slot, &k) in kids.iter().enumerate() {
            let b = &binary[k];
            for axis in 0..3 {
                self.nodes[at].bounds[axis][slot] = b.min[axis];
                self.nodes[at].bounds[3 + axis][slot] = b.max[axis];
            }
            let child = self.add(binary, k);
            self.nodes[at].children[slot] = child;
        }
        Child::inner(at as u32)
    }

    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }
}

/// Per-ray values for the four-box slab test.
struct RayBox4 {
    origin: [f32x4; 3],
    inv_dir: [f32x4; 3],
    /// For each axis, whether the ray runs towards negative values (then near and far swap).
    negative: [bool; 3],
}

/// Ize's factor: the far slab distance grows by 2 gamma(3) to cover rounding (see `RayBox`).
const FAR_SCALE: f32 = super::FAR_SCALE;

impl RayBox4 {
    fn new(ray: &Ray) -> Self {
        // A zero direction component becomes a tiny one, so 1/d is huge but finite and no
        // 0 * inf NaN can arise in the slab test.
        let safe = |d: f32| if d.abs() < 1e-30 { 1e-30f32.copysign(d) } else { d };
        let inv = [1.0 / safe(ray.dir.x), 1.0 / safe(ray.dir.y), 1.0 / safe(ray.dir.z)];
        RayBox4 {
            origin: [f32x4::splat(ray.origin.x), f32x4::splat(ray.origin.y), f32x4::splat(ray.origin.z)],
            inv_dir: inv.map(f32x4::splat),
            negative: inv.map(|i| i < 0.0),
        }
    }

    /// Entry distances of the four children, and a bit mask of those the ray meets within
    /// [0, t_max].
    #[inline(always)]
    fn hit(&self, n: &Node4, t_max: f32) -> (f32x4, u32) {
        let mut t_near = f32x4::splat(0.0);
        let mut t_far = f32x4::splat(t_max);
        for axis in 0..3 {
            let (near, far) = if self.negative[axis] { (3 + axis, axis) } else { (axis, 3 + axis) };
            let a = (f32x4::new(n.bounds[near]) - self.origin[axis]) * self.inv_dir[axis];
            let b = (f32x4::new(n.bounds[far]) - self.origin[axis]) * self.inv_dir[axis];
            t_near = t_near.fast_max(a);
            t_far = t_far.fast_min(b);
        }
        let mask = t_near.simd_le(t_far * f32x4::splat(FAR_SCALE)).to_bitmask();
        (t_near, mask)
    }
}

/// A stack entry: a child and the distance at which the ray entered its box.
#[derive(Clone, Copy)]
struct Entry {
    child: Child,
    t: f32,
}

impl Bvh4 {
    /// Closest hit along `ray` among `prims` (the binary tree's primitive order).
    pub fn intersect(&self, prims: &[Prim], ray: &Ray) -> Option<Hit> {
        if self.root == Child::EMPTY {
            return None;
        }
        let rb = RayBox4::new(ray);
        let rt = RayTri::new(ray);
        let mut best: Option<Hit> = None;
        let mut t_max = ray.t_max;
        let mut stack = [Entry { child: Child::EMPTY, t: 0.0 }; STACK];
        let mut sp = 0;
        let mut current = Entry { child: self.root, t: 0.0 };
        loop {
            let child = current.child;
            if child.is_leaf() {
                for p in &prims[child.range()] {
                    if let Some(h) = prim_hit(p, ray, &rt, t_max) {
                        t_max = h.t;
                        best = Some(h);
                    }
                }
            } else {
                let node = &self.nodes[child.0 as usize];
                // Empty slots hold inverted boxes, so the mask never names them.
                let (t_near, mut mask) = rb.hit(node, t_max);
                let t_near = t_near.to_array();
                // Order the hit children by decreasing entry distance (insertion sort of at
                // most four), push all but the nearest, and visit the nearest next.
                let mut order = [Entry { child: Child::EMPTY, t: 0.0 }; 4];
                let mut k = 0;
                while mask != 0 {
                    let slot = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let mut j = k;
                    while j > 0 && order[j - 1].t < t_near[slot] {
                        order[j] = order[j - 1];
                        j -= 1;
                    }
                    order[j] = Entry { child: node.children[slot], t: t_near[slot] };
                    k += 1;
                }
                if k > 0 {
                    stack[sp..sp + k - 1].copy_from_slice(&order[..k - 1]);
                    sp += k - 1;
                    current = order[k - 1];
                    continue;
                }
            }
            // Pop the next entry that the closest hit so far has not ruled out.
            loop {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                if stack[sp].t <= t_max * FAR_SCALE {
                    current = stack[sp];
                    break;
                }
            }
        }
    }

    /// Whether anything lies along `ray` within [0, t_max]; stops at the first hit.
    pub fn occluded(&self, prims: &[Prim], ray: &Ray) -> bool {
        if self.root == Child::EMPTY {
            return false;
        }
        let rb = RayBox4::new(ray);
        let rt = RayTri::new(ray);
        let mut stack = [Child::EMPTY; STACK];
        let mut sp = 0;
        let mut current = self.root;
        loop {
            if current.is_leaf() {
                if prims[current.range()].iter().any(|p| prim_hit(p, ray, &rt, ray.t_max).is_some()) {
                    return true;
                }
            } else {
                let node = &self.nodes[current.0 as usize];
                let (_, mut mask) = rb.hit(node, ray.t_max);
                while mask != 0 {
                    let slot = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    stack[sp] = node.children[slot];
                    sp += 1;
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            current = stack[sp];
        }
    }
}
