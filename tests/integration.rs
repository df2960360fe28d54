//! The integration tests, one module a file, linked into one binary: with the release profile's
//! fat LTO each test binary is a whole-program link, and one link instead of fourteen saves
//! minutes of every test run. Run one file's tests with `cargo test --release --test integration
//! hardening::`.

mod common;

mod adaptive;
mod agreement;
mod analytic;
mod aovs;
mod cameras;
mod checker;
mod cli;
mod components;
mod converge;
mod cryptomatte;
mod cutouts;
mod determinism;
mod embree;
mod features;
mod formats;
mod guiding;
mod hardening;
mod hostile_parts;
mod hostile_scenes;
mod instancing;
mod mitsuba;
mod nonfinite;
mod parts;
mod properties;
mod stress;
mod variance;
