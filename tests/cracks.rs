//! Watertightness as an image: a finely subdivided plane seen from above, and a closed sphere
//! mesh seen from inside, must show a surface in every pixel on both backends — a ray that
//! slips between two triangles sharing an edge would leave a pixel with no object.

use std::fmt::Write as _;
use std::path::Path;

use lightsplit::accel::Backend;
use lightsplit::render::{render, RenderOptions};
use lightsplit::scene;

/// Renders `scene_path` on `backend` and counts the pixels where some sample saw no object:
/// sample 0 hit nothing (object -1), or another sample saw something else than sample 0 did
/// (coverage below 1; the scenes have one object).
fn holes(scene_path: &Path, backend: Backend) -> usize {
    let scene = scene::load(scene_path).expect("scene loads");
    let mut options = RenderOptions::from_scene(&scene);
    options.accel = backend;
    let film = render(&scene, &options, &|_| {}).expect("renders").film;
    film.object.iter().zip(&film.coverage).filter(|(&o, &c)| o < 0.0 || c < 1.0).count()
}

/// A UV sphere of `n` x `2n` quads (as triangles sharing every edge), wound outwards.
fn sphere_obj(n: usize) -> String {
    let mut obj = String::new();
    let (rows, cols) = (n, 2 * n);
    // Poles once each, rings between.
    let _ = writeln!(obj, "v 0 1 0");
    for i in 1..rows {
        let theta = std::f64::consts::PI * i as f64 / rows as f64;
        for j in 0..cols {
            let phi = std::f64::consts::TAU * j as f64 / cols as f64;
            let _ =
                writeln!(obj, "v {} {} {}", theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
        }
    }
    let _ = writeln!(obj, "v 0 -1 0");
    let ring = |i: usize, j: usize| 2 + (i - 1) * cols + j % cols; // 1-based OBJ index
    let south = 2 + (rows - 1) * cols;
    for j in 0..cols {
        let _ = writeln!(obj, "f 1 {} {}", ring(1, j + 1), ring(1, j));
        let _ = writeln!(obj, "f {south} {} {}", ring(rows - 1, j), ring(rows - 1, j + 1));
    }
    for i in 1..rows - 1 {
        for j in 0..cols {
            let (a, b, c, d) = (ring(i, j), ring(i, j + 1), ring(i + 1, j + 1), ring(i + 1, j));
            let _ = writeln!(obj, "f {a} {b} {c}\nf {a} {c} {d}");
        }
    }
    obj
}

#[test]
fn no_ray_slips_through_a_subdivided_plane_or_a_closed_sphere() {
    let dir = tempfile::tempdir().expect("tempdir");
    // 2 x 300^2 triangles, seen from above at an angle: every pixel looks at the plane.
    let plane = dir.path().join("plane.toml");
    std::fs::write(
        &plane,
        "[camera]\nposition = [0.3, 4, -1.1]\nlook_at = [0.01, 0, 0.02]\nfov = 50\n\
         [film]\nwidth = 96\nheight = 96\nspp = 4\n[render]\nmax_depth = 1\n\
         [[shape]]\ntype = \"terrain\"\nresolution = 300\nsize = 20\nheight = 0\n",
    )
    .expect("write");
    // From inside a closed mesh every direction hits it.
    std::fs::write(dir.path().join("sphere.obj"), sphere_obj(48)).expect("write");
    let sphere = dir.path().join("sphere.toml");
    std::fs::write(
        &sphere,
        "[camera]\nposition = [0.123, 0.071, -0.05]\nlook_at = [0.5, 0.3, 1]\nfov = 120\n\
         [film]\nwidth = 96\nheight = 96\nspp = 4\n[render]\nmax_depth = 1\n\
         [[shape]]\ntype = \"mesh\"\nfile = \"sphere.obj\"\ntransform = { scale = 3 }\n",
    )
    .expect("write");
    // The control: the same sphere without its north cap (the faces touching its top four
    // rings of 96 vertices), looked at from inside, has holes.
    let cap = |l: &str| {
        l.starts_with('f')
            && l.split_whitespace().skip(1).any(|v| v.parse::<usize>().is_ok_and(|v| v <= 1 + 4 * 96))
    };
    let open: String = sphere_obj(48).lines().filter(|l| !cap(l)).map(|l| format!("{l}\n")).collect();
    std::fs::write(dir.path().join("open.obj"), open).expect("write");
    let open_scene = dir.path().join("open.toml");
    std::fs::write(
        &open_scene,
        std::fs::read_to_string(&sphere)
            .expect("read")
            .replace("sphere.obj", "open.obj")
            .replace("look_at = [0.5, 0.3, 1]", "look_at = [0.123, 1, -0.05]\nup = [0, 0, 1]"),
    )
    .expect("write");
    for backend in [Backend::Embree, Backend::Bvh] {
        assert_eq!(holes(&plane, backend), 0, "{backend:?}: a ray slipped through the plane");
        assert_eq!(holes(&sphere, backend), 0, "{backend:?}: a ray escaped the closed sphere");
        assert!(holes(&open_scene, backend) > 100, "{backend:?}: the control shows no hole");
    }
}
