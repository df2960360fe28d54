//! The binned SAH build. Each node bins the primitives' centroids on all three axes, sweeps the
//! bins for the cheapest split under the surface area heuristic, and partitions in place;
//! subtrees above a size are built in parallel with `rayon::join`. Deep nodes fall back to median
//! splits, which bounds the depth (and so the traversal stack) whatever the input.

use glam::{Vec3A, Vec4};
use wide::{f32x4, i32x4};

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
    /// A box left out of the tree (its index is one no primitive has: they number under
    /// [`super::wide::MAX_PRIMS`]).
    const LEFT_OUT: Item = Item { min: Vec4::new(0.0, 0.0, 0.0, f32::from_bits(u32::MAX)), max: Vec3A::ZERO };

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

/// The tree while it is built: the top levels as boxes, built on several threads; below
/// [`PARALLEL_MIN`] primitives, each subtree already flat, built on one thread.
enum Tree {
    Inner {
        bounds: Aabb,
        children: Box<[Tree; 2]>,
    },
    /// A subtree's nodes, flattened: its root first, inner nodes' `first` indexing this vector.
    Flat(Vec<Node>),
}

pub(super) fn build(prims: Vec<Prim>, options: BuildOptions) -> Bvh {
    // Degenerate (zero-area) triangles can never be hit by the watertight test; leaving them out
    // keeps them from costing traversal.
    let bounds = |i: usize| match &prims[i] {
        Prim::Triangle { v, .. } if super::degenerate(v) => None,
        p => Some(prim_bounds(p)),
    };
    let Some((nodes, order)) = tree(prims.len(), bounds, options) else {
        return Bvh {
            nodes: Vec::new(),
            prims: Vec::new(),
            bounds: None,
            wide: Bvh8::collapse(&[], &[], &[]),
            instances: None,
            cutouts: None,
        };
    };
    let wide = Bvh8::collapse(&nodes, &prims, &order);
    let bounds = nodes.first().map(Node::bounds);
    if options.keep_binary {
        let ordered = order.iter().map(|&i| prims[i as usize]).collect();
        Bvh { nodes, prims: ordered, bounds, wide, instances: None, cutouts: None }
    } else {
        // Rays traverse the wide tree only: the binary one and the primitives are not kept.
        Bvh { nodes: Vec::new(), prims: Vec::new(), bounds, wide, instances: None, cutouts: None }
    }
}

/// The binary tree over the boxes `bounds(i)` of `i` in `0..n` that have one (the others are
/// left out): its flattened nodes, and the order of the boxes in its leaves (leaf ranges index
/// that order). None without any box.
pub(super) fn tree(
    n: usize,
    bounds: impl Fn(usize) -> Option<Aabb> + Sync,
    options: BuildOptions,
) -> Option<(Vec<Node>, Vec<u32>)> {
    use rayon::prelude::*;
    let mut items: Vec<Item> = (0..n)
        .into_par_iter()
        .map(|i| bounds(i).map_or(Item::LEFT_OUT, |b| Item::new(b, i as u32)))
        .collect();
    items.retain(|it| it.index() != Item::LEFT_OUT.index());
    if items.is_empty() {
        return None;
    }
    let tree = build_node(&mut items, 0, &options, 0, None);
    let mut nodes = Vec::with_capacity(2 * items.len().div_ceil(options.block.max(1)) + 1);
    nodes.push(PLACEHOLDER);
    flatten(&tree, &mut nodes, 0);
    Some((nodes, items.iter().map(|it| it.index() as u32).collect()))
}

/// A node's place, taken before the node is known.
const PLACEHOLDER: Node = Node { min: [0.0; 3], first: 0, max: [0.0; 3], count: 0 };

fn flatten(tree: &Tree, nodes: &mut Vec<Node>, at: usize) {
    match tree {
        Tree::Flat(flat) => {
            // The root goes to `at`, the rest after what is there: inner nodes' children move
            // with them.
            let base = nodes.len() as u32 - 1;
            let moved = |n: &Node| if n.count > 0 { *n } else { Node { first: n.first + base, ..*n } };
            let (root, rest) = flat.split_first().unwrap_or((&PLACEHOLDER, &[]));
            nodes[at] = moved(root);
            nodes.extend(rest.iter().map(moved));
        }
        Tree::Inner { bounds, children } => {
            let first = nodes.len();
            nodes.push(PLACEHOLDER);
            nodes.push(PLACEHOLDER);
            nodes[at] = Node::inner(bounds, first);
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

/// What a node becomes: a leaf, or two children split at `mid` with (when known) the bounds of
/// each side's boxes and centroids.
enum Decision {
    Leaf,
    Split { mid: usize, sides: [Option<(Aabb, Aabb)>; 2] },
}

/// Chooses between a leaf and a split for `items` (whose box and centroid bounds are
/// `bounds`), partitioning them in place for a split.
fn decide(items: &mut [Item], bounds: &(Aabb, Aabb), options: &BuildOptions, depth: usize) -> Decision {
    let n = items.len();
    // Any split costs at least one traversal step: where a leaf costs no more, no binning can
    // find a cheaper split (most nodes are these, at the bottom of the tree).
    if n == 1 || (n <= options.max_leaf && blocks(n, options) <= options.traversal_cost) {
        return Decision::Leaf;
    }
    let (bounds, centroids) = bounds;
    let extent = centroids.max - centroids.min;
    let split = if depth < SAH_DEPTH && extent.max_element() > 0.0 {
        best_sah_split(items, bounds, centroids, options)
    } else {
        None
    };
    let median = |items: &mut [Item]| Decision::Split { mid: median_split(items, extent), sides: [None; 2] };
    match split {
        Some(Split { cost, axis, bin, binner }) => {
            if n <= options.max_leaf && cost >= blocks(n, options) {
                return Decision::Leaf; // a leaf is cheaper than any split
            }
            // The same arithmetic as the binning, so each item goes where it was counted.
            match partition(items, |c| binner.bins(c)[axis] <= bin as i32) {
                (0, _) => median(items),
                (mid, _) if mid == n => median(items),
                (mid, [l, r]) => Decision::Split { mid, sides: [Some(l), Some(r)] },
            }
        }
        None if n <= options.max_leaf => Decision::Leaf,
        None => median(items),
    }
}

/// Builds the subtree over `items`, which start at `offset` in the final primitive order;
/// `known` is the bounds of their boxes and centroids when the caller has them. Subtrees of
/// up to [`PARALLEL_MIN`] items are built flat on this thread ([`build_flat`]).
fn build_node(
    items: &mut [Item],
    offset: usize,
    options: &BuildOptions,
    depth: usize,
    known: Option<(Aabb, Aabb)>,
) -> Tree {
    let n = items.len();
    let bounds = known.unwrap_or_else(|| bounds_of(items));
    if n <= PARALLEL_MIN {
        let mut nodes = Vec::with_capacity(2 * n.div_ceil(options.block.max(1)));
        nodes.push(PLACEHOLDER);
        build_flat(&mut nodes, 0, items, offset, options, depth, bounds);
        return Tree::Flat(nodes);
    }
    match decide(items, &bounds, options, depth) {
        Decision::Leaf => Tree::Flat(vec![Node::leaf(&bounds.0, offset, n)]),
        Decision::Split { mid, sides: [kl, kr] } => {
            let (left, right) = items.split_at_mut(mid);
            let (l, r) = rayon::join(
                || build_node(left, offset, options, depth + 1, kl),
                || build_node(right, offset + mid, options, depth + 1, kr),
            );
            Tree::Inner { bounds: bounds.0, children: Box::new([l, r]) }
        }
    }
}

/// Builds the subtree over `items` into `nodes[at]`, its descendants appended after, each
/// inner node's two children side by side.
fn build_flat(
    nodes: &mut Vec<Node>,
    at: usize,
    items: &mut [Item],
    offset: usize,
    options: &BuildOptions,
    depth: usize,
    bounds: (Aabb, Aabb),
) {
    match decide(items, &bounds, options, depth) {
        Decision::Leaf => nodes[at] = Node::leaf(&bounds.0, offset, items.len()),
        Decision::Split { mid, sides: [kl, kr] } => {
            let first = nodes.len();
            nodes.push(PLACEHOLDER);
            nodes.push(PLACEHOLDER);
            nodes[at] = Node::inner(&bounds.0, first);
            let (left, right) = items.split_at_mut(mid);
            let kl = kl.unwrap_or_else(|| bounds_of(left));
            let kr = kr.unwrap_or_else(|| bounds_of(right));
            build_flat(nodes, first, left, offset, options, depth + 1, kl);
            build_flat(nodes, first + 1, right, offset + mid, options, depth + 1, kr);
        }
    }
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
/// come first), and the bounds of boxes and centroids on each side, gathered on the way. Two
/// cursors meet in the middle, swapping only items on the wrong side; each side's bounds stay
/// in registers. (A branch-free version, swapping every item, measured slower.)
fn partition(items: &mut [Item], pred: impl Fn(Vec3A) -> bool) -> (usize, [(Aabb, Aabb); 2]) {
    let (mut left, mut right) = ((Aabb::EMPTY, Aabb::EMPTY), (Aabb::EMPTY, Aabb::EMPTY));
    let grow =
        |side: &mut (Aabb, Aabb), it: &Item| *side = (side.0.union(&it.bounds()), side.1.grow(it.centroid()));
    let (mut i, mut j) = (0, items.len());
    loop {
        while i < j && pred(items[i].centroid()) {
            grow(&mut left, &items[i]);
            i += 1;
        }
        while i < j && !pred(items[j - 1].centroid()) {
            grow(&mut right, &items[j - 1]);
            j -= 1;
        }
        if i == j {
            return (i, [left, right]);
        }
        // items[i] belongs right and items[j - 1] left.
        items.swap(i, j - 1);
        grow(&mut left, &items[i]);
        grow(&mut right, &items[j - 1]);
        i += 1;
        j -= 1;
    }
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
    binner: Binner,
}

/// The SAH's cost of testing `n` primitives: the number of blocks the leaf test takes.
#[inline(always)]
fn blocks(n: usize, options: &BuildOptions) -> f32 {
    let block = options.block.max(1);
    // A shift where the block is a power of two (always, by default): the sweeps ask this for
    // every bin boundary, and a division costs more than the rest of the step.
    if block.is_power_of_two() {
        ((n + block - 1) >> block.trailing_zeros()) as f32
    } else {
        n.div_ceil(block) as f32
    }
}

/// Maps centroids to bins on all three axes at once: `(c - lo) * scale`, truncated and clamped
/// to `[0, bins - 1]` (a NaN goes to bin 0). The binning and the partition both use it, so each
/// item goes to the side where it was counted.
#[derive(Clone, Copy)]
struct Binner {
    lo: f32x4,
    scale: f32x4,
    last: i32x4,
}

impl Binner {
    fn new(lo: Vec3A, scale: Vec3A, bins: usize) -> Binner {
        Binner {
            lo: f32x4::from(lo.extend(0.0).to_array()),
            scale: f32x4::from(scale.extend(0.0).to_array()),
            last: i32x4::splat(bins as i32 - 1),
        }
    }

    #[inline(always)]
    fn bins(&self, c: Vec3A) -> [i32; 4] {
        let c = f32x4::from(c.extend(0.0).to_array());
        // Out of range or NaN truncates to i32::MIN, which the clamp takes to 0.
        ((c - self.lo) * self.scale).fast_trunc_int().max(i32x4::ZERO).min(self.last).to_array()
    }
}

/// Centroid bins on the three axes: bounds and count of the items in each.
type Bins<const B: usize> = [[Bin; B]; 3];
const MAX_BINS: usize = 32;
/// Nodes with more items than this bin on several threads.
const PARALLEL_BINNING: usize = 1 << 15;

impl Bin {
    const EMPTY: Bin = Bin { bounds: Aabb::EMPTY, count: 0 };
}

/// Adds `item` to the bins `binner` assigns it on each axis. `B` is a power of two at least the
/// bins in use.
#[inline(always)]
fn add<const B: usize>(bins: &mut Bins<B>, binner: &Binner, item: &Item) {
    const { assert!(B.is_power_of_two()) };
    let (ib, c) = (item.bounds(), item.centroid());
    let index = binner.bins(c);
    for axis in 0..3 {
        // The clamp keeps the index below the bins in use; the mask tells the compiler so.
        let bin = &mut bins[axis][index[axis] as usize & (B - 1)];
        bin.bounds = bin.bounds.union(&ib);
        bin.count += 1;
    }
}

/// The first `n` bins of each axis: those in use.
fn in_use<const B: usize>(bins: &Bins<B>, n: usize) -> [&[Bin]; 3] {
    bins.each_ref().map(|axis| &axis[..n])
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
    let binner = Binner::new(lo, scale, bins_n);
    let sweep = |bins: [&[Bin]; 3]| sweep(bins, items.len(), bounds, binner, options);
    if items.len() > PARALLEL_BINNING {
        let empty = || Box::new([[Bin::EMPTY; MAX_BINS]; 3]);
        let bins = items
            .par_chunks(PARALLEL_BINNING / 4)
            .map(|chunk| {
                chunk.iter().fold(empty(), |mut bins, it| {
                    add(&mut bins, &binner, it);
                    bins
                })
            })
            .reduce(empty, |mut a, b| {
                for axis in 0..3 {
                    for (x, y) in a[axis].iter_mut().zip(b[axis].iter()) {
                        x.bounds = x.bounds.union(&y.bounds);
                        x.count += y.count;
                    }
                }
                a
            });
        sweep(in_use(&bins, bins_n))
    } else {
        // Smaller nodes bin on the stack, in as few bins as they use: setting up bins costs as
        // much as binning a handful of items.
        fn on_stack<const B: usize>(items: &[Item], binner: &Binner) -> Bins<B> {
            let mut bins = [[Bin::EMPTY; B]; 3];
            for it in items {
                add(&mut bins, binner, it);
            }
            bins
        }
        if bins_n <= 8 {
            sweep(in_use(&on_stack::<8>(items, &binner), bins_n))
        } else if bins_n <= 16 {
            sweep(in_use(&on_stack::<16>(items, &binner), bins_n))
        } else {
            sweep(in_use(&on_stack::<MAX_BINS>(items, &binner), bins_n))
        }
    }
}

/// Sweeps the bins of each axis for the split of least SAH cost.
fn sweep(
    bins: [&[Bin]; 3],
    n: usize,
    bounds: &Aabb,
    binner: Binner,
    options: &BuildOptions,
) -> Option<Split> {
    let parent_area = bounds.half_area().max(f32::MIN_POSITIVE);
    let mut best = (f32::INFINITY, 0, 0);
    let scale = binner.scale.to_array();
    for (axis, bins) in bins.into_iter().enumerate() {
        // A flat axis (all centroids in one bin) gives no split.
        let bins_n = bins.len();
        if scale[axis] <= 0.0 {
            continue;
        }
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
            // Area-weighted block counts: the cost but for the traversal step and the parent's
            // area, which every candidate shares.
            let cost = acc.half_area() * blocks(count as usize, options) + right_cost[b + 1];
            if cost < best.0 {
                best = (cost, axis, b);
            }
        }
    }
    let (cost, axis, bin) = best;
    cost.is_finite().then(|| Split { cost: options.traversal_cost + cost / parent_area, axis, bin, binner })
}
