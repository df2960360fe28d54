//! The command line as a user meets it: bad input is one clear error with exit status 2 and no
//! panic; the README's render command makes a PNG that is not black; --json has its keys.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::lightsplit;

const CAMERA: &str = "[camera]\nposition = [0, 1, -5]\nlook_at = [0, 1, 0]\n";

/// Writes a scene (and any side files) into a temporary directory and renders it.
fn render_bad(files: &[(&str, &str)], extra: &[&str]) -> (i32, String, tempfile::TempDir) {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, text) in files {
        std::fs::write(dir.path().join(name), text).expect("write");
    }
    let scene = dir.path().join(files[0].0);
    let out = dir.path().join("out.png");
    let mut args = vec!["render", scene.to_str().expect("utf8"), "-o", out.to_str().expect("utf8")];
    args.extend_from_slice(extra);
    let output = lightsplit(&args);
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "a panic: {stderr}");
    assert!(!out.exists(), "an output was written for bad input");
    (output.status.code().unwrap_or(-1), stderr, dir)
}

/// A bad-input case: what it is, the files (scene first), what the error must mention.
type Case = (&'static str, Vec<(&'static str, String)>, &'static str);

#[test]
fn each_kind_of_bad_scene_is_one_error_with_status_2() {
    let cases: Vec<Case> = vec![
        ("unknown key", vec![("s.toml", format!("{CAMERA}[film]\nwidht = 3\n"))], "s.toml:5:"),
        (
            "NaN",
            vec![("s.toml", format!("{CAMERA}[[shape]]\ntype = \"sphere\"\nradius = nan\n"))],
            "s.toml:6:",
        ),
        (
            "infinity",
            vec![(
                "s.toml",
                format!(
                    "{CAMERA}[[light]]\ntype = \"point\"\nposition = [0, -inf, 0]\nintensity = [1, 1, 1]\n"
                ),
            )],
            "s.toml:6:",
        ),
        ("wrong type", vec![("s.toml", format!("{CAMERA}[film]\nspp = \"many\"\n"))], "s.toml:5:"),
        ("syntax", vec![("s.toml", format!("{CAMERA}[film\n"))], "s.toml:4:"),
        (
            "missing mesh",
            vec![("s.toml", format!("{CAMERA}[[shape]]\ntype = \"mesh\"\nfile = \"gone.obj\"\n"))],
            "gone.obj",
        ),
        (
            "mesh index out of range",
            vec![
                ("s.toml", format!("{CAMERA}[[shape]]\ntype = \"mesh\"\nfile = \"m.obj\"\n")),
                ("m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n".into()),
            ],
            "m.obj:4:",
        ),
        (
            "unknown material",
            vec![(
                "s.toml",
                format!("{CAMERA}[[shape]]\ntype = \"sphere\"\nradius = 1\nmaterial = \"gold\"\n"),
            )],
            "gold",
        ),
        ("unknown shape", vec![("s.toml", format!("{CAMERA}[[shape]]\ntype = \"torus\"\n"))], "torus"),
        ("no camera", vec![("s.toml", "[film]\nspp = 4\n".into())], "camera"),
        ("zero size", vec![("s.toml", format!("{CAMERA}[film]\nwidth = 0\n"))], "s.toml:5:"),
    ];
    for (what, files, expect) in cases {
        let files: Vec<(&str, &str)> = files.iter().map(|(n, t)| (*n, t.as_str())).collect();
        let (code, stderr, _dir) = render_bad(&files, &[]);
        assert_eq!(code, 2, "{what}: status {code}, stderr {stderr}");
        assert!(stderr.contains(expect), "{what}: expected `{expect}` in: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{what}: not one line: {stderr}");
    }
}

#[test]
fn missing_scene_file_and_bad_arguments_are_status_2() {
    let out = lightsplit(&["render", "no/such/scene.toml"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no/such/scene.toml"));

    let scene = format!("{CAMERA}[film]\nwidth = 4\nheight = 4\nspp = 1\n");
    for args in [&["--spp", "0"][..], &["--threads", "0"][..], &["--spp", "-3"][..]] {
        let (code, stderr, _dir) = render_bad(&[("s.toml", &scene)], args);
        assert_eq!(code, 2, "{args:?}: {stderr}");
    }
    // An output that cannot be written is refused before rendering.
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("s.toml");
    std::fs::write(&path, &scene).expect("write");
    for bad in ["out.jpg", "no/such/dir/out.png"] {
        let target = dir.path().join(bad);
        let out = lightsplit(&["render", path.to_str().expect("utf8"), "-o", target.to_str().expect("utf8")]);
        assert_eq!(out.status.code(), Some(2), "{bad}");
    }
}

/// Every range a flag must lie in is checked as the command line is parsed: one error naming
/// the flag and the rule, status 2, before any scene is read.
#[test]
fn out_of_range_flags_are_usage_errors_naming_the_flag() {
    let cases: [&[&str]; 14] = [
        &["render", "s.toml", "--width", "0"],
        &["render", "s.toml", "--sampler", "halton"],
        &["converge", "s.toml", "--out", "d", "--sampler", "independent,random"],
        &["render", "s.toml", "--max-depth", "0"],
        &["render", "s.toml", "--exposure", "nan"],
        &["render", "s.toml", "--adaptive", "0"],
        &["converge", "s.toml", "--out", "d", "--spp", "1,0"],
        &["converge", "s.toml", "--out", "d", "--seeds", "0"],
        &["converge", "s.toml", "--out", "d", "--threads", "0"],
        &["bench-accel", "s.toml", "--rays", "0"],
        &["bench-accel", "s.toml", "--seconds", "0"],
        &["bench-features", "s.toml", "--rounds", "0"],
        &["stress", "--threads", "0"],
        &["stress", "--accel", "gpu"],
    ];
    for args in cases {
        let out = lightsplit(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        let flag = args[args.len() - 2];
        assert!(stderr.starts_with("error: invalid value") && stderr.contains(flag), "{args:?}: {stderr}");
        assert!(!stderr.contains("s.toml"), "{args:?}: the scene was read: {stderr}");
    }
}

/// The render command the README gives a newcomer, run as written (with the output redirected
/// into a temporary directory).
#[test]
fn readme_render_command_makes_a_png_that_is_not_black() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).expect("README.md");
    let command = readme
        .lines()
        .find_map(|l| l.split_once("cargo run --release -- render ").map(|(_, rest)| rest.to_string()))
        .expect("the README has a `cargo run --release -- render` command");
    let mut args: Vec<String> = command.split_whitespace().map(str::to_string).collect();
    let dir = tempfile::tempdir().expect("tempdir");
    let out_index = args.iter().position(|a| a == "-o").expect("the command names an output") + 1;
    let png: PathBuf = dir.path().join(Path::new(&args[out_index]).file_name().expect("file name"));
    args[out_index] = png.to_string_lossy().into_owned();
    let mut full = vec!["render".to_string()];
    full.extend(args);
    let output =
        Command::new(env!("CARGO_BIN_EXE_lightsplit")).current_dir(root).args(&full).output().expect("runs");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let img = image::open(&png).expect("a PNG").into_rgb8();
    let mean: f64 = img.pixels().map(|p| p.0.iter().map(|&c| c as f64).sum::<f64>()).sum::<f64>()
        / (3.0 * img.pixels().len() as f64);
    assert!(mean > 20.0, "mean pixel value {mean} is nearly black");
}

#[test]
fn json_summary_has_the_documented_keys() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sky-sphere.toml");
    let out = dir.path().join("s.exr");
    let output = lightsplit(&[
        "render",
        scene.to_str().expect("utf8"),
        "-o",
        out.to_str().expect("utf8"),
        "--spp",
        "2",
        "--width",
        "24",
        "--height",
        "16",
        "--sampler",
        "independent",
        "--seed",
        "5",
        "--json",
    ]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let v: serde_json::Value = serde_json::from_slice(&output.stdout).expect("one JSON object");
    for key in [
        "seconds",
        "spp",
        "width",
        "height",
        "accel",
        "samples_per_second",
        "rays_per_second",
        "nonfinite_samples",
        "outputs",
    ] {
        assert!(v.get(key).is_some(), "missing {key}: {v}");
    }
    assert_eq!(v["spp"], 2);
    assert_eq!((v["width"].as_u64(), v["height"].as_u64()), (Some(24), Some(16)));
    assert_eq!(v["accel"], "embree");
    assert_eq!((v["sampler"].as_str(), v["seed"].as_u64()), (Some("independent"), Some(5)));
    assert!(v["rays_per_second"].as_f64().unwrap_or(0.0) > 0.0);
    // Issue 19: the settings that reproduce the image, and the program's version.
    assert_eq!(v["max_depth"].as_u64(), Some(8));
    assert_eq!(v["version"].as_str(), Some(env!("CARGO_PKG_VERSION")));
    assert_eq!((v["edge_aware"].as_bool(), v["edge_pure"].as_bool()), (Some(false), Some(false)));
    assert!(out.exists());
    // Nothing but the output is left in the directory (no temporary files).
    assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 1);
}

/// Issue 19: the EXR says how it was made (pbrt-v4's attribute names where it has them), and
/// its alpha is the coverage of the non-background; `filter` keeps what its input recorded and
/// names its own filter.
#[test]
fn the_exr_records_how_it_was_made_and_has_an_alpha() {
    use lightsplit::film::{read_exr_channels, Metadata};
    let dir = tempfile::tempdir().expect("tempdir");
    let p = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    // A sphere filling the middle of the image, nothing behind it.
    let scene = format!("{CAMERA}[film]\nwidth = 16\nheight = 16\nspp = 16\n[[shape]]\ntype = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1.2\n[[light]]\ntype = \"point\"\nposition = [0, 4, -3]\nintensity = [9, 9, 9]\n");
    std::fs::write(p("s.toml"), scene).expect("write");
    let o = lightsplit(&["render", &p("s.toml"), "-o", &p("a.exr"), "--seed", "77", "--max-depth", "3"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let meta = Metadata::of_exr(Path::new(&p("a.exr"))).expect("a header");
    assert_eq!((meta.spp, meta.seed, meta.max_depth), (Some(16), Some(77), Some(3)));
    assert_eq!(meta.sampler.as_deref(), Some("sobol"));
    assert_eq!(meta.scene.as_deref(), Some(p("s.toml").as_str()));
    assert!(meta.render_seconds.is_some_and(|s| s > 0.0));
    assert!(meta.world_to_camera.is_some() && meta.world_to_ndc.is_some());
    // worldToCamera takes the camera's position (0, 1, -5) to camera space's origin.
    let m = meta.world_to_camera.expect("matrix");
    let eye: Vec<f32> =
        (0..3).map(|r| m[4 * r] * 0.0 + m[4 * r + 1] * 1.0 + m[4 * r + 2] * -5.0 + m[4 * r + 3]).collect();
    assert!(eye.iter().all(|v| v.abs() < 1e-5), "{eye:?}");
    let (w, _, channels) = read_exr_channels(Path::new(&p("a.exr"))).expect("reads");
    let alpha = &channels.iter().find(|(n, _)| n == "A").expect("an A channel").1;
    let at = |x: usize, y: usize| alpha[y * w as usize + x];
    assert_eq!((at(8, 8), at(0, 0)), (1.0, 0.0), "the sphere's middle and an empty corner");
    assert!(alpha.iter().any(|&a| a > 0.0 && a < 1.0), "fractional on the silhouette");
    // `filter` keeps the render's record and names its filter.
    let o = lightsplit(&["filter", &p("a.exr"), "-o", &p("b.exr"), "--filter", "box3"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let filtered = Metadata::of_exr(Path::new(&p("b.exr"))).expect("a header");
    assert_eq!(filtered.filter.as_deref(), Some("box3 on indirect"));
    assert_eq!(Metadata { filter: None, ..filtered }, meta);
}

/// `render --filter` writes every layer of DESIGN's list; `filter` re-filters the saved file
/// and `compare` measures it; mismatched sizes and missing layers are clear errors (status 2).
#[test]
fn render_filter_and_compare_work_together() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sky-sphere.toml");
    let p = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let scene = scene.to_string_lossy().into_owned();
    let small = ["--width", "32", "--height", "24", "--spp", "4"];
    let run = |args: &[&str]| {
        let out = lightsplit(args);
        assert!(!String::from_utf8_lossy(&out.stderr).contains("panicked"));
        out
    };
    let out = run(&[&["render", &scene, "-o", &p("f.exr"), "--filter", "weighted3"][..], &small].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (_, _, channels) = lightsplit::film::read_exr_channels(Path::new(&p("f.exr"))).expect("reads");
    let names: Vec<&str> = channels.iter().map(|(n, _)| n.as_str()).collect();
    for layer in ["raw", "emitted", "direct", "caustic", "indirect", "indirect_filtered", "albedo"] {
        for c in ["R", "G", "B"] {
            assert!(names.contains(&format!("{layer}.{c}").as_str()), "{layer}.{c} missing: {names:?}");
        }
    }
    for name in ["R", "G", "B", "normal.X", "normal.Y", "normal.Z", "depth.Z", "objectid.ID"] {
        assert!(names.contains(&name), "{name} missing");
    }

    let out = run(&["filter", &p("f.exr"), "-o", &p("g.exr"), "--filter", "median3", "--edge-aware"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = run(&["compare", &p("g.exr"), &p("f.exr"), "--json", "--diff", &p("d.png")]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    for key in ["sse", "rmse", "relmse", "rmse_trimmed", "relmse_trimmed", "width", "height"] {
        assert!(v.get(key).is_some(), "{key}");
    }
    assert!(v["rmse"].as_f64().expect("rmse") > 0.0);
    assert!(Path::new(&p("d.png")).exists());
    let same = run(&["compare", &p("f.exr"), &p("f.exr"), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&same.stdout).expect("json");
    assert_eq!(v["sse"], 0.0);

    // Another compression: the same channels, bit for bit, and the header says which; an
    // unknown one is status 2 and writes nothing.
    let args = ["filter", &p("f.exr"), "-o", &p("rle.exr"), "--filter", "median3", "--edge-aware"];
    let out = run(&[&args[..], &["--exr-compression", "rle"]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let header = lightsplit::film::Metadata::of_exr(Path::new(&p("rle.exr"))).expect("header");
    assert_eq!(header.compression, lightsplit::film::ExrCompression::Rle);
    let read = |name: &str| lightsplit::film::read_exr_channels(Path::new(&p(name))).expect("reads").2;
    let bits = |c: Vec<(String, Vec<f32>)>| -> Vec<(String, Vec<u32>)> {
        c.into_iter().map(|(n, v)| (n, v.iter().map(|x| x.to_bits()).collect())).collect()
    };
    assert_eq!(bits(read("rle.exr")), bits(read("g.exr")));
    let lzw = p("lzw.exr");
    let out = run(&["filter", &p("f.exr"), "-o", &lzw, "--filter", "median3", "--exr-compression", "lzw"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("exr-compression"));
    assert!(!Path::new(&lzw).exists());

    // A different size, a file without the layers, a bad kernel: status 2 each.
    run(&["render", &scene, "-o", &p("other.exr"), "--width", "16", "--height", "16", "--spp", "1"]);
    let out = run(&["compare", &p("f.exr"), &p("other.exr")]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("size"));
    let rgb_only = p("rgb.exr");
    lightsplit::film::write(&lightsplit::film::Image::new(4, 4), Path::new(&rgb_only), 0.0).expect("write");
    let out = run(&["filter", &rgb_only, "-o", &p("h.exr"), "--filter", "box3"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("raw.R"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = run(&["filter", &p("f.exr"), "-o", &p("h.exr"), "--filter", "gauss"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(!Path::new(&p("h.exr")).exists());
}

/// The à-trous filter and the `components` target from the command line: they run on a render's
/// EXR; a bad setting, or a file written before the variance layers existed, is status 2.
#[test]
fn atrous_and_the_components_target_work_and_check_their_input() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sky-sphere.toml");
    let p = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let scene = scene.to_string_lossy().into_owned();
    let run = |args: &[&str]| {
        let out = lightsplit(args);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(!stderr.contains("panicked"), "{stderr}");
        (out, stderr)
    };
    let (out, err) =
        run(&["render", &scene, "-o", &p("f.exr"), "--width", "32", "--height", "24", "--spp", "4"]);
    assert!(out.status.success(), "{err}");
    for target in ["indirect", "components", "image"] {
        let g = p(&format!("{target}.exr"));
        let (out, err) =
            run(&["filter", &p("f.exr"), "-o", &g, "--filter", "atrous:passes=3", "--filter-target", target]);
        assert!(out.status.success(), "{target}: {err}");
        let (out, _) = run(&["compare", &g, &p("f.exr"), "--json"]);
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        assert!(v["rmse"].as_f64().expect("rmse") > 0.0, "{target}: atrous changed nothing");
    }
    for (args, needle) in [
        (vec!["--filter", "atrous:passes=0"], "passes"),
        (vec!["--filter", "atrous:sigma_l=-1"], "sigma_l"),
        (vec!["--filter", "atrous:taps=4"], "taps"),
        (vec!["--filter", "atrous", "--filter-target", "everything"], "everything"),
    ] {
        let (out, err) = run(&[&["filter", &p("f.exr"), "-o", &p("bad.exr")][..], &args].concat());
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!Path::new(&p("bad.exr")).exists());
    }
    // --denoise: the shortcut filters, and cannot be combined with a filter of one's own.
    let (out, err) = run(&["filter", &p("f.exr"), "-o", &p("denoised.exr"), "--denoise", "--json"]);
    assert!(out.status.success(), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(v["filter_target"], "components");
    assert!(v["filter"].as_str().is_some_and(|f| f.starts_with("atrous")), "{v}");
    assert!(v["filter_seconds"].as_f64().is_some_and(|s| s > 0.0), "{v}");
    let (out, _) = run(&["compare", &p("denoised.exr"), &p("f.exr"), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert!(v["rmse"].as_f64().expect("rmse") > 0.0, "--denoise changed nothing");
    for other in [&["--filter", "box3"][..], &["--filter-target", "image"], &["--edge-aware"]] {
        let (out, err) =
            run(&[&["filter", &p("f.exr"), "-o", &p("bad.exr"), "--denoise"][..], other].concat());
        assert_eq!(out.status.code(), Some(2), "{other:?}: {err}");
        assert!(err.contains("--denoise"), "{err}");
    }
    // A file without the variance layers: the paper's filters still run, atrous says why not.
    let (w, h, channels) = lightsplit::film::read_exr_channels(Path::new(&p("f.exr"))).expect("reads");
    let old: Vec<_> = channels.into_iter().filter(|(name, _)| !name.contains("_variance")).collect();
    lightsplit::film::write_exr_channels(old, w, h, &Default::default(), Path::new(&p("old.exr")))
        .expect("writes");
    let (out, err) = run(&["filter", &p("old.exr"), "-o", &p("box.png"), "--filter", "box3"]);
    assert!(out.status.success(), "{err}");
    let (out, err) = run(&["filter", &p("old.exr"), "-o", &p("atrous.png"), "--filter", "atrous"]);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("variance") && err.lines().count() == 1, "{err}");
    assert!(!Path::new(&p("atrous.png")).exists());
}

/// A scene file's `[filter]` applies unless the command line says otherwise: `--filter` replaces
/// its kernel, `--filter-target none` turns it off.
#[test]
fn the_scene_file_filter_applies_and_the_command_line_overrides_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let base = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sky-sphere.toml"))
        .expect("scene");
    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        format!("{base}\n[filter]\nkernel = [1, 2, 1, 2, 4, 2, 1, 2, 1]\nedge_aware = true\n"),
    )
    .expect("write");
    let scene = scene.to_string_lossy().into_owned();
    let p = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let render = |out: &str, extra: &[&str]| {
        let path = p(out);
        let args = [
            &["render", &scene, "-o", &path, "--json"][..],
            &["--width", "32", "--height", "24", "--spp", "4"],
            extra,
        ]
        .concat();
        let out = lightsplit(&args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_slice::<serde_json::Value>(&out.stdout).expect("json")
    };
    let layers = |f: &str| {
        let (_, _, channels) = lightsplit::film::read_exr_channels(Path::new(&p(f))).expect("reads");
        channels.into_iter().collect::<std::collections::HashMap<_, _>>()
    };
    let v = render("scene.exr", &[]);
    assert_eq!(
        (v["filter"].as_str(), v["filter_target"].as_str(), v["edge_aware"].as_bool()),
        (Some("weighted3"), Some("indirect"), Some(true))
    );
    let scene_layers = layers("scene.exr");
    assert!(scene_layers.contains_key("indirect_filtered.R"));
    // The same setting from the command line gives the same image.
    render("cli.exr", &["--filter", "weighted3", "--edge-aware"]);
    assert_eq!(layers("cli.exr")["R"], scene_layers["R"]);
    // Another kernel replaces the scene's; target none turns filtering off.
    let v = render("box.exr", &["--filter", "box5"]);
    assert_eq!(v["filter"].as_str(), Some("box5"));
    assert_ne!(layers("box.exr")["R"], scene_layers["R"]);
    let v = render("none.exr", &["--filter-target", "none"]);
    assert_eq!(v["filter_target"].as_str(), Some("none"));
    let none = layers("none.exr");
    assert_eq!(none["R"], none["raw.R"]);
}

/// `--layer` writes one layer to a PNG; asking it of an EXR, or the filtered layer without a
/// filter, is a clear error before any rendering (status 2, nothing written).
#[test]
fn layer_picks_what_a_png_shows() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sky-sphere.toml");
    let scene = scene.to_string_lossy().into_owned();
    let p = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let small = ["--width", "24", "--height", "16", "--spp", "2"];
    let run = |out: &str, extra: &[&str]| {
        lightsplit(&[&["render", &scene, "-o", &p(out)][..], &small, extra].concat())
    };
    assert!(run("final.png", &[]).status.success());
    let out = run("indirect.png", &["--layer", "indirect"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let read = |f: &str| std::fs::read(p(f)).expect("png");
    assert_ne!(read("final.png"), read("indirect.png"));
    let out = run("f.png", &["--layer", "indirect-filtered", "--filter", "box3"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for (file, extra) in
        [("x.exr", &["--layer", "direct"][..]), ("y.png", &["--layer", "indirect-filtered"][..])]
    {
        let out = run(file, extra);
        assert_eq!(out.status.code(), Some(2), "{extra:?}");
        assert!(String::from_utf8_lossy(&out.stderr).contains("--layer"));
        assert!(!Path::new(&p(file)).exists());
    }
}

/// `lightsplit info` explains every scene in `scenes/`: its lobes, lights and textures, and
/// what a render of it needs; a missing scene is status 2.
#[test]
fn info_explains_every_scene() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    let mut seen = 0;
    for entry in std::fs::read_dir(dir).expect("scenes/") {
        let path = entry.expect("entry").path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let o = lightsplit(&["info", path.to_str().expect("utf-8")]);
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{}: {}", path.display(), String::from_utf8_lossy(&o.stderr));
        for line in ["material lobes: ", "lights: ", "MIS between light and BSDF", "the component split"] {
            assert!(text.contains(line), "{}: no `{line}` in\n{text}", path.display());
        }
        seen += 1;
    }
    assert!(seen >= 7, "{seen} scenes");
    let o = lightsplit(&["info", "no-such-scene.toml"]);
    assert_eq!(o.status.code(), Some(2));
}

/// `bench-accel` over several scenes measures each (one JSON object a line, a scene each, with the
/// BVH's exact bytes and its tree, and Embree's settings, those a render uses) and draws the
/// scaling plot; a plot that is not a PNG, or `--embree-settings` with several scenes, is
/// refused before anything is measured.
#[test]
fn bench_accel_measures_several_scenes_and_plots_them() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut scenes = Vec::new();
    for resolution in [4, 12] {
        let path = dir.path().join(format!("t{resolution}.toml"));
        let scene = format!(
            "{CAMERA}[[shape]]\ntype = \"terrain\"\nresolution = {resolution}\nsize = 4\nheight = 1\n\
             [[light]]\ntype = \"sun\"\ndirection = [0, 1, 0]\nirradiance = [1, 1, 1]\n"
        );
        std::fs::write(&path, scene).expect("write");
        scenes.push(path.to_str().expect("utf8").to_string());
    }
    let plot = dir.path().join("scaling.png");
    let mut args = vec!["bench-accel"];
    args.extend(scenes.iter().map(String::as_str));
    let tail = ["--rays", "500", "--seconds", "0.001", "--rounds", "1", "--threads", "1", "--json", "--plot"];
    args.extend(tail);
    args.push(plot.to_str().expect("utf8"));
    let out = lightsplit(&args);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let reports: Vec<serde_json::Value> =
        stdout.lines().map(|l| serde_json::from_str(l).expect("a JSON object a line")).collect();
    assert_eq!(reports.len(), 2);
    let triangles: Vec<u64> = reports.iter().map(|r| r["triangles"].as_u64().expect("triangles")).collect();
    assert_eq!(triangles, [2 * 4 * 4, 2 * 12 * 12]);
    for r in &reports {
        // Nodes, leaves and bytes are those of a real tree over the scene's triangles.
        let bytes = r["bvh_bytes"].as_u64().expect("bvh_bytes");
        let leaves = r["bvh_tree"]["leaves"].as_u64().expect("leaves");
        let per_leaf = r["bvh_tree"]["mean_leaf_triangles"].as_f64().expect("fill");
        assert!(leaves > 0 && bytes > 0, "{r}");
        assert!((per_leaf * leaves as f64 - r["triangles"].as_f64().expect("n")).abs() < 1e-6, "{r}");
        assert_eq!(r["rows"].as_array().expect("rows").len(), 6, "{r}");
        // Embree is measured as a render builds it: one shape of triangles, robust at `high`.
        assert_eq!(r["embree_build"], serde_json::json!({"robust": true, "quality": "high"}), "{r}");
    }
    // Two shapes: the two-level build (`low`) a render of them uses.
    let two = dir.path().join("two.toml");
    let body = std::fs::read_to_string(&scenes[0]).expect("read");
    std::fs::write(&two, format!("{body}[[shape]]\ntype = \"sphere\"\ncenter = [0, 3, 0]\nradius = 0.5\n"))
        .expect("write");
    let mut args = vec!["bench-accel", two.to_str().expect("utf8")];
    args.extend(&tail[..tail.len() - 1]);
    let out = lightsplit(&args);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(report["embree_build"], serde_json::json!({"robust": true, "quality": "low"}), "{report}");
    let png = image::open(&plot).expect("the plot is a PNG");
    assert!(png.width() > 100 && png.height() > 100);

    // `--isa` picks the BVH's kernels; the portable ones run on every CPU.
    let mut args = vec!["bench-accel", scenes[0].as_str(), "--isa", "portable"];
    args.extend(&tail[..tail.len() - 1]);
    let out = lightsplit(&args);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(report["bvh_isa"], "portable", "{report}");

    for bad in [
        vec!["bench-accel", scenes[0].as_str(), "--plot", "out.jpg"],
        vec!["bench-accel", scenes[0].as_str(), scenes[1].as_str(), "--embree-settings"],
        vec!["bench-accel", scenes[0].as_str(), "--isa", "sse9"],
    ] {
        let out = lightsplit(&bad);
        assert_eq!(out.status.code(), Some(2), "{bad:?}: {}", String::from_utf8_lossy(&out.stderr));
    }
}
