//! Issue 19: the scenes people have (HDRI environment maps, glTF, OBJ materials) come in, and bad
//! ones are one clear error with exit status 2, never a panic.

use std::path::Path;
use std::process::Command;

use crate::common::pfm;

/// Renders `scene` (written into `dir`) to a PNG there; returns the exit code and stderr.
fn render_in(dir: &Path, scene: &str) -> (Option<i32>, String) {
    std::fs::write(dir.join("s.toml"), scene).expect("write");
    let o = Command::new(env!("CARGO_BIN_EXE_lightsplit"))
        .args(["render", "s.toml", "-o", "o.png", "--spp", "1"])
        .current_dir(dir)
        .output()
        .expect("the binary runs");
    (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
}

const CAMERA: &str = "[camera]\nposition = [0, 1, -5]\nlook_at = [0, 1, 0]\n[film]\nwidth = 8\nheight = 8\n\
[[shape]]\ntype = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1\n";

/// Bad environment maps: empty, not lat-long, NaN, negative; bad keys. Each is refused with
/// exit status 2 and one line naming the scene line, the file and what is wrong.
#[test]
fn bad_environment_maps_are_one_clear_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(d.join("empty.hdr"), b"").expect("write");
    std::fs::write(d.join("square.pfm"), pfm(4, 4, &[1.0; 48])).expect("write");
    let mut nan = vec![1.0f32; 24];
    nan[4] = f32::NAN;
    std::fs::write(d.join("nan.pfm"), pfm(4, 2, &nan)).expect("write");
    std::fs::write(d.join("negative.pfm"), pfm(4, 2, &[-1.0; 24])).expect("write");
    std::fs::write(d.join("ok.pfm"), pfm(4, 2, &[1.0; 24])).expect("write");
    let light = |keys: &str| format!("{CAMERA}[[light]]\ntype = \"environment\"\n{keys}\n");
    for (keys, needles) in [
        ("file = \"empty.hdr\"", vec!["empty.hdr", "empty (0 bytes)"]),
        ("file = \"square.pfm\"", vec!["square.pfm", "twice as wide as high", "4x4"]),
        ("file = \"nan.pfm\"", vec!["nan.pfm", "1 of the environment map's 8 pixels"]),
        ("file = \"negative.pfm\"", vec!["negative.pfm", "negative"]),
        ("file = \"missing.exr\"", vec!["missing.exr"]),
        ("file = \"ok.pfm\"\nscale = -1", vec!["scale", "negative"]),
        ("file = \"ok.pfm\"\nsampling = \"cosine\"", vec!["sampling", "cosine", "luminance or uniform"]),
        ("scale = 2", vec!["file"]),
    ] {
        let (code, err) = render_in(d, &light(keys));
        assert_eq!(code, Some(2), "{keys}: {err}");
        assert_eq!(err.lines().count(), 1, "{keys}: one line: {err}");
        assert!(err.starts_with("error: s.toml:11:"), "{keys}: names the light's line: {err}");
        for n in needles {
            assert!(err.contains(n), "{keys}: `{n}` in {err}");
        }
        assert!(!d.join("o.png").exists(), "{keys}: nothing written");
    }
    let (code, err) = render_in(d, &light("file = \"ok.pfm\""));
    assert_eq!(code, Some(0), "{err}");
}

use crate::common::GltfDoc;
use glam::{DVec3, Vec3};
use lightsplit::scene::{self, Geometry, Light};
use serde_json::json;

/// The first vertex of shape `name` of a scene as placed, its first triangle's normal by
/// winding, the first vertex's shading normal as placed, and whether the shape is an instance.
fn placed(s: &scene::Scene, name: &str) -> (Vec3, Vec3, Vec3, bool) {
    let shape = s.shapes.iter().find(|x| x.name == name).unwrap_or_else(|| panic!("no shape {name}"));
    let Geometry::Triangles(m) = &shape.geometry else { panic!("a mesh") };
    assert_eq!(m.indices[0][0], 0, "triangle 0 starts at vertex 0");
    let [a, b, c] = m.triangle(0);
    let normals = m.normals.as_ref().expect("normals");
    let normal = match &m.instance {
        Some(i) => (i.normals * normals[0]).normalize(),
        None => normals[0],
    };
    (a, (b - a).cross(c - a).normalize(), normal, m.instance.is_some())
}

/// The node hierarchy: transforms compose from the root down, a mesh used by two nodes appears
/// in both places, a mirroring node keeps its faces' winding outward, and the first camera gives
/// the view, its field of view and its aspect ratio.
#[test]
fn a_gltf_node_hierarchy_places_every_use_of_a_mesh() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut doc = GltfDoc::quad();
    let h = std::f64::consts::FRAC_1_SQRT_2;
    doc.node(json!({"name": "root", "translation": [10, 0, 0], "rotation": [0, h, 0, h], "scale": [2, 2, 2], "children": [1, 2]}), true);
    doc.node(json!({"name": "A", "mesh": 0, "translation": [0, 1, 0]}), false);
    doc.node(json!({"name": "B", "mesh": 0, "scale": [-1, 1, 1]}), false);
    doc.node(json!({"name": "eye", "camera": 0, "translation": [0, 0, 5]}), true);
    doc.json["cameras"] =
        json!([{"type": "perspective", "perspective": {"yfov": 0.6, "znear": 0.1, "aspectRatio": 2.0}}]);
    let path = doc.write_gltf(dir.path(), "m");
    let s = scene::load(&path).expect("loads");
    assert_eq!(s.origin, DVec3::new(0.0, 0.0, 5.0), "the camera's position is the origin");
    assert!((s.camera.fov - 0.6f32.to_degrees()).abs() < 1e-4, "{}", s.camera.fov);
    assert!((s.camera.look_at.normalize() - Vec3::NEG_Z).length() < 1e-6);
    assert_eq!((s.film.width, s.film.height), (640, 320));
    assert_eq!(s.shapes.len(), 2, "one mesh, two uses");
    assert_eq!(s.inputs, vec![path.clone(), dir.path().join("m.bin")]);
    // Corner (-0.5, -0.5, 0) under A: up 1, scaled 2, turned 90 degrees about y ((x, y, z) to
    // (z, y, -x)), moved 10 along x: (10, 1, 1); less the origin. Under B: mirrored in x, then
    // the same: (10, -1, -1).
    // A places the shared mesh as an instance; B mirrors, so it gets its own copy with the
    // winding turned.
    let (a, a_winding, a_normal, a_instance) = placed(&s, "m/A/quad/0");
    assert!((a - Vec3::new(10.0, 1.0, -4.0)).length() < 1e-5, "{a}");
    let (b, b_winding, b_normal, b_instance) = placed(&s, "m/B/quad/0");
    assert!((b - Vec3::new(10.0, -1.0, -6.0)).length() < 1e-5, "{b}");
    assert!(a_instance && !b_instance, "A is an instance ({a_instance}), mirrored B a copy ({b_instance})");
    for (winding, normal) in [(a_winding, a_normal), (b_winding, b_normal)] {
        assert!((normal - Vec3::X).length() < 1e-5, "the quad's +z turns to +x: {normal}");
        assert!(winding.dot(normal) > 0.999, "winding {winding} agrees with the normal {normal}");
    }
    // Each node is an object of its own.
    assert_eq!(s.objects, vec!["m/A".to_string(), "m/B".to_string()]);
}

/// `KHR_lights_punctual`: point, spot and directional lights, placed and turned by their
/// nodes, their photometric units turned into radiometric ones at 683 lm/W.
#[test]
fn gltf_punctual_lights_are_placed_and_converted() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut doc = GltfDoc::quad();
    doc.node(json!({"mesh": 0}), true);
    let h = std::f64::consts::FRAC_1_SQRT_2;
    doc.json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    doc.json["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "point", "color": [1.0, 0.5, 0.25], "intensity": 683.0},
        {"type": "spot", "intensity": 1366.0, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.4}},
        {"type": "directional", "intensity": 6830.0}
    ]}});
    let light = |k: usize| json!({"KHR_lights_punctual": {"light": k}});
    doc.node(json!({"translation": [1, 2, 3], "extensions": light(0)}), true);
    doc.node(json!({"translation": [0, 4, 0], "rotation": [-h, 0, 0, h], "extensions": light(1)}), true);
    doc.node(json!({"extensions": light(2)}), true);
    let path = doc.write_gltf(dir.path(), "lights");
    let s = scene::load(&path).expect("loads");
    assert!(s.notes.iter().all(|n| !n.contains("default environment")), "{:?}", s.notes);
    let o = s.origin.as_vec3();
    let near = |a: Vec3, b: Vec3| (a - b).length() < 1e-4;
    let Light::Point { position, intensity } = s.lights[0] else { panic!("{:?}", s.lights[0]) };
    assert!(near(position + o, Vec3::new(1.0, 2.0, 3.0)) && near(intensity, Vec3::new(1.0, 0.5, 0.25)));
    let Light::Spot { position, direction, intensity, cos_total, cos_falloff_start } = s.lights[1] else {
        panic!("{:?}", s.lights[1])
    };
    assert!(near(position + o, Vec3::new(0.0, 4.0, 0.0)) && near(direction, Vec3::NEG_Y), "{direction}");
    assert!(near(intensity, Vec3::splat(2.0)));
    assert!((cos_total - 0.4f32.cos()).abs() < 1e-6 && (cos_falloff_start - 0.2f32.cos()).abs() < 1e-6);
    let Light::Sun { direction, radiance, one_minus_cos, .. } = s.lights[2] else {
        panic!("{:?}", s.lights[2])
    };
    assert!(near(direction, Vec3::Z), "towards the light, against its -z: {direction}");
    let irradiance = radiance.x * 2.0 * std::f32::consts::PI * one_minus_cos;
    assert!((irradiance - 10.0).abs() < 1e-3, "{irradiance}");
}

/// The Embree Cornell box converted by obj2gltf (npm, `tests/data/embree-cornell.gltf`) renders as
/// the OBJ does but for glTF's 4% rough specular layer over each wall (metallic 0, roughness 1,
/// as obj2gltf writes a `Kd`): a channel of albedo `b` reflects `E + b (1 - E)` (`E` the layer's
/// albedo, at most 0.05 here), never less than Lambert's `b` and at most `E (1 - b)` more. So the
/// per-pixel differences of two renders at different seeds are never negative beyond four
/// standard errors of their spread, and the mean is at most 5% brighter in every channel.
#[test]
fn the_cornell_box_from_gltf_renders_as_from_obj() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR"));
    let obj = std::fs::read_to_string(data.join("scenes/embree-cornell.toml")).expect("read");
    let gltf = obj.replace(
        "type = \"mesh\"\nfile = \"embree-cornell.obj\"",
        "type = \"gltf\"\nfile = \"../tests/data/embree-cornell.gltf\"",
    );
    assert_ne!(obj, gltf);
    let render = |text: &str, seed: u64| {
        let s = lightsplit::scene::file::parse(&data.join("scenes/x.toml"), text).expect("parses");
        let mut options = lightsplit::render::RenderOptions::from_scene(&s);
        (options.width, options.height, options.spp, options.seed) = (32, 32, 64, seed);
        lightsplit::render::render(&s, &options, &|_| {}).expect("renders").film.raw
    };
    let (a, b) = (render(&obj, 1), render(&gltf, 2));
    for channel in 0..3 {
        let d: Vec<f64> =
            a.pixels.iter().zip(&b.pixels).map(|(p, q)| (q[channel] - p[channel]) as f64).collect();
        let (mean, se) = crate::common::mean_and_standard_error_of(&d);
        let level = a.mean()[channel] as f64;
        assert!(mean > -4.0 * se, "channel {channel}: glTF darker by {mean}, standard error {se}");
        assert!(mean < 0.05 * level + 4.0 * se, "channel {channel}: glTF brighter by {mean} of {level}");
    }
    let level = a.mean();
    assert!(level.min_element() > 0.05, "not black: {level}");
}

/// `KHR_materials_emissive_strength` scales the emissive factor past 1; an extension a file uses
/// but does not require, and that is not read, is named in a note and the file loads.
#[test]
fn emissive_strength_scales_emission_and_unread_extensions_are_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut doc = GltfDoc::quad();
    doc.json["extensionsUsed"] = json!(["KHR_materials_emissive_strength", "KHR_materials_iridescence"]);
    doc.json["materials"] = json!([{
        "emissiveFactor": [0.5, 0.25, 1.0],
        "extensions": {
            "KHR_materials_emissive_strength": {"emissiveStrength": 4.0},
            "KHR_materials_iridescence": {"iridescenceFactor": 1.0}
        }
    }]);
    doc.json["meshes"][0]["primitives"][0]["material"] = json!(0);
    doc.node(json!({"mesh": 0}), true);
    let path = doc.write_gltf(dir.path(), "strength");
    let s = scene::load(&path).expect("loads");
    assert_eq!(s.shapes[0].emission, Vec3::new(2.0, 1.0, 4.0));
    assert!(
        s.notes.iter().any(|n| n.contains("extensions not read") && n.contains("KHR_materials_iridescence")),
        "{:?}",
        s.notes
    );
    assert!(s.notes.iter().all(|n| !n.contains("KHR_materials_emissive_strength")), "{:?}", s.notes);
}

/// A model with emission and no punctual light is lit by the default environment too (its
/// emission kept), said in a note; `--environment` replaces what lights it from infinity: none,
/// a white sky, or an HDRI (which becomes one of the render's inputs); a file it cannot read is
/// bad input.
#[test]
fn the_default_environment_lights_an_emissive_model_and_environment_replaces_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut doc = GltfDoc::quad();
    doc.json["materials"] = json!([{"emissiveFactor": [0.02, 0.02, 0.02]}]);
    doc.json["meshes"][0]["primitives"][0]["material"] = json!(0);
    doc.node(json!({"mesh": 0}), true);
    std::fs::write(dir.path().join("m.glb"), doc.glb()).expect("write");
    let mut s = scene::load(&dir.path().join("m.glb")).expect("loads");
    assert!(
        s.notes.iter().any(|n| n.contains("default environment") && n.contains("its own emission")),
        "{:?}",
        s.notes
    );
    assert_eq!(s.lights, [Light::Sky { radiance: Vec3::ONE, diffuse_source: true }]);
    s.set_environment(&scene::Environment::None).expect("none");
    assert!(s.lights.is_empty());
    let hdr = dir.path().join("e.pfm");
    std::fs::write(&hdr, pfm(4, 2, &[0.5; 24])).expect("write");
    s.set_environment(&scene::Environment::File(hdr.clone())).expect("an HDRI");
    assert!(matches!(s.lights[..], [Light::Environment { .. }]), "{:?}", s.lights);
    assert!(s.inputs.contains(&hdr));
    let render = |env: &str| {
        let o = Command::new(env!("CARGO_BIN_EXE_lightsplit"))
            .args([
                "render",
                "m.glb",
                "-o",
                &format!("{env}.exr"),
                "--spp",
                "4",
                "--width",
                "32",
                "--height",
                "24",
            ])
            .args(["--environment", env])
            .current_dir(dir.path())
            .output()
            .expect("runs");
        (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    for env in ["none", "white", "e.pfm"] {
        let (code, err) = render(env);
        assert_eq!(code, Some(0), "{env}: {err}");
    }
    let image = |name: &str| lightsplit::film::read_image(&dir.path().join(name)).expect("reads");
    // Without an environment only the quad's emission is seen; the sky of the PFM is 0.5.
    let (none, pfm) = (image("none.exr"), image("e.pfm.exr"));
    assert_eq!(none.get(0, 0), Vec3::ZERO);
    assert!((none.get(16, 12) - Vec3::splat(0.02)).abs().max_element() < 1e-6, "{}", none.get(16, 12));
    assert!((pfm.get(0, 0) - Vec3::splat(0.5)).abs().max_element() < 1e-6, "{}", pfm.get(0, 0));
    assert_eq!(image("white.exr").get(0, 0), Vec3::ONE);
    let (code, err) = render("missing.hdr");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--environment") && err.contains("missing.hdr"), "{err}");
}

/// `lightsplit render model.glb` renders the file itself: without a camera it frames the bounds,
/// without lights it is lit by the default environment, and both are said.
#[test]
fn a_glb_renders_directly_and_says_what_it_assumed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut doc = GltfDoc::quad();
    doc.node(json!({"mesh": 0}), true);
    std::fs::write(dir.path().join("m.glb"), doc.glb()).expect("write");
    let o = Command::new(env!("CARGO_BIN_EXE_lightsplit"))
        .args(["render", "m.glb", "-o", "o.exr", "--spp", "4", "--width", "32", "--height", "24"])
        .current_dir(dir.path())
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("note: m.glb: no camera: framing"), "{err}");
    assert!(
        err.contains("note: m.glb: no lights: lit by the default environment, a uniform white sky"),
        "{err}"
    );
    let image = lightsplit::film::read_image(&dir.path().join("o.exr")).expect("reads");
    // The sky around the quad is 1. The quad, in glTF's default material (a rough white metal,
    // its multiple scattering restored), reflects all of the white sky: its central pixels'
    // mean is 1 within four standard errors of their spread and the albedo table's 0.5%.
    assert_eq!(image.get(0, 0), Vec3::ONE);
    let block: Vec<f64> =
        (12..20).flat_map(|x| (8..16).map(move |y| (x, y))).map(|(x, y)| image.get(x, y).x as f64).collect();
    let (mean, se) = crate::common::mean_and_standard_error_of(&block);
    assert!((mean - 1.0).abs() < 4.0 * se + 0.005, "the quad reflects the sky: {mean} +- {se}");
}

/// Bad glTF files: each is one line, exit status 2, naming the file and what is wrong.
#[test]
fn bad_gltf_files_are_one_clear_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let with_node = || {
        let mut doc = GltfDoc::quad();
        doc.node(json!({"mesh": 0}), true);
        doc
    };
    let glb = with_node().glb();
    std::fs::write(d.join("truncated.glb"), &glb[..glb.len() / 2]).expect("write");
    std::fs::write(d.join("empty.glb"), b"").expect("write");
    let missing = with_node().write_gltf(d, "missing");
    std::fs::remove_file(d.join("missing.bin")).expect("remove");
    let mut range = with_node();
    let i = range.indices(&[0, 1, 7]);
    range.json["meshes"][0]["primitives"][0]["indices"] = json!(i);
    range.write_gltf(d, "range");
    let mut required = with_node();
    required.json["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
    required.json["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    required.write_gltf(d, "required");
    let mut nan = with_node();
    let p = nan.floats(&[f32::NAN, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0], "VEC3");
    nan.json["accessors"][p]["min"] = json!([0, 0, 0]);
    nan.json["accessors"][p]["max"] = json!([1, 1, 0]);
    nan.json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(p);
    nan.write_gltf(d, "nan");
    assert!(missing.exists());
    for (file, needles) in [
        ("truncated.glb", vec!["not valid glTF"]),
        ("empty.glb", vec!["empty (0 bytes)"]),
        ("missing.gltf", vec!["buffer 0 `missing.bin`"]),
        ("range.gltf", vec!["index 7 is out of range (4 vertices)"]),
        ("required.gltf", vec!["KHR_draco_mesh_compression"]),
        ("nan.gltf", vec!["position 0 is not finite"]),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_lightsplit"))
            .args(["render", file, "-o", "o.png"])
            .current_dir(d)
            .output()
            .expect("runs");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{file}: {err}");
        assert_eq!(err.lines().count(), 1, "{file}: one line: {err}");
        assert!(err.starts_with(&format!("error: {file}: ")), "{file}: {err}");
        for n in needles {
            assert!(err.contains(n), "{file}: `{n}` in {err}");
        }
    }
    // In a scene file, the error names the shape's line.
    let (code, err) = render_in(d, &format!("{CAMERA}[[shape]]\ntype = \"gltf\"\nfile = \"range.gltf\"\n"));
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.starts_with("error: s.toml:11: glTF `range.gltf`: mesh `quad` primitive 0: index 7"),
        "{err}"
    );
}

/// An OBJ's `.mtl` materials in a scene: a textured diffuse (`map_Kd`), a glossy (`Ks`, `Ns`)
/// and a glass (`d`, `Ni`) become those materials, the texture is an input and is seen in the
/// image, and an unread key is one note naming the library's line.
#[test]
fn obj_materials_are_read_and_unread_keys_are_noted() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    // A texture red on the left half, green on the right.
    let mut img = image::RgbImage::new(2, 1);
    img.put_pixel(0, 0, image::Rgb([255, 0, 0]));
    img.put_pixel(1, 0, image::Rgb([0, 255, 0]));
    img.save(d.join("rg.png")).expect("png");
    std::fs::write(
        d.join("m.mtl"),
        "newmtl tex\nKd 1 1 1\nmap_Kd rg.png\nKa 0.2 0.2 0.2\nnewmtl shiny\nKd 0.2 0.2 0.2\nKs 0.5 0.5 0.5\nNs 50\n\
         newmtl glass\nd 0.1\nNi 1.45\n",
    )
    .expect("write");
    std::fs::write(
        d.join("m.obj"),
        "mtllib m.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
         v 20 0 0\nv 21 0 0\nv 21 1 0\n\
         o tex\nusemtl tex\nf 1/1 2/2 3/3 4/4\no shiny\nusemtl shiny\nf 5 6 7\no glass\nusemtl glass\nf 5 7 6\n",
    )
    .expect("write");
    let text = "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\nfov = 40\n[film]\nwidth = 16\nheight = 16\n\
                [[shape]]\ntype = \"mesh\"\nfile = \"m.obj\"\n[[light]]\ntype = \"sky\"\nradiance = [1, 1, 1]\n";
    std::fs::write(d.join("s.toml"), text).expect("write");
    let s = lightsplit::scene::load(&d.join("s.toml")).expect("loads");
    use lightsplit::scene::Material;
    assert!(matches!(s.materials[0], Material::Diffuse { .. }), "{:?}", s.materials[0]);
    assert!(s.maps(0).color.is_some());
    assert!(
        matches!(s.materials[1], Material::Glossy { roughness, .. } if (roughness - (2.0f32 / 52.0).sqrt().sqrt()).abs() < 1e-6)
    );
    assert!(matches!(s.materials[2], Material::Glass { ior, .. } if ior == 1.45), "{:?}", s.materials[2]);
    assert!(s.inputs.contains(&d.join("rg.png")), "{:?}", s.inputs);
    assert_eq!(s.notes, [format!("{}:4: `Ka` is not read", d.join("m.mtl").display())]);
    // The textured quad seen from the front: the image's left half red, right half green (the
    // camera looks down -z, so +x is on the right).
    let out = crate::common::render_text(
        &std::fs::read_to_string(d.join("s.toml"))
            .expect("read")
            .replace("m.obj", &d.join("m.obj").to_string_lossy()),
        4,
    );
    let (left, right) = (out.film.raw.get(5, 8), out.film.raw.get(10, 8));
    assert!(left.x > 2.0 * left.y && right.y > 2.0 * right.x, "left {left}, right {right}");
    let o = Command::new(env!("CARGO_BIN_EXE_lightsplit"))
        .args(["render", "s.toml", "-o", "o.png", "--spp", "1"])
        .current_dir(d)
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        // The note names its own file and line, not the scene's again.
        o.status.success() && err.contains("note: m.mtl:4: `Ka` is not read"),
        "{err}"
    );
}

/// A glTF normal map bends the shading normal in the frame of the texture coordinates: a quad
/// facing +z, lit by a directional light 40 degrees toward +x, is brightest with its normals
/// tilted 45 degrees toward +x (its u direction), darker flat, darkest tilted toward -x, the
/// three in the ratios of their cosines to the light (within the noise of 64 samples).
#[test]
fn a_gltf_normal_map_bends_the_shading_normal() {
    let dir = tempfile::tempdir().expect("tempdir");
    let render = |tilt: Option<f32>| -> f32 {
        let mut doc = GltfDoc::quad();
        doc.node(json!({"mesh": 0}), true);
        let (s, c) = 20f64.to_radians().sin_cos();
        doc.json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
        doc.json["extensions"] =
            json!({"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 683.0}]}});
        doc.node(
            json!({"rotation": [0, s, 0, c], "extensions": {"KHR_lights_punctual": {"light": 0}}}),
            true,
        );
        let mut material = json!({"pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 1.0}});
        if let Some(t) = tilt {
            let m = Vec3::new(t.sin(), 0.0, t.cos());
            let byte = |x: f32| ((x + 1.0) * 0.5 * 255.0).round() as u8;
            let mut png = Vec::new();
            image::RgbImage::from_pixel(2, 2, image::Rgb([byte(m.x), byte(m.y), byte(m.z)]))
                .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
                .expect("png");
            material["normalTexture"] = json!({"index": doc.texture(&png)});
        }
        doc.json["materials"] = json!([material]);
        doc.json["meshes"][0]["primitives"][0]["material"] = json!(0);
        std::fs::write(dir.path().join("n.glb"), doc.glb()).expect("write");
        let text = format!(
            "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\nfov = 10\n[film]\nwidth = 4\nheight = 4\n\
             [[shape]]\ntype = \"gltf\"\nfile = \"{}\"\n",
            dir.path().join("n.glb").display()
        );
        let out = crate::common::render_text(&text, 64);
        out.film.raw.mean().x
    };
    let (toward, flat, away) =
        (render(Some(45f32.to_radians())), render(None), render(Some(-45f32.to_radians())));
    let cos = |deg: f32| deg.to_radians().cos();
    assert!(toward > flat && flat > away, "{toward} {flat} {away}");
    // The diffuse base dominates a rough dielectric: brightness follows the cosine to within
    // the specular layer's share (a few percent) and the 8-bit rounding of the map.
    assert!((flat / toward - cos(40.0) / cos(5.0)).abs() < 0.05, "{}", flat / toward);
    assert!((away / toward - cos(85.0) / cos(5.0)).abs() < 0.05, "{}", away / toward);
}

/// An OBJ's `map_Bump` height image bends the shading normal: a floor whose height rises along
/// +x (a linear ramp image, read as data without the sRGB curve, `-bm` scaling it) faces a little toward -x, so a sun low in the -x sky
/// lights it more, and one low in the +x sky less, than it lights the flat floor.
#[test]
fn an_obj_bump_map_tilts_the_floor_toward_its_slope() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let ramp = image::GrayImage::from_fn(64, 4, |x, _| image::Luma([(x * 4) as u8]));
    ramp.save(d.join("ramp.png")).expect("png");
    std::fs::write(
        d.join("m.obj"),
        "mtllib m.mtl\nv -1 0 1\nv 1 0 1\nv 1 0 -1\nv -1 0 -1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3 4/4\n",
    )
    .expect("write");
    let render = |bump: bool, sun_x: f32| -> f32 {
        let mtl = if bump {
            "newmtl m\nKd 0.5 0.5 0.5\nmap_Bump -bm 0.3 ramp.png\n"
        } else {
            "newmtl m\nKd 0.5 0.5 0.5\n"
        };
        std::fs::write(d.join("m.mtl"), mtl).expect("write");
        let text = format!(
            "[camera]\nposition = [0, 3, 0.001]\nlook_at = [0, 0, 0]\nfov = 20\n[film]\nwidth = 8\nheight = 8\n\
             [[shape]]\ntype = \"mesh\"\nfile = \"{}\"\n[[light]]\ntype = \"sun\"\ndirection = [{sun_x}, 1, 0]\nirradiance = [1, 1, 1]\n",
            d.join("m.obj").display()
        );
        crate::common::render_text(&text, 16).film.raw.mean().x
    };
    let (flat_west, flat_east) = (render(false, -1.0), render(false, 1.0));
    assert!((flat_west - flat_east).abs() < 1e-3 * flat_west, "{flat_west} {flat_east}");
    let (west, east) = (render(true, -1.0), render(true, 1.0));
    // The slope is 0.3 (height) over 2 (the floor's width in u): the normal tilts by
    // atan(0.15) = 8.5 degrees toward -x; a sun at 45 degrees then gives cos(36.5) against
    // cos(53.5), ratios of 1.14 and 0.84 to the flat floor's cos(45).
    let cos = |deg: f32| deg.to_radians().cos();
    assert!((west / flat_west - cos(45.0 - 8.53) / cos(45.0)).abs() < 0.03, "{}", west / flat_west);
    assert!((east / flat_east - cos(45.0 + 8.53) / cos(45.0)).abs() < 0.03, "{}", east / flat_east);
}

/// A PNG of 4 x 1 texels, black on its left half and white on its right: two texels a half,
/// so bilinear lookups inside each half are exact.
fn half_black_png() -> Vec<u8> {
    let mut png = Vec::new();
    image::RgbImage::from_fn(4, 1, |x, _| image::Rgb(if x < 2 { [0, 0, 0] } else { [255, 255, 255] }))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("png");
    png
}

/// A quad document with one mesh (and one node) per material of `materials`, in order.
fn quads_of(materials: serde_json::Value) -> GltfDoc {
    let mut doc = GltfDoc::quad();
    let primitive = doc.json["meshes"][0]["primitives"][0].clone();
    let n = materials.as_array().map_or(0, |m| m.len());
    doc.json["materials"] = materials;
    doc.json["meshes"] = json!([]);
    for k in 0..n {
        let mut p = primitive.clone();
        p["material"] = json!(k);
        doc.json["meshes"].as_array_mut().expect("meshes").push(json!({"primitives": [p]}));
        doc.node(json!({"mesh": k, "translation": [k as f32 * 1.5, 0.0, 0.0]}), true);
    }
    doc
}

/// glTF's material extensions become one layered material: specular and ior the dielectric's
/// Fresnel, transmission and volume what crosses it (with Beer-Lambert absorption), clearcoat
/// and sheen the layers on top (read even when required), specular-glossiness converted; a
/// plain material stays the metallic-roughness one; a bad factor is one error naming it.
#[test]
fn the_material_extensions_become_one_layered_material() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut doc = quads_of(json!([
        {"name": "coated", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.1, 0.1, 1], "roughnessFactor": 0.4},
         "extensions": {
            "KHR_materials_clearcoat": {"clearcoatFactor": 0.9, "clearcoatRoughnessFactor": 0.2},
            "KHR_materials_sheen": {"sheenColorFactor": [0.5, 0.4, 0.3], "sheenRoughnessFactor": 0.6},
            "KHR_materials_specular": {"specularFactor": 0.5, "specularColorFactor": [1.0, 0.5, 0.5]},
            "KHR_materials_ior": {"ior": 2.0}}},
        {"name": "glass", "pbrMetallicRoughness": {"metallicFactor": 0, "roughnessFactor": 0.1},
         "extensions": {
            "KHR_materials_transmission": {"transmissionFactor": 1.0},
            "KHR_materials_volume": {"thicknessFactor": 0.1, "attenuationColor": [0.5, 0.25, 1.0], "attenuationDistance": 2.0}}},
        {"name": "specgloss", "extensions": {"KHR_materials_pbrSpecularGlossiness": {
            "diffuseFactor": [0.2, 0.3, 0.4, 1], "specularFactor": [0.9, 0.8, 0.1], "glossinessFactor": 0.7}}},
        {"name": "plain", "pbrMetallicRoughness": {"metallicFactor": 0.5, "roughnessFactor": 0.3}}
    ]));
    doc.json["extensionsUsed"] = json!([
        "KHR_materials_clearcoat",
        "KHR_materials_sheen",
        "KHR_materials_specular",
        "KHR_materials_ior",
        "KHR_materials_transmission",
        "KHR_materials_volume",
        "KHR_materials_pbrSpecularGlossiness"
    ]);
    doc.json["extensionsRequired"] = json!(["KHR_materials_clearcoat", "KHR_materials_sheen"]);
    let path = doc.write_gltf(dir.path(), "layers");
    let s = scene::load(&path).expect("loads");
    let layered = |k: usize| match &s.materials[k] {
        scene::Material::Layered(l) => l.clone(),
        other => panic!("material {k} is {other:?}"),
    };
    let close = |a: Vec3, b: Vec3| (a - b).abs().max_element() < 1e-5;
    let coated = layered(0);
    assert_eq!((coated.base_color, coated.roughness), (Vec3::new(0.8, 0.1, 0.1), 0.4));
    let l = coated.layers;
    // f0 = ((2 - 1) / (2 + 1))^2 = 1/9, times the specular colour and factor.
    assert!(close(l.f0, Vec3::new(1.0, 0.5, 0.5) / 9.0 * 0.5), "{}", l.f0);
    assert_eq!((l.f90, l.ior, l.clearcoat, l.clearcoat_roughness), (0.5, 2.0, 0.9, 0.2));
    assert_eq!((l.sheen_color, l.sheen_roughness, l.transmission), (Vec3::new(0.5, 0.4, 0.3), 0.6, 0.0));
    let glass = layered(1).layers;
    assert_eq!((glass.transmission, glass.thin), (1.0, false));
    let expected = Vec3::new(0.5f32.ln(), 0.25f32.ln(), 0.0) / -2.0;
    assert!(close(glass.absorption, expected), "{}", glass.absorption);
    assert!(s.materials.iter().filter(|m| matches!(m, scene::Material::Layered(_))).count() == 3);
    let sg = layered(2);
    assert_eq!((sg.base_color, sg.metallic), (Vec3::new(0.2, 0.3, 0.4), 0.0));
    assert!((sg.roughness - 0.3).abs() < 1e-6 && close(sg.layers.f0, Vec3::new(0.9, 0.8, 0.1)), "{sg:?}");
    assert!(
        matches!(s.materials[3], scene::Material::Pbr { metallic: 0.5, roughness: 0.3, .. }),
        "{:?}",
        s.materials[3]
    );
    assert!(s.notes.iter().all(|n| !n.contains("extensions not read")), "{:?}", s.notes);

    for (key, value, says) in [
        ("KHR_materials_ior", json!({"ior": 0.5}), "index of refraction"),
        ("KHR_materials_clearcoat", json!({"clearcoatFactor": 2.0}), "clearcoatFactor"),
        ("KHR_materials_sheen", json!({"sheenColorFactor": [1, 1]}), "sheenColorFactor"),
        ("KHR_materials_transmission", json!({"transmissionFactor": -1}), "transmission"),
    ] {
        let mut bad = quads_of(json!([{"name": "bad", "extensions": {key: value}}]));
        bad.json["extensionsUsed"] = json!([key]);
        let path = bad.write_gltf(dir.path(), "bad");
        let err = scene::load(&path).expect_err(key).to_string();
        assert!(err.contains("material `bad`") && err.contains(says), "{key}: {err}");
    }
}

/// Under layered materials (a clearcoat with sheen, a rough metal, a transmissive quad) the
/// four components still sum to the beauty in every pixel.
#[test]
fn layered_materials_keep_the_components_summing_to_the_beauty() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut doc = quads_of(json!([
        {"pbrMetallicRoughness": {"metallicFactor": 0, "roughnessFactor": 0.5}, "extensions": {
            "KHR_materials_clearcoat": {"clearcoatFactor": 1.0},
            "KHR_materials_sheen": {"sheenColorFactor": [1, 1, 1], "sheenRoughnessFactor": 0.5}}},
        {"pbrMetallicRoughness": {"metallicFactor": 1, "roughnessFactor": 0.7},
         "extensions": {"KHR_materials_ior": {"ior": 1.5}}},
        {"pbrMetallicRoughness": {"metallicFactor": 0, "roughnessFactor": 0.2},
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}}}
    ]));
    doc.json["extensionsUsed"] = json!([
        "KHR_materials_clearcoat",
        "KHR_materials_sheen",
        "KHR_materials_ior",
        "KHR_materials_transmission"
    ]);
    std::fs::write(dir.path().join("m.glb"), doc.glb()).expect("write");
    let s = scene::load(&dir.path().join("m.glb")).expect("loads");
    let mut options = lightsplit::render::RenderOptions::from_scene(&s);
    (options.width, options.height, options.spp) = (48, 16, 8);
    let f = lightsplit::render::render(&s, &options, &|_| {}).expect("renders").film;
    for (i, raw) in f.raw.pixels.iter().enumerate() {
        let parts: Vec3 = f.components.iter().map(|c| c.pixels[i]).sum();
        assert!((parts - *raw).abs().max_element() <= 1e-5 * raw.abs().max_element().max(1e-3), "pixel {i}");
    }
    assert!(f.raw.mean().min_element() > 0.05, "lit: {}", f.raw.mean());
}

/// An emissive texture is a texture, not its mean: a quad whose emissive texture is black on its
/// left half and white on its right is seen so (nothing else lights the scene), and, sampled
/// as a light, it lights a white floor below it as a uniform emitter of half its radiance
/// does (the floor's mean, by symmetry, within four standard errors of the difference).
#[test]
fn an_emissive_texture_is_seen_and_sampled_as_a_texture() {
    let dir = tempfile::tempdir().expect("tempdir");
    let png = half_black_png();
    let write = |name: &str, textured: bool| {
        let mut doc = quads_of(json!([
            {"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]}, "emissiveFactor": [1, 1, 1]},
            {"pbrMetallicRoughness": {"metallicFactor": 0, "roughnessFactor": 1}}
        ]));
        if textured {
            doc.json["materials"][0]["emissiveTexture"] = json!({"index": doc.texture(&png)});
        } else {
            doc.json["materials"][0]["emissiveFactor"] = json!([0.5, 0.5, 0.5]);
        }
        // The emitter 1 above the floor, facing down (turned half a turn about x); the floor
        // at the origin, facing up (a quarter turn about x).
        let (s, c) = std::f64::consts::FRAC_PI_4.sin_cos();
        doc.json["nodes"][0] = json!({"mesh": 0, "translation": [0, 1, 0], "rotation": [c, 0, 0, s]});
        doc.json["nodes"][1] = json!({"mesh": 1, "scale": [3, 3, 3], "rotation": [-s, 0, 0, c]});
        std::fs::write(dir.path().join(name), doc.glb()).expect("write");
    };
    write("textured.glb", true);
    write("uniform.glb", false);
    let render = |name: &str, camera: &str, spp: u32| {
        let text = format!(
            "{camera}[film]\nwidth = 16\nheight = 16\n[[shape]]\ntype = \"gltf\"\nfile = \"{}\"\n",
            dir.path().join(name).display()
        );
        crate::common::render_text(&text, spp).film.raw
    };
    // From below, looking up at the emitter's face (the floor behind the camera).
    let below = "[camera]\nposition = [0, 0.5, 0]\nlook_at = [0, 1, 0]\nup = [0, 0, 1]\nfov = 60\n";
    let seen = render("textured.glb", below, 4);
    // Which image side shows which half depends on the view's handedness: one is black, the
    // other white.
    let (left, right) = (seen.get(2, 8).x, seen.get(13, 8).x);
    assert!(
        left > 0.9 && right < 0.05 || right > 0.9 && left < 0.05,
        "a half black, a half white: {left} {right}"
    );
    let above = "[camera]\nposition = [0, 0.6, 2.5]\nlook_at = [0, 0, 0]\nfov = 40\n";
    let (a, b) = (render("textured.glb", above, 64), render("uniform.glb", above, 64));
    let d: Vec<f64> = a.pixels.iter().zip(&b.pixels).map(|(p, q)| (p.x - q.x) as f64).collect();
    let (mean, se) = crate::common::mean_and_standard_error_of(&d);
    assert!(mean.abs() < 4.0 * se, "textured minus uniform: {mean} +- {se}");
    assert!(b.mean().x > 0.01, "the floor is lit: {}", b.mean());
}

/// The extensions' textures become maps of the material (the specular-glossiness texture as
/// its colour and its alpha, sheen and the clearcoat's normal map from the extensions' JSON),
/// and an unlit material emits its
/// base colour from a surface that reflects nothing.
#[test]
fn extension_textures_are_read_and_unlit_emits_its_colour() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut png = Vec::new();
    image::RgbaImage::from_pixel(2, 2, image::Rgba([200, 100, 50, 128]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("png");
    let mut doc = quads_of(json!([
        {"name": "sg", "extensions": {"KHR_materials_pbrSpecularGlossiness": {"specularGlossinessTexture": {"index": 0}}}},
        {"name": "cloth", "extensions": {"KHR_materials_sheen": {"sheenColorFactor": [1, 1, 1],
            "sheenColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"scale": [2, 2]}}}}}},
        {"name": "flat", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.4, 0.6, 1]}, "extensions": {"KHR_materials_unlit": {}}},
        {"name": "coat", "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1,
            "clearcoatNormalTexture": {"index": 0, "scale": 0.5}}}}
    ]));
    assert_eq!(doc.texture(&png), 0);
    doc.json["extensionsUsed"] = json!([
        "KHR_materials_clearcoat",
        "KHR_materials_pbrSpecularGlossiness",
        "KHR_materials_sheen",
        "KHR_materials_unlit",
        "KHR_texture_transform"
    ]);
    std::fs::write(dir.path().join("t.glb"), doc.glb()).expect("write");
    let s = scene::load(&dir.path().join("t.glb")).expect("loads");
    let (sg, cloth, flat) = (s.maps(s.shapes[0].material), s.maps(s.shapes[1].material), &s.shapes[2]);
    let (color, gloss) = sg.spec_gloss.expect("the specular-glossiness texture is read");
    let pixel = |t: u32| s.textures[t as usize].color(DVec3::ZERO, glam::Vec2::splat(0.5));
    assert!((pixel(gloss).x - 128.0 / 255.0).abs() < 1e-3, "alpha: {}", pixel(gloss));
    assert!(pixel(color).x > pixel(color).y && pixel(color).y > pixel(color).z, "colour: {}", pixel(color));
    assert!(cloth.layer.sheen_color.is_some(), "{cloth:?}");
    let coat = s.maps(s.shapes[3].material).layer.clearcoat_normal.expect("the clearcoat's normal map");
    assert_eq!(coat.1, 0.5);
    assert!(pixel(coat.0).x > 0.7, "read linear: {}", pixel(coat.0));
    assert_eq!(flat.emission, Vec3::new(0.2, 0.4, 0.6));
    assert_eq!(s.materials[flat.material as usize], scene::Material::Diffuse { albedo: Vec3::ZERO });
    assert!(s.notes.iter().all(|n| !n.contains("extensions not read")), "{:?}", s.notes);
}

/// A texture's sampler (wrap modes and magnification filter) and its texture coordinates set
/// are read: the quad's emissive texture, black on its left half and white on its right, is
/// seen white where a second set of coordinates maps the quad into the right half, black
/// through the first set, and the sampler's modes come through.
#[test]
fn textures_read_their_sampler_and_second_coordinates() {
    use lightsplit::scene::texture::{Sampling, Wrap};
    let dir = tempfile::tempdir().expect("tempdir");
    let png = half_black_png();
    let write = |name: &str, set: u32| {
        let mut doc = quads_of(json!([{"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]},
            "emissiveFactor": [1, 1, 1]}]));
        let texture = doc.texture(&png);
        doc.json["samplers"] = json!([{"wrapS": 33071, "wrapT": 33648, "magFilter": 9728}]);
        doc.json["textures"][texture]["sampler"] = json!(0);
        doc.json["materials"][0]["emissiveTexture"] = json!({"index": texture, "texCoord": set});
        // TEXCOORD_0 in the left (black) half, TEXCOORD_1 in the right (white) one.
        let t0 = doc.floats(&[0.05, 0.9, 0.45, 0.9, 0.45, 0.1, 0.05, 0.1], "VEC2");
        let t1 = doc.floats(&[0.55, 0.9, 0.95, 0.9, 0.95, 0.1, 0.55, 0.1], "VEC2");
        let attributes = &mut doc.json["meshes"][0]["primitives"][0]["attributes"];
        attributes["TEXCOORD_0"] = json!(t0);
        attributes["TEXCOORD_1"] = json!(t1);
        std::fs::write(dir.path().join(name), doc.glb()).expect("write");
        dir.path().join(name)
    };
    let (first, second) = (write("first.glb", 0), write("second.glb", 1));
    let g = scene::gltf::load(&second).expect("load");
    let sampling = Sampling { wrap: [Wrap::Clamp, Wrap::Mirror], nearest: true, set: 1 };
    assert_eq!(g.textures.iter().map(|t| t.2).collect::<Vec<_>>(), vec![sampling]);
    let seen = |path: &Path| {
        let text = format!(
            "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\nfov = 8\n[film]\nwidth = 8\nheight = 8\n\
             [[shape]]\ntype = \"gltf\"\nfile = \"{}\"\n",
            path.display()
        );
        crate::common::render_text(&text, 4).film.raw.mean().x
    };
    let (black, white) = (seen(&first), seen(&second));
    assert!(black < 1e-6 && (white - 1.0).abs() < 1e-4, "first set {black}, second set {white}");
}

/// The mean of a 4x4 render of the unit quad under a directional light tilted `light_tilt`
/// degrees toward +y, from the camera at `camera`, its normal map a uniform tangent-space normal
/// `m`, with the given tangents and vertex colour.
fn normal_mapped_quad(
    m: Vec3,
    light_tilt: f64,
    camera: [f32; 3],
    tangent: Option<[f32; 4]>,
    color: Option<[f32; 3]>,
) -> Vec3 {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut doc = GltfDoc::quad();
    doc.node(json!({"mesh": 0}), true);
    let (s, c) = (-light_tilt / 2.0).to_radians().sin_cos();
    doc.json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    doc.json["extensions"] =
        json!({"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 683.0}]}});
    doc.node(json!({"rotation": [s, 0, 0, c], "extensions": {"KHR_lights_punctual": {"light": 0}}}), true);
    let byte = |x: f32| ((x + 1.0) * 0.5 * 255.0).round() as u8;
    let mut png = Vec::new();
    image::RgbImage::from_pixel(2, 2, image::Rgb([byte(m.x), byte(m.y), byte(m.z)]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("png");
    let normal = doc.texture(&png);
    doc.json["materials"] = json!([{"pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 1.0},
        "normalTexture": {"index": normal}}]);
    doc.json["meshes"][0]["primitives"][0]["material"] = json!(0);
    if let Some(t) = tangent {
        let a = doc.floats(&t.repeat(4), "VEC4");
        doc.json["meshes"][0]["primitives"][0]["attributes"]["TANGENT"] = json!(a);
    }
    if let Some(c) = color {
        let a = doc.floats(&c.repeat(4), "VEC3");
        doc.json["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(a);
    }
    std::fs::write(dir.path().join("t.glb"), doc.glb()).expect("write");
    let text = format!(
        "[camera]\nposition = {camera:?}\nlook_at = [0, 0, 0]\nfov = 10\n[film]\nwidth = 4\nheight = 4\n\
         [[shape]]\ntype = \"gltf\"\nfile = \"{}\"\n",
        dir.path().join("t.glb").display()
    );
    crate::common::render_text(&text, 64).film.raw.mean()
}

/// Vertex colours multiply the base colour, and a mesh's tangents give the normal map its
/// frame, the bitangent's sign from their w: a quad facing +z under a directional light 40
/// degrees toward +y, its normal map tilting 45 degrees along the map's y, is lit by the cosine
/// of 5 degrees with the bitangent along +y (as the texture coordinates also say), of 85
/// degrees with it turned by w = -1, and of 63 degrees with the tangent along +y (the
/// bitangent along -x).
#[test]
fn vertex_colours_and_tangents_are_read() {
    let m = Vec3::new(0.0, 45f32.to_radians().sin(), 45f32.to_radians().cos());
    let render = |tangent: Option<[f32; 4]>, color: Option<[f32; 3]>| -> Vec3 {
        normal_mapped_quad(m, 40.0, [0.0, 0.0, 3.0], tangent, color)
    };
    let none = render(None, None).x;
    let along = render(Some([1.0, 0.0, 0.0, 1.0]), None).x;
    let flipped = render(Some([1.0, 0.0, 0.0, -1.0]), None).x;
    let turned = render(Some([0.0, 1.0, 0.0, 1.0]), None).x;
    let cos = |deg: f32| deg.to_radians().cos();
    // The diffuse base dominates: brightness follows the cosine within the specular layer's
    // share and the map's 8-bit rounding.
    assert!((along / none - 1.0).abs() < 0.02, "tangent along u: {along} against {none}");
    assert!((flipped / none - cos(85.0) / cos(5.0)).abs() < 0.05, "w = -1: {}", flipped / none);
    let tilt = (45f32.to_radians().cos() * 40f32.to_radians().cos()).acos().to_degrees();
    assert!((turned / none - cos(tilt) / cos(5.0)).abs() < 0.05, "turned: {}", turned / none);
    let red = render(None, Some([1.0, 0.0, 0.0]));
    // Green and blue are the specular layer's alone (4% at normal incidence).
    assert!(red.y < 0.1 * red.x && red.z < 0.1 * red.x, "a red vertex colour: {red}");
}

/// A normal map that turns the normal away from the viewer (60 degrees along +x, the camera 45
/// degrees the other way: the view is below the bent normal) still shades, as Cycles does: the
/// glossy layer in a normal raised until it reflects the view above the surface, the diffuse
/// base by the bent normal, lit from overhead by its cosine of 60 degrees (a path that ended
/// there was black). A normal turned 100 degrees, below the surface, leaves the base unlit
/// (it was left unbent, as bright as a flat quad).
#[test]
fn normal_maps_turned_from_the_view_or_below_the_surface_shade_as_cycles_does() {
    let tilted = |deg: f32| Vec3::new(deg.to_radians().sin(), 0.0, deg.to_radians().cos());
    let camera = [-2.12, 0.0, 2.12];
    let flat = normal_mapped_quad(Vec3::Z, 0.0, camera, None, None).x;
    let away = normal_mapped_quad(tilted(60.0), 0.0, camera, None, None).x;
    let below = normal_mapped_quad(tilted(100.0), 0.0, camera, None, None).x;
    // The base dominates (the specular layer reflects the light away from the camera); the
    // map's 8-bit rounding moves the cosine by under 1%.
    assert!(flat > 0.1, "the flat quad is lit: {flat}");
    assert!((away / flat - 0.5).abs() < 0.06, "turned from the view: {away} against {flat}");
    assert!(below < 0.1 * flat, "below the surface: {below} against {flat}");
}

/// An OBJ or a PLY renders by itself as a glTF does: framed from the front (the mesh fills the
/// middle of the image), lit by the default environment, both said in notes; a `usemtl` that no
/// library defines is a note naming the file and line; with the environment taken away, a scene
/// with no light source at all is a warning before the render.
#[test]
fn obj_and_ply_files_render_by_themselves_and_say_what_they_lack() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(d.join("m.mtl"), "newmtl wall\nKd 0.5 0.5 0.5\n").expect("write");
    let quad = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nv -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\n";
    let obj = format!("mtllib m.mtl\n{quad}usemtl wall\nf 1 2 3 4\nusemtl light\nf 5 6 7\n");
    std::fs::write(d.join("m.obj"), obj).expect("write");
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
               element face 1\nproperty list uchar int vertex_indices\nend_header\n-1 -1 0\n1 -1 0\n0 1 0\n3 0 1 2\n";
    std::fs::write(d.join("t.ply"), ply).expect("write");
    let run = |file: &str, extra: &[&str]| {
        let (input, output) = (d.join(file), d.join("o.exr"));
        let mut args = vec!["render", input.to_str().expect("utf-8"), "-o", output.to_str().expect("utf-8")];
        args.extend_from_slice(&["--width", "32", "--height", "24", "--spp", "4"]);
        args.extend_from_slice(extra);
        let o = crate::common::lightsplit(&args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{file}: {err}");
        (err, lightsplit::film::read_image(&output).expect("reads"))
    };
    let (err, image) = run("m.obj", &[]);
    assert!(err.contains("m.obj: no camera: framing the model's bounds"), "{err}");
    assert!(err.contains("m.obj: no lights: lit by the default environment"), "{err}");
    assert!(err.contains("m.obj:11: `usemtl light`: its material libraries do not define it"), "{err}");
    assert!(!err.contains("warning"), "{err}");
    // The sky at a corner, the grey wall (under a white sky, about its albedo) in the middle.
    assert_eq!(image.get(0, 0), Vec3::ONE);
    let middle = image.get(16, 12).x;
    assert!(middle > 0.2 && middle < 0.8, "the wall fills the middle: {middle}");
    let (err, _) = run("m.obj", &["--environment", "none"]);
    assert!(err.contains("warning: ") && err.contains("no light source"), "{err}");
    let (err, image) = run("t.ply", &[]);
    assert!(err.contains("t.ply: no camera: framing"), "{err}");
    assert!(image.get(16, 12).x < 1.0 && image.get(0, 0) == Vec3::ONE, "the triangle in the middle");
}

/// `KHR_mesh_quantization`: positions as shorts (not normalized, scaled back by the node),
/// normals and texture coordinates as normalized shorts, read to the same quad as the floats
/// give; without the extension in the file, integer positions are one clear error naming it.
#[test]
fn quantized_meshes_read_as_their_floats() {
    let dir = tempfile::tempdir().expect("tempdir");
    let quad = |quantized: bool| {
        let mut doc = GltfDoc::quad();
        if quantized {
            let p = doc.shorts(&[-500, -500, 0, 500, -500, 0, 500, 500, 0, -500, 500, 0], "VEC3", false);
            let n = doc.shorts(&[0, 0, 32767].repeat(4), "VEC3", true);
            let t = doc.shorts(&[0, 32767, 32767, 32767, 32767, 0, 0, 0], "VEC2", true);
            doc.json["meshes"][0]["primitives"][0]["attributes"] =
                json!({"POSITION": p, "NORMAL": n, "TEXCOORD_0": t});
            doc.node(json!({"mesh": 0, "scale": [0.001, 0.001, 0.001]}), true);
        } else {
            doc.node(json!({"mesh": 0}), true);
        }
        doc
    };
    let triangles = |s: &lightsplit::scene::Scene| -> Vec<[Vec3; 3]> {
        match &s.shapes[0].geometry {
            lightsplit::scene::Geometry::Triangles(m) => (0..2).map(|t| m.triangle(t)).collect(),
            _ => panic!("a mesh"),
        }
    };
    let floats = scene::load(&quad(false).write_gltf(dir.path(), "f")).expect("loads");
    let mut doc = quad(true);
    doc.json["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
    doc.json["extensionsRequired"] = json!(["KHR_mesh_quantization"]);
    let shorts = scene::load(&doc.write_gltf(dir.path(), "q")).expect("loads");
    for (a, b) in triangles(&floats).iter().zip(&triangles(&shorts)) {
        for (p, q) in a.iter().zip(b) {
            assert!((*p - *q).abs().max_element() < 1e-6, "{p} against {q}");
        }
    }
    assert!(shorts.notes.iter().all(|n| !n.contains("KHR_mesh_quantization")), "{:?}", shorts.notes);
    let e = scene::load(&quad(true).write_gltf(dir.path(), "bad")).expect_err("refused");
    assert!(e.to_string().contains("KHR_mesh_quantization"), "{e}");
}

/// A file that requires a compression lightsplit does not decode (Draco, BasisU) is refused by
/// the extension's name, with what to do instead (exit status 2).
#[test]
fn compressed_gltf_files_are_refused_by_name_with_what_to_do() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (extension, advice) in [
        ("KHR_draco_mesh_compression", "uncompressed meshes"),
        ("KHR_texture_basisu", "gltf-transform ktxdecompress"),
    ] {
        let mut doc = GltfDoc::quad();
        doc.node(json!({"mesh": 0}), true);
        doc.json["extensionsUsed"] = json!([extension]);
        doc.json["extensionsRequired"] = json!([extension]);
        let path = doc.write_gltf(dir.path(), "c");
        let o = crate::common::lightsplit(&["render", path.to_str().expect("utf-8"), "-o", "/dev/null.png"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(&format!("requires `{extension}`")) && err.contains(advice), "{err}");
    }
}

/// `--camera` picks one of a glTF file's cameras by index or by name (the camera's, else its
/// node's); with several and no choice the first is used and a note names the others; an
/// unknown choice, or a choice for a file that is not a glTF, is one error.
#[test]
fn a_gltf_camera_is_picked_by_index_or_name() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut doc = GltfDoc::quad();
    doc.node(json!({"mesh": 0}), true);
    doc.json["cameras"] = json!([
        {"type": "perspective", "name": "front", "perspective": {"yfov": 0.8, "znear": 0.01}},
        {"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.01}}
    ]);
    doc.node(json!({"camera": 0, "translation": [0, 0, 3]}), true);
    doc.node(json!({"camera": 1, "name": "far", "translation": [0, 0, 6]}), true);
    let path = doc.write_gltf(dir.path(), "cams");
    let origin = |choice: Option<&str>| scene::load_with_camera(&path, choice).expect("loads").origin;
    assert_eq!(origin(None), glam::DVec3::new(0.0, 0.0, 3.0));
    assert_eq!(origin(Some("1")), glam::DVec3::new(0.0, 0.0, 6.0));
    assert_eq!(origin(Some("far")), glam::DVec3::new(0.0, 0.0, 6.0));
    assert_eq!(origin(Some("front")), glam::DVec3::new(0.0, 0.0, 3.0));
    let notes = scene::load(&path).expect("loads").notes;
    assert!(
        notes.iter().any(|n| n.contains("2 cameras: rendering the first") && n.contains("1 `far`")),
        "{notes:?}"
    );
    for (choice, wanted) in [("2", "no such camera"), ("back", "0 `front`, 1 `far`")] {
        let o = crate::common::lightsplit(&[
            "render",
            path.to_str().expect("utf-8"),
            "--camera",
            choice,
            "-o",
            "/dev/null.exr",
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(wanted), "{err}");
    }
    let e =
        scene::load_with_camera(std::path::Path::new("scenes/cornell.toml"), Some("0")).expect_err("refused");
    assert!(e.to_string().contains("not a glTF file"), "{e}");
}

/// `EXT_meshopt_compression`: a quad whose positions (floats), octahedral-filtered normals
/// (bytes, `KHR_mesh_quantization`) and triangles are compressed by meshoptimizer's codecs
/// (the `meshoptimizer-rs` encoders, the extension's vertex version 0), its views in a fallback
/// buffer that holds nothing, loads to the same positions and triangles as the uncompressed
/// quad, its normals within a byte's rounding; a stream cut short is one error naming the view.
#[test]
fn meshopt_compressed_meshes_are_decoded() {
    use meshoptimizer_rs::codec::{
        encode_filter_oct, encode_index_buffer, encode_vertex_buffer, IndexEncoding, VertexEncoding,
    };
    use meshoptimizer_rs::Workspace;
    let dir = tempfile::tempdir().expect("tempdir");
    let positions: [f32; 12] = [-0.5, -0.5, 0.0, 0.5, -0.5, 0.0, 0.5, 0.5, 0.0, -0.5, 0.5, 0.0];
    let indices: [u32; 6] = [0, 1, 2, 0, 2, 3];
    let mut ws = Workspace::default();
    let v0 = VertexEncoding::new(0, 0).expect("version 0");
    let bytes: Vec<u8> = positions.iter().flat_map(|x| x.to_le_bytes()).collect();
    let p = encode_vertex_buffer(&bytes, 4, 12, v0, &mut ws).expect("positions");
    let normals: Vec<f32> = [0.0, 0.0, 1.0, 0.0].repeat(4);
    let n = encode_filter_oct(4, 4, 8, &normals, &mut ws).expect("oct filter");
    let n = encode_vertex_buffer(&n, 4, 4, v0, &mut ws).expect("normals");
    let i = encode_index_buffer(&indices, IndexEncoding::DEFAULT, &mut ws).expect("indices");
    let mut bin = Vec::new();
    let mut place = |stream: &[u8]| {
        let at = bin.len();
        bin.extend_from_slice(stream);
        while bin.len() % 4 != 0 {
            bin.push(0);
        }
        (at, stream.len())
    };
    let (p, n, i) = (place(&p), place(&n), place(&i));
    let write = |name: &str, cut: usize| {
        // A view of `count` elements of `stride` bytes, at `fallback_at` in the empty fallback
        // buffer, decoded from `len` bytes (less `cut`) at `at` in the real one.
        let view = |(at, len): (usize, usize),
                    stride: usize,
                    count: usize,
                    mode: &str,
                    filter: &str,
                    fallback_at: usize| {
            let mut v = json!({"buffer": 1, "byteOffset": fallback_at, "byteLength": stride * count,
                "extensions": {"EXT_meshopt_compression": {"buffer": 0, "byteOffset": at, "byteLength": len - cut,
                    "byteStride": stride, "count": count, "mode": mode, "filter": filter}}});
            if mode == "ATTRIBUTES" {
                v["byteStride"] = json!(stride);
            }
            v
        };
        let views = [
            view(p, 12, 4, "ATTRIBUTES", "NONE", 0),
            view(n, 4, 4, "ATTRIBUTES", "OCTAHEDRAL", 48),
            view(i, 4, 6, "TRIANGLES", "NONE", 64),
        ];
        let doc = json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": ["EXT_meshopt_compression", "KHR_mesh_quantization"],
            "extensionsRequired": ["EXT_meshopt_compression", "KHR_mesh_quantization"],
            "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2}]}],
            "buffers": [{"uri": "c.bin", "byteLength": bin.len()},
                {"byteLength": 88, "extensions": {"EXT_meshopt_compression": {"fallback": true}}}],
            "bufferViews": views,
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-0.5, -0.5, 0.0], "max": [0.5, 0.5, 0.0]},
                {"bufferView": 1, "componentType": 5120, "normalized": true, "count": 4, "type": "VEC3"},
                {"bufferView": 2, "componentType": 5125, "count": 6, "type": "SCALAR"}
            ]
        });
        std::fs::write(dir.path().join("c.bin"), &bin).expect("write");
        let path = dir.path().join(name);
        std::fs::write(&path, serde_json::to_vec(&doc).expect("json")).expect("write");
        path
    };
    let scene = scene::load(&write("c.gltf", 0)).expect("the compressed quad loads");
    assert!(scene.notes.iter().all(|n| !n.contains("EXT_meshopt_compression")), "{:?}", scene.notes);
    let lightsplit::scene::Geometry::Triangles(mesh) = &scene.shapes[0].geometry else { panic!("a mesh") };
    let mut doc = GltfDoc::quad();
    doc.node(json!({"mesh": 0}), true);
    let plain = scene::load(&doc.write_gltf(dir.path(), "plain")).expect("loads");
    let lightsplit::scene::Geometry::Triangles(want) = &plain.shapes[0].geometry else { panic!("a mesh") };
    assert_eq!(mesh.positions, want.positions);
    assert_eq!(mesh.indices, want.indices);
    for n in mesh.normals.as_deref().expect("normals") {
        assert!((*n - glam::Vec3::Z).length() < 2.0 / 127.0, "{n}");
    }
    let e = scene::load(&write("short.gltf", 3)).expect_err("a stream cut short");
    assert!(
        e.to_string().contains("buffer view") && e.to_string().contains("EXT_meshopt_compression"),
        "{e}"
    );
}
