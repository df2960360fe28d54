//! No NaN or Inf reaches the film: a sample that produces one is dropped, counted, reported in
//! `--json`, and with `--debug-nonfinite` printed with its pixel, sample index and path. An
//! adversarial scene provokes it: a point light of 3e38 W/sr half a unit above a plane, whose
//! irradiance overflows f32.

use crate::common;

use common::{lightsplit, render_text};

const SCENE: &str = r#"
[camera]
position = [0, 2, -3]
look_at = [0, 0, 0]
[film]
width = 16
height = 16
spp = 4
[[shape]]
type = "quad"
name = "floor"
vertices = [[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]]
[[light]]
type = "point"
position = [0, 0.5, 0]
intensity = [3e38, 3e38, 3e38]
"#;

#[test]
fn overflowing_samples_are_dropped_counted_and_explained() {
    let out = render_text(SCENE, 4);
    let n = out.stats.nonfinite_samples;
    assert!(n > 0 && n < out.stats.samples, "{n} of {} samples non-finite", out.stats.samples);
    let film = &out.film;
    for layer in std::iter::once(&film.raw).chain(&film.components) {
        assert!(layer.pixels.iter().all(|p| p.is_finite()), "a non-finite value reached the film");
    }

    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("nan.toml");
    std::fs::write(&path, SCENE).expect("write");
    let run = |extra: &[&str]| {
        let mut args = vec!["render", path.to_str().expect("utf-8"), "-o"];
        let exr = dir.path().join("nan.exr");
        args.push(exr.to_str().expect("utf-8"));
        args.extend_from_slice(extra);
        lightsplit(&args)
    };
    let o = run(&["--json", "--debug-nonfinite"]);
    assert!(o.status.success());
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["nonfinite_samples"].as_u64(), Some(n), "the same count from the command line");
    let err = String::from_utf8_lossy(&o.stderr);
    let reports = err.matches("non-finite sample dropped at pixel (").count();
    assert!(reports == 20.min(n as usize), "{reports} reports for {n} samples:\n{err}");
    assert!(err.contains("hit `floor` at") && err.contains("radiance [inf"), "{err}");
    // Without the flag: counted, not printed.
    let o = run(&["--json"]);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("non-finite sample dropped"));
}
