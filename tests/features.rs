//! Skipping what a scene does not need changes nothing a user sees: for every scene in
//! `scenes/`, every feature set that keeps what the scene needs renders the same beauty, bit for
//! bit, as the general integrator at the same seed, and the split and guides it computes are the
//! same too. Leaving out something the scene does need changes the image (so the flags do
//! remove code), and the buffers a render skips are not allocated.

use crate::common;

use std::path::{Path, PathBuf};

use lightsplit::accel::Backend;
use lightsplit::component::Component::Emitted;
use lightsplit::film::Film;
use lightsplit::render::{render, Features, Outputs, RenderOptions};
use lightsplit::scene::{self, analysis::Analysis, Scene};

fn scenes() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("scenes/ lists")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    paths
}

fn all_subsets() -> impl Iterator<Item = Features> {
    (0..16u8).map(|b| Features {
        mis: b & 1 != 0,
        split: b & 2 != 0,
        guides: b & 4 != 0,
        textures: b & 8 != 0,
    })
}

fn render_with(scene: &Scene, features: Features, accel: Backend) -> (Film, u64, u64) {
    let mut options = RenderOptions::from_scene(scene);
    options.width = 24;
    options.height = 20;
    options.spp = 3;
    options.seed = 5;
    options.accel = accel;
    options.features = features;
    let out = render(scene, &options, &|_| {}).expect("renders");
    (out.film, out.stats.rays, out.stats.buffer_bytes)
}

fn bits(image: &lightsplit::film::Image) -> Vec<u32> {
    image.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect()
}

#[test]
fn every_feature_set_a_scene_allows_renders_the_same_image() {
    let mut checked = 0;
    let mut scenes_without_mis = 0;
    for path in scenes() {
        let scene = scene::load(&path).expect("scene loads");
        let needed = Features::needed(&Analysis::of(&scene), Outputs { split: false, guides: false });
        scenes_without_mis += !needed.mis as usize;
        let backends: &[Backend] = if path.ends_with("embree-cornell.toml") {
            &[Backend::Embree, Backend::Bvh]
        } else {
            &[Backend::Embree]
        };
        for &accel in backends {
            let (full, full_rays, full_bytes) = render_with(&scene, Features::ALL, accel);
            assert!(full.raw.mean().max_element() > 0.0, "{}: a black image tests nothing", path.display());
            for f in all_subsets().filter(|f| (f.mis || !needed.mis) && (f.textures || !needed.textures)) {
                let (film, rays, bytes) = render_with(&scene, f, accel);
                let what = format!("{} on {accel}, computing {}", path.display(), f.names());
                assert_eq!(bits(&film.raw), bits(&full.raw), "{what}: the beauty changed");
                assert_eq!(film.has_split(), f.split, "{what}");
                assert_eq!(film.has_guides(), f.guides, "{what}");
                if f.split {
                    for (a, b) in film.components.iter().zip(&full.components) {
                        assert_eq!(bits(a), bits(b), "{what}: a component changed");
                    }
                }
                if f.guides {
                    assert_eq!(film.object, full.object, "{what}: object IDs changed");
                    assert_eq!(film.coverage, full.coverage, "{what}");
                    assert_eq!(bits(&film.normal), bits(&full.normal), "{what}");
                    assert_eq!(bits(&film.albedo), bits(&full.albedo), "{what}");
                }
                assert!(rays <= full_rays, "{what}: {rays} rays, more than the general {full_rays}");
                assert!(!f.mis || rays == full_rays, "{what}: with MIS every ray is traced");
                assert!((f.split && f.guides) || bytes < full_bytes, "{what}: {bytes} bytes of buffers");
                checked += 1;
            }
        }
    }
    assert!(scenes_without_mis >= 1, "some scene has only point or spot lights");
    assert!(checked >= 60, "{checked} renders compared");
}

/// The flags really remove code: leaving out what a scene needs changes its image, and without
/// MIS the ray after a path's last vertex is not traced.
#[test]
fn leaving_out_what_a_scene_needs_changes_it() {
    let load = |name: &str| {
        scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(name)).expect("loads")
    };
    let textured = load("paper-gallery.toml");
    assert!(Features::needed(&Analysis::of(&textured), Outputs::ALL).textures);
    let (with, ..) = render_with(&textured, Features::ALL, Backend::Embree);
    let (without, ..) =
        render_with(&textured, Features { textures: false, ..Features::ALL }, Backend::Embree);
    assert_ne!(bits(&with.raw), bits(&without.raw), "textures off must change a textured scene");

    let area_lit = load("cornell.toml");
    assert!(Features::needed(&Analysis::of(&area_lit), Outputs::ALL).mis);
    let (with, ..) = render_with(&area_lit, Features::ALL, Backend::Embree);
    let (without, ..) = render_with(&area_lit, Features { mis: false, ..Features::ALL }, Backend::Embree);
    // Without emission at hits the light itself goes black.
    assert!(without.components[Emitted].mean().x < 0.5 * with.components[Emitted].mean().x);

    let point_lit = load("embree-cornell.toml");
    assert!(!Features::needed(&Analysis::of(&point_lit), Outputs::ALL).mis);
    let (_, with_rays, _) = render_with(&point_lit, Features::ALL, Backend::Embree);
    let (_, without_rays, _) =
        render_with(&point_lit, Features { mis: false, ..Features::ALL }, Backend::Embree);
    assert!(without_rays < with_rays, "{without_rays} rays, the general integrator {with_rays}");
}

#[test]
fn the_command_line_computes_what_the_output_reads() {
    let dir = std::env::temp_dir().join(format!("lightsplit-features-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/embree-cornell.toml");
    let run = |out: &str, extra: &[&str]| -> serde_json::Value {
        let out = dir.join(out);
        let mut args = vec!["render", scene.to_str().expect("utf-8"), "-o", out.to_str().expect("utf-8")];
        args.extend(["--width", "16", "--height", "16", "--spp", "2", "--json"]);
        args.extend(extra);
        let o = common::lightsplit(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&o.stdout).expect("json")
    };
    let png = run("a.png", &[]);
    assert_eq!(
        png["features"],
        serde_json::json!({"mis": false, "split": false, "guides": false, "textures": false})
    );
    assert_eq!(png["embree"]["quality"], "low");
    let filtered = run("b.png", &["--filter", "box3", "--edge-aware"]);
    assert_eq!(
        (filtered["features"]["split"].as_bool(), filtered["features"]["guides"].as_bool()),
        (Some(true), Some(true))
    );
    let exr = run("c.exr", &[]);
    assert_eq!(
        (exr["features"]["split"].as_bool(), exr["features"]["guides"].as_bool()),
        (Some(true), Some(true))
    );
    let forced = run("d.png", &["--all-features"]);
    assert_eq!(forced["features"]["mis"], true);
    assert_eq!(forced["embree"], serde_json::json!({"robust": true, "quality": "high"}));
    let bytes = |v: &serde_json::Value| v["buffer_bytes"].as_u64().expect("buffer_bytes");
    assert!(bytes(&png) * 4 < bytes(&exr), "{} vs {}", bytes(&png), bytes(&exr));

    let info = common::lightsplit(&["info", scene.to_str().expect("utf-8"), "-o", "x.png"]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(text.contains("so the render computes: none"), "{text}");

    let bench = common::lightsplit(&[
        "bench-features",
        scene.to_str().expect("utf-8"),
        "--width",
        "16",
        "--height",
        "16",
        "--spp",
        "2",
        "--rounds",
        "1",
        "--json",
    ]);
    assert!(bench.status.success(), "{}", String::from_utf8_lossy(&bench.stderr));
    let v: serde_json::Value = serde_json::from_slice(&bench.stdout).expect("json");
    let row = &v["rows"][0];
    assert_eq!(row["integrator_pixels_differing"], 0);
    assert!(row["speedup"].as_f64().is_some_and(|s| s > 0.0), "{row}");
    let missing = common::lightsplit(&["bench-features", "no-such.toml"]);
    assert_eq!(missing.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}
