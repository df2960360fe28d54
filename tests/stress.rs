//! `lightsplit stress`: every row of the numerical-stability table holds on both backends, each
//! judged by its own figures (no row is excused), and the command prints the table and its JSON.

use crate::common;

use common::lightsplit;
use lightsplit::accel::Backend;
use lightsplit::stress::{names, run_row};

fn every_row_holds(backend: Backend) {
    let mut failed = Vec::new();
    for name in names() {
        let row = run_row(name, backend, None).expect("the row runs");
        eprintln!("{backend} {:34} {} {}", row.name, row.pass, row.figure);
        if !row.pass {
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

/// The translations reach 1e8 (f32's step there is 8 units, more than the scene's size).
#[test]
fn translations_reach_1e8() {
    let translations: Vec<&str> = names().filter(|n| n.starts_with("translate")).collect();
    assert_eq!(
        translations,
        ["translate 1e3", "translate 1e5", "translate 1e6", "translate 1e7", "translate 1e8"]
    );
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
