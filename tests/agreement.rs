//! Embree and the BVH give the same hits on every scene in `scenes/` and on generated ray sets
//! (primary, shadow, incoherent), and the same image at the same seed up to float rounding.

use std::path::{Path, PathBuf};

use lightsplit::accel::{build_embree, bvh::Bvh, Backend, Hit, Ray};
use lightsplit::bench::rays::{RayKind, RaySets};
use lightsplit::render::{render, RenderOptions};
use lightsplit::scene::Geometry;
use lightsplit::scene::{self, Scene};

fn scenes() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("scenes/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    assert!(paths.len() >= 3);
    paths
}

#[derive(Default, Debug)]
struct Tally {
    rays: usize,
    hits: usize,
    /// Both hit at the same distance but report different primitives: a tie on a shared edge.
    ties: usize,
    /// One hits and the other misses, or the distances differ.
    disagreements: usize,
}

/// t within 1e-5 relative, where "relative" includes the size of the coordinates: a hit 0.3
/// units from an origin 500 units out, or on a triangle whose corners are 100 units away,
/// carries the rounding of coordinates that large (an f32 ulp near 500 is 3e-5), whatever the
/// length of the ray.
fn same_t(ray: &Ray, a: f32, b: f32, coordinates: f32, cos: f32) -> bool {
    let scale = a.abs().max(b.abs()) + (ray.origin.abs().max_element() + coordinates) / ray.dir.length();
    // A hit point's rounding moves t by its size over the cosine of incidence: a ray that
    // grazes a triangle meets its plane at a t that rounding moves further (seen: 2e-5 at an
    // edge of a sphere's silhouette, the same triangle hit by both backends).
    (a - b).abs() <= 1e-5 * scale / cos.max(1e-2)
}

/// The cosine between `ray` and the normal of the primitive `hit` found (1 for a sphere, which
/// is intersected in closed form).
fn incidence(scene: &Scene, ray: &Ray, hit: &Hit) -> f32 {
    match &scene.shapes[hit.shape as usize].geometry {
        Geometry::Triangles(mesh) => {
            let [a, b, c] = mesh.triangle(hit.prim);
            (b - a).cross(c - a).normalize_or_zero().dot(ray.dir.normalize_or_zero()).abs()
        }
        Geometry::Sphere { .. } => 1.0,
    }
}

/// The largest coordinate of the primitive hit (a triangle's corners; a sphere's centre and
/// radius).
fn coordinates(scene: &Scene, hit: &Hit) -> f32 {
    match &scene.shapes[hit.shape as usize].geometry {
        Geometry::Triangles(mesh) => {
            mesh.triangle(hit.prim).iter().map(|p| p.abs().max_element()).fold(0.0, f32::max)
        }
        Geometry::Sphere { center, radius } => center.abs().max_element() + radius,
    }
}

fn compare(scene: &Scene, ray: &Ray, a: Option<Hit>, b: Option<Hit>, tally: &mut Tally) {
    tally.rays += 1;
    match (a, b) {
        (None, None) => {}
        (Some(x), Some(y)) => {
            tally.hits += 1;
            let cos = incidence(scene, ray, &x).min(incidence(scene, ray, &y));
            if !same_t(ray, x.t, y.t, coordinates(scene, &x).max(coordinates(scene, &y)), cos) {
                tally.disagreements += 1;
            } else if (x.shape, x.prim) != (y.shape, y.prim) {
                tally.ties += 1;
            }
        }
        _ => tally.disagreements += 1,
    }
}

fn tally_scene(scene: &Scene, n: usize) -> [Tally; 3] {
    let embree = build_embree(scene, None).expect("embree builds");
    let bvh = Bvh::new(scene).expect("bvh builds");
    let sets = RaySets::generate(scene, &embree, n, 3);
    RayKind::ALL.map(|kind| {
        let mut tally = Tally::default();
        for ray in sets.get(kind) {
            if kind == RayKind::Shadow {
                let (a, b) = (embree.occluded(ray), bvh.occluded(ray));
                tally.rays += 1;
                tally.hits += a as usize;
                tally.disagreements += (a != b) as usize;
            } else {
                let (a, b) = (embree.intersect(ray), bvh.intersect(ray));
                let before = tally.disagreements;
                compare(scene, ray, a, b, &mut tally);
                if tally.disagreements > before && std::env::var_os("AGREEMENT_DEBUG").is_some() {
                    eprintln!("  {ray:?}\n    embree {a:?}\n    bvh    {b:?}");
                }
            }
        }
        tally
    })
}

#[test]
fn both_backends_agree_on_every_scene() {
    for path in scenes() {
        let scene = scene::load(&path).expect("scene loads");
        let tallies = tally_scene(&scene, 20_000);
        for (kind, t) in RayKind::ALL.iter().zip(&tallies) {
            eprintln!("{}: {} rays: {t:?}", path.display(), kind.name());
            assert!(t.rays > 1000, "{kind:?}: too few rays to say anything");
            // Differences in t beyond 1e-5 or in hit/miss would be a bug; allow one in 10^4
            // for rays that graze a silhouette exactly.
            assert!(t.disagreements * 10_000 <= t.rays, "{}: {kind:?}: {t:?}", path.display());
            // Ties on shared edges are rare: both backends are watertight, they just may pick
            // different triangles of the two that share the edge.
            assert!(t.ties * 1_000 <= t.rays, "{}: {kind:?}: {t:?}", path.display());
        }
    }
}

#[test]
fn images_agree_up_to_float_rounding() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml");
    let scene = scene::load(&path).expect("scene loads");
    let mut options = RenderOptions::from_scene(&scene);
    options.width = 64;
    options.height = 64;
    options.spp = 8;
    let a = render(&scene, &options, &|_| {}).expect("embree renders").film.raw;
    options.accel = Backend::Bvh;
    let b = render(&scene, &options, &|_| {}).expect("bvh renders").film.raw;
    let scale = a.mean().max_element();
    let (mut largest, mut sum, mut identical, mut diverged) = (0.0f32, 0.0f64, 0usize, 0usize);
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        let d = (*p - *q).abs().max_element();
        largest = largest.max(d);
        identical += (p == q) as usize;
        if d >= 1e-3 * scale {
            diverged += 1;
        } else {
            sum += d as f64;
        }
    }
    // The mean over the pixels that differ by rounding only: one diverged path (0.012 in one
    // pixel) alone would add 3e-6 to a mean over all of them.
    let mean = sum / (a.pixels.len() - diverged) as f64;
    eprintln!(
        "cornell 64x64 8 spp: largest pixel difference {largest}, mean {mean:e}, {identical} of {} pixels \
         identical, {diverged} beyond 1e-3 of the mean",
        a.pixels.len()
    );
    // Hit points differ by rounding, so pixels differ in their last bits. A larger difference
    // means a path went another way: a shadow or bounce ray that grazes an edge may pass on one
    // backend and not the other (both right up to rounding), seen in 1 pixel of 4,096 with the
    // Sobol sampler and none with independent numbers. More than 4 (0.1%), or a mean beyond
    // rounding among the others, would be a different hit that is not a rounding.
    assert!(diverged <= 4, "{diverged} pixels differ by 1e-3 of the mean or more (largest {largest})");
    assert!(mean < 1e-6 * scale as f64, "mean difference {mean}");
}

/// Rays from the camera aimed exactly at the midpoints of triangle edges, where two triangles
/// of a quad or mesh meet: neither backend may miss (both are watertight), but they may pick
/// different triangles of the pair. The ties are counted and reported.
#[test]
fn rays_at_shared_edges_hit_on_both_backends() {
    for path in scenes() {
        let name = path.display();
        let scene = scene::load(&path).expect("loads");
        let embree = build_embree(&scene, None).expect("embree builds");
        let bvh = Bvh::new(&scene).expect("bvh builds");
        let mut tally = Tally::default();
        let (mut misses, mut grazing) = (0, 0);
        for shape in &scene.shapes {
            let Geometry::Triangles(mesh) = &shape.geometry else {
                continue;
            };
            // Edges used by two triangles of the mesh, with the two vertices opposite them (a
            // boundary edge may be missed by both backends).
            let mut uses: std::collections::HashMap<(u32, u32), Vec<u32>> = Default::default();
            for tri in mesh.indices.iter() {
                for k in 0..3 {
                    let (i, j, o) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                    uses.entry((i.min(j), i.max(j))).or_default().push(o);
                }
            }
            let mut shared: Vec<((u32, u32), [u32; 2])> =
                uses.into_iter().filter_map(|(e, o)| (o.len() == 2).then(|| (e, [o[0], o[1]]))).collect();
            shared.sort_unstable();
            // At most about 5000 edges a mesh.
            let stride = shared.len() / 5000 + 1;
            for &((i, j), [o1, o2]) in shared.iter().step_by(stride) {
                let v = |k: u32| mesh.vertex(k);
                let (p, q) = (v(i), v(j));
                let target = (p + q) * 0.5;
                let ray = Ray::new(scene.camera.position, target - scene.camera.position);
                // The surface crosses the ray at the edge only if the two triangles lie on
                // opposite sides of the plane through the ray and the edge; otherwise the ray
                // grazes a fold (a silhouette), where a miss is no crack.
                let n = ray.dir.cross(q - p);
                let (s1, s2) = (n.dot(v(o1) - p), n.dot(v(o2) - p));
                if s1 * s2 >= 0.0 {
                    grazing += 1;
                    continue;
                }
                let (x, y) = (embree.intersect(&ray), bvh.intersect(&ray));
                misses += x.is_none() as usize + y.is_none() as usize;
                let before = tally.disagreements;
                compare(&scene, &ray, x, y, &mut tally);
                if tally.disagreements > before && std::env::var_os("AGREEMENT_DEBUG").is_some() {
                    eprintln!(
                        "  {ray:?} aimed at t = 1 ({}, {i}, {j})\n    embree {x:?}\n    bvh    {y:?}",
                        shape.name
                    );
                }
            }
        }
        eprintln!(
            "{name}: rays at edge midpoints: {tally:?}, misses {misses}, grazing folds skipped {grazing}"
        );
        assert_eq!(misses, 0, "{name}: a ray aimed at an edge slipped through");
        assert_eq!(tally.disagreements, 0, "{name}: {tally:?}");
    }
}

/// The camera rays of a pixel traced together (`Accel::intersect_coherent`: 8-ray packets with
/// the coherent flag on Embree) hit what the same rays traced one by one hit, on every scene,
/// with the build the renderer uses and with the default one, in full packets and in a partial
/// one (the valid mask).
#[test]
fn packets_of_camera_rays_hit_what_single_rays_hit() {
    use lightsplit::accel::{build_embree_with, Accel};
    use lightsplit::render::camera::PinholeCamera;
    use lightsplit::render::sampler::Sampler;
    use lightsplit::scene::analysis::Analysis;

    fn check<A: Accel>(scene: &Scene, accel: &A, name: &str) {
        let (w, h) = (48, 48);
        let camera = PinholeCamera::new(&scene.camera, w, h);
        let (mut tally, mut identical) = (Tally::default(), 0);
        for pixel in 0..w * h {
            let (x, y) = (pixel % w, pixel / w);
            // 8 rays (one packet), then 5 (a partial packet), as the renderer makes them.
            for (first, n) in [(0u64, 8usize), (8, 5)] {
                let rays: Vec<Ray> = (0..n as u64)
                    .map(|k| camera.ray(x, y, Sampler::new(7, pixel as u64, first + k).next_2d()))
                    .collect();
                let mut hits = vec![None; n];
                accel.intersect_coherent(&rays, &mut hits);
                for (ray, packet) in rays.iter().zip(hits) {
                    let single = accel.intersect(ray);
                    identical += (packet == single) as usize;
                    compare(scene, ray, packet, single, &mut tally);
                }
            }
        }
        eprintln!("{name}: packets against single rays: {tally:?}, bit-identical {identical}");
        assert_eq!(tally.rays, (w * h * 13) as usize);
        assert!(tally.hits > 0, "{name}: no camera ray hit anything");
        assert_eq!(tally.disagreements, 0, "{name}: {tally:?}");
        assert!(tally.ties * 1_000 <= tally.rays, "{name}: {tally:?}");
    }

    for path in scenes() {
        let name = path.display().to_string();
        let scene = scene::load(&path).expect("loads");
        let rendered = lightsplit::accel::BuildHints::for_scene(&Analysis::of(&scene));
        check(&scene, &build_embree_with(&scene, None, rendered).expect("embree builds"), &name);
        check(
            &scene,
            &build_embree(&scene, None).expect("embree builds"),
            &format!("{name} (default build)"),
        );
        check(&scene, &Bvh::new(&scene).expect("bvh builds"), &format!("{name} (bvh)"));
    }
}
