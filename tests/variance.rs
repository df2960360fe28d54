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

/// Renders `scenes/NAME` at 32x24 with `spp` and `seed`, `set` changing the options further.
fn render_of(name: &str, spp: u32, seed: u64, set: impl Fn(&mut RenderOptions)) -> lightsplit::film::Film {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(name);
    let scene = scene::load(&path).expect("loads");
    let mut options = RenderOptions::from_scene(&scene);
    (options.width, options.height, options.spp, options.seed) = (32, 24, spp, seed);
    set(&mut options);
    render(&scene, &options, &|_| {}).expect("renders").film
}

#[test]
fn the_second_half_is_the_render_of_its_samples() {
    // At 16 spp the second half is samples 8 to 15, part 1 of 2: its mean, scaled by its share
    // (a power of two, so exact), is the whole render's half layer, bit for bit.
    let whole = render_of("cornell.toml", 16, 3, |_| {});
    let part = render_of("cornell.toml", 16, 3, |o| o.part = lightsplit::render::Part { index: 1, count: 2 });
    assert!(whole.has_halves() && whole.half_share.iter().all(|&s| s == 0.5));
    let scaled = |image: &lightsplit::film::Image| image.pixels.iter().map(|&p| p * 0.5).collect::<Vec<_>>();
    assert_eq!(scaled(&part.raw), whole.half.pixels);
    for c in Component::ALL {
        assert_eq!(scaled(&part.components[c]), whole.component_half[c].pixels, "{c:?}");
    }
    // At 24 spp the second half is samples 8 to 15 again (bit 8 of the index): a third.
    let film = render_of("cornell.toml", 24, 3, |_| {});
    assert!(film.half_share.iter().all(|&s| (s - 1.0 / 3.0).abs() < 1e-6));
}

#[test]
fn the_halves_estimate_a_sobol_renders_noise() {
    // With Sobol the samples of a pixel are not independent, and their sample variance
    // overstates the noise of the mean; the halves' estimate follows it. Over 8 seeds, the
    // estimates' total against the total spread of the pixels' means across seeds: within a
    // factor of 1.8 either way (the halves' correlation, film::tests); the spread itself, from
    // 8 seeds, within 1 +- 4 sqrt(2 / (7 pixels)) of its own expectation over the image.
    let seeds = 8u64;
    let films: Vec<_> = (0..seeds).map(|seed| render_of("sky-sphere.toml", 32, seed, |_| {})).collect();
    let pixels = films[0].raw.pixels.len();
    let (mut estimated, mut empirical) = (0.0, 0.0);
    for p in 0..pixels {
        let means: Vec<f64> = films.iter().map(|f| luminance(f.raw.pixels[p]) as f64).collect();
        let m = means.iter().sum::<f64>() / seeds as f64;
        empirical += means.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (seeds - 1) as f64;
        estimated += films.iter().map(|f| f.variance[p] as f64).sum::<f64>() / seeds as f64;
    }
    assert!(empirical > 0.0, "no noise to measure");
    let ratio = estimated / empirical;
    assert!((0.55..1.8).contains(&ratio), "halves' estimate over the spread across seeds: {ratio}");
}

#[test]
fn the_filter_keeps_what_the_halves_say_lowers_the_error() {
    use lightsplit::filter::{composite, FilterInput, Method, Setting};
    // A noisy render (4 spp): `--denoise` changes it, and the check keeps most of the filter.
    let film = render_of("cornell.toml", 4, 1, |_| {});
    let setting = Setting::denoise();
    let method = setting.method.as_ref().expect("a method");
    let (checked, _) = composite(&film, Some(method), setting.target, &setting.stops);
    assert_ne!(checked.pixels, film.raw.pixels, "the filter was dropped on a noisy render");
    // Halves that agree measure no noise: the filter is kept whole. Each half is filtered as a
    // mean of half the samples (at 4 spp each half has two of the four), with twice the
    // variance, its colour stop reading the other half at the taps; the halves' filtered images
    // are then equal, and the output is that image: the pairs of halves through the filter,
    // component by component, added to the emitted light.
    assert!(film.half_share.iter().all(|&s| s == 0.5), "halves of equal size at 4 spp");
    let mut agreeing = film.clone();
    for c in Component::ALL {
        agreeing.component_half[c].pixels =
            film.components[c].pixels.iter().zip(&film.half_share).map(|(&p, &s)| p * s).collect();
    }
    let Some(Method::Atrous(a)) = setting.method.as_ref() else { panic!("--denoise is not atrous") };
    let split = [Component::Direct, Component::Caustic, Component::Indirect];
    let doubled: Vec<Vec<f32>> =
        split.iter().map(|&c| agreeing.component_variance[c].iter().map(|v| v * 2.0).collect()).collect();
    let live: Vec<usize> = (0..3).filter(|&i| !agreeing.components[split[i]].is_black()).collect();
    let (agreed, doubled) = (&agreeing, &doubled);
    let inputs: Vec<FilterInput> = live
        .iter()
        .enumerate()
        .flat_map(|(n, &i)| {
            (0..2).map(move |h| FilterInput {
                image: &agreed.components[split[i]].pixels,
                variance: Some(&doubled[i]),
                component: Some(split[i]),
                halves: None,
                stops_from: Some(2 * n + 1 - h),
            })
        })
        .collect();
    let halves = lightsplit::filter::atrous::filter(&inputs, &agreeing, a, setting.stops.pure);
    let mut whole = agreeing.components[Component::Emitted].clone();
    for (i, &c) in split.iter().enumerate() {
        let image = match live.iter().position(|&l| l == i) {
            Some(n) => {
                assert!(halves[2 * n] == halves[2 * n + 1], "the halves' filtered images differ");
                &halves[2 * n][..]
            }
            None => &agreeing.components[c].pixels[..],
        };
        whole.pixels.iter_mut().zip(image).for_each(|(o, p)| *o += *p);
    }
    let kept = composite(&agreeing, Some(method), setting.target, &setting.stops).0.into_owned();
    assert_ne!(kept.pixels, agreeing.raw.pixels, "nothing filtered");
    assert_eq!(kept.pixels, whole.pixels);
}
