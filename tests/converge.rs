//! `lightsplit converge`: the files it writes, and a run killed half way that the same command
//! finishes without losing or repeating a row.

use crate::common;

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
    assert_eq!(Row::parse(&new), Some(row.clone()));
    assert_eq!(Row::parse("cornell.toml,embree,halton,16,0,none,none,false,0.5,0,1,2,3,4"), None);
    // A row with its run key reads it back; a key that is not hexadecimal is a damaged line.
    let keyed = Row { run: "00ff00ff00ff00ff".into(), ..row };
    assert_eq!(Row::parse(&keyed.csv()).as_ref(), Some(&keyed));
    assert_eq!(Row::parse(&keyed.csv().replace("00ff00ff00ff00ff", "not-a-key")), None);
}

/// Issue 18, defect 2: the resume key covers everything that changes a number. A run into the
/// same `--out` at another size renders its own rows, says the others are not used, and its
/// summary reads only its own; a damaged (non-UTF-8) line spoils only itself.
#[test]
fn rows_of_other_settings_are_not_reused_and_a_bad_byte_spoils_one_line() {
    let (_dir, out, out_s) = run_dir();
    let scene = scene();
    let args = |width: &'static str| {
        let mut a = vec!["converge", &scene, "--width", width, "--height", "8", "--spp", "1,2"];
        a.extend(["--reference-spp", "8", "--filters", "none,box3", "--out", &out_s]);
        a.into_iter().map(String::from).collect::<Vec<String>>()
    };
    let run = |a: &[String]| {
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        lightsplit(&a)
    };
    let o = run(&args("12"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let first = read_rows(&out.join("results.csv"));
    assert_eq!(first.len(), 2 * 2);
    // Another width: nothing of the first run is reused, and the output says so.
    let o = run(&args("16"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("4 row(s)") && stderr.contains("not used"), "{stderr}");
    let all = read_rows(&out.join("results.csv"));
    assert_eq!(all.len(), 2 * first.len(), "the second run rendered its own rows");
    assert_eq!(&all[..first.len()], &first[..], "the first run's rows are kept in the file");
    let keys: HashSet<&str> = all.iter().map(|r| r.run.as_str()).collect();
    assert_eq!(keys.len(), 2, "two runs, two keys");
    let summary = std::fs::read_to_string(out.join("summary.md")).expect("summary");
    assert!(summary.contains("16x8") && summary.contains("4 more row(s)"), "{summary}");
    // A non-UTF-8 byte on one line: the same command finds every row done.
    let csv = out.join("results.csv");
    let mut bytes = std::fs::read(&csv).expect("csv");
    bytes.extend_from_slice(b"sky-sphere.toml,embree,\xff\n");
    std::fs::write(&csv, &bytes).expect("write");
    let o = run(&args("16"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(read_rows(&csv), all, "no row repeated or lost");
}

/// A results.csv from before the run column is brought to the new header; its rows are kept,
/// but, having no key, never used.
#[test]
fn an_older_results_file_is_upgraded_and_its_rows_kept_unused() {
    let (_dir, out, out_s) = run_dir();
    std::fs::create_dir_all(&out).expect("mkdir");
    let old = "scene,accel,sampler,spp,seed,filter,target,edge_aware,render_seconds,filter_seconds,sse,rmse,relmse,rmse_border\n\
               sky-sphere.toml,embree,independent,1,0,none,none,false,0.5,0,1.0e0,2.0e-2,3.0e-3,4.0e-2\n";
    std::fs::write(out.join("results.csv"), old).expect("write");
    let scene = scene();
    let args = [
        "converge",
        &scene,
        "--width",
        "8",
        "--height",
        "8",
        "--spp",
        "1",
        "--reference-spp",
        "4",
        "--filters",
        "none",
    ];
    let o = lightsplit(&[&args[..], &["--out", &out_s]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(out.join("results.csv")).expect("csv");
    assert_eq!(text.lines().next(), Some(HEADER));
    let rows = read_rows(&out.join("results.csv"));
    assert_eq!(rows.len(), 2, "the old row and the new one");
    assert_eq!((rows[0].run.as_str(), rows[0].rmse), ("", 2.0e-2));
    assert!(!rows[1].run.is_empty());
}

/// The run key changes with every input file (scene, mesh, material library, texture) and every
/// setting that changes a number, and with nothing else.
#[test]
fn the_run_key_covers_the_scene_files_and_every_setting() {
    use lightsplit::converge::Plan;
    use lightsplit::render::RenderOptions;
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let write = |name: &str, text: &str| std::fs::write(d.join(name), text).expect("write");
    write("m.mtl", "newmtl m\nKd 0.5 0.5 0.5\n");
    write("m.obj", "mtllib m.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    // A 1x1 PFM texture.
    let mut pfm = b"PF\n1 1\n-1\n".to_vec();
    pfm.extend([0.5f32, 0.5, 0.5].iter().flat_map(|v| v.to_le_bytes()));
    std::fs::write(d.join("t.pfm"), &pfm).expect("write");
    let scene_text = "[camera]\nposition = [0, 0, -3]\nlook_at = [0, 0, 0]\n\
        [[texture]]\nname = \"t\"\ntype = \"image\"\nfile = \"t.pfm\"\n\
        [[material]]\nname = \"m\"\ntype = \"diffuse\"\ntexture = \"t\"\n\
        [[shape]]\ntype = \"mesh\"\nfile = \"m.obj\"\nmaterial = \"m\"\n";
    write("s.toml", scene_text);
    let load = || lightsplit::scene::load(&d.join("s.toml")).expect("loads");
    let scene = load();
    let plan = Plan {
        scene_path: d.join("s.toml"),
        options: RenderOptions::from_scene(&scene),
        spps: vec![1],
        seeds: 1,
        samplers: vec![SamplerKind::Independent],
        choices: vec![],
        reference: None,
        reference_spp: 64,
        diff_spp: None,
        adaptive: None,
        out: d.join("out"),
    };
    let key = |plan: &Plan| plan.run_key(&load()).expect("key");
    let base = key(&plan);
    assert_eq!(key(&plan), base, "the same run, the same key");
    // Settings.
    let mut changed = Vec::new();
    for edit in [
        |p: &mut Plan| p.options.width += 1,
        |p: &mut Plan| p.options.height += 1,
        |p: &mut Plan| p.options.max_depth += 1,
        |p: &mut Plan| p.options.seed += 1,
        |p: &mut Plan| p.reference_spp *= 2,
        |p: &mut Plan| p.samplers = vec![SamplerKind::Independent, SamplerKind::Sobol],
    ] {
        let mut p = plan.clone();
        edit(&mut p);
        changed.push(key(&p));
    }
    // Files: each edited in turn, then restored.
    for (name, edited) in [
        ("s.toml", format!("{scene_text}[render]\nmax_depth = 3\n").into_bytes()),
        ("m.obj", b"mtllib m.mtl\nusemtl m\nv 0 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\n".to_vec()),
        ("m.mtl", b"newmtl m\nKd 0.25 0.5 0.5\n".to_vec()),
        ("t.pfm", [&pfm[..pfm.len() - 4], &0.25f32.to_le_bytes()[..]].concat()),
    ] {
        let before = std::fs::read(d.join(name)).expect("read");
        std::fs::write(d.join(name), &edited).expect("write");
        changed.push(key(&plan));
        std::fs::write(d.join(name), &before).expect("write");
    }
    assert_eq!(key(&plan), base, "restored files, the same key");
    let distinct: HashSet<&String> = changed.iter().chain([&base]).collect();
    assert_eq!(distinct.len(), changed.len() + 1, "every change gives a key of its own: {changed:?}");
    // A given reference: its contents count, not its name.
    std::fs::write(d.join("ref.pfm"), &pfm).expect("write");
    let given = Plan { reference: Some(d.join("ref.pfm")), ..plan.clone() };
    let k = key(&given);
    std::fs::write(d.join("ref.pfm"), [&pfm[..pfm.len() - 4], &0.25f32.to_le_bytes()[..]].concat())
        .expect("write");
    assert_ne!(key(&given), k);
}
