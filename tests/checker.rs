//! Issue 34's regression: a solid checker on planes that lie exactly on its cell boundaries (a
//! floor at y = 0 and a wall at x = 1, cells of 0.5) rendered mottled, because each sample's
//! point was rebuilt from camera-relative f32 coordinates and landed a rounding error above or
//! below the boundary. A solid texture now reads a point interpolated from the triangle's own
//! vertices in f64 scene coordinates, exact where the geometry is.

use std::path::Path;

use glam::Vec3;
use lightsplit::accel::Backend;
use lightsplit::render::{render, RenderOptions};
use lightsplit::scene::file::parse;

const A: [f32; 3] = [0.8, 0.1, 0.1];
const B: [f32; 3] = [0.1, 0.1, 0.8];

/// The corner of a floor at y = `lift` and a wall at x = 1 + `lift`, under a white sky, seen
/// from a camera; the whole world moved by `far` on every axis (a multiple of the cell size, so
/// the pattern is the same).
fn scene(lift: f64, far: f64) -> String {
    let p = |x: f64, y: f64, z: f64| format!("[{}, {}, {}]", far + x, far + y, far + z);
    let (y, x) = (lift, 1.0 + lift);
    format!(
        "[camera]\nposition = {}\nlook_at = {}\nfov = 60\n\
         [film]\nwidth = 64\nheight = 64\nspp = 16\n\
         [[light]]\ntype = \"sky\"\nradiance = [1, 1, 1]\n\
         [[texture]]\nname = \"c\"\ntype = \"checker\"\nsize = 0.5\ncolor = {A:?}\ncolor2 = {B:?}\n\
         [[material]]\nname = \"m\"\ntype = \"diffuse\"\ntexture = \"c\"\n\
         [[shape]]\ntype = \"quad\"\nmaterial = \"m\"\nvertices = [{}, {}, {}, {}]\n\
         [[shape]]\ntype = \"quad\"\nmaterial = \"m\"\nvertices = [{}, {}, {}, {}]\n",
        p(-1.3, 1.7, -2.1),
        p(0.6, 0.4, 0.9),
        p(-4.0, y, -4.0),
        p(-4.0, y, 6.0),
        p(x, y, 6.0),
        p(x, y, -4.0),
        p(x, y, -4.0),
        p(x, y, 6.0),
        p(x, 4.0, 6.0),
        p(x, 4.0, -4.0),
    )
}

/// The fraction of the surface pixels whose albedo guide is neither colour: a mix of the two.
fn mixed(text: &str, accel: Backend) -> f64 {
    let scene = parse(Path::new("checker.toml"), text).expect("scene parses");
    let mut options = RenderOptions::from_scene(&scene);
    options.accel = accel;
    let film = render(&scene, &options, &|_| {}).expect("renders").film;
    let (a, b) = (Vec3::from(A), Vec3::from(B));
    let mut surface = 0;
    let mut mixed = 0;
    for (albedo, alpha) in film.albedo.pixels.iter().zip(&film.alpha) {
        if *alpha < 1.0 {
            continue;
        }
        surface += 1;
        let pure = |c: Vec3| (*albedo - c).abs().max_element() < 1e-4;
        mixed += (!pure(a) && !pure(b)) as usize;
    }
    assert!(surface > 64 * 64 / 2, "the planes fill the view ({surface} pixels)");
    mixed as f64 / surface as f64
}

/// The planes on the boundaries show no more mixed pixels than the same planes moved 0.01 off
/// them (there, only the antialiased cell edges mix), on both backends, with the world at the
/// origin and moved by 1e8. Before the fix: 57% against 28%.
#[test]
fn a_checker_on_its_cell_boundaries_is_not_mottled() {
    for accel in [Backend::Embree, Backend::Bvh] {
        for far in [0.0, 1e8] {
            let on = mixed(&scene(0.0, far), accel);
            let off = mixed(&scene(0.01, far), accel);
            // Moving the planes by 0.01 moves the cell edges in the image by a fraction of a
            // pixel: one pixel in a hundred is the most that changes.
            assert!(on <= off + 0.01, "{accel} at {far}: {on:.3} mixed on the boundary, {off:.3} off it");
            assert!(off > 0.05 && off < 0.5, "{accel} at {far}: {off:.3} of the pixels hold cell edges");
        }
    }
}
