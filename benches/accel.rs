//! Criterion benchmarks of the accelerator kernels that `bench-accel` measures: BVH and Embree
//! builds, and tracing the same primary, shadow and incoherent ray sets on one thread (the BVH
//! with its AVX2 slab test and with the portable one), on the Cornell box and on a
//! 100-thousand-triangle terrain generated in code.

use std::path::Path;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use lightsplit::accel::{build_embree, bvh::Bvh};
use lightsplit::bench::rays::{RayKind, RaySets};
use lightsplit::bench::trace_pass;
use lightsplit::scene::{self, Scene};

fn scenes() -> Vec<(&'static str, Scene)> {
    let cornell = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml");
    let terrain = r#"
        [camera]
        position = [0, 9, -26]
        look_at = [0, 0, 0]
        fov = 45
        [[shape]]
        type = "terrain"
        resolution = 224
        size = 40
        height = 6
        [[light]]
        type = "sun"
        direction = [0.6, 0.5, -0.4]
        irradiance = [3, 3, 3]
    "#;
    vec![
        ("cornell", scene::load(&cornell).expect("cornell loads")),
        ("terrain-100k", scene::file::parse(Path::new("terrain.toml"), terrain).expect("terrain parses")),
    ]
}

fn bench(c: &mut Criterion) {
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a pool");
    for (name, scene) in scenes() {
        let embree = build_embree(&scene, None).expect("embree");
        let bvh = Bvh::new(&scene).expect("bvh");
        // The same tree with the portable slab test and (where the CPU runs both) with the
        // AVX2 kernels beside the AVX-512 ones: what each kernel is worth.
        let portable = Bvh::new(&scene).expect("bvh").portable();
        let avx2 = lightsplit::accel::bvh::simd::Isa::avx2()
            .filter(|_| bvh.isa().name() == "avx512")
            .map(|isa| Bvh::new(&scene).expect("bvh").with_isa(isa));
        let sets = RaySets::generate(&scene, &embree, 50_000, 1);

        let mut builds = c.benchmark_group(format!("build/{name}"));
        builds.sample_size(10);
        builds.bench_function("embree", |b| b.iter(|| build_embree(&scene, None).expect("embree")));
        builds.bench_function("bvh", |b| b.iter(|| Bvh::new(&scene).expect("bvh")));
        builds.finish();

        for kind in RayKind::ALL {
            let rays = sets.get(kind);
            let mut group = c.benchmark_group(format!("trace/{name}/{}", kind.name()));
            group.throughput(Throughput::Elements(rays.len() as u64));
            group.sample_size(20);
            group.bench_function(BenchmarkId::from_parameter("embree"), |b| {
                b.iter(|| one.install(|| trace_pass(&embree, rays, kind)))
            });
            group.bench_function(BenchmarkId::from_parameter("bvh"), |b| {
                b.iter(|| one.install(|| trace_pass(&bvh, rays, kind)))
            });
            group.bench_function(BenchmarkId::from_parameter("bvh-portable"), |b| {
                b.iter(|| one.install(|| trace_pass(&portable, rays, kind)))
            });
            if let Some(avx2) = &avx2 {
                group.bench_function(BenchmarkId::from_parameter("bvh-avx2"), |b| {
                    b.iter(|| one.install(|| trace_pass(avx2, rays, kind)))
                });
            }
            group.finish();
        }
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
