//! Issue 38: Mitsuba 3 scene XML in. Small files written here (no third-party scene is
//! committed): a furnace that the reader must get right end to end, parameters from `-D`,
//! references, includes and instances, crops and reconstruction filters, what is not read said
//! as a note with its file and line, and bad files refused with exit status 2.

use std::path::{Path, PathBuf};

use lightsplit::render::{render, RenderOptions};
use lightsplit::scene;

use crate::common::{lightsplit, mean_and_standard_error_of};

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write");
    path
}

/// A sensor looking down -z from z = 4 at a unit sphere, `size` pixels, with `extra` inside
/// the film.
fn sensor(size: &str, extra: &str) -> String {
    format!(
        r#"<sensor type="perspective">
    <float name="fov" value="30"/>
    <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
    <film type="hdrfilm">
        <integer name="width" value="{size}"/><integer name="height" value="{size}"/>
        {extra}
    </film>
</sensor>"#
    )
}

/// The white furnace through the whole reader: a two-sided diffuse sphere of reflectance 0.5
/// (given by reference) under a constant emitter of radiance 1. A convex shape sees only the
/// sky, so each of its pixels is 0.5 exactly in expectation and the background 1: the centre
/// pixels' mean lies within 4 standard errors of 0.5 (their spread the noise), the corners are
/// 1 (an escaping ray sees the sky alone, no noise).
#[test]
fn a_diffuse_sphere_under_a_constant_sky_is_half_as_bright() {
    let dir = tempfile::tempdir().expect("tempdir");
    let text = format!(
        r#"<scene version="3.0.0">
    <default name="res" value="32"/>
    <integrator type="path"><integer name="max_depth" value="-1"/></integrator>
    {}
    <bsdf type="twosided" id="grey"><bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></bsdf>
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    <shape type="sphere"><float name="radius" value="1"/><ref id="grey"/></shape>
</scene>"#,
        sensor("$res", r#"<rfilter type="box"/>"#)
    );
    let path = write(dir.path(), "furnace.xml", &text);
    let scene = scene::load(&path).expect("loads");
    assert!(scene.notes.is_empty(), "{:?}", scene.notes);
    let mut options = RenderOptions::from_scene(&scene);
    options.spp = 64;
    let out = render(&scene, &options, &|_| {}).expect("renders");
    let image = &out.film.raw;
    assert_eq!((image.width, image.height), (32, 32));
    let centre: Vec<f64> =
        (12..20).flat_map(|y| (12..20).map(move |x| (x, y))).map(|(x, y)| image.get(x, y).x as f64).collect();
    let (mean, se) = mean_and_standard_error_of(&centre);
    assert!((mean - 0.5).abs() < 4.0 * se + 1e-4, "sphere {mean} +- {se}");
    for (x, y) in [(0, 0), (31, 0), (0, 31), (31, 31)] {
        assert!(
            (image.get(x, y) - glam::Vec3::ONE).abs().max_element() < 1e-5,
            "corner {:?}",
            image.get(x, y)
        );
    }
}

/// `-D` sets a parameter over its `<default>` (here the film's size), on the command line as in
/// the library; a file that is not Mitsuba's refuses it; a crop window is the image's size.
#[test]
fn parameters_and_crops_set_the_image() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene_text = |film_extra: &str| {
        format!(
            r#"<scene version="3.0.0">
    <default name="res" value="8"/>
    {}
    <emitter type="constant"/>
    <shape type="sphere"><bsdf type="diffuse"/></shape>
</scene>"#,
            sensor("$res", film_extra)
        )
    };
    let path = write(dir.path(), "p.xml", &scene_text(""));
    let options = scene::LoadOptions { camera: None, defines: vec![("res".into(), "12".into())] };
    let loaded = scene::load_with(&path, &options).expect("loads");
    assert_eq!((loaded.film.width, loaded.film.height), (12, 12));
    assert_eq!(scene::load(&path).expect("loads").film.width, 8);
    let out = dir.path().join("o.exr");
    let o = lightsplit(&[
        "render",
        path.to_str().unwrap(),
        "-D",
        "res=10",
        "--spp",
        "1",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let image = lightsplit::film::read_image(&out).expect("reads");
    assert_eq!((image.width, image.height), (10, 10));
    let o = lightsplit(&["info", "scenes/cornell.toml", "-D", "res=10"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not an XML file"));
    let crop = r#"<integer name="crop_offset_x" value="2"/><integer name="crop_offset_y" value="1"/>
        <integer name="crop_width" value="5"/><integer name="crop_height" value="3"/>"#;
    let path = write(dir.path(), "c.xml", &scene_text(crop));
    let loaded = scene::load(&path).expect("loads");
    assert_eq!((loaded.film.width, loaded.film.height), (5, 3));
    let window = loaded.film.window.expect("a window");
    assert_eq!((window.film_width, window.film_height, window.x, window.y), (8, 8, 2, 1));
    // The default filter is Mitsuba's: a Gaussian of stddev 0.5.
    assert_eq!(loaded.film.pixel_filter, scene::PixelFilter::Gaussian { stddev: 0.5 });
    let bad = r#"<integer name="crop_offset_x" value="6"/><integer name="crop_width" value="5"/>"#;
    let e = scene::load(&write(dir.path(), "bad.xml", &scene_text(bad))).expect_err("outside");
    assert!(e.to_string().contains("does not lie within"), "{e}");
}

/// Includes (from the top file's directory, as Mitsuba resolves them), references to objects
/// defined later, instances of a shape group, and a named conductor: the scene has what the
/// files say, and an unknown BSDF or parameter is one note naming its file and line.
#[test]
fn includes_references_instances_and_notes() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::create_dir(dir.path().join("parts")).expect("mkdir");
    write(
        dir.path(),
        "parts/bsdfs.xml",
        r#"<scene version="3.0.0">
    <bsdf type="roughconductor" id="gold"><string name="material" value="Au"/><float name="alpha" value="0.2"/></bsdf>
    <bsdf type="velvet" id="odd"><float name="sheen" value="1"/></bsdf>
</scene>"#,
    );
    let text = format!(
        r#"<scene version="3.0.0">
    {}
    <include filename="parts/bsdfs.xml"/>
    <shape type="sphere"><ref id="odd"/><float name="sparkle" value="2"/></shape>
    <shape type="shapegroup" id="pair">
        <shape type="sphere"><float name="radius" value="0.2"/><ref id="gold"/></shape>
        <shape type="cube"><ref id="later"/></shape>
    </shape>
    <shape type="instance"><ref id="pair"/><transform name="to_world"><translate x="2"/></transform></shape>
    <shape type="instance"><ref id="pair"/><transform name="to_world"><translate x="-2"/></transform></shape>
    <bsdf type="diffuse" id="later"/>
    <emitter type="point"><point name="position" x="0" y="3" z="3"/><rgb name="intensity" value="10"/></emitter>
</scene>"#,
        sensor("16", "")
    );
    let path = write(dir.path(), "s.xml", &text);
    let loaded = scene::load(&path).expect("loads");
    assert!(loaded.inputs.iter().any(|p| p.ends_with("parts/bsdfs.xml")), "{:?}", loaded.inputs);
    // A one-sided BSDF is black from behind, as Mitsuba's.
    let gold = |m: &scene::Material| match m {
        scene::Material::Front(inner) => matches!(**inner, scene::Material::Conductor(_)),
        _ => false,
    };
    assert!(loaded.materials.iter().any(gold), "{:?}", loaded.materials);
    let instanced = loaded
        .shapes
        .iter()
        .filter(|s| matches!(&s.geometry, scene::Geometry::Triangles(m) if m.instance.is_some()))
        .count();
    // The group's cube (the sphere is not a mesh) in each of the two instances.
    assert_eq!(instanced, 2, "two instances of the group's mesh");
    let velvet = loaded.notes.iter().find(|n| n.contains("velvet")).expect("a note for velvet");
    assert!(velvet.contains("parts/bsdfs.xml:3:"), "{velvet}");
    let sparkle = loaded.notes.iter().find(|n| n.contains("sparkle")).expect("a note for sparkle");
    assert!(sparkle.contains("s.xml:12:"), "{sparkle}");
    let o = lightsplit(&["info", path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stderr = String::from_utf8_lossy(&o.stderr);
    let line = stderr.lines().find(|l| l.contains("sparkle")).expect("printed");
    assert!(line.starts_with("note: ") && line.matches("s.xml").count() == 1, "{line}");
}

/// Bad files are one error naming the file and line, exit status 2: an unclosed tag, an unknown
/// reference, a missing mesh, a cycle of includes, a bad value.
#[test]
fn bad_files_are_one_error_with_file_and_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let body = |inner: &str| format!("<scene version=\"3.0.0\">\n{}\n{inner}\n</scene>", sensor("8", ""));
    write(d, "a.xml", "<scene version=\"3.0.0\">\n<include filename=\"b.xml\"/>\n</scene>");
    write(d, "b.xml", "<scene version=\"3.0.0\">\n<include filename=\"a.xml\"/>\n</scene>");
    for (name, text, needles) in [
        (
            "unclosed.xml",
            "<scene version=\"3.0.0\">\n<shape type=\"sphere\">\n</scene>".to_string(),
            vec!["unclosed.xml:", "not valid XML"],
        ),
        (
            "ref.xml",
            body("<shape type=\"sphere\"><ref id=\"nowhere\"/></shape>"),
            vec!["ref.xml:11:", "nowhere"],
        ),
        (
            "mesh.xml",
            body("<shape type=\"obj\"><string name=\"filename\" value=\"gone.obj\"/></shape>"),
            vec!["mesh.xml:11:", "gone.obj"],
        ),
        (
            "cycle.xml",
            "<scene version=\"3.0.0\">\n<include filename=\"a.xml\"/>\n</scene>".to_string(),
            vec!["cycle.xml:2:", "a cycle"],
        ),
        (
            "value.xml",
            body("<shape type=\"sphere\"><float name=\"radius\" value=\"wide\"/></shape>"),
            vec!["value.xml:11:", "wide"],
        ),
    ] {
        let path = write(d, name, &text);
        let o = lightsplit(&["render", path.to_str().unwrap(), "-o", d.join("o.png").to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{name}: {stderr}");
        assert_eq!(stderr.lines().filter(|l| l.starts_with("error")).count(), 1, "{name}: {stderr}");
        for needle in needles {
            assert!(stderr.contains(needle), "{name}: no `{needle}` in {stderr}");
        }
        assert!(!d.join("o.png").exists(), "{name}: wrote an image");
    }
}

/// The TOML film takes the same reconstruction filters; a bad one is refused with its line.
#[test]
fn toml_pixel_filters() {
    let base = "[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\n[[shape]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n";
    let with = |film: &str| {
        scene::file::parse(Path::new("t.toml"), &format!("{base}[film]\nwidth = 8\nheight = 8\n{film}"))
    };
    assert_eq!(with("").expect("parses").film.pixel_filter, scene::PixelFilter::Box { radius: 0.5 });
    let tent = with("pixel_filter = \"tent\"\npixel_filter_radius = 1.5").expect("parses");
    assert_eq!(tent.film.pixel_filter, scene::PixelFilter::Tent { radius: 1.5 });
    let g = with("pixel_filter = \"gaussian\"").expect("parses");
    assert_eq!(g.film.pixel_filter, scene::PixelFilter::Gaussian { stddev: 0.5 });
    for (bad, needle) in [
        ("pixel_filter = \"lanczos\"", "unknown pixel_filter"),
        ("pixel_filter = \"gaussian\"\npixel_filter_radius = 2", "does not apply"),
        ("pixel_filter = \"tent\"\npixel_filter_radius = -1", "must lie in"),
    ] {
        let e = with(bad).expect_err(bad);
        assert!(e.to_string().contains(needle), "{bad}: {e}");
    }
}

/// A `mask`'s opacity from a colour bitmap is its luminance, its alpha channel dropped, as
/// Mitsuba's `eval_1` reads it: a pure red RGBA image (alpha 1) is opacity 0.2127, so a black
/// masked rectangle before a sky of radiance 1 shows 1 - 0.2127 of the sky (within 4
/// standard errors of the pixels' spread), where its red channel or its alpha would hide all.
#[test]
fn a_mask_reads_a_colour_bitmap_by_its_luminance() {
    let dir = tempfile::tempdir().expect("tempdir");
    let red = image::RgbaImage::from_pixel(2, 2, image::Rgba([255, 0, 0, 255]));
    red.save(dir.path().join("red.png")).expect("png");
    let text = format!(
        r#"<scene version="3.0.0">
    {}
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    <shape type="rectangle">
        <transform name="to_world"><scale value="3"/></transform>
        <bsdf type="mask">
            <texture type="bitmap" name="opacity"><string name="filename" value="red.png"/></texture>
            <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
        </bsdf>
    </shape>
</scene>"#,
        sensor("16", r#"<rfilter type="box"/>"#)
    );
    let path = write(dir.path(), "mask.xml", &text);
    let scene = scene::load(&path).expect("loads");
    let mut options = RenderOptions::from_scene(&scene);
    options.spp = 64;
    let out = render(&scene, &options, &|_| {}).expect("renders");
    let values: Vec<f64> = out.film.raw.pixels.iter().map(|p| p.y as f64).collect();
    let (mean, se) = mean_and_standard_error_of(&values);
    let want = 1.0 - 0.212671;
    assert!((mean - want).abs() < 4.0 * se + 1e-3, "{mean} +- {se}, want {want}");
}

/// A `blendbsdf` is its two BSDFs mixed by its weight: a sphere blending black (weight 0.75)
/// and a white diffuse of reflectance 0.8 (weight 0.25) under a sky of radiance 1 is 0.2 in
/// expectation (a convex shape sees only the sky), within 4 standard errors of its pixels.
#[test]
fn a_blend_mixes_its_bsdfs_by_weight() {
    let dir = tempfile::tempdir().expect("tempdir");
    let text = format!(
        r#"<scene version="3.0.0">
    {}
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    <shape type="sphere">
        <bsdf type="blendbsdf">
            <float name="weight" value="0.25"/>
            <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.8"/></bsdf>
        </bsdf>
    </shape>
</scene>"#,
        sensor("32", r#"<rfilter type="box"/>"#)
    );
    let path = write(dir.path(), "blend.xml", &text);
    let scene = scene::load(&path).expect("loads");
    assert!(scene.notes.is_empty(), "{:?}", scene.notes);
    let mut options = RenderOptions::from_scene(&scene);
    options.spp = 64;
    let out = render(&scene, &options, &|_| {}).expect("renders");
    let centre: Vec<f64> = (12..20)
        .flat_map(|y| (12..20).map(move |x| (x, y)))
        .map(|(x, y)| out.film.raw.get(x, y).x as f64)
        .collect();
    let (mean, se) = mean_and_standard_error_of(&centre);
    assert!((mean - 0.2).abs() < 4.0 * se + 1e-3, "{mean} +- {se}");
    let bad = text.replace(r#"value="0.25""#, r#"value="1.5""#);
    let e = scene::load(&write(dir.path(), "bad.xml", &bad)).expect_err("weight over 1");
    assert!(e.to_string().contains("[0, 1]"), "{e}");
}
