//! AOVs of light path expressions (`[[aov]]`, `--aov`): an AOV of a component's expression is
//! that component bit for bit (splatted too); Arnold's direct, indirect and emission partition
//! the beauty; parts merge to the whole render's AOVs; the EXR carries them through `merge`
//! and `filter`; bad names and expressions are one error with status 2.

use std::path::Path;

use glam::Vec3;
use lightsplit::component::Component;
use lightsplit::film::{self, AovLayer, Film, Sums};
use lightsplit::render::{render_controlled, Control, Part, RenderOptions};
use lightsplit::scene::{self, Aov, Scene};

use crate::common::lightsplit as run;

/// A camera and nothing else: the smallest scene that parses.
const MINIMAL: &str = "[camera]\nposition = [0, 1, -5]\nlook_at = [0, 1, 0]\n";

fn scene(name: &str) -> Scene {
    scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(name)).expect("loads")
}

fn aov(name: &str, lpe: &str) -> Aov {
    Aov::new(name, Some(lpe)).expect("a valid AOV")
}

fn sums(scene: &Scene, aovs: &[Aov], part: Part) -> Sums {
    let mut o = RenderOptions::from_scene(scene);
    (o.width, o.height, o.spp, o.seed, o.part) = (24, 20, 8, 5, part);
    o.aovs = aovs.to_vec();
    let control = Control { keep_sums: true, ..Control::progress(&|_| {}) };
    render_controlled(scene, &o, control).expect("renders").sums.expect("sums kept")
}

fn layer<'f>(film: &'f Film, name: &str) -> &'f AovLayer {
    film.aovs.iter().find(|a| a.name == name).unwrap_or_else(|| panic!("no AOV `{name}`"))
}

/// The paper's components given again as AOVs (by their built-in names, and one written out)
/// sum exactly what the components sum, sample by sample in the same order: equal bits. The
/// gallery has every component (glossy caustics, indirect light); the Gaussian pixel filter
/// splats.
#[test]
fn an_aov_of_a_components_expression_is_that_component_bit_for_bit() {
    let gallery = scene("paper-gallery.toml");
    let aovs = [
        aov("e", "emitted"),
        aov("d", "direct"),
        aov("c", "C[GS]*D[GS]+L"),
        aov("i", "indirect"),
        aov("nothing", "C<TD>L"),
    ];
    let mut splatted = gallery.clone();
    splatted.film.pixel_filter = scene::PixelFilter::Gaussian { stddev: 0.5 };
    for (what, scene) in [("box", &gallery), ("gaussian", &splatted)] {
        let film = sums(scene, &aovs, Part::default()).into_means();
        for (c, name) in Component::ALL.into_iter().zip(["e", "d", "c", "i"]) {
            let (x, y) = (&layer(&film, name).image.pixels, &film.components[c].pixels);
            assert!(x == y, "{what}: AOV `{name}` differs from `{}`", c.name());
            assert!(y.iter().any(|p| p.max_element() > 0.0), "{what}: `{}` is black", c.name());
        }
        // No diffuse transmission in the gallery: nothing, and not nothing by accident.
        assert!(layer(&film, "nothing").image.pixels.iter().all(|p| *p == Vec3::ZERO), "{what}");
    }
}

/// Arnold's direct, indirect and emission split every path: they add up to the beauty within
/// float rounding, each pixel (the Cornell box, whose light the camera sees).
#[test]
fn arnolds_direct_indirect_and_emission_sum_to_the_beauty() {
    let cornell = scene("cornell.toml");
    let aovs =
        [Aov::new("arnold_direct", None), Aov::new("arnold_indirect", None), Aov::new("emission", None)]
            .map(|a| a.expect("a built-in"));
    let film = sums(&cornell, &aovs, Part::default()).into_means();
    let parts = aovs.map(|a| &layer(&film, &a.name).image.pixels);
    for (i, raw) in film.raw.pixels.iter().enumerate() {
        let sum = parts[0][i] + parts[1][i] + parts[2][i];
        assert!(
            (sum - *raw).abs().max_element() <= 1e-5 * raw.max_element().max(1.0),
            "pixel {i}: {sum} against {raw}"
        );
    }
    for p in parts {
        assert!(p.iter().any(|v| v.max_element() > 0.0), "a black Arnold AOV");
    }
}

/// Three parts merge to the whole render's AOV sums (up to the order of float additions).
#[test]
fn parts_merge_to_the_whole_renders_aovs() {
    let cornell = scene("cornell.toml");
    let aovs = [aov("diffuse_indirect", "diffuse_indirect"), aov("via_red", "C.*<RD>.*L")];
    let whole = sums(&cornell, &aovs, Part::default());
    let mut merged = sums(&cornell, &aovs, Part { index: 0, count: 3 });
    for index in 1..3 {
        merged.add(&sums(&cornell, &aovs, Part { index, count: 3 })).expect("parts of one render");
    }
    for (a, b) in whole.film.aovs.iter().zip(&merged.film.aovs) {
        assert_eq!(a.name, b.name);
        for (p, q) in a.image.pixels.iter().zip(&b.image.pixels) {
            assert!(
                (*p - *q).abs().max_element() <= 1e-5 * p.max_element().max(1e-3),
                "{}: {p} against {q}",
                a.name
            );
        }
    }
    // Sums with other AOVs are not parts of this render.
    let other = sums(&cornell, &aovs[..1], Part { index: 1, count: 3 });
    assert!(whole.clone().add(&other).is_err());
}

/// The CLI: `--aov` layers in the EXR, kept by a part file, `merge` and `filter`; the header
/// lists them.
#[test]
fn the_exr_carries_aovs_through_parts_merge_and_filter() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml");
    let scene = scene.to_str().expect("utf-8 path");
    let common =
        ["--width", "16", "--height", "12", "--spp", "8", "--aov", "glossy=C<RG>.*", "--aov", "emission"];
    let whole = out("whole.exr");
    let status = run(&[&["render", scene, "-o", &whole][..], &common].concat());
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let mut parts = Vec::new();
    for p in ["0/2", "1/2"] {
        let part = out(&format!("part{}.exr", &p[..1]));
        let status = run(&[&["render", scene, "-o", &part, "--part", p][..], &common].concat());
        assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
        parts.push(part);
    }
    let merged = out("merged.exr");
    let status = run(&["merge", &parts[0], &parts[1], "-o", &merged]);
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let filtered = out("filtered.exr");
    let status = run(&["filter", &merged, "-o", &filtered, "--filter", "box3"]);
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let read = |p: &str| film::read_film(Path::new(p)).expect("reads");
    let (whole, merged, filtered) = (read(&whole), read(&merged), read(&filtered));
    for film in [&whole, &merged, &filtered] {
        assert_eq!(film::aov_list(&film.aovs), "glossy,emission");
    }
    for (a, b) in whole.aovs.iter().zip(&merged.aovs) {
        for (p, q) in a.image.pixels.iter().zip(&b.image.pixels) {
            assert!((*p - *q).abs().max_element() <= 1e-5 * p.max_element().max(1e-3), "{}", a.name);
        }
    }
    // `filter` filters the image, not the AOVs: they are the merged ones.
    assert_eq!(merged.aovs, filtered.aovs);
    // The light the camera sees directly is the emitted component.
    assert_eq!(layer(&whole, "emission").image.pixels, whole.components[Component::Emitted].pixels);
}

/// Bad AOVs are one error naming what is wrong, with status 2, and nothing is written.
#[test]
fn bad_aovs_are_one_error_with_status_2() {
    let dir = tempfile::tempdir().expect("temp dir");
    let exr = dir.path().join("out.exr").to_string_lossy().into_owned();
    let png = dir.path().join("out.png").to_string_lossy().into_owned();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml");
    let scene = scene.to_str().expect("utf-8 path");
    for (args, says) in [
        (["--aov", "x=C<RD"], "column"),
        (["--aov", "x=CQ"], "column 2"),
        (["--aov", "2x=CL"], "letters, digits"),
        (["--aov", "direct=CL"], "has a layer of that name"),
        (["--aov", "image=CL"], "a filter target's"),
        (["--aov", "final=CL"], "the final image's"),
        (["--aov", "nonesuch"], "not a built-in"),
    ] {
        let o = run(&[&["render", scene, "-o", &exr, "--width", "8", "--height", "8"][..], &args].concat());
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
    let o = run(&["render", scene, "-o", &png, "--aov", "e=emission"]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!Path::new(&exr).exists() && !Path::new(&png).exists());
    // In a scene file: the file and the line of the table.
    let text = format!(
        "{}\n[[aov]]\nname = \"ok\"\nlpe = \"CL\"\n\n[[aov]]\nname = \"bad\"\nlpe = \"C(L\"\n",
        MINIMAL
    );
    let err = lightsplit::scene::file::parse(Path::new("s.toml"), &text).expect_err("a bad expression");
    // The second table starts on line 9: its header or its first key.
    assert!(matches!(err.line, Some(9..=11)), "{err}");
    assert!(err.to_string().contains("column"), "{err}");
    let twice =
        format!("{}\n[[aov]]\nname = \"a\"\nlpe = \"CL\"\n[[aov]]\nname = \"a\"\nlpe = \"CDL\"\n", MINIMAL);
    let err = lightsplit::scene::file::parse(Path::new("s.toml"), &twice).expect_err("a name twice");
    assert!(err.to_string().contains("second"), "{err}");
}

/// The Cornell box with its ceiling light in group `ceiling` and a point light added in group
/// `bulb`.
fn grouped_cornell() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml");
    let text = std::fs::read_to_string(&path).expect("reads");
    let emission = "emission = [18.387, 13.9873, 6.75357]\n";
    assert!(text.contains(emission), "the Cornell box's light");
    let text = text.replace(emission, &format!("{emission}light_group = \"ceiling\"\n"))
        + "\n[[light]]\ntype = \"point\"\nposition = [150, 400, 200]\nintensity = [20000, 30000, 40000]\nlight_group = \"bulb\"\n";
    scene::file::parse(&path, &text).expect("parses")
}

/// Light groups: one layer a group (`--light-groups`'s AOVs), and they split the light by
/// source: with every emitter in a group, the layers sum to the beauty, and each group's
/// direct light (`C[GS]*DL'name'`) sums to the direct component.
#[test]
fn light_groups_split_the_light_by_source() {
    let cornell = grouped_cornell();
    // A scene file's lights' groups first, then its shapes'.
    assert_eq!(cornell.light_groups.names, ["bulb", "ceiling"]);
    let mut aovs = cornell.light_groups.aovs().expect("groups make AOVs");
    assert_eq!(aovs.iter().map(|a| a.name.as_str()).collect::<Vec<_>>(), ["group_bulb", "group_ceiling"]);
    aovs.push(aov("direct_ceiling", "C[GS]*DL'ceiling'"));
    aovs.push(aov("direct_bulb", "C[GS]*DL'bulb'"));
    aovs.push(aov("unknown_group", "C.*L'nonesuch'"));
    let film = sums(&cornell, &aovs, Part::default()).into_means();
    let pixels = |name: &str| &layer(&film, name).image.pixels;
    let close = |a: Vec3, b: Vec3| (a - b).abs().max_element() <= 1e-5 * b.max_element().max(1.0);
    let direct = &film.components[Component::Direct].pixels;
    for (i, raw) in film.raw.pixels.iter().enumerate() {
        let groups = pixels("group_ceiling")[i] + pixels("group_bulb")[i];
        assert!(close(groups, *raw), "pixel {i}: groups {groups} against the beauty {raw}");
        let directs = pixels("direct_ceiling")[i] + pixels("direct_bulb")[i];
        assert!(close(directs, direct[i]), "pixel {i}: {directs} against the direct {}", direct[i]);
    }
    for name in ["group_ceiling", "group_bulb", "direct_ceiling", "direct_bulb"] {
        assert!(pixels(name).iter().any(|p| p.max_element() > 0.0), "`{name}` is black");
    }
    assert!(pixels("unknown_group").iter().all(|p| *p == Vec3::ZERO));
    // The bulb lights what the ceiling light does not reach the same way: the two differ.
    assert_ne!(pixels("group_ceiling"), pixels("group_bulb"));
}

/// `--light-groups` on a scene without groups, and a group name with a quote, are errors.
#[test]
fn light_group_errors() {
    let dir = tempfile::tempdir().expect("temp dir");
    let exr = dir.path().join("out.exr").to_string_lossy().into_owned();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml");
    let o = run(&["render", scene.to_str().expect("utf-8"), "-o", &exr, "--light-groups"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no light groups"));
    let text = format!("{MINIMAL}[[light]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\nlight_group = \"it's\"\n");
    let err = scene::file::parse(Path::new("s.toml"), &text).expect_err("a quote in a group name");
    assert_eq!(err.line, Some(4), "{err}");
}

/// A glTF file's lights and emissive materials are light groups by their names (a light
/// without a name by its node's, a quote made `_`), in the file read directly and placed by a
/// scene file; a scene file's `light_group` on the shape puts them all in its one group.
#[test]
fn gltf_lights_and_emissive_materials_are_groups_by_name() {
    use crate::common::GltfDoc;
    use serde_json::json;
    let dir = tempfile::tempdir().expect("temp dir");
    let mut doc = GltfDoc::quad();
    doc.json["materials"] = json!([{"name": "panel's glow", "emissiveFactor": [1.0, 1.0, 1.0]}]);
    doc.json["meshes"][0]["primitives"][0]["material"] = json!(0);
    doc.node(json!({"mesh": 0}), true);
    doc.json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    doc.json["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "point", "name": "key", "intensity": 683.0},
        {"type": "point", "intensity": 683.0}
    ]}});
    let light = |k: usize| json!({"KHR_lights_punctual": {"light": k}});
    doc.node(json!({"translation": [1, 2, 3], "extensions": light(0)}), true);
    doc.node(json!({"name": "fill_node", "translation": [0, 2, 3], "extensions": light(1)}), true);
    let path = doc.write_gltf(dir.path(), "groups");
    let direct = scene::load(&path).expect("loads");
    assert_eq!(direct.light_groups.names, ["panel_s glow", "key", "fill_node"]);
    assert_eq!(direct.light_groups.of_light(1), Some(2));
    let shape = direct.shapes.iter().position(|s| s.is_emissive()).expect("an emissive shape") as u32;
    assert_eq!(direct.light_groups.of_shape(shape), Some(0));
    let aovs = direct.light_groups.aovs().expect("groups make AOVs");
    let names: Vec<&str> = aovs.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["group_panel_s_glow", "group_key", "group_fill_node"]);

    let toml = |extra: &str| {
        format!("{MINIMAL}[[shape]]\ntype = \"gltf\"\nfile = \"groups.gltf\"\n{extra}\n[[light]]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = [1, 1, 1]\n")
    };
    let placed = scene::file::parse(&dir.path().join("s.toml"), &toml("")).expect("parses");
    assert_eq!(placed.light_groups.names, ["panel_s glow", "key", "fill_node"]);
    // The file's own light is first, in no group: the glTF file's follow it.
    assert_eq!((placed.light_groups.of_light(0), placed.light_groups.of_light(1)), (None, Some(1)));
    assert_eq!(placed.light_groups.of_light(2), Some(2));
    let one = scene::file::parse(&dir.path().join("s.toml"), &toml("light_group = \"all\"")).expect("parses");
    assert_eq!(one.light_groups.names, ["all"]);
    assert_eq!((one.light_groups.of_light(1), one.light_groups.of_light(2)), (Some(0), Some(0)));
}

/// `--environment` removes and adds lights at infinity: the other lights keep their groups.
#[test]
fn groups_follow_their_lights_when_the_environment_changes() {
    let text = format!(
        "{MINIMAL}[[light]]\ntype = \"sky\"\nradiance = [1, 1, 1]\n[[light]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\nlight_group = \"bulb\"\n"
    );
    let mut s = scene::file::parse(Path::new("s.toml"), &text).expect("parses");
    assert_eq!((s.light_groups.of_light(0), s.light_groups.of_light(1)), (None, Some(0)));
    s.set_environment(&scene::Environment::None).expect("no environment");
    assert!(matches!(s.lights[0], scene::Light::Point { .. }));
    assert_eq!(s.light_groups.of_light(0), Some(0));
    s.set_environment(&scene::Environment::White).expect("a white sky");
    assert_eq!((s.light_groups.of_light(0), s.light_groups.of_light(1)), (Some(0), None));
}

/// `--filter-target AOV`: the beauty less the AOV plus the AOV filtered. On an AOV of the
/// indirect expression it is the paper's filter on indirect (up to float rounding); on a black
/// AOV the beauty itself; an AOV the render lacks is one error with status 2.
#[test]
fn a_filter_on_an_aov_replaces_that_aov_by_its_filtered_self() {
    use lightsplit::filter::{composite, EdgeStops, Method, Target};
    let cornell = scene("cornell.toml");
    let film =
        sums(&cornell, &[aov("ind", "indirect"), aov("none_of_it", "C<TD>L")], Part::default()).into_means();
    let box3 = Method::parse("box3").expect("a kernel");
    let stops = EdgeStops::default();
    let target = |name: &str| Target::from_name(name).expect("an AOV's name");
    let (by_aov, _) = composite(&film, Some(&box3), target("ind"), &stops);
    let (paper, _) = composite(&film, Some(&box3), Target::Indirect, &stops);
    assert!(by_aov.pixels != film.raw.pixels, "the filter changed nothing");
    for (a, b) in by_aov.pixels.iter().zip(&paper.pixels) {
        assert!((*a - *b).abs().max_element() <= 1e-5 * b.max_element().max(1.0), "{a} against {b}");
    }
    let (black, _) = composite(&film, Some(&box3), target("none_of_it"), &stops);
    assert_eq!(black.pixels, film.raw.pixels);

    let dir = tempfile::tempdir().expect("temp dir");
    let exr = dir.path().join("out.exr").to_string_lossy().into_owned();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml");
    let scene = path.to_str().expect("utf-8 path");
    let small = ["--width", "8", "--height", "8", "--spp", "2", "--filter", "box3"];
    let o = run(&[
        &["render", scene, "-o", &exr, "--aov", "ind=indirect", "--filter-target", "indd"][..],
        &small,
    ]
    .concat());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("no AOV of that name (the AOVs: ind)"), "{err}");
    assert!(!Path::new(&exr).exists());
    let o =
        run(&[&["render", scene, "-o", &exr, "--aov", "ind=indirect", "--filter-target", "ind"][..], &small]
            .concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // `filter` of the file on its AOV, and on one it lacks.
    let again = dir.path().join("again.exr").to_string_lossy().into_owned();
    let o = run(&["filter", &exr, "-o", &again, "--filter", "box3", "--filter-target", "ind"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = run(&["filter", &exr, "-o", &again, "--filter", "box3", "--filter-target", "glossy"]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `compare --layer`: a layer of two EXRs, not their final images; identical layers give a sum
/// of squares of exactly 0, and a layer the file lacks is one error with status 2.
#[test]
fn compare_takes_any_layer() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml");
    let scene = path.to_str().expect("utf-8 path");
    let small = ["--width", "8", "--height", "8", "--spp", "2", "--aov", "d=direct"];
    for (name, seed) in [("a.exr", "1"), ("b.exr", "1"), ("c.exr", "2")] {
        let o = run(&[&["render", scene, "-o", &out(name), "--seed", seed][..], &small].concat());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let sse = |a: &str, b: &str, layer: &str| -> f64 {
        let o = run(&["compare", &out(a), &out(b), "--layer", layer, "--json"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
        json["sse"].as_f64().expect("sse")
    };
    assert_eq!(sse("a.exr", "b.exr", "direct"), 0.0);
    assert!(sse("a.exr", "c.exr", "direct") > 0.0);
    assert!(sse("a.exr", "c.exr", "d") > 0.0);
    let o = run(&["compare", &out("a.exr"), &out("b.exr"), "--layer", "glossy"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no layer `glossy`"));
}

/// Arnold's albedo (`arnold_albedo`, `C[DGSV]A`) in the Cornell box, all diffuse: each pixel's mean albedo of
/// its first hits, the guide buffers' albedo layer (the same first diffuse vertex); and the
/// components are the same bits with it as without it (an albedo is not light).
#[test]
fn the_albedo_aov_is_the_first_surfaces_albedo() {
    let cornell = scene("cornell.toml");
    let with =
        sums(&cornell, &[Aov::new("arnold_albedo", None).expect("a built-in")], Part::default()).into_means();
    let without = sums(&cornell, &[], Part::default()).into_means();
    assert!(with.components == without.components && with.raw == without.raw, "the light changed");
    let albedo = &layer(&with, "arnold_albedo").image.pixels;
    assert!(albedo.iter().any(|p| p.max_element() > 0.5), "a black albedo");
    for (i, (a, b)) in albedo.iter().zip(&with.albedo.pixels).enumerate() {
        assert!((*a - *b).abs().max_element() <= 1e-6, "pixel {i}: {a} against the guide's {b}");
    }
}
