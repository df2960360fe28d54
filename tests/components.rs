//! The paper's component split: the four components sum to the beauty, each lands where its
//! light path says, and the guide buffers see the first diffuse vertex.

use std::path::Path;

use glam::Vec3;
use lightsplit::film::Film;
use lightsplit::render::{render, RenderOptions};
use lightsplit::scene::file::parse;

fn film(text: &str, spp: u32) -> Film {
    let scene = parse(Path::new("test.toml"), text).expect("scene parses");
    let mut options = RenderOptions::from_scene(&scene);
    options.spp = spp;
    render(&scene, &options, &|_| {}).expect("renders").film
}

fn cornell(width: u32) -> Film {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml");
    let scene = lightsplit::scene::load(&path).expect("loads");
    let mut options = RenderOptions::from_scene(&scene);
    options.width = width;
    options.height = width;
    options.spp = 8;
    render(&scene, &options, &|_| {}).expect("renders").film
}

#[test]
fn components_sum_to_the_beauty_per_pixel_and_image() {
    let f = cornell(32);
    let mut sum_parts = Vec3::ZERO;
    for (i, raw) in f.raw.pixels.iter().enumerate() {
        let parts: Vec3 = f.components.iter().map(|c| c.pixels[i]).sum();
        // Summed in another order than the beauty: equal up to float rounding.
        assert!((parts - *raw).abs().max_element() <= 1e-5 * raw.abs().max_element().max(1e-3), "pixel {i}");
        sum_parts += parts;
    }
    let image: Vec3 = f.raw.pixels.iter().copied().sum();
    assert!((sum_parts - image).abs().max_element() <= 1e-5 * image.max_element());
    // The Cornell box has light in every component it can have.
    for (name, layer) in ["emitted", "direct", "indirect"].iter().zip([0, 1, 3]) {
        assert!(f.components[layer].mean().max_element() > 0.0, "{name} is empty");
    }
}

#[test]
fn no_specular_material_means_no_caustic() {
    let f = cornell(24);
    assert!(f.components[2].pixels.iter().all(|p| *p == Vec3::ZERO));
}

/// A closed box lit by a point light: the walls get indirect light, and a point in the shadow of
/// a block gets no direct light at all (but some indirect).
#[test]
fn closed_box_has_indirect_everywhere_and_no_direct_in_shadow() {
    let mut text = String::from(
        r#"
        [camera]
        position = [0, 0, -0.9]
        look_at = [0, -1, 0.3]
        fov = 60
        [film]
        width = 32
        height = 32
        [render]
        max_depth = 6
        [[material]]
        name = "white"
        type = "diffuse"
        color = [0.7, 0.7, 0.7]
        [[shape]]
        type = "box"
        name = "blocker"
        material = "white"
        min = [-0.3, 0.3, -0.3]
        max = [0.3, 0.35, 0.3]
        [[light]]
        type = "point"
        position = [0, 0.8, 0]
        intensity = [2, 2, 2]
        "#,
    );
    // The room: six inward-facing quads of [-1, 1]^3.
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let corner = |a: f32, b: f32| {
                let mut p = [0.0f32; 3];
                p[axis] = sign;
                p[(axis + 1) % 3] = a;
                p[(axis + 2) % 3] = b;
                format!("[{}, {}, {}]", p[0], p[1], p[2])
            };
            let quad = [corner(-1.0, -1.0), corner(1.0, -1.0), corner(1.0, 1.0), corner(-1.0, 1.0)];
            text.push_str(&format!(
                "[[shape]]\ntype = \"quad\"\nobject = \"room\"\nmaterial = \"white\"\nvertices = [{}]\n",
                quad.join(", ")
            ));
        }
    }
    let f = film(&text, 16);
    // The camera looks down at the floor under the blocker: its centre is in the block's shadow.
    let centre = (16 * 32 + 16) as usize;
    assert_eq!(f.components[1].pixels[centre], Vec3::ZERO, "direct light in the shadow");
    assert!(f.components[3].pixels[centre].x > 0.0, "no indirect light in the shadow");
    assert!(f.components[3].mean().x > 0.0);
    assert!(f.components[1].mean().x > 0.0, "no direct light anywhere");
    // Nothing emits, and no path sees the point light itself.
    assert!(f.components[0].pixels.iter().all(|p| *p == Vec3::ZERO));
}

/// The sky is a diffuse source: all its light on the scene counts as indirect, as the paper says
/// of its first test scene, while the sun's is direct and the sky seen directly is emitted.
#[test]
fn diffuse_source_sky_light_is_indirect() {
    let base = r#"
        [camera]
        position = [0, 2, -6]
        look_at = [0, 0.5, 0]
        fov = 40
        [film]
        width = 24
        height = 24
        [[shape]]
        type = "quad"
        vertices = [[-50, 0, -50], [-50, 0, 50], [50, 0, 50], [50, 0, -50]]
        [[light]]
        type = "sky"
        radiance = [1, 1, 1]
    "#;
    let f = film(base, 4);
    let bottom = (23 * 24 + 12) as usize; // the plane
    let top = 12usize; // the sky
    assert_eq!(f.components[1].pixels[bottom], Vec3::ZERO);
    assert!(f.components[3].pixels[bottom].x > 0.0);
    assert_eq!(f.components[0].pixels[top], Vec3::ONE);
    // Not a diffuse source: the same light is direct.
    let f = film(&base.replace("radiance = [1, 1, 1]", "radiance = [1, 1, 1]\ndiffuse_source = false"), 4);
    assert_eq!(f.components[3].pixels[bottom], Vec3::ZERO);
    assert!(f.components[1].pixels[bottom].x > 0.0);
}

#[test]
fn object_ids_come_from_one_sample_and_are_never_averaged() {
    let f = cornell(32);
    let ids: std::collections::BTreeSet<i64> = f.object.iter().map(|&o| o as i64).collect();
    // Whole numbers only (an average would give fractions), and several objects.
    assert!(f.object.iter().all(|o| o.fract() == 0.0));
    assert!(ids.len() >= 5, "{ids:?}");
    // Normals are unit, depths positive where an object was seen.
    for (i, o) in f.object.iter().enumerate() {
        if *o >= 0.0 {
            assert!((f.normal.pixels[i].length() - 1.0).abs() < 1e-3 && f.depth[i] > 0.0);
        }
    }
}
