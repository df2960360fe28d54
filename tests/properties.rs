//! Property tests (proptest): the scene parser never panics, whatever it reads, and a scene it
//! accepts renders without panicking; a damaged input file is refused, never a panic; the
//! filters keep energy and symmetry.

use std::path::Path;

use glam::Vec3;
use lightsplit::accel::Backend;
use lightsplit::film::{Film, Image};
use lightsplit::filter::{filter, EdgeStops, Method};
use lightsplit::render::{render, RenderOptions};
use lightsplit::scene::file::parse;
use proptest::prelude::*;

/// A valid scene with every section, which the mutations below break in small ways.
const SCENE: &str = r#"[camera]
position = [0, 1, -4]
look_at = [0, 0.5, 0]
up = [0, 1, 0]
fov = 40
[film]
width = 4
height = 4
spp = 1
[render]
max_depth = 3
seed = 2
[filter]
kernel = "box3"
edge_aware = true
[[texture]]
name = "check"
type = "checker"
size = 0.5
[[material]]
name = "m"
type = "glossy"
color = [0.9, 0.6, 0.2]
roughness = 0.3
texture = "check"
[[material]]
name = "g"
type = "glass"
ior = 1.5
[[shape]]
type = "sphere"
material = "g"
center = [0, 0.5, 0]
radius = 0.5
[[shape]]
type = "quad"
material = "m"
vertices = [[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]]
[[shape]]
type = "box"
min = [0.6, 0, 0]
max = [1, 0.4, 0.4]
emission = [1, 1, 1]
[[light]]
type = "spot"
position = [0, 3, 0]
direction = [0, -1, 0]
intensity = [5, 5, 5]
cone_angle = 30
[[light]]
type = "sun"
direction = [0.3, 1, 0.2]
irradiance = [1, 1, 1]
"#;

/// Values a mutation puts in place of a number or a string.
const VALUES: [&str; 22] = [
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "-0.0",
    "1e39",
    "1e-45",
    "3e38",
    "18446744073709551616",
    "-9223372036854775808",
    "4294967296",
    "\"\"",
    "\"x\"",
    "[]",
    "[1, 2]",
    "[nan, 0, 0]",
    "[1e30, 1e30, 1e30]",
    "{}",
    "true",
    "\"median3\"",
    "\"../../nope.obj\"",
];

/// The scene with the `k`-th token (a run of characters between separators) replaced.
fn replace_token(text: &str, k: usize, value: &str) -> String {
    let separators = |c: char| c.is_whitespace() || "=[],".contains(c);
    let mut tokens: Vec<(usize, usize)> = Vec::new();
    let mut start = None;
    for (i, c) in text.char_indices() {
        match (separators(c), start) {
            (true, Some(s)) => {
                tokens.push((s, i));
                start = None;
            }
            (false, None) => start = Some(i),
            _ => {}
        }
    }
    let (s, e) = tokens[k % tokens.len()];
    format!("{}{value}{}", &text[..s], &text[e..])
}

/// Parses; when the scene is accepted, renders it small with the BVH. Must not panic.
fn parse_and_render(text: &str) {
    if let Ok(scene) = parse(Path::new("fuzz.toml"), text) {
        let mut options = RenderOptions::from_scene(&scene);
        (options.width, options.height, options.spp, options.max_depth) = (4, 4, 1, 3);
        options.accel = Backend::Bvh;
        options.threads = Some(1);
        let _ = render(&scene, &options, &|_| {});
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn the_parser_never_panics_on_arbitrary_text(text in any::<String>()) {
        parse_and_render(&text);
    }

    #[test]
    fn the_parser_never_panics_on_a_broken_scene(edits in prop::collection::vec((any::<usize>(), 0..VALUES.len()), 1..4),
                                                 cut in any::<usize>(), drop_line in any::<Option<usize>>()) {
        let mut text = SCENE.to_string();
        for (k, v) in edits {
            text = replace_token(&text, k, VALUES[v]);
        }
        if let Some(n) = drop_line {
            let lines: Vec<&str> = text.lines().collect();
            let n = n % lines.len();
            text = lines.iter().enumerate().filter(|&(i, _)| i != n).map(|(_, l)| *l).collect::<Vec<_>>().join("\n");
        }
        parse_and_render(&text);
        // Cut anywhere (on a character boundary): a half-written file.
        let at = (0..=cut % (text.len() + 1)).rev().find(|&i| text.is_char_boundary(i)).unwrap_or(0);
        parse_and_render(&text[..at]);
    }
}

/// An image of `w` x `h` pixels from `values` (cycled), and a film whose object IDs are `ids`.
fn image_and_film(w: u32, h: u32, values: &[f32], ids: &[u8]) -> (Image, Film) {
    let mut image = Image::new(w, h);
    let mut film = Film::new(w, h);
    for i in 0..(w * h) as usize {
        let v = |k: usize| values[(3 * i + k) % values.len()];
        image.pixels[i] = Vec3::new(v(0), v(1), v(2));
        film.object[i] = ids[i % ids.len()] as f32;
    }
    (image, film)
}

/// `image` mirrored left to right.
fn mirror(image: &Image) -> Image {
    let mut out = Image::new(image.width, image.height);
    for y in 0..image.height {
        for x in 0..image.width {
            out.set(image.width - 1 - x, y, image.get(x, y));
        }
    }
    out
}

/// `image` transposed (x and y swapped).
fn transpose(image: &Image) -> Image {
    let mut out = Image::new(image.height, image.width);
    for y in 0..image.height {
        for x in 0..image.width {
            out.set(y, x, image.get(x, y));
        }
    }
    out
}

fn mirror_film(film: &Film, f: impl Fn(&Image) -> Image) -> Film {
    let ids = Image {
        width: film.width,
        height: film.height,
        pixels: film.object.iter().map(|&o| Vec3::splat(o)).collect(),
    };
    let moved = f(&ids);
    let mut out = Film::new(moved.width, moved.height);
    out.object = moved.pixels.iter().map(|p| p.x).collect();
    out
}

fn kernels() -> impl Strategy<Value = Method> {
    prop_oneof![Just("box3"), Just("weighted3"), Just("median3"), Just("box5"), Just("1,3,1,3,9,3,1,3,1"),]
        .prop_map(|name| Method::parse(name).expect("a kernel"))
}

fn close(a: &Image, b: &Image) -> Result<(), TestCaseError> {
    for (i, (p, q)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        let tolerance = 1e-5 * (1.0 + p.abs().max_element());
        prop_assert!((*p - *q).abs().max_element() <= tolerance, "pixel {i}: {p} vs {q}");
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// Filtering commutes with mirroring and transposing the image (and its object IDs): no
    /// direction is preferred, the borders included.
    #[test]
    fn filters_are_symmetric(w in 1u32..14, h in 1u32..14, values in prop::collection::vec(0.0f32..100.0, 1..64),
                             ids in prop::collection::vec(0u8..3, 1..7), kernel in kernels(), aware in any::<bool>()) {
        let (image, film) = image_and_film(w, h, &values, &ids);
        let stops = EdgeStops { object: aware, ..EdgeStops::default() };
        let once = filter(&image, &kernel, &film, &stops);
        close(&filter(&mirror(&image), &kernel, &mirror_film(&film, mirror), &stops), &mirror(&once))?;
        close(&filter(&transpose(&image), &kernel, &mirror_film(&film, transpose), &stops), &transpose(&once))?;
    }

    /// A linear filter keeps the image's energy: light more than the kernel's radius from the
    /// border is spread, never lost or made (the sum is unchanged); and a constant stays itself.
    #[test]
    fn linear_filters_keep_energy(w in 5u32..20, h in 5u32..20, values in prop::collection::vec(0.0f32..100.0, 1..64),
                                  kernel in kernels(), level in 0.0f32..1e4) {
        let Method::Convolution { size, .. } = kernel else { return Ok(()) };
        let r = size as u32 / 2;
        let margin = 2 * r;
        prop_assume!(w > 2 * margin && h > 2 * margin);
        let (mut image, film) = image_and_film(w, h, &values, &[0]);
        for y in 0..h {
            for x in 0..w {
                if x < margin || y < margin || x >= w - margin || y >= h - margin {
                    image.set(x, y, Vec3::ZERO);
                }
            }
        }
        let out = filter(&image, &kernel, &film, &EdgeStops::default());
        let sum = |img: &Image| img.pixels.iter().map(|p| p.as_dvec3()).sum::<glam::DVec3>();
        let (before, after) = (sum(&image), sum(&out));
        prop_assert!((before - after).abs().max_element() <= 1e-5 * before.abs().max_element().max(1.0),
                     "{before} -> {after}");
        let mut flat = Image::new(w, h);
        flat.pixels.iter_mut().for_each(|p| *p = Vec3::splat(level));
        let out = filter(&flat, &kernel, &film, &EdgeStops::default());
        prop_assert!(out.pixels.iter().all(|p| (*p - Vec3::splat(level)).abs().max_element() <= 1e-5 * level.max(1.0)));
    }
}

/// The mutations start from a scene that parses and renders, and a fair share of them still
/// parse (so the render after the parser is exercised too).
#[test]
fn the_base_scene_is_valid_and_mutations_often_parse() {
    let scene = parse(Path::new("base.toml"), SCENE).expect("the base scene parses");
    assert_eq!((scene.shapes.len(), scene.lights.len(), scene.textures.len()), (3, 2, 1));
    let ok = (0..VALUES.len() * 40)
        .filter(|&k| {
            parse(Path::new("m.toml"), &replace_token(SCENE, k * 7, VALUES[k % VALUES.len()])).is_ok()
        })
        .count();
    assert!(ok > 20, "only {ok} of {} single mutations parse", VALUES.len() * 40);
}

/// Valid environment maps in each format a map may have (EXR, Radiance HDR, PFM), as bytes.
fn environment_files() -> Vec<(&'static str, Vec<u8>)> {
    let dir = tempfile::tempdir().expect("tempdir");
    let pixels = (0..32).map(|i| Vec3::new(i as f32, 0.5, 2.0)).collect();
    let image = Image { width: 8, height: 4, pixels };
    ["exr", "hdr", "pfm"]
        .into_iter()
        .map(|ext| {
            let path = dir.path().join(format!("env.{ext}"));
            lightsplit::film::write(&image, &path, 0.0).expect("writes");
            (ext, std::fs::read(&path).expect("reads"))
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    /// A damaged environment map (cut short, or bytes overwritten) is read or refused with an
    /// error, never a panic; a map it reads passes the map's own checks.
    #[test]
    fn a_damaged_environment_map_is_refused_not_a_panic(
        format in 0usize..3,
        cut in any::<prop::sample::Index>(),
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..6),
    ) {
        let files = environment_files();
        let (ext, mut bytes) = files[format].clone();
        bytes.truncate(cut.index(bytes.len() + 1));
        for (at, b) in edits {
            if !bytes.is_empty() {
                let i = at.index(bytes.len());
                bytes[i] = b;
            }
        }
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join(format!("env.{ext}"));
        std::fs::write(&path, &bytes).expect("write");
        if let Ok(map) = lightsplit::scene::environment::EnvironmentMap::load(&path, 1.0, 0.0) {
            prop_assert_eq!(map.image.width, 2 * map.image.height);
            prop_assert!(map.image.pixels.iter().all(|p| p.is_finite() && p.min_element() >= 0.0));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// A damaged binary glTF (cut short, or bytes overwritten, in its JSON or its buffer) is read
    /// or refused with an error, never a panic; what it reads has only finite positions and
    /// indices in range.
    #[test]
    fn a_damaged_glb_is_refused_not_a_panic(
        cut in any::<prop::sample::Index>(),
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..6),
    ) {
        let mut doc = crate::common::GltfDoc::quad();
        doc.node(serde_json::json!({"mesh": 0, "translation": [0, 1, 0]}), true);
        let mut bytes = doc.glb();
        bytes.truncate(cut.index(bytes.len() + 1).max(bytes.len() * 9 / 10));
        for (at, b) in edits {
            let i = at.index(bytes.len());
            bytes[i] = b;
        }
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("m.glb");
        std::fs::write(&path, &bytes).expect("write");
        if let Ok(g) = lightsplit::scene::gltf::load(&path) {
            for p in &g.primitives {
                prop_assert!(p.positions.iter().all(|p| p.is_finite()));
                prop_assert!(p.indices.iter().flatten().all(|&i| (i as usize) < p.positions.len()));
            }
            for part in &g.parts {
                prop_assert!(part.primitive < g.primitives.len());
                prop_assert!(part.positions(&g).all(|p| p.is_finite()));
            }
        }
    }
}
