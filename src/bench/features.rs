//! `bench-features`: what skipping what a scene does not need is worth. Each scene is rendered
//! three ways in every round, back to back: specialised (the features and the Embree build the
//! scene and a PNG of its final image need), the general integrator on the specialised build
//! (so the integrator's share is seen alone), and everything forced on (every feature, Embree's
//! robust high-quality build). Speeds are medians over rounds of ratios measured side by side.
//!
//! With AOVs, light groups or Cryptomatte asked for, each round also renders an EXR's film
//! twice, back to back: with the four components alone, and with those layers too, and the
//! row gives the time ratio (the layers' cost) and whether the components came out the same.

use std::path::Path;

use serde::Serialize;

use crate::accel::{Backend, BuildHints};
use crate::film::{Film, Format};
use crate::filter::Setting;
use crate::output::Layer;
use crate::render::{self, Features, RenderError, RenderOptions, RenderStats};
use crate::scene::{Aov, Scene};

use super::median;

/// How each scene is rendered.
#[derive(Clone, Debug)]
pub struct BenchFeaturesOptions {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub rounds: usize,
    pub threads: Option<usize>,
    pub accel: Backend,
    /// Layers whose cost to measure: AOVs, a layer a light group, Cryptomatte's mattes.
    pub aovs: Vec<Aov>,
    pub light_groups: bool,
    pub cryptomatte: bool,
}

impl BenchFeaturesOptions {
    fn has_layers(&self) -> bool {
        !self.aovs.is_empty() || self.light_groups || self.cryptomatte
    }
}

/// What the layers asked for cost a scene's render.
#[derive(Clone, Debug, Serialize)]
pub struct LayersCost {
    /// The AOVs (with the light groups') and `cryptomatte`, comma-separated.
    pub layers: String,
    /// Median over rounds of the render's seconds with the layers over without, measured back
    /// to back (both with the components and guides an EXR has).
    pub time_ratio: f64,
    /// Whether the component layers are bit-identical with and without the layers.
    pub components_identical: bool,
}

/// One scene's row.
#[derive(Clone, Debug, Serialize)]
pub struct FeaturesRow {
    pub scene: String,
    /// The specialised render's features and Embree build.
    pub features: Features,
    pub embree: BuildHints,
    /// Path samples per second (median over rounds) of the specialised render, of the general
    /// integrator on the specialised build, and of everything forced on.
    pub samples_per_second: [f64; 3],
    /// Median over rounds of specialised / forced on, measured back to back.
    pub speedup: f64,
    /// Median over rounds of (general integrator, same build) / forced on: the Embree build's
    /// share of the speed-up; speedup over this is the integrator's.
    pub build_speedup: f64,
    /// Bytes of per-pixel buffers, specialised and forced on.
    pub buffer_bytes: [u64; 2],
    /// Pixels whose beauty differs between the specialised integrator and the general one on
    /// the same Embree build (the integrator's promise: none).
    pub integrator_pixels_differing: usize,
    /// Pixels whose beauty differs between the specialised render and everything forced on,
    /// and the largest difference relative to the pixel's value: a different Embree build may
    /// report the other of two triangles a ray meets exactly on their shared edge.
    pub pixels_differing: usize,
    pub max_relative_difference: f32,
    /// The layers' cost, when asked for.
    pub layers: Option<LayersCost>,
}

fn differing(a: &Film, b: &Film) -> (usize, f32) {
    let mut n = 0;
    let mut worst = 0.0f32;
    for (x, y) in a.raw.pixels.iter().zip(&b.raw.pixels) {
        if x != y {
            n += 1;
            let rel = ((*x - *y).abs() / y.abs().max(glam::Vec3::splat(1e-3))).max_element();
            worst = worst.max(rel);
        }
    }
    (n, worst)
}

/// Measures one scene, whose `[filter]` section asks for `filter`.
pub fn bench_scene(
    path: &Path,
    scene: &Scene,
    filter: &Setting,
    options: &BenchFeaturesOptions,
) -> Result<FeaturesRow, RenderError> {
    let mut base = RenderOptions::from_scene(scene);
    base.width = options.width;
    base.height = options.height;
    base.spp = options.spp;
    base.threads = options.threads;
    base.accel = options.accel;
    // `base` has what the scene needs; a PNG of the final image reads only what its filter does.
    let png = Layer::Final.reads(Format::Png, filter);
    let specialised = RenderOptions {
        features: Features { split: png.split, guides: png.guides, ..base.features },
        ..base.clone()
    };
    let general_same_build = RenderOptions { features: Features::ALL, ..specialised.clone() };
    let forced = RenderOptions { features: Features::ALL, build: BuildHints::default(), ..base.clone() };
    // An EXR's film, without and with the layers asked for.
    let components =
        RenderOptions { features: Features { split: true, guides: true, ..base.features }, ..base };
    let mut layered =
        RenderOptions { aovs: options.aovs.clone(), cryptomatte: options.cryptomatte, ..components.clone() };
    if options.light_groups {
        layered.aovs.extend(scene.light_groups.aovs().map_err(RenderError::Aovs)?);
    }
    let mut modes = vec![&specialised, &general_same_build, &forced];
    if options.has_layers() {
        modes.extend([&components, &layered]);
    }

    let mut rates: [Vec<f64>; 5] = Default::default();
    let (mut speedup, mut build_speedup, mut cost) = (Vec::new(), Vec::new(), Vec::new());
    let mut films: [Option<Film>; 5] = Default::default();
    let mut stats = [RenderStats::default(); 5];
    for round in 0..options.rounds.max(1) {
        let mut r = [0.0; 5];
        // Each round starts with another mode, so no mode always runs first.
        for k in 0..modes.len() {
            let i = (k + round) % modes.len();
            let mode = modes[i];
            let out = render::render(scene, mode, &|_| {})?;
            r[i] = out.stats.samples as f64 / out.stats.seconds.max(1e-9);
            rates[i].push(r[i]);
            if round == 0 {
                films[i] = Some(out.film);
                stats[i] = out.stats;
            }
        }
        speedup.push(r[0] / r[2]);
        build_speedup.push(r[1] / r[2]);
        if options.has_layers() {
            // Both take the same samples: the ratio of their rates is that of their times.
            cost.push(r[3] / r[4]);
        }
    }
    let [Some(specialised_film), Some(general_film), Some(forced_film), components_film, layered_film] =
        films
    else {
        unreachable!("round 0 renders every mode")
    };
    let layers = match (components_film, layered_film) {
        (Some(a), Some(b)) => Some(LayersCost {
            layers: layered
                .aovs
                .iter()
                .map(|a| a.name.as_str())
                .chain(layered.cryptomatte.then_some("cryptomatte"))
                .collect::<Vec<_>>()
                .join(","),
            time_ratio: median(cost),
            components_identical: a.components == b.components,
        }),
        _ => None,
    };
    let (integrator_pixels_differing, _) = differing(&specialised_film, &general_film);
    let (pixels_differing, max_relative_difference) = differing(&specialised_film, &forced_film);
    Ok(FeaturesRow {
        scene: path.display().to_string(),
        features: specialised.features,
        embree: specialised.build,
        samples_per_second: {
            let [a, b, c, ..] = rates;
            [a, b, c].map(median)
        },
        speedup: median(speedup),
        build_speedup: median(build_speedup),
        buffer_bytes: [stats[0].buffer_bytes, stats[2].buffer_bytes],
        integrator_pixels_differing,
        pixels_differing,
        max_relative_difference,
        layers,
    })
}

/// The rows as a Markdown table.
pub fn table(rows: &[FeaturesRow], options: &BenchFeaturesOptions) -> String {
    let mut out = format!(
        "{}x{} at {} spp, {}, median of {} rounds; a PNG of the final image (the scene's own filter)\n\n",
        options.width, options.height, options.spp, options.accel, options.rounds
    );
    out += "| scene | computes | Embree build | M samples/s specialised | forced on | speed-up | of which the build | buffers (KiB) specialised / forced | pixels differing: integrator / all |\n";
    out += "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | --- |\n";
    for r in rows {
        out += &format!(
            "| {} | {} | {}, {} | {:.3} | {:.3} | {:.2}x | {:.2}x | {} / {} | {} / {}{} |\n",
            Path::new(&r.scene).file_name().map_or(r.scene.clone(), |n| n.to_string_lossy().into_owned()),
            r.features.names(),
            if r.embree.robust { "robust" } else { "not robust" },
            r.embree.quality.name(),
            r.samples_per_second[0] / 1e6,
            r.samples_per_second[2] / 1e6,
            r.speedup,
            r.build_speedup,
            r.buffer_bytes[0] / 1024,
            r.buffer_bytes[1] / 1024,
            r.integrator_pixels_differing,
            r.pixels_differing,
            if r.pixels_differing > 0 {
                format!(" (at most {:.1e} relative)", r.max_relative_difference)
            } else {
                String::new()
            }
        );
    }
    if rows.iter().any(|r| r.layers.is_some()) {
        out += "\nThe layers' cost: an EXR's film (components and guides) with the layers over without, back to back\n\n";
        out +=
            "| scene | layers | time with / without | components identical |\n| --- | --- | ---: | --- |\n";
        for (r, l) in rows.iter().filter_map(|r| r.layers.as_ref().map(|l| (r, l))) {
            let name =
                Path::new(&r.scene).file_name().map_or(r.scene.clone(), |n| n.to_string_lossy().into_owned());
            out += &format!(
                "| {name} | {} | {:.3}x | {} |\n",
                l.layers,
                l.time_ratio,
                if l.components_identical { "yes" } else { "NO" }
            );
        }
    }
    out
}
