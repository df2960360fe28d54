//! The same seed gives the same image, bit for bit, whatever the thread count.

use std::path::Path;

use lightsplit::render::{render, RenderOptions};
use lightsplit::scene;

fn cornell(threads: usize, seed: u64) -> lightsplit::film::Image {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.toml");
    let scene = scene::load(&path).expect("cornell loads");
    let mut options = RenderOptions::from_scene(&scene);
    options.width = 40; // not a multiple of the tile size, to cover partial tiles
    options.height = 36;
    options.spp = 4;
    options.seed = seed;
    options.threads = Some(threads);
    render(&scene, &options, &|_| {}).expect("renders").film.raw
}

#[test]
fn same_seed_same_image_on_one_and_two_threads() {
    let one = cornell(1, 7);
    let two = cornell(2, 7);
    let bits = |img: &lightsplit::film::Image| -> Vec<u32> {
        img.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect()
    };
    assert_eq!(bits(&one), bits(&two));
    assert!(one.mean().x > 0.0);
}

#[test]
fn another_seed_gives_another_image() {
    let a = cornell(2, 7);
    let b = cornell(2, 8);
    let differing = a.pixels.iter().zip(&b.pixels).filter(|(p, q)| p != q).count();
    // With 4 spp nearly every lit pixel differs.
    assert!(differing > a.pixels.len() / 2, "only {differing} pixels differ");
}
