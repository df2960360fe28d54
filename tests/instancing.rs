//! Meshes used by several glTF nodes are shared (instanced), not copied: the same hits, surfaces,
//! light and image as the same file with a copy of the mesh for every node, on both backends.

use std::path::{Path, PathBuf};

use glam::Vec3;
use lightsplit::accel::{build_embree, bvh::Bvh, Accel, Backend, Hit, Ray};
use lightsplit::render::surface::surface;
use lightsplit::render::{render, RenderOptions};
use lightsplit::scene::analysis::Analysis;
use lightsplit::scene::{self, Geometry, Scene};
use serde_json::json;

use crate::common::GltfDoc;

/// A GLB's JSON and binary chunks.
fn read_glb(bytes: &[u8]) -> GltfDoc {
    let u32_at = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().expect("4 bytes")) as usize;
    let json_len = u32_at(12);
    let json = serde_json::from_slice(&bytes[20..20 + json_len]).expect("glb json");
    let bin_at = 20 + json_len;
    let bin = bytes[bin_at + 8..bin_at + 8 + u32_at(bin_at)].to_vec();
    GltfDoc { json, bin }
}

/// The same document with nothing shared: every node that uses a mesh gets a mesh of its own
/// (the same accessors under another index), which the reader copies into the node's place.
fn unshared(doc: &GltfDoc) -> GltfDoc {
    let mut out = GltfDoc { json: doc.json.clone(), bin: doc.bin.clone() };
    let meshes = doc.json["meshes"].as_array().expect("meshes").clone();
    let mut own = Vec::new();
    for node in out.json["nodes"].as_array_mut().expect("nodes") {
        if let Some(m) = node["mesh"].as_u64() {
            own.push(meshes[m as usize].clone());
            node["mesh"] = json!(own.len() - 1);
        }
    }
    out.json["meshes"] = json!(own);
    out
}

/// `scenes/instances.toml` as it is, and with its glTF's meshes copied into every node.
fn instanced_and_copied(dir: &Path) -> (Scene, Scene) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let glb = std::fs::read(root.join("gltf/instances.glb")).expect("scenes/gltf/instances.glb");
    std::fs::create_dir_all(dir.join("gltf")).expect("mkdir");
    std::fs::write(dir.join("gltf/instances.glb"), unshared(&read_glb(&glb)).glb()).expect("write");
    std::fs::copy(root.join("sky.hdr"), dir.join("sky.hdr")).expect("copy the map");
    let text = std::fs::read_to_string(root.join("instances.toml")).expect("scene");
    let copied: PathBuf = dir.join("instances.toml");
    std::fs::write(&copied, text).expect("write");
    let instanced = scene::load(&root.join("instances.toml")).expect("loads");
    (instanced, scene::load(&copied).expect("loads"))
}

/// The smallest barycentric weight of a hit: near 0, the hit is near an edge of its triangle,
/// where rounding may pick the neighbour.
fn edge_distance(h: &Hit) -> f32 {
    h.u.min(h.v).min(1.0 - h.u - h.v)
}

/// Hits of the two scenes agree: both miss, or both hit the same shape's same triangle at the
/// same distance (up to the rounding of the placements, f32 in one and f64 in the other, a few
/// ulps of the coordinates, over the cosine of incidence). Returns whether they disagree
/// somewhere an edge excuses (within 1e-3 of one, in either), or `Err` where nothing does.
fn agree(scene: &Scene, ray: &Ray, a: Option<Hit>, b: Option<Hit>, size: f32) -> Result<bool, String> {
    match (a, b) {
        (None, None) => Ok(false),
        (Some(x), Some(y)) if (x.shape, x.prim) == (y.shape, y.prim) => {
            let Geometry::Triangles(mesh) = &scene.shapes[y.shape as usize].geometry else {
                return Err("not a mesh".into());
            };
            let [p, q, r] = mesh.triangle(y.prim);
            let cos = (q - p).cross(r - p).normalize_or_zero().dot(ray.dir.normalize()).abs().max(1e-2);
            let tolerance = 1e-5 * (x.t.max(y.t) + size / ray.dir.length()) / cos;
            if (x.t - y.t).abs() <= tolerance {
                Ok(false)
            } else if edge_distance(&x).min(edge_distance(&y)) < 1e-3 {
                Ok(true)
            } else {
                Err(format!("t {} against {} (tolerance {tolerance})", x.t, y.t))
            }
        }
        (x, y) => {
            let near_edge = x.iter().chain(y.iter()).any(|h| edge_distance(h) < 1e-3);
            if near_edge {
                Ok(true)
            } else {
                Err(format!("{x:?} against {y:?}"))
            }
        }
    }
}

/// Camera rays over the field and rays leaving their hits in scattered directions.
fn rays(scene: &Scene, accel: &impl Accel) -> Vec<Ray> {
    let mut out = Vec::new();
    let (lo, hi) = scene.bounds();
    let mut next = crate::common::uniform_stream(0x9e3779b97f4a7c15u64);
    for _ in 0..4000 {
        let target = lo + (hi - lo) * Vec3::new(next(), next(), next());
        let ray = Ray::new(Vec3::ZERO, target);
        out.push(ray);
        if let Some(h) = accel.intersect(&ray) {
            let s = surface(scene, &ray, &h);
            let d = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5);
            let d = if d.dot(s.ng) < 0.0 { -d } else { d };
            out.push(Ray::new(s.origin(s.ng), d));
        }
    }
    out
}

/// On both backends, the instanced scene hits what the copied one does, and the surfaces at the
/// hits (point, geometric and shading normal) are the same; `info` counts 98 instances of
/// 2 meshes (one mesh, two materials), the triangles stored once.
#[test]
fn a_mesh_used_by_several_nodes_is_shared_and_hit_as_its_copies() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (instanced, copied) = instanced_and_copied(dir.path());
    let (a, b) = (Analysis::of(&instanced), Analysis::of(&copied));
    assert_eq!((a.instances, a.shared_meshes), (49, 2), "{a:?}");
    assert_eq!((b.instances, b.shared_meshes), (0, 0), "{b:?}");
    assert_eq!(a.triangles, b.triangles);
    assert_eq!(a.stored_triangles, 2 + 2 * 528, "{a:?}");
    assert_eq!(b.stored_triangles, b.triangles);
    let (lo, hi) = copied.bounds();
    let size = lo.abs().max(hi.abs()).max_element();
    let check = |name: &str, x: &dyn Accel, y: &dyn Accel, rays: &[Ray]| {
        let (mut hits, mut excused) = (0usize, 0usize);
        for ray in rays {
            let (hx, hy) = (x.intersect(ray), y.intersect(ray));
            match agree(&copied, ray, hx, hy, size) {
                Ok(e) => excused += e as usize,
                Err(e) => panic!("{name}: {ray:?}: {e}"),
            }
            assert_eq!(x.occluded(ray), hx.is_some(), "{name}: occlusion of {ray:?}");
            if let (Some(hx), Some(hy)) = (hx, hy) {
                if (hx.shape, hx.prim) != (hy.shape, hy.prim) {
                    continue;
                }
                hits += 1;
                let (sx, sy) = (surface(&instanced, ray, &hx), surface(&copied, ray, &hy));
                assert!((sx.p - sy.p).length() <= 1e-4 * size, "{name}: point {} against {}", sx.p, sy.p);
                assert!(sx.ng.dot(sy.ng) > 1.0 - 1e-5, "{name}: normal {} against {}", sx.ng, sy.ng);
                assert!(sx.ns.dot(sy.ns) > 1.0 - 1e-5, "{name}: shading normal {} against {}", sx.ns, sy.ns);
                assert!((sx.uv - sy.uv).length() < 1e-4, "{name}: uv {} against {}", sx.uv, sy.uv);
            }
        }
        eprintln!("{name}: {} rays, {hits} hits, {excused} differences at edges", rays.len());
        assert!(hits > 2000, "{name}: too few hits ({hits}) to say anything");
        assert!(excused * 1000 <= rays.len(), "{name}: {excused} differences at edges");
    };
    let embree =
        (build_embree(&instanced, None).expect("embree"), build_embree(&copied, None).expect("embree"));
    let bvh = (Bvh::new(&instanced).expect("bvh"), Bvh::new(&copied).expect("bvh"));
    assert_eq!(bvh.0.instance_counts(), (49, 2));
    assert_eq!(bvh.1.instance_counts(), (0, 0));
    let rays = rays(&copied, &embree.1);
    check("embree", &embree.0, &embree.1, &rays);
    check("bvh", &bvh.0, &bvh.1, &rays);
}

/// An emissive mesh used by several nodes lights the floor as its copies do (light sampling
/// reads the placed triangles), on both backends, within the noise of the two renders.
#[test]
fn shared_emissive_meshes_light_the_scene_as_copies_do() {
    let mut doc = GltfDoc::quad();
    doc.json["materials"] = json!([
        {"name": "lamp", "emissiveFactor": [1.0, 0.9, 0.8],
         "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0, "roughnessFactor": 1}},
        {"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1], "metallicFactor": 0, "roughnessFactor": 1}},
    ]);
    doc.json["meshes"][0]["primitives"][0]["material"] = json!(0);
    let floor = doc.json["meshes"][0].clone();
    doc.json["meshes"].as_array_mut().expect("meshes").push(floor);
    doc.json["meshes"][1]["primitives"][0]["material"] = json!(1);
    let down = [std::f64::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2];
    for (i, x) in [-1.5, 0.0, 1.5].into_iter().enumerate() {
        // Turned about x by 90 degrees: the quad's +z front faces down (-y), 1 unit up.
        doc.node(json!({"name": format!("lamp{i}"), "mesh": 0, "translation": [x, 1.0, 0.0], "rotation": down, "scale": [0.8, 0.8, 1.0]}), true);
    }
    let up = [-std::f64::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2];
    doc.node(json!({"name": "floor", "mesh": 1, "rotation": up, "scale": [6.0, 3.0, 1.0]}), true);
    doc.node(json!({"name": "eye", "camera": 0, "translation": [0.0, 0.5, 4.0]}), true);
    doc.json["cameras"] =
        json!([{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "aspectRatio": 1.0}}]);
    let dir = tempfile::tempdir().expect("tempdir");
    let shared = scene::load(&doc.write_gltf(dir.path(), "shared")).expect("loads");
    let copies = scene::load(&unshared(&doc).write_gltf(dir.path(), "copies")).expect("loads");
    assert_eq!(Analysis::of(&shared).instances, 3);
    assert_eq!(Analysis::of(&copies).instances, 0);
    for accel in [Backend::Embree, Backend::Bvh] {
        let image = |s: &Scene, seed: u64| {
            let mut options = RenderOptions::from_scene(s);
            (options.width, options.height, options.spp, options.seed, options.accel) =
                (32, 32, 16, seed, accel);
            render(s, &options, &|_| {}).expect("renders").film.raw
        };
        let (a, b) = (image(&shared, 1), image(&copies, 2));
        let (ma, ea) = crate::common::mean_and_standard_error(&a);
        let (mb, eb) = crate::common::mean_and_standard_error(&b);
        eprintln!("{accel:?}: shared {ma} +- {ea}, copies {mb} +- {eb}");
        assert!(ma > 0.01, "{accel:?}: the lamps light the floor ({ma})");
        assert!(
            (ma - mb).abs() <= 4.0 * (ea * ea + eb * eb).sqrt(),
            "{accel:?}: {ma} +- {ea} against {mb} +- {eb}"
        );
    }
}

/// Rendered at the same seed, the instanced and copied scenes differ only where rounding sends
/// a path another way: far less than two seeds of the copied scene differ.
#[test]
fn an_instanced_scene_renders_as_its_copies() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (instanced, copied) = instanced_and_copied(dir.path());
    for accel in [Backend::Embree, Backend::Bvh] {
        let image = |s: &Scene, seed: u64| {
            let mut options = RenderOptions::from_scene(s);
            (options.width, options.height, options.spp, options.seed, options.accel) =
                (64, 40, 16, seed, accel);
            render(s, &options, &|_| {}).expect("renders").film.raw
        };
        let reference = image(&copied, 1);
        let rmse = |a: &lightsplit::film::Image| {
            lightsplit::metrics::compare(a, &reference).expect("same size").rmse
        };
        let same_seed = rmse(&image(&instanced, 1));
        let other_seed = rmse(&image(&copied, 2));
        eprintln!("{accel:?}: rmse: instanced {same_seed}, another seed {other_seed}");
        assert!(
            same_seed < 0.3 * other_seed,
            "{accel:?}: instanced {same_seed} against another seed {other_seed}"
        );
    }
}

/// Rays leaving a shared mesh never hit it again: the ray origin's offset covers the rounding of
/// the placement, both ways (the hit point placed into the scene, the next ray taken back into
/// the mesh's coordinates), at large and small scales, turned, and sheared (a turned child of a
/// node scaled unevenly). The mesh is a closed cube, convex, so any hit of its own shape by a
/// ray leaving it outward is a self-hit.
#[test]
fn rays_leaving_an_instance_do_not_hit_it_again() {
    let mut doc = GltfDoc::quad();
    let p: Vec<f32> = (0..8)
        .flat_map(|i| [(i & 1) as f32 - 0.5, ((i >> 1) & 1) as f32 - 0.5, ((i >> 2) & 1) as f32 - 0.5])
        .collect();
    let p = doc.floats(&p, "VEC3");
    // Outward winding: each face's corners counter-clockwise seen from outside.
    let faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let indices: Vec<u32> = faces.iter().flat_map(|f| [f[0], f[1], f[2], f[0], f[2], f[3]]).collect();
    let i = doc.indices(&indices);
    // The same cube with coordinates 5000 units out in its own space, placed back near the
    // camera: the rounding that matters is the mesh's own, not the scene's.
    let far: Vec<f32> = (0..8)
        .flat_map(|i| [(i & 1) as f32 + 4999.5, ((i >> 1) & 1) as f32 - 0.5, ((i >> 2) & 1) as f32 + 4999.5])
        .collect();
    let far = doc.floats(&far, "VEC3");
    doc.json["meshes"] = json!([
        {"name": "cube", "primitives": [{"attributes": {"POSITION": p}, "indices": i}]},
        {"name": "far", "primitives": [{"attributes": {"POSITION": far}, "indices": i}]},
    ]);
    doc.node(json!({"name": "far-a", "mesh": 1, "translation": [-5001, 0, -5003]}), true);
    doc.node(json!({"name": "far-b", "mesh": 1, "translation": [-4998.5, 0.5, -5004], "rotation": [0, 0.1, 0, 0.994_987_437_106_62f64]}), true);
    let turn = [0.3, 0.5, 0.1, 0.806_225_774_829_854_9f64];
    doc.node(json!({"name": "large", "mesh": 0, "translation": [3000, 200, -4000], "rotation": turn, "scale": [1000, 1000, 1000]}), true);
    doc.node(json!({"name": "small", "mesh": 0, "translation": [0.01, 0.002, -0.03], "rotation": turn, "scale": [0.001, 0.001, 0.001]}), true);
    let sheared = doc.node(json!({"name": "sheared", "mesh": 0, "rotation": [0, 0, 0.382_683_432_365_089_8f64, 0.923_879_532_511_286_7f64]}), false);
    doc.node(
        json!({"name": "stretch", "translation": [4, 1, -2], "scale": [1, 30, 0.2], "children": [sheared]}),
        true,
    );
    doc.node(json!({"name": "plain", "mesh": 0, "translation": [-2, 0, -1]}), true);
    // The camera (the scene's origin) near the small cubes, so their coordinates are small.
    doc.node(json!({"name": "eye", "camera": 0, "translation": [0, 0, 2]}), true);
    doc.json["cameras"] = json!([{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}]);
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = scene::load(&doc.write_gltf(dir.path(), "cubes")).expect("loads");
    assert_eq!(Analysis::of(&scene).instances, 6);
    let embree = build_embree(&scene, None).expect("embree");
    let bvh = Bvh::new(&scene).expect("bvh");
    let mut next = crate::common::uniform_stream(0x2545f4914f6cdd1du64);
    let accels: [(&str, &dyn Accel); 2] = [("embree", &embree), ("bvh", &bvh)];
    for (name, accel) in accels {
        let (mut rays, mut self_hits) = (0usize, 0usize);
        for (k, shape) in scene.shapes.iter().enumerate() {
            let Geometry::Triangles(mesh) = &shape.geometry else { panic!("a mesh") };
            let corners: Vec<Vec3> = (0..12).flat_map(|t| mesh.triangle(t)).collect();
            let centre = corners.iter().copied().sum::<Vec3>() / corners.len() as f32;
            let size = corners.iter().map(|&c| (c - centre).length()).fold(0.0, f32::max);
            for _ in 0..400 {
                let d = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5).normalize_or(Vec3::X);
                let target = centre + Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * size * 0.5;
                let ray = Ray::new(target + d * 4.0 * size, -d * size);
                let Some(hit) = accel.intersect(&ray) else { continue };
                if hit.shape != k as u32 {
                    continue;
                }
                let s = surface(&scene, &ray, &hit);
                let out = if s.ng.dot(ray.dir) < 0.0 { s.ng } else { -s.ng };
                let origin = s.origin(out);
                for e in [1e-3f32, 1e-2, 0.1, 0.5, 1.0] {
                    let phi = std::f32::consts::TAU * next();
                    let frame = lightsplit::math::Frame::new(out);
                    let d = frame.to_world(Vec3::new(phi.cos(), phi.sin(), e).normalize());
                    rays += 1;
                    if accel.intersect(&Ray::new(origin, d)).is_some_and(|h| h.shape == hit.shape) {
                        self_hits += 1;
                    }
                }
            }
        }
        eprintln!("{name}: {rays} rays leaving the cubes, {self_hits} self-hits");
        assert!(rays > 4000, "{name}: too few rays ({rays})");
        assert_eq!(self_hits, 0, "{name}: {self_hits} of {rays} rays hit the cube they leave");
    }
}
