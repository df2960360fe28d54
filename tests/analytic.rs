//! Renders with a known answer: a white furnace (under a sky and under an environment map) and a
//! diffuse plane under a point light and under an environment map.

use crate::common;

use std::path::Path;

use glam::Vec2;
use lightsplit::render::camera::PinholeCamera;
use lightsplit::scene::file::parse;

use common::render_text;

/// An albedo-1 sphere under a uniform sky reflects exactly the sky: every pixel's expectation is
/// the sky radiance, so the image mean must be too.
#[test]
fn white_furnace_mean_equals_sky_radiance() {
    let text = r#"
        [camera]
        position = [0, 0, -4]
        look_at = [0, 0, 0]
        fov = 40
        [film]
        width = 48
        height = 48
        [render]
        max_depth = 16
        [[material]]
        name = "white"
        type = "diffuse"
        color = [1, 1, 1]
        [[shape]]
        type = "sphere"
        material = "white"
        radius = 1
        [[light]]
        type = "sky"
        radiance = [0.5, 1.0, 2.0]
    "#;
    let out = render_text(text, 32);
    let mean = out.film.raw.mean();
    for (got, want) in mean.to_array().into_iter().zip([0.5f32, 1.0, 2.0]) {
        assert!((got / want - 1.0).abs() < 0.01, "mean {mean} vs sky");
    }
    // The sphere covers much of the image, so this is not just the background.
    let centre = out.film.raw.get(24, 24);
    assert!((centre.y - 1.0).abs() < 0.35, "centre pixel {centre}");
}

/// A diffuse plane under a point light, seen from above: the only light path is the direct one,
/// so each pixel is albedo / pi * I cos(theta) / r^2 averaged over the points the pixel sees.
/// The only noise is the camera's jitter within the pixel; the tolerance is five standard errors
/// of that jitter, from the formula's spread across the pixel.
#[test]
fn diffuse_plane_under_point_light_matches_the_formula() {
    let text = r#"
        [camera]
        position = [0, 3, 0.001]
        look_at = [0, 0, 0]
        fov = 50
        [film]
        width = 32
        height = 32
        [[material]]
        name = "grey"
        type = "diffuse"
        color = [0.6, 0.6, 0.6]
        [[shape]]
        type = "quad"
        material = "grey"
        vertices = [[-20, 0, -20], [-20, 0, 20], [20, 0, 20], [20, 0, -20]]
        [[light]]
        type = "point"
        position = [0.7, 1.5, -0.4]
        intensity = [10, 10, 10]
    "#;
    let scene = parse(Path::new("test.toml"), text).expect("scene parses");
    let spp = 16;
    let out = render_text(text, spp);
    let camera = PinholeCamera::new(&scene.camera, 32, 32);
    // The scene stores points relative to its camera: the light, and the plane y = 0.
    let origin = scene.origin.as_vec3();
    let light = glam::Vec3::new(0.7, 1.5, -0.4) - origin;
    let mut worst = 0.0f32;
    for y in 0..32 {
        for x in 0..32 {
            // The formula on an 8x8 grid inside the pixel: its mean and spread.
            let values: Vec<f32> = (0..64)
                .map(|j| {
                    let offset = Vec2::new((j % 8) as f32 + 0.5, (j / 8) as f32 + 0.5) / 8.0;
                    let ray = camera.ray(x, y, offset);
                    let p = ray.at((-origin.y - ray.origin.y) / ray.dir.y);
                    let d = light - p;
                    0.6 / std::f32::consts::PI * 10.0 * (d.y / d.length()) / d.length_squared()
                })
                .collect();
            let mean = values.iter().sum::<f32>() / 64.0;
            let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / 63.0;
            let tolerance = 5.0 * (var / spp as f32).sqrt() + 2e-3 * mean;
            let got = out.film.raw.get(x, y).x;
            assert!((got - mean).abs() <= tolerance, "pixel ({x}, {y}): {got} vs {mean} +- {tolerance}");
            worst = worst.max((got / mean - 1.0).abs());
        }
    }
    // The jitter noise bounds the per-pixel error; no pixel is off by more than a few percent.
    assert!(worst < 0.05, "largest relative error {worst}");
}

/// A closed box whose walls all emit `Le` (inwards) and reflect with albedo `a`: the radiance
/// everywhere inside is `Le / (1 - a)`. Exercises every bounce, the area-light MIS on both
/// strategies, and Russian roulette.
#[test]
fn emissive_closed_box_reaches_le_over_one_minus_albedo() {
    let mut text = String::from(
        r#"
        [camera]
        position = [0.1, -0.2, -0.5]
        look_at = [0, 0, 1]
        fov = 90
        [film]
        width = 32
        height = 32
        [render]
        max_depth = 100
        [[material]]
        name = "half"
        type = "diffuse"
        color = [0.5, 0.5, 0.5]
        "#,
    );
    text.push_str(&common::inward_cube("material = \"half\"\nemission = [1, 1, 1]"));
    let out = render_text(&text, 16);
    let mean = out.film.raw.mean();
    assert!((mean.x / 2.0 - 1.0).abs() < 0.01, "mean {mean}, expected 2");
}

/// Russian roulette leaves the mean unchanged: walls of albedo 0.9 make paths of tens of
/// bounces, almost all ended by roulette (after the second bounce a path survives with
/// probability 0.9 and is reweighted by 1/0.9), and the mean must still be Le / (1 - 0.9) = 10.
/// The tolerance is four standard errors of the mean, measured from the pixels themselves
/// (independent estimates: every pixel has its own sample streams). `max_depth` is the cap,
/// 1024: the light beyond it is 10 x 0.9^1024, about 1e-46.
#[test]
fn russian_roulette_leaves_the_mean_unchanged() {
    let mut text = String::from(
        "[camera]\nposition = [0.1, -0.2, -0.5]\nlook_at = [0, 0, 1]\nfov = 90\n\
         [film]\nwidth = 32\nheight = 32\n[render]\nmax_depth = 1024\n\
         [[material]]\nname = \"bright\"\ntype = \"diffuse\"\ncolor = [0.9, 0.9, 0.9]\n",
    );
    text.push_str(&common::inward_cube("material = \"bright\"\nemission = [1, 1, 1]"));
    let (mean, se) = common::mean_and_standard_error(&render_text(&text, 64).film.raw);
    eprintln!("mean {mean:.4}, standard error {se:.4}");
    assert!(se > 0.0 && se < 0.1, "standard error {se}");
    assert!((mean - 10.0).abs() < 4.0 * se, "mean {mean}, expected 10 within 4 x {se}");
}

/// Writes a latitude-longitude map, given top row first, as a portable float map (whose rows
/// run bottom to top) and returns its path.
fn environment_file(dir: &Path, width: u32, height: u32, pixel: impl Fn(u32, u32) -> [f32; 3]) -> String {
    let values: Vec<f32> = (0..height)
        .rev()
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .flat_map(|(x, y)| pixel(x, y))
        .collect();
    let path = dir.join("env.pfm");
    std::fs::write(&path, common::pfm(width, height, &values)).expect("write");
    path.to_string_lossy().into_owned()
}

/// The furnace under an environment map: an albedo-1 sphere in a constant map reflects the map's
/// radiance exactly, so the image mean is that radiance within its noise.
#[test]
fn white_furnace_in_a_constant_environment_map() {
    let dir = tempfile::tempdir().expect("tempdir");
    let file = environment_file(dir.path(), 32, 16, |_, _| [0.5, 1.0, 2.0]);
    let text = format!(
        "[camera]\nposition = [0, 0, -4]\nlook_at = [0, 0, 0]\nfov = 40\n[film]\nwidth = 32\nheight = 32\n\
         [render]\nmax_depth = 16\n[[material]]\nname = \"white\"\ntype = \"diffuse\"\ncolor = [1, 1, 1]\n\
         [[shape]]\ntype = \"sphere\"\nmaterial = \"white\"\nradius = 1\n\
         [[light]]\ntype = \"environment\"\nfile = \"{file}\"\nrotate = 30\n"
    );
    let out = render_text(&text, 16);
    let (mean, se) = common::mean_and_standard_error(&out.film.raw);
    assert!((mean - 0.5).abs() <= 4.0 * se + 1e-4, "mean {mean} (standard error {se}) vs 0.5");
    // The sphere covers the centre, which shows the map's radiance too.
    let centre = out.film.raw.get(16, 16);
    assert!((centre.z / centre.x - 4.0).abs() < 0.05, "centre pixel {centre}");
}

/// A diffuse plane facing up under a map with a small bright sun, a gradient sky and a bright
/// ground below the horizon: each point of the plane reflects albedo / pi times the map's
/// cosine-weighted integral over the upper hemisphere, summed exactly pixel by pixel (a pixel of
/// row j spans polar angles theta_j to theta_j+1 and 2 pi / width in azimuth, and its cosine-
/// weighted solid angle is (sin^2 theta_j+1 - sin^2 theta_j) pi / width). The tolerance is four
/// standard errors of the pixels' spread.
#[test]
fn diffuse_plane_under_an_environment_map_reflects_its_cosine_integral() {
    let (w, h) = (64u32, 32u32);
    let radiance = |x: u32, y: u32| -> f32 {
        if (10..12).contains(&x) && (4..6).contains(&y) {
            3000.0
        } else if y >= h / 2 {
            5.0
        } else {
            0.3 + 0.4 * x as f32 / w as f32
        }
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let file = environment_file(dir.path(), w, h, |x, y| [radiance(x, y); 3]);
    let mut expected = 0.0f64;
    for y in 0..h / 2 {
        let s = |j: u32| (std::f64::consts::PI * j as f64 / h as f64).sin().powi(2);
        let weight = (s(y + 1) - s(y)) * std::f64::consts::PI / w as f64;
        expected += (0..w).map(|x| radiance(x, y) as f64 * weight).sum::<f64>();
    }
    let albedo = 0.5;
    expected *= albedo / std::f64::consts::PI;
    let text = format!(
        "[camera]\nposition = [0, 1, 0.001]\nlook_at = [0, 0, 0]\nfov = 40\n[film]\nwidth = 32\nheight = 32\n\
         [[material]]\nname = \"grey\"\ntype = \"diffuse\"\ncolor = [{albedo}, {albedo}, {albedo}]\n\
         [[shape]]\ntype = \"quad\"\nmaterial = \"grey\"\n\
         vertices = [[-100, 0, -100], [-100, 0, 100], [100, 0, 100], [100, 0, -100]]\n\
         [[light]]\ntype = \"environment\"\nfile = \"{file}\"\nrotate = 90\n"
    );
    let out = render_text(&text, 16);
    let (mean, se) = common::mean_and_standard_error(&out.film.raw);
    assert!(
        (mean - expected).abs() <= 4.0 * se + 1e-4 * expected,
        "mean {mean} (standard error {se}) vs {expected}"
    );
    assert!(
        se < 0.02 * expected,
        "importance sampling keeps the noise low: standard error {se} of {expected}"
    );
}
