//! Adaptive sampling (`--adaptive THRESHOLD`): a pixel stops once the estimated relative error
//! of its mean is at most the threshold. Its samples are the uniform render's first ones, so a
//! threshold nothing reaches gives the uniform image bit for bit; pixels that stop early are as
//! accurate as the threshold says; and they are the flat ones, not the noisy ones.

use std::path::Path;

use lightsplit::render::sampler::SamplerKind;
use lightsplit::render::{relative_error, render, RenderOptions, RenderOutput};
use lightsplit::scene::{self, Scene};

fn paper_sky() -> Scene {
    scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper-sky.toml")).expect("loads")
}

fn render_at(scene: &Scene, spp: u32, adaptive: Option<f32>, seed: u64) -> RenderOutput {
    render_with(scene, spp, adaptive, seed, SamplerKind::default())
}

fn render_with(
    scene: &Scene,
    spp: u32,
    adaptive: Option<f32>,
    seed: u64,
    sampler: SamplerKind,
) -> RenderOutput {
    let mut options = RenderOptions::from_scene(scene);
    options.sampler = sampler;
    options.width = 48;
    options.height = 48;
    options.spp = spp;
    options.seed = seed;
    options.adaptive = adaptive;
    render(scene, &options, &|_| {}).expect("renders")
}

#[test]
fn the_relative_error_of_known_samples() {
    // Samples 1 and 3: mean 2, sample variance 2, standard error 1, relative error 0.5.
    assert!((relative_error(2, 4.0, 10.0) - 0.5).abs() < 1e-12);
    assert_eq!(relative_error(5, 0.0, 0.0), 0.0, "black in every sample: converged");
    assert_eq!(relative_error(1, 3.0, 9.0), f64::INFINITY, "one sample says nothing of its spread");
    assert_eq!(relative_error(4, 8.0, 16.0), 0.0, "four equal samples");
}

#[test]
fn a_threshold_no_pixel_reaches_gives_the_uniform_image() {
    let scene = paper_sky();
    let bits = |o: &RenderOutput| -> Vec<u32> {
        o.film.raw.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect()
    };
    // With either sampler a pixel's sample k draws the same numbers whatever the passes.
    for sampler in SamplerKind::ALL {
        let uniform = render_with(&scene, 40, None, 3, sampler);
        let adaptive = render_with(&scene, 40, Some(1e-30), 3, sampler);
        assert_eq!(bits(&adaptive), bits(&uniform), "{sampler}: passes of 16, 32, 40 samples: the same sums");
        assert_eq!(adaptive.film.components, uniform.film.components);
        assert_eq!(adaptive.stats.samples, uniform.stats.samples);
        assert_eq!(adaptive.stats.stopped_early, 0);
    }
}

#[test]
fn pixels_that_stop_early_are_as_accurate_as_the_threshold() {
    let scene = paper_sky();
    let threshold = 0.05f32;
    let reference = render_at(&scene, 2048, None, 99).film.raw;
    let out = render_at(&scene, 512, Some(threshold), 1);
    let uniform_samples = 48 * 48 * 512u64;
    assert!(
        out.stats.samples < uniform_samples / 2,
        "the sky and the lit floor converge early: {} of {uniform_samples} samples",
        out.stats.samples
    );
    assert!(out.stats.stopped_early > 48 * 48 / 4, "{} pixels stopped early", out.stats.stopped_early);
    // The realised relative error of every lit pixel (mean luminance against the reference's,
    // rendered with 4x the most samples and another seed): its root mean square must be near
    // the threshold, not far above it.
    let lum = |v: glam::Vec3| (0.2126 * v.x + 0.7152 * v.y + 0.0722 * v.z) as f64;
    let mut sq = Vec::new();
    for (p, r) in out.film.raw.pixels.iter().zip(&reference.pixels) {
        if lum(*r) > 1e-3 {
            sq.push(((lum(*p) - lum(*r)) / lum(*r)).powi(2));
        }
    }
    let rms = (sq.iter().sum::<f64>() / sq.len() as f64).sqrt();
    assert!(rms < 2.0 * threshold as f64, "realised relative error {rms:.4} over {} pixels", sq.len());
}
