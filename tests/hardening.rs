//! Issue 18's defects, one test each: what a careless or hostile user found, checked so that it
//! cannot come back. Each test failed before its fix.

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
