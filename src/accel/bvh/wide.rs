//! The 8-wide BVH that rays actually traverse: the binary SAH tree collapsed so that each node
//! holds up to eight children, their boxes stored axis by axis so one slab test checks all eight
//! at once: AVX-512 or AVX2 where the CPU has them, chosen at run time, or the portable test of
//! the `wide` crate ([`super::simd`], the only module with `unsafe`). A leaf is one or two blocks
//! of four lanes, each a triangle or a quad (two triangles sharing an edge, paired as the scene
//! is read: [`Prim::Quad`]), each block tested at once by the watertight test, four lanes wide.

use arrayvec::ArrayVec;
use wide::f32x4;

use super::intersect::{gamma, sphere, RayTri};
use super::pages::Pages;
use super::simd::{BoxTest, Isa, Portable, RayBox8};
use super::Filter;
use super::{Node, Prim};
use crate::accel::{Hit, Ray};

/// A reference to a child, 32 bits so a node's eight children take 32 bytes: the cache line of
/// the tree's array where it starts, for an inner node with the top bit clear; for a leaf (its
/// first block) with the top bit set, and the next bit set when a second block of four
/// follows it.
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(transparent)]
pub struct Child(u32);

const LEAF: u32 = 1 << 31;
const TWO: u32 = 1 << 30;
/// The most primitives a leaf can hold: two blocks of four lanes.
pub const MAX_LEAF: u32 = 8;
/// The most primitives a tree can hold: every line index fits below [`TWO`]. With n primitives
/// there are at most n leaf blocks of four lines, and fewer than n nodes of four (each has two
/// children at least), so fewer than 8 n lines.
pub const MAX_PRIMS: u32 = TWO / 8 - 1;

impl Child {
    const EMPTY: Child = Child(u32::MAX);

    fn inner(index: u32) -> Child {
        debug_assert!(index < LEAF);
        Child(index)
    }

    fn leaf(index: u32, blocks: u32) -> Child {
        debug_assert!(index < TWO - 1 && (1..=2).contains(&blocks));
        Child(LEAF | index | if blocks == 2 { TWO } else { 0 })
    }

    /// Whether this is a leaf (EMPTY, never traversed, also has the top bit set).
    #[inline(always)]
    fn is_leaf(self) -> bool {
        self.0 & LEAF != 0
    }

    /// A leaf's first block.
    #[inline(always)]
    fn index(self) -> usize {
        (self.0 & !(LEAF | TWO)) as usize
    }

    /// A leaf's blocks.
    #[inline(always)]
    fn blocks(self) -> usize {
        1 + usize::from(self.0 & TWO != 0)
    }
}

/// What both kinds of leaf block hold besides vertices: each lane's shape and primitive, and
/// the block's counts.
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
struct Head {
    shape: [u32; 4],
    /// Each lane's (first) triangle; a quad's second is the next one.
    prim: [u32; 4],
    triangles: u16,
    /// The lanes that hold a quad: zero when the block has none, whose second test is skipped.
    quads: u16,
    spheres_first: u32,
    spheres_count: u32,
    /// The lanes whose shape has a cut-out ([`Bvh8::mark_cutouts`]): their hits are asked
    /// whether they count. Zero for the blocks of a scene without alpha, which test nothing
    /// more.
    cut: u32,
}

impl Head {
    const EMPTY: Head = Head {
        shape: [0; 4],
        prim: [0; 4],
        triangles: 0,
        quads: 0,
        spheres_first: 0,
        spheres_count: 0,
        cut: 0,
    };
}

/// A leaf block of four triangles, structure-of-arrays so that one SIMD pass tests all four:
/// `v[3 * k + a]` holds axis `a` of vertex `k` of each triangle. Unused lanes hold NaN
/// vertices, which no ray hits, so the test needs no lane mask. Spheres (rare) are kept aside
/// and tested one by one. Three cache lines (blocks are cast from the tree's [`Line`]s, plain
/// data).
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C, align(64))]
pub struct Tri4 {
    v: [[f32; 4]; 9],
    head: Head,
}

/// A leaf block of four lanes, each a triangle `v0 v1 v2` or two sharing an edge
/// ([`Prim::Quad`]: `v0 v1 v2` and `v0 v2 v3`), as [`Tri4`] with a fourth vertex row `v3` (NaN
/// in a lane of one triangle) and each lane's rotations. Four cache lines for up to eight
/// triangles, against six for two [`Tri4`]s: the trees of large meshes take them
/// ([`QUAD_MIN`](super::QUAD_MIN)).
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C, align(64))]
pub struct Quad4 {
    v: [[f32; 4]; 9],
    v3: [[f32; 4]; 3],
    /// Each lane's rotations (`rot` of [`Prim::Quad`]): the hit's barycentrics and distance are
    /// computed in the triangle's own vertex order, so they are the scalar test's to the bit.
    rot: [u32; 4],
    head: Head,
}

/// What the traversal and the packing ask of a leaf block, [`Tri4`] or [`Quad4`]: a tree holds
/// one kind, and its traversal is compiled for it.
trait Block: bytemuck::Pod + Send + Sync {
    /// No triangles: every lane's vertices are NaN, which no ray hits.
    const EMPTY: Self;
    const LINES: usize;
    fn v(&self) -> &[[f32; 4]; 9];
    fn head(&self) -> &Head;
    fn head_mut(&mut self) -> &mut Head;
    /// The fourth vertex row and the rotations, where the block has quads.
    fn quads(&self) -> Option<(&[[f32; 4]; 3], &[u32; 4])>;
    /// Writes a triangle (three vertices) or a quad (four) into `lane`.
    fn put(&mut self, lane: usize, vertices: &[glam::Vec3], rot: u8);
    /// The blocks of a leaf from its lines (`n` blocks, one or two).
    fn of(lines: &[Line], n: usize) -> &[Self];
}

/// Writes `vertices` (three or four) into the rows of `lane`.
fn put_rows(rows: &mut [[f32; 4]], lane: usize, vertices: &[glam::Vec3]) {
    for (k, vertex) in vertices.iter().enumerate() {
        for a in 0..3 {
            rows[3 * k + a][lane] = vertex[a];
        }
    }
}

/// `n` (one or two) blocks of `L` lines each from the start of `lines`: cast from lines of a
/// size known when compiling, so no run-time check of the alignment and of the length's
/// multiple (a division), which `cast_slice` makes at every visit.
macro_rules! blocks_of_lines {
    ($lines:expr, $n:expr, $l:literal, $t:ty) => {{
        let blocks = match $n {
            1 => $lines.first_chunk::<$l>().map(|l| std::slice::from_ref(bytemuck::cast_ref::<_, $t>(l))),
            _ => $lines.first_chunk::<{ 2 * $l }>().map(|l| bytemuck::cast_ref::<_, [$t; 2]>(l).as_slice()),
        };
        let Some(blocks) = blocks else { unreachable!("a child names blocks inside the tree") };
        blocks
    }};
}

/// What both kinds of block do alike: their lines, first three vertex rows and counts.
macro_rules! common_block_fns {
    ($t:ty, $lines:literal) => {
        const LINES: usize = $lines;
        #[inline(always)]
        fn v(&self) -> &[[f32; 4]; 9] {
            &self.v
        }
        #[inline(always)]
        fn head(&self) -> &Head {
            &self.head
        }
        fn head_mut(&mut self) -> &mut Head {
            &mut self.head
        }
        #[inline(always)]
        fn of(lines: &[Line], n: usize) -> &[$t] {
            blocks_of_lines!(lines, n, $lines, $t)
        }
    };
}

impl Block for Tri4 {
    const EMPTY: Tri4 = Tri4 { v: [[f32::NAN; 4]; 9], head: Head::EMPTY };
    common_block_fns!(Tri4, 3);
    #[inline(always)]
    fn quads(&self) -> Option<(&[[f32; 4]; 3], &[u32; 4])> {
        None
    }
    fn put(&mut self, lane: usize, vertices: &[glam::Vec3], _rot: u8) {
        debug_assert_eq!(vertices.len(), 3, "a tree of triangle blocks holds no quads");
        put_rows(&mut self.v, lane, &vertices[..3]);
    }
}

impl Block for Quad4 {
    const EMPTY: Quad4 =
        Quad4 { v: [[f32::NAN; 4]; 9], v3: [[f32::NAN; 4]; 3], rot: [0; 4], head: Head::EMPTY };
    common_block_fns!(Quad4, 4);
    #[inline(always)]
    fn quads(&self) -> Option<(&[[f32; 4]; 3], &[u32; 4])> {
        (self.head.quads != 0).then_some((&self.v3, &self.rot))
    }
    fn put(&mut self, lane: usize, vertices: &[glam::Vec3], rot: u8) {
        put_rows(&mut self.v, lane, &vertices[..3]);
        if let Some(&d) = vertices.get(3) {
            put_rows(&mut self.v3, lane, &[d]);
        }
        self.rot[lane] = u32::from(rot);
    }
}

/// Packs a leaf's primitives into `blocks` (empty, enough for all of them), a triangle or a
/// quad a lane, four lanes a block, and counts its spheres in the first block. Unused vertices
/// keep the NaN of [`Block::EMPTY`]. Returns the blocks used (at least one) and the spheres,
/// which the caller stores.
fn pack<'a, B: Block>(blocks: &mut [B], prims: impl Iterator<Item = &'a Prim>) -> (usize, u32) {
    let (mut lanes, mut spheres) = (0, 0);
    for prim in prims {
        let (vertices, shape, prim, rot): (&[glam::Vec3], _, _, _) = match prim {
            Prim::Triangle { v, shape, prim } => (v, *shape, *prim, 0),
            Prim::Quad { v, shape, prim, rot } => (v, *shape, *prim, *rot),
            Prim::Sphere { .. } => {
                spheres += 1;
                continue;
            }
        };
        let (block, lane) = (&mut blocks[lanes / 4], lanes % 4);
        block.put(lane, vertices, rot);
        let head = block.head_mut();
        head.shape[lane] = shape;
        head.prim[lane] = prim;
        head.triangles += vertices.len() as u16 - 2;
        if vertices.len() == 4 {
            head.quads |= 1 << lane;
        }
        lanes += 1;
    }
    let used = lanes.div_ceil(4).max(1);
    blocks[0].head_mut().spheres_count = spheres;
    (used, spheres)
}

/// A sphere of a leaf.
#[derive(Clone, Copy, Debug)]
struct SphereRef {
    center: glam::Vec3,
    radius: f32,
    shape: u32,
}

/// How many children an inner node has at most.
pub const WIDTH: usize = 8;

/// Eight children's boxes, axis by axis (empty slots hold an inverted box that no ray meets),
/// and what each child is: 224 bytes, padded to four cache lines.
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C, align(64))]
pub struct Node8 {
    /// min x, min y, min z, max x, max y, max z of the eight children.
    pub bounds: [[f32; WIDTH]; 6],
    children: [Child; WIDTH],
    /// To four cache lines, spelled out (nodes are cast from the tree's [`Line`]s, plain data).
    _pad: [u32; 8],
}

impl Node8 {
    /// A node with every slot empty.
    pub const EMPTY: Node8 = Node8 {
        bounds: [
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
        ],
        children: [Child::EMPTY; WIDTH],
        _pad: [0; 8],
    };

    /// The box of slot `slot`.
    pub fn child_box(&self, slot: usize) -> super::Aabb {
        let plane = |row: usize| self.bounds[row][slot];
        super::Aabb {
            min: glam::Vec3A::new(plane(0), plane(1), plane(2)),
            max: glam::Vec3A::new(plane(3), plane(4), plane(5)),
        }
    }

    /// A node whose first child has the box `[min, max]` and whose others are empty.
    #[cfg(test)]
    pub(super) fn with_first_box(min: glam::Vec3, max: glam::Vec3) -> Node8 {
        let mut node = Node8::EMPTY;
        for a in 0..3 {
            node.bounds[a][0] = min[a];
            node.bounds[3 + a][0] = max[a];
        }
        node
    }
}

/// Counts and sizes of a wide tree: what rays traverse, and what it takes in memory.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct WideStats {
    pub nodes: usize,
    pub leaves: usize,
    /// Children per inner node (at most eight).
    pub mean_children: f64,
    /// Triangles per leaf block (at most eight: four quads).
    pub mean_leaf_triangles: f64,
    /// Bytes of nodes, leaves and spheres, exactly.
    pub bytes: usize,
    /// Inner nodes on the longest path from the root.
    pub depth: usize,
    /// The surface area heuristic as Embree's statistics report it (`verbose=2`), so the two
    /// trees compare: each inner node's box area, and each leaf's area times its blocks, over
    /// the root's area.
    pub sah_nodes: f64,
    pub sah_leaves: f64,
}

/// Primitives and the order the binary tree's leaf ranges index.
struct Ordered<'a> {
    prims: &'a [Prim],
    order: &'a [u32],
}

/// A cache line of the tree's array: nodes take [`NODE_LINES`], leaf blocks [`Block::LINES`].
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C, align(64))]
struct Line([u8; 64]);

const NODE_LINES: usize = std::mem::size_of::<Node8>() / 64;
const _: () = assert!(
    NODE_LINES * 64 == std::mem::size_of::<Node8>()
        && Tri4::LINES * 64 == std::mem::size_of::<Tri4>()
        && Quad4::LINES * 64 == std::mem::size_of::<Quad4>()
);

/// What [`Bvh8::walk`] finds.
struct Walk {
    children: usize,
    triangles: usize,
    sah_nodes: f64,
    sah_leaves: f64,
}

/// What [`Bvh8::lay_out`] places: a node (its index in the collapse) or a leaf (its note).
#[derive(Clone, Copy)]
enum Item {
    Node(usize),
    Leaf(usize),
}

pub struct Bvh8 {
    /// Nodes and leaf blocks, depth first, each node followed by its leaves ([`Self::lay_out`]);
    /// a child names the line it starts at. In huge pages where the OS offers them
    /// ([`Pages`]): rays in random order touch all of it, far more 4 KiB pages than the TLB
    /// holds.
    lines: Pages<Line>,
    node_count: usize,
    block_count: usize,
    /// Whether the leaf blocks are [`Quad4`]s (else [`Tri4`]s): the tree holds quads.
    pub(super) quads: bool,
    spheres: Vec<SphereRef>,
    root: Child,
    /// The slab test this CPU runs best.
    isa: Isa,
    /// Inner nodes on the longest path from the root: the stack holds at most
    /// `(WIDTH - 1) * depth + 1` entries.
    depth: usize,
}

/// Traversal stack depth: each level of the tree pushes at most seven entries, and collapsing
/// never deepens the binary tree, whose depth the build bounds.
const STACK: usize = (WIDTH - 1) * super::STACK + 1;
/// The stack of trees shallow enough for it (every tree of a real scene): a smaller frame. (The
/// stacks are not initialised, so their length costs no time; each size has its own traversal
/// function, so no frame holds both.)
const SHORT_STACK: usize = 128;

/// Ize's factor: the far slab distance grows by 2 gamma(3) to cover rounding (see `RayBox`).
const FAR_SCALE: f32 = super::FAR_SCALE;

impl Bvh8 {
    /// Collapses a binary tree: each wide node takes its binary node's children, then keeps
    /// opening the inner child of largest area until it has eight. Then the nodes and leaves are
    /// laid out in one array ([`Self::lay_out`]) and the leaves packed on all threads. `order`
    /// maps the binary leaves' ranges to `prims`.
    pub fn collapse(binary: &[Node], prims: &[Prim], order: &[u32]) -> Bvh8 {
        let mut bvh = Bvh8 {
            lines: Pages::default(),
            node_count: 0,
            block_count: 0,
            quads: prims.iter().any(|p| matches!(p, Prim::Quad { .. })),
            spheres: Vec::new(),
            root: Child::EMPTY,
            isa: Isa::best(),
            depth: 0,
        };
        if binary.is_empty() {
            return bvh;
        }
        // The nodes first, each leaf noted where it goes (node, slot, binary leaf).
        let mut pending = Vec::with_capacity(binary.len() / 2 + 1);
        let mut nodes = Vec::with_capacity(binary.len() / 6 + 1);
        if binary[0].count > 0 {
            pending.push((0, 0, 0));
        } else {
            nodes.push(Node8::EMPTY);
            bvh.fill(binary, &mut nodes, &mut pending, 0, 0, 1);
        }
        bvh.lay_out(binary, &nodes, &pending, &Ordered { prims, order });
        bvh
    }

    /// Lays the tree out in one array of cache lines, depth first, each node followed by its
    /// leaves' blocks and then by its inner children's subtrees (as Embree's allocator places
    /// them): the read of a node that leads to a leaf opens the memory row the leaf is in and
    /// wakes the hardware prefetcher for it. Writes the nodes with their children's places,
    /// then packs every leaf's primitives on all threads.
    fn lay_out(
        &mut self,
        binary: &[Node],
        nodes: &[Node8],
        pending: &[(usize, usize, usize)],
        prims: &Ordered,
    ) {
        use rayon::prelude::*;
        // Each node's leaves: `fill` notes a node's leaves together.
        let mut leaves_of = vec![0..0; nodes.len().max(1)];
        for (p, &(at, _, _)) in pending.iter().enumerate() {
            if leaves_of[at].is_empty() {
                leaves_of[at] = p..p;
            }
            leaves_of[at].end = p + 1;
        }
        // A leaf gets blocks for all its primitives (spheres, rare, leave some unused).
        let blocks_of = |p: usize| binary[pending[p].2].count.div_ceil(4).max(1) as usize;
        let leaf_lines = self.leaf_lines();
        // Where each node and each leaf starts, in lines, and the order they are met in, each
        // with its length in lines.
        let (mut node_line, mut leaf_line) = (vec![0u32; nodes.len()], vec![0u32; pending.len()]);
        let mut items = Vec::with_capacity(nodes.len() + pending.len());
        let mut cursor = 0usize;
        let mut stack = Vec::new();
        if nodes.is_empty() {
            items.push((Item::Leaf(0), leaf_lines * blocks_of(0)));
            cursor = items[0].1;
        } else {
            stack.push(0);
        }
        while let Some(n) = stack.pop() {
            node_line[n] = cursor as u32;
            items.push((Item::Node(n), NODE_LINES));
            cursor += NODE_LINES;
            for p in leaves_of[n].clone() {
                leaf_line[p] = cursor as u32;
                items.push((Item::Leaf(p), leaf_lines * blocks_of(p)));
                cursor += leaf_lines * blocks_of(p);
            }
            // Inner children in slot order: pushed in reverse, popped first to last.
            for c in nodes[n].children.iter().rev().filter(|c| **c != Child::EMPTY && !c.is_leaf()) {
                stack.push(c.0 as usize);
            }
        }
        self.node_count = nodes.len();
        // Every line is written below: a node, or a leaf block set up empty first.
        self.lines = Pages::zeroed(cursor);
        // Each item's lines, split off in the order they lie.
        let mut rest = &mut self.lines[..];
        let mut node_slices = Vec::with_capacity(nodes.len());
        let mut leaf_slices = Vec::with_capacity(pending.len());
        for &(item, len) in &items {
            let (mine, others) = std::mem::take(&mut rest).split_at_mut(len);
            match item {
                Item::Node(n) => node_slices.push((n, mine)),
                Item::Leaf(p) => leaf_slices.push((p, mine)),
            }
            rest = others;
        }
        let of = |p: usize| {
            let i = pending[p].2;
            prims.order[binary[i].prims()].iter().map(|&q| &prims.prims[q as usize])
        };
        // Each leaf's blocks used and spheres.
        fn packed_in<'a, B: Block>(
            lines: &mut [Line],
            prims: impl Iterator<Item = &'a Prim>,
        ) -> (usize, u32) {
            let blocks: &mut [B] = bytemuck::cast_slice_mut(lines);
            blocks.fill(B::EMPTY);
            pack(blocks, prims)
        }
        let quads = self.quads;
        let packed: Vec<(usize, usize, u32)> = leaf_slices
            .into_par_iter()
            .map(|(p, lines)| {
                let (used, spheres) =
                    if quads { packed_in::<Quad4>(lines, of(p)) } else { packed_in::<Tri4>(lines, of(p)) };
                (p, used, spheres)
            })
            .collect();
        let mut children = vec![Child::EMPTY; pending.len()];
        for &(p, used, _) in &packed {
            children[p] = Child::leaf(leaf_line[p], used as u32);
        }
        for (n, lines) in node_slices {
            let mut node = nodes[n];
            for c in node.children.iter_mut().filter(|c| **c != Child::EMPTY) {
                *c = Child::inner(node_line[c.0 as usize]);
            }
            for p in leaves_of[n].clone() {
                node.children[pending[p].1] = children[p];
            }
            bytemuck::cast_slice_mut::<Line, Node8>(lines)[0] = node;
        }
        self.block_count = packed.iter().map(|&(_, used, _)| used).sum();
        // Spheres (rare) go to their own array, leaf by leaf.
        for &(p, _, spheres) in &packed {
            if spheres > 0 {
                let first = self.spheres.len() as u32;
                self.head_mut(children[p]).spheres_first = first;
                for prim in of(p) {
                    if let Prim::Sphere { center, radius, shape } = *prim {
                        self.spheres.push(SphereRef { center, radius, shape });
                    }
                }
            }
        }
        self.root = if nodes.is_empty() { children[0] } else { Child::inner(node_line[0]) };
    }

    /// Checks the layout: every line belongs to exactly one node or leaf block, and each node's
    /// leaves follow it directly, in slot order. Returns the first violation found.
    #[cfg(test)]
    pub(super) fn check_layout(&self) -> Result<(), String> {
        let mut owner = vec![false; self.lines.len()];
        let mut claim = |start: usize, len: usize, what: &str| -> Result<(), String> {
            let lines =
                owner.get_mut(start..start + len).ok_or(format!("{what} at {start} runs past the array"))?;
            if lines.iter().any(|&taken| taken) {
                return Err(format!("{what} at {start} overlaps another"));
            }
            lines.fill(true);
            Ok(())
        };
        if self.root == Child::EMPTY {
            return Ok(());
        }
        let mut stack = vec![self.root];
        while let Some(c) = stack.pop() {
            if c.is_leaf() {
                claim(c.index(), self.leaf_lines() * c.blocks(), "leaf")?;
                continue;
            }
            claim(c.0 as usize, NODE_LINES, "node")?;
            let mut next = c.0 as usize + NODE_LINES;
            for &child in self.node(c).children.iter().filter(|k| **k != Child::EMPTY) {
                if child.is_leaf() {
                    if child.index() != next {
                        return Err(format!(
                            "a leaf of the node at {} starts at {}, not {next}",
                            c.0,
                            child.index()
                        ));
                    }
                    next += self.leaf_lines() * child.blocks();
                }
                stack.push(child);
            }
        }
        match owner.iter().position(|&taken| !taken) {
            Some(line) => Err(format!("line {line} belongs to nothing")),
            None => Ok(()),
        }
    }

    /// Marks the lanes whose shape `cuts` names as cut-outs, whose hits the traversal asks
    /// its [`Filter`] about; returns whether any lane is marked.
    pub(super) fn mark_cutouts(&mut self, cuts: impl Fn(u32) -> bool) -> bool {
        let mut leaves = Vec::new();
        let mut stack = vec![self.root];
        while let Some(child) = stack.pop() {
            if child == Child::EMPTY {
                continue;
            }
            if child.is_leaf() {
                leaves.push(child);
            } else {
                stack.extend(self.node(child).children.iter().copied());
            }
        }
        fn mark<B: Block>(blocks: &mut [B], cuts: &impl Fn(u32) -> bool) -> bool {
            let mut any = false;
            for block in blocks {
                // A used lane has a first vertex (an unused one NaN).
                let used = std::array::from_fn::<bool, 4, _>(|l| !block.v()[0][l].is_nan());
                let head = block.head_mut();
                head.cut = (0..4).filter(|&l| used[l] && cuts(head.shape[l])).fold(0, |m, l| m | 1 << l);
                any |= head.cut != 0;
            }
            any
        }
        let mut any = false;
        for child in leaves {
            let lines = self.leaf_lines() * child.blocks();
            let lines = &mut self.lines[child.index()..child.index() + lines];
            any |= if self.quads {
                mark::<Quad4>(bytemuck::cast_slice_mut(lines), &cuts)
            } else {
                mark::<Tri4>(bytemuck::cast_slice_mut(lines), &cuts)
            };
        }
        any
    }

    /// Lines a leaf block takes in this tree.
    fn leaf_lines(&self) -> usize {
        if self.quads {
            Quad4::LINES
        } else {
            Tri4::LINES
        }
    }

    /// The first block's counts of leaf `child`.
    fn head_mut(&mut self, child: Child) -> &mut Head {
        let (at, lines) = (child.index(), self.leaf_lines());
        let lines = &mut self.lines[at..at + lines];
        if self.quads {
            &mut bytemuck::cast_slice_mut::<Line, Quad4>(lines)[0].head
        } else {
            &mut bytemuck::cast_slice_mut::<Line, Tri4>(lines)[0].head
        }
    }

    /// Inner node `child`.
    #[inline(always)]
    fn node(&self, child: Child) -> &Node8 {
        // Cast from lines of a size known when compiling: no run-time check of the alignment
        // and of the length's multiple (a division), which `cast_slice` makes at every visit.
        let Some(lines) = self.lines[child.0 as usize..].first_chunk::<NODE_LINES>() else {
            unreachable!("a child names a node inside the tree")
        };
        bytemuck::cast_ref::<[Line; NODE_LINES], Node8>(lines)
    }

    /// Leaf `child`'s blocks, of kind `B` (the tree's).
    #[inline(always)]
    fn blocks<B: Block>(&self, child: Child) -> &[B] {
        B::of(&self.lines[child.index()..], child.blocks())
    }

    /// Fills wide node `at` from binary inner node `index`: its children, then the inner child
    /// of largest area opened until there are eight. (Where the nodes go in memory is decided
    /// after, by [`Self::lay_out`].)
    fn fill(
        &mut self,
        binary: &[Node],
        nodes: &mut Vec<Node8>,
        leaves: &mut Vec<(usize, usize, usize)>,
        index: usize,
        at: usize,
        level: usize,
    ) {
        self.depth = self.depth.max(level);
        let n = &binary[index];
        let area = |i: usize| {
            let b = &binary[i];
            let d = [b.max[0] - b.min[0], b.max[1] - b.min[1], b.max[2] - b.min[2]];
            d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
        };
        let mut kids = [n.first as usize, n.first as usize + 1, 0, 0, 0, 0, 0, 0];
        let mut len = 2;
        while len < WIDTH {
            let open = (0..len)
                .filter(|&slot| binary[kids[slot]].count == 0)
                .max_by(|&a, &b| area(kids[a]).total_cmp(&area(kids[b])));
            let Some(slot) = open else { break };
            let first = binary[kids[slot]].first as usize;
            kids[slot] = first;
            kids[len] = first + 1;
            len += 1;
        }
        let mut inner = [(0, 0); WIDTH];
        let mut inner_len = 0;
        for (slot, &k) in kids[..len].iter().enumerate() {
            let b = &binary[k];
            for axis in 0..3 {
                nodes[at].bounds[axis][slot] = b.min[axis];
                nodes[at].bounds[3 + axis][slot] = b.max[axis];
            }
            nodes[at].children[slot] = if b.count > 0 {
                leaves.push((at, slot, k));
                Child::EMPTY // until the leaves are packed
            } else {
                nodes.push(Node8::EMPTY);
                inner[inner_len] = (k, nodes.len() - 1);
                inner_len += 1;
                Child::inner((nodes.len() - 1) as u32)
            };
        }
        for &(k, node) in &inner[..inner_len] {
            self.fill(binary, nodes, leaves, k, node, level + 1);
        }
    }

    pub fn node_count(&self) -> usize {
        self.node_count
    }

    fn leaf_spheres(&self, leaf: &Head) -> &[SphereRef] {
        &self.spheres[leaf.spheres_first as usize..(leaf.spheres_first + leaf.spheres_count) as usize]
    }

    /// Bytes of nodes, leaves and spheres, exactly.
    pub fn bytes(&self) -> usize {
        self.lines.len() * std::mem::size_of::<Line>() + self.spheres.len() * std::mem::size_of::<SphereRef>()
    }

    /// Counts and sizes of the tree.
    pub fn stats(&self) -> WideStats {
        let walk = self.walk();
        WideStats {
            nodes: self.node_count,
            leaves: self.block_count,
            mean_children: walk.children as f64 / self.node_count.max(1) as f64,
            mean_leaf_triangles: walk.triangles as f64 / self.block_count.max(1) as f64,
            bytes: self.bytes(),
            depth: self.depth,
            sah_nodes: walk.sah_nodes,
            sah_leaves: walk.sah_leaves,
        }
    }

    /// One walk over the tree: its children and triangles, and Embree's SAH of it (inner node
    /// areas, and leaf areas times blocks, over the root's area).
    fn walk(&self) -> Walk {
        let mut walk = Walk { children: 0, triangles: 0, sah_nodes: 0.0, sah_leaves: 0.0 };
        fn triangles<B: Block>(blocks: &[B]) -> usize {
            blocks.iter().map(|b| b.head().triangles as usize).sum()
        }
        let count = |c: Child| {
            if self.quads {
                triangles(self.blocks::<Quad4>(c))
            } else {
                triangles(self.blocks::<Tri4>(c))
            }
        };
        if self.root == Child::EMPTY || self.root.is_leaf() {
            if self.root != Child::EMPTY {
                walk.triangles = count(self.root);
                walk.sah_leaves = self.root.blocks() as f64;
            }
            return walk;
        }
        let node_box = |n: &Node8| {
            (0..WIDTH)
                .filter(|&s| n.children[s] != Child::EMPTY)
                .fold(super::Aabb::EMPTY, |b, s| b.union(&n.child_box(s)))
        };
        let root = (node_box(self.node(self.root)).half_area() as f64).max(f64::MIN_POSITIVE);
        let mut stack = vec![self.root];
        while let Some(c) = stack.pop() {
            let n = self.node(c);
            walk.sah_nodes += node_box(n).half_area() as f64 / root;
            for slot in 0..WIDTH {
                let c = n.children[slot];
                if c == Child::EMPTY {
                    continue;
                }
                walk.children += 1;
                if c.is_leaf() {
                    walk.triangles += count(c);
                    walk.sah_leaves += n.child_box(slot).half_area() as f64 * c.blocks() as f64 / root;
                } else {
                    stack.push(c);
                }
            }
        }
        walk
    }

    /// The same tree traversed with kernels `isa` (for tests and benchmarks; `isa` exists
    /// only where this CPU runs it).
    pub fn with_isa(mut self, isa: Isa) -> Bvh8 {
        self.isa = isa;
        self
    }

    /// The slab test rays use.
    pub fn isa(&self) -> Isa {
        self.isa
    }
}

/// A stack entry: a child and the distance at which the ray entered its box.
#[derive(Clone, Copy)]
struct Entry {
    child: Child,
    t: f32,
}

/// The watertight test of [`RayTri`] on the four lanes of a leaf block at once, each lane's
/// first triangle and then, where the block has quads, their second ones: the same formulas lane
/// by lane (including the double-precision retry when an edge function rounds to zero), so what
/// holds for the scalar test holds here.
struct RayTri4 {
    origin: [f32x4; 3],
    k: [usize; 3],
    shear: [f32; 3],
}

/// A hit in a block: distance, lane, barycentrics of the second and third vertices, and which
/// of the lane's triangles (0 or 1).
type LaneHit = (f32, usize, f32, f32, u32);

impl RayTri4 {
    fn new(ray: &Ray) -> Self {
        let (k, shear) = RayTri::axes(ray);
        RayTri4 { origin: ray.origin.to_array().map(f32x4::splat), k, shear }
    }

    /// The `R` vertex rows `rows` (axis `a` of vertex `k` at `3 * k + a`) in the ray's sheared
    /// frame: x and y sheared, z relative to the origin (not yet scaled by Sz). Transformed once
    /// for both triangles of a quad, and the same way whichever triangle a vertex belongs to,
    /// which keeps shared edges watertight.
    #[inline(always)]
    fn shear_vertices<const R: usize>(&self, rows: &[[f32; 4]]) -> [[f32x4; 3]; R] {
        let [kx, ky, kz] = self.k;
        let (sx, sy) = (f32x4::splat(self.shear[0]), f32x4::splat(self.shear[1]));
        let rel = |vertex: usize, axis: usize| f32x4::new(rows[3 * vertex + axis]) - self.origin[axis];
        let sheared = |k: usize| {
            let z = rel(k, kz);
            [rel(k, kx) - sx * z, rel(k, ky) - sy * z, z]
        };
        let mut out = [[f32x4::ZERO; 3]; R];
        // Unrolled by hand: R is 1 or 3.
        out[0] = sheared(0);
        if R == 3 {
            out[1] = sheared(1);
            out[2] = sheared(2);
        }
        out
    }

    /// The nearest hit in the block within [0, t_max].
    #[inline(always)]
    fn hit<B: Block>(&self, leaf: &B, t_max: f32) -> Option<LaneHit> {
        if leaf.quads().is_some() {
            return self.hit_kept(leaf, t_max, |_, _, _, _| true);
        }
        // A block of triangles alone (every block of most trees): the nearest lane hit, without
        // `hit_kept`'s cut-out loop (through it, trees of triangles measured 6% to 13% slower).
        let [a, b, c] = self.shear_vertices::<3>(leaf.v());
        let (mut mask, t, inv, v, w) = self.lanes([a, b, c], None, t_max)?;
        let mut best = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        while mask != 0 {
            let l = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            if t[l] < t[best] {
                best = l;
            }
        }
        Some((t[best], best, v[best] * inv[best], w[best] * inv[best], 0))
    }

    /// [`Self::hit`], each lane's hit taken only if `keeps(lane, triangle, u, v)` says it counts
    /// (asked only of lanes marked as cut-outs), nearest first: the nearest hit that counts. The
    /// second triangles are tested within the first ones' nearest hit, so a tie goes to the
    /// second, as in the scalar reference.
    #[inline(always)]
    fn hit_kept<B: Block>(
        &self,
        leaf: &B,
        t_max: f32,
        keeps: impl Fn(usize, u32, f32, f32) -> bool,
    ) -> Option<LaneHit> {
        let [a, b, c] = self.shear_vertices::<3>(leaf.v());
        let Some((v3, rot)) = leaf.quads() else {
            return self.nearest(leaf.head(), [a, b, c], None, t_max, 0, &keeps);
        };
        let [d] = self.shear_vertices::<1>(v3);
        // Rotations only where a lane has one.
        let rot = (*rot != [0; 4]).then(|| wide::i32x4::new(bytemuck::cast(*rot)));
        let first = rot.map(|r| r & wide::i32x4::splat(3));
        let best = self.nearest(leaf.head(), [a, b, c], first, t_max, 0, &keeps);
        let t_max = best.map_or(t_max, |h| h.0);
        let second = rot.map(|r| (r >> 2) & wide::i32x4::splat(3));
        self.nearest(leaf.head(), [a, c, d], second, t_max, 1, &keeps).or(best)
    }

    /// The nearest kept hit of one triangle per lane, `tri` (0 or 1) of each lane.
    #[inline(always)]
    fn nearest(
        &self,
        leaf: &Head,
        v: [[f32x4; 3]; 3],
        rot: Option<wide::i32x4>,
        t_max: f32,
        tri: u32,
        keeps: &impl Fn(usize, u32, f32, f32) -> bool,
    ) -> Option<LaneHit> {
        let (mut mask, t, inv, v, w) = self.lanes(v, rot, t_max)?;
        while mask != 0 {
            let mut best = mask.trailing_zeros() as usize;
            let mut rest = mask & (mask - 1);
            while rest != 0 {
                let l = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                if t[l] < t[best] {
                    best = l;
                }
            }
            let (u, v) = (v[best] * inv[best], w[best] * inv[best]);
            if leaf.cut & (1 << best) == 0 || keeps(best, tri, u, v) {
                return Some((t[best], best, u, v, tri));
            }
            mask &= !(1 << best);
        }
        None
    }

    /// The lanes whose triangle `a b c` (sheared, [`Self::shear_vertices`]) the ray hits within
    /// [0, t_max] (a bit mask, never empty) with their `t`, the reciprocal of their
    /// determinant and their two unscaled barycentrics. `rot` is each lane's rotation of its
    /// triangle's own vertex order (none: all zero): the sums are taken in that order, as the
    /// scalar test does.
    #[inline(always)]
    #[allow(clippy::type_complexity)]
    fn lanes(
        &self,
        [[ax, ay, az], [bx, by, bz], [cx, cy, cz]]: [[f32x4; 3]; 3],
        rot: Option<wide::i32x4>,
        t_max: f32,
    ) -> Option<(u32, [f32; 4], [f32; 4], [f32; 4], [f32; 4])> {
        let sz = f32x4::splat(self.shear[2]);
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        let zero = f32x4::splat(0.0);
        let on_edge = u.simd_eq(zero) | v.simd_eq(zero) | w.simd_eq(zero);
        if on_edge.any() {
            // On an edge: decide in f64, as the scalar test does, in the lanes with a zero
            // only (elsewhere the f32 values stand, as they do in the scalar test).
            let (ax, ay, bx, by, cx, cy) =
                (ax.to_array(), ay.to_array(), bx.to_array(), by.to_array(), cx.to_array(), cy.to_array());
            let (mut uu, mut vv, mut ww) = ([0.0f32; 4], [0.0f32; 4], [0.0f32; 4]);
            for l in 0..4 {
                let (ax, ay, bx, by, cx, cy) =
                    (ax[l] as f64, ay[l] as f64, bx[l] as f64, by[l] as f64, cx[l] as f64, cy[l] as f64);
                uu[l] = (cx * by - cy * bx) as f32;
                vv[l] = (ax * cy - ay * cx) as f32;
                ww[l] = (bx * ay - by * ax) as f32;
            }
            u = on_edge.bitselect(f32x4::new(uu), u);
            v = on_edge.bitselect(f32x4::new(vv), v);
            w = on_edge.bitselect(f32x4::new(ww), w);
        }
        // All three edge functions of one sign (or zero): false for the NaN of unused lanes.
        let inside = (u.simd_ge(zero) & v.simd_ge(zero) & w.simd_ge(zero))
            | (u.simd_le(zero) & v.simd_le(zero) & w.simd_le(zero));
        if inside.to_bitmask() == 0 {
            return None; // the common case: the ray passes beside all four
        }
        // Back to each triangle's own vertex order (the bound below is symmetric in them).
        let ([u, v, w], [az, bz, cz]) = match rot {
            None => ([u, v, w], [az, bz, cz]),
            Some(rot) => {
                let (one, two) = (
                    bytemuck::cast::<wide::i32x4, f32x4>(rot.simd_eq(wide::i32x4::splat(1))),
                    bytemuck::cast::<wide::i32x4, f32x4>(rot.simd_eq(wide::i32x4::splat(2))),
                );
                let own = |e: [f32x4; 3]| {
                    [
                        one.bitselect(e[2], two.bitselect(e[1], e[0])),
                        one.bitselect(e[0], two.bitselect(e[2], e[1])),
                        one.bitselect(e[1], two.bitselect(e[0], e[2])),
                    ]
                };
                (own([u, v, w]), own([az, bz, cz]))
            }
        };
        let det = u + v + w;
        let t_scaled = u * (sz * az) + v * (sz * bz) + w * (sz * cz);
        // Fold det's sign into both sides: t = t_scaled / det must lie in (error bound, t_max].
        let sign = det & f32x4::splat(-0.0);
        let (t_signed, det_abs) = (t_scaled ^ sign, det ^ sign);
        let in_range = inside
            & !det.simd_eq(zero)
            & t_signed.simd_gt(zero)
            & t_signed.simd_le(f32x4::splat(t_max) * det_abs);
        if in_range.to_bitmask() == 0 {
            return None;
        }
        // Only now the bound on t's rounding error (t_error_bound, lane by lane).
        let bound = {
            let max3 = |a: f32x4, b: f32x4, c: f32x4| a.abs().fast_max(b.abs()).fast_max(c.abs());
            let (max_x, max_y) = (max3(ax, bx, cx), max3(ay, by, cy));
            let max_z = max3(sz * az, sz * bz, sz * cz);
            let max_e = max3(u, v, w);
            let g = |n: f32| f32x4::splat(gamma(n));
            let delta_x = g(5.0) * (max_x + max_z);
            let delta_y = g(5.0) * (max_y + max_z);
            let delta_z = g(3.0) * max_z;
            let delta_e = f32x4::splat(2.0) * (g(2.0) * max_x * max_y + delta_y * max_x + delta_x * max_y);
            f32x4::splat(3.0) * (g(3.0) * max_e * max_z + delta_e * max_z + delta_z * max_e)
        };
        let valid = in_range & t_signed.simd_gt(bound);
        let mask = valid.to_bitmask();
        if mask == 0 {
            return None;
        }
        // t, u, v as the scalar test computes them: through the reciprocal of det.
        let inv = f32x4::splat(1.0) / det;
        Some((mask, (t_scaled * inv).to_array(), inv.to_array(), v.to_array(), w.to_array()))
    }
}

impl Bvh8 {
    /// Closest hit along `ray`, with the slab test this CPU runs best.
    pub fn intersect(&self, ray: &Ray, filter: Filter) -> Option<Hit> {
        // Each stack size its own function: one frame holding both stacks (4.6 KB) took a
        // stack probe at every ray.
        if self.shallow() {
            self.intersect_on::<SHORT_STACK>(ray, filter)
        } else {
            self.intersect_on::<STACK>(ray, filter)
        }
    }

    /// [`Self::intersect`] on a stack of `N` entries.
    fn intersect_on<const N: usize>(&self, ray: &Ray, filter: Filter) -> Option<Hit> {
        match self.isa {
            Isa::Portable => self.intersect_with::<Portable, N>(ray, filter, Portable),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(k) => k.intersect::<N>(self, ray, filter),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(k) => k.intersect::<N>(self, ray, filter),
        }
    }

    /// Whether [`SHORT_STACK`] holds every entry a traversal of this tree can push.
    #[inline(always)]
    fn shallow(&self) -> bool {
        (WIDTH - 1) * self.depth < SHORT_STACK
    }

    /// Whether anything lies along `ray` within [0, t_max]; stops at the first hit.
    pub fn occluded(&self, ray: &Ray, filter: Filter) -> bool {
        if self.shallow() {
            self.occluded_on::<SHORT_STACK>(ray, filter)
        } else {
            self.occluded_on::<STACK>(ray, filter)
        }
    }

    /// [`Self::occluded`] on a stack of `N` entries.
    fn occluded_on<const N: usize>(&self, ray: &Ray, filter: Filter) -> bool {
        match self.isa {
            Isa::Portable => self.occluded_with::<Portable, N>(ray, filter, Portable),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(k) => k.occluded::<N>(self, ray, filter),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(k) => k.occluded::<N>(self, ray, filter),
        }
    }

    /// Closest hit along `ray`, ordered: the children a node's box test passes are visited
    /// nearest first, and entries the closest hit so far has passed are skipped when popped.
    /// On a stack of `N` entries, which the caller has checked is enough ([`Self::shallow`]).
    #[inline(always)]
    pub(super) fn intersect_with<K: BoxTest, const N: usize>(
        &self,
        ray: &Ray,
        filter: Filter,
        k: K,
    ) -> Option<Hit> {
        if self.quads {
            self.intersect_in::<K, N, Quad4>(ray, filter, k)
        } else {
            self.intersect_in::<K, N, Tri4>(ray, filter, k)
        }
    }

    /// [`Self::intersect_with`] on a tree of leaf blocks `B`.
    #[inline(always)]
    fn intersect_in<K: BoxTest, const N: usize, B: Block>(
        &self,
        ray: &Ray,
        filter: Filter,
        k: K,
    ) -> Option<Hit> {
        if self.root == Child::EMPTY {
            return None;
        }
        let rb = RayBox8::new(ray);
        let rt = RayTri4::new(ray);
        let mut best: Option<Hit> = None;
        let mut t_max = ray.t_max;
        // Not initialised: a ray sets up no more of its stack than it uses.
        let mut stack = ArrayVec::<Entry, N>::new();
        let mut current = Entry { child: self.root, t: 0.0 };
        loop {
            let child = current.child;
            if child.is_leaf() {
                let blocks = self.blocks::<B>(child);
                for leaf in blocks {
                    let head = leaf.head();
                    let hit = if head.cut == 0 {
                        rt.hit(leaf, t_max)
                    } else {
                        rt.hit_kept(leaf, t_max, |l, tri, u, v| {
                            filter.keeps(head.shape[l], head.prim[l] + tri, u, v)
                        })
                    };
                    if let Some((t, lane, u, v, tri)) = hit {
                        t_max = t;
                        best = Some(Hit { t, shape: head.shape[lane], prim: head.prim[lane] + tri, u, v });
                    }
                }
                for s in self.leaf_spheres(blocks[0].head()) {
                    if let Some(t) = sphere(ray, s.center, s.radius, t_max) {
                        t_max = t;
                        best = Some(Hit { t, shape: s.shape, prim: 0, u: 0.0, v: 0.0 });
                    }
                }
            } else {
                let node = self.node(child);
                // Empty slots hold inverted boxes, so the mask never names them.
                let (t_near, mut mask) = k.hit(&rb, node, t_max);
                if mask != 0 {
                    let slot = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let first = Entry { child: node.children[slot], t: t_near[slot] };
                    if mask == 0 {
                        // One child: visit it, the stack untouched.
                        current = first;
                        continue;
                    }
                    // Several: push them ordered by decreasing entry distance (insertion into
                    // the top of the stack), then pop the nearest.
                    let base = stack.len();
                    self.prefetch::<K, B>(k, first.child);
                    stack.push(first);
                    while mask != 0 {
                        let slot = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let e = Entry { child: node.children[slot], t: t_near[slot] };
                        self.prefetch::<K, B>(k, e.child);
                        stack.push(e);
                        let s = stack.as_mut_slice();
                        let mut j = s.len() - 1;
                        while j > base && s[j - 1].t < e.t {
                            s[j] = s[j - 1];
                            j -= 1;
                        }
                        s[j] = e;
                    }
                    current = stack.pop().unwrap_or(first);
                    continue;
                }
            }
            // Pop the next entry that the closest hit so far has not ruled out.
            loop {
                let Some(e) = stack.pop() else { return best };
                if e.t <= t_max * FAR_SCALE {
                    current = e;
                    break;
                }
            }
        }
    }

    /// Hints the CPU to load `child`'s node or leaf.
    #[inline(always)]
    fn prefetch<K: BoxTest, B: Block>(&self, k: K, child: Child) {
        if child.is_leaf() {
            for leaf in self.blocks::<B>(child) {
                k.prefetch(leaf);
            }
        } else {
            k.prefetch(self.node(child));
        }
    }

    /// Whether anything lies along `ray` within [0, t_max], in any order.
    /// On a stack of `N` entries, which the caller has checked is enough ([`Self::shallow`]).
    #[inline(always)]
    pub(super) fn occluded_with<K: BoxTest, const N: usize>(&self, ray: &Ray, filter: Filter, k: K) -> bool {
        if self.quads {
            self.occluded_in::<K, N, Quad4>(ray, filter, k)
        } else {
            self.occluded_in::<K, N, Tri4>(ray, filter, k)
        }
    }

    /// [`Self::occluded_with`] on a tree of leaf blocks `B`.
    #[inline(always)]
    fn occluded_in<K: BoxTest, const N: usize, B: Block>(&self, ray: &Ray, filter: Filter, k: K) -> bool {
        if self.root == Child::EMPTY {
            return false;
        }
        let rb = RayBox8::new(ray);
        let rt = RayTri4::new(ray);
        let mut stack = ArrayVec::<Child, N>::new();
        let mut current = self.root;
        loop {
            if current.is_leaf() {
                let blocks = self.blocks::<B>(current);
                let blocked = |leaf: &B| match leaf.head().cut {
                    0 => rt.hit(leaf, ray.t_max).is_some(),
                    _ => rt
                        .hit_kept(leaf, ray.t_max, |l, tri, u, v| {
                            filter.keeps(leaf.head().shape[l], leaf.head().prim[l] + tri, u, v)
                        })
                        .is_some(),
                };
                if blocks.iter().any(blocked) {
                    return true;
                }
                if self
                    .leaf_spheres(blocks[0].head())
                    .iter()
                    .any(|s| sphere(ray, s.center, s.radius, ray.t_max).is_some())
                {
                    return true;
                }
            } else {
                let node = self.node(current);
                let (_, mut mask) = k.hit(&rb, node, ray.t_max);
                while mask != 0 {
                    let slot = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    stack.push(node.children[slot]);
                    self.prefetch::<K, B>(k, node.children[slot]);
                }
            }
            let Some(next) = stack.pop() else { return false };
            current = next;
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    /// A block of two quads, the unit square at z = 0 and the same square at z = -1, each split
    /// along its diagonal from (0, 0) to (1, 1) and stored rotated: a ray down through a point
    /// of the square hits the first quad's triangle on that side, and a cut-out's verdict is
    /// asked of that triangle, the nearest first, then of the next hit below.
    #[test]
    fn a_quad_lane_reports_each_triangle_and_asks_about_each() {
        let square = |z: f32| {
            let p = [
                Vec3::new(0.0, 0.0, z),
                Vec3::new(1.0, 0.0, z),
                Vec3::new(1.0, 1.0, z),
                Vec3::new(0.0, 1.0, z),
            ];
            // The first triangle starts at its second vertex, the second at its third.
            Prim::quad([p[1], p[2], p[0]], [p[3], p[0], p[2]], 7, 10).expect("pairs")
        };
        let prims = [square(0.0), square(-1.0)];
        let mut blocks = [Quad4::EMPTY];
        assert_eq!(pack(&mut blocks, prims.iter()), (1, 0));
        let block = &blocks[0];
        assert_eq!((block.head.quads, block.head.triangles), (0b11, 4));
        let down =
            |x: f32, y: f32| Ray { origin: Vec3::new(x, y, 1.0), dir: Vec3::NEG_Z, t_max: f32::INFINITY };
        let scalar = |ray: &Ray, tri: usize| {
            let Prim::Quad { v, rot, .. } = prims[0] else { unreachable!("a quad") };
            RayTri::new(ray).hit(&Prim::quad_triangles(&v, rot)[tri], f32::INFINITY)
        };
        for (x, y, tri) in [(0.7, 0.3, 0u32), (0.3, 0.7, 1)] {
            let ray = down(x, y);
            let rt = RayTri4::new(&ray);
            let Some((t, lane, u, v, hit_tri)) = rt.hit(block, ray.t_max) else {
                panic!("missed at {x} {y}")
            };
            assert_eq!((lane, hit_tri), (0, tri), "at {x} {y}");
            // The scalar test on the triangle in its own vertex order, to the bit.
            let Some((st, su, sv)) = scalar(&ray, tri as usize) else { panic!("the scalar test missed") };
            assert_eq!((t.to_bits(), u.to_bits(), v.to_bits()), (st.to_bits(), su.to_bits(), sv.to_bits()));
            // No lane marked as a cut-out: nothing is asked, the nearest hit stands.
            let asked = std::cell::RefCell::new(Vec::new());
            let ask = |l, tri, _, _| {
                asked.borrow_mut().push((l, tri));
                false
            };
            assert_eq!(rt.hit_kept(block, ray.t_max, ask).map(|h| (h.0, h.1, h.4)), Some((1.0, 0, tri)));
            assert!(asked.borrow().is_empty(), "asked {:?} of a block with no cut-outs", asked.borrow());
            // The upper square a cut-out that cuts everywhere: its hit triangle is asked about,
            // and the same triangle of the square below is hit.
            let mut cut = *block;
            cut.head.cut = 0b01;
            let kept = rt.hit_kept(&cut, ray.t_max, ask);
            assert_eq!(kept.map(|h| (h.0, h.1, h.4)), Some((2.0, 1, tri)), "at {x} {y}");
            assert_eq!(*asked.borrow(), [(0, tri)], "at {x} {y}");
        }
    }
}
