//! Cryptomatte (`--cryptomatte`): each pixel's coverage is the share of its samples whose camera
//! ray first hit each object and material, which two other accumulators of the render confirm;
//! parts merge to the whole render's coverage exactly, splatted too; the EXR has the
//! specification's layers and header, kept by part files, `merge` and `filter`; `lightsplit
//! matte` reads it back as a compositor does; bad requests are one error with status 2.

use std::path::Path;

use lightsplit::film::cryptomatte::{self, Matte};
use lightsplit::film::{self, Film, Metadata, Sums};
use lightsplit::render::{render_controlled, Control, Part, RenderOptions};
use lightsplit::scene::{self, Scene};

use crate::common::lightsplit as run;

/// Two diffuse spheres of two materials over a diffuse floor of the first, under a sky the
/// camera also sees: edges between objects, between materials, and against nothing.
const SCENE: &str = r#"
[camera]
position = [0, 1.2, -5]
look_at = [0, 0.6, 0]
fov = 40

[[material]]
name = "chalk"
type = "diffuse"
color = [0.7, 0.7, 0.7]

[[material]]
name = "brick"
type = "diffuse"
color = [0.6, 0.2, 0.1]

[[shape]]
type = "sphere"
object = "left ball"
material = "chalk"
center = [-0.7, 0.6, 0]
radius = 0.6

[[shape]]
type = "sphere"
object = "right ball"
material = "brick"
center = [0.6, 0.5, -0.4]
radius = 0.5

[[shape]]
type = "quad"
object = "floor"
material = "chalk"
vertices = [[-3, 0, -3], [-3, 0, 3], [3, 0, 3], [3, 0, -3]]

[[light]]
type = "sky"
radiance = [1, 1, 1]
"#;

fn scene() -> Scene {
    scene::file::parse(Path::new("balls.toml"), SCENE).expect("parses")
}

fn sums(scene: &Scene, part: Part) -> Sums {
    let mut o = RenderOptions::from_scene(scene);
    (o.width, o.height, o.spp, o.seed, o.part, o.cryptomatte) = (32, 24, 16, 3, part, true);
    let control = Control { keep_sums: true, ..Control::progress(&|_| {}) };
    render_controlled(scene, &o, control).expect("renders").sums.expect("sums kept")
}

fn matte<'f>(film: &'f Film, kind: &str) -> &'f Matte {
    film.mattes.iter().find(|m| m.kind == kind).unwrap_or_else(|| panic!("no {kind}"))
}

/// Each pixel's share of `name` in a matte's coverage (all its ids, not only six ranks).
fn share(film: &Film, kind: &str, name: &str, i: usize) -> f32 {
    let c = matte(film, kind).coverage().expect("a render's coverage")[i];
    let id = f32::from_bits(cryptomatte::name_id(name));
    c.ranks(cryptomatte::CAP).iter().find(|r| r.0 == id).map_or(0.0, |r| r.1)
}

/// With the pixel's own box every sample weighs 1: a pixel's coverage of the object its sample 0
/// shows is the object-ID buffer's coverage (the share of samples seeing that object, counted
/// by the guide buffers), the ranks together are its alpha (the share that hit anything), and
/// the materials split the same samples (chalk = left ball + floor, brick = right ball).
#[test]
fn coverage_is_the_share_of_samples_hitting_each_object_and_material() {
    let scene = scene();
    let film = sums(&scene, Part::default()).into_means();
    let (mut edges, mut sky_edges) = (0, 0);
    for i in 0..film.object.len() {
        let c = matte(&film, cryptomatte::OBJECT).coverage().expect("coverage")[i];
        assert_eq!(c.total_units(), 16u128 << 32, "pixel {i}: 16 samples of weight 1");
        let covered: f32 = c.ranks(cryptomatte::CAP).iter().map(|r| r.1).sum();
        assert!(
            (covered - film.alpha[i]).abs() < 1e-6,
            "pixel {i}: {covered} against alpha {}",
            film.alpha[i]
        );
        if film.object[i] >= 0.0 {
            let name = &scene.objects[film.object[i] as usize];
            let got = share(&film, cryptomatte::OBJECT, name, i);
            assert!(
                (got - film.coverage[i]).abs() < 1e-6,
                "pixel {i}: {name} {got} against {}",
                film.coverage[i]
            );
        }
        let object = |n: &str| share(&film, cryptomatte::OBJECT, n, i);
        let material = |n: &str| share(&film, cryptomatte::MATERIAL, n, i);
        assert!((material("chalk") - object("left ball") - object("floor")).abs() < 1e-6, "pixel {i}");
        assert_eq!(material("brick"), object("right ball"), "pixel {i}");
        edges += (c.len() > 1) as u32;
        sky_edges += (c.len() == 1 && film.alpha[i] > 0.0 && film.alpha[i] < 1.0) as u32;
    }
    // The test means something: pixels mixing objects, and objects mixed with the sky.
    assert!(edges > 10 && sky_edges > 10, "{edges} edges, {sky_edges} against the sky");
}

/// Parts merge to exactly the whole render's coverage (fixed-point sums), with the pixel's box
/// and with a splatted Gaussian, whose weights reach the neighbours.
#[test]
fn parts_merge_to_the_whole_coverage_exactly() {
    let boxed = scene();
    let mut gaussian = scene();
    gaussian.film.pixel_filter = scene::PixelFilter::Gaussian { stddev: 0.5 };
    for (what, scene) in [("box", &boxed), ("gaussian", &gaussian)] {
        let whole = sums(scene, Part::default());
        let mut merged = sums(scene, Part { index: 2, count: 3 });
        for index in [0, 1] {
            merged.add(&sums(scene, Part { index, count: 3 })).expect("parts of one render");
        }
        assert_eq!(whole.film.mattes, merged.film.mattes, "{what}");
        let ranks = |s: &Sums| s.film.mattes.iter().map(Matte::rank_channels).collect::<Vec<_>>();
        assert_eq!(ranks(&whole), ranks(&merged), "{what}");
    }
    // A splatted pixel's total is the filter's weights around it, not its sample count.
    let splat = sums(&gaussian, Part::default());
    let c = matte(&splat.film, cryptomatte::OBJECT).coverage().expect("coverage");
    assert!(c.iter().any(|c| c.total_units() != 16u128 << 32));
}

fn channels(path: &str) -> (film::Channels, Metadata) {
    let (_, _, channels) = film::read_exr_channels(Path::new(path)).expect("reads");
    (channels, Metadata::of_exr(Path::new(path)).expect("header"))
}

fn crypto(channels: &film::Channels) -> film::Channels {
    channels.iter().filter(|(n, _)| n.starts_with("Crypto")).cloned().collect()
}

/// The command line: the specification's layers and header attributes, the same through two
/// part files and `merge`, then `filter`; `matte` sums a name's ranks, as a compositor does.
#[test]
fn the_exr_has_the_specifications_layers_through_parts_merge_filter_and_matte() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let scene_path = out("balls.toml");
    std::fs::write(&scene_path, SCENE).expect("writes");
    let common = ["--width", "32", "--height", "24", "--spp", "16", "--seed", "3", "--cryptomatte"];
    let ok = |o: std::process::Output| assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let whole = out("whole.exr");
    ok(run(&[&["render", &scene_path, "-o", &whole][..], &common].concat()));
    let parts: Vec<String> = (0..2).map(|p| out(&format!("p{p}.exr"))).collect();
    for (p, part) in parts.iter().enumerate() {
        ok(run(&[&["render", &scene_path, "-o", part, "--part", &format!("{p}/2")][..], &common].concat()));
    }
    let merged = out("merged.exr");
    ok(run(&["merge", &parts[0], &parts[1], "-o", &merged]));
    let filtered = out("filtered.exr");
    ok(run(&["filter", &merged, "-o", &filtered, "--filter", "box3"]));

    let (whole_channels, meta) = channels(&whole);
    let names: Vec<String> = crypto(&whole_channels).into_iter().map(|(n, _)| n).collect();
    let mut expected = cryptomatte::channel_names("CryptoMaterial", 6);
    expected.extend(cryptomatte::channel_names("CryptoObject", 6));
    // An EXR's channels are sorted by name.
    expected.sort();
    assert_eq!(names, expected);
    for kind in ["CryptoObject", "CryptoMaterial"] {
        let key = cryptomatte::layer_key(kind);
        let attr =
            |a: &str| meta.extra.iter().find(|(n, _)| *n == format!("cryptomatte/{key}/{a}")).map(|(_, v)| v);
        assert_eq!(attr("name").map(String::as_str), Some(kind));
        assert_eq!(attr("hash").map(String::as_str), Some("MurmurHash3_32"));
        assert_eq!(attr("conversion").map(String::as_str), Some("uint32_to_float32"));
        let manifest = attr("manifest").expect("a manifest");
        let json: serde_json::Value = serde_json::from_str(manifest).expect("JSON");
        let names = if kind == "CryptoObject" {
            ["left ball", "right ball", "floor"]
        } else {
            ["chalk", "brick", "chalk"]
        };
        for name in names {
            assert_eq!(json[name], cryptomatte::id_hex(cryptomatte::name_id(name)), "{kind} {name}");
        }
    }
    for other in [&merged, &filtered] {
        let (c, m) = channels(other);
        assert!(crypto(&c) == crypto(&whole_channels), "{other}: other ranks");
        let attrs = |m: &Metadata| {
            m.extra.iter().filter(|(n, _)| n.starts_with("cryptomatte/")).cloned().collect::<Vec<_>>()
        };
        assert_eq!(attrs(&m), attrs(&meta), "{other}");
    }

    // `matte` of the left ball and of both balls: the coverage the render's film has.
    let film = sums(&scene(), Part::default()).into_means();
    for (names, pfm) in
        [(vec!["left ball"], out("left.pfm")), (vec!["left ball", "right ball"], out("balls.pfm"))]
    {
        ok(run(&[&["matte", &whole][..], &names, &["-o", &pfm]].concat()));
        let image = film::read_image(Path::new(&pfm)).expect("reads");
        for (i, p) in image.pixels.iter().enumerate() {
            let want: f32 = names.iter().map(|n| share(&film, cryptomatte::OBJECT, n, i)).sum();
            assert!((p.x - want).abs() < 1e-6, "{names:?} pixel {i}: {} against {want}", p.x);
        }
        assert!(image.pixels.iter().any(|p| p.x > 0.0 && p.x < 1.0), "an antialiased edge");
    }
    let material = out("brick.pfm");
    ok(run(&["matte", &whole, "brick", "--type", "CryptoMaterial", "-o", &material]));
    let image = film::read_image(Path::new(&material)).expect("reads");
    for (i, p) in image.pixels.iter().enumerate() {
        let want = share(&film, cryptomatte::MATERIAL, "brick", i);
        assert!((p.x - want).abs() < 1e-6, "brick pixel {i}: {} against {want}", p.x);
    }
    assert!(image.pixels.iter().any(|p| p.x == 1.0));
}

/// Bad requests: a matte that is not an EXR layer, a name or type the file does not have, a
/// file without Cryptomatte; each one error with status 2, nothing written.
#[test]
fn bad_cryptomatte_requests_are_one_error_with_status_2() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let scene_path = out("balls.toml");
    std::fs::write(&scene_path, SCENE).expect("writes");
    let small = ["--width", "8", "--height", "8", "--spp", "1"];
    let png = out("out.png");
    let o = run(&[&["render", &scene_path, "-o", &png, "--cryptomatte"][..], &small].concat());
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains(".exr"));
    let (with, without) = (out("with.exr"), out("without.exr"));
    assert!(run(&[&["render", &scene_path, "-o", &with, "--cryptomatte"][..], &small].concat())
        .status
        .success());
    assert!(run(&[&["render", &scene_path, "-o", &without][..], &small].concat()).status.success());
    let m = out("m.exr");
    for (args, says) in [
        (vec!["matte", &with, "left bal", "-o", &m], "not in the `CryptoObject` manifest"),
        (
            vec!["matte", &with, "chalk", "--type", "CryptoAsset", "-o", &m],
            "no Cryptomatte type `CryptoAsset`",
        ),
        (vec!["matte", &without, "floor", "-o", &m], "no Cryptomatte layers"),
    ] {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
    assert!(!Path::new(&m).exists() && !Path::new(&png).exists());
}
