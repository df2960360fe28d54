//! `lightsplit stress`: every row of the numerical-stability table holds on both backends (a
//! row past f32's reach may fail, and must say why), and the command prints the table and its
//! JSON.

mod common;

use common::lightsplit;
use lightsplit::accel::Backend;
use lightsplit::stress::{names, run_row};

fn every_row_holds(backend: Backend) {
    let mut failed = Vec::new();
    for name in names() {
        let row = run_row(name, backend, None).expect("the row runs");
        eprintln!("{backend} {:34} {} {}", row.name, row.pass, row.figure);
        let explained = row.limit && row.note.contains("f32 runs out");
        if !(row.pass || explained) {
            failed.push(format!("{}: {} ({})", row.name, row.figure, row.note));
        }
    }
    assert!(failed.is_empty(), "on {backend}:\n{}", failed.join("\n"));
}

#[test]
fn every_row_holds_on_embree() {
    every_row_holds(Backend::Embree);
}

#[test]
fn every_row_holds_on_the_bvh() {
    every_row_holds(Backend::Bvh);
}

/// f32 holds the scene to 1e-3 of its size at every scale and up to a translation of 1e3.
#[test]
fn rows_past_f32_are_the_far_translations() {
    let limits: Vec<&str> = ["translate 1e3", "translate 1e5", "translate 1e6", "scale 1e-4", "scale 1e5"]
        .into_iter()
        .filter(|name| run_row(name, Backend::Bvh, None).expect("runs").limit)
        .collect();
    assert_eq!(limits, ["translate 1e5", "translate 1e6"], "rows past f32's reach");
}

#[test]
fn the_command_prints_a_table_and_json() {
    let o = lightsplit(&["stress", "--only", "watertight", "--json", "--accel", "bvh"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    let rows = v["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 2);
    for r in rows {
        assert!(r["name"].as_str().is_some_and(|n| n.starts_with("watertight")));
        assert!(r["figure"].as_str().is_some_and(|f| f.contains("hole 0 of")), "{r}");
        assert_eq!(r["pass"], true);
    }
    let o = lightsplit(&["stress", "--only", "zero-radius"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && text.contains("zero-radius sphere") && text.contains("yes"), "{text}");
    let o = lightsplit(&["stress", "--only", "no such row"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("the rows are: translate 1e3"));
}
