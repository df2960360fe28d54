//! A hostile user's findings on parts, checkpoints, the EXR reader and the commands that read
//! files (`merge`, `--resume`, `filter`, `compare`, `converge`): one test per finding, each
//! named in its doc comment with what happened before. Each failed before its fix.

use std::ffi::OsStr;
use std::path::Path;
use std::process::{Command, Output, Stdio};

use exr::image::FlatSamples;
use exr::meta::header::LayerAttributes;

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

/// Copies `from` to `to` in `d`.
fn copy(d: &Path, from: &str, to: &str) {
    std::fs::copy(d.join(from), d.join(to)).expect("copy");
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
