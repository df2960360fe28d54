//! Rendering: camera rays, the sampler, lights, the path integrator, and the driver that renders
//! tiles in parallel with rayon and gathers them into a [`crate::film::Image`].

pub mod bsdf;
pub mod camera;
pub mod integrator;
pub mod lights;
pub mod sampler;
pub mod surface;

use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::{self, Accel, Backend};
use crate::film::Film;
use crate::scene::Scene;
use camera::PinholeCamera;
use integrator::Integrator;
use lights::Lights;
use sampler::Sampler;

/// How many non-finite samples `debug_nonfinite` prints.
const MAX_REPORTS: u32 = 20;

/// Tile edge in pixels: small enough to balance two to many cores, large enough to be cheap.
pub const TILE: u32 = 16;

/// What to render; the scene file gives the defaults.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub seed: u64,
    /// Worker threads; `None` for one per core.
    pub threads: Option<usize>,
    pub accel: Backend,
    /// Print each dropped non-finite sample (the first few): pixel, sample index, path.
    pub debug_nonfinite: bool,
}

impl RenderOptions {
    /// The scene file's settings.
    pub fn from_scene(scene: &Scene) -> Self {
        RenderOptions {
            width: scene.film.width,
            height: scene.film.height,
            spp: scene.film.spp,
            max_depth: scene.render.max_depth,
            seed: scene.render.seed,
            threads: None,
            accel: Backend::Embree,
            debug_nonfinite: false,
        }
    }
}

/// Counts from one render.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderStats {
    /// Wall-clock seconds spent tracing (after the accelerator was built).
    pub seconds: f64,
    /// Seconds spent building the accelerator.
    pub build_seconds: f64,
    /// Path samples taken.
    pub samples: u64,
    /// Rays traced: camera, bounce and shadow rays.
    pub rays: u64,
    /// Samples dropped because their value was NaN or infinite.
    pub nonfinite_samples: u64,
}

/// A finished render.
pub struct RenderOutput {
    pub film: Film,
    pub stats: RenderStats,
}

/// An error while rendering (the scene itself was valid).
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Accel(#[from] accel::AccelError),
    #[error("the image size {0}x{1} is empty or too large")]
    Size(u32, u32),
}

/// Renders `scene` with `options`; `progress` is called with the number of pixels of each
/// finished tile, from worker threads.
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<RenderOutput, RenderError> {
    if options.width == 0 || options.height == 0 || options.width as u64 * options.height as u64 > 1 << 30 {
        return Err(RenderError::Size(options.width, options.height));
    }
    let run = || -> Result<RenderOutput, accel::AccelError> {
        // Build, then render with the backend's own monomorphised integrator.
        let start = Instant::now();
        let built = |mut out: RenderOutput| {
            out.stats.build_seconds = start.elapsed().as_secs_f64() - out.stats.seconds;
            out
        };
        Ok(match options.accel {
            Backend::Embree => {
                built(render_with(scene, &accel::build_embree(scene, options.threads)?, options, progress))
            }
            Backend::Bvh => built(render_with(scene, &accel::bvh::Bvh::new(scene)?, options, progress)),
        })
    };
    Ok(match options.threads {
        Some(n) => accel::thread_pool(n)?.install(run)?,
        None => run()?,
    })
}

/// One pixel's means over its samples (the object ID is sample 0's, never averaged).
#[derive(Clone, Copy, Default)]
struct Pixel {
    beauty: Vec3,
    components: [Vec3; 4],
    albedo: Vec3,
    normal: Vec3,
    depth: f32,
    object: Option<u32>,
    /// Samples that saw the same object as sample 0.
    same: u32,
}

/// One tile's pixels and counts.
struct Tile {
    x0: u32,
    y0: u32,
    w: u32,
    pixels: Vec<Pixel>,
    rays: u64,
    nonfinite: u64,
}

/// Renders with a given accelerator, on the current rayon pool. The image depends only on the
/// scene, the options and the seed: never on the thread count or the order of tiles.
pub fn render_with<A: Accel>(
    scene: &Scene,
    accel: &A,
    options: &RenderOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> RenderOutput {
    let start = Instant::now();
    let (width, height) = (options.width, options.height);
    let camera = PinholeCamera::new(&scene.camera, width, height);
    let lights = Lights::new(scene);
    let integrator = Integrator { scene, accel, lights: &lights, max_depth: options.max_depth };
    let spp = options.spp.max(1);
    let reported = AtomicU32::new(0);

    let tiles: Vec<(u32, u32)> = (0..height.div_ceil(TILE))
        .flat_map(|ty| (0..width.div_ceil(TILE)).map(move |tx| (tx * TILE, ty * TILE)))
        .collect();
    let done: Vec<Tile> = tiles
        .par_iter()
        .map(|&(x0, y0)| {
            let (w, h) = (TILE.min(width - x0), TILE.min(height - y0));
            let mut tile =
                Tile { x0, y0, w, pixels: Vec::with_capacity((w * h) as usize), rays: 0, nonfinite: 0 };
            for y in y0..y0 + h {
                for x in x0..x0 + w {
                    let pixel = y as u64 * width as u64 + x as u64;
                    let mut sum = Pixel::default();
                    for i in 0..spp {
                        let mut sampler = Sampler::new(options.seed, pixel, i as u64);
                        let ray = camera.ray(x, y, sampler.next_2d());
                        let s = integrator.sample(ray, &mut sampler, &mut tile.rays);
                        if i == 0 {
                            sum.object = s.object;
                        }
                        sum.same += (s.object == sum.object) as u32;
                        if !s.beauty.is_finite() || s.components.iter().any(|c| !c.is_finite()) {
                            tile.nonfinite += 1;
                            if options.debug_nonfinite && reported.fetch_add(1, Ordering::Relaxed) < MAX_REPORTS {
                                // The sampler is a pure function of (seed, pixel, sample): the
                                // same path again, recorded.
                                let mut sampler = Sampler::new(options.seed, pixel, i as u64);
                                let ray = camera.ray(x, y, sampler.next_2d());
                                let mut path = Vec::new();
                                let again = integrator.sample_recorded(ray, &mut sampler, &mut 0, &mut path);
                                eprintln!(
                                    "non-finite sample dropped at pixel ({x}, {y}), sample {i}: radiance {}\n{}",
                                    again.beauty,
                                    path.join("\n")
                                );
                            }
                            continue; // dropped: counts as a zero sample
                        }
                        sum.beauty += s.beauty;
                        for (a, c) in sum.components.iter_mut().zip(s.components) {
                            *a += c;
                        }
                        sum.albedo += s.albedo;
                        sum.normal += s.normal;
                        sum.depth += s.depth;
                    }
                    let inv = 1.0 / spp as f32;
                    sum.beauty *= inv;
                    sum.components = sum.components.map(|c| c * inv);
                    sum.albedo *= inv;
                    sum.normal = sum.normal.normalize_or_zero();
                    sum.depth *= inv;
                    tile.pixels.push(sum);
                }
            }
            progress((w * h) as u64);
            tile
        })
        .collect();

    let mut film = Film::new(width, height);
    let mut stats = RenderStats { samples: width as u64 * height as u64 * spp as u64, ..Default::default() };
    for tile in done {
        for (i, p) in tile.pixels.iter().enumerate() {
            let (x, y) = (tile.x0 + i as u32 % tile.w, tile.y0 + i as u32 / tile.w);
            film.raw.set(x, y, p.beauty);
            for (layer, c) in film.components.iter_mut().zip(p.components) {
                layer.set(x, y, c);
            }
            film.albedo.set(x, y, p.albedo);
            film.normal.set(x, y, p.normal);
            let at = (y * width + x) as usize;
            film.depth[at] = p.depth;
            film.object[at] = p.object.map_or(-1.0, |o| o as f32);
            film.coverage[at] = p.same as f32 / spp as f32;
        }
        stats.rays += tile.rays;
        stats.nonfinite_samples += tile.nonfinite;
    }
    stats.seconds = start.elapsed().as_secs_f64();
    RenderOutput { film, stats }
}
