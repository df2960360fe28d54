//! Rendering on many machines: parts of a render merge to the whole render (up to the order of
//! float sums), filtering after the merge filters the whole, bad sets of parts are refused, a
//! checkpoint resumes to the uninterrupted image, and a stopped render keeps its work.

use std::ffi::OsStr;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};

use glam::Vec3;
use lightsplit::film::Film;
use lightsplit::film::Sums;
use lightsplit::filter::{composite, EdgeStops, Method, Target};
use lightsplit::render::{render_controlled, Control, Part, RenderOptions};
use lightsplit::scene::{self, Scene};

use crate::common::lightsplit as run;

fn cornell() -> Scene {
    scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml")).expect("loads")
}

fn options(scene: &Scene, spp: u32) -> RenderOptions {
    let mut o = RenderOptions::from_scene(scene);
    (o.width, o.height, o.spp, o.seed) = (24, 20, spp, 7);
    o
}

/// The sums of a render of `part`.
fn sums(scene: &Scene, options: &RenderOptions, part: Part) -> Sums {
    let options = RenderOptions { part, ..options.clone() };
    let control = Control { keep_sums: true, ..Control::progress(&|_| {}) };
    render_controlled(scene, &options, control).expect("renders").sums.expect("sums kept")
}

/// gamma(n) = n u / (1 - n u), u the unit roundoff of f32: a bound on the relative error of n
/// roundings.
fn gamma(n: u32) -> f32 {
    let u = f32::EPSILON / 2.0;
    n as f32 * u / (1.0 - n as f32 * u)
}

/// Every sum of `a` and `b` agrees within `bound` times the magnitude it was summed from: the
/// value itself for sums of values that are never negative (light, albedo, depth, squares), the
/// sample count for sums of unit normals. Objects and counts are equal.
fn same_sums(a: &Sums, b: &Sums, bound: f32, what: &str) {
    assert_eq!(a.samples, b.samples, "{what}: sample counts");
    let (fa, fb) = (&a.film, &b.film);
    let close = |x: f32, y: f32, scale: f32, layer: &str, i: usize| {
        assert!(
            (x - y).abs() <= bound * scale + f32::MIN_POSITIVE,
            "{what}: {layer} pixel {i}: {x} against {y}"
        );
    };
    let rgb = |x: &lightsplit::film::Image, y: &lightsplit::film::Image, layer: &str, unit: bool| {
        assert_eq!(x.pixels.len(), y.pixels.len(), "{what}: {layer}");
        for (i, (p, q)) in x.pixels.iter().zip(&y.pixels).enumerate() {
            for c in 0..3 {
                let scale = if unit { a.samples[i] as f32 } else { p[c].abs().max(q[c].abs()) };
                close(p[c], q[c], scale, layer, i);
            }
        }
    };
    rgb(&fa.raw, &fb.raw, "raw", false);
    for (c, (x, y)) in fa.components.iter().zip(&fb.components).enumerate() {
        rgb(x, y, &format!("component {c}"), false);
    }
    rgb(&fa.albedo, &fb.albedo, "albedo", false);
    rgb(&fa.normal, &fb.normal, "normal", true);
    let scalars = |x: &Vec<f32>, y: &Vec<f32>, layer: &str| {
        assert_eq!(x.len(), y.len(), "{what}: {layer}");
        for (i, (p, q)) in x.iter().zip(y).enumerate() {
            close(*p, *q, p.abs().max(q.abs()), layer, i);
        }
    };
    scalars(&fa.depth, &fb.depth, "depth");
    assert!(!a.squares.is_empty() && !b.squares.is_empty(), "{what}: sums of squares");
    for (k, (x, y)) in a.squares.layers().zip(b.squares.layers()).enumerate() {
        assert_eq!(x.len(), y.len(), "{what}: squares {k}");
        for (i, (p, q)) in x.iter().zip(y).enumerate() {
            let scale = p.abs().max(q.abs());
            assert!((p - q).abs() <= bound as f64 * scale, "{what}: squares {k} pixel {i}: {p} against {q}");
        }
    }
    assert_eq!(fa.object, fb.object, "{what}: the object of sample 0");
    assert_eq!(fa.coverage, fb.coverage, "{what}: samples that saw it");
    assert_eq!(fa.alpha, fb.alpha, "{what}: samples that hit a surface");
}

/// Parts 0..N of a render, added up, equal the whole render's sums for N = 1, 2, 3 and 7 (spp
/// 14: parts of 14, 7, 4 or 5, and 2 samples), with both samplers, within the rounding of float
/// sums in another order: the whole adds `spp` values one by one in f32, the merge adds each
/// part's sums and then the N part sums, so both are within gamma(spp + N) of the exact sum of
/// the same nonnegative values, and within 2 gamma(spp + N) of each other (the squares, summed
/// in f64, much closer). The part files hold the sums bit for bit.
#[test]
fn merged_parts_equal_the_whole_render() {
    let scene = cornell();
    let dir = tempfile::tempdir().expect("tempdir");
    for sampler in [
        lightsplit::render::sampler::SamplerKind::Sobol,
        lightsplit::render::sampler::SamplerKind::Independent,
    ] {
        let spp = 14;
        let options = RenderOptions { sampler, ..options(&scene, spp) };
        let whole = sums(&scene, &options, Part::default());
        assert!(whole.film.has_split() && whole.film.has_guides());
        for n in [1u32, 2, 3, 7] {
            let mut merged: Option<Sums> = None;
            let mut named = Vec::new();
            for i in 0..n {
                let part = Part { index: i, count: n };
                let s = sums(&scene, &options, part);
                let expect = part.samples(spp).len() as u32;
                assert!(s.samples.iter().all(|&k| k == expect), "part {part} takes {expect} samples a pixel");
                let path = dir.path().join(format!("p{i}.exr"));
                let header = lightsplit::part::Header {
                    key: "k".into(),
                    part,
                    spp,
                    adaptive: None,
                    complete: true,
                    meta: lightsplit::film::Metadata::default(),
                };
                lightsplit::part::write(&path, &s, &header).expect("part file");
                let (back_header, back) = lightsplit::part::read(&path).expect("reads");
                assert_eq!(back_header.part, part);
                assert_eq!(back, s, "a part file holds its sums bit for bit");
                named.push(lightsplit::part::Named { path, header: back_header, held: None });
                match &mut merged {
                    None => merged = Some(s),
                    Some(m) => m.add(&s).expect("adds"),
                }
            }
            let merged = merged.expect("parts");
            let what = format!("{sampler:?}, {n} parts");
            same_sums(&merged, &whole, 2.0 * gamma(2 * spp + 2 * n + 2), &what);
            // Through the files, in another order: the same sums exactly.
            named.reverse();
            lightsplit::part::check(&named, false).expect("a whole set");
            let from_files = lightsplit::part::merge(&named, &|| {}).expect("merges");
            assert_eq!(from_files, merged, "{what}: merged from files");
        }
    }
}

/// Parts rendered with adaptive sampling take different counts per pixel; the merge is the
/// sample-weighted mean of the parts' means.
#[test]
fn adaptive_parts_merge_to_the_sample_weighted_mean() {
    let scene = cornell();
    let options = RenderOptions { adaptive: Some(0.2), ..options(&scene, 128) };
    let parts: Vec<Sums> = (0..2).map(|i| sums(&scene, &options, Part { index: i, count: 2 })).collect();
    for p in &parts {
        let (lo, hi) = (p.samples.iter().min().copied(), p.samples.iter().max().copied());
        assert!(lo < hi, "adaptive sampling stopped some pixels early ({lo:?} to {hi:?})");
    }
    let means: Vec<Film> = parts.iter().map(|p| p.clone().into_means()).collect();
    let mut merged = parts[0].clone();
    merged.add(&parts[1]).expect("adds");
    let counts = merged.samples.clone();
    let film = merged.into_means();
    for (i, &count) in counts.iter().enumerate() {
        let (na, nb) = (parts[0].samples[i] as f32, parts[1].samples[i] as f32);
        let expect = (means[0].raw.pixels[i] * na + means[1].raw.pixels[i] * nb) / (na + nb);
        let got = film.raw.pixels[i];
        assert_eq!(count, parts[0].samples[i] + parts[1].samples[i]);
        assert!(
            (got - expect).abs().max_element() <= 1e-5 * expect.abs().max_element() + 1e-30,
            "pixel {i}: {got} against {expect}"
        );
    }
}

/// The filter runs once, after the merge: filtering the merged film (box3 on indirect with the
/// edge stops, and the median) gives the filtered whole render, up to the merge's rounding.
#[test]
fn filtering_after_the_merge_equals_filtering_the_whole() {
    let scene = cornell();
    let options = options(&scene, 16);
    let whole = sums(&scene, &options, Part::default()).into_means();
    let mut merged = sums(&scene, &options, Part { index: 0, count: 3 });
    for i in 1..3 {
        merged.add(&sums(&scene, &options, Part { index: i, count: 3 })).expect("adds");
    }
    let merged = merged.into_means();
    let stops = EdgeStops { object: true, normal_degrees: Some(30.0), depth_relative: Some(0.1), pure: true };
    for kernel in ["box3", "median3"] {
        let k = Method::parse(kernel).expect("kernel");
        let (a, _) = composite(&merged, Some(&k), Target::Indirect, &stops);
        let (b, _) = composite(&whole, Some(&k), Target::Indirect, &stops);
        let worst = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .map(|(p, q)| ((*p - *q).abs() / q.abs().max(Vec3::splat(1e-3))).max_element())
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-4, "{kernel}: merged and filtered against whole and filtered: {worst}");
    }
}

/// A render stopped after some passes and resumed from its sums gives the uninterrupted image,
/// bit for bit.
#[test]
fn a_resumed_render_gives_the_uninterrupted_image() {
    let scene = cornell();
    let options = options(&scene, 40);
    let full = sums(&scene, &options, Part::default());
    let stop = AtomicBool::new(false);
    // Stop once some samples are done: the render ends after the pass under way.
    let progress = |_n: u64| stop.store(true, Ordering::SeqCst);
    let first =
        render_controlled(&scene, &options, Control { stop: Some(&stop), ..Control::progress(&progress) })
            .expect("renders");
    assert!(first.stats.interrupted);
    let partial = first.sums.expect("an interrupted render keeps its sums");
    let taken = partial.samples[0];
    assert!(taken > 0 && taken < 40 && partial.samples.iter().all(|&n| n == taken), "{taken}");
    let control = Control { resume: Some(partial), keep_sums: true, ..Control::progress(&|_| {}) };
    let resumed = render_controlled(&scene, &options, control).expect("resumes");
    assert!(!resumed.stats.interrupted);
    assert_eq!(resumed.sums.expect("sums"), full, "resumed after {taken} samples");
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

const SCENE: &str = "[camera]\nposition = [0, 1, 4]\nlook_at = [0, 0.5, 0]\nfov = 40\n\
    [film]\nwidth = 16\nheight = 12\nspp = 12\n\
    [[material]]\nname = \"white\"\ntype = \"diffuse\"\ncolor = [0.7, 0.7, 0.7]\n\
    [[shape]]\ntype = \"quad\"\nmaterial = \"white\"\nvertices = [[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]]\n\
    [[shape]]\ntype = \"sphere\"\nmaterial = \"white\"\ncenter = [0, 0.5, 0]\nradius = 0.5\n\
    [[light]]\ntype = \"sun\"\ndirection = [0.3, 1, 0.2]\nirradiance = [2, 2, 2]\n\
    [[light]]\ntype = \"sky\"\nradiance = [0.3, 0.3, 0.4]\n";

/// [`SCENE`] written into `dir`; its path.
fn scene_in(dir: &Path) -> String {
    let scene = dir.join("s.toml");
    std::fs::write(&scene, SCENE).expect("write");
    scene.to_string_lossy().into_owned()
}

/// From the command line: parts of another render, a part named twice and a missing part are
/// refused with status 2, naming them; --allow-missing merges what there is; a filtered part, a
/// part that does not exist and `auto` without a scheduler are refused; `auto` reads Slurm's
/// array variables.
#[test]
fn bad_sets_of_parts_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let s = &scene_in(d);
    let path = |name: &str| d.join(name).to_string_lossy().into_owned();
    for i in 0..3 {
        let o = run(&["render", s, "--part", &format!("{i}/3"), "-o", &path(&format!("p{i}.exr"))]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let o = run(&["render", s, "--part", "1/3", "--seed", "9", "-o", &path("other.exr")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let merge = |parts: &[&str], extra: &[&str]| {
        let mut args = vec!["merge".to_string()];
        args.extend(parts.iter().map(|p| path(p)));
        args.extend(["-o".to_string(), path("m.exr")]);
        args.extend(extra.iter().map(|e| e.to_string()));
        run(&args.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let o = merge(&["p0.exr", "other.exr", "p2.exr"], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("other.exr") && stderr(&o).contains("different renders"), "{}", stderr(&o));
    let o = merge(&["p0.exr", "p1.exr", "p1.exr", "p2.exr"], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("both part 1/3"), "{}", stderr(&o));
    let o = merge(&["p0.exr", "p2.exr"], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("missing part 1/3"), "{}", stderr(&o));
    assert!(!d.join("m.exr").exists(), "nothing is written for a refused merge");
    let o = merge(&["p0.exr", "p2.exr"], &["--allow-missing", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(json["missing"], serde_json::json!([1]));
    assert_eq!(json["samples_per_pixel_min"], 8);
    let o = merge(&["p2.exr", "p0.exr", "p1.exr"], &["--filter", "box3", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(json["samples_per_pixel_min"], 12);

    let o = run(&["render", s, "--part", "0/2", "--filter", "box3", "-o", &path("f.exr")]);
    assert_eq!(o.status.code(), Some(2), "a filtered part: {}", stderr(&o));
    let o = run(&["render", s, "--part", "0/2", "-o", &path("f.png")]);
    assert_eq!(o.status.code(), Some(2), "a part as PNG: {}", stderr(&o));
    for bad in ["3/3", "1/0", "x", "-1/2"] {
        let o = run(&["render", s, "--part", bad, "-o", &path("f.exr")]);
        assert_eq!(o.status.code(), Some(2), "--part {bad}: {}", stderr(&o));
    }
    let auto = |vars: &[(&str, &str)]| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_lightsplit"));
        c.args(["render", s, "--part", "auto", "--json", "-o", &path("a.exr")]);
        for v in [
            "SLURM_ARRAY_TASK_ID",
            "SLURM_ARRAY_TASK_MIN",
            "SLURM_ARRAY_TASK_COUNT",
            "JOB_COMPLETION_INDEX",
            "LIGHTSPLIT_PART_COUNT",
        ] {
            c.env_remove(v);
        }
        c.envs(vars.iter().copied());
        c.output().expect("runs")
    };
    let o = auto(&[]);
    assert_eq!(o.status.code(), Some(2), "auto without a scheduler: {}", stderr(&o));
    let o =
        auto(&[("SLURM_ARRAY_TASK_ID", "3"), ("SLURM_ARRAY_TASK_MIN", "1"), ("SLURM_ARRAY_TASK_COUNT", "4")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(json["part"], "2/4", "task 3 of an array 1-4");
    let o = auto(&[("JOB_COMPLETION_INDEX", "1"), ("LIGHTSPLIT_PART_COUNT", "3")]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(json["part"], "1/3", "{}", stderr(&o));
}

/// `--time-limit` ends a render early with its part file; `--resume` of it gives the image of an
/// uninterrupted render exactly, and removes nothing it did not write.
#[test]
fn a_time_limited_render_resumes_to_the_whole_image() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let s = &scene_in(d);
    let path = |name: &str| d.join(name).to_string_lossy().into_owned();
    let o = run(&["render", s, "--spp", "400", "-o", &path("whole.exr")]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A limit far below one pass's time: the first pass runs, then the render ends.
    let o = run(&["render", s, "--spp", "400", "--time-limit", "0.000001", "--json", "-o", &path("cut.exr")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(json["interrupted"], true);
    assert_eq!(json["samples_per_pixel_max"], lightsplit::render::PASS, "one pass");
    assert!(d.join("cut.part.exr").exists(), "the part file of what was rendered");
    assert!(lightsplit::film::read_image(&d.join("cut.exr")).is_ok(), "the image of what was rendered");
    let o =
        run(&["render", s, "--spp", "400", "--resume", &path("cut.part.exr"), "-o", &path("resumed.exr")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let a = lightsplit::film::read_image(&d.join("resumed.exr")).expect("reads");
    let b = lightsplit::film::read_image(&d.join("whole.exr")).expect("reads");
    assert_eq!(a.pixels, b.pixels, "resumed and whole renders differ");
    // A part stopped early is refused by a merge, unless it merges what there is.
    let o = run(&["merge", &path("cut.part.exr"), "-o", &path("m.exr")]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("stopped before its samples were all taken"), "{}", stderr(&o));
    let o = run(&["merge", &path("cut.part.exr"), "--allow-missing", "-o", &path("m.exr")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let merged = lightsplit::film::read_image(&d.join("m.exr")).expect("reads");
    let cut = lightsplit::film::read_image(&d.join("cut.exr")).expect("reads");
    assert_eq!(merged.pixels, cut.pixels, "the merge of a stopped render's part is its image");
    // Another scene's checkpoint, or another spp, is refused.
    let o = run(&["render", s, "--spp", "300", "--resume", &path("cut.part.exr"), "-o", &path("x.exr")]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// SIGTERM and SIGINT during a render: it finishes the pass under way, writes the image of the
/// samples taken and its part file, and exits with 128 + the signal. Judged by the files: the
/// part file holds a whole number of passes, fewer than the spp, and the image is their mean.
#[test]
fn a_stopped_render_keeps_its_work() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let scene = d.join("s.toml");
    std::fs::write(&scene, SCENE).expect("write");
    use rustix::process::{Pid, Signal};
    for (sig, number) in [(Signal::TERM, 15), (Signal::INT, 2)] {
        let out = d.join(format!("o{number}.exr"));
        let part = d.join(format!("o{number}.part.exr"));
        // A checkpoint after the first pass says the render is under way.
        let mut child = Command::new(env!("CARGO_BIN_EXE_lightsplit"))
            .args([OsStr::new("render"), scene.as_os_str(), OsStr::new("-o"), out.as_os_str()])
            .args(["--width", "160", "--height", "120", "--spp", "100000", "--checkpoint", "0.001"])
            .stderr(Stdio::null())
            .spawn()
            .expect("spawns");
        let start = std::time::Instant::now();
        while !part.exists() && start.elapsed() < std::time::Duration::from_secs(120) {
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        assert!(part.exists(), "no checkpoint appeared");
        rustix::process::kill_process(Pid::from_child(&child), sig).expect("the signal is sent");
        let status = child.wait().expect("waits");
        assert_eq!(status.code(), Some(128 + number), "signal {number}");
        let (header, sums) = lightsplit::part::read(&part).expect("a valid part file");
        assert_eq!(header.spp, 100000);
        let n = sums.samples[0];
        assert!(n > 0 && n < 100000 && n % lightsplit::render::PASS == 0, "{n} samples");
        assert!(sums.samples.iter().all(|&k| k == n), "every pixel has the passes done");
        let image = lightsplit::film::read_image(&out).expect("a valid image");
        assert_eq!(image.pixels, sums.into_means().raw.pixels, "the image is the mean of the samples taken");
    }
}

/// The Kubernetes manifest (which cannot run here) parses, and its numbers agree: an Indexed Job
/// whose completions are the part count its pods are given, each rendering `--part auto`, and a
/// merge Job that waits for as many finished parts and merges them.
#[test]
fn the_kubernetes_manifest_is_an_indexed_job_and_a_merge() {
    use serde::Deserialize;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("deploy/k8s/render-job.yaml");
    let text = std::fs::read_to_string(&path).expect("deploy/k8s/render-job.yaml");
    let docs: Vec<serde_yaml::Value> = serde_yaml::Deserializer::from_str(&text)
        .map(|d| serde_yaml::Value::deserialize(d).expect("YAML"))
        .collect();
    assert_eq!(docs.len(), 2, "two Jobs");
    let env = |container: &serde_yaml::Value, name: &str| -> Option<String> {
        container["env"]
            .as_sequence()?
            .iter()
            .find(|e| e["name"] == name)
            .and_then(|e| e["value"].as_str().map(String::from))
    };
    let (parts, merge) = (&docs[0], &docs[1]);
    for d in &docs {
        assert_eq!(d["apiVersion"], "batch/v1");
        assert_eq!(d["kind"], "Job");
    }
    assert_eq!(parts["spec"]["completionMode"], "Indexed");
    let completions = parts["spec"]["completions"].as_u64().expect("completions");
    let render = &parts["spec"]["template"]["spec"]["containers"][0];
    assert_eq!(env(render, "LIGHTSPLIT_PART_COUNT"), Some(completions.to_string()));
    let script = render["args"][0].as_str().expect("the part's script");
    assert!(script.contains("lightsplit render") && script.contains("--part auto"), "{script}");
    assert!(script.contains("${JOB_COMPLETION_INDEX}"), "each part its own file: {script}");
    let wait = &merge["spec"]["template"]["spec"]["initContainers"][0];
    assert_eq!(env(wait, "PARTS"), Some(completions.to_string()));
    let merging = merge["spec"]["template"]["spec"]["containers"][0]["args"][0].as_str().expect("merge");
    assert!(merging.contains("lightsplit merge"), "{merging}");
    let claim = |d: &serde_yaml::Value| {
        d["spec"]["template"]["spec"]["volumes"][0]["persistentVolumeClaim"]["claimName"].clone()
    };
    assert_eq!(claim(parts), claim(merge), "one shared volume");
}

/// The Cornell box with Mitsuba's default filter, a Gaussian of stddev 0.5, splatted.
fn cornell_gaussian() -> Scene {
    let mut scene = cornell();
    scene.film.pixel_filter = scene::PixelFilter::Gaussian { stddev: 0.5 };
    scene
}

/// A splatted filter keeps every promise of the sums: parts merge to the whole (sums and
/// weights, within the rounding of float sums in another order: each pixel's sums gather up to
/// 25 splats a sample), through their files bit for bit; a resumed render gives the
/// uninterrupted sums bit for bit; and one thread gives what two give.
#[test]
fn splatted_filters_merge_resume_and_stay_deterministic() {
    let scene = cornell_gaussian();
    let options = options(&scene, 12);
    let whole = sums(&scene, &options, Part::default());
    assert_eq!(whole.weights.len(), whole.samples.len(), "splatted: weights kept");
    let dir = tempfile::tempdir().expect("tempdir");
    let mut merged: Option<Sums> = None;
    for i in 0..3 {
        let part = Part { index: i, count: 3 };
        let s = sums(&scene, &options, part);
        let path = dir.path().join(format!("g{i}.exr"));
        let header = lightsplit::part::Header {
            key: "k".into(),
            part,
            spp: 12,
            adaptive: None,
            complete: true,
            meta: lightsplit::film::Metadata::default(),
        };
        lightsplit::part::write(&path, &s, &header).expect("part file");
        let (_, back) = lightsplit::part::read(&path).expect("reads");
        assert_eq!(back, s, "a part file holds splatted sums and weights bit for bit");
        match &mut merged {
            None => merged = Some(s),
            Some(m) => m.add(&s).expect("adds"),
        }
    }
    let merged = merged.expect("parts");
    same_sums(&merged, &whole, 2.0 * gamma(25 * 12 + 8), "gaussian, 3 parts");
    for (i, (a, b)) in merged.weights.iter().zip(&whole.weights).enumerate() {
        assert!(
            (a - b).abs() <= 2.0 * gamma(25 * 12 + 8) * a.max(*b),
            "weight of pixel {i}: {a} against {b}"
        );
    }
    let full_image = whole.clone().into_means().raw;
    assert!(full_image.mean().x > 0.0);

    let options = self::options(&scene, 40);
    let full = sums(&scene, &options, Part::default());
    let stop = AtomicBool::new(false);
    let progress = |_n: u64| stop.store(true, Ordering::SeqCst);
    let first =
        render_controlled(&scene, &options, Control { stop: Some(&stop), ..Control::progress(&progress) })
            .expect("renders");
    let partial = first.sums.expect("an interrupted render keeps its sums");
    let control = Control { resume: Some(partial), keep_sums: true, ..Control::progress(&|_| {}) };
    let resumed = render_controlled(&scene, &options, control).expect("resumes");
    assert_eq!(resumed.sums.expect("sums"), full, "a splatted render resumes bit for bit");

    let on = |threads: usize| {
        let o = RenderOptions { threads: Some(threads), ..self::options(&scene, 8) };
        sums(&scene, &o, Part::default())
    };
    assert_eq!(on(1), on(2), "the same splats on one thread and on two");
}

/// A guided render keeps the invariants of parts and resumes: the guide it trains first is
/// the same in every part and in a resumed render (its training is a pure function of the
/// scene and the options), so 2 and 3 parts merge to the whole and a render stopped after a
/// pass resumes to the uninterrupted one, bit for bit.
#[test]
fn a_guided_render_merges_and_resumes_exactly() {
    let scene = cornell();
    for guiding in [lightsplit::scene::Guiding::All, lightsplit::scene::Guiding::Indirect] {
        let options = RenderOptions { guiding, ..options(&scene, 24) };
        let whole = sums(&scene, &options, Part::default());
        for n in [2u32, 3] {
            let mut merged: Option<Sums> = None;
            for i in 0..n {
                let s = sums(&scene, &options, Part { index: i, count: n });
                match &mut merged {
                    None => merged = Some(s),
                    Some(m) => m.add(&s).expect("adds"),
                }
            }
            same_sums(&merged.expect("parts"), &whole, 2.0 * gamma(2 * 24 + 2 * n + 2), "guided parts");
        }
        let stop = AtomicBool::new(false);
        let progress = |_n: u64| stop.store(true, Ordering::SeqCst);
        let first = render_controlled(
            &scene,
            &options,
            Control { stop: Some(&stop), ..Control::progress(&progress) },
        )
        .expect("renders");
        let partial = first.sums.expect("an interrupted render keeps its sums");
        let control = Control { resume: Some(partial), keep_sums: true, ..Control::progress(&|_| {}) };
        let resumed = render_controlled(&scene, &options, control).expect("resumes");
        assert_eq!(resumed.sums.expect("sums"), whole, "{guiding:?}: resumed");
    }
}

/// `--guide FILE` writes the guide a render trains when the file does not exist, and a render
/// that reads it makes the same image; a file that is not a guide is one error, exit 2.
#[test]
fn a_guide_file_is_written_and_read() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let s = &scene_in(d);
    let path = |name: &str| d.join(name).to_string_lossy().into_owned();
    let render = |out: &str, extra: &[&str]| {
        let mut args = vec!["render", s, "--spp", "16", "--guiding", "-o"];
        let out = path(out);
        args.push(&out);
        args.extend_from_slice(extra);
        run(&args)
    };
    let guide = path("scene.guide");
    let o = render("trained.exr", &["--guide", &guide]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("scene.guide").exists(), "the guide is written");
    let o = render("read.exr", &["--guide", &guide]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = render("again.exr", &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let image = |name: &str| lightsplit::film::read_image(&d.join(name)).expect("reads").pixels;
    assert_eq!(image("trained.exr"), image("read.exr"), "the guide read is the guide trained");
    assert_eq!(image("trained.exr"), image("again.exr"), "training is the same every time");
    std::fs::write(d.join("bad.guide"), b"not a guide").expect("writes");
    let o = render("bad.exr", &["--guide", &path("bad.guide")]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("bad.guide") && stderr(&o).contains("not a guide"), "{}", stderr(&o));
    assert!(!d.join("bad.exr").exists());
}
