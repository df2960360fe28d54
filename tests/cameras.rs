//! Cameras: the orthographic camera's image of a cube, and a glTF's orthographic camera.

use std::path::Path;

use lightsplit::accel::Backend;
use lightsplit::render::{render, RenderOptions};
use lightsplit::scene::file::parse;

/// An orthographic camera seeing 4 units from the image's bottom to its top looks straight at a
/// unit cube: its image is a square a quarter of the image's height on a side (16 of 64 pixels,
/// whatever the distance), centred, on both backends. A pinhole camera at the same place sees it
/// smaller from farther away; the orthographic one does not.
#[test]
fn the_orthographic_image_of_a_unit_cube_is_a_square_of_its_size() {
    for accel in [Backend::Embree, Backend::Bvh] {
        for distance in [3.0, 30.0] {
            let text = format!(
                "[camera]\nposition = [0, 0, {distance}]\nlook_at = [0, 0, 0]\northographic = 4\n\
                 [film]\nwidth = 64\nheight = 64\n\
                 [[shape]]\ntype = \"box\"\nmin = [-0.5, -0.5, -0.5]\nmax = [0.5, 0.5, 0.5]\nemission = [1, 1, 1]\n"
            );
            let scene = parse(Path::new("o.toml"), &text).expect("parses");
            let mut options = RenderOptions::from_scene(&scene);
            (options.spp, options.accel) = (4, accel);
            let image = render(&scene, &options, &|_| {}).expect("renders").film.raw;
            let lit: Vec<(u32, u32)> = (0..64u32)
                .flat_map(|y| (0..64u32).map(move |x| (x, y)))
                .filter(|&(x, y)| image.get(x, y).x > 0.5)
                .collect();
            // Every pixel fully inside the square is lit, none outside it: its edges lie on
            // pixel boundaries (24 to 40), so the antialiased border is not more than half lit.
            assert_eq!(lit.len(), 16 * 16, "{accel} at {distance}: {} pixels lit", lit.len());
            assert!(lit.iter().all(|&(x, y)| (24..40).contains(&x) && (24..40).contains(&y)), "{accel}");
        }
    }
}

/// A glTF orthographic camera (`ymag` 1: a view 2 units high; `xmag` 1: a square image) looking at
/// the unit quad shows it as a square half the image on a side, without the camera note.
#[test]
fn a_gltf_orthographic_camera_is_read() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut doc = crate::common::GltfDoc::quad();
    doc.json["materials"] = serde_json::json!([{"pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.2, 0.2, 1], "metallicFactor": 0.0}}]);
    doc.json["meshes"][0]["primitives"][0]["material"] = serde_json::json!(0);
    doc.node(serde_json::json!({"mesh": 0}), true);
    doc.json["cameras"] = serde_json::json!([{"type": "orthographic",
        "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.01, "zfar": 100.0}}]);
    doc.node(serde_json::json!({"camera": 0, "translation": [0, 0, 5]}), true);
    let path = doc.write_gltf(dir.path(), "ortho");
    let scene = lightsplit::scene::load(&path).expect("loads");
    assert_eq!(scene.camera.orthographic, Some(2.0));
    assert!(scene.notes.iter().all(|n| !n.contains("orthographic")), "{:?}", scene.notes);
    let mut options = RenderOptions::from_scene(&scene);
    (options.width, options.height, options.spp) = (64, 64, 4);
    let image = render(&scene, &options, &|_| {}).expect("renders").film.raw;
    // The sky is 1, the grey quad under it about 0.2: its edges lie on pixel boundaries (16
    // to 48), so exactly its 32 x 32 pixels are dark.
    let dark: Vec<usize> = (0..image.pixels.len()).filter(|&i| image.pixels[i].x < 0.5).collect();
    assert_eq!(dark.len(), 32 * 32, "{} pixels show the quad", dark.len());
    assert!(dark.iter().all(|&i| (16..48).contains(&(i % 64)) && (16..48).contains(&(i / 64))));
}

fn render_text(text: &str, accel: Backend, spp: u32, seed: u64) -> lightsplit::film::Image {
    let scene = parse(Path::new("lens.toml"), text).expect("parses");
    let mut options = RenderOptions::from_scene(&scene);
    (options.spp, options.accel, options.seed) = (spp, accel, seed);
    render(&scene, &options, &|_| {}).expect("renders").film.raw
}

/// A checker-textured plane at the focus distance is as sharp through a thin lens as through
/// the pinhole: the lens image is no farther from a pinhole image than a second pinhole image
/// of another seed is (their difference is the noise alone), and the same lens focused at half
/// the distance is several times farther (the test can tell a blurred image). Both backends.
#[test]
fn a_thin_lens_is_sharp_at_its_focus_distance() {
    let scene = |lens: &str| {
        format!(
            "[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\nfov = 30\n{lens}\n\
             [film]\nwidth = 48\nheight = 48\n\
             [[light]]\ntype = \"sky\"\nradiance = [1, 1, 1]\n\
             [[texture]]\nname = \"checks\"\ntype = \"checker\"\nsize = 0.125\ncolor = [0.9, 0.9, 0.9]\ncolor2 = [0.05, 0.05, 0.05]\n\
             [[material]]\nname = \"board\"\ntype = \"diffuse\"\ntexture = \"checks\"\n\
             [[shape]]\ntype = \"quad\"\nmaterial = \"board\"\nvertices = [[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]]\n"
        )
    };
    let rmse = |a: &lightsplit::film::Image, b: &lightsplit::film::Image| {
        lightsplit::metrics::compare(a, b).expect("compares").rmse
    };
    for accel in [Backend::Embree, Backend::Bvh] {
        let pinhole = render_text(&scene(""), accel, 64, 1);
        let other = render_text(&scene(""), accel, 64, 2);
        let sharp = render_text(&scene("aperture = 0.2\nfocus_distance = 4"), accel, 64, 3);
        let blurred = render_text(&scene("aperture = 0.2\nfocus_distance = 2"), accel, 64, 3);
        let (noise, lens, defocus) =
            (rmse(&other, &pinhole), rmse(&sharp, &pinhole), rmse(&blurred, &pinhole));
        assert!(noise > 0.0, "{accel}");
        assert!(lens < 1.5 * noise, "{accel}: in focus {lens} against the noise {noise}");
        assert!(defocus > 4.0 * noise, "{accel}: out of focus {defocus} against the noise {noise}");
    }
}

/// The circle of confusion: a small emitting sphere at distance 2 seen through a lens of
/// radius A = 0.4 focused at 4 is a disc of radius A |2 - 4| / 2 = 0.4 on the plane of focus,
/// 0.4 / (4 tan 20 degrees) of the image's half height. Its radius, from the second moment of
/// the disc's light (a uniform disc's mean squared radius is R^2 / 2; the sphere's own image
/// and the pixels' width add their own, subtracted), is the lens formula's within 3%. Both
/// backends; `f_number` gives the radius of its focal length on a full-frame sensor.
#[test]
fn an_out_of_focus_point_is_a_disc_of_the_lens_formula_radius() {
    let (size, fov, distance, focus, aperture, sphere) = (64.0f64, 40.0f64, 2.0, 4.0, 0.4, 0.02);
    let text = format!(
        "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\nfov = {fov}\naperture = {aperture}\nfocus_distance = {focus}\n\
         [film]\nwidth = {size}\nheight = {size}\n\
         [[shape]]\ntype = \"sphere\"\ncenter = [0, 0, -{distance}]\nradius = {sphere}\nemission = [1, 1, 1]\n"
    );
    let half = focus * (0.5 * fov).to_radians().tan();
    let pixels = |on_focus_plane: f64| on_focus_plane / half * size / 2.0;
    let want = pixels(aperture * (distance - focus).abs() / distance);
    // The sphere's image on the plane of focus (seen from the lens centre), and a pixel's box.
    let own = pixels(sphere * focus / distance);
    for accel in [Backend::Embree, Backend::Bvh] {
        let image = render_text(&text, accel, 1024, 1);
        let (mut weight, mut moment) = (0.0f64, 0.0f64);
        for y in 0..size as u32 {
            for x in 0..size as u32 {
                let w = image.get(x, y).x as f64;
                let (dx, dy) = (x as f64 + 0.5 - size / 2.0, y as f64 + 0.5 - size / 2.0);
                weight += w;
                moment += w * (dx * dx + dy * dy);
            }
        }
        let mean_square = moment / weight;
        let got = (2.0 * (mean_square - own * own / 2.0 - 1.0 / 6.0)).sqrt();
        assert!((got / want - 1.0).abs() < 0.03, "{accel}: radius {got:.3} pixels against {want:.3}");
    }
    // An f-number: the focal length of a 40-degree view on a 24 mm high sensor, over 2 N.
    let scene = parse(
        Path::new("f.toml"),
        "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -3]\nfov = 40\nf_number = 2\n",
    )
    .expect("parses");
    let lens = scene.camera.lens.expect("a lens");
    let focal = 0.012 / 20f64.to_radians().tan();
    assert!((lens.radius as f64 - focal / 4.0).abs() < 1e-7, "{}", lens.radius);
    assert_eq!(lens.focus_distance, 3.0);
}

/// The lens keys are checked: both forms of aperture, a focus without a lens, a focus point
/// behind the camera, a zero aperture, each one error naming the key.
#[test]
fn bad_lens_keys_are_errors() {
    let camera = "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\n";
    for (keys, says) in [
        ("aperture = 0.1\nf_number = 2", "not both"),
        ("focus_distance = 3", "needs a lens"),
        ("aperture = 0.1\nfocus_on = [0, 0, 5]", "in front of the camera"),
        ("aperture = 0", "`aperture` must be a positive number"),
        ("aperture = 0.1\nfocus_distance = 2\nfocus_on = [0, 0, -2]", "not both"),
    ] {
        let err = parse(Path::new("bad.toml"), &format!("{camera}{keys}\n")).expect_err(keys);
        assert!(err.to_string().contains(says), "{keys}: {err}");
    }
}
