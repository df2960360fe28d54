//! The per-pixel variance a render keeps: the variance of each pixel's mean luminance, of the
//! beauty and of each component, estimated from the pixel's own samples.

use std::path::Path;

use lightsplit::component::Component;
use lightsplit::math::luminance;
use lightsplit::render::sampler::SamplerKind;
use lightsplit::render::{render, RenderOptions};
use lightsplit::scene;

#[test]
fn the_estimated_variance_matches_the_spread_across_seeds() {
    // With independent numbers, each render's estimate of a pixel's variance of the mean and
    // the variance of that pixel's mean across seeds estimate the same quantity. Their
    // difference, averaged over the pixels, must be within four standard errors of zero (the
    // standard error from the pixels' own spread of differences), for the beauty and for the
    // indirect component.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sky-sphere.toml");
    let scene = scene::load(&path).expect("loads");
    let seeds = 8;
    let films: Vec<_> = (0..seeds)
        .map(|seed| {
            let mut options = RenderOptions::from_scene(&scene);
            options.width = 32;
            options.height = 24;
            options.spp = 32;
            options.seed = seed;
            options.sampler = SamplerKind::Independent;
            render(&scene, &options, &|_| {}).expect("renders").film
        })
        .collect();
    let pixels = films[0].raw.pixels.len();
    let check = |what: &str,
                 mean_of: &dyn Fn(usize, usize) -> f64,
                 estimate_of: &dyn Fn(usize, usize) -> f64| {
        let mut d = Vec::new();
        let mut total = 0.0;
        for p in 0..pixels {
            let means: Vec<f64> = (0..seeds as usize).map(|k| mean_of(k, p)).collect();
            let m = means.iter().sum::<f64>() / seeds as f64;
            let empirical = means.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (seeds - 1) as f64;
            let estimated = (0..seeds as usize).map(|k| estimate_of(k, p)).sum::<f64>() / seeds as f64;
            d.push(estimated - empirical);
            total += empirical;
        }
        let n = d.len() as f64;
        let mean = d.iter().sum::<f64>() / n;
        let se = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
        assert!(total > 0.0, "{what}: no noise to measure");
        assert!(mean.abs() < 4.0 * se, "{what}: estimated minus empirical {mean:e}, standard error {se:e}");
    };
    check("beauty", &|k, p| luminance(films[k].raw.pixels[p]) as f64, &|k, p| films[k].variance[p] as f64);
    let c = Component::Indirect;
    check("indirect", &|k, p| luminance(films[k].components[c].pixels[p]) as f64, &|k, p| {
        films[k].component_variance[c][p] as f64
    });
    // No estimate is negative.
    for film in &films {
        assert!(film.variance.iter().chain(film.component_variance.iter().flatten()).all(|&v| v >= 0.0));
    }
}
