//! The BVH's second level: meshes shared by several shapes (instances) are built once, in their
//! own coordinates, and a binary tree over the instances' boxes in the scene leads rays to them,
//! turned into each mesh's coordinates. A ray's parameter `t` is the same in both coordinates
//! (its direction is mapped, not normalised), so hits compare across levels directly.

use std::collections::HashMap;

use glam::{Affine3A, Vec3A};

use super::{any, build, closest, Aabb, BuildOptions, Bvh, Filter, Node, TooLarge};
use crate::accel::{Hit, Ray};
use crate::scene::cutout::Cutouts;
use crate::scene::{Geometry, Scene};

/// One placed mesh.
#[derive(Clone, Copy, Debug)]
struct Placed {
    to_local: Affine3A,
    /// The shape the hits report.
    shape: u32,
    /// Index into [`Instances::meshes`].
    mesh: u32,
}

/// The instanced shapes of a scene.
pub(super) struct Instances {
    /// The binary tree over the instances' boxes (leaves index `placed`).
    nodes: Vec<Node>,
    placed: Vec<Placed>,
    /// Each shared mesh's own BVH, in its own coordinates (shape 0 in its hits).
    meshes: Vec<Bvh>,
}

impl Instances {
    /// The instanced shapes of `scene`, or `None` when it has none (or only empty ones).
    /// The meshes that some instance with a cut-out places have all their lanes marked: their
    /// hits are asked about as each instance's shape.
    pub(super) fn new(
        scene: &Scene,
        options: BuildOptions,
        cutouts: Option<&Cutouts>,
    ) -> Result<Option<Instances>, TooLarge> {
        let mut meshes: Vec<Bvh> = Vec::new();
        let mut by_arrays: HashMap<(usize, usize), u32> = HashMap::new();
        let mut placed = Vec::new();
        let mut boxes = Vec::new();
        for (s, shape) in scene.shapes.iter().enumerate() {
            let Geometry::Triangles(mesh) = &shape.geometry else { continue };
            let Some(instance) = &mesh.instance else { continue };
            let m = match by_arrays.get(&mesh.arrays()) {
                Some(&m) => m,
                None => {
                    // The build leaves out degenerate triangles.
                    use rayon::iter::ParallelIterator;
                    let pair = mesh.indices.len() >= options.quad_min;
                    let mut prims: Vec<_> =
                        super::mesh_prims(mesh.indices.len() as u32, 0, pair, |t| mesh.local_triangle(t))
                            .collect();
                    let options = if pair { super::settle_quads(&mut prims, options) } else { options };
                    if prims.len() > super::wide::MAX_PRIMS as usize {
                        return Err(TooLarge(prims.len()));
                    }
                    meshes.push(build::build(prims, options));
                    by_arrays.insert(mesh.arrays(), meshes.len() as u32 - 1);
                    meshes.len() as u32 - 1
                }
            };
            let Some(local) = meshes[m as usize].bounds else { continue };
            boxes.push(placed_box(&local, &instance.to_world));
            placed.push(Placed { to_local: instance.to_local, shape: s as u32, mesh: m });
        }
        if placed.is_empty() {
            return Ok(None);
        }
        if let Some(c) = cutouts {
            for (m, mesh) in meshes.iter_mut().enumerate() {
                if placed.iter().any(|p: &Placed| p.mesh as usize == m && c.cuts(p.shape)) {
                    mesh.wide.mark_cutouts(|_| true);
                }
            }
        }
        let Some((nodes, order)) =
            build::tree(boxes.len(), |i| Some(boxes[i]), BuildOptions { max_leaf: 1, block: 1, ..options })
        else {
            return Ok(None);
        };
        let placed = order.iter().map(|&i| placed[i as usize]).collect();
        Ok(Some(Instances { nodes, placed, meshes }))
    }

    /// How many instances, and how many distinct meshes they place.
    pub(super) fn counts(&self) -> (usize, usize) {
        (self.placed.len(), self.meshes.len())
    }

    /// Bytes held: the tree over the instances, their placements, and each shared mesh's BVH.
    pub(super) fn bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node>()
            + self.placed.len() * std::mem::size_of::<Placed>()
            + self.meshes.iter().map(Bvh::bytes).sum::<usize>()
    }

    /// The closest hit along `ray` nearer than `best` (the hit found so far, if any).
    pub(super) fn intersect(&self, ray: &Ray, best: Option<Hit>, filter: Filter) -> Option<Hit> {
        let t_max = best.map_or(ray.t_max, |h| h.t);
        closest(&self.nodes, ray, t_max, best, |range, t_max| {
            let mut found = None;
            for p in &self.placed[range] {
                let local = Ray { t_max: *t_max, ..local_ray(ray, &p.to_local) };
                let filter = Filter { shape: Some(p.shape), ..filter };
                if let Some(h) = self.meshes[p.mesh as usize].wide.intersect(&local, filter) {
                    *t_max = h.t;
                    found = Some(Hit { shape: p.shape, ..h });
                }
            }
            found
        })
    }

    /// Whether any instance lies along `ray` within [0, t_max].
    pub(super) fn occluded(&self, ray: &Ray, filter: Filter) -> bool {
        any(&self.nodes, ray, |range| {
            self.placed[range].iter().any(|p| {
                let local = Ray { t_max: ray.t_max, ..local_ray(ray, &p.to_local) };
                let filter = Filter { shape: Some(p.shape), ..filter };
                self.meshes[p.mesh as usize].wide.occluded(&local, filter)
            })
        })
    }
}

/// `ray` in a mesh's own coordinates.
#[inline(always)]
fn local_ray(ray: &Ray, to_local: &Affine3A) -> Ray {
    Ray {
        origin: to_local.transform_point3(ray.origin),
        dir: to_local.transform_vector3(ray.dir),
        t_max: ray.t_max,
    }
}

/// The box in the scene of a mesh whose own box is `local`, placed by `to_world`: the box of
/// its eight corners placed, grown by the rounding of the placement (a few ulps of the
/// coordinates' magnitude), so that no placed triangle sticks out of it.
fn placed_box(local: &Aabb, to_world: &Affine3A) -> Aabb {
    let mut b = Aabb::EMPTY;
    for k in 0..8 {
        let corner = Vec3A::new(
            if k & 1 == 0 { local.min.x } else { local.max.x },
            if k & 2 == 0 { local.min.y } else { local.max.y },
            if k & 4 == 0 { local.min.z } else { local.max.z },
        );
        b = b.grow(to_world.transform_point3a(corner));
    }
    let pad = (b.min.abs().max(b.max.abs())).max_element() * 8.0 * f32::EPSILON;
    Aabb { min: b.min - Vec3A::splat(pad), max: b.max + Vec3A::splat(pad) }
}
