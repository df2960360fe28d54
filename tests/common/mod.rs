//! Helpers shared by the integration tests (each test binary uses some of them).
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

use lightsplit::render::{render, RenderOptions, RenderOutput};
use lightsplit::scene::file::parse;

/// Runs the `lightsplit` binary with `args`.
pub fn lightsplit(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lightsplit")).args(args).output().expect("the binary runs")
}

/// Renders a scene given as text at `spp`, with the file's other settings.
pub fn render_text(text: &str, spp: u32) -> RenderOutput {
    let scene = parse(Path::new("test.toml"), text).expect("scene parses");
    let mut options = RenderOptions::from_scene(&scene);
    options.spp = spp;
    render(&scene, &options, &|_| {}).expect("renders")
}

/// The mean of the red channel and its standard error from the spread of the pixels (each pixel
/// an independent estimate of the same value).
pub fn mean_and_standard_error(image: &lightsplit::film::Image) -> (f64, f64) {
    let n = image.pixels.len() as f64;
    let mean = image.pixels.iter().map(|p| p.x as f64).sum::<f64>() / n;
    let var = image.pixels.iter().map(|p| (p.x as f64 - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// The six faces of the cube [-1, 1]^3 as scene-file quads, wound so that their front (emitting)
/// side faces inwards; `keys` (TOML lines such as `material = "white"`) go into each.
pub fn inward_cube(keys: &str) -> String {
    let mut text = String::new();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let corner = |a: f32, b: f32| {
                let mut p = [0.0f32; 3];
                p[axis] = sign;
                p[(axis + 1) % 3] = a;
                p[(axis + 2) % 3] = b;
                format!("[{}, {}, {}]", p[0], p[1], p[2])
            };
            // (a, b) counter-clockwise gives a normal along +axis; reverse it on the + side.
            let mut quad = [corner(-1.0, -1.0), corner(1.0, -1.0), corner(1.0, 1.0), corner(-1.0, 1.0)];
            if sign > 0.0 {
                quad.reverse();
            }
            text.push_str(&format!("[[shape]]\ntype = \"quad\"\n{keys}\nvertices = [{}]\n", quad.join(", ")));
        }
    }
    text
}

/// A portable float map (RGB, little-endian) of `values`, three a pixel, in the file's order:
/// the bottom row first.
pub fn pfm(width: u32, height: u32, values: &[f32]) -> Vec<u8> {
    let mut bytes = format!("PF\n{width} {height}\n-1.0\n").into_bytes();
    values.iter().for_each(|v| bytes.extend_from_slice(&v.to_le_bytes()));
    bytes
}
