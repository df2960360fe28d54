//! The binned SAH build. Each node bins the primitives' centroids on all three axes, sweeps the
//! bins for the cheapest split under the surface area heuristic, and partitions in place;
//! subtrees above a size are built in parallel with `rayon::join`. Deep nodes fall back to median
//! splits, which bounds the depth (and so the traversal stack) whatever the input.

use glam::{Vec3A, Vec4};

use super::wide::Bvh8;
use super::{prim_bounds, Aabb, BuildOptions, Bvh, Node, Prim, STACK};

/// Subtrees with more primitives than this are built on two threads.
const PARALLEL_MIN: usize = 4096;
/// Below this depth SAH chooses splits; deeper, median splits keep the depth logarithmic, so
/// the whole tree stays within the traversal stack (32 + log2 of the primitive count).
const SAH_DEPTH: usize = 32;
const _: () = assert!(SAH_DEPTH + 32 <= STACK);

#[derive(Clone, Copy)]
struct Item {
    /// The box's minimum, with the primitive's index in the fourth lane (bit for bit), so that an
    /// item is 32 bytes: the build is bound by how fast it streams items through memory.
    min: Vec4,
    max: Vec3A,
}

impl Item {
    fn new(bounds: Aabb, index: u32) -> Item {
        Item { min: bounds.min.extend(f32::from_bits(index)), max: bounds.max }
    }

    #[inline(always)]
    fn bounds(&self) -> Aabb {
        Aabb { min: Vec3A::from_vec4(self.min), max: self.max }
    }

    #[inline(always)]
    fn centroid(&self) -> Vec3A {
        (Vec3A::from_vec4(self.min) + self.max) * 0.5
    }

    fn index(&self) -> usize {
        self.min.w.to_bits() as usize
    }
}

enum Tree {
    Leaf { bounds: Aabb, start: usize, count: usize },
    Inner { bounds: Aabb, children: Box<[Tree; 2]> },
}

impl Tree {
    fn bounds(&self) -> &Aabb {
        match self {
            Tree::Leaf { bounds, .. } | Tree::Inner { bounds, .. } => bounds,
        }
    }
}

pub(super) fn build(prims: Vec<Prim>, options: BuildOptions) -> Bvh {
    if prims.is_empty() {
        return Bvh {
            nodes: Vec::new(),
            prims,
            bounds: None,
            wide: Bvh8::collapse(&[], &[], &[]),
            instances: None,
        };
    }
    let (nodes, order) = tree(prims.len(), |i| prim_bounds(&prims[i]), options);
    let wide = Bvh8::collapse(&nodes, &prims, &order);
    let bounds = nodes.first().map(|n| Aabb { min: Vec3A::from(n.min), max: Vec3A::from(n.max) });
    if options.keep_binary {
        let ordered = order.iter().map(|&i| prims[i as usize]).collect();
        Bvh { nodes, prims: ordered, bounds, wide, instances: None }
    } else {
        // Rays traverse the wide tree only: the binary one and the primitives are not kept.
        Bvh { nodes: Vec::new(), prims: Vec::new(), bounds, wide, instances: None }
    }
}

/// The binary tree over `n` boxes (`bounds(i)` the `i`th; at least one): its flattened nodes,
/// and the order of the boxes in its leaves (leaf ranges index that order).
pub(super) fn tree(
    n: usize,
    bounds: impl Fn(usize) -> Aabb + Sync,
    options: BuildOptions,
) -> (Vec<Node>, Vec<u32>) {
    use rayon::prelude::*;
    let mut items: Vec<Item> = (0..n).into_par_iter().map(|i| Item::new(bounds(i), i as u32)).collect();
    let tree = build_node(&mut items, 0, &options, 0, None);
    let mut nodes = Vec::with_capacity(2 * items.len() / options.max_leaf.max(1) + 1);
    nodes.push(placeholder());
    flatten(&tree, &mut nodes, 0);
    (nodes, items.iter().map(|it| it.index() as u32).collect())
}

fn placeholder() -> Node {
    Node { min: [0.0; 3], first: 0, max: [0.0; 3], count: 0 }
}

fn flatten(tree: &Tree, nodes: &mut Vec<Node>, at: usize) {
    let b = tree.bounds();
    match tree {
        Tree::Leaf { start, count, .. } => {
            nodes[at] =
                Node { min: b.min.into(), first: *start as u32, max: b.max.into(), count: *count as u32 };
        }
        Tree::Inner { children, .. } => {
            let first = nodes.len();
            nodes.push(placeholder());
            nodes.push(placeholder());
            nodes[at] = Node { min: b.min.into(), first: first as u32, max: b.max.into(), count: 0 };
            flatten(&children[0], nodes, first);
            flatten(&children[1], nodes, first + 1);
        }
    }
}

/// The bounds of items' boxes and of their centroids.
fn bounds_of(items: &[Item]) -> (Aabb, Aabb) {
    use rayon::prelude::*;
    let grow = |(b, c): (Aabb, Aabb), it: &Item| (b.union(&it.bounds()), c.grow(it.centroid()));
    if items.len() > PARALLEL_BINNING {
        items
            .par_chunks(PARALLEL_BINNING / 4)
            .map(|chunk| chunk.iter().fold((Aabb::EMPTY, Aabb::EMPTY), grow))
            .reduce(|| (Aabb::EMPTY, Aabb::EMPTY), |(a, b), (c, d)| (a.union(&c), b.union(&d)))
    } else {
        items.iter().fold((Aabb::EMPTY, Aabb::EMPTY), grow)
    }
}

/// Builds the subtree over `items`, which start at `offset` in the final primitive order;
/// `known` is the bounds of their boxes and centroids when the caller has them.
fn build_node(
    items: &mut [Item],
    offset: usize,
    options: &BuildOptions,
    depth: usize,
    known: Option<(Aabb, Aabb)>,
) -> Tree {
    let n = items.len();
    let (bounds, centroids) = known.unwrap_or_else(|| bounds_of(items));
    let leaf = Tree::Leaf { bounds, start: offset, count: n };
    if n == 1 {
        return leaf;
    }

    // Any split costs at least one traversal step: where a leaf costs no more, no binning can
    // find a cheaper split (most nodes are these, at the bottom of the tree).
    if n <= options.max_leaf && blocks(n, options) <= options.traversal_cost {
        return leaf;
    }
    let extent = centroids.max - centroids.min;
    let split = if depth < SAH_DEPTH && extent.max_element() > 0.0 {
        best_sah_split(items, &bounds, &centroids, options)
    } else {
        None
    };
    let (mid, sides) = match split {
        Some(Split { cost, axis, bin, lo, scale, bins }) => {
            if n <= options.max_leaf && cost >= blocks(n, options) {
                return leaf; // a leaf is cheaper than any split
            }
            // The same arithmetic as the binning, so each item goes where it was counted.
            match partition(items, |c| bin_of(c[axis], lo, scale, bins) <= bin) {
                (0, _) => (median_split(items, extent), None),
                (mid, _) if mid == n => (median_split(items, extent), None),
                (mid, sides) => (mid, Some(sides)),
            }
        }
        None if n <= options.max_leaf => return leaf,
        None => (median_split(items, extent), None),
    };

    let (left, right) = items.split_at_mut(mid);
    let (kl, kr) = match sides {
        Some([l, r]) => (Some(l), Some(r)),
        None => (None, None),
    };
    let (l, r) = if n > PARALLEL_MIN {
        rayon::join(
            || build_node(left, offset, options, depth + 1, kl),
            || build_node(right, offset + mid, options, depth + 1, kr),
        )
    } else {
        (
            build_node(left, offset, options, depth + 1, kl),
            build_node(right, offset + mid, options, depth + 1, kr),
        )
    };
    Tree::Inner { bounds, children: Box::new([l, r]) }
}

/// Splits at the median along the axis of largest centroid extent (or, when all centroids
/// coincide, simply in half). Always returns a split with both sides non-empty.
fn median_split(items: &mut [Item], extent: Vec3A) -> usize {
    let mid = items.len() / 2;
    if extent.max_element() > 0.0 {
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        items.select_nth_unstable_by(mid, |a, b| a.centroid()[axis].total_cmp(&b.centroid()[axis]));
    }
    mid
}

/// In-place partition by `pred` of each item's centroid; returns how many items satisfy it (they
/// come first), and the bounds of boxes and centroids on each side, gathered on the way.
fn partition(items: &mut [Item], pred: impl Fn(Vec3A) -> bool) -> (usize, [(Aabb, Aabb); 2]) {
    let mut sides = [(Aabb::EMPTY, Aabb::EMPTY); 2];
    let mut i = 0;
    for j in 0..items.len() {
        let (b, c) = (items[j].bounds(), items[j].centroid());
        let left = pred(c);
        let side = &mut sides[usize::from(!left)];
        *side = (side.0.union(&b), side.1.grow(c));
        if left {
            items.swap(i, j);
            i += 1;
        }
    }
    (i, sides)
}

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

/// A split between bins `bin` and `bin + 1` on `axis`; `cost` is in units of one leaf test of a
/// block of primitives (a leaf of n primitives costs n / block, rounded up).
struct Split {
    cost: f32,
    axis: usize,
    bin: usize,
    lo: f32,
    scale: f32,
    bins: usize,
}

/// The SAH's cost of testing `n` primitives: the number of blocks the leaf test takes.
#[inline(always)]
fn blocks(n: usize, options: &BuildOptions) -> f32 {
    n.div_ceil(options.block.max(1)) as f32
}

#[inline(always)]
fn bin_of(c: f32, lo: f32, scale: f32, bins: usize) -> usize {
    (((c - lo) * scale) as usize).min(bins - 1)
}

/// Centroid bins on the three axes: bounds and count of the items in each.
type Bins = [[Bin; MAX_BINS]; 3];
const MAX_BINS: usize = 32;
/// Nodes with more items than this bin on several threads.
const PARALLEL_BINNING: usize = 1 << 15;

fn empty_bins() -> Box<Bins> {
    Box::new([[Bin { bounds: Aabb::EMPTY, count: 0 }; MAX_BINS]; 3])
}

/// The cheapest binned SAH split over all three axes, binning every axis in one pass over the
/// items (split across threads for large nodes).
fn best_sah_split(items: &[Item], bounds: &Aabb, centroids: &Aabb, options: &BuildOptions) -> Option<Split> {
    use rayon::prelude::*;
    // More bins than items cannot find a better split.
    let bins_n = options.bins.min(items.len()).clamp(2, MAX_BINS);
    let lo = centroids.min;
    let extent = centroids.max - lo;
    let scale = Vec3A::select(extent.cmpgt(Vec3A::ZERO), Vec3A::splat(bins_n as f32) / extent, Vec3A::ZERO);
    let fill = |mut bins: Box<Bins>, it: &Item| {
        let (ib, c) = (it.bounds(), it.centroid());
        for axis in 0..3 {
            let b = bin_of(c[axis], lo[axis], scale[axis], bins_n);
            bins[axis][b].bounds = bins[axis][b].bounds.union(&ib);
            bins[axis][b].count += 1;
        }
        bins
    };
    if items.len() > PARALLEL_BINNING {
        let bins = items
            .par_chunks(PARALLEL_BINNING / 4)
            .map(|chunk| chunk.iter().fold(empty_bins(), fill))
            .reduce(empty_bins, |mut a, b| {
                for axis in 0..3 {
                    for (x, y) in a[axis].iter_mut().zip(b[axis].iter()) {
                        x.bounds = x.bounds.union(&y.bounds);
                        x.count += y.count;
                    }
                }
                a
            });
        sweep(&bins, items.len(), bounds, lo, scale, bins_n, options)
    } else {
        // Small nodes bin on the stack.
        let mut bins = [[Bin { bounds: Aabb::EMPTY, count: 0 }; MAX_BINS]; 3];
        for it in items {
            let (ib, c) = (it.bounds(), it.centroid());
            for axis in 0..3 {
                let b = bin_of(c[axis], lo[axis], scale[axis], bins_n);
                bins[axis][b].bounds = bins[axis][b].bounds.union(&ib);
                bins[axis][b].count += 1;
            }
        }
        sweep(&bins, items.len(), bounds, lo, scale, bins_n, options)
    }
}

/// Sweeps the bins of each axis for the split of least SAH cost.
fn sweep(
    bins: &Bins,
    n: usize,
    bounds: &Aabb,
    lo: Vec3A,
    scale: Vec3A,
    bins_n: usize,
    options: &BuildOptions,
) -> Option<Split> {
    let parent_area = bounds.half_area().max(f32::MIN_POSITIVE);
    let mut best: Option<Split> = None;
    for axis in 0..3 {
        if scale[axis] <= 0.0 {
            continue;
        }
        let bins = &bins[axis];
        // Right-to-left sweep: area x count of everything right of each boundary.
        let mut right_cost = [0.0f32; MAX_BINS];
        let mut acc = Aabb::EMPTY;
        let mut count = 0u32;
        for b in (1..bins_n).rev() {
            acc = acc.union(&bins[b].bounds);
            count += bins[b].count;
            right_cost[b] = acc.half_area() * blocks(count as usize, options);
        }
        let mut acc = Aabb::EMPTY;
        let mut count = 0u32;
        for b in 0..bins_n - 1 {
            acc = acc.union(&bins[b].bounds);
            count += bins[b].count;
            if count == 0 || count as usize == n {
                continue;
            }
            let cost = options.traversal_cost
                + (acc.half_area() * blocks(count as usize, options) + right_cost[b + 1]) / parent_area;
            if best.as_ref().is_none_or(|s| cost < s.cost) {
                best = Some(Split { cost, axis, bin: b, lo: lo[axis], scale: scale[axis], bins: bins_n });
            }
        }
    }
    best
}
