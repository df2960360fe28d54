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
