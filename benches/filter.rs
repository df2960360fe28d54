//! Criterion benchmarks of one filter pass (the paper's filters, plain and edge-aware) and of one
//! `compare`, at 256x256 and at 3840x2160, on a noisy film with several objects.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::Vec3;
use lightsplit::component::Component::{Caustic, Direct, Indirect};
use lightsplit::film::Film;
use lightsplit::filter::{composite, filter, EdgeStops, Method, Target};

fn noisy_film(width: u32, height: u32) -> Film {
    let mut film = Film::new(width, height);
    let mut state = 0x9e37_79b9u32;
    for i in 0..(width * height) as usize {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        let p = Vec3::splat((state >> 8) as f32 / 16_777_216.0);
        film.components[Indirect].pixels[i] = p;
        let (x, y) = (i as u32 % width, i as u32 / width);
        film.object[i] = ((x / 64 + y / 64) % 5) as f32;
        // Direct light smooth and nearly clean, caustics zero, as on most scenes.
        film.components[Direct].pixels[i] = Vec3::splat(0.5 + 0.01 * p.x);
        film.components[Caustic].pixels[i] = Vec3::ZERO;
        film.albedo.pixels[i] = Vec3::new(0.8, 0.6, 0.4);
        film.coverage[i] = 1.0;
        film.variance[i] = 0.01;
        film.component_variance[Direct][i] = 1e-5;
        film.component_variance[Indirect][i] = 0.01;
        film.normal.pixels[i] = Vec3::Z;
        film.depth[i] = 1.0;
        // Two halves of 32 samples that differ by the noise: the check runs as on a render.
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        let q = Vec3::splat((state >> 8) as f32 / 16_777_216.0);
        film.component_half[Indirect].pixels[i] = 0.5 * q;
        film.component_half[Direct].pixels[i] = 0.5 * film.components[Direct].pixels[i];
        film.half_share[i] = 0.5;
    }
    film
}

fn bench(c: &mut Criterion) {
    // The command line's pool: its main thread among the pool's threads.
    lightsplit::accel::join_global_pool();
    for (w, h) in [(256, 256), (3840, 2160)] {
        let film = noisy_film(w, h);
        let mut group = c.benchmark_group(format!("filter/{w}x{h}"));
        group.sample_size(10);
        for name in ["box3", "weighted3", "median3", "box5"] {
            let kernel = Method::parse(name).expect("kernel");
            group.bench_function(BenchmarkId::new(name, "plain"), |b| {
                b.iter(|| filter(film.indirect(), &kernel, &film, &EdgeStops::default()))
            });
            let stops = EdgeStops { object: true, ..Default::default() };
            group.bench_function(BenchmarkId::new(name, "edge-aware"), |b| {
                b.iter(|| filter(film.indirect(), &kernel, &film, &stops))
            });
        }
        // The à-trous filter through `composite`, as `render` runs it: on indirect alone, and
        // on every component (caustic is zero, so two layers are filtered).
        // What `--denoise` runs, the time budget: 10 ms at 256x256, 1.5 s at 4K.
        // With the check against the halves (the default), and without it (`cross=0`).
        let denoise = lightsplit::filter::Setting::denoise();
        group.bench_function(BenchmarkId::new("denoise", denoise.target.name()), |b| {
            b.iter(|| composite(&film, denoise.method.as_ref(), denoise.target, &denoise.stops))
        });
        let unchecked = match denoise.method.clone() {
            Some(Method::Atrous(a)) => {
                Method::Atrous(lightsplit::filter::atrous::Atrous { cross: false, ..a })
            }
            other => other.expect("a method"),
        };
        group.bench_function(BenchmarkId::new("denoise-cross0", denoise.target.name()), |b| {
            b.iter(|| composite(&film, Some(&unchecked), denoise.target, &denoise.stops))
        });
        for (spec, target) in [
            ("atrous:taps=3:passes=4:sigma_l=6:sigma_n=32:sigma_z=2", Target::Indirect),
            ("atrous", Target::Indirect),
            ("atrous", Target::Components),
        ] {
            let kernel = Method::parse(spec).expect("kernel");
            let stops = EdgeStops::default();
            group.bench_function(BenchmarkId::new(spec, target.name()), |b| {
                b.iter(|| composite(&film, Some(&kernel), target, &stops))
            });
        }
        group.finish();
    }
    // One `compare` (the paper's metric, RMSE, relMSE and the trimmed pair) of two images.
    let mut group = c.benchmark_group("compare");
    group.sample_size(10);
    for (w, h) in [(256, 256), (3840, 2160)] {
        let a = noisy_film(w, h);
        let mut b = noisy_film(w, h);
        b.components[Indirect].pixels.iter_mut().for_each(|p| *p *= 1.01);
        group.bench_function(BenchmarkId::new("compare", format!("{w}x{h}")), |bench| {
            bench.iter(|| lightsplit::metrics::compare(a.indirect(), b.indirect()).expect("same size"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
