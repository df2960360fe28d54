//! A hostile user's findings on parts, checkpoints, the EXR reader and the commands that read
//! files (`merge`, `--resume`, `filter`, `compare`, `converge`): one test per finding, each
//! named in its doc comment with what happened before. Each failed before its fix.

use std::ffi::OsStr;
use std::os::unix::ffi::OsStrExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use exr::image::FlatSamples;
use exr::meta::attribute::{AttributeValue, Text};
use exr::meta::header::LayerAttributes;

use crate::common::pfm;

/// A sphere under a point light.
const SCENE: &str = "[camera]\nposition = [0, 1, -5]\nlook_at = [0, 1, 0]\n\
[film]\nwidth = 8\nheight = 8\nspp = 1\n\
[[light]]\ntype = \"point\"\nposition = [0, 3, -1]\nintensity = [5, 5, 5]\n\
[[shape]]\ntype = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1\n";

/// What every render of these tests adds, unless it names its own spp.
const SMALL: [&str; 6] = ["--width", "32", "--height", "32", "--threads", "1"];

/// The address space (KiB) the memory bombs run in: a tiny render needs under 500 MB of it
/// (Embree and rayon reserve some), and each bomb asked for 4 GB or more before its fix, which
/// this limit turns into a quick abort instead of a machine swapping.
const ADDRESS_SPACE_KIB: u64 = 1 << 20;

/// The scheduler variables `--part auto` reads, removed from every run so the tests' own
/// environment (a CI job on Slurm, say) cannot change them.
const SCHEDULER: [&str; 5] = [
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_MIN",
    "SLURM_ARRAY_TASK_COUNT",
    "JOB_COMPLETION_INDEX",
    "LIGHTSPLIT_PART_COUNT",
];

fn lightsplit(dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_lightsplit"));
    c.current_dir(dir).stdin(Stdio::null());
    for v in SCHEDULER {
        c.env_remove(v);
    }
    c
}

/// Runs `lightsplit ARGS` in `dir`.
fn run<S: AsRef<OsStr>>(dir: &Path, args: &[S]) -> Output {
    lightsplit(dir).args(args).output().expect("the binary runs")
}

/// Runs `lightsplit ARGS` in `dir` with the variables `vars` set.
fn run_with(dir: &Path, vars: &[(&str, &OsStr)], args: &[&str]) -> Output {
    lightsplit(dir).envs(vars.iter().copied()).args(args).output().expect("the binary runs")
}

/// Runs `lightsplit ARGS` in `dir` within [`ADDRESS_SPACE_KIB`] of address space.
fn run_limited(dir: &Path, args: &[&str]) -> Output {
    Command::new("sh")
        .current_dir(dir)
        .arg("-c")
        .arg(format!("ulimit -v {ADDRESS_SPACE_KIB}; exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_lightsplit"))
        .args(args)
        .output()
        .expect("sh runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `args` with [`SMALL`] after them.
fn small<'a>(args: &[&'a str]) -> Vec<&'a str> {
    args.iter().copied().chain(SMALL).collect()
}

/// Asserts that `o` is one clear refusal: status 2, no panic, a message holding each of `want`.
#[track_caller]
fn refused(o: &Output, want: &[&str], what: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{what}: {err}");
    assert!(!err.contains("panicked"), "{what}: {err}");
    for w in want {
        assert!(err.contains(w), "{what}: no `{w}` in: {err}");
    }
}

/// A directory holding [`SCENE`] as `s.toml`.
fn scene_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("s.toml"), SCENE).expect("write");
    dir
}

/// Renders `s.toml` in `dir` with `args` (and [`SMALL`]), expecting success.
#[track_caller]
fn render(dir: &Path, args: &[&str]) {
    let o = run(dir, &small(&[&["render", "s.toml"], args].concat()));
    assert_eq!(o.status.code(), Some(0), "render {args:?}: {}", stderr(&o));
}

/// Rewrites the EXR at `path`: `channel` sees each channel's name and samples, `attributes`
/// the header's own attributes.
fn edit_exr(
    path: &Path,
    mut channel: impl FnMut(&str, &mut FlatSamples),
    attributes: impl Fn(&mut LayerAttributes),
) {
    use exr::prelude::*;
    let mut image = read_all_flat_layers_from_file(path).expect("an EXR");
    for layer in image.layer_data.iter_mut() {
        attributes(&mut layer.attributes);
        for c in layer.channel_data.list.iter_mut() {
            channel(&c.name.to_string(), &mut c.sample_data);
        }
    }
    image.write().to_file(path).expect("rewritten");
}

/// Sets every value of the float channel `name` of the EXR at `path` (pixel `at` alone, when
/// given) to `value`.
fn set_channel(path: &Path, name: &str, at: Option<usize>, value: f32) {
    let mut found = false;
    edit_exr(
        path,
        |n, samples| {
            if n == name {
                let FlatSamples::F32(v) = samples else { panic!("{name} is not a float channel") };
                match at {
                    Some(i) => v[i] = value,
                    None => v.iter_mut().for_each(|x| *x = value),
                }
                found = true;
            }
        },
        |_| {},
    );
    assert!(found, "no channel {name}");
}

/// Sets the text attribute `name` of the EXR at `path` to `value`.
fn set_attribute(path: &Path, name: &str, value: &str) {
    edit_exr(
        path,
        |_, _| {},
        |a| {
            a.other.insert(Text::from(name), AttributeValue::Text(Text::from(value)));
        },
    );
}

/// An EXR attribute: its name, type, size and value.
fn attribute(name: &str, kind: &str, value: &[u8]) -> Vec<u8> {
    let mut out = [name.as_bytes(), b"\0", kind.as_bytes(), b"\0"].concat();
    out.extend((value.len() as i32).to_le_bytes());
    out.extend(value);
    out
}

/// A tiled EXR that declares one `w` x `h` tile of half RGB and its offset table, but holds no
/// pixels: a few hundred bytes (349 with no `text` attributes) that claim gigabytes.
fn tiled_exr_without_pixels(w: u32, h: u32, text: &[(&str, &str)]) -> Vec<u8> {
    let i32s = |v: &[i32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let mut channels = Vec::new();
    for c in ["B", "G", "R"] {
        channels.extend([c.as_bytes(), b"\0"].concat());
        channels.extend(i32s(&[1])); // half
        channels.extend([0, 0, 0, 0]); // linear, reserved
        channels.extend(i32s(&[1, 1])); // sampling
    }
    channels.push(0);
    let window = i32s(&[0, 0, w as i32 - 1, h as i32 - 1]);
    let mut tiles = [w.to_le_bytes(), h.to_le_bytes()].concat();
    tiles.push(0); // one level
    let mut out = vec![0x76, 0x2f, 0x31, 0x01];
    out.extend((2u32 | 0x200).to_le_bytes()); // version 2, tiled
    for a in [
        attribute("channels", "chlist", &channels),
        attribute("compression", "compression", &[0]),
        attribute("dataWindow", "box2i", &window),
        attribute("displayWindow", "box2i", &window),
        attribute("lineOrder", "lineOrder", &[0]),
        attribute("pixelAspectRatio", "float", &1f32.to_le_bytes()),
        attribute("screenWindowCenter", "v2f", &[0; 8]),
        attribute("screenWindowWidth", "float", &1f32.to_le_bytes()),
        attribute("tiles", "tiledesc", &tiles),
    ] {
        out.extend(a);
    }
    for (name, value) in text {
        out.extend(attribute(name, "string", value.as_bytes()));
    }
    out.push(0);
    // The offset of the one tile: just past this table, where the file ends.
    let end = out.len() as u64 + 8;
    out.extend(end.to_le_bytes());
    out
}

/// H4: a 349-byte tiled EXR declaring one 65536x32768 tile (no pixels) as an environment map
/// allocated 12 GB and ran 43 s (within this test's address space: status 134); at 2^29 x 2^28
/// it aborted outright; `merge`, `--resume`, `filter`, `compare` and `converge --reference`
/// did the same. The headers are checked before any pixel is decoded: every command refuses
/// it, status 2, naming the file, within 1 GiB of address space.
#[test]
fn h4_an_exr_declaring_gigabytes_is_refused_before_decoding() {
    let dir = scene_dir();
    let d = dir.path();
    let part = [
        ("lightsplit.key", "0"),
        ("lightsplit.part", "0/1"),
        ("lightsplit.spp", "1"),
        ("lightsplit.adaptive", "no"),
        ("lightsplit.complete", "yes"),
    ];
    let bomb = tiled_exr_without_pixels(65536, 32768, &part);
    std::fs::write(d.join("bomb.exr"), &bomb).expect("write");
    assert_eq!(tiled_exr_without_pixels(65536, 32768, &[]).len(), 349);
    std::fs::write(d.join("huge.exr"), tiled_exr_without_pixels(1 << 29, 1 << 28, &[])).expect("write");
    // Within the bounds of size, but 3 GiB of pixels that are not there.
    std::fs::write(d.join("short.exr"), tiled_exr_without_pixels(32768, 16384, &[])).expect("write");
    for map in ["bomb.exr", "huge.exr", "short.exr"] {
        let env = SCENE.replace(
            "[[light]]\ntype = \"point\"",
            &format!("[[light]]\ntype = \"environment\"\nfile = \"{map}\"\n[[light]]\ntype = \"point\""),
        );
        std::fs::write(d.join("env.toml"), env).expect("write");
        let o = run_limited(d, &small(&["render", "env.toml", "--spp", "1", "-o", "e.exr"]));
        refused(&o, &[map, "declares"], map);
    }
    let commands: Vec<Vec<&str>> = vec![
        vec!["merge", "bomb.exr", "-o", "m.exr"],
        small(&["render", "s.toml", "--spp", "1", "--resume", "bomb.exr", "-o", "r.exr"]),
        vec!["filter", "bomb.exr", "-o", "f.exr"],
        vec!["filter", "huge.exr", "-o", "f.exr"],
        vec!["compare", "bomb.exr", "short.exr"],
        small(&[
            "converge",
            "s.toml",
            "--spp",
            "1",
            "--filters",
            "none",
            "--reference",
            "bomb.exr",
            "--out",
            "c",
        ]),
    ];
    for args in commands {
        let o = run_limited(d, &args);
        refused(&o, &["declares", ".exr"], &format!("{args:?}"));
    }
    let written: Vec<_> =
        ["e.exr", "m.exr", "r.exr", "f.exr", "c"].iter().filter(|f| d.join(f).exists()).collect();
    assert!(written.is_empty(), "{written:?}");
}

/// H5 and L7: `--part 0/4294967295 --spp 4` (or `SLURM_ARRAY_TASK_COUNT=4294967295`) rendered a
/// part of 0 samples with status 0, and `merge --allow-missing` of it allocated 68.7 GB and
/// aborted; `--part 5/8 --spp 4` was accepted (half its parts have no samples); a merge of one
/// part of 4096 printed 4095 warning lines. Now at most spp parts (each takes a sample), a part
/// file's header is held to that bound, and a merge names the first few missing parts and counts
/// the rest, on one line.
#[test]
fn h5_l7_a_render_has_at_most_spp_parts_and_a_merge_counts_what_is_missing() {
    let dir = scene_dir();
    let d = dir.path();
    for part in ["0/4294967295", "5/8", "0/5"] {
        let o = run(d, &small(&["render", "s.toml", "--spp", "4", "--part", part, "-o", "p.exr"]));
        refused(&o, &["--part", "at most as many parts as it has samples a pixel (4)"], part);
    }
    let count: &OsStr = OsStr::new("4294967295");
    let vars = [("SLURM_ARRAY_TASK_ID", OsStr::new("0")), ("SLURM_ARRAY_TASK_COUNT", count)];
    let o = run_with(d, &vars, &small(&["render", "s.toml", "--spp", "4", "--part", "auto", "-o", "p.exr"]));
    refused(&o, &["--part auto", "at most as many parts"], "Slurm");
    assert!(!d.join("p.exr").exists(), "a refused part writes nothing");

    // A part file whose header claims billions of parts.
    render(d, &["--spp", "4", "--part", "0/4", "-o", "p.exr"]);
    set_attribute(&d.join("p.exr"), "lightsplit.part", "0/4294967295");
    let o = run_limited(d, &["merge", "p.exr", "--allow-missing", "-o", "m.exr"]);
    refused(&o, &["p.exr", "at most as many parts"], "a forged part count");

    // One part of 4096: the others are named and counted on one line.
    render(d, &["--spp", "4096", "--part", "0/4096", "-o", "q.exr"]);
    let o = run(d, &["merge", "q.exr", "--allow-missing", "--json", "-o", "m.exr"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("parts 1/4096, 2/4096") && err.contains("and 4087 more"), "{err}");
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(json["missing_count"], 4095);
    assert_eq!(json["missing"].as_array().map(Vec::len), Some(8));
    let o = run(d, &["merge", "q.exr", "-o", "m2.exr"]);
    refused(&o, &["missing parts 1/4096", "and 4087 more of 4096"], "without --allow-missing");
}

/// The `*_variance.Y` layers of the EXR at `path`: how many of their values are not finite.
fn nonfinite_variances(path: &Path) -> usize {
    let (_, _, channels) = lightsplit::film::read_exr_channels(path).expect("reads");
    let variances: Vec<_> = channels.iter().filter(|(n, _)| n.ends_with("_variance.Y")).collect();
    assert_eq!(variances.len(), 5, "the variance layers");
    variances.iter().map(|(_, v)| v.iter().filter(|x| !x.is_finite()).count()).sum()
}

/// M1: a point light of 1e30, an environment pixel of 1e30 or an environment `scale` of 1e30
/// rendered with status 0 and infinities in hundreds of pixels of `*_variance.Y` (32-bit sums
/// of squares overflow from 1.8e19), and part files carried them into the merge. The sums of
/// squares are f64 from the sample to the part file; each variance layer is finite.
#[test]
fn m1_bright_lights_give_finite_variances() {
    let dir = scene_dir();
    let d = dir.path();
    std::fs::write(d.join("bright.pfm"), pfm(2, 1, &[1e30; 6])).expect("write");
    std::fs::write(d.join("one.pfm"), pfm(2, 1, &[1.0; 6])).expect("write");
    let environment = |file: &str, scale: &str| {
        SCENE.replace(
            "[[light]]\ntype = \"point\"\nposition = [0, 3, -1]\nintensity = [5, 5, 5]\n",
            &format!("[[light]]\ntype = \"environment\"\nfile = \"{file}\"\nscale = {scale}\n"),
        )
    };
    let scenes = [
        ("point", SCENE.replace("intensity = [5, 5, 5]", "intensity = [1e30, 1e30, 1e30]")),
        ("pixel", environment("bright.pfm", "1")),
        ("scale", environment("one.pfm", "1e30")),
    ];
    for (name, text) in scenes {
        std::fs::write(d.join("b.toml"), text).expect("write");
        let o = run(d, &small(&["render", "b.toml", "--spp", "4", "-o", "b.exr"]));
        assert_eq!(o.status.code(), Some(0), "{name}: {}", stderr(&o));
        assert_eq!(nonfinite_variances(&d.join("b.exr")), 0, "{name}: the render's variances");
        for i in 0..2 {
            let part = format!("--part={i}/2");
            let o = run(d, &small(&["render", "b.toml", "--spp", "4", &part, "-o", &format!("p{i}.exr")]));
            assert_eq!(o.status.code(), Some(0), "{name}: {}", stderr(&o));
        }
        let o = run(d, &["merge", "p0.exr", "p1.exr", "-o", "m.exr"]);
        assert_eq!(o.status.code(), Some(0), "{name}: {}", stderr(&o));
        assert_eq!(nonfinite_variances(&d.join("m.exr")), 0, "{name}: the merge's variances");
        // The spread of samples of 1e30 is beyond 32 bits: such a variance is the largest float.
        let (_, _, channels) = lightsplit::film::read_exr_channels(&d.join("m.exr")).expect("reads");
        let variance = channels.iter().find(|(n, _)| n == "raw_variance.Y").expect("variance");
        assert!(variance.1.contains(&f32::MAX), "{name}: a variance beyond 32 bits, saturated");
    }
}

/// Two complete parts, `p0.exr` and `p1.exr`, of a render of `s.toml` at 4 spp (two samples
/// each), and a checkpoint `cut.part.exr` of a render at 400 spp holding its first pass.
fn parts_and_a_checkpoint(d: &Path) {
    for i in 0..2 {
        render(d, &["--spp", "4", &format!("--part={i}/2"), "-o", &format!("p{i}.exr")]);
    }
    render(d, &["--spp", "400", "--time-limit", "0.000001", "-o", "cut.exr"]);
    assert!(d.join("cut.part.exr").exists());
}

/// Copies `from` to `to` in `d`.
fn copy(d: &Path, from: &str, to: &str) {
    std::fs::copy(d.join(from), d.join(to)).expect("copy");
}

/// M5: a NaN in `sums.raw`, an infinity, a NaN in `A`, the depth or the albedo, and negative
/// sums, merged (or resumed) with status 0 into NaN images. Each is refused, status 2, naming
/// the file and the layer.
#[test]
fn m5_non_finite_or_negative_sums_in_a_part_file_are_refused() {
    let dir = scene_dir();
    let d = dir.path();
    parts_and_a_checkpoint(d);
    let cases = [
        ("sums.raw.R", f32::NAN, "sums.raw"),
        ("sums.raw.G", f32::INFINITY, "sums.raw"),
        ("sums.A", f32::NAN, "sums.A"),
        ("sums.depth.Z", f32::NAN, "sums.depth.Z"),
        ("sums.albedo.R", f32::NAN, "sums.albedo"),
        ("sums.normal.X", f32::NEG_INFINITY, "sums.normal"),
        ("sums.raw.B", -1.0, "sums.raw"),
        ("sums.indirect.R", -0.5, "sums.indirect"),
        ("sums.objectid.coverage", -1.0, "sums.objectid.coverage"),
        // The halves of the samples: a half above its whole, a NaN, a share not a count.
        ("sums.raw_half.R", 1e6, "sums.raw_half"),
        ("sums.indirect_half.G", f32::NAN, "sums.indirect_half"),
        ("sums.half_share.Y", 0.5, "sums.half_share"),
    ];
    for (channel, value, layer) in cases {
        copy(d, "p1.exr", "bad.exr");
        set_channel(&d.join("bad.exr"), channel, Some(3), value);
        let o = run(d, &["merge", "p0.exr", "bad.exr", "-o", "m.exr"]);
        refused(&o, &["bad.exr", layer], &format!("merge: {channel} = {value}"));
        copy(d, "cut.part.exr", "bad.part.exr");
        set_channel(&d.join("bad.part.exr"), channel, Some(3), value);
        let o =
            run(d, &small(&["render", "s.toml", "--spp", "400", "--resume", "bad.part.exr", "-o", "r.exr"]));
        refused(&o, &["bad.part.exr", layer], &format!("resume: {channel} = {value}"));
    }
    // A sum of squares (two words a value) that is NaN.
    copy(d, "p1.exr", "bad.exr");
    edit_exr(
        &d.join("bad.exr"),
        |n, s| {
            if let (true, FlatSamples::U32(v)) = (n.ends_with("raw_squares.hi"), s) {
                v[0] = 0x7ff8_0000;
            }
        },
        |_| {},
    );
    let o = run(d, &["merge", "p0.exr", "bad.exr", "-o", "m.exr"]);
    refused(&o, &["bad.exr", "sums.raw_squares", "NaN"], "a NaN square");
    // A whole count of the second half, but not the part's (samples 2 and 3 of 4 are all in
    // it).
    copy(d, "p1.exr", "bad.exr");
    set_channel(&d.join("bad.exr"), "sums.half_share.Y", Some(3), 1.0);
    let o = run(d, &["merge", "p0.exr", "bad.exr", "-o", "m.exr"]);
    refused(&o, &["bad.exr", "sums.half_share", "second half"], "a forged half count");
    assert!(!d.join("m.exr").exists() && !d.join("r.exr").exists(), "nothing written");
}

/// M6: forged sample counts. A part claiming 4 of its 2 samples merged as "2 of 2 parts (6
/// samples a pixel)" for a 4-spp render; a part of zero counts made the image twice as bright
/// (coverage 2.0); a checkpoint whose counts were lowered (there from 8 to 1) resumed into a
/// brighter image. All with status 0; each is refused now, naming the file.
#[test]
fn m6_forged_sample_counts_are_refused() {
    let dir = scene_dir();
    let d = dir.path();
    parts_and_a_checkpoint(d);
    copy(d, "p0.exr", "four.exr");
    set_channel(&d.join("four.exr"), "samples.N", None, 4.0);
    let o = run(d, &["merge", "four.exr", "p1.exr", "-o", "m.exr"]);
    refused(&o, &["four.exr", "samples.N", "part 0/2 of 4 spp has 2"], "4 of 2 samples");
    copy(d, "p1.exr", "zero.exr");
    set_channel(&d.join("zero.exr"), "samples.N", None, 0.0);
    let o = run(d, &["merge", "p0.exr", "zero.exr", "-o", "m.exr"]);
    refused(&o, &["zero.exr", "samples.N"], "zero counts");
    // One pixel of another count, in a complete part.
    copy(d, "p1.exr", "one.exr");
    set_channel(&d.join("one.exr"), "samples.N", Some(7), 1.0);
    let o = run(d, &["merge", "p0.exr", "one.exr", "-o", "m.exr"]);
    refused(&o, &["one.exr", "samples.N", "(7, 0)"], "one pixel's count");
    // A checkpoint of 8 samples claiming 1: its coverage and its sums of squares give it away.
    copy(d, "cut.part.exr", "low.part.exr");
    set_channel(&d.join("low.part.exr"), "samples.N", None, 1.0);
    let o = run(d, &small(&["render", "s.toml", "--spp", "400", "--resume", "low.part.exr", "-o", "r.exr"]));
    refused(&o, &["low.part.exr", "sums."], "lowered counts");
    assert!(!d.join("m.exr").exists() && !d.join("r.exr").exists(), "nothing written");
    // The same counts without the guides' coverage: the sums of squares alone tell.
    copy(d, "cut.part.exr", "low.part.exr");
    edit_exr(
        &d.join("low.part.exr"),
        |n, s| match (n, s) {
            ("samples.N", FlatSamples::F32(v)) => v.iter_mut().for_each(|x| *x = 1.0),
            ("sums.objectid.coverage" | "sums.A", FlatSamples::F32(v)) => {
                v.iter_mut().for_each(|x| *x = x.min(1.0))
            }
            _ => {}
        },
        |_| {},
    );
    let o = run(d, &small(&["render", "s.toml", "--spp", "400", "--resume", "low.part.exr", "-o", "r.exr"]));
    refused(&o, &["low.part.exr", "by their sums of squares"], "lowered counts, coverage too");
    // The untouched files still merge and resume.
    let o = run(d, &["merge", "p0.exr", "p1.exr", "-o", "m.exr"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = run(d, &small(&["render", "s.toml", "--spp", "400", "--resume", "cut.part.exr", "-o", "r.exr"]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// Runs `lightsplit ARGS` in `dir`, killed if it has not ended after two minutes (a hang, which
/// the assertion on its status then reports).
fn run_or_kill(dir: &Path, args: &[&str]) -> Option<Output> {
    let mut child =
        lightsplit(dir).args(args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("spawns");
    for _ in 0..1200 {
        if child.try_wait().expect("waits").is_some() {
            return Some(child.wait_with_output().expect("output"));
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    let _ = child.kill();
    let _ = child.wait();
    None
}

/// M7: `converge` hung for ever on a `results.csv` row of this run with `rmse=inf` (or
/// `render_seconds=inf`): plotters' log axis looped. Such a row is left out with a `note:`,
/// measured again, and the plots are drawn.
#[test]
fn m7_converge_leaves_out_rows_that_are_not_finite() {
    let dir = scene_dir();
    let d = dir.path();
    let args = small(&[
        "converge",
        "s.toml",
        "--spp",
        "1,2",
        "--filters",
        "none",
        "--reference-spp",
        "2",
        "--out",
        "c",
    ]);
    let o = run(d, &args);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let csv = d.join("c/results.csv");
    for column in ["rmse", "render_seconds"] {
        // The last row, measured by the run before (the first is left out after the first edit).
        let text = std::fs::read_to_string(&csv).expect("results.csv");
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        let at = lines[0].split(',').position(|c| c == column).expect("the column");
        let last = lines.len() - 1;
        let mut row: Vec<&str> = lines[last].split(',').collect();
        row[at] = "inf";
        lines[last] = row.join(",");
        std::fs::write(&csv, lines.join("\n") + "\n").expect("write");
        let o = run_or_kill(d, &args).expect("converge ends");
        assert_eq!(o.status.code(), Some(0), "{column}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("note:") && stderr(&o).contains("not finite"),
            "{column}: {}",
            stderr(&o)
        );
        assert!(d.join("c/error-vs-spp.png").exists() && d.join("c/error-vs-time.png").exists());
    }
}

/// M8: `--resume V.part.exr -o V.part.exr` replaced the checkpoint it read with the final
/// image, status 0. It is refused before rendering, and the checkpoint is left as it was; a
/// part resumed into its own file (a part's output is its part file) still works.
#[test]
fn m8_a_resume_file_is_never_the_output() {
    let dir = scene_dir();
    let d = dir.path();
    render(d, &["--spp", "400", "--time-limit", "0.000001", "-o", "v.exr"]);
    let before = std::fs::read(d.join("v.part.exr")).expect("the checkpoint");
    let o =
        run(d, &small(&["render", "s.toml", "--spp", "400", "--resume", "v.part.exr", "-o", "v.part.exr"]));
    refused(&o, &["v.part.exr", "is an input"], "resume onto itself");
    assert!(std::fs::read(d.join("v.part.exr")).expect("the checkpoint") == before, "the checkpoint changed");
    render(d, &["--spp", "400", "--part", "0/1", "--time-limit", "0.000001", "-o", "p.exr"]);
    assert!(!lightsplit::part::read_header(&d.join("p.exr")).expect("a part").complete);
    render(d, &["--spp", "400", "--part", "0/1", "--resume", "p.exr", "-o", "p.exr"]);
    assert!(lightsplit::part::read_header(&d.join("p.exr")).expect("a part").complete);
}

/// L4: `filter` of an EXR with one NaN pixel spread it to nine pixels; finite values of 3e38
/// became infinities over the whole image (nine summed by box3); a kernel of weights of 1e38
/// made NaN. A non-finite pixel is refused with its count; the weighted sums cannot overflow
/// where the mean is finite; and where the image cannot be filtered and added up in 32 bits,
/// that is an error, never an image of infinities.
#[test]
fn l4_filter_refuses_non_finite_pixels_and_never_overflows() {
    let dir = scene_dir();
    let d = dir.path();
    render(d, &["--spp", "2", "-o", "a.exr"]);
    copy(d, "a.exr", "nan.exr");
    set_channel(&d.join("nan.exr"), "indirect.R", Some(5), f32::NAN);
    let o = run(d, &["filter", "nan.exr", "--filter", "box3", "-o", "f.exr"]);
    refused(&o, &["nan.exr", "1 of the 1024 pixels", "indirect"], "a NaN pixel");
    assert!(!d.join("f.exr").exists());
    // Every raw value 3e38: the whole image filtered stays 3e38.
    copy(d, "a.exr", "big.exr");
    for c in ["raw.R", "raw.G", "raw.B"] {
        set_channel(&d.join("big.exr"), c, None, 3e38);
    }
    let huge_weights = ["1e38"; 9].join(",");
    for kernel in ["box3", "weighted3", "box5", "median3", &huge_weights] {
        let o = run(d, &["filter", "big.exr", "--filter", kernel, "--filter-target", "image", "-o", "f.exr"]);
        assert_eq!(o.status.code(), Some(0), "{kernel}: {}", stderr(&o));
        let image = lightsplit::film::read_image(&d.join("f.exr")).expect("reads");
        for p in &image.pixels {
            assert!(p.is_finite() && (p.x / 3e38 - 1.0).abs() < 1e-5, "{kernel}: {p}");
        }
    }
    // Four components of 3e38 add up to more than any float: refused, nothing written.
    for layer in ["emitted", "direct", "caustic", "indirect"] {
        for c in ["R", "G", "B"] {
            set_channel(&d.join("big.exr"), &format!("{layer}.{c}"), None, 3e38);
        }
    }
    std::fs::remove_file(d.join("f.exr")).expect("remove");
    let o = run(d, &["filter", "big.exr", "--filter", "box3", "-o", "f.exr"]);
    refused(&o, &["overflow"], "components beyond a float");
    assert!(!d.join("f.exr").exists());
}

/// L5: an output name of 254 bytes passed the checks before the render, whose write then
/// failed ("File name too long", status 1), the temporary's name being 14 bytes longer. The
/// temporary's name is probed first: status 2 before any work, for an image, a filter's output
/// and a checkpoint's part file alike.
#[test]
fn l5_an_output_name_too_long_for_its_temporary_is_refused_up_front() {
    let dir = scene_dir();
    let d = dir.path();
    render(d, &["--spp", "1", "-o", "a.exr"]);
    let long = format!("{}.exr", "x".repeat(250));
    let o = run(d, &small(&["render", "s.toml", "--spp", "1", "-o", &long]));
    refused(&o, &["too long", "temporary"], "render");
    let o = run(d, &["filter", "a.exr", "--filter", "box3", "-o", &long]);
    refused(&o, &["too long"], "filter");
    // The image's name fits, and its checkpoint's (`.part.exr`, 5 bytes longer) does not: 238
    // bytes, whose temporary takes 248 and the process id (Linux gives none below 300 to a
    // process, so 3 to 7 digits), the checkpoint's 253 and the id.
    let image = format!("{}.exr", "y".repeat(234));
    let o = run(d, &small(&["render", "s.toml", "--spp", "1", "--checkpoint", "60", "-o", &image]));
    refused(&o, &["too long", ".part.exr"], "checkpoint");
    let names: Vec<_> = std::fs::read_dir(d).expect("list").map(|e| e.expect("entry").file_name()).collect();
    assert_eq!(names.len(), 2, "only the scene and a.exr: {names:?}");
}

/// L6: messages that named the wrong cause. Parts differing only in `lightsplit.spp` said
/// "key K against K"; `--resume` of a PNG said "invalid: file identifier missing", and of a
/// checkpoint to a `.png` output "the settings differ" (the same settings, another output);
/// a Slurm task ID below the array's minimum said `4294967295/4`; a non-UTF-8
/// `SLURM_ARRAY_TASK_ID` said "no scheduler found"; a NaN reference made `converge` exit 1.
#[test]
fn l6_messages_name_the_cause() {
    let dir = scene_dir();
    let d = dir.path();
    parts_and_a_checkpoint(d);
    set_attribute(&d.join("p1.exr"), "lightsplit.spp", "8");
    let o = run(d, &["merge", "p0.exr", "p1.exr", "-o", "m.exr"]);
    refused(&o, &["p1.exr", "different renders", "of 8 spp against 4"], "spp alone");

    render(d, &["--spp", "1", "-o", "img.png"]);
    let o = run(d, &small(&["render", "s.toml", "--spp", "400", "--resume", "img.png", "-o", "r.exr"]));
    refused(&o, &["img.png", "a resume file is a part file", "--checkpoint"], "a PNG to resume");
    // A checkpoint written for an EXR resumes to a PNG: the buffers it holds change no sample.
    let o = run(d, &small(&["render", "s.toml", "--spp", "400", "--resume", "cut.part.exr", "-o", "r.png"]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    render(d, &["--spp", "400", "-o", "whole.png"]);
    assert!(std::fs::read(d.join("r.png")).expect("png") == std::fs::read(d.join("whole.png")).expect("png"));

    let slurm = |id: &OsStr| {
        let vars = [
            ("SLURM_ARRAY_TASK_ID", id),
            ("SLURM_ARRAY_TASK_MIN", OsStr::new("1")),
            ("SLURM_ARRAY_TASK_COUNT", OsStr::new("4")),
        ];
        run_with(d, &vars, &small(&["render", "s.toml", "--spp", "4", "--part", "auto", "-o", "s.exr"]))
    };
    refused(
        &slurm(OsStr::new("0")),
        &["SLURM_ARRAY_TASK_ID=0 is below SLURM_ARRAY_TASK_MIN=1"],
        "below the minimum",
    );
    refused(&slurm(OsStr::from_bytes(b"\xff")), &["SLURM_ARRAY_TASK_ID=", "is not a number"], "not UTF-8");

    render(d, &["--spp", "1", "-o", "ref.exr"]);
    set_channel(&d.join("ref.exr"), "R", Some(0), f32::NAN);
    let args = small(&[
        "converge",
        "s.toml",
        "--spp",
        "1",
        "--filters",
        "none",
        "--reference",
        "ref.exr",
        "--out",
        "c",
    ]);
    refused(&run(d, &args), &["ref.exr", "1 of its 1024 pixels are NaN"], "a NaN reference");
}

/// What a mutation of a part file does: one of these, a few at a time.
#[derive(Clone, Debug)]
enum Mutation {
    /// Flips bit `bit` of the byte at `at` (a fraction of the length).
    Flip { at: f64, bit: u8 },
    /// Cuts the file at `at`.
    Truncate { at: f64 },
    /// Inserts `bytes` at `at`.
    Insert { at: f64, bytes: Vec<u8> },
    /// Gives the text attribute `name` the value `value`.
    Text { name: &'static str, value: String },
    /// Overwrites the four bytes of the data window's `corner` (0 to 3) with `value`.
    Window { corner: usize, value: i32 },
}

/// The text attributes of a part file's header.
const PART_ATTRIBUTES: [&str; 5] =
    ["lightsplit.key", "lightsplit.part", "lightsplit.spp", "lightsplit.adaptive", "lightsplit.complete"];

fn mutation() -> impl proptest::strategy::Strategy<Value = Mutation> {
    use proptest::prelude::*;
    let text = prop_oneof![
        Just("0/1".to_string()),
        Just("4294967295/4294967295".to_string()),
        Just("1/0".to_string()),
        Just("-1".to_string()),
        Just("nan".to_string()),
        Just(String::new()),
        Just("99999999999".to_string()),
        Just("16777216".to_string()),
        Just("no".to_string()),
        Just("yes".to_string()),
        Just("inf".to_string()),
        "[ -~]{0,12}",
    ];
    prop_oneof![
        (0.0..1.0f64, 0..8u8).prop_map(|(at, bit)| Mutation::Flip { at, bit }),
        (0.0..1.0f64).prop_map(|at| Mutation::Truncate { at }),
        (0.0..1.0f64, prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(at, bytes)| Mutation::Insert { at, bytes }),
        (prop::sample::select(PART_ATTRIBUTES.to_vec()), text)
            .prop_map(|(name, value)| Mutation::Text { name, value }),
        (
            0..4usize,
            prop_oneof![Just(-1), Just(0), Just(7), Just(8), Just(65535), Just(i32::MAX), any::<i32>()]
        )
            .prop_map(|(corner, value)| Mutation::Window { corner, value }),
    ]
}

/// The position in `bytes` of the value of attribute `name` of type `kind`, and its length.
fn attribute_value(bytes: &[u8], name: &str, kind: &str) -> Option<(usize, usize)> {
    let key = [name.as_bytes(), b"\0", kind.as_bytes(), b"\0"].concat();
    let at = bytes.windows(key.len()).position(|w| w == key.as_slice())? + key.len();
    let size = i32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?);
    Some((at + 4, usize::try_from(size).ok()?))
}

fn mutate(bytes: &mut Vec<u8>, m: &Mutation) {
    let at = |f: f64, len: usize| ((f * len as f64) as usize).min(len.saturating_sub(1));
    match m {
        Mutation::Flip { at: f, bit } => {
            let i = at(*f, bytes.len());
            if let Some(b) = bytes.get_mut(i) {
                *b ^= 1 << bit;
            }
        }
        Mutation::Truncate { at: f } => bytes.truncate(at(*f, bytes.len())),
        Mutation::Insert { at: f, bytes: new } => {
            let i = at(*f, bytes.len());
            bytes.splice(i..i, new.iter().copied());
        }
        Mutation::Text { name, value } => {
            if let Some((start, len)) = attribute_value(bytes, name, "string") {
                if start + len <= bytes.len() {
                    bytes.splice(start..start + len, value.bytes());
                    bytes[start - 4..start].copy_from_slice(&(value.len() as i32).to_le_bytes());
                }
            }
        }
        Mutation::Window { corner, value } => {
            if let Some((start, 16)) = attribute_value(bytes, "dataWindow", "box2i") {
                if let Some(v) = bytes.get_mut(start + 4 * corner..start + 4 * corner + 4) {
                    v.copy_from_slice(&value.to_le_bytes());
                }
            }
        }
    }
}

/// Fuzzing the part file reader: a valid part file (written by the binary), mutated by byte
/// flips, cuts, inserted bytes and edited header values (the part, the spp, the data window),
/// 256 cases from a fixed seed, read and merged by the library: an error or a result, never a
/// panic. (Memory stays small: the header checks refuse a file declaring more pixels than its
/// bytes can pack.)
#[test]
fn fuzz_mutated_part_files_never_panic() {
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    let dir = scene_dir();
    let d = dir.path();
    let o = run(
        d,
        &["render", "s.toml", "--spp", "2", "--part", "0/1", "--width", "8", "--height", "8", "-o", "p.exr"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let valid = std::fs::read(d.join("p.exr")).expect("a part file");
    let path: PathBuf = d.join("m.exr");
    let config = Config { cases: 256, failure_persistence: None, ..Config::default() };
    let mut runner = TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &[7; 32]));
    let strategy = proptest::collection::vec(mutation(), 1..4);
    let counts = std::cell::Cell::new((0, 0));
    runner
        .run(&strategy, |mutations| {
            let mut bytes = valid.clone();
            for m in &mutations {
                mutate(&mut bytes, m);
            }
            std::fs::write(&path, &bytes).expect("write");
            let _ = lightsplit::film::read_exr_channels(&path);
            if let Ok(header) = lightsplit::part::read_header(&path) {
                let named = [lightsplit::part::Named { path: path.clone(), header, held: None }];
                if lightsplit::part::check(&named, true).is_ok() {
                    let (r, m) = counts.get();
                    let merges = lightsplit::part::merge(&named, &|| {}).is_ok();
                    counts.set((r + 1, m + merges as u32));
                }
            }
            Ok(())
        })
        .expect("no mutation makes the reader panic");
    let (read, merged) = counts.get();
    // The mutations are not all refused at once: some reach the sums, and some merge.
    assert!(read > 0 && merged > 0, "{read} headers read, {merged} merged");
}
