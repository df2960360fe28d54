//! Path guiding: the learned incident radiance of Müller, Gross and Novák, "Practical Path
//! Guiding for Efficient Light-Transport Simulation" (2017), an SD-tree. A binary tree over the
//! scene's bounding cube (split at midpoints along x, y, z in turn) holds in each leaf a
//! quadtree over directions; a guide samples directions at a point in proportion to the
//! incident radiance recorded near it, and gives the density of any direction.
//!
//! Directions are points of the unit square under the cylindrical equal-area map (cos theta =
//! 2u - 1, phi = 2 pi v): a cell's share of the square is its share of the sphere, so a
//! quadtree leaf of depth `d` holding the fraction `f` of its tree's energy has the density
//! `f * 4^d / (4 pi)` over solid angle. A quadtree with no energy is uniform.
//!
//! A guide is learned in iterations (the paper's sections 3.3 and 3.4). Iteration `k` renders
//! with guide `k` and turns its path vertices into [`RadianceRecord`]s (the integrator's `GuidePath`
//! follows a path for that); [`Guide::train`] makes guide `k + 1` from them:
//! - a spatial leaf that received more than `c * sqrt(2^k)` records is split, and its halves
//!   again while theirs exceed it; the records falling in each half are counted, where Müller
//!   halves the parent's count;
//! - each new leaf's quadtree is the refinement of the quadtree of guide `k` over the same
//!   region: a node holding more than `rho` of that tree's energy is subdivided (recursively,
//!   to depth 20), one holding less becomes a leaf;
//! - the new quadtrees' energies are the records of iteration `k` alone. The structure comes
//!   from the previous iteration and the estimates from this one, so a cell is never refined
//!   on the same noisy values that then fill it (which would put a lone outlier's energy into
//!   a tiny cell of huge density).
//!
//! Records are spread over a box the size of their leaf ([`SpatialFilter::Box`], from Müller's
//! implementation, by default), which smooths the estimates across leaf borders and gives a
//! leaf that saw few records its neighbours' light; [`GuideOptions::default`] has the
//! measurements.
//!
//! Training is deterministic: one thread takes the records in the order given, sums in `f64`,
//! and decides the structure from integer counts and IEEE arithmetic alone, so the same records
//! in the same order (say, tile by tile) give the same guide, byte for byte, however many
//! threads rendered them. A render trains
//! once and writes the guide ([`Guide::to_bytes`]); every part of a split render reads the
//! same file ([`Guide::from_bytes`], which validates all of it), and samples the same
//! directions. (The direction map uses the platform's `atan2`, so the bytes are the same on one
//! platform; a file read elsewhere still samples and evaluates consistently.)
//!
//! A guide's density is zero in cells where no energy was recorded: combine it with BSDF
//! sampling (Müller samples either with probability 1/2 and weights by the mixture's density),
//! never use it alone.

use glam::{Vec2, Vec3};
use std::f32::consts::{PI, TAU};

/// The density of a uniform direction, 1 / (4 pi).
const UNIFORM: f32 = 1.0 / (4.0 * PI);

/// The largest `f32` below one.
const BELOW_ONE: f32 = 1.0 - f32::EPSILON / 2.0;

/// How far from a quadtree cell's border (in the square) a sampled point surely maps back
/// into its cell through a direction: 2^-18, twenty times the rounding of the round trip.
const ROUND_TRIP: f32 = 1.0 / (1u32 << 18) as f32;

/// The largest `f64` below one.
const BELOW_ONE_F64: f64 = 1.0 - f64::EPSILON / 2.0;

/// The deepest a directional quadtree may go (Müller's limit): a cell's side is then 2^-20 of
/// the square's, and cell corners stay exact in `f32`.
pub const MAX_DIRECTIONAL_DEPTH: u32 = 20;

/// The deepest the spatial tree may go: 20 halvings along each axis, a millionth of the bounds'
/// side, about the resolution of `f32` positions. It stops the runaway splitting of many
/// records piled on one point.
pub const MAX_SPATIAL_DEPTH: u32 = 60;

/// The file's first eight bytes.
const MAGIC: [u8; 8] = *b"LSGUIDE\0";

/// The file format's version; a reader refuses any other.
const VERSION: u32 = 1;

/// The bytes before the nodes: magic, version, the options (4 words), the iteration, the
/// bounds (4 words) and the two node counts.
const HEADER: usize = 8 + 4 * 12;

/// One training sample: an estimate of the radiance arriving at `position` along `direction`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RadianceRecord {
    /// Where the radiance arrives (a path vertex).
    pub position: Vec3,
    /// The direction toward where the light comes from (the direction the path continued in),
    /// unit length (it is normalised; a zero or non-finite one drops the record).
    pub direction: Vec3,
    /// The estimate of the incident radiance along `direction` (a scalar, e.g. its luminance)
    /// divided by the density `direction` was sampled with: what the direction's cell gets.
    /// Zero: a sample that found no light, counted toward splitting but adding nothing.
    /// Negative or not finite: the record is dropped.
    pub value: f32,
}

impl RadianceRecord {
    /// A record of `value` arriving at `position` along `direction`.
    pub fn new(position: Vec3, direction: Vec3, value: f32) -> Self {
        RadianceRecord { position, direction, value }
    }

    /// The record's unit direction, or `None` when the record is to be dropped (a position,
    /// direction or value that is not finite, a zero direction, a negative value).
    fn direction(&self) -> Option<Vec3> {
        if !self.position.is_finite() || !self.value.is_finite() || self.value < 0.0 {
            return None;
        }
        self.direction.try_normalize()
    }
}

/// How a record's value is spread over the spatial leaves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpatialFilter {
    /// All of it to the leaf containing the record (the paper).
    Nearest,
    /// Over a box the size of that leaf centred on the record: each leaf the box overlaps gets
    /// the overlapped fraction of the box's volume (Müller's implementation, `spatialFilter =
    /// box`); the part outside the bounds is lost. Deterministic; a record reaches about 8
    /// leaves, so training takes about 6 times as long (2.3 against 0.4 microseconds a
    /// record, on a 2-core VM sharing its cores with a build).
    Box,
}

/// The training parameters, kept in the guide (and its file) so that every iteration uses the
/// same.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuideOptions {
    /// Müller's `c`: in iteration `k` a spatial leaf with more than `c * sqrt(2^k)` records is
    /// split. At least 1.
    pub split_records: f32,
    /// Müller's `rho`: a quadtree node holding more than this fraction of its tree's energy is
    /// subdivided. In [1e-4, 1].
    pub subdivide_fraction: f32,
    /// The deepest a quadtree may go, 1 to [`MAX_DIRECTIONAL_DEPTH`].
    pub max_depth: u32,
    /// How records are spread over the spatial leaves.
    pub filter: SpatialFilter,
}

impl Default for GuideOptions {
    /// `c` = 4,000, `rho` = 0.01, depth 20 and the box filter. `rho` and the depth are
    /// Müller's; his `c`, 12,000, is for budgets doubling up to hundreds of samples a pixel,
    /// and a smaller one keeps some spatial resolution on the few samples a pixel a training
    /// pass affords (a leaf then holds 2,000 to 4,000 records over the 100 to 400 cells `rho`
    /// allows). Measured on a sky whose bright lobe turns with the position, after 4
    /// iterations, by the relative second moment of the one-sample estimator mixing the
    /// guide and uniform sampling half and half (uniform sampling alone: 50):
    ///
    /// | records an iteration | box, c = 1,000 / 4,000 / 12,000 | nearest, the same |
    /// |---|---|---|
    /// | 50,000    | 29.7 / 17.3 / 19.8 | 58.6 / 29.3 / 28.4 |
    /// | 200,000   | 12.3 / 10.3 / 8.2  | 47.1 / 22.2 / 13.4 |
    /// | 1,000,000 | 6.4 / 5.0 / 5.2    | 38.2 / 13.6 / 8.5  |
    ///
    /// Without the filter a leaf's few records make a noisy distribution (at 50,000 records
    /// and `c` = 1,000, worse than none); with it `c` matters less.
    fn default() -> Self {
        GuideOptions {
            split_records: 4000.0,
            subdivide_fraction: 0.01,
            max_depth: MAX_DIRECTIONAL_DEPTH,
            filter: SpatialFilter::Box,
        }
    }
}

impl GuideOptions {
    /// An error naming the first parameter out of its range.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.split_records.is_finite() && self.split_records >= 1.0) {
            return Err(format!("guide: split_records {} is not a number of at least 1", self.split_records));
        }
        if !(self.subdivide_fraction >= 1e-4 && self.subdivide_fraction <= 1.0) {
            return Err(format!("guide: subdivide_fraction {} is not in [1e-4, 1]", self.subdivide_fraction));
        }
        if !(1..=MAX_DIRECTIONAL_DEPTH).contains(&self.max_depth) {
            return Err(format!("guide: max_depth {} is not in 1..={MAX_DIRECTIONAL_DEPTH}", self.max_depth));
        }
        Ok(())
    }
}

/// A node of the spatial tree: an inner node's children are `child` and `child + 1` (the
/// lower and upper half along its axis); a leaf (`child` 0) has its quadtree's root at `quad`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct SpatialNode {
    child: u32,
    quad: u32,
}

/// A node of a quadtree: its energy (the sum of its children's, in `f32`, in order) and, for
/// an inner node, its four children at `child..child + 4`, child `ix + 2 iy` covering the half
/// `ix` along u and `iy` along v. A leaf has `child` 0 (no node is anyone's child at 0).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct QuadNode {
    energy: f32,
    child: u32,
}

/// A box of the spatial tree in the cube's normalised coordinates: dyadic, so its corners and
/// midpoints are exact and its tests agree with [`Guide::locate`]'s.
#[derive(Clone, Copy, Debug)]
struct Cell {
    lo: [f32; 3],
    size: [f32; 3],
}

impl Cell {
    /// The whole cube.
    const ROOT: Cell = Cell { lo: [0.0; 3], size: [1.0; 3] };

    /// The splitting plane along `axis`.
    #[inline]
    fn mid(&self, axis: usize) -> f32 {
        self.lo[axis] + 0.5 * self.size[axis]
    }

    /// Whether the normalised point `q` lies in the upper half along `axis`.
    #[inline]
    fn upper(&self, q: Vec3, axis: usize) -> bool {
        q[axis] >= self.mid(axis)
    }

    /// The lower or upper half along `axis`.
    #[inline]
    fn half(&self, axis: usize, upper: bool) -> Cell {
        let mut c = *self;
        if upper {
            c.lo[axis] = self.mid(axis);
        }
        c.size[axis] *= 0.5;
        c
    }

    /// The volume of the overlap with the box `lo..hi`.
    fn overlap(&self, lo: [f64; 3], hi: [f64; 3]) -> f64 {
        let mut v = 1.0;
        for a in 0..3 {
            let l = (self.lo[a] as f64).max(lo[a]);
            let h = (self.lo[a] as f64 + self.size[a] as f64).min(hi[a]);
            v *= (h - l).max(0.0);
        }
        v
    }
}

/// The learned distribution of incident radiance over a scene's bounds: an SD-tree.
#[derive(Clone, Debug, PartialEq)]
pub struct Guide {
    options: GuideOptions,
    /// How many times training made this guide from [`Guide::new`]'s.
    iteration: u32,
    /// The bounding cube: `min` to `max` = `min + size`.
    min: Vec3,
    size: f32,
    max: Vec3,
    spatial: Vec<SpatialNode>,
    /// All the quadtrees, each contiguous, in the order of their spatial leaves.
    quads: Vec<QuadNode>,
}

/// The directional distribution of one spatial leaf, found once for a point and then sampled
/// or evaluated many times (a guided vertex samples a direction and evaluates another's
/// density).
#[derive(Clone, Copy, Debug)]
pub struct Directions<'a> {
    nodes: &'a [QuadNode],
    root: usize,
}

impl Guide {
    /// An untrained guide over the box `bounds_min..bounds_max`, with the default options: it
    /// samples uniformly everywhere.
    pub fn new(bounds_min: Vec3, bounds_max: Vec3) -> Guide {
        let (min, size) = cube(bounds_min, bounds_max);
        Guide {
            options: GuideOptions::default(),
            iteration: 0,
            min,
            size,
            max: min + Vec3::splat(size),
            spatial: vec![SpatialNode::default()],
            quads: vec![QuadNode::default()],
        }
    }

    /// [`Guide::new`] with other options; an error if they are out of range.
    pub fn with_options(bounds_min: Vec3, bounds_max: Vec3, options: GuideOptions) -> Result<Guide, String> {
        options.validate()?;
        Ok(Guide { options, ..Guide::new(bounds_min, bounds_max) })
    }

    /// The training parameters.
    pub fn options(&self) -> &GuideOptions {
        &self.options
    }

    /// How many training iterations made this guide (0 for [`Guide::new`]'s).
    pub fn iteration(&self) -> u32 {
        self.iteration
    }

    /// The bounding cube's corners: the bounds given to [`Guide::new`], their longest side
    /// made the cube's (Müller: cubes split into better-shaped cells).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.min, self.max)
    }

    /// The number of spatial leaves.
    pub fn leaves(&self) -> usize {
        self.spatial.iter().filter(|n| n.child == 0).count()
    }

    /// The number of quadtree nodes over all leaves (8 bytes each).
    pub fn directional_nodes(&self) -> usize {
        self.quads.len()
    }

    /// `p` in the bounding cube's coordinates, in [0, 1)^3 (clamped; NaN to 0). The spatial
    /// tree lives in these: its cells are dyadic boxes, which every descent finds exactly.
    #[inline]
    fn normalise(&self, p: Vec3) -> Vec3 {
        ((p - self.min) / self.size).max(Vec3::ZERO).min(Vec3::splat(BELOW_ONE))
    }

    /// The leaf containing the normalised point `q`, and its depth. Each level doubles one
    /// coordinate (x, y, z in turn) and drops its integer part, exactly, so the leaf found is
    /// the one whose dyadic box contains `q`.
    #[inline]
    fn locate(&self, q: Vec3) -> (usize, u32) {
        let mut t = q.to_array();
        let (mut i, mut depth) = (0usize, 0u32);
        loop {
            for c in &mut t {
                let n = self.spatial[i];
                if n.child == 0 {
                    return (i, depth);
                }
                let upper = *c >= 0.5;
                *c = 2.0 * *c - upper as u32 as f32;
                i = n.child as usize + upper as usize;
                depth += 1;
            }
        }
    }

    /// The directional distribution at `p` (clamped to the bounds).
    #[inline]
    pub fn at(&self, p: Vec3) -> Directions<'_> {
        self.at_leaf(self.locate(self.normalise(p)).0)
    }

    /// A direction at `p` for the uniform numbers `u` in [0, 1)^2, and its density over solid
    /// angle: the density of the cell sampled, positive, and the very number [`Guide::pdf`]
    /// gives for the direction.
    #[inline]
    pub fn sample(&self, p: Vec3, u: Vec2) -> (Vec3, f32) {
        self.at(p).sample(u)
    }

    /// The density over solid angle of the unit direction `dir` at `p`.
    #[inline]
    pub fn pdf(&self, p: Vec3, dir: Vec3) -> f32 {
        self.at(p).pdf(dir)
    }

    /// The next guide, from one iteration's records in the order given (see the module's
    /// documentation). One thread; besides the two guides, 12 bytes a record and 8 a quadtree
    /// node of scratch.
    pub fn train(&self, records: &[RadianceRecord]) -> Guide {
        // 1. The spatial tree: the old one, its leaves split by the records they received
        // (their normalised positions, 12 bytes a record, partitioned in place).
        let mut points: Vec<Vec3> =
            records.iter().filter(|r| r.direction().is_some()).map(|r| self.normalise(r.position)).collect();
        let c = self.options.split_records as f64;
        let mut split = Split {
            old: self,
            threshold_sq: c * c * 2f64.powi(self.iteration.min(1000) as i32),
            spatial: vec![SpatialNode::default()],
            leaves: Vec::new(),
        };
        split.build(0, 0, Cell::ROOT, 0, &mut points);
        drop(points);
        let Split { mut spatial, leaves, .. } = split;

        // 2. Each new leaf's quadtree: the refinement of its region's old one.
        let rho = self.options.subdivide_fraction as f64;
        let mut quads = Vec::new();
        let mut roots = Vec::with_capacity(leaves.len() + 1);
        for &(node, old_root) in &leaves {
            let root = refine(&self.quads, old_root as usize, rho, self.options.max_depth, &mut quads);
            spatial[node as usize].quad = root as u32;
            roots.push(root);
        }
        roots.push(quads.len());
        let mut next = Guide {
            options: self.options,
            iteration: self.iteration.saturating_add(1),
            spatial,
            quads,
            ..*self
        };

        // 3. The energies: this iteration's records, in order.
        let mut sums = vec![0.0f64; next.quads.len()];
        let mut stack = Vec::new();
        for r in records {
            let Some(d) = r.direction() else { continue };
            if r.value <= 0.0 {
                continue;
            }
            let s = to_square(d);
            let q = next.normalise(r.position);
            let (leaf, depth) = next.locate(q);
            match self.options.filter {
                SpatialFilter::Nearest => {
                    let k = next.at_leaf(leaf).find(s).0;
                    sums[k] += r.value as f64;
                }
                SpatialFilter::Box => next.splat_box(q, depth, s, r.value as f64, &mut sums, &mut stack),
            }
        }

        // 4. Each quadtree normalised (its leaves' fractions of its total), its inner nodes
        // the sums of their children.
        for w in roots.windows(2) {
            let range = w[0]..w[1];
            let total: f64 = range.clone().filter(|&i| next.quads[i].child == 0).map(|i| sums[i]).sum();
            for i in range.rev() {
                let child = next.quads[i].child as usize;
                next.quads[i].energy = if child == 0 {
                    if total > 0.0 {
                        (sums[i] / total) as f32
                    } else {
                        0.0
                    }
                } else {
                    let e = |k: usize| next.quads[child + k].energy;
                    e(0) + e(1) + e(2) + e(3)
                };
            }
        }
        next
    }

    /// The directional distribution of spatial leaf `leaf`.
    #[inline]
    fn at_leaf(&self, leaf: usize) -> Directions<'_> {
        Directions { nodes: &self.quads, root: self.spatial[leaf].quad as usize }
    }

    /// Adds `value` at the square point `s` to every leaf overlapping a box the size of a
    /// leaf of depth `depth` centred on the normalised point `q`, in proportion to the overlap.
    fn splat_box(
        &self,
        q: Vec3,
        depth: u32,
        s: Vec2,
        value: f64,
        sums: &mut [f64],
        stack: &mut Vec<(usize, Cell, usize)>,
    ) {
        let (mut lo, mut hi, mut volume) = ([0.0f64; 3], [0.0f64; 3], 1.0f64);
        for a in 0..3 {
            // The leaf's side along axis a: halved at depths a, a + 3, a + 6...
            let side = 1.0 / (1u64 << ((depth as usize + 2 - a) / 3)) as f64;
            lo[a] = q[a] as f64 - 0.5 * side;
            hi[a] = q[a] as f64 + 0.5 * side;
            volume *= side;
        }
        stack.clear();
        stack.push((0, Cell::ROOT, 0));
        while let Some((i, c, axis)) = stack.pop() {
            let overlap = c.overlap(lo, hi);
            if overlap <= 0.0 {
                continue;
            }
            let n = self.spatial[i];
            if n.child == 0 {
                let k = self.at_leaf(i).find(s).0;
                sums[k] += value * (overlap / volume);
            } else {
                let next_axis = if axis == 2 { 0 } else { axis + 1 };
                stack.push((n.child as usize + 1, c.half(axis, true), next_axis));
                stack.push((n.child as usize, c.half(axis, false), next_axis));
            }
        }
    }

    /// The guide as bytes: a magic number and version, the options, the iteration, the
    /// bounds, the nodes, and an FNV-1a checksum of all before it, little-endian.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(HEADER + 8 * (self.spatial.len() + self.quads.len()) + 8);
        b.extend_from_slice(&MAGIC);
        let o = &self.options;
        let filter = match o.filter {
            SpatialFilter::Nearest => 0u32,
            SpatialFilter::Box => 1,
        };
        for w in [VERSION, o.split_records.to_bits(), o.subdivide_fraction.to_bits(), o.max_depth, filter] {
            b.extend_from_slice(&w.to_le_bytes());
        }
        b.extend_from_slice(&self.iteration.to_le_bytes());
        for x in [self.min.x, self.min.y, self.min.z, self.size] {
            b.extend_from_slice(&x.to_le_bytes());
        }
        b.extend_from_slice(&(self.spatial.len() as u32).to_le_bytes());
        b.extend_from_slice(&(self.quads.len() as u32).to_le_bytes());
        for n in &self.spatial {
            b.extend_from_slice(&n.child.to_le_bytes());
            b.extend_from_slice(&n.quad.to_le_bytes());
        }
        for n in &self.quads {
            b.extend_from_slice(&n.energy.to_le_bytes());
            b.extend_from_slice(&n.child.to_le_bytes());
        }
        let sum = fnv1a(&b);
        b.extend_from_slice(&sum.to_le_bytes());
        b
    }

    /// A guide written by [`Guide::to_bytes`]; an error, never a panic, on anything else (a
    /// wrong magic number, version or checksum, a wrong length, options out of range, bounds
    /// that are not finite, a node list that is not a tree, a tree too deep, energies that are
    /// negative, not finite or not their children's sums).
    pub fn from_bytes(bytes: &[u8]) -> Result<Guide, String> {
        if bytes.len() < HEADER + 8 || bytes[..8] != MAGIC {
            return Err("guide: not a guide file".into());
        }
        let (body, sum) = bytes.split_at(bytes.len() - 8);
        let mut r = Reader { bytes: body, at: 8 };
        let version = r.u32()?;
        if version != VERSION {
            return Err(format!("guide: file version {version}, this build reads {VERSION}"));
        }
        if u64::from_le_bytes(sum.try_into().map_err(|_| "guide: no checksum")?) != fnv1a(body) {
            return Err("guide: checksum mismatch (a damaged file)".into());
        }
        let options = GuideOptions {
            split_records: r.f32()?,
            subdivide_fraction: r.f32()?,
            max_depth: r.u32()?,
            filter: match r.u32()? {
                0 => SpatialFilter::Nearest,
                1 => SpatialFilter::Box,
                f => return Err(format!("guide: unknown filter {f}")),
            },
        };
        options.validate()?;
        let iteration = r.u32()?;
        let min = Vec3::new(r.f32()?, r.f32()?, r.f32()?);
        let size = r.f32()?;
        let max = min + Vec3::splat(size);
        if !(min.is_finite() && max.is_finite() && size > 0.0) {
            return Err("guide: bounds not finite or empty".into());
        }
        let (ns, nq) = (r.u32()? as usize, r.u32()? as usize);
        if ns == 0 || nq == 0 || (ns as u64 + nq as u64) * 8 != (body.len() - HEADER) as u64 {
            return Err(format!("guide: {ns} spatial and {nq} directional nodes in {} bytes", body.len()));
        }
        let mut spatial = Vec::with_capacity(ns);
        for _ in 0..ns {
            spatial.push(SpatialNode { child: r.u32()?, quad: r.u32()? });
        }
        let mut quads = Vec::with_capacity(nq);
        for _ in 0..nq {
            quads.push(QuadNode { energy: r.f32()?, child: r.u32()? });
        }
        let guide = Guide { options, iteration, min, size, max, spatial, quads };
        guide.check()?;
        Ok(guide)
    }

    /// Checks that the nodes form trees a descent can follow: each node reached once from its
    /// root, children in range, depths within the limits, energies finite, non-negative and
    /// their children's sums.
    fn check(&self) -> Result<(), String> {
        let (ns, nq) = (self.spatial.len(), self.quads.len());
        let mut seen = vec![false; ns];
        let mut roots = Vec::new();
        let mut stack = vec![(0usize, 0u32)];
        seen[0] = true;
        while let Some((i, depth)) = stack.pop() {
            let n = self.spatial[i];
            if n.child == 0 {
                roots.push(n.quad as usize);
                continue;
            }
            let c = n.child as usize;
            if depth >= MAX_SPATIAL_DEPTH || n.quad != 0 || c + 1 >= ns {
                return Err(format!("guide: spatial node {i} is malformed"));
            }
            for k in [c, c + 1] {
                if std::mem::replace(&mut seen[k], true) {
                    return Err(format!("guide: spatial node {k} has two parents"));
                }
                stack.push((k, depth + 1));
            }
        }
        if seen.contains(&false) {
            return Err("guide: unreachable spatial nodes".into());
        }
        let mut seen = vec![false; nq];
        let mut stack = Vec::new();
        for root in roots {
            if root >= nq || std::mem::replace(&mut seen[root], true) {
                return Err(format!("guide: quadtree root {root} out of range or shared"));
            }
            stack.push((root, 0u32));
            while let Some((i, depth)) = stack.pop() {
                let n = self.quads[i];
                if !(n.energy.is_finite() && n.energy >= 0.0) {
                    return Err(format!("guide: quadtree node {i} has energy {}", n.energy));
                }
                if n.child == 0 {
                    continue;
                }
                let c = n.child as usize;
                if depth >= self.options.max_depth || c + 3 >= nq {
                    return Err(format!("guide: quadtree node {i} is malformed"));
                }
                let e = |k: usize| self.quads[c + k].energy;
                if e(0) + e(1) + e(2) + e(3) != n.energy {
                    return Err(format!("guide: quadtree node {i} is not the sum of its children"));
                }
                for (k, seen) in (c..).zip(&mut seen[c..c + 4]) {
                    if std::mem::replace(seen, true) {
                        return Err(format!("guide: quadtree node {k} has two parents"));
                    }
                    stack.push((k, depth + 1));
                }
            }
        }
        if seen.contains(&false) {
            return Err("guide: unreachable quadtree nodes".into());
        }
        Ok(())
    }
}

impl Directions<'_> {
    /// Whether this distribution is uniform (no energy recorded here).
    pub fn is_uniform(&self) -> bool {
        self.nodes[self.root].energy <= 0.0
    }

    /// The density over solid angle of the unit direction `dir`.
    #[inline]
    pub fn pdf(&self, dir: Vec3) -> f32 {
        let total = self.nodes[self.root].energy;
        if total <= 0.0 {
            return UNIFORM;
        }
        let (leaf, depth) = self.find(to_square(dir));
        density(self.nodes[leaf].energy, total, depth)
    }

    /// A direction for the uniform numbers `u` in [0, 1)^2 and its density over solid angle,
    /// equal to [`Directions::pdf`] of the direction.
    ///
    /// The descent picks a child in proportion to energy (the u half by `u.x`, then the v half
    /// within it by `u.y`, each number rescaled to [0, 1) for the next level, in `f64`), then a
    /// uniform point of the leaf cell.
    #[inline]
    pub fn sample(&self, u: Vec2) -> (Vec3, f32) {
        let total = self.nodes[self.root].energy;
        let u = Vec2::new(unit(u.x), unit(u.y));
        if total <= 0.0 {
            return (from_square(u), UNIFORM);
        }
        let (mut x, mut y) = (u.x as f64, u.y as f64);
        let (mut i, mut depth, mut ox, mut oy) = (self.root, 0u32, 0u32, 0u32);
        loop {
            let n = self.nodes[i];
            if n.child == 0 {
                break;
            }
            // Every node reached has energy, so the halves chosen below do: a half with none
            // has probability 0 and a number in [0, 1) never selects it.
            let c = n.child as usize;
            let e = [0, 1, 2, 3].map(|k| self.nodes[c + k].energy as f64);
            let ix = pick(&mut x, e[0] + e[2], e[1] + e[3]);
            let iy = pick(&mut y, e[ix], e[ix + 2]);
            i = c + ix + 2 * iy;
            depth += 1;
            ox = 2 * ox + ix as u32;
            oy = 2 * oy + iy as u32;
        }
        // The leaf cell: [ox, ox + 1) x [oy, oy + 1) times 2^-depth, exact in f32.
        let side = 1.0 / (1u64 << depth) as f32;
        let lo = Vec2::new(ox as f32 * side, oy as f32 * side);
        let hi = lo + Vec2::splat(side);
        let below_hi = Vec2::new(f32::from_bits(hi.x.to_bits() - 1), f32::from_bits(hi.y.to_bits() - 1));
        let mut s = (lo + Vec2::new(x as f32, y as f32) * side).clamp(lo, below_hi);
        let density = density(self.nodes[i].energy, total, depth);
        // A direction maps back to the square within about 2e-7 (the rounding of sin, cos and
        // atan2); a point farther than ROUND_TRIP from the cell's border maps back into the
        // cell, so that pdf() of its direction finds this cell's density.
        if (s - lo).min_element() >= ROUND_TRIP && (hi - s).min_element() > ROUND_TRIP {
            return (from_square(s), density);
        }
        // Nearer, the direction may map into the next cell, which may be empty: the point
        // moves halfway to the centre until its direction maps back into the cell (a shift of
        // a fraction of a micro-cell's width, at depth 20, to keep sample and pdf one).
        let centre = lo + Vec2::splat(0.5 * side);
        let in_cell = |o: u32, t: f32| (t as f64 * (1u64 << depth) as f64).floor() == o as f64;
        for _ in 0..4 {
            let d = from_square(s);
            let back = to_square(d);
            if in_cell(ox, back.x) && in_cell(oy, back.y) {
                return (d, density);
            }
            s = (s + centre) * 0.5;
        }
        let d = from_square(s);
        (d, self.pdf(d))
    }

    /// The leaf containing the square point `s`, and its depth. The descent halves exactly
    /// (`2 s - 1` is exact for `s` in [1/2, 1)), so it finds the leaf whose dyadic cell
    /// contains `s`.
    #[inline]
    fn find(&self, s: Vec2) -> (usize, u32) {
        let (mut i, mut depth, mut x, mut y) = (self.root, 0u32, s.x, s.y);
        loop {
            let n = self.nodes[i];
            if n.child == 0 {
                return (i, depth);
            }
            let (ix, iy) = (x >= 0.5, y >= 0.5);
            x = 2.0 * x - ix as u32 as f32;
            y = 2.0 * y - iy as u32 as f32;
            i = n.child as usize + ix as usize + 2 * iy as usize;
            depth += 1;
        }
    }
}

/// Chooses between two halves of energies `a` and `b` (not both zero) with the uniform number
/// `t` in [0, 1), and rescales `t` to [0, 1) within the chosen half's interval: 0 or 1. One
/// division (the descent's cost).
#[inline]
fn pick(t: &mut f64, a: f64, b: f64) -> usize {
    let scaled = *t * (a + b);
    if scaled < a || b == 0.0 {
        *t = (scaled / a).min(BELOW_ONE_F64);
        0
    } else {
        *t = ((scaled - a) / b).clamp(0.0, BELOW_ONE_F64);
        1
    }
}

/// The density over solid angle of a quadtree leaf of depth `depth` holding `energy` of the
/// tree's `total`: its fraction over its share of the square (4^-depth), over 4 pi. Sampling
/// and evaluation both call this, so they agree to the bit.
#[inline]
fn density(energy: f32, total: f32, depth: u32) -> f32 {
    energy / total * (1u64 << (2 * depth)) as f32 * UNIFORM
}

/// The cylindrical equal-area map from the unit square to the sphere: z = 2u - 1, phi = 2 pi v.
#[inline]
fn from_square(s: Vec2) -> Vec3 {
    let z = 2.0 * s.x - 1.0;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (sin, cos) = crate::math::sin_cos_turn(s.y);
    Vec3::new(r * cos, r * sin, z)
}

/// The inverse of [`from_square`] for a unit direction, in [0, 1)^2 (a non-finite direction
/// maps to a corner).
#[inline]
fn to_square(d: Vec3) -> Vec2 {
    let u = (d.z + 1.0) * 0.5;
    let mut v = d.y.atan2(d.x) * (1.0 / TAU);
    if v < 0.0 {
        v += 1.0;
    }
    Vec2::new(unit(u), unit(v))
}

/// `t` clamped to [0, 1), NaN to 0 (`clamp` would keep it).
#[inline]
fn unit(t: f32) -> f32 {
    #[allow(clippy::manual_clamp)]
    t.max(0.0).min(BELOW_ONE)
}

/// The cube Müller's tree covers: from the bounds' lower corner, as wide as their longest side.
/// Bounds that are not finite become the unit cube at the origin (or at the finite corner), and
/// empty ones a unit-wide cube: a guide over them still samples and evaluates.
fn cube(a: Vec3, b: Vec3) -> (Vec3, f32) {
    let min = a.min(b);
    let min = if min.is_finite() { min } else { Vec3::ZERO };
    let size = (a.max(b) - min).max_element();
    let size =
        if size.is_finite() && size > 0.0 && (min + Vec3::splat(size)).is_finite() { size } else { 1.0 };
    (min, size)
}

/// The refinement of the old quadtree at `old_root` (Müller's `DTree::reset`): a node whose
/// fraction of the old tree's energy exceeds `rho` is subdivided, below `max_depth`; a node
/// the old tree did not subdivide gives its children a quarter of its fraction each. An old
/// tree without energy counts as uniform (a node of depth d holds 4^-d). The new nodes are
/// appended to `out`, energies zero; returns the new root's index.
fn refine(old: &[QuadNode], old_root: usize, rho: f64, max_depth: u32, out: &mut Vec<QuadNode>) -> usize {
    let total = old[old_root].energy as f64;
    let root = out.len();
    out.push(QuadNode::default());
    // (new node, the old node it refines if the old tree went that deep, depth, fraction)
    let mut stack = vec![(root, (total > 0.0).then_some(old_root), 0u32, 1.0f64)];
    while let Some((i, src, depth, fraction)) = stack.pop() {
        if depth >= max_depth || fraction <= rho {
            continue;
        }
        let c = out.len();
        out.extend([QuadNode::default(); 4]);
        out[i].child = c as u32;
        for q in 0..4 {
            let child = match src {
                Some(j) if old[j].child != 0 => {
                    let k = old[j].child as usize + q;
                    (Some(k), old[k].energy as f64 / total)
                }
                _ => (None, 0.25 * fraction),
            };
            stack.push((c + q, child.0, depth + 1, child.1));
        }
    }
    root
}

/// The state of the spatial split in [`Guide::train`].
struct Split<'a> {
    old: &'a Guide,
    /// A leaf splits when the square of its record count exceeds this: (c sqrt(2^k))^2,
    /// compared without a square root.
    threshold_sq: f64,
    spatial: Vec<SpatialNode>,
    /// Each new leaf's node and the root of the old quadtree over its region.
    leaves: Vec<(u32, u32)>,
}

impl Split<'_> {
    /// Makes new node `slot`, over `cell` at `depth`, from old node `old` (an old leaf when the
    /// new tree goes deeper) and the normalised positions `points` of the records falling in
    /// it (reordered in place: the counts, not the order, decide the splits).
    fn build(&mut self, slot: usize, old: usize, cell: Cell, depth: u32, points: &mut [Vec3]) {
        let o = self.old.spatial[old];
        let count = points.len() as f64;
        let split = o.child == 0 && depth < MAX_SPATIAL_DEPTH && count * count > self.threshold_sq;
        if o.child == 0 && !split {
            self.leaves.push((slot as u32, o.quad));
            return;
        }
        let axis = (depth % 3) as usize;
        let mut lower = 0;
        for k in 0..points.len() {
            if !cell.upper(points[k], axis) {
                points.swap(k, lower);
                lower += 1;
            }
        }
        let first = self.spatial.len();
        self.spatial.extend([SpatialNode::default(); 2]);
        self.spatial[slot].child = first as u32;
        let (a, b) = if split { (old, old) } else { (o.child as usize, o.child as usize + 1) };
        let (lo, hi) = points.split_at_mut(lower);
        self.build(first, a, cell.half(axis, false), depth + 1, lo);
        self.build(first + 1, b, cell.half(axis, true), depth + 1, hi);
    }
}

/// Reads little-endian words from a guide file.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn u32(&mut self) -> Result<u32, String> {
        let w = self.bytes.get(self.at..self.at + 4).ok_or("guide: file truncated")?;
        self.at += 4;
        Ok(u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
    }

    fn f32(&mut self) -> Result<f32, String> {
        self.u32().map(f32::from_bits)
    }
}

/// FNV-1a, 64 bits: the file's checksum.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// PCG32 (O'Neill 2014): the tests' random numbers, seeded, so the tests are repeatable.
    struct Rng {
        state: u64,
        inc: u64,
    }

    impl Rng {
        fn new(seed: u64) -> Rng {
            let mut r = Rng { state: 0, inc: (seed << 1) | 1 };
            r.next_u32();
            r.state = r.state.wrapping_add(0x853c_49e6_748f_ea9b ^ seed);
            r.next_u32();
            r
        }

        fn next_u32(&mut self) -> u32 {
            let old = self.state;
            self.state = old.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(self.inc);
            ((((old >> 18) ^ old) >> 27) as u32).rotate_right((old >> 59) as u32)
        }

        fn next_1d(&mut self) -> f32 {
            (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
        }

        fn next_2d(&mut self) -> Vec2 {
            Vec2::new(self.next_1d(), self.next_1d())
        }

        fn point(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
            lo + (hi - lo) * Vec3::new(self.next_1d(), self.next_1d(), self.next_1d())
        }
    }

    use crate::math::chi_square::z_score;

    fn uniform_sphere(u: Vec2) -> Vec3 {
        from_square(u)
    }

    const UNIT: (Vec3, Vec3) = (Vec3::ZERO, Vec3::ONE);

    fn lobe_a() -> Vec3 {
        Vec3::new(0.3, 0.5, 0.8).normalize()
    }

    fn lobe_b() -> Vec3 {
        Vec3::new(-0.7, -0.2, -0.3).normalize()
    }

    /// A sky of two lobes over a floor: 40 more within 15 degrees of `a`, 15 more within 25
    /// degrees of lobe B, 1 everywhere.
    fn two_lobes(a: Vec3) -> impl Fn(Vec3, Vec3) -> f32 {
        let (ca, cb) = (15f32.to_radians().cos(), 25f32.to_radians().cos());
        move |_, d| {
            1.0 + if d.dot(a) > ca { 40.0 } else { 0.0 } + if d.dot(lobe_b()) > cb { 15.0 } else { 0.0 }
        }
    }

    /// One iteration's records: `n` points from `at`, each direction uniform or from `guide`
    /// with probability 1/2 (the mixture a guided render samples), its value the radiance over
    /// the mixture's density.
    fn records(
        guide: &Guide,
        n: usize,
        rng: &mut Rng,
        at: &impl Fn(&mut Rng) -> Vec3,
        radiance: &impl Fn(Vec3, Vec3) -> f32,
    ) -> Vec<RadianceRecord> {
        (0..n)
            .map(|_| {
                let p = at(rng);
                let (pick, u) = (rng.next_1d(), rng.next_2d());
                let d = if pick < 0.5 { uniform_sphere(u) } else { guide.sample(p, u).0 };
                let pdf = 0.5 * UNIFORM + 0.5 * guide.pdf(p, d);
                RadianceRecord::new(p, d, radiance(p, d) / pdf)
            })
            .collect()
    }

    /// `iterations` trainings of `guide` on `n` records each.
    fn train(
        mut guide: Guide,
        iterations: u32,
        n: usize,
        seed: u64,
        at: impl Fn(&mut Rng) -> Vec3,
        radiance: impl Fn(Vec3, Vec3) -> f32,
    ) -> Guide {
        let mut rng = Rng::new(seed);
        for _ in 0..iterations {
            guide = guide.train(&records(&guide, n, &mut rng, &at, &radiance));
        }
        guide
    }

    /// The two-lobe sky learned over the unit cube.
    fn lobe_guide(a: Vec3, seed: u64) -> Guide {
        train(Guide::new(UNIT.0, UNIT.1), 3, 50_000, seed, |r| r.point(UNIT.0, UNIT.1), two_lobes(a))
    }

    /// A guide whose every record comes from one direction (with a few uniform ones): its
    /// quadtrees reach depth 20.
    fn spike_guide() -> Guide {
        let d = Vec3::new(0.2, -0.4, 0.5).normalize();
        let mut guide = Guide::new(UNIT.0, UNIT.1);
        let mut rng = Rng::new(5);
        // Each iteration refines the spike's cell four levels deeper (rho = 0.01 < 4^-3).
        for _ in 0..5 {
            let records: Vec<_> = (0..20_000)
                .map(|i| {
                    let p = rng.point(UNIT.0, UNIT.1);
                    let dir = if i % 50 == 0 { uniform_sphere(rng.next_2d()) } else { d };
                    RadianceRecord::new(p, dir, 1.0)
                })
                .collect();
            guide = guide.train(&records);
        }
        guide
    }

    impl Guide {
        /// The depth of the deepest quadtree leaf.
        fn max_quad_depth(&self) -> u32 {
            let mut stack: Vec<_> =
                self.spatial.iter().filter(|n| n.child == 0).map(|n| (n.quad as usize, 0)).collect();
            let mut deepest = 0;
            while let Some((i, d)) = stack.pop() {
                deepest = deepest.max(d);
                let c = self.quads[i].child as usize;
                if c != 0 {
                    stack.extend((c..c + 4).map(|k| (k, d + 1)));
                }
            }
            deepest
        }

        /// The depth of the spatial leaf containing `p`.
        fn leaf_depth(&self, p: Vec3) -> u32 {
            self.locate(self.normalise(p)).1
        }

        /// For each spatial leaf with energy: its leaves' densities times their solid angles,
        /// summed (1 for a normalised distribution).
        fn leaf_masses(&self) -> Vec<f64> {
            let mut masses = Vec::new();
            for n in self.spatial.iter().filter(|n| n.child == 0) {
                let total = self.quads[n.quad as usize].energy;
                if total <= 0.0 {
                    continue;
                }
                let (mut mass, mut stack) = (0.0f64, vec![(n.quad as usize, 0u32)]);
                while let Some((i, d)) = stack.pop() {
                    let c = self.quads[i].child as usize;
                    if c == 0 {
                        let solid_angle = 4.0 * std::f64::consts::PI / (1u64 << (2 * d)) as f64;
                        mass += density(self.quads[i].energy, total, d) as f64 * solid_angle;
                    } else {
                        stack.extend((c..c + 4).map(|k| (k, d + 1)));
                    }
                }
                masses.push(mass);
            }
            masses
        }
    }

    /// The integral of `pdf` over the sphere: the midpoint rule on a 1024 x 1024 grid of the
    /// square (exact for quadtrees down to depth 10).
    fn integral(pdf: impl Fn(Vec3) -> f32) -> f64 {
        let n = 1024;
        let mut sum = 0.0f64;
        for i in 0..n {
            for j in 0..n {
                let s = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                sum += pdf(from_square(s)) as f64;
            }
        }
        sum * 4.0 * std::f64::consts::PI / (n * n) as f64
    }

    #[test]
    fn sampling_matches_the_density_of_a_trained_guide() {
        let g = lobe_guide(lobe_a(), 1);
        // The quadrature of the expected counts is exact to depth 9.
        assert!(g.max_quad_depth() <= 9, "depth {}", g.max_quad_depth());
        assert!(g.leaves() > 1, "{} leaves", g.leaves());
        for p in [Vec3::splat(0.5), Vec3::new(0.1, 0.9, 0.3)] {
            let z = z_score(|s| Some(g.sample(p, s.next_2d()).0), |d| g.pdf(p, d));
            assert!(z < 4.0, "z = {z} at {p}");
        }
    }

    #[test]
    fn the_chi_square_test_has_power() {
        let g = lobe_guide(lobe_a(), 1);
        let p = Vec3::splat(0.5);
        // Against the uniform density, and against a guide of the same sky with lobe A turned
        // by 3 degrees (a fifth of its radius).
        let z = z_score(|s| Some(g.sample(p, s.next_2d()).0), |_| UNIFORM);
        assert!(z > 10.0, "uniform: z = {z}");
        let turned = Vec3::new(0.3, 0.5, 0.8).normalize();
        let turned = (turned + 3f32.to_radians() * Vec3::X.cross(turned).normalize()).normalize();
        let other = lobe_guide(turned, 1);
        let z = z_score(|s| Some(g.sample(p, s.next_2d()).0), |d| other.pdf(p, d));
        assert!(z > 10.0, "turned 3 degrees: z = {z}");
        // And against the same sky learned from other records (their noise alone).
        let other = lobe_guide(lobe_a(), 2);
        let z = z_score(|s| Some(g.sample(p, s.next_2d()).0), |d| other.pdf(p, d));
        assert!(z > 10.0, "other records: z = {z}");
    }

    #[test]
    fn an_untrained_guide_is_uniform() {
        let g = Guide::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let p = Vec3::new(0.2, 0.3, -0.4);
        assert_eq!(g.pdf(p, Vec3::Z), UNIFORM);
        let z = z_score(|s| Some(g.sample(p, s.next_2d()).0), |_| UNIFORM);
        assert!(z < 4.0, "z = {z}");
        // Trained on nothing, still uniform (its quadtrees refined to 256 empty cells).
        let g = g.train(&[]);
        assert_eq!(g.pdf(p, Vec3::Z), UNIFORM);
        assert_eq!(g.sample(p, Vec2::new(0.3, 0.6)).1, UNIFORM);
        assert_eq!(g.directional_nodes(), 1 + 4 + 16 + 64 + 256);
    }

    #[test]
    fn the_density_integrates_to_one() {
        let empty = Guide::new(UNIT.0, UNIT.1);
        let lobes = lobe_guide(lobe_a(), 1);
        for (name, g) in [("empty", &empty), ("lobes", &lobes)] {
            for p in [Vec3::splat(0.5), Vec3::new(0.9, 0.05, 0.7)] {
                let i = integral(|d| g.pdf(p, d));
                assert!((i - 1.0).abs() < 1e-3, "{name} at {p}: {i}");
            }
        }
        // Quadtrees down to depth 20, too fine for quadrature: each leaf's density times its
        // solid angle, summed over every spatial leaf.
        let spike = spike_guide();
        assert!(spike.max_quad_depth() == MAX_DIRECTIONAL_DEPTH, "depth {}", spike.max_quad_depth());
        for g in [&lobes, &spike] {
            let masses = g.leaf_masses();
            assert!(!masses.is_empty());
            for m in masses {
                assert!((m - 1.0).abs() < 1e-5, "{m}");
            }
        }
    }

    #[test]
    fn sample_returns_the_density_of_its_direction() {
        let guides = [Guide::new(UNIT.0, UNIT.1), lobe_guide(lobe_a(), 1), spike_guide()];
        let mut rng = Rng::new(3);
        for g in &guides {
            let mut zero = 0;
            for _ in 0..100_000 {
                let p = rng.point(Vec3::splat(-0.1), Vec3::splat(1.1));
                let (d, pdf) = g.sample(p, rng.next_2d());
                assert!((d.length() - 1.0).abs() < 1e-5, "{d}");
                assert_eq!(pdf.to_bits(), g.pdf(p, d).to_bits(), "at {p} along {d}");
                zero += (pdf == 0.0) as u32;
            }
            assert_eq!(zero, 0, "samples of density 0");
        }
    }

    #[test]
    fn training_concentrates_density_on_a_bright_cone() {
        let axis = Vec3::new(-0.4, 0.1, 0.9).normalize();
        let cos = 5f32.to_radians().cos();
        let radiance = move |_: Vec3, d: Vec3| if d.dot(axis) > cos { 1000.0 } else { 0.1 };
        let g = train(Guide::new(UNIT.0, UNIT.1), 4, 20_000, 9, |r| r.point(UNIT.0, UNIT.1), radiance);
        let mut rng = Rng::new(4);
        let (mut inside, n) = (0, 20_000);
        let mut lowest = f32::INFINITY;
        for _ in 0..n {
            let p = rng.point(UNIT.0, UNIT.1);
            lowest = lowest.min(g.pdf(p, axis));
            inside += (g.sample(p, rng.next_2d()).0.dot(axis) > cos) as u32;
        }
        assert!(lowest > 50.0 * UNIFORM, "pdf at the cone's axis {} times uniform", lowest / UNIFORM);
        let fraction = inside as f64 / n as f64;
        assert!(fraction > 0.75, "{fraction} of the samples in the cone (it is 0.0019 of the sphere)");
    }

    #[test]
    fn only_leaves_with_records_split() {
        let mut rng = Rng::new(6);
        let records: Vec<_> = (0..20_000)
            .map(|_| RadianceRecord::new(rng.point(UNIT.0, Vec3::new(0.5, 1.0, 1.0)), Vec3::Z, 1.0))
            .collect();
        let (empty, full) = (Vec3::new(0.75, 0.5, 0.5), Vec3::new(0.25, 0.5, 0.5));
        for filter in [SpatialFilter::Nearest, SpatialFilter::Box] {
            let options = GuideOptions { split_records: 1000.0, filter, ..GuideOptions::default() };
            let g = Guide::with_options(UNIT.0, UNIT.1, options).expect("valid options").train(&records);
            // The root splits along x; the empty upper half stays one leaf, the lower one
            // splits until its leaves hold at most 1,000 records (about 20 leaves).
            assert_eq!(g.leaf_depth(empty), 1);
            assert_eq!(g.leaf_depth(Vec3::new(0.99, 0.01, 0.99)), 1);
            assert!(g.leaf_depth(full) >= 5, "{}", g.leaf_depth(full));
            assert!((17..=64).contains(&g.leaves()), "{} leaves", g.leaves());
            assert!(g.pdf(full, Vec3::Z) > 100.0 * UNIFORM);
            match filter {
                // The empty half learned nothing...
                SpatialFilter::Nearest => assert_eq!(g.pdf(empty, Vec3::Z), UNIFORM),
                // ...unless the box filter spread its neighbours' records into it.
                SpatialFilter::Box => assert!(g.pdf(empty, Vec3::Z) > 100.0 * UNIFORM),
            }
        }
    }

    #[test]
    fn regions_learn_their_own_light() {
        // Light from +z where x < 1/2, from +x elsewhere: 20-degree cones over a dim floor.
        let cos = 20f32.to_radians().cos();
        let radiance = move |p: Vec3, d: Vec3| {
            let axis = if p.x < 0.5 { Vec3::Z } else { Vec3::X };
            if d.dot(axis) > cos {
                100.0
            } else {
                0.1
            }
        };
        // The mean density over directions within 15 degrees of `axis`: 10 to 40 records a
        // cell make single cells noisy.
        let mut rng = Rng::new(19);
        let cone: Vec<Vec2> = (0..256).map(|_| rng.next_2d()).collect();
        let mean = |g: &Guide, p: Vec3, axis: Vec3| {
            let frame = if axis == Vec3::Z { (Vec3::X, Vec3::Y) } else { (Vec3::Y, Vec3::Z) };
            let sum: f32 = cone
                .iter()
                .map(|u| {
                    let z = 1.0 - u.x * (1.0 - 15f32.to_radians().cos());
                    let r = (1.0 - z * z).sqrt();
                    let (sin, cos) = (TAU * u.y).sin_cos();
                    g.pdf(p, axis * z + frame.0 * (r * cos) + frame.1 * (r * sin))
                })
                .sum();
            sum / cone.len() as f32
        };
        for filter in [SpatialFilter::Nearest, SpatialFilter::Box] {
            let options = GuideOptions { filter, ..GuideOptions::default() };
            let g = Guide::with_options(UNIT.0, UNIT.1, options).expect("valid options");
            let g = train(g, 3, 40_000, 8, |r| r.point(UNIT.0, UNIT.1), radiance);
            // Away from the border between them: the box filter blurs over a leaf's width, and
            // next to the border a leaf a quarter of the cube wide gets some of the other
            // side's light.
            let (a, b) = (Vec3::new(0.1, 0.5, 0.5), Vec3::new(0.9, 0.5, 0.5));
            for (p, lit, dark) in [(a, Vec3::Z, Vec3::X), (b, Vec3::X, Vec3::Z)] {
                let (hi, lo) = (mean(&g, p, lit), mean(&g, p, dark));
                assert!(hi > 20.0 * UNIFORM && lo < 0.5 * UNIFORM, "{filter:?} at {p}: {hi}, {lo}");
            }
        }
    }

    #[test]
    fn training_is_deterministic_and_files_round_trip() {
        let g = lobe_guide(lobe_a(), 1);
        let recs = records(
            &g,
            30_000,
            &mut Rng::new(12),
            &|r: &mut Rng| r.point(UNIT.0, UNIT.1),
            &two_lobes(lobe_a()),
        );
        let (a, b) = (g.train(&recs), g.train(&recs));
        let bytes = a.to_bytes();
        assert_eq!(bytes, b.to_bytes());
        let back = Guide::from_bytes(&bytes).expect("a guide's own bytes");
        assert_eq!(back, a);
        assert_eq!(back.to_bytes(), bytes);
        let mut rng = Rng::new(13);
        for _ in 0..10_000 {
            let (p, u) = (rng.point(UNIT.0, UNIT.1), rng.next_2d());
            let (d, pdf) = a.sample(p, u);
            let (d2, pdf2) = back.sample(p, u);
            assert_eq!(
                (d.to_array().map(f32::to_bits), pdf.to_bits()),
                (d2.to_array().map(f32::to_bits), pdf2.to_bits())
            );
            let e = uniform_sphere(rng.next_2d());
            assert_eq!(a.pdf(p, e).to_bits(), back.pdf(p, e).to_bits());
        }
        // The empty guide too.
        let empty = Guide::new(Vec3::splat(-3.0), Vec3::new(1.0, 2.0, 5.0));
        assert_eq!(Guide::from_bytes(&empty.to_bytes()), Ok(empty));
    }

    /// Replaces the checksum of a (changed) file with the right one, so that the structural
    /// checks behind it are reached.
    fn reseal(bytes: &mut [u8]) {
        let n = bytes.len();
        if n >= 8 {
            let sum = fnv1a(&bytes[..n - 8]);
            bytes[n - 8..].copy_from_slice(&sum.to_le_bytes());
        }
    }

    #[test]
    fn damaged_files_are_errors() {
        let g = train(
            Guide::new(UNIT.0, UNIT.1),
            2,
            20_000,
            14,
            |r| r.point(UNIT.0, UNIT.1),
            two_lobes(lobe_a()),
        );
        let bytes = g.to_bytes();
        assert!(bytes.len() > 1000, "{} bytes", bytes.len());
        // Every truncation (checked whether resealed or not).
        for n in 0..bytes.len() {
            let mut cut = bytes[..n].to_vec();
            assert!(Guide::from_bytes(&cut).is_err(), "{n} bytes read");
            reseal(&mut cut);
            assert!(Guide::from_bytes(&cut).is_err(), "{n} bytes read, resealed");
        }
        // A byte more.
        let mut long = bytes.clone();
        long.insert(HEADER, 0);
        reseal(&mut long);
        assert!(Guide::from_bytes(&long).is_err());
        // Garbage, with and without the magic number.
        let mut rng = Rng::new(15);
        for n in [0, 7, 8, 60, 64, 1000, 5000] {
            let mut junk: Vec<u8> = (0..n).map(|_| rng.next_u32() as u8).collect();
            assert!(Guide::from_bytes(&junk).is_err());
            if n >= 8 {
                junk[..8].copy_from_slice(&MAGIC);
                reseal(&mut junk);
                assert!(Guide::from_bytes(&junk).is_err());
            }
        }
        // Random flips: refused by the checksum, and, resealed, parsed without a panic; what
        // parses is a guide that works.
        let (mut parsed, mut refused) = (0, 0);
        for _ in 0..3000 {
            let mut b = bytes.clone();
            for _ in 0..1 + rng.next_u32() % 3 {
                let at = rng.next_u32() as usize % b.len();
                b[at] ^= 1 + (rng.next_u32() % 255) as u8;
            }
            assert!(Guide::from_bytes(&b).is_err(), "a flipped byte passed the checksum");
            reseal(&mut b);
            match Guide::from_bytes(&b) {
                Ok(g) => {
                    parsed += 1;
                    for _ in 0..20 {
                        let p = rng.point(Vec3::splat(-1.0), Vec3::splat(2.0));
                        let (d, pdf) = g.sample(p, rng.next_2d());
                        assert!(d.is_finite() && pdf.is_finite() && pdf >= 0.0);
                        assert_eq!(pdf, g.pdf(p, d));
                    }
                    assert_eq!(g.to_bytes(), b);
                }
                Err(_) => refused += 1,
            }
        }
        assert!(refused > 1500, "{refused} refused, {parsed} parsed");
    }

    #[test]
    fn bad_records_are_ignored() {
        let g = lobe_guide(lobe_a(), 1);
        let good = records(
            &g,
            20_000,
            &mut Rng::new(16),
            &|r: &mut Rng| r.point(UNIT.0, UNIT.1),
            &two_lobes(lobe_a()),
        );
        let bad = [
            RadianceRecord::new(Vec3::splat(0.5), Vec3::Z, f32::NAN),
            RadianceRecord::new(Vec3::splat(0.5), Vec3::Z, -5.0),
            RadianceRecord::new(Vec3::splat(0.5), Vec3::Z, f32::INFINITY),
            RadianceRecord::new(Vec3::splat(0.5), Vec3::Z, -f32::INFINITY),
            RadianceRecord::new(Vec3::new(f32::NAN, 0.5, 0.5), Vec3::Z, 1.0),
            RadianceRecord::new(Vec3::new(0.5, f32::INFINITY, 0.5), Vec3::Z, 1.0),
            RadianceRecord::new(Vec3::splat(0.5), Vec3::ZERO, 1.0),
            RadianceRecord::new(Vec3::splat(0.5), Vec3::new(f32::NAN, 0.0, 1.0), 1.0),
            RadianceRecord::new(Vec3::splat(0.5), Vec3::splat(f32::INFINITY), 1.0),
        ];
        let mixed: Vec<_> = good.iter().enumerate().flat_map(|(i, r)| [*r, bad[i % bad.len()]]).collect();
        assert_eq!(g.train(&good).to_bytes(), g.train(&mixed).to_bytes());
        // Zero values count toward splitting but add no energy: under a threshold they do not
        // reach, they change nothing.
        let options = GuideOptions { split_records: 1e9, ..GuideOptions::default() };
        let g = Guide::with_options(UNIT.0, UNIT.1, options).expect("valid options");
        let zeros: Vec<_> = good.iter().flat_map(|r| [*r, RadianceRecord { value: 0.0, ..*r }]).collect();
        let (a, b) = (g.train(&good), g.train(&zeros));
        assert_eq!(a.to_bytes(), b.to_bytes());
        assert!(a.quads.iter().all(|n| n.energy.is_finite()));
        assert!(a.pdf(Vec3::splat(0.5), lobe_a()) > 5.0 * UNIFORM);
    }

    #[test]
    fn points_outside_the_bounds_use_the_nearest_leaf() {
        let g = lobe_guide(lobe_a(), 1);
        let mut rng = Rng::new(18);
        for _ in 0..1000 {
            let p = rng.point(Vec3::splat(-5.0), Vec3::splat(6.0));
            let d = uniform_sphere(rng.next_2d());
            assert_eq!(g.pdf(p, d), g.pdf(p.clamp(UNIT.0, UNIT.1), d));
        }
        assert!(g.pdf(Vec3::splat(f32::NAN), Vec3::Z).is_finite());
    }

    #[test]
    fn options_and_bounds_are_checked() {
        let bad = [
            GuideOptions { split_records: 0.5, ..GuideOptions::default() },
            GuideOptions { split_records: f32::NAN, ..GuideOptions::default() },
            GuideOptions { subdivide_fraction: 0.0, ..GuideOptions::default() },
            GuideOptions { subdivide_fraction: 1.5, ..GuideOptions::default() },
            GuideOptions { max_depth: 0, ..GuideOptions::default() },
            GuideOptions { max_depth: 21, ..GuideOptions::default() },
        ];
        for o in bad {
            assert!(Guide::with_options(UNIT.0, UNIT.1, o).is_err(), "{o:?}");
        }
        // Bounds flat, empty, inverted or not finite still make a guide that trains.
        let (flat, point) = (Vec3::new(2.0, 0.0, 2.0), Vec3::splat(3.0));
        for (a, b) in [(-flat, flat), (point, point), (Vec3::ONE, Vec3::ZERO), (Vec3::NAN, Vec3::ONE)] {
            let g = Guide::new(a, b);
            let (lo, hi) = g.bounds();
            assert!(lo.is_finite() && hi.is_finite() && (hi - lo).min_element() > 0.0, "{a} {b}: {lo} {hi}");
            let recs = [RadianceRecord::new(lo, Vec3::Y, 1.0); 10];
            let g = g.train(&recs);
            assert!(g.pdf(lo, Vec3::Y) > UNIFORM);
        }
        assert_eq!(Guide::new(-flat, flat).bounds(), (-flat, Vec3::new(2.0, 4.0, 2.0)));
    }
}
