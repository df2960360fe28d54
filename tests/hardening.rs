//! Issue 18's defects, one test each: what a careless or hostile user found, checked so that it
//! cannot come back. Each test failed before its fix.

use crate::common::pfm;

use std::ffi::OsStr;
use std::os::unix::ffi::OsStrExt;
use std::process::{Command, Output, Stdio};

const SCENE: &str = "[camera]\nposition = [0, 1, -5]\nlook_at = [0, 1, 0]\n\
[film]\nwidth = 8\nheight = 8\nspp = 1\n\
[[light]]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = [5, 5, 5]\n\
[[shape]]\ntype = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1\n";

fn run<S: AsRef<OsStr>>(args: &[S]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lightsplit")).args(args).output().expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Defect 1: `--json` with a path that is not UTF-8 panicked (exit 101) after the image was
/// written; now the path is written lossily and the command succeeds.
#[test]
fn json_with_a_non_utf8_path_does_not_panic() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join(OsStr::from_bytes(b"sc\xffene.toml"));
    std::fs::write(&scene, SCENE).expect("write");
    let out = dir.path().join(OsStr::from_bytes(b"o\xfe.exr"));
    let o = run(&[
        OsStr::new("render"),
        scene.as_os_str(),
        OsStr::new("-o"),
        out.as_os_str(),
        OsStr::new("--json"),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert!(v["scene"].as_str().expect("scene").contains('\u{fffd}'), "{v}");
    assert!(out.exists());
    let o = run(&[
        OsStr::new("filter"),
        out.as_os_str(),
        OsStr::new("-o"),
        dir.path().join(OsStr::from_bytes(b"f\xff.exr")).as_os_str(),
        OsStr::new("--json"),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert!(v["output"].as_str().expect("output").contains('\u{fffd}'), "{v}");
}

/// A reader that has gone (`| head`) ended `compare --json` and the others with a panic on
/// the broken pipe; now they stop quietly.
#[test]
fn a_closed_standard_output_is_not_a_panic() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("s.toml");
    std::fs::write(&scene, SCENE).expect("write");
    let image = dir.path().join("o.exr");
    assert!(run(&[OsStr::new("render"), scene.as_os_str(), OsStr::new("-o"), image.as_os_str()])
        .status
        .success());
    for args in [
        vec![OsStr::new("compare"), image.as_os_str(), image.as_os_str(), OsStr::new("--json")],
        vec![OsStr::new("compare"), image.as_os_str(), image.as_os_str()],
        vec![OsStr::new("info"), scene.as_os_str()],
    ] {
        // A pipe whose reading end is closed before the command starts: every write fails.
        let (reader, writer) = std::io::pipe().expect("a pipe");
        drop(reader);
        let o = Command::new(env!("CARGO_BIN_EXE_lightsplit"))
            .args(&args)
            .stdout(Stdio::from(writer))
            .stderr(Stdio::piped())
            .output()
            .expect("the binary runs");
        assert!(!stderr(&o).contains("panicked"), "{args:?}: {}", stderr(&o));
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
    }
}

/// Runs `lightsplit` in `dir`.
fn run_in<S: AsRef<OsStr>>(dir: &std::path::Path, args: &[S]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lightsplit"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("the binary runs")
}

/// Defect 3: an output could overwrite its own input, the scene (through the default output or
/// `-o`), a texture or a mesh of it, `filter`'s input or `compare`'s images. Each is refused
/// with status 2 and the input is left as it was.
#[test]
fn no_output_overwrites_an_input() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let textured = format!(
        "{SCENE}[[texture]]\nname = \"t\"\ntype = \"image\"\nfile = \"t.png\"\n\
         [[material]]\nname = \"m\"\ntype = \"diffuse\"\ntexture = \"t\"\n\
         [[shape]]\ntype = \"mesh\"\nfile = \"mesh.pfm\"\nmaterial = \"m\"\n"
    );
    std::fs::write(d.join("scene.exr"), SCENE).expect("write");
    std::fs::write(d.join("textured.toml"), &textured).expect("write");
    std::fs::write(d.join("mesh.pfm"), obj).expect("write");
    let png = {
        let mut p = Vec::new();
        image::RgbImage::from_pixel(2, 2, image::Rgb([200, 100, 50]))
            .write_to(&mut std::io::Cursor::new(&mut p), image::ImageFormat::Png)
            .expect("png");
        p
    };
    std::fs::write(d.join("t.png"), &png).expect("write");
    std::fs::hard_link(d.join("scene.exr"), d.join("link.exr")).expect("a hard link");
    // The textured scene renders when its output is elsewhere.
    let o = run_in(d, &["render", "textured.toml", "-o", "fine.exr"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let cases: Vec<Vec<&str>> = vec![
        vec!["render", "scene.exr"],
        vec!["render", "scene.exr", "-o", "scene.exr"],
        vec!["render", "scene.exr", "-o", "./sub/../scene.exr"],
        vec!["render", "scene.exr", "-o", "link.exr"],
        vec!["render", "textured.toml", "-o", "t.png"],
        vec!["render", "textured.toml", "-o", "mesh.pfm"],
        vec!["filter", "fine.exr", "-o", "fine.exr"],
        vec!["compare", "fine.exr", "fine.exr", "--diff", "fine.exr"],
    ];
    std::fs::create_dir(d.join("sub")).expect("mkdir");
    let before: Vec<Vec<u8>> = ["scene.exr", "t.png", "mesh.pfm", "fine.exr"]
        .iter()
        .map(|f| std::fs::read(d.join(f)).expect("read"))
        .collect();
    for args in cases {
        let o = run_in(d, &args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("is an input"), "{args:?}: {}", stderr(&o));
    }
    let after: Vec<Vec<u8>> = ["scene.exr", "t.png", "mesh.pfm", "fine.exr"]
        .iter()
        .map(|f| std::fs::read(d.join(f)).expect("read"))
        .collect();
    assert!(before == after, "an input was changed");
}

/// Defect 9: output problems were found only after the render, with status 1. A directory, a
/// directory that cannot be written and a missing one are refused first, with status 2.
#[test]
fn output_problems_are_found_before_the_render() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SCENE).expect("write");
    std::fs::create_dir(d.join("taken.exr")).expect("mkdir");
    for (output, why) in [
        ("taken.exr", "is a directory"),
        ("/proc/lightsplit-test.exr", "cannot write in /proc"),
        ("gone/x.exr", "does not exist"),
    ] {
        // A render of seconds, were it started: the refusal comes first.
        let o = run_in(
            d,
            &["render", "s.toml", "-o", output, "--spp", "64", "--width", "1024", "--height", "1024"],
        );
        assert_eq!(o.status.code(), Some(2), "{output}: {}", stderr(&o));
        assert!(stderr(&o).contains(why), "{output}: {}", stderr(&o));
    }
    let leftovers: Vec<_> =
        std::fs::read_dir(d).expect("list").filter_map(Result::ok).map(|e| e.file_name()).collect();
    assert_eq!(leftovers.len(), 2, "{leftovers:?}");
}

/// Defect 4: memory and time without bounds. A render larger than memory, `/dev/zero` as a
/// scene or a mesh, a kernel beyond 63x63, absurd thread counts and depths: each refused with
/// status 2 before any work. And (item 10) the command line keeps the scene file's bounds.
#[test]
fn unbounded_requests_are_refused_up_front() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SCENE).expect("write");
    let zero_mesh = format!("{SCENE}[[shape]]\ntype = \"mesh\"\nfile = \"/dev/zero\"\n");
    std::fs::write(d.join("zero.toml"), zero_mesh).expect("write");
    let weights = vec!["1"; 65 * 65].join(", ");
    std::fs::write(d.join("kernel.toml"), format!("{SCENE}[filter]\nkernel = [{weights}]\n")).expect("write");
    std::fs::write(d.join("nan.toml"), format!("{SCENE}[filter]\nkernel = [1, nan, 1, 1, 1, 1, 1, 1, 1]\n"))
        .expect("write");
    std::fs::write(d.join("deep.toml"), format!("{SCENE}[render]\nmax_depth = 1025\n")).expect("write");
    let big = lightsplit_max_size_plus(0);
    let cases: Vec<(Vec<String>, &str)> = vec![
        (args(&["render", "s.toml", "--width", &big, "--height", &big]), "GiB is available"),
        (args(&["render", "/dev/zero", "-o", "z.exr"]), "not a regular file"),
        (args(&["render", "zero.toml", "-o", "z.exr"]), "not a regular file"),
        (args(&["render", "kernel.toml", "-o", "k.exr"]), "at most 63x63"),
        (args(&["render", "nan.toml", "-o", "k.exr"]), "not a finite number"),
        (args(&["render", "s.toml", "--filter", &vec!["1"; 65 * 65].join(",")]), "at most 63x63"),
        (args(&["render", "s.toml", "--threads", "100000"]), "16 a core"),
        (args(&["render", "s.toml", "--max-depth", "4294967295"]), "1 to 1024"),
        (args(&["render", "deep.toml", "-o", "x.exr"]), "between 1 and 1024"),
        (args(&["render", "s.toml", "--width", &lightsplit_max_size_plus(1)]), "1 to 65536"),
        (args(&["render", "s.toml", "--spp", "16777217"]), "1 to 16777216"),
        (args(&["converge", "s.toml", "--spp", "16777217"]), "1 to 16777216"),
    ];
    for (a, why) in cases {
        let o = run_in(d, &a);
        assert_eq!(o.status.code(), Some(2), "{a:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(why), "{a:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"), "{a:?}: {}", stderr(&o));
    }
    // The bounds themselves are allowed.
    let o = run_in(d, &["render", "s.toml", "-o", "ok.exr", "--max-depth", "1024", "--width", "8"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

fn args(a: &[&str]) -> Vec<String> {
    a.iter().map(|s| s.to_string()).collect()
}

/// The largest image side the scene file allows, plus `n`, as text.
fn lightsplit_max_size_plus(n: u32) -> String {
    ((1u32 << 16) + n).to_string()
}

/// Defect 5: extra array elements, junk included, were accepted silently. A vector has exactly
/// its length; the error names the file and line.
#[test]
fn a_vector_has_exactly_its_length() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let cases = [
        ("position = [0, 3, 0]", "position = [0, 2.2, -7, nan]", 10),
        ("intensity = [5, 5, 5]", "intensity = [0.7, 0.08, 0.06, 9]", 11),
        ("radius = 1", "radius = 1\nrotate = [0, 0, 0, \"junk\", [1, 2]]", 16),
        ("intensity = [5, 5, 5]", "intensity = [5, 5]", 11),
    ];
    for (i, (from, to, line)) in cases.into_iter().enumerate() {
        assert!(SCENE.contains(from));
        let name = format!("v{i}.toml");
        std::fs::write(d.join(&name), SCENE.replace(from, to)).expect("write");
        let o = run_in(d, &["render", &name, "-o", "x.exr"]);
        assert_eq!(o.status.code(), Some(2), "{to}: {}", stderr(&o));
        assert!(stderr(&o).contains(&format!("{name}:{line}:")), "{to}: {}", stderr(&o));
    }
    assert!(!d.join("x.exr").exists());
}

/// Item 10: `compare` with NaN or infinite pixels printed NaN figures and exited 0; now it says
/// how many pixels are not finite and exits with status 2.
#[test]
fn compare_refuses_non_finite_pixels() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    // A 2x1 PFM with a NaN in its first pixel, and a clean one.
    let pfm = |first: f32| pfm(2, 1, &[first, 0.5, 0.5, 0.5, 0.5, 0.5]);
    std::fs::write(d.join("nan.pfm"), pfm(f32::NAN)).expect("write");
    std::fs::write(d.join("ok.pfm"), pfm(0.5)).expect("write");
    let o = run_in(d, &["compare", "nan.pfm", "ok.pfm", "--json"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("1 of 2 pixels that are not finite"), "{}", stderr(&o));
    assert!(o.stdout.is_empty(), "figures were printed: {}", String::from_utf8_lossy(&o.stdout));
    let o = run_in(d, &["compare", "ok.pfm", "ok.pfm", "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// Item 10: `--exposure` was ignored silently for EXR and HDR output, and by `info`; now a
/// render warns, and `info` says what it does to a PNG.
#[test]
fn exposure_is_never_ignored_silently() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(d.join("s.toml"), SCENE).expect("write");
    for out in ["x.exr", "x.hdr", "x.pfm"] {
        let o = run_in(d, &["render", "s.toml", "-o", out, "--exposure", "2"]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(stderr(&o).contains("warning: --exposure 2 is ignored"), "{out}: {}", stderr(&o));
    }
    let o = run_in(d, &["render", "s.toml", "-o", "x.png", "--exposure", "2"]);
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    let o = run_in(d, &["info", "s.toml", "-o", "x.png", "--exposure", "1.5"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("exposed by 1.5 stops"), "{o:?}");
    let o = run_in(d, &["info", "s.toml", "-o", "x.exr", "--exposure", "1.5"]);
    assert!(stderr(&o).contains("warning: --exposure 1.5 is ignored"), "{}", stderr(&o));
}

/// Defect 7: `emission = [3e38, ...]` wrote an EXR of infinities. Emission is bounded (1e12),
/// so the film stays finite; a value within the bound renders. (A light's overflowing samples
/// are infinite, dropped and counted: `tests/nonfinite.rs`.)
#[test]
fn emission_that_would_overflow_the_film_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let cases = [
        ("radius = 1", "radius = 1\nemission = [3e38, 3e38, 3e38]", "`emission` must be at most"),
        ("radius = 1", "radius = 1\nemission = [1, 2e12, 1]", "`emission` must be at most"),
    ];
    for (i, (from, to, why)) in cases.into_iter().enumerate() {
        let name = format!("e{i}.toml");
        std::fs::write(d.join(&name), SCENE.replace(from, to)).expect("write");
        let o = run_in(d, &["render", &name, "-o", "x.exr"]);
        assert_eq!(o.status.code(), Some(2), "{to}: {}", stderr(&o));
        assert!(stderr(&o).contains(why), "{to}: {}", stderr(&o));
    }
    std::fs::write(
        d.join("bright.toml"),
        SCENE.replace("radius = 1", "radius = 1\nemission = [1e12, 1e12, 1e12]"),
    )
    .expect("write");
    let o = run_in(d, &["render", "bright.toml", "-o", "b.pfm"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let bytes = std::fs::read(d.join("b.pfm")).expect("read");
    let header = b"PF\n8 8\n-1.0\n".len();
    let values: Vec<f32> =
        bytes[header..].chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    assert_eq!(values.len(), 8 * 8 * 3);
    assert!(values.iter().all(|v| v.is_finite()), "the film is not finite");
    assert!(values.iter().any(|&v| v > 1e11), "the emitter is not seen");
}

/// Defect 6: texture values were not validated: an EXR texture of NaN rendered black with exit
/// 0, a value of 100 or -1 gave huge or negative radiance, a `constant` texture took [5, 5, 5].
/// Now non-finite pixels are refused, image values are clamped to [0, 1] as a colour (so 100
/// renders as 1 and -1 as 0, exactly), and pattern colours outside [0, 1] are refused.
#[test]
fn texture_values_follow_the_rules_of_colours() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let pfm = |v: f32| pfm(2, 2, &[v; 12]);
    let textured = |file: &str| {
        format!(
            "{SCENE}[[texture]]\nname = \"t\"\ntype = \"image\"\nfile = \"{file}\"\n\
             [[material]]\nname = \"m\"\ntype = \"diffuse\"\ntexture = \"t\"\n\
             [[shape]]\ntype = \"quad\"\nvertices = [[-3, 0, -3], [-3, 0, 3], [3, 0, 3], [3, 0, -3]]\nmaterial = \"m\"\n"
        )
    };
    let render = |name: &str, value: f32| {
        std::fs::write(d.join(format!("{name}.pfm")), pfm(value)).expect("write");
        std::fs::write(d.join(format!("{name}.toml")), textured(&format!("{name}.pfm"))).expect("write");
        run_in(d, &["render", &format!("{name}.toml"), "-o", &format!("{name}-out.pfm")])
    };
    let o = render("nan", f32::NAN);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("4 of its 4 pixels are NaN or infinite"), "{}", stderr(&o));
    for (name, value, same_as) in [("hundred", 100.0, 1.0), ("minus", -1.0, 0.0)] {
        assert_eq!(render(name, value).status.code(), Some(0));
        assert_eq!(render(&format!("{name}-ref"), same_as).status.code(), Some(0));
        let got = std::fs::read(d.join(format!("{name}-out.pfm"))).expect("read");
        let want = std::fs::read(d.join(format!("{name}-ref-out.pfm"))).expect("read");
        assert!(got == want, "a texture of {value} does not render as {same_as}");
    }
    // The texture shows: white and black render differently.
    let white = std::fs::read(d.join("hundred-ref-out.pfm")).expect("read");
    let black = std::fs::read(d.join("minus-ref-out.pfm")).expect("read");
    assert!(white != black, "the texture does not show in the render");
    let constant = format!("{SCENE}[[texture]]\nname = \"c\"\ntype = \"constant\"\ncolor = [5, 5, 5]\n");
    std::fs::write(d.join("c.toml"), constant).expect("write");
    let o = run_in(d, &["render", "c.toml", "-o", "c.exr"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("must lie in [0, 1]"), "{}", stderr(&o));
}

/// Item 10: smaller defects. Control characters from a name were echoed raw to the terminal;
/// a `.ply` or `.gltf` mesh said "has no faces"; `converge` left an empty `--out` behind when
/// its reference was bad.
#[test]
fn smaller_defects_of_item_10() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let scene = format!("{SCENE}material = \"\\u001b[31mred\\u0000\"\n");
    std::fs::write(d.join("esc.toml"), scene).expect("write");
    let o = run_in(d, &["render", "esc.toml", "-o", "x.exr"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!o.stderr.contains(&0x1b) && !o.stderr.contains(&0), "raw control bytes: {:?}", stderr(&o));
    assert!(stderr(&o).contains("\\u{1b}[31mred\\u{0}"), "{}", stderr(&o));
    // A glTF named as a mesh is pointed to its own shape type (issue 19 reads glTF); another
    // format is refused by name.
    for (ext, needle) in [
        ("gltf", "a glTF file is a shape of its own"),
        ("GLB", "shape of its own"),
        ("fbx", "meshes are Wavefront OBJ files"),
    ] {
        std::fs::write(d.join(format!("m.{ext}")), "ply\nformat ascii 1.0\n").expect("write");
        let text = format!("{SCENE}[[shape]]\ntype = \"mesh\"\nfile = \"m.{ext}\"\n");
        std::fs::write(d.join("mesh.toml"), text).expect("write");
        let o = run_in(d, &["render", "mesh.toml", "-o", "x.exr"]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{ext}: {}", stderr(&o));
    }
    // Counts are whole numbers, as docs/scene-format.md now says.
    std::fs::write(d.join("w.toml"), SCENE.replace("width = 8", "width = 8.0")).expect("write");
    let o = run_in(d, &["render", "w.toml", "-o", "x.exr"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("w.toml:5:"), "{}", stderr(&o));
    std::fs::write(d.join("s.toml"), SCENE).expect("write");
    std::fs::write(d.join("bad.exr"), "not an image").expect("write");
    let o = run_in(d, &["converge", "s.toml", "--reference", "bad.exr", "--out", "conv", "--spp", "1"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!d.join("conv").exists(), "an empty --out was left behind");
}

/// Worlds far from the origin: a scene (TOML and OBJ) moved by 1e8 renders bit for bit as at
/// the origin, solid texture included. The coordinates are read in f64 and the camera's
/// position subtracted before rounding to f32 (f32's step at 1e8 is 8 units: before, the
/// floor, the sphere and the camera collapsed onto one grid point).
#[test]
fn a_world_moved_by_1e8_renders_as_at_the_origin() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene_at = |offset: f64, name: &str| -> std::path::PathBuf {
        let p = |x: f64, y: f64, z: f64| format!("[{}, {}, {}]", offset + x, offset + y, offset + z);
        let v = |x: f64, y: f64, z: f64| format!("v {} {} {}\n", offset + x, offset + y, offset + z);
        let obj = dir.path().join(format!("{name}.obj"));
        let mut text = String::new();
        for (x, z) in [(-2.0, -2.0), (2.0, -2.0), (2.0, 2.0), (-2.0, 2.0)] {
            text.push_str(&v(x, 0.0, z));
        }
        text.push_str("f 1 4 3 2\n");
        std::fs::write(&obj, text).expect("write obj");
        let toml = format!(
            "[camera]\nposition = {}\nlook_at = {}\n[film]\nwidth = 16\nheight = 16\nspp = 4\n\
             [[light]]\ntype = \"point\"\nposition = {}\nintensity = [5, 5, 5]\n\
             [[texture]]\nname = \"c\"\ntype = \"checker\"\nsize = 0.5\n\
             [[material]]\nname = \"floor\"\ntype = \"diffuse\"\ntexture = \"c\"\n\
             [[shape]]\ntype = \"mesh\"\nfile = \"{name}.obj\"\nmaterial = \"floor\"\n\
             [[shape]]\ntype = \"sphere\"\ncenter = {}\nradius = 0.75\n",
            p(0.25, 1.5, -4.0),
            p(0.0, 0.5, 0.0),
            p(0.5, 3.0, -0.5),
            p(0.0, 0.75, 0.0),
        );
        let path = dir.path().join(format!("{name}.toml"));
        std::fs::write(&path, toml).expect("write scene");
        path
    };
    let render = |scene: &std::path::Path| -> Vec<u8> {
        let out = scene.with_extension("pfm");
        let o = run(&[OsStr::new("render"), scene.as_os_str(), OsStr::new("-o"), out.as_os_str()]);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read(out).expect("image")
    };
    let near = render(&scene_at(0.0, "near"));
    let far = render(&scene_at(1e8, "far"));
    assert!(near.len() > 16 * 16 * 12);
    let floats = |b: &[u8]| -> Vec<f32> {
        b[b.len() - 16 * 16 * 12..]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    };
    let (near, far) = (floats(&near), floats(&far));
    assert!(near.iter().any(|&v| v > 0.0), "the scene is lit");
    let differ = near.iter().zip(&far).filter(|(a, b)| a != b).count();
    assert_eq!(differ, 0, "{differ} of {} values differ", near.len());
}

/// Defect 8: a SIGTERM or SIGINT in the middle of a write removes the temporary file and leaves
/// the output as it was (exit status 128 + the signal). A temporary that a SIGKILL left, its
/// process gone, is removed by the next write of the same file; a running process's is not.
#[test]
fn a_stop_during_a_write_leaves_no_temporary() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("s.toml");
    std::fs::write(&scene, SCENE).expect("write");
    let out = dir.path().join("o.exr");
    std::fs::write(&out, b"the old output").expect("write");
    let temporaries = || -> Vec<String> {
        let names = std::fs::read_dir(dir.path()).expect("read_dir").flatten();
        names.map(|e| e.file_name().to_string_lossy().into_owned()).filter(|n| n.contains(".tmp.")).collect()
    };
    use rustix::process::{Pid, Signal};
    for (signal, sig, number) in [("TERM", Signal::TERM, 15), ("INT", Signal::INT, 2)] {
        // A 1024x1024 EXR takes about half a second to write: the stop lands inside it.
        let mut child = Command::new(env!("CARGO_BIN_EXE_lightsplit"))
            .args([OsStr::new("render"), scene.as_os_str(), OsStr::new("-o"), out.as_os_str()])
            .args(["--width", "1024", "--height", "1024"])
            .stderr(Stdio::null())
            .spawn()
            .expect("spawns");
        let tmp = dir.path().join(format!(".o.exr.{}.tmp.exr", child.id()));
        let start = std::time::Instant::now();
        while !tmp.exists() && start.elapsed() < std::time::Duration::from_secs(60) {
            if child.try_wait().expect("waits").is_some() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        assert!(tmp.exists(), "the write was never seen under way");
        rustix::process::kill_process(Pid::from_child(&child), sig).expect("the signal is sent");
        let status = child.wait().expect("waits");
        assert_eq!(status.code(), Some(128 + number), "SIG{signal}");
        assert_eq!(temporaries(), Vec::<String>::new(), "SIG{signal} left a temporary");
        assert_eq!(std::fs::read(&out).expect("read"), b"the old output", "SIG{signal} touched the output");
    }
    // Beyond Linux's largest process id (2^22): the process that left it is gone.
    let stale = dir.path().join(".o.exr.4194305.tmp.exr");
    let live = dir.path().join(format!(".o.exr.{}.tmp.exr", std::process::id()));
    let other = dir.path().join(".p.exr.4194305.tmp.exr");
    for f in [&stale, &live, &other] {
        std::fs::write(f, b"half an image").expect("write");
    }
    let o = run(&[OsStr::new("render"), scene.as_os_str(), OsStr::new("-o"), out.as_os_str()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stale.exists(), "the stale temporary of o.exr is removed");
    assert!(live.exists(), "a running process's temporary is left alone");
    assert!(other.exists(), "another file's temporary is not this write's to remove");
}

/// Issue 19: a PLY mesh (binary) renders bit for bit as the same mesh from an OBJ.
#[test]
fn a_ply_mesh_renders_as_its_obj() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let corners =
        [[-2.0f32, 0.0, -2.0], [-2.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -2.0], [0.0, 1.5, 0.0]];
    let faces = [[0u32, 1, 2, 3], [0, 4, 1, 1], [1, 4, 2, 2]];
    let mut obj = String::new();
    corners.iter().for_each(|c| obj.push_str(&format!("v {} {} {}\n", c[0], c[1], c[2])));
    obj.push_str("f 1 2 3 4\nf 1 5 2\nf 2 5 3\n");
    std::fs::write(d.join("m.obj"), obj).expect("write");
    let mut ply =
        b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\n\
property float z\nelement face 3\nproperty list uchar uint vertex_indices\nend_header\n"
            .to_vec();
    corners.iter().flatten().for_each(|x| ply.extend(x.to_le_bytes()));
    for (k, f) in faces.iter().enumerate() {
        let n = if k == 0 { 4 } else { 3 };
        ply.push(n as u8);
        f[..n].iter().for_each(|i| ply.extend(i.to_le_bytes()));
    }
    std::fs::write(d.join("m.ply"), ply).expect("write");
    let render = |mesh: &str| -> Vec<u8> {
        let text = SCENE.replace("[[shape]]\ntype = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1\n", "")
            + &format!("[[shape]]\ntype = \"mesh\"\nfile = \"{mesh}\"\n");
        std::fs::write(d.join("s.toml"), text).expect("write");
        let o = run_in(d, &["render", "s.toml", "-o", "x.pfm"]);
        assert!(o.status.success(), "{mesh}: {}", stderr(&o));
        std::fs::read(d.join("x.pfm")).expect("image")
    };
    let (a, b) = (render("m.obj"), render("m.ply"));
    assert!(a.iter().skip(20).any(|&x| x != 0), "the mesh is lit");
    assert_eq!(a, b);
}
