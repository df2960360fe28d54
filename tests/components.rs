//! The paper's component split: the four components sum to the beauty, each lands where its
//! light path says, and the guide buffers see the first diffuse vertex.

use crate::common;

use std::path::Path;

use common::mean_and_standard_error;
use glam::Vec3;
use lightsplit::component::Component::{Caustic, Direct, Emitted, Indirect};
use lightsplit::film::Film;
use lightsplit::render::{render, RenderOptions};

fn film(text: &str, spp: u32) -> Film {
    common::render_text(text, spp).film
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
    for layer in [Emitted, Direct, Indirect] {
        assert!(f.components[layer].mean().max_element() > 0.0, "{} is empty", layer.name());
    }
}

#[test]
fn no_specular_material_means_no_caustic() {
    let f = cornell(24);
    assert!(f.components[Caustic].pixels.iter().all(|p| *p == Vec3::ZERO));
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
    text.push_str(&common::inward_cube("object = \"room\"\nmaterial = \"white\""));
    let f = film(&text, 16);
    // The camera looks down at the floor under the blocker: its centre is in the block's shadow.
    let centre = (16 * 32 + 16) as usize;
    assert_eq!(f.components[Direct].pixels[centre], Vec3::ZERO, "direct light in the shadow");
    assert!(f.components[Indirect].pixels[centre].x > 0.0, "no indirect light in the shadow");
    assert!(f.components[Indirect].mean().x > 0.0);
    assert!(f.components[Direct].mean().x > 0.0, "no direct light anywhere");
    // Nothing emits, and no path sees the point light itself.
    assert!(f.components[Emitted].pixels.iter().all(|p| *p == Vec3::ZERO));
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
    assert_eq!(f.components[Direct].pixels[bottom], Vec3::ZERO);
    assert!(f.components[Indirect].pixels[bottom].x > 0.0);
    assert_eq!(f.components[Emitted].pixels[top], Vec3::ONE);
    // Not a diffuse source: the same light is direct.
    let f = film(&base.replace("radiance = [1, 1, 1]", "radiance = [1, 1, 1]\ndiffuse_source = false"), 4);
    assert_eq!(f.components[Indirect].pixels[bottom], Vec3::ZERO);
    assert!(f.components[Direct].pixels[bottom].x > 0.0);
}

/// An environment map's light is direct unless `diffuse_source` says it is a diffuse source (an
/// HDRI often holds a sun, whose shadows must stay sharp); seen directly it is emitted.
#[test]
fn an_environment_is_direct_light_unless_a_diffuse_source() {
    let dir = tempfile::tempdir().expect("tempdir");
    let map = dir.path().join("env.pfm");
    std::fs::write(&map, common::pfm(8, 4, &[1.0; 96])).expect("write");
    let base = format!(
        "[camera]\nposition = [0, 2, -6]\nlook_at = [0, 0.5, 0]\nfov = 40\n[film]\nwidth = 24\nheight = 24\n\
         [[shape]]\ntype = \"quad\"\nvertices = [[-50, 0, -50], [-50, 0, 50], [50, 0, 50], [50, 0, -50]]\n\
         [[light]]\ntype = \"environment\"\nfile = \"{}\"\n",
        map.display()
    );
    let (bottom, top) = ((23 * 24 + 12) as usize, 12usize);
    let f = film(&base, 4);
    assert!(f.components[Direct].pixels[bottom].x > 0.0);
    assert_eq!(f.components[Indirect].pixels[bottom], Vec3::ZERO);
    assert_eq!(f.components[Emitted].pixels[top], Vec3::ONE);
    let f = film(&format!("{base}diffuse_source = true\n"), 4);
    assert_eq!(f.components[Direct].pixels[bottom], Vec3::ZERO);
    assert!(f.components[Indirect].pixels[bottom].x > 0.0);
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

/// Looking into a mirror, a pixel carries the reflected object's ID and its light: E S D L is
/// direct light, and the mirror itself is no object of the guide buffers.
#[test]
fn through_a_mirror_a_pixel_carries_the_reflected_object() {
    let text = r#"
        [camera]
        position = [0, 0, 0]
        look_at = [0, 0, 1]
        fov = 20
        [film]
        width = 16
        height = 16
        [[material]]
        name = "mirror"
        type = "mirror"
        [[shape]]
        type = "quad"
        name = "mirror"
        material = "mirror"
        vertices = [[-3, -3, 2], [3, -3, 2], [3, 3, 2], [-3, 3, 2]]
        [[shape]]
        type = "sphere"
        name = "ball"
        center = [0, 0, -3]
        radius = 1.5
        [[light]]
        type = "point"
        position = [0, 3, 0]
        intensity = [20, 20, 20]
    "#;
    let f = film(text, 4);
    let centre = (8 * 16 + 8) as usize;
    // Objects are numbered in the order of the scene file: mirror 0, ball 1.
    assert_eq!(f.object[centre], 1.0, "the pixel shows the mirror, not the ball it reflects");
    assert!(f.components[Direct].pixels[centre].x > 0.0, "E S D L must be direct");
    assert_eq!(f.components[Emitted].pixels[centre], Vec3::ZERO);
    assert_eq!(f.components[Caustic].pixels[centre], Vec3::ZERO);
    // The depth is the whole way: 2 to the mirror, then about 3.5 back to the ball.
    assert!((f.depth[centre] - 5.5).abs() < 0.1, "depth {}", f.depth[centre]);
}

/// A glass sphere above a diffuse floor focuses a small light onto the floor: that light,
/// E D S+ L, is the caustic component. (A point light cannot make a caustic in a path tracer:
/// no sampled direction from the floor can hit it, so the light here is a small sphere.)
#[test]
fn a_glass_sphere_puts_its_focused_light_in_caustic() {
    let text = r#"
        [camera]
        position = [0, 2.5, -3]
        look_at = [0, 0, 0]
        fov = 40
        [film]
        width = 24
        height = 24
        [render]
        max_depth = 8
        [[material]]
        name = "glass"
        type = "glass"
        ior = 1.5
        [[shape]]
        type = "sphere"
        material = "glass"
        center = [0, 1, 0]
        radius = 0.5
        [[shape]]
        type = "quad"
        vertices = [[-5, 0, -5], [-5, 0, 5], [5, 0, 5], [5, 0, -5]]
        [[shape]]
        type = "sphere"
        name = "lamp"
        center = [0, 4, 0]
        radius = 0.1
        emission = [400, 400, 400]
    "#;
    let f = film(text, 64);
    let caustic = f.components[Caustic].mean();
    assert!(caustic.x > 0.0, "no caustic at all");
    // The caustic is concentrated (under the sphere): its brightest pixel is far above its mean.
    let max = f.components[Caustic].pixels.iter().map(|p| p.x).fold(0.0f32, f32::max);
    assert!(max > 5.0 * caustic.x, "the caustic is not focused: max {max}, mean {}", caustic.x);
}

/// Mirror and glass spheres of colour 1 inside a uniform sky reflect and transmit exactly the
/// sky: a white furnace for the specular materials (energy kept through the 1/eta^2 scaling).
#[test]
fn specular_white_furnace() {
    for material in ["type = \"mirror\"", "type = \"glass\"\nior = 1.5"] {
        let text = format!(
            r#"
            [camera]
            position = [0, 0, -4]
            look_at = [0, 0, 0]
            fov = 40
            [film]
            width = 32
            height = 32
            [render]
            max_depth = 64
            [[material]]
            name = "m"
            {material}
            [[shape]]
            type = "sphere"
            material = "m"
            radius = 1
            [[light]]
            type = "sky"
            radiance = [1, 1, 1]
            "#
        );
        let mean = film(&text, 16).raw.mean();
        assert!((mean.x - 1.0).abs() < 0.01, "{material}: mean {mean}");
    }
}

/// A glossy plane with a diffuse base under a uniform sky (a diffuse source), seen at 45 degrees
/// through a narrow camera: the GGX lobe's light reaches the eye as E S L (`emitted`), the base's
/// as E D L_sky (`indirect`), and each equals its lobe's directional albedo, integrated here by
/// quadrature from the BRDF itself. This checks next-event estimation, BSDF sampling and their
/// per-lobe MIS weights together.
#[test]
fn glossy_lobes_reflect_their_albedo_into_their_components() {
    use lightsplit::render::bsdf::GlossyLobes;
    let text = r#"
        [camera]
        position = [0, 2, -2]
        look_at = [0, 0, 0]
        fov = 1
        [film]
        width = 16
        height = 16
        [render]
        max_depth = 4
        [[material]]
        name = "g"
        type = "glossy"
        color = [0.5, 0.5, 0.5]
        roughness = 0.5
        base = [0.8, 0.8, 0.8]
        [[shape]]
        type = "quad"
        material = "g"
        vertices = [[-5, 0, -5], [-5, 0, 5], [5, 0, 5], [5, 0, -5]]
        [[light]]
        type = "sky"
        radiance = [1, 1, 1]
    "#;
    let f = film(text, 256);
    let g = GlossyLobes { specular: Vec3::splat(0.5), alpha: 0.25, base: Vec3::splat(0.8) };
    let wo = Vec3::new(0.0, (0.5f32).sqrt(), (0.5f32).sqrt());
    // Midpoint rule over (cos theta, phi), where d omega = d cos d phi.
    let n = 2000;
    let (mut spec, mut base) = (0.0f64, 0.0f64);
    for i in 0..n {
        let z = (i as f32 + 0.5) / n as f32;
        let r = (1.0 - z * z).sqrt();
        for j in 0..n {
            let phi = (j as f32 + 0.5) / n as f32 * std::f32::consts::TAU;
            let wi = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            spec += (g.eval_specular(wo, wi).x * z) as f64;
            base += (g.eval_base(wo, wi).x * z) as f64;
        }
    }
    let cell = std::f64::consts::TAU / (n * n) as f64;
    let (spec, base) = (spec * cell, base * cell);
    // Within 4 standard errors (from the spread of the pixels) of the integrals.
    for (layer, expected, name) in [(Emitted, spec, "GGX lobe"), (Indirect, base, "base")] {
        let (mean, se) = mean_and_standard_error(&f.components[layer]);
        assert!((mean - expected).abs() < 4.0 * se, "{name}: rendered {mean} ± {se}, integral {expected}");
    }
    assert!(f.components[Direct].mean() == Vec3::ZERO && f.components[Caustic].mean() == Vec3::ZERO);
}

/// The glossy material in a white furnace, the sphere filling the frame: the BRDF never returns
/// more light than arrives, and (single-scattering GGX loses what would bounce between
/// microfacets) not much less.
#[test]
fn glossy_white_furnace_keeps_energy_bounded() {
    let text = r#"
        [camera]
        position = [0, 0, -4]
        look_at = [0, 0, 0]
        fov = 20
        [film]
        width = 32
        height = 32
        [render]
        max_depth = 64
        [[material]]
        name = "m"
        type = "glossy"
        color = [1, 1, 1]
        roughness = 0.2
        [[shape]]
        type = "sphere"
        material = "m"
        radius = 1
        [[light]]
        type = "sky"
        radiance = [1, 1, 1]
    "#;
    let (mean, se) = mean_and_standard_error(&film(text, 16).raw);
    assert!(mean <= 1.0 + 4.0 * se && mean > 0.9, "mean {mean}, standard error {se}");
}
