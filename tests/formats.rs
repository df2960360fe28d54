//! Issue 19: the scenes people have (HDRI environment maps, glTF, OBJ materials) come in, and bad
//! ones are one clear error with exit status 2, never a panic.

use std::path::Path;
use std::process::Command;

use crate::common::pfm;

/// Renders `scene` (written into `dir`) to a PNG there; returns the exit code and stderr.
fn render_in(dir: &Path, scene: &str) -> (Option<i32>, String) {
    std::fs::write(dir.join("s.toml"), scene).expect("write");
    let o = Command::new(env!("CARGO_BIN_EXE_lightsplit"))
        .args(["render", "s.toml", "-o", "o.png", "--spp", "1"])
        .current_dir(dir)
        .output()
        .expect("the binary runs");
    (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
}

const CAMERA: &str = "[camera]\nposition = [0, 1, -5]\nlook_at = [0, 1, 0]\n[film]\nwidth = 8\nheight = 8\n\
[[shape]]\ntype = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1\n";

/// Bad environment maps: empty, not lat-long, NaN, negative; bad keys. Each is refused with
/// exit status 2 and one line naming the scene line, the file and what is wrong.
#[test]
fn bad_environment_maps_are_one_clear_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(d.join("empty.hdr"), b"").expect("write");
    std::fs::write(d.join("square.pfm"), pfm(4, 4, &[1.0; 48])).expect("write");
    let mut nan = vec![1.0f32; 24];
    nan[4] = f32::NAN;
    std::fs::write(d.join("nan.pfm"), pfm(4, 2, &nan)).expect("write");
    std::fs::write(d.join("negative.pfm"), pfm(4, 2, &[-1.0; 24])).expect("write");
    std::fs::write(d.join("ok.pfm"), pfm(4, 2, &[1.0; 24])).expect("write");
    let light = |keys: &str| format!("{CAMERA}[[light]]\ntype = \"environment\"\n{keys}\n");
    for (keys, needles) in [
        ("file = \"empty.hdr\"", vec!["empty.hdr", "empty (0 bytes)"]),
        ("file = \"square.pfm\"", vec!["square.pfm", "twice as wide as high", "4x4"]),
        ("file = \"nan.pfm\"", vec!["nan.pfm", "1 of the environment map's 8 pixels"]),
        ("file = \"negative.pfm\"", vec!["negative.pfm", "negative"]),
        ("file = \"missing.exr\"", vec!["missing.exr"]),
        ("file = \"ok.pfm\"\nscale = -1", vec!["scale", "negative"]),
        ("file = \"ok.pfm\"\nsampling = \"cosine\"", vec!["sampling", "cosine", "luminance or uniform"]),
        ("scale = 2", vec!["file"]),
    ] {
        let (code, err) = render_in(d, &light(keys));
        assert_eq!(code, Some(2), "{keys}: {err}");
        assert_eq!(err.lines().count(), 1, "{keys}: one line: {err}");
        assert!(err.starts_with("error: s.toml:11:"), "{keys}: names the light's line: {err}");
        for n in needles {
            assert!(err.contains(n), "{keys}: `{n}` in {err}");
        }
        assert!(!d.join("o.png").exists(), "{keys}: nothing written");
    }
    let (code, err) = render_in(d, &light("file = \"ok.pfm\""));
    assert_eq!(code, Some(0), "{err}");
}
