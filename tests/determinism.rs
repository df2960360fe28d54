//! The same seed gives the same image, bit for bit, whatever the thread count.

use std::path::Path;

use lightsplit::render::sampler::SamplerKind;
use lightsplit::render::{render, RenderOptions};
use lightsplit::scene;

fn cornell(threads: usize, seed: u64, sampler: SamplerKind) -> lightsplit::film::Image {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml");
    let scene = scene::load(&path).expect("cornell loads");
    let mut options = RenderOptions::from_scene(&scene);
    options.width = 40; // not a multiple of the tile size, to cover partial tiles
    options.height = 36;
    options.spp = 4;
    options.seed = seed;
    options.sampler = sampler;
    options.threads = Some(threads);
    render(&scene, &options, &|_| {}).expect("renders").film.raw
}

#[test]
fn same_seed_same_image_on_one_and_two_threads() {
    let bits = |img: &lightsplit::film::Image| -> Vec<u32> {
        img.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect()
    };
    for sampler in SamplerKind::ALL {
        let one = cornell(1, 7, sampler);
        let two = cornell(2, 7, sampler);
        assert_eq!(bits(&one), bits(&two), "{sampler}");
        assert!(one.mean().x > 0.0);
    }
    // The samplers draw different numbers.
    assert_ne!(bits(&cornell(2, 7, SamplerKind::Independent)), bits(&cornell(2, 7, SamplerKind::Sobol)));
}

#[test]
fn another_seed_gives_another_image() {
    // The seed changes the Sobol scrambling as it changes the independent streams.
    for sampler in SamplerKind::ALL {
        let a = cornell(2, 7, sampler);
        let b = cornell(2, 8, sampler);
        let differing = a.pixels.iter().zip(&b.pixels).filter(|(p, q)| p != q).count();
        // With 4 spp nearly every lit pixel differs.
        assert!(differing > a.pixels.len() / 2, "{sampler}: only {differing} pixels differ");
    }
}
