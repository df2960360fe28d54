//! `lightsplit converge`: the files it writes, and a run killed half way that the same command
//! finishes without losing or repeating a row.

mod common;

use std::collections::HashSet;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use common::lightsplit;
use lightsplit::converge::{read_rows, Edge, Row, HEADER};
use lightsplit::render::sampler::SamplerKind;

fn scene() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sky-sphere.toml").to_string_lossy().into_owned()
}

fn keys(rows: &[Row]) -> HashSet<(u32, u32, (String, String, Edge))> {
    rows.iter().map(|r| (r.spp, r.seed, r.key())).collect()
}

/// A fresh output directory for a run (kept while the first value lives), and its path as text.
fn run_dir() -> (tempfile::TempDir, std::path::PathBuf, String) {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("run");
    let out_s = out.to_string_lossy().into_owned();
    (dir, out, out_s)
}

#[test]
fn writes_results_summary_plots_and_difference_images() {
    let (_dir, out, out_s) = run_dir();
    let args = [
        "converge",
        &scene(),
        "--width",
        "24",
        "--height",
        "16",
        "--spp",
        "1,4,16",
        "--reference-spp",
        "64",
        "--filters",
        "none,box3,weighted3",
        "--targets",
        "indirect,image",
        "--edge-aware",
        "off,pure",
        "--seeds",
        "2",
        "--out",
        &out_s,
    ];
    let o = lightsplit(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(out.join("results.csv")).expect("csv");
    assert_eq!(text.lines().next(), Some(HEADER));
    let rows = read_rows(&out.join("results.csv"));
    // 3 spp x 2 seeds x (none + 2 filters x 2 targets x 2 edge modes).
    assert_eq!(rows.len(), 3 * 2 * 9);
    assert!(rows.iter().any(|r| r.edge_aware == Edge::Pure));
    assert_eq!(keys(&rows).len(), rows.len());
    // One render per (spp, seed): every setting of it shares the render time.
    for r in &rows {
        let same: Vec<&Row> = rows.iter().filter(|o| o.spp == r.spp && o.seed == r.seed).collect();
        assert!(same.iter().all(|o| o.render_seconds == r.render_seconds));
        assert!(r.rmse > 0.0 && r.sse > 0.0 && r.relmse > 0.0);
        assert_eq!(r.filter_seconds > 0.0, r.filter != "none");
    }
    // The unfiltered error falls with the sample count.
    let rmse =
        |spp: u32| rows.iter().filter(|r| r.spp == spp && r.filter == "none").map(|r| r.rmse).sum::<f64>();
    assert!(rmse(1) > rmse(4) && rmse(4) > rmse(16), "{} {} {}", rmse(1), rmse(4), rmse(16));
    let summary = std::fs::read_to_string(out.join("summary.md")).expect("summary");
    assert!(summary.contains("weighted3 indirect edge-aware pure") && summary.contains("worth"), "{summary}");
    for f in
        ["error-vs-spp.png", "error-vs-time.png", "diff-16spp-unfiltered.png", "diff-16spp-box3-indirect.png"]
    {
        let img = image::open(out.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        assert!(img.width() > 0, "{f}");
    }
    // The reference was cached: a second run renders nothing new and says so.
    let o = lightsplit(&args);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("cached"));
    assert_eq!(read_rows(&out.join("results.csv")), rows, "a finished run is not repeated");
    // Bad input: a spp of 0, an unknown filter, a reference of another size: status 2.
    let scene = scene();
    for bad in [&["--spp", "0"][..], &["--filters", "gauss"][..], &["--diff-spp", "3"][..]] {
        let mut a = vec!["converge", &scene, "--out", &out_s];
        a.extend_from_slice(bad);
        assert_eq!(lightsplit(&a).status.code(), Some(2), "{bad:?}");
    }
}

#[test]
fn a_killed_run_continues_where_it_stopped() {
    let (_dir, out, out_s) = run_dir();
    let scene = scene();
    let args = [
        "converge",
        &scene,
        "--width",
        "32",
        "--height",
        "32",
        "--spp",
        "1,2,4,8,16,32,64,128,256,512,1024,2048",
        "--reference-spp",
        "16",
        "--filters",
        "none,box3,median3",
        "--out",
        &out_s,
    ];
    let mut child = Command::new(env!("CARGO_BIN_EXE_lightsplit"))
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("spawns");
    // Kill it as soon as some rows are in.
    let csv = out.join("results.csv");
    let start = Instant::now();
    while read_rows(&csv).len() < 4 && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(5));
    }
    let _ = child.kill();
    let _ = child.wait();
    let before = read_rows(&csv);
    assert!(before.len() >= 4, "no rows before the kill");
    assert!(before.len() < 12 * 3, "the run ended before the kill: the test proves nothing");
    let o = lightsplit(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let after = read_rows(&csv);
    assert_eq!(after.len(), 12 * 3, "every row once");
    assert_eq!(keys(&after).len(), after.len(), "no row twice");
    assert_eq!(&after[..before.len()], &before[..], "the rows of the killed run are kept");
}

#[test]
fn two_samplers_are_measured_and_compared_in_one_run() {
    let (_dir, out, out_s) = run_dir();
    let scene = scene();
    let args = [
        "converge",
        &scene,
        "--width",
        "24",
        "--height",
        "16",
        "--spp",
        "4,16",
        "--reference-spp",
        "256",
        "--filters",
        "none,weighted3",
        "--sampler",
        "sobol,independent",
        "--seeds",
        "2",
        "--out",
        &out_s,
    ];
    let o = lightsplit(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows = read_rows(&out.join("results.csv"));
    // 2 samplers x 2 spp x 2 seeds x 2 settings, each its own row.
    assert_eq!(rows.len(), 16);
    for sampler in SamplerKind::ALL {
        let mine: Vec<&Row> = rows.iter().filter(|r| r.sampler == sampler).collect();
        assert_eq!(mine.len(), 8, "{sampler}");
    }
    // The same seed index renders different numbers under each sampler.
    let unfiltered = |s: SamplerKind| {
        rows.iter()
            .find(|r| r.sampler == s && r.spp == 4 && r.seed == 0 && r.filter == "none")
            .map(|r| r.rmse)
    };
    assert_ne!(unfiltered(SamplerKind::Sobol), unfiltered(SamplerKind::Independent));
    let summary = std::fs::read_to_string(out.join("summary.md")).expect("summary");
    for want in ["sobol is worth", "## Sampler independent", "## Sampler sobol", "sobol weighted3 indirect"] {
        assert!(summary.contains(want), "no {want:?} in {summary}");
    }
    assert!(out.join("diff-16spp-sobol-unfiltered.png").exists());
    // A second run finds every row done.
    let o = lightsplit(&args);
    assert!(o.status.success());
    assert_eq!(read_rows(&out.join("results.csv")), rows);
}

#[test]
fn rows_written_before_the_sampler_column_read_as_independent() {
    let old = "cornell.toml,embree,16,0,none,none,false,0.5,0,1.0e0,2.0e-2,3.0e-3,4.0e-2";
    let row = Row::parse(old).expect("a 13-column row parses");
    assert_eq!((row.sampler, row.spp, row.rmse), (SamplerKind::Independent, 16, 2.0e-2));
    let new = row.csv();
    assert_eq!(new.split(',').nth(2), Some("independent"));
    assert_eq!(Row::parse(&new), Some(row));
    assert_eq!(Row::parse("cornell.toml,embree,halton,16,0,none,none,false,0.5,0,1,2,3,4"), None);
}
