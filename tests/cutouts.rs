//! Cut-outs: glTF's alpha modes and an OBJ's `d` and `map_d`, seen by camera rays and by
//! shadow rays, on both backends.

use std::path::{Path, PathBuf};

use lightsplit::accel::Backend;
use lightsplit::render::{render, RenderOptions};
use lightsplit::scene::Scene;
use serde_json::json;

use crate::common::GltfDoc;

/// A PNG of one row of texels, dark grey, with these alphas.
fn alpha_row(alphas: &[u8]) -> Vec<u8> {
    let mut image = image::RgbaImage::new(alphas.len() as u32, 1);
    for (x, &a) in alphas.iter().enumerate() {
        image.put_pixel(x as u32, 0, image::Rgba([40, 40, 40, a]));
    }
    let mut png = Vec::new();
    image.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).expect("png");
    png
}

/// The unit quad (facing +z) with one material, `material`'s keys added to a dark one, whose
/// base colour texture (nearest texels) has `alphas` along u; seen, when `camera`, by an
/// orthographic camera 2 units high from z = 5.
fn quad(dir: &Path, name: &str, material: serde_json::Value, alphas: &[u8], camera: bool) -> PathBuf {
    let mut doc = GltfDoc::quad();
    let texture = doc.texture(&alpha_row(alphas));
    doc.json["samplers"] = json!([{"magFilter": 9728, "minFilter": 9728}]);
    doc.json["textures"][texture]["sampler"] = json!(0);
    let mut m = json!({"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1],
        "baseColorTexture": {"index": texture}, "metallicFactor": 0.0}});
    for (k, v) in material.as_object().expect("keys") {
        m[k] = v.clone();
    }
    doc.json["materials"] = json!([m]);
    doc.json["meshes"][0]["primitives"][0]["material"] = json!(0);
    doc.node(json!({"mesh": 0}), true);
    if camera {
        doc.json["cameras"] = json!([{"type": "orthographic",
            "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.01, "zfar": 100.0}}]);
        doc.node(json!({"camera": 0, "translation": [0, 0, 5]}), true);
    }
    doc.write_gltf(dir, name)
}

fn rendered(scene: &Scene, accel: Backend, spp: u32) -> lightsplit::film::Film {
    let mut options = RenderOptions::from_scene(&scene.clone());
    (options.width, options.height, options.spp, options.accel) = (64, 64, spp, accel);
    render(scene, &options, &|_| {}).expect("renders").film
}

/// The mean red of the pixels of columns `xs` and rows `ys`.
fn mean(image: &lightsplit::film::Image, xs: std::ops::Range<u32>, ys: std::ops::Range<u32>) -> f64 {
    let n = (xs.len() * ys.len()) as f64;
    ys.flat_map(|y| xs.clone().map(move |x| (x, y))).map(|(x, y)| image.get(x, y).x as f64).sum::<f64>() / n
}

/// MASK: the quad (columns 16 to 48 of 64) is cut where its texture's alpha is under the
/// cutoff. With alpha 0 on its left half and 255 on its right, the left half shows the white
/// sky and no object, the right half the dark quad; texels of alpha 128 the default cutoff
/// (0.5) keeps and a cutoff of 0.75 cuts. Both backends.
#[test]
fn a_mask_cuts_camera_rays_where_alpha_is_under_the_cutoff() {
    let dir = tempfile::tempdir().expect("tempdir");
    for accel in [Backend::Embree, Backend::Bvh] {
        let path = quad(dir.path(), "mask", json!({"alphaMode": "MASK"}), &[0, 255], true);
        let scene = lightsplit::scene::load(&path).expect("loads");
        // `info` counts the shape as cut out.
        assert_eq!(lightsplit::scene::analysis::Analysis::of(&scene).cut_outs, 1);
        let film = rendered(&scene, accel, 4);
        let (left, right) = (mean(&film.raw, 17..31, 17..47), mean(&film.raw, 33..47, 17..47));
        assert!(left > 0.99 && right < 0.2, "{accel}: left {left}, right {right}");
        // The object buffer follows the surface seen: none through the cut half.
        let object = |x: usize, y: usize| film.object[y * 64 + x];
        assert_eq!(object(20, 30), -1.0, "{accel}");
        assert!(object(40, 30) >= 0.0, "{accel}");

        for (cutoff, kept) in [(None, true), (Some(0.75), false)] {
            let mut m = json!({"alphaMode": "MASK"});
            if let Some(c) = cutoff {
                m["alphaCutoff"] = json!(c);
            }
            let path = quad(dir.path(), "half", m, &[128], true);
            let film = rendered(&lightsplit::scene::load(&path).expect("loads"), accel, 4);
            let middle = mean(&film.raw, 20..44, 20..44);
            assert_eq!(middle < 0.5, kept, "{accel}, cutoff {cutoff:?}: {middle}");
        }
    }
}

/// A mesh two nodes place (an instance on both backends) is cut in both places, as its own
/// shape: behind the quad's cut half, the second copy's cut half shows the sky too.
#[test]
fn instanced_cut_outs_are_cut() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = quad(dir.path(), "one", json!({"alphaMode": "MASK"}), &[0, 255], true);
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).expect("read")).expect("json");
    doc["nodes"].as_array_mut().expect("nodes").push(json!({"mesh": 0, "translation": [0, 0, -1]}));
    doc["scenes"][0]["nodes"].as_array_mut().expect("scene").push(json!(2));
    std::fs::write(&path, serde_json::to_vec(&doc).expect("json")).expect("write");
    let scene = lightsplit::scene::load(&path).expect("loads");
    let instanced = scene.shapes.iter().filter(|s| match &s.geometry {
        lightsplit::scene::Geometry::Triangles(m) => m.instance.is_some(),
        _ => false,
    });
    assert_eq!(instanced.count(), 2);
    for accel in [Backend::Embree, Backend::Bvh] {
        let film = rendered(&scene, accel, 4);
        let (left, right) = (mean(&film.raw, 17..31, 17..47), mean(&film.raw, 33..47, 17..47));
        assert!(left > 0.99 && right < 0.2, "{accel}: left {left}, right {right}");
    }
}

/// A cut-out leaf casts the cut-out's shadow: the leaf (the quad turned to face up, one unit
/// above a white floor, its left half, x < 0, cut) under a sun at 45 degrees towards -x shadows
/// the floor from x = 1 to 1.5 (the kept half's shadow) and not from 0.5 to 1 (the cut half's),
/// seen from above by an orthographic camera 4 units wide. Both backends.
#[test]
fn a_cut_out_casts_the_shadow_of_its_cut_out() {
    let dir = tempfile::tempdir().expect("tempdir");
    quad(dir.path(), "leaf", json!({"alphaMode": "MASK"}), &[0, 255], false);
    let text = "[camera]\nposition = [0, 5, 0]\nlook_at = [0, 0, 0]\nup = [0, 0, -1]\northographic = 4\n\
         [[light]]\ntype = \"sun\"\ndirection = [-1, 1, 0]\nirradiance = [1, 1, 1]\n\
         [[shape]]\ntype = \"quad\"\nvertices = [[-3, 0, -3], [-3, 0, 3], [3, 0, 3], [3, 0, -3]]\n\
         [[shape]]\ntype = \"gltf\"\nfile = \"leaf.gltf\"\ntransform = { rotate = [-90, 0, 0], translate = [0, 1, 0] }\n";
    let path = dir.path().join("shadow.toml");
    std::fs::write(&path, text).expect("write");
    for accel in [Backend::Embree, Backend::Bvh] {
        let scene = lightsplit::scene::load(&path).expect("loads");
        let film = rendered(&scene, accel, 4);
        // Columns: x = -2 + (column + 0.5) / 16; rows 26 to 38 lie over the leaf's z.
        let at = |xs: std::ops::Range<u32>| mean(&film.raw, xs, 26..38);
        let (open, kept, through, cut_shadow, shadow) =
            (at(1..7), at(33..39), at(25..31), at(41..47), at(49..55));
        assert!(kept < 0.2 * open, "{accel}: the kept half {kept}, open floor {open}");
        assert!((through - open).abs() < 0.02 * open, "{accel}: through the cut half {through}, open {open}");
        assert!((cut_shadow - open).abs() < 0.02 * open, "{accel}: under the cut half's shadow {cut_shadow}");
        assert!(shadow < 0.05 * open, "{accel}: the kept half's shadow {shadow}, open floor {open}");
    }
}

/// BLEND is stochastic transparency: a quad of alpha 0.3 over the white sky has, in the mean,
/// 0.3 of the opaque quad's radiance and 0.7 of the sky's, within the noise (five standard
/// errors of the pixels' mean, from their spread), on both backends.
#[test]
fn a_blend_mean_is_alpha_weighted_mixing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let alpha = 0.3;
    let a = (alpha * 255.0f64).round() as u8;
    for accel in [Backend::Embree, Backend::Bvh] {
        let opaque = quad(dir.path(), "opaque", json!({}), &[a], true);
        let blend = quad(dir.path(), "blend", json!({"alphaMode": "BLEND"}), &[a], true);
        let opaque = rendered(&lightsplit::scene::load(&opaque).expect("loads"), accel, 4);
        let blend = rendered(&lightsplit::scene::load(&blend).expect("loads"), accel, 16);
        let (xs, ys) = (20..44, 20..44);
        let quad = mean(&opaque.raw, xs.clone(), ys.clone());
        let sky = mean(&opaque.raw, 1..8, 1..63);
        let want = a as f64 / 255.0 * quad + (1.0 - a as f64 / 255.0) * sky;
        let values: Vec<f64> = ys
            .flat_map(|y| xs.clone().map(move |x| (x, y)))
            .map(|(x, y)| blend.raw.get(x, y).x as f64)
            .collect();
        let (got, se) = crate::common::mean_and_standard_error_of(&values);
        assert!(se > 0.0, "{accel}: blending is noisy");
        assert!((got - want).abs() < 5.0 * se, "{accel}: {got} against {want} (standard error {se})");
        // Not simply opaque or simply absent.
        assert!(got > quad + 0.2 && got < sky - 0.1, "{accel}: {got} between {quad} and {sky}");
    }
}

/// An OBJ's `map_d` cuts its surface (here the left half of a quad, seen through to a white
/// emitter behind it) and `d` blends it, on both backends.
#[test]
fn obj_d_and_map_d_cut_and_blend() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut png = Vec::new();
    image::GrayImage::from_fn(8, 1, |x, _| image::Luma([if x < 4 { 0 } else { 255 }]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("png");
    std::fs::write(dir.path().join("mask.png"), &png).expect("write");
    std::fs::write(
        dir.path().join("leaf.mtl"),
        "newmtl cut\nKd 0.05 0.05 0.05\nmap_d mask.png\nnewmtl thin\nKd 0.05 0.05 0.05\nd 0.3\n",
    )
    .expect("write");
    for (material, name) in [("cut", "cut.obj"), ("thin", "thin.obj")] {
        std::fs::write(
            dir.path().join(name),
            format!(
                "mtllib leaf.mtl\nv -0.5 -0.5 0\nv 0.5 -0.5 0\nv 0.5 0.5 0\nv -0.5 0.5 0\n\
                 vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl {material}\nf 1/1 2/2 3/3 4/4\n"
            ),
        )
        .expect("write");
    }
    let scene_text = |mesh: &str| {
        format!(
            "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\northographic = 1\n\
             [[shape]]\ntype = \"mesh\"\nfile = \"{mesh}\"\n\
             [[shape]]\ntype = \"quad\"\nemission = [1, 1, 1]\nvertices = [[-2, -2, -1], [2, -2, -1], [2, 2, -1], [-2, 2, -1]]\n"
        )
    };
    for accel in [Backend::Embree, Backend::Bvh] {
        let path = dir.path().join("cut.toml");
        std::fs::write(&path, scene_text("cut.obj")).expect("write");
        let film = rendered(&lightsplit::scene::load(&path).expect("loads"), accel, 4);
        // The quad fills the image; texels 0 to 3 of 8 have coverage 0, 4 to 7 coverage 1 (a
        // grey image: its value), blended bilinearly only between neighbours.
        let (left, right) = (mean(&film.raw, 6..26, 2..62), mean(&film.raw, 38..58, 2..62));
        assert!(left > 0.99 && right < 0.1, "{accel}: map_d: left {left}, right {right}");

        let path = dir.path().join("thin.toml");
        std::fs::write(&path, scene_text("thin.obj")).expect("write");
        let film = rendered(&lightsplit::scene::load(&path).expect("loads"), accel, 16);
        // 0.7 of the emitter is seen through; the quad itself, lit by nothing in front, is
        // black: within five standard errors of the pixels' mean.
        let values: Vec<f64> = (2..62u32)
            .flat_map(|y| (2..62u32).map(move |x| (x, y)))
            .map(|(x, y)| film.raw.get(x, y).x as f64)
            .collect();
        let (seen, se) = crate::common::mean_and_standard_error_of(&values);
        assert!(se > 0.0 && (seen - 0.7).abs() < 5.0 * se, "{accel}: d 0.3: {seen} (standard error {se})");
    }
}

/// An emitter with a cut-out emits only where it is not cut, by light sampling as by rays that
/// hit it: the floor beside an emitting quad whose left half is cut (MASK, an emissive factor)
/// is as bright, within the noise, as beside an opaque quad whose left half emits nothing (an
/// emissive texture black there). Light samples on the cut half would make it brighter.
#[test]
fn a_cut_out_emitter_emits_only_where_it_is_not_cut() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut png = Vec::new();
    let mut image = image::RgbaImage::new(2, 1);
    image.put_pixel(0, 0, image::Rgba([0, 0, 0, 0]));
    image.put_pixel(1, 0, image::Rgba([255, 255, 255, 255]));
    image.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).expect("png");
    let write = |name: &str, material: serde_json::Value| {
        let mut doc = GltfDoc::quad();
        let texture = doc.texture(&png);
        doc.json["samplers"] = json!([{"magFilter": 9728, "minFilter": 9728}]);
        doc.json["textures"][texture]["sampler"] = json!(0);
        let mut m = json!({"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0}});
        for (k, v) in material.as_object().expect("keys") {
            m[k] = v.clone();
        }
        doc.json["materials"] = json!([m]);
        doc.json["meshes"][0]["primitives"][0]["material"] = json!(0);
        doc.node(json!({"mesh": 0}), true);
        doc.write_gltf(dir.path(), name);
    };
    write(
        "cut",
        json!({"alphaMode": "MASK", "emissiveFactor": [1, 1, 1],
            "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}),
    );
    write("dark", json!({"emissiveFactor": [1, 1, 1], "emissiveTexture": {"index": 0}}));
    let floor = |accel: Backend, emitter: &str| {
        let text = format!(
            "[camera]\nposition = [0, 5, 0]\nlook_at = [0, 0, 0]\nup = [0, 0, -1]\northographic = 4\n\
             [[shape]]\ntype = \"quad\"\nvertices = [[-3, 0, -3], [-3, 0, 3], [3, 0, 3], [3, 0, -3]]\n\
             [[shape]]\ntype = \"gltf\"\nfile = \"{emitter}.gltf\"\ntransform = {{ rotate = [90, 0, 0], translate = [0, 0.5, 0] }}\n"
        );
        let path = dir.path().join(format!("{emitter}.toml"));
        std::fs::write(&path, text).expect("write");
        let film = rendered(&lightsplit::scene::load(&path).expect("loads"), accel, 64);
        // The floor from x = 0.75 to 1.75 (columns 44 to 60), beside the emitter.
        (24..40u32)
            .flat_map(|y| (44..60u32).map(move |x| (x, y)))
            .map(|(x, y)| film.raw.get(x, y).x as f64)
            .collect::<Vec<f64>>()
    };
    for accel in [Backend::Embree, Backend::Bvh] {
        let (cut, dark) = (floor(accel, "cut"), floor(accel, "dark"));
        // Pixel by pixel, so that the floor's falloff cancels and only the noise is left.
        let differences: Vec<f64> = cut.iter().zip(&dark).map(|(a, b)| a - b).collect();
        let (difference, se) = crate::common::mean_and_standard_error_of(&differences);
        let lit = dark.iter().sum::<f64>() / dark.len() as f64;
        assert!(lit > 0.0 && se > 0.0, "{accel}: the floor is lit");
        assert!(
            difference.abs() < 5.0 * se,
            "{accel}: {difference} brighter beside the cut emitter than the half-dark one's {lit} (se {se})"
        );
    }
}
