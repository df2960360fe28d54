//! Criterion benchmark of path samples: the time of one sample (camera ray, bounces, shadow
//! rays, the component split), for the Cornell box and the paper's two scenes, on Embree.

use std::path::Path;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use lightsplit::accel::build_embree;
use lightsplit::render::camera::PinholeCamera;
use lightsplit::render::integrator::Integrator;
use lightsplit::render::lights::Lights;
use lightsplit::render::sampler::Sampler;
use lightsplit::render::surface::FaceNormals;
use lightsplit::scene;

fn bench(c: &mut Criterion) {
    // The command line's pool: its main thread among the pool's threads.
    lightsplit::accel::join_global_pool();
    let mut group = c.benchmark_group("path sample");
    const SAMPLES: u64 = 4096;
    group.throughput(Throughput::Elements(SAMPLES));
    for name in ["cornell", "paper-sky", "paper-gallery"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}.toml"));
        let scene = scene::load(&path).expect("scene loads");
        let accel = build_embree(&scene, None).expect("embree builds");
        let lights = Lights::new(&scene, scene.render.light_sampler);
        let faces = FaceNormals::new(&scene);
        let paths = lightsplit::render::paths::PathExprs::new(&lights);
        // The general integrator (every feature); `bench-features` measures the specialised ones.
        let integrator: Integrator<'_, _> = Integrator::of_scene(&scene, &accel, &lights, &paths, &faces, 1);
        let (w, h) = (scene.film.width, scene.film.height);
        let camera = PinholeCamera::new(&scene.camera, w, h);
        group.bench_function(BenchmarkId::new(name, SAMPLES), |b| {
            b.iter(|| {
                // Samples spread over the image, as a render takes them.
                let mut rays = 0u64;
                let mut sum = glam::Vec3::ZERO;
                for i in 0..SAMPLES as u32 {
                    let (x, y) = ((i * 7919) % w, (i * 104_729 / w) % h);
                    let mut sampler = Sampler::new(1, (y * w + x) as u64, i as u64);
                    let ray = camera.ray(x, y, sampler.next_2d());
                    sum += integrator.sample(ray, &mut sampler, &mut rays).beauty;
                }
                sum
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
