//! Rendering: camera rays, the sampler, lights, the path integrator, and the driver that renders
//! tiles in parallel with rayon and gathers them into a [`crate::film::Image`].

pub mod bsdf;
pub mod camera;
pub mod features;
pub mod guide;
pub mod integrator;
pub mod lights;
pub mod material;
pub mod paths;
pub mod sampler;
pub mod splat;
pub mod surface;

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::{self, Accel, Backend, Ray};
use crate::accel::{BuildHints, UseAccel, PACKET};
use crate::component::Split;
use crate::film::{self, cryptomatte, Film, Sums};
use crate::scene::analysis::Analysis;
use crate::scene::{Aov, Guiding, LightSamplerKind, Scene};
use camera::PinholeCamera;
pub use features::{Features, Outputs};
use guide::{Guide, RadianceRecord};
use integrator::{Integrator, PathSample};
use lights::Lights;
use sampler::{PixelSampler, Sampler, SamplerKind};
use std::sync::Arc;

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
    /// Which numbers the paths draw: Owen-scrambled Sobol points or independent streams.
    pub sampler: SamplerKind,
    /// How next-event estimation picks a light among many.
    pub light_sampler: LightSamplerKind,
    /// Whether directions at diffuse-like vertices are guided by the learned incident light,
    /// and what the guide learns from.
    pub guiding: Guiding,
    /// The guide to render with (read from a file); `None` trains one first when guided.
    pub guide: Option<Arc<Guide>>,
    /// Worker threads; `None` for one per core.
    pub threads: Option<usize>,
    pub accel: Backend,
    /// Print each dropped non-finite sample (the first few): pixel, sample index, path.
    pub debug_nonfinite: bool,
    /// Image textures filtered over the camera ray cone's footprint by their mipmaps (true by
    /// default); false: looked up at a point.
    pub texture_filter: bool,
    /// What the integrator computes: by default what the scene needs for every layer.
    pub features: Features,
    /// How the accelerator builds the scene: by default what the scene needs.
    pub build: BuildHints,
    /// Adaptive sampling: stop a pixel once the relative standard error of its mean falls to
    /// this (checked after 16, 32, 64, ... samples; `spp` is the most a pixel takes).
    pub adaptive: Option<f32>,
    /// Which of each pixel's `spp` samples this render takes (all, by default).
    pub part: Part,
    /// Output layers of light path expressions (the scene file's `[[aov]]`, then `--aov`).
    pub aovs: Vec<Aov>,
    /// Cryptomatte's object and material mattes (`CryptoObject`, `CryptoMaterial`): each
    /// pixel's coverage by the camera rays' first hits.
    pub cryptomatte: bool,
}

/// A share of each pixel's samples: part `index` of `count` takes samples `index spp / count`
/// up to `(index + 1) spp / count` (sample `k` of a pixel always draws the same numbers, so
/// the parts of a render take exactly the samples the whole would).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Part {
    pub index: u32,
    pub count: u32,
}

impl Default for Part {
    fn default() -> Self {
        Part { index: 0, count: 1 }
    }
}

impl Part {
    /// The sample indices of this part of `spp`.
    pub fn samples(self, spp: u32) -> Range<u32> {
        let at = |i: u32| (i as u64 * spp as u64 / self.count.max(1) as u64) as u32;
        at(self.index)..at(self.index + 1)
    }

    /// Whether this is the whole render.
    pub fn is_whole(self) -> bool {
        self.count <= 1
    }

    /// Checks that this is a part of a render of `spp`: one of its `count` (`index` below it),
    /// and `count` at most `spp`, so that every part takes at least one sample of each pixel.
    /// More parts than samples would make parts of no samples, whose files merge to nothing,
    /// and a count of billions that a merge would have to account for.
    pub fn check(self, spp: u32) -> Result<(), String> {
        if self.count == 0 || self.index >= self.count {
            return Err(format!("part {self} does not exist (0 <= I < N)"));
        }
        if self.count > spp {
            return Err(format!(
                "part {self} of a render of {spp} spp: a render splits into at most as many parts as \
                 it has samples a pixel ({spp}), so that each part takes at least one"
            ));
        }
        Ok(())
    }
}

impl std::fmt::Display for Part {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// What writes a checkpoint: given the sums so far, with each pixel's sample count.
pub type Checkpoint<'a> = dyn Fn(&Sums) + Sync + 'a;

/// How a render runs beyond its options: progress, stopping, checkpoints, resuming.
pub struct Control<'a> {
    /// Called with the number of samples each tile pass has done, from worker threads.
    pub progress: &'a (dyn Fn(u64) + Sync),
    /// Once set, the render ends after the pass under way: every pixel keeps the samples of
    /// the passes done.
    pub stop: Option<&'a AtomicBool>,
    /// Seconds of rendering after which the render ends at a pass boundary: the last pass it
    /// starts is one that, at the pace so far, ends within the limit (the first pass always
    /// runs).
    pub time_limit: Option<f64>,
    /// Every so many seconds, at the end of a pass, called with the sums so far and the
    /// samples of each pixel (a checkpoint).
    pub checkpoint: Option<(f64, &'a Checkpoint<'a>)>,
    /// Continue from these sums (a checkpoint of a render with the same scene and options).
    pub resume: Option<Sums>,
    /// Keep the sums in [`RenderOutput::sums`].
    pub keep_sums: bool,
}

impl<'a> Control<'a> {
    /// Progress alone.
    pub fn progress(progress: &'a (dyn Fn(u64) + Sync)) -> Control<'a> {
        Control { progress, stop: None, time_limit: None, checkpoint: None, resume: None, keep_sums: false }
    }
}

/// What a file records of a render of `scene` with `options` that took `seconds`
/// ([`film::Metadata`]): the scene file, the settings that reproduce it, its time and the
/// camera's matrices. The filter, when there is one, is the caller's to add.
pub fn metadata(scene: &Scene, options: &RenderOptions, seconds: f64) -> film::Metadata {
    let (world_to_camera, world_to_ndc) =
        camera::exr_matrices(&scene.camera, scene.origin, options.width, options.height);
    film::Metadata {
        scene: Some(scene.path.to_string_lossy().into_owned()),
        spp: Some(options.spp),
        seed: Some(options.seed),
        max_depth: Some(options.max_depth),
        sampler: Some(options.sampler.name().to_string()),
        render_seconds: Some(seconds),
        filter: None,
        world_to_camera: Some(world_to_camera),
        world_to_ndc: Some(world_to_ndc),
        extra: [
            ("lightsplit.light_sampler".into(), options.light_sampler.name().into()),
            ("lightsplit.guiding".into(), options.guiding.name().into()),
        ]
        .into_iter()
        .chain((!options.aovs.is_empty()).then(|| {
            let names: Vec<&str> = options.aovs.iter().map(|a| a.name.as_str()).collect();
            (film::AOVS_ATTRIBUTE.into(), names.join(","))
        }))
        .chain((!options.aovs.is_empty()).then(|| {
            let lpes: Vec<String> = options.aovs.iter().map(|a| format!("{}={}", a.name, a.lpe)).collect();
            (film::AOV_LPES_ATTRIBUTE.into(), lpes.join(";"))
        }))
        .collect(),
        compression: film::ExrCompression::default(),
    }
}

impl RenderOptions {
    /// The scene file's settings, and the features its analysis says a render with every
    /// layer needs.
    pub fn from_scene(scene: &Scene) -> Self {
        let analysis = Analysis::of(scene);
        RenderOptions {
            width: scene.film.width,
            height: scene.film.height,
            spp: scene.film.spp,
            max_depth: scene.render.max_depth,
            seed: scene.render.seed,
            sampler: scene.render.sampler,
            light_sampler: scene.render.light_sampler,
            guiding: scene.render.guiding,
            guide: None,
            threads: None,
            accel: Backend::Embree,
            debug_nonfinite: false,
            texture_filter: true,
            features: Features::needed(&analysis, Outputs::ALL),
            build: BuildHints::for_scene(&analysis),
            adaptive: None,
            part: Part::default(),
            aovs: scene.aovs.clone(),
            cryptomatte: false,
        }
    }
}

/// The bytes a pixel that a render's AOVs and Cryptomatte types add to its film at most. Each
/// AOV: its sums, a splatted tile's over the tile and its margin (up to about twice the
/// pixels), the copy a part keeps and its output channels. Each type: its coverage in the
/// film, in splatted tiles (twice) and in the copy a part keeps, its part file's words (at
/// most 2 + 3 x 16 words) and its rank channels (12 floats).
pub fn layer_bytes(options: &RenderOptions) -> u64 {
    let aov = 5 * size_of::<Vec3>() as u64;
    let coverage = size_of::<cryptomatte::Coverage>() as u64;
    let matte =
        4 * coverage + 4 * (4 + 3 * cryptomatte::CAP as u64) + 4 * 2 * cryptomatte::DEFAULT_RANKS as u64;
    options.aovs.len() as u64 * aov + matte_kinds(options).len() as u64 * matte
}

/// The Cryptomatte types a render with `options` writes, in the order a film keeps them.
pub fn matte_kinds(options: &RenderOptions) -> Vec<&'static str> {
    match options.cryptomatte {
        true => vec![cryptomatte::MATERIAL, cryptomatte::OBJECT],
        false => Vec::new(),
    }
}

/// The id at index `i` of `ids`, or the empty name's.
fn id_of(ids: &[u32], i: u32) -> u32 {
    ids.get(i as usize).copied().unwrap_or_else(|| cryptomatte::name_id(""))
}

/// The film's Cryptomatte types for `scene` ([`matte_kinds`], whose order, by name, a part
/// file's also has), empty, over `pixels` pixels; and each shape's id in each, in that order.
fn mattes(scene: &Scene, options: &RenderOptions, pixels: usize) -> (Vec<cryptomatte::Matte>, Vec<[u32; 2]>) {
    if !options.cryptomatte {
        return (Vec::new(), Vec::new());
    }
    let materials = scene.material_name_list();
    let materials: Vec<&str> = materials.iter().map(|m| m.as_ref()).collect();
    let objects: Vec<&str> = scene.objects.iter().map(String::as_str).collect();
    // Each name hashed once; a shape's index past the lists (none is) takes the empty name's.
    let id = |names: &[&str], i: u32| {
        names.get(i as usize).map_or(cryptomatte::name_id(""), |n| cryptomatte::name_id(n))
    };
    let (material_ids, object_ids): (Vec<u32>, Vec<u32>) = (
        (0..materials.len() as u32).map(|m| id(&materials, m)).collect(),
        (0..objects.len() as u32).map(|o| id(&objects, o)).collect(),
    );
    let ids = scene
        .shapes
        .iter()
        .map(|s| [id_of(&material_ids, s.material), id_of(&object_ids, s.object)])
        .collect();
    let mattes = vec![
        cryptomatte::Matte::new(cryptomatte::MATERIAL, &materials, pixels),
        cryptomatte::Matte::new(cryptomatte::OBJECT, &objects, pixels),
    ];
    (mattes, ids)
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
    /// Bytes of the per-pixel buffers the render filled: the film and the tiles' pixels.
    pub buffer_bytes: u64,
    /// Pixels adaptive sampling stopped before the spp.
    pub stopped_early: u64,
    /// The fewest and the most samples a pixel took (of this render's range, those it resumed
    /// included).
    pub min_spp: u32,
    pub max_spp: u32,
    /// Whether a stop or the time limit ended the render before its samples were all taken.
    pub interrupted: bool,
}

/// A finished render.
pub struct RenderOutput {
    pub film: Film,
    pub stats: RenderStats,
    /// The sums, when [`Control::keep_sums`] asked for them.
    pub sums: Option<Sums>,
    /// The guide the render used, when guided (trained by it, or given).
    pub guide: Option<Arc<Guide>>,
}

/// An error while rendering (the scene itself was valid).
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Accel(#[from] accel::AccelError),
    #[error("the image size {0}x{1} is empty or too large")]
    Size(u32, u32),
    /// The sums to resume from do not fit the render.
    #[error("cannot resume: {0}")]
    Resume(String),
    /// The part asked for is not one of the render ([`Part::check`]).
    #[error("{0}")]
    Part(String),
    /// The AOVs' expressions cannot be compiled together.
    #[error("{0}")]
    Aovs(String),
}

impl crate::error::Classify for RenderError {
    /// Whether the request itself was bad (a part or a checkpoint that does not fit), rather
    /// than the rendering.
    fn is_input(&self) -> bool {
        matches!(self, RenderError::Resume(_) | RenderError::Part(_) | RenderError::Aovs(_))
    }
}

/// Renders `scene` with `options`; `progress` is called with the number of samples each tile
/// pass has done (a converged pixel's skipped samples count as done), from worker threads.
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<RenderOutput, RenderError> {
    render_controlled(scene, options, Control::progress(progress))
}

/// [`render`] under `control`: stopped, time-limited, checkpointed or resumed.
pub fn render_controlled(
    scene: &Scene,
    options: &RenderOptions,
    control: Control,
) -> Result<RenderOutput, RenderError> {
    let pixels = options.width as u64 * options.height as u64;
    if pixels == 0 || pixels > crate::scene::limits::MAX_IMAGE_PIXELS {
        return Err(RenderError::Size(options.width, options.height));
    }
    options.part.check(options.spp.max(1)).map_err(RenderError::Part)?;
    // The AOVs' expressions compile together (else `render_with` renders without them).
    let aovs: &[Aov] = if options.features.split { &options.aovs } else { &[] };
    paths::PathExprs::with_aovs(&Lights::default(), aovs, &scene.light_groups.names)
        .map_err(RenderError::Aovs)?;
    if let Some(r) = &control.resume {
        let f = &r.film;
        let (split, guides) = (options.features.split, options.features.guides);
        if (f.width, f.height) != (options.width, options.height) {
            return Err(RenderError::Resume(format!(
                "the checkpoint is {}x{}, the render {}x{}",
                f.width, f.height, options.width, options.height
            )));
        }
        if (f.has_split(), f.has_guides(), !r.squares.is_empty()) != (split, guides, split) {
            return Err(RenderError::Resume("the checkpoint was rendered with other buffers".into()));
        }
        if options.adaptive.is_some() {
            return Err(RenderError::Resume("an adaptive render cannot be resumed".into()));
        }
        let names: Vec<&str> = aovs.iter().map(|a| a.name.as_str()).collect();
        if crate::film::aov_list(&f.aovs) != names.join(",") {
            return Err(RenderError::Resume("the checkpoint was rendered with other AOVs".into()));
        }
        let kinds: Vec<&str> = f.mattes.iter().map(|m| m.kind.as_str()).collect();
        if kinds != matte_kinds(options) {
            return Err(RenderError::Resume(
                "the checkpoint was rendered with other Cryptomatte types".into(),
            ));
        }
        let range = options.part.samples(options.spp.max(1));
        let first = r.samples.first().copied().unwrap_or(0);
        if r.samples.iter().any(|&n| n != first) || first > range.end - range.start {
            return Err(RenderError::Resume(format!(
                "the checkpoint's sample counts are not those of a pass of samples {}..{}",
                range.start, range.end
            )));
        }
    }
    let control = &control;
    let run = || -> Result<RenderOutput, accel::AccelError> {
        // Build, then render with the backend's own monomorphised integrator.
        let start = Instant::now();
        let built = |mut out: RenderOutput| {
            out.stats.build_seconds = start.elapsed().as_secs_f64() - out.stats.seconds;
            out
        };
        /// A render on whichever accelerator was built.
        struct Render<'r> {
            scene: &'r Scene,
            options: &'r RenderOptions,
            control: &'r Control<'r>,
        }
        impl UseAccel for Render<'_> {
            type Output = RenderOutput;
            fn with<A: Accel>(self, accel: &A) -> RenderOutput {
                render_with_control(self.scene, accel, self.options, self.control)
            }
        }
        let render = Render { scene, options, control };
        Ok(built(options.accel.build(scene, options.threads, options.build, render)?))
    };
    Ok(match options.threads {
        Some(n) => accel::thread_pool(n)?.install(run)?,
        None => run()?,
    })
}

/// One pixel's guide sums over its samples, and the object of sample 0 (never averaged) with
/// how many samples saw it.
#[derive(Clone, Copy, Default)]
struct GuideSums {
    albedo: Vec3,
    normal: Vec3,
    depth: f32,
    object: Option<u32>,
    same: u32,
    /// Samples that hit a surface.
    hits: u32,
}

/// A tile of the image and what it keeps between passes: the samples each pixel has taken and,
/// for adaptive sampling, each pixel's moments and whether it has converged. Its sums live in
/// the film, so no second image-sized copy of them exists.
struct Tile {
    x0: u32,
    y0: u32,
    w: u32,
    h: u32,
    /// The samples each pixel has taken; for adaptive sampling also the sums of its sample
    /// luminances and of their squares, and whether it has converged (empty otherwise: every
    /// pixel takes the spp).
    n: Vec<u32>,
    moments: Vec<[f64; 2]>,
    converged: Vec<bool>,
    rays: u64,
    nonfinite: u64,
    /// A splatted filter's sums of this pass over the tile and its margin.
    splat: Option<splat::TileSplat>,
}

impl Tile {
    fn new(
        x0: u32,
        y0: u32,
        w: u32,
        h: u32,
        adaptive: bool,
        done: u32,
        splat: Option<splat::TileSplat>,
    ) -> Tile {
        let n = (w * h) as usize;
        let some = if adaptive { n } else { 0 };
        Tile {
            x0,
            y0,
            w,
            h,
            n: vec![done; n],
            moments: vec![[0.0; 2]; some],
            converged: vec![false; some],
            rays: 0,
            nonfinite: 0,
            splat,
        }
    }

    fn bytes(&self) -> u64 {
        (self.n.capacity() * size_of::<u32>()
            + self.moments.capacity() * size_of::<[f64; 2]>()
            + self.converged.capacity()) as u64
            + self.splat.as_ref().map_or(0, splat::TileSplat::bytes)
    }

    fn done(&self) -> bool {
        !self.converged.is_empty() && self.converged.iter().all(|&c| c)
    }

    /// The film index of the tile's pixel `i`, and its coordinates.
    fn pixel(&self, i: usize, width: u32) -> (usize, u32, u32) {
        let (x, y) = (self.x0 + i as u32 % self.w, self.y0 + i as u32 / self.w);
        (y as usize * width as usize + x as usize, x, y)
    }
}

/// A tile's sums while a pass renders it: loaded from the film before, stored back after, so
/// every pixel's sums add up in the order of its samples, pass after pass. The split and the
/// guides are empty when not computed.
struct TileSums {
    beauty: Vec<Vec3>,
    components: Vec<Split<Vec3>>,
    /// Each pixel's AOVs, `naovs` a pixel.
    aovs: Vec<Vec3>,
    naovs: usize,
    /// Each pixel's coverage in each Cryptomatte type, `nmattes` a pixel.
    mattes: Vec<cryptomatte::Coverage>,
    nmattes: usize,
    guides: Vec<GuideSums>,
    /// The sums of the squared sample luminances, of the beauty then of each component (with
    /// the split only), in f64 as [`film::Squares`] keeps them.
    squares: Vec<(f64, Split<f64>)>,
    /// The sums over the samples of each pixel's second half ([`film::half_of`]) of the beauty
    /// and the components, and their count (with the split and unsplatted only).
    halves: Vec<(Vec3, Split<Vec3>, u32)>,
    /// The render's samples per pixel, which say each sample's half.
    spp: u32,
    /// Whether the beauty and the components are splatted ([`splat`]): then a sample adds
    /// them to its tile's splats, not to its pixel's sums here.
    splatted: bool,
}

impl TileSums {
    /// The sums of `tile`'s pixels so far, from the render's (of `spp` samples per pixel).
    fn load(tile: &Tile, sums: &Sums, spp: u32) -> TileSums {
        let (film, squares) = (&sums.film, &sums.squares);
        let n = (tile.w * tile.h) as usize;
        let at = |i: usize| tile.pixel(i, film.width).0;
        TileSums {
            beauty: (0..n).map(|i| film.raw.pixels[at(i)]).collect(),
            components: if film.has_split() {
                (0..n).map(|i| Split::from_fn(|c| film.components[c].pixels[at(i)])).collect()
            } else {
                Vec::new()
            },
            aovs: (0..n).flat_map(|i| film.aovs.iter().map(move |a| a.image.pixels[at(i)])).collect(),
            naovs: film.aovs.len(),
            mattes: (0..n)
                .flat_map(|i| film.mattes.iter().filter_map(move |m| m.coverage().map(|c| c[at(i)])))
                .collect(),
            nmattes: film.mattes.len(),
            squares: if squares.is_empty() {
                Vec::new()
            } else {
                (0..n)
                    .map(|i| {
                        let at = at(i);
                        (squares.beauty[at], Split::from_fn(|c| squares.components[c][at]))
                    })
                    .collect()
            },
            halves: if film.has_halves() {
                (0..n)
                    .map(|i| {
                        let at = at(i);
                        let components = Split::from_fn(|c| film.component_half[c].pixels[at]);
                        (film.half.pixels[at], components, film.half_share[at] as u32)
                    })
                    .collect()
            } else {
                Vec::new()
            },
            spp,
            splatted: !sums.weights.is_empty(),
            guides: if film.has_guides() {
                (0..n)
                    .map(|i| {
                        let at = at(i);
                        let object = film.object[at];
                        GuideSums {
                            albedo: film.albedo.pixels[at],
                            normal: film.normal.pixels[at],
                            depth: film.depth[at],
                            object: (object >= 0.0).then_some(object as u32),
                            same: film.coverage[at] as u32,
                            hits: film.alpha[at] as u32,
                        }
                    })
                    .collect()
            } else {
                Vec::new()
            },
        }
    }

    /// Writes the sums back into the render's.
    fn store(&self, tile: &Tile, sums: &mut Sums) {
        let (film, squares) = (&mut sums.film, &mut sums.squares);
        for (i, &beauty) in self.beauty.iter().enumerate() {
            let (at, ..) = tile.pixel(i, film.width);
            film.raw.pixels[at] = beauty;
            if let Some(c) = self.components.get(i) {
                for (layer, &c) in film.components.iter_mut().zip(c) {
                    layer.pixels[at] = c;
                }
            }
            for (layer, &v) in film.aovs.iter_mut().zip(self.aovs_of(i)) {
                layer.image.pixels[at] = v;
            }
            let mattes = self.mattes.get(i * self.nmattes..(i + 1) * self.nmattes).unwrap_or(&[]);
            for (matte, c) in film.mattes.iter_mut().zip(mattes) {
                if let Some(m) = matte.coverage_mut() {
                    m[at] = *c;
                }
            }
            if let Some((beauty, components)) = self.squares.get(i) {
                squares.beauty[at] = *beauty;
                for (layer, &c) in squares.components.iter_mut().zip(components) {
                    layer[at] = c;
                }
            }
            if let Some((beauty, components, n)) = self.halves.get(i) {
                film.half.pixels[at] = *beauty;
                for (layer, &c) in film.component_half.iter_mut().zip(components) {
                    layer.pixels[at] = c;
                }
                film.half_share[at] = *n as f32;
            }
            if let Some(g) = self.guides.get(i) {
                film.albedo.pixels[at] = g.albedo;
                film.normal.pixels[at] = g.normal;
                film.depth[at] = g.depth;
                film.object[at] = g.object.map_or(-1.0, |o| o as f32);
                film.coverage[at] = g.same as f32;
                film.alpha[at] = g.hits as f32;
            }
        }
    }

    /// Sets the object pixel `i` shows: that of its sample 0, traced by a part that does not
    /// take it.
    fn set_object(&mut self, i: usize, object: Option<u32>) {
        if let Some(g) = self.guides.get_mut(i) {
            g.object = object;
        }
    }

    /// Adds a sample of pixel `i` (the pixel's own box: weight 1) to its Cryptomatte coverage:
    /// the ids of what its camera ray hit first (`None`: nothing).
    #[inline]
    fn add_matte(&mut self, i: usize, ids: Option<&[u32; 2]>) {
        let mattes = &mut self.mattes[i * self.nmattes..(i + 1) * self.nmattes];
        for (k, c) in mattes.iter_mut().enumerate() {
            match ids {
                Some(ids) => c.add(ids[k], 1.0),
                None => c.add_none(1.0),
            }
        }
    }

    /// Pixel `i`'s AOVs.
    fn aovs_of(&self, i: usize) -> &[Vec3] {
        self.aovs.get(i * self.naovs..(i + 1) * self.naovs).unwrap_or(&[])
    }

    /// Adds sample `k` of pixel `i`, and its AOVs `aovs`; false when it was dropped as
    /// non-finite (it counts as a zero sample).
    #[inline(always)]
    fn add(
        &mut self,
        i: usize,
        k: u32,
        (s, aovs): (&PathSample, &[Vec3]),
        split: bool,
        moments: Option<&mut [f64; 2]>,
    ) -> bool {
        if let Some(g) = self.guides.get_mut(i) {
            if k == 0 {
                g.object = s.object;
            }
            g.same += (s.object == g.object) as u32;
            g.hits += s.object.is_some() as u32;
        }
        // A dropped sample counts as a zero sample, in its half too.
        let half = film::half_of(k, self.spp);
        if let Some(h) = self.halves.get_mut(i).filter(|_| half) {
            h.2 += 1;
        }
        if !s.beauty.is_finite()
            || (split && s.components.iter().any(|c| !c.is_finite()))
            || aovs.iter().any(|a| !a.is_finite())
        {
            return false;
        }
        if !self.splatted {
            self.beauty[i] += s.beauty;
        }
        if let Some(m) = moments {
            let l = crate::math::luminance(s.beauty) as f64;
            m[0] += l;
            m[1] += l * l;
        }
        if let (Some(c), false) = (self.components.get_mut(i), self.splatted) {
            for (a, c) in c.iter_mut().zip(s.components) {
                *a += c;
            }
        }
        if self.naovs > 0 && !self.splatted {
            let sums = &mut self.aovs[i * self.naovs..(i + 1) * self.naovs];
            for (a, &v) in sums.iter_mut().zip(aovs) {
                *a += v;
            }
        }
        if let Some((beauty, components)) = self.squares.get_mut(i) {
            let sq = |v: Vec3| (crate::math::luminance(v) as f64).powi(2);
            *beauty += sq(s.beauty);
            for (a, c) in components.iter_mut().zip(s.components) {
                *a += sq(c);
            }
        }
        if let Some((beauty, components, _)) = self.halves.get_mut(i).filter(|_| half) {
            *beauty += s.beauty;
            for (a, c) in components.iter_mut().zip(s.components) {
                *a += c;
            }
        }
        if let Some(g) = self.guides.get_mut(i) {
            g.albedo += s.albedo;
            g.normal += s.normal;
            g.depth += s.depth;
        }
        true
    }
}

/// The first pass of an adaptive render takes this many samples a pixel; each later pass
/// doubles the count, up to the render's spp.
pub const ADAPTIVE_FIRST_PASS: u32 = 16;

/// Without adaptive sampling, a pass takes this many samples a pixel (a packet of camera rays):
/// a stop, a time limit or a checkpoint waits at most one pass.
pub const PASS: u32 = PACKET as u32;

/// The sample indices at which the passes over `samples` end, after `done` (samples from
/// `samples.start` up to `done` are taken): counted from the start, every [`PASS`]; for
/// adaptive sampling 16, 32, 64 and so on. The last is `samples.end`.
fn pass_ends(samples: Range<u32>, adaptive: bool, done: u32) -> Vec<u32> {
    let len = samples.end - samples.start;
    let mut ends = Vec::new();
    let mut k = if adaptive { ADAPTIVE_FIRST_PASS } else { PASS };
    loop {
        let end = samples.start + k.min(len);
        if end > done {
            ends.push(end);
        }
        if k >= len {
            return ends;
        }
        k = if adaptive { k.saturating_mul(2) } else { k.saturating_add(PASS) };
    }
}

/// The relative standard error of a pixel's mean from its `n` sample luminances' sum and sum of
/// squares; 0 for a pixel that was black in every sample.
pub fn relative_error(n: u32, sum: f64, sum_sq: f64) -> f64 {
    if n < 2 {
        return f64::INFINITY;
    }
    let var_mean = film::variance_of_mean(n, sum, sum_sq);
    let mean = sum / n as f64;
    if mean <= 0.0 {
        return if var_mean == 0.0 { 0.0 } else { f64::INFINITY };
    }
    var_mean.sqrt() / mean
}

/// Renders with a given accelerator, on the current rayon pool, with the integrator
/// specialised to `options.features`. The image depends only on the scene, the options and the
/// seed: never on the thread count or the order of tiles; the beauty not on the features.
pub fn render_with<A: Accel>(
    scene: &Scene,
    accel: &A,
    options: &RenderOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> RenderOutput {
    render_with_control(scene, accel, options, &Control::progress(progress))
}

/// [`render_with`] under `control` (whose resume state [`render_controlled`] has checked).
pub fn render_with_control<A: Accel>(
    scene: &Scene,
    accel: &A,
    options: &RenderOptions,
    control: &Control,
) -> RenderOutput {
    // Every combination of the four features, each its own integrator: an exhaustive match,
    // so a feature added to `Features` fails to compile here until it is listed.
    macro_rules! specialised {
        ($(($mis:literal, $split:literal, $guides:literal, $textures:literal))*) => {
            match options.features {
                $(Features { mis: $mis, split: $split, guides: $guides, textures: $textures } => {
                    const BITS: u8 = ($mis as u8 * features::MIS)
                        | ($split as u8 * features::SPLIT)
                        | ($guides as u8 * features::GUIDES)
                        | ($textures as u8 * features::TEXTURES);
                    render_features::<A, BITS>(scene, accel, options, control)
                })*
            }
        };
    }
    specialised!((false, false, false, false)(true, false, false, false)(false, true, false, false)(
        true, true, false, false
    )(false, false, true, false)(true, false, true, false)(false, true, true, false)(
        true, true, true, false
    )(false, false, false, true)(true, false, false, true)(false, true, false, true)(
        true, true, false, true
    )(false, false, true, true)(true, false, true, true)(false, true, true, true)(
        true, true, true, true
    ))
}

/// [`render_with`] for one feature set `F`.
fn render_features<A: Accel, const F: u8>(
    scene: &Scene,
    accel: &A,
    options: &RenderOptions,
    control: &Control,
) -> RenderOutput {
    let progress = control.progress;
    let (split, guides) = (F & features::SPLIT != 0, F & features::GUIDES != 0);
    let start = Instant::now();
    let (width, height) = (options.width, options.height);
    let camera = PinholeCamera::of_film(&scene.camera, &scene.film, width, height);
    let lights = Lights::new(scene, options.light_sampler);
    let faces = surface::FaceNormals::new(scene);
    // The AOVs, computed with the split (an EXR's) only; expressions that cannot be compiled
    // together, which `render_controlled` refuses, leave them out.
    let aovs: &[Aov] = if split { &options.aovs } else { &[] };
    let paths = paths::PathExprs::with_aovs(&lights, aovs, &scene.light_groups.names)
        .unwrap_or_else(|_| paths::PathExprs::new(&lights));
    let aov_names: Vec<String> = aovs.iter().take(paths.aovs()).map(|a| a.name.clone()).collect();
    let naovs = aov_names.len();
    let integrator: Integrator<'_, A, F> = Integrator {
        scene,
        accel,
        lights: &lights,
        paths: &paths,
        faces: &faces,
        max_depth: options.max_depth,
        cone: match options.texture_filter {
            true => integrator::Cone::of_camera(&scene.camera, height, options.spp),
            false => integrator::Cone::default(),
        },
        guide: None,
        isa: crate::accel::bvh::simd::Isa::for_loops(),
    };
    // The guide: given, or trained now (the same on any threads, so every part of a split
    // render and a resumed one train the same).
    let mut training_rays = 0;
    let guide = match (options.guiding, &options.guide) {
        (Guiding::Off, _) => None,
        (_, Some(g)) => Some(g.clone()),
        (learns, None) => {
            Some(Arc::new(train_guide(&integrator, scene, options, learns, &mut training_rays)))
        }
    };
    let integrator = Integrator { guide: guide.as_deref(), ..integrator };
    let spp = options.spp.max(1);
    let reported = AtomicU32::new(0);

    let adaptive = options.adaptive;
    let range = options.part.samples(spp);
    // The film holds each pixel's sums (the coverage: how many samples saw the object) until
    // every pass is done, then their means.
    // A filter wider than the pixel is splatted; the pixel's own box is not.
    let weights =
        (!scene.film.pixel_filter.is_pixel_box()).then(|| splat::Weights::new(scene.film.pixel_filter));
    // Cryptomatte's types, and each shape's id in each.
    let (matte_films, matte_ids) = mattes(scene, options, width as usize * height as usize);
    let nmattes = matte_films.len();
    let start_state = match &control.resume {
        Some(r) => r.clone(),
        None => {
            let mut sums = Sums::empty(width, height, split, guides, weights.is_some());
            sums.film = sums.film.with_aovs(&aov_names);
            sums.film.mattes = matte_films;
            sums
        }
    };
    // Samples are taken in order: a resumed render has taken the first of its range.
    let done = range.start + start_state.samples.first().copied().unwrap_or(0);
    let mut tiles: Vec<Tile> = (0..height.div_ceil(TILE))
        .flat_map(|ty| (0..width.div_ceil(TILE)).map(move |tx| (tx * TILE, ty * TILE)))
        .map(|(x0, y0)| {
            let (w, h) = (TILE.min(width - x0), TILE.min(height - y0));
            let splat = weights.as_ref().map(|wt| {
                splat::TileSplat::new((x0, y0, w, h), (width, height), wt, split, (naovs, nmattes))
            });
            Tile::new(x0, y0, w, h, adaptive.is_some(), done, splat)
        })
        .collect();
    // A part that does not start at sample 0 traces each pixel's sample 0 for the object it
    // shows, so every part counts the coverage of the same object.
    let trace_first = guides && range.start > 0 && control.resume.is_none();
    let shared = Mutex::new(start_state);
    let lock = || shared.lock().unwrap_or_else(|e| e.into_inner());

    // `--debug-nonfinite`: the sampler is a pure function of (seed, pixel, sample), so the
    // dropped sample's path is traced again, recorded (its camera ray alone, not as a packet).
    let report_nonfinite = |x: u32, y: u32, k: u32| {
        if !options.debug_nonfinite || reported.fetch_add(1, Ordering::Relaxed) >= MAX_REPORTS {
            return;
        }
        let mut sampler =
            Sampler::of(options.sampler, options.seed, y as u64 * width as u64 + x as u64, k as u64);
        let ray = camera.generate(x, y, &mut sampler);
        let mut path = Vec::new();
        let again = integrator.sample_recorded(ray, &mut sampler, &mut 0, &mut path);
        eprintln!(
            "non-finite sample dropped at pixel ({x}, {y}), sample {k}: radiance {}\n{}",
            again.beauty,
            path.join("\n")
        );
    };

    // Samples [from, to) of every pixel not yet converged, tile by tile; the pixel's sample i
    // always draws from the same stream, so passes change no sample.
    let mut from = done;
    let (mut interrupted, mut last_checkpoint) = (false, Instant::now());
    for to in pass_ends(range.clone(), adaptive.is_some(), done) {
        let stop_asked = control.stop.is_some_and(|s| s.load(Ordering::Relaxed));
        let over_time = control.time_limit.is_some_and(|limit| {
            // At the pace so far (per sample), would this pass end after the limit?
            let elapsed = start.elapsed().as_secs_f64();
            let pace = elapsed / (from - done).max(1) as f64;
            from > done && elapsed + pace * (to - from) as f64 > limit
        });
        if stop_asked || over_time {
            interrupted = true;
            break;
        }
        tiles.par_iter_mut().filter(|t| !t.done()).for_each(|tile| {
            let mut sums = TileSums::load(tile, &lock(), options.spp.max(1));
            let mut taken = 0u64;
            // One sample's AOVs.
            let mut aov = vec![Vec3::ZERO; naovs];
            for i in 0..(tile.w * tile.h) as usize {
                if tile.converged.get(i) == Some(&true) {
                    continue;
                }
                let (at, x, y) = tile.pixel(i, width);
                // The pixel's camera rays, a packet at a time, then each path from its hit.
                let streams = PixelSampler::new(options.sampler, options.seed, at as u64);
                if trace_first && from == range.start {
                    let mut sampler = streams.sample(0);
                    let ray = camera.generate(x, y, &mut sampler);
                    let hit = accel.intersect(&ray);
                    let s = integrator.sample_from(ray, hit, &mut sampler, &mut tile.rays);
                    sums.set_object(i, s.object);
                }
                let mut k = from;
                while k < to {
                    let n = (to - k).min(PACKET as u32) as usize;
                    // Streams only for the samples this packet takes (a partial one at low spp);
                    // the slots past them hold a copy, never used.
                    let stream = |j: usize| streams.sample((k + j as u32) as u64);
                    let first = stream(0);
                    let mut samplers: [Sampler; PACKET] =
                        std::array::from_fn(|j| if j == 0 || j >= n { first.clone() } else { stream(j) });
                    let mut rays = [Ray::new(Vec3::ZERO, Vec3::Z); PACKET];
                    let mut offsets = [glam::Vec2::ZERO; PACKET];
                    for ((ray, offset), sampler) in
                        rays.iter_mut().zip(&mut offsets).zip(&mut samplers).take(n)
                    {
                        (*ray, *offset) = camera.generate_at(x, y, sampler);
                    }
                    let mut hits = [None; PACKET];
                    accel.intersect_coherent(&rays[..n], &mut hits[..n]);
                    for (j, sampler) in samplers.iter_mut().take(n).enumerate() {
                        aov.fill(Vec3::ZERO);
                        // The Cryptomatte ids of the camera ray's first hit, whatever its light.
                        let ids = hits[j].and_then(|h| matte_ids.get(h.shape as usize));
                        match tile.splat.as_mut().zip(weights.as_ref()) {
                            Some((splats, w)) if nmattes > 0 => splats.add_matte((x, y), offsets[j], w, ids),
                            _ if nmattes > 0 => sums.add_matte(i, ids),
                            _ => {}
                        }
                        let s =
                            integrator.sample_from_into(rays[j], hits[j], sampler, &mut tile.rays, &mut aov);
                        if !sums.add(i, k + j as u32, (&s, &aov), split, tile.moments.get_mut(i)) {
                            tile.nonfinite += 1;
                            report_nonfinite(x, y, k + j as u32);
                        } else if let (Some(splats), Some(w)) = (tile.splat.as_mut(), &weights) {
                            splats.add((x, y), offsets[j], w, s.beauty, split.then_some(&s.components), &aov);
                        }
                    }
                    k += n as u32;
                }
                tile.n[i] = to;
                taken += (to - from) as u64;
                if let (Some(threshold), Some(m)) = (adaptive, tile.moments.get(i)) {
                    let n = to - range.start;
                    if to == range.end || relative_error(n, m[0], m[1]) <= threshold as f64 {
                        tile.converged[i] = true;
                        taken += (range.end - to) as u64; // never taken: done, for the progress bar
                    }
                }
            }
            sums.store(tile, &mut lock());
            progress(taken);
        });
        // The pass's splats, tile after tile in a fixed order: the same sums on any threads.
        if weights.is_some() {
            let mut state = lock();
            for tile in &mut tiles {
                if let Some(splats) = tile.splat.as_mut() {
                    splats.flush(&mut state);
                }
            }
        }
        from = to;
        if let Some((every, write)) = control.checkpoint {
            if last_checkpoint.elapsed().as_secs_f64() >= every && to < range.end {
                let mut state = lock();
                state.samples = samples_of(&tiles, width, height, range.start);
                write(&state);
                last_checkpoint = Instant::now();
            }
        }
    }

    let mut state = shared.into_inner().unwrap_or_else(|e| e.into_inner());
    let samples = samples_of(&tiles, width, height, range.start);
    let mut stats = RenderStats {
        buffer_bytes: state.bytes() + tiles.iter().map(Tile::bytes).sum::<u64>(),
        min_spp: samples.iter().copied().min().unwrap_or(0),
        max_spp: samples.iter().copied().max().unwrap_or(0),
        interrupted,
        ..Default::default()
    };
    stats.rays += training_rays;
    for tile in &tiles {
        stats.rays += tile.rays;
        stats.nonfinite_samples += tile.nonfinite;
    }
    for &n in &samples {
        stats.samples += n as u64;
        stats.stopped_early += (n < range.end - range.start && !interrupted) as u64;
    }
    state.samples = samples;
    let sums = (control.keep_sums || interrupted).then(|| state.clone());
    stats.seconds = start.elapsed().as_secs_f64();
    RenderOutput { film: state.into_means(), stats, sums, guide }
}

/// Training iterations of the guide, each this many samples a pixel (Müller et al. double
/// each iteration's budget; each guide trains the next).
const TRAINING_SPP: [u32; 4] = [1, 2, 4, 8];

/// Trains the guide for a render with `options` (Müller et al.'s iterations): renders a
/// smaller image of the same view, its pixels about an eighth of the render's samples over
/// the iterations' total, each iteration guided by the guide of the one before, whose paths'
/// records (in pixel order: the same on any threads) train the next. `rays` counts the rays.
fn train_guide<A: Accel, const F: u8>(
    integrator: &Integrator<'_, A, F>,
    scene: &Scene,
    options: &RenderOptions,
    learns: Guiding,
    rays: &mut u64,
) -> Guide {
    let (lo, hi) = scene.bounds();
    let mut guide = Guide::new(lo, hi);
    let learns = match learns {
        Guiding::All => integrator::Learns::All,
        _ => integrator::Learns::Indirect,
    };
    let total: u32 = TRAINING_SPP.iter().sum();
    let (w, h) = (options.width.max(1), options.height.max(1));
    let share = (options.spp.max(1) as f64 / (8.0 * total as f64)).min(1.0);
    let scale = share.sqrt();
    let (tw, th) =
        (((w as f64 * scale).round() as u32).clamp(1, w), ((h as f64 * scale).round() as u32).clamp(1, h));
    let camera = PinholeCamera::of_film(&scene.camera, &scene.film, tw, th);
    let counted = std::sync::atomic::AtomicU64::new(0);
    for (k, &spp) in TRAINING_SPP.iter().enumerate() {
        let seed = options.seed ^ 0x6775_6964_6500_0000 ^ ((k as u64 + 1) << 40);
        let current = Integrator { guide: (k > 0).then_some(&guide), ..*integrator };
        let rows: Vec<Vec<RadianceRecord>> = (0..th)
            .into_par_iter()
            .map(|y| {
                let mut path = integrator::GuidePath::new(learns);
                let mut traced = 0;
                for x in 0..tw {
                    let streams = PixelSampler::new(options.sampler, seed, y as u64 * tw as u64 + x as u64);
                    for i in 0..spp {
                        let mut sampler = streams.sample(i as u64);
                        let ray = camera.generate(x, y, &mut sampler);
                        current.sample_training(ray, &mut sampler, &mut traced, &mut path);
                    }
                }
                counted.fetch_add(traced, Ordering::Relaxed);
                path.records
            })
            .collect();
        guide = guide.train(&rows.concat());
    }
    *rays += counted.into_inner();
    guide
}

/// Each pixel's sample count, from the tiles (whose counts run from `first`, the range's first
/// sample).
fn samples_of(tiles: &[Tile], width: u32, height: u32, first: u32) -> Vec<u32> {
    let mut out = vec![0; width as usize * height as usize];
    for tile in tiles {
        for (i, &n) in tile.n.iter().enumerate() {
            out[tile.pixel(i, width).0] = n - first.min(n);
        }
    }
    out
}
