use std::sync::Arc;

use glam::{Vec2, Vec3, Vec3A};

use super::intersect::{sphere, RayTri};
use super::*;
use crate::render::sampler::Sampler;
use crate::scene::{Camera, FilmSettings, Material, Mesh, RenderSettings, Scene, Shape};

pub(super) fn scene_of(shapes: Vec<Geometry>) -> Scene {
    Scene {
        path: "test".into(),
        inputs: vec![],
        origin: glam::DVec3::ZERO,
        camera: Camera {
            position: Vec3::ZERO,
            look_at: Vec3::Z,
            up: Vec3::Y,
            fov: 40.0,
            orthographic: None,
            lens: None,
        },
        film: FilmSettings::new(1, 1, 1),
        render: RenderSettings {
            max_depth: 1,
            seed: 0,
            sampler: Default::default(),
            light_sampler: Default::default(),
            guiding: Default::default(),
        },
        materials: vec![Material::Diffuse { albedo: Vec3::ONE }],
        shapes: shapes
            .into_iter()
            .enumerate()
            .map(|(i, geometry)| Shape {
                name: format!("s{i}"),
                geometry,
                material: 0,
                emission: Vec3::ZERO,
                object: i as u32,
            })
            .collect(),
        lights: vec![],
        objects: vec![],
        material_names: vec![],
        filter: Default::default(),
        textures: vec![],
        maps: vec![],
        notes: vec![],
        parameters: vec![],
        aovs: vec![],
        light_groups: Default::default(),
    }
}

pub(super) fn mesh(positions: Vec<Vec3>, indices: Vec<[u32; 3]>) -> Geometry {
    Geometry::Triangles(Mesh {
        positions: positions.into_iter().map(Vec3A::from).collect::<Arc<[Vec3A]>>(),
        indices: indices.into(),
        normals: None,
        uvs: None,
        attributes: None,
        instance: None,
        world: None,
    })
}

/// A triangle soup of `n` triangles at random places, plus spheres: the items run pair, pair,
/// single, single, each pair two triangles sharing an edge (which a tree of quads pairs as a
/// [`Prim::Quad`], its first triangle at an even index), the pairs' triangles starting at each
/// of their vertices in turn, so every one of the nine rotations of a quad occurs, and blocks
/// mix quads with lone triangles.
fn soup(n: usize, seed: u64) -> Scene {
    let mut s = Sampler::new(seed, 0, 0);
    let mut p = || Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 20.0 - Vec3::splat(10.0);
    let mut positions = Vec::new();
    let mut indices: Vec<[u32; 3]> = Vec::new();
    let rotated = |t: [u32; 3], r: usize| std::array::from_fn(|k| t[(k + r) % 3]);
    let (mut item, mut pairs) = (0, 0);
    while indices.len() < n {
        let at = positions.len() as u32;
        let c = p();
        let a = c + (p() * 0.05);
        let b = c + (p() * 0.05);
        positions.extend([c, a, b]);
        if item % 4 < 2 && indices.len() + 1 < n {
            // c a b and c b d share the edge b c, run in opposite directions.
            positions.push(c + (p() * 0.05));
            indices.push(rotated([at, at + 1, at + 2], pairs % 3));
            indices.push(rotated([at, at + 2, at + 3], (pairs / 3) % 3));
            pairs += 1;
        } else {
            indices.push(rotated([at, at + 1, at + 2], item % 3));
        }
        item += 1;
    }
    let mut shapes = vec![mesh(positions, indices)];
    for _ in 0..5 {
        shapes.push(Geometry::Sphere { center: p(), radius: 0.7 });
    }
    scene_of(shapes)
}

fn brute_force(scene: &Scene, ray: &Ray) -> Option<Hit> {
    brute_force_kept(scene, ray, |_, _, _, _| true)
}

/// The nearest hit of `ray` in `scene` that `keeps(shape, prim, u, v)` lets count, each
/// primitive tested by the scalar tests.
fn brute_force_kept(scene: &Scene, ray: &Ray, keeps: impl Fn(u32, u32, f32, f32) -> bool) -> Option<Hit> {
    let rt = RayTri::new(ray);
    let mut best: Option<Hit> = None;
    let mut t_max = ray.t_max;
    for (s, shape) in scene.shapes.iter().enumerate() {
        match &shape.geometry {
            Geometry::Sphere { center, radius } => {
                if let Some(t) = sphere(ray, *center, *radius, t_max) {
                    t_max = t;
                    best = Some(Hit { t, shape: s as u32, prim: 0, u: 0.0, v: 0.0 });
                }
            }
            Geometry::Triangles(m) => {
                for t in 0..m.indices.len() as u32 {
                    let hit = rt.hit(&m.triangle(t), t_max).filter(|&(_, u, v)| keeps(s as u32, t, u, v));
                    if let Some((th, u, v)) = hit {
                        t_max = th;
                        best = Some(Hit { t: th, shape: s as u32, prim: t, u, v });
                    }
                }
            }
        }
    }
    best
}

#[test]
fn tree_is_valid_and_matches_brute_force() {
    let scene = soup(3000, 1);
    for (kind, bvh) in Bvh::both_kinds(&scene) {
        matches_brute_force(&scene, &bvh, kind);
    }
}

fn matches_brute_force(scene: &Scene, bvh: &Bvh, kind: &str) {
    bvh.validate(BuildOptions::default().max_leaf).expect("valid tree");
    let mut s = Sampler::new(9, 1, 1);
    let mut hits = 0;
    for _ in 0..3000 {
        let origin = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 30.0 - Vec3::splat(15.0);
        // Aim at a random point of the soup, so that many rays hit something.
        let target = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 20.0 - Vec3::splat(10.0);
        let dir = (target - origin).normalize();
        let ray = Ray { origin, dir, t_max: if s.next_1d() < 0.5 { f32::INFINITY } else { 12.0 } };
        let want = brute_force(scene, &ray);
        let bits = |h: Hit| (h.shape, h.prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits());
        assert_eq!(bvh.intersect(&ray).map(bits), want.map(bits), "{kind}");
        assert_eq!(bvh.occluded(&ray), want.is_some(), "{kind}");
        hits += want.is_some() as u32;
    }
    assert!(hits > 300, "only {hits} rays hit: the test would prove little");
    let quads = bvh.prims.iter().filter(|p| matches!(p, Prim::Quad { .. })).count();
    match kind {
        "quads" => assert!(quads >= 900 && bvh.wide.quads, "only {quads} quads: the pairs were not paired"),
        _ => assert!(quads == 0 && !bvh.wide.quads, "{quads} quads in a tree of triangles"),
    }
}

/// Cut-outs (a mask over vertex alpha of 0 or 1, so most triangles are cut in part) on a soup
/// and on a placed copy of it (the instance level): both kinds of tree find the nearest hit
/// that the cut-outs keep, as the scalar tests over every triangle do, bit for bit.
#[test]
fn cut_outs_and_instances_match_brute_force_in_both_kinds() {
    use crate::scene::cutout::{Alpha, AlphaMode, Cutouts};
    let mut scene = soup(3000, 4);
    let Geometry::Triangles(mesh) = &mut scene.shapes[0].geometry else { unreachable!("the soup's mesh") };
    let mut s = Sampler::new(21, 0, 0);
    let alpha: Vec<f32> =
        (0..mesh.positions.len()).map(|_| if s.next_1d() < 0.5 { 0.0 } else { 1.0 }).collect();
    mesh.attributes =
        Some(Box::new(crate::scene::Attributes { alpha: Some(alpha.into()), ..Default::default() }));
    let mut copy = mesh.clone();
    let to_world = glam::Affine3A::from_translation(glam::Vec3::new(3.0, -2.0, 1.0));
    let Some(placed) = crate::scene::Instance::new(to_world) else { panic!("a translation places") };
    copy.instance = Some(Box::new(placed));
    scene.shapes.push(Shape {
        name: "copy".into(),
        geometry: Geometry::Triangles(copy),
        material: 0,
        emission: Vec3::ZERO,
        object: 9,
    });
    scene.maps = vec![crate::scene::Maps {
        alpha: Some(Alpha { mode: AlphaMode::Mask(0.5), factor: 1.0, texture: None }),
        ..Default::default()
    }];
    let Some(cutouts) = Cutouts::new(&scene) else { panic!("the soup has no cut-outs") };
    for (kind, bvh) in Bvh::both_kinds(&scene) {
        assert_eq!((bvh.instance_counts(), bvh.wide.quads), ((1, 1), kind == "quads"));
        let mut s = Sampler::new(9, 1, 1);
        let (mut hits, mut cut, mut copy) = (0, 0, 0);
        for _ in 0..3000 {
            let origin = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 30.0 - Vec3::splat(15.0);
            let target = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 20.0 - Vec3::splat(10.0);
            let ray = Ray { origin, dir: (target - origin).normalize(), t_max: f32::INFINITY };
            let want = brute_force_kept(&scene, &ray, |shape, prim, u, v| cutouts.keeps(shape, prim, u, v));
            let bits = |h: Hit| (h.shape, h.prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits());
            match (bvh.intersect(&ray), want) {
                // The copy is tested in its own coordinates: the same hit up to rounding.
                (Some(got), Some(want)) if want.shape == 6 => {
                    assert_eq!((got.shape, got.prim), (want.shape, want.prim), "{kind}: {ray:?}");
                    let close = |a: f32, b: f32| (a - b).abs() <= 1e-4 * b.abs().max(1.0);
                    assert!(
                        close(got.t, want.t) && close(got.u, want.u) && close(got.v, want.v),
                        "{kind}: {got:?} {want:?}"
                    );
                }
                (got, want) => assert_eq!(got.map(bits), want.map(bits), "{kind}: {ray:?}"),
            }
            assert_eq!(bvh.occluded(&ray), want.is_some(), "{kind}: {ray:?}");
            hits += usize::from(want.is_some());
            copy += usize::from(want.is_some_and(|h| h.shape == 6));
            cut += usize::from(want.map(bits) != brute_force(&scene, &ray).map(bits));
        }
        // Many hits, on both copies, and many that a cut-out moved: the comparison covers all.
        assert!(
            hits > 300 && copy > 100 && cut > 100,
            "{kind}: {hits} hits ({copy} on the copy), {cut} moved by a cut-out"
        );
    }
}

/// A pair sharing an edge becomes a quad whose two triangles are the pair's, vertex for vertex
/// in the pair's own order, whichever vertex each starts at; a pair wound inconsistently, or
/// with a degenerate triangle, stays two triangles.
#[test]
fn quads_keep_their_triangles_vertex_order() {
    let [a, b, c, d] = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(-1.0, 0.5, 0.25)];
    let rotated = |t: [Vec3; 3], r: usize| std::array::from_fn(|k| t[(k + r) % 3]);
    for ra in 0..3 {
        for rb in 0..3 {
            // a b c and a c d share the edge c a.
            let (first, second) = (rotated([a, b, c], ra), rotated([a, c, d], rb));
            let Some(Prim::Quad { v, prim, shape, rot }) = Prim::quad(first, second, 3, 8) else {
                panic!("rotations {ra} {rb}: not paired")
            };
            assert_eq!((prim, shape), (8, 3));
            assert_eq!(Prim::quad_triangles(&v, rot), [first, second], "rotations {ra} {rb}");
            // The same edge in the same direction: the pair is not consistently wound.
            assert!(Prim::quad(first, rotated([c, a, d], rb), 0, 0).is_none());
        }
    }
    assert!(Prim::quad([a, b, c], [a, c, a], 0, 0).is_none(), "degenerate second triangle");
}

#[test]
fn triangle_test_reports_embree_barycentrics() {
    let ray = Ray::new(Vec3::new(0.25, 0.5, -2.0), Vec3::Z);
    let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let (t, u, v) = RayTri::new(&ray).hit(&tri, f32::INFINITY).expect("hit");
    assert!((t - 2.0).abs() < 1e-6 && (u - 0.25).abs() < 1e-6 && (v - 0.5).abs() < 1e-6);
    // Both windings hit (no backface culling); t_max cuts.
    let flipped = [Vec3::ZERO, Vec3::Y, Vec3::X];
    assert!(RayTri::new(&ray).hit(&flipped, f32::INFINITY).is_some());
    assert!(RayTri::new(&ray).hit(&tri, 1.9).is_none());
}

#[test]
fn sphere_from_outside_inside_and_behind() {
    let c = Vec3::new(0.0, 0.0, 10.0);
    assert!((sphere(&Ray::new(Vec3::ZERO, Vec3::Z), c, 2.0, f32::INFINITY).expect("hit") - 8.0).abs() < 1e-5);
    assert!((sphere(&Ray::new(c, Vec3::X), c, 2.0, f32::INFINITY).expect("inside") - 2.0).abs() < 1e-5);
    assert!(sphere(&Ray::new(Vec3::ZERO, -Vec3::Z), c, 2.0, f32::INFINITY).is_none());
    // Far from the origin the perpendicular-distance discriminant keeps small spheres hittable.
    let far = Vec3::new(0.0, 0.0, 1e5);
    let t = sphere(&Ray::new(Vec3::ZERO, Vec3::Z), far, 0.01, f32::INFINITY).expect("small far sphere");
    assert!((t - (1e5 - 0.01)).abs() < 0.02, "{t}");
}

/// A crack test: a finely subdivided plane, rays aimed exactly at its vertices and edge
/// midpoints (where two or more triangles meet), from oblique directions. Every ray must hit.
#[test]
fn no_ray_slips_through_shared_edges_and_vertices() {
    let n = 64u32;
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            positions.push(Vec3::new(i as f32 / n as f32 * 3.7 - 1.3, 0.0, j as f32 / n as f32 * 2.9 - 0.6));
        }
    }
    let mut indices = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            let (b, c, d) = (a + 1, a + n + 2, a + n + 1);
            indices.push([a, b, c]);
            indices.push([a, c, d]);
        }
    }
    let scene = scene_of(vec![mesh(positions.clone(), indices)]);
    let bvh = Bvh::with_reference(&scene).expect("builds");
    let mut s = Sampler::new(5, 0, 0);
    let mut rays = 0;
    // Interior vertices only: on the plane's outer boundary only one triangle has the edge.
    for p in positions.iter().filter(|p| p.x > -1.2 && p.x < 2.3 && p.z > -0.5 && p.z < 2.2) {
        for target in [
            *p,
            *p + Vec3::new(3.7 / n as f32 / 2.0, 0.0, 0.0),
            *p + Vec3::new(3.7 / n as f32 / 2.0, 0.0, 2.9 / n as f32 / 2.0),
        ] {
            let dir = crate::math::cosine_hemisphere(s.next_2d() * 0.98 + Vec2::splat(0.01));
            let dir = Vec3::new(dir.x, dir.z, dir.y); // hemisphere around +y
            let origin = target + dir * (1.0 + 5.0 * s.next_1d());
            let ray = Ray::new(origin, -dir);
            assert!(bvh.intersect(&ray).is_some(), "ray to {target} from {origin} slipped through");
            assert!(bvh.occluded(&ray));
            rays += 1;
        }
    }
    assert!(rays > 1000);
}

#[test]
fn degenerate_input_builds_a_bounded_tree() {
    // Many primitives with the same centroid: no SAH split exists, median splits must take over.
    let positions: Vec<Vec3> = (0..3000).flat_map(|_| [Vec3::ZERO, Vec3::X, Vec3::Y]).collect();
    let indices: Vec<[u32; 3]> = (0..3000u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    let scene = scene_of(vec![mesh(positions, indices)]);
    let bvh = Bvh::with_reference(&scene).expect("builds");
    bvh.validate(BuildOptions::default().max_leaf).expect("valid");
    let hit = bvh.intersect(&Ray::new(Vec3::new(0.2, 0.2, -1.0), Vec3::Z)).expect("hit");
    assert_eq!(hit.t, 1.0);
    // Zero-area triangles and empty spheres are dropped, not hit.
    let scene = scene_of(vec![
        mesh(vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0], vec![[0, 1, 2]]),
        Geometry::Sphere { center: Vec3::ZERO, radius: 0.0 },
    ]);
    let bvh = Bvh::with_reference(&scene).expect("builds");
    assert_eq!(bvh.size().2, 0);
    assert!(bvh.intersect(&Ray::new(Vec3::new(1.0, 0.0, -1.0), Vec3::Z)).is_none());
}

/// A ray leaving a large triangle from just off its plane, far from its vertices (the offset
/// origin of a secondary ray on the Cornell box's wall), must not hit the triangle behind it:
/// the distance the watertight test computes carries an error larger than the offset, which the
/// t error bound accounts for.
#[test]
fn rays_leaving_a_surface_do_not_hit_it() {
    let wall = [Vec3::new(0.0, 0.0, 559.2), Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 548.8, 0.0)];
    let scene = scene_of(vec![mesh(wall.to_vec(), vec![[0, 1, 2]])]);
    let bvh = Bvh::with_reference(&scene).expect("builds");
    let mut s = Sampler::new(11, 0, 0);
    for _ in 0..2000 {
        let (y, z) = (s.next_1d() * 200.0 + 20.0, s.next_1d() * 200.0 + 20.0);
        let origin = crate::math::offset_ray_origin(Vec3::new(0.0, y, z), Vec3::X, 559.2);
        let dir =
            Vec3::new(50.0 + 300.0 * s.next_1d(), 400.0 * s.next_1d() - 200.0, 400.0 * s.next_1d() - 200.0);
        let ray = Ray { origin, dir, t_max: 1.0 };
        assert!(!bvh.occluded(&ray), "{ray:?} hit the surface it leaves");
        assert!(bvh.intersect(&ray).is_none() && bvh.intersect_binary(&ray).is_none());
        // From a unit in front, the ray turned around does hit it.
        let back = Ray { origin: origin + Vec3::X, dir: -dir, t_max: 1.0 };
        assert!(bvh.occluded(&back) && bvh.intersect(&back).is_some());
    }
}

/// The traversals compiled for AVX2 and for AVX-512 (where this CPU has them) find exactly the
/// hits of the same tree traversed with the portable slab test: closest hits bit for bit, and
/// any-hit answers, on rays from inside and outside a triangle soup, toward it and past it,
/// some with zero direction components and some with a finite reach.
#[test]
fn the_avx2_traversal_equals_the_portable_one() {
    match super::simd::Isa::avx2() {
        Some(isa) => traversal_equals_the_portable_one(isa),
        None => eprintln!("no AVX2 on this CPU: only the portable traversal runs here"),
    }
}

#[test]
fn the_avx512_traversal_equals_the_portable_one() {
    match super::simd::Isa::best() {
        isa if isa.name() == "avx512" => traversal_equals_the_portable_one(isa),
        _ => eprintln!("no AVX-512 on this CPU: its traversal is not checked here"),
    }
}

fn traversal_equals_the_portable_one(isa: super::simd::Isa) {
    let scene = soup(3000, 11);
    for ((kind, fast), (_, portable)) in Bvh::both_kinds(&scene).into_iter().zip(Bvh::both_kinds(&scene)) {
        assert_eq!(fast.wide.quads, kind == "quads");
        traversals_agree(&fast.with_isa(isa), &portable.portable(), isa);
    }
}

fn traversals_agree(fast: &Bvh, portable: &Bvh, isa: super::simd::Isa) {
    assert_eq!(fast.isa().name(), isa.name());
    assert_eq!(portable.isa().name(), "portable");
    let mut rng = Sampler::new(5, 0, 0);
    let mut f = |scale: f32| (rng.next_1d() * 2.0 - 1.0) * scale;
    let (mut hits, mut occluded) = (0, 0);
    for i in 0..20_000 {
        let origin = Vec3::new(f(14.0), f(14.0), f(14.0));
        let target = Vec3::new(f(10.0), f(10.0), f(10.0));
        let mut dir = target - origin;
        if i % 17 == 0 {
            dir.x = 0.0;
        }
        let t_max = if i % 3 == 0 { f(1.0).abs() } else { f32::INFINITY };
        let ray = Ray { origin, dir, t_max };
        let (a, b) = (fast.intersect(&ray), portable.intersect(&ray));
        let bits = |h: Hit| (h.shape, h.prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits());
        assert_eq!(a.map(bits), b.map(bits));
        assert_eq!(fast.occluded(&ray), portable.occluded(&ray), "{ray:?}");
        hits += usize::from(a.is_some());
        occluded += usize::from(fast.occluded(&ray));
    }
    // Both answers occur often, so the comparison covers hits and misses.
    assert!(hits > 1000 && hits < 19_000 && occluded > 1000, "{hits} hits, {occluded} occluded");
}

/// The wide tree's array holds every node and leaf block once, each node's leaves right after
/// it (the layout the traversal's memory reads count on), on a soup, on a grid of shared edges
/// and on a scene of one leaf.
#[test]
fn each_node_is_followed_by_its_leaves() {
    for (name, scene) in [("soup", soup(3000, 5)), ("one leaf", soup(3, 1))] {
        for (kind, bvh) in Bvh::both_kinds(&scene) {
            bvh.wide.check_layout().unwrap_or_else(|e| panic!("{name}, {kind}: {e}"));
        }
    }
    let n = 40;
    let positions: Vec<Vec3> = (0..=n)
        .flat_map(|j| (0..=n).map(move |i| Vec3::new(i as f32, ((i * j) % 7) as f32 * 0.1, j as f32)))
        .collect();
    let indices: Vec<[u32; 3]> = (0..n)
        .flat_map(|j| {
            (0..n).flat_map(move |i| {
                let v = |a: u32, b: u32| b * (n + 1) + a;
                [[v(i, j), v(i + 1, j), v(i, j + 1)], [v(i + 1, j), v(i + 1, j + 1), v(i, j + 1)]]
            })
        })
        .collect();
    for (kind, grid) in Bvh::both_kinds(&scene_of(vec![mesh(positions, indices)])) {
        assert!(grid.wide.node_count() > 10, "{kind}");
        assert_eq!(grid.wide.quads, kind == "quads");
        grid.wide.check_layout().unwrap_or_else(|e| panic!("grid, {kind}: {e}"));
    }
}
