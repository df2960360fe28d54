//! A render job: what `lightsplit render` does between parsing its arguments and printing its
//! summary. [`Job::new`] applies the rules of a request (the options over the scene file's, the
//! part rules, the features the output needs, the resume checks, the run key) before any work;
//! [`Job::run`] renders, writes the part file or checkpoint it must, and writes the output.
//!
//! The rules, in one place:
//! - A part (`--part I/N` or `auto`) is never filtered: the scene's `[filter]` does not apply to
//!   it, a filter asked for is an error, its output is its part file (an EXR), and it keeps the
//!   split and the guides, since the merge may filter any way.
//! - Otherwise the output decides what the render computes beyond what the scene needs: the
//!   split and the guides its layer and filter read ([`crate::output::Layer::reads`]).
//! - A render that checkpoints, or may stop (a time limit, a signal), keeps its part file
//!   beside its output (`NAME.part.exr`), and removes it once it completes.
//! - A resumed render goes on from a part file of the same render (its run key).

use std::ffi::OsString;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use crate::accel::Backend;
use crate::error::Classify;
use crate::film::{self, Format, Sums};
use crate::filter::{Method, Overrides, Setting, Target};
use crate::output::{self, Layer, OutputError};
use crate::part;
use crate::render::sampler::SamplerKind;
use crate::render::{self, Features, Outputs, RenderError, RenderOptions, RenderStats};
use crate::scene::{self, Aov, Guiding, LightSamplerKind, Scene};

/// What a render is asked for: the command line's `render`, in the library's terms. `None`
/// keeps the scene file's value.
#[derive(Clone, Debug, Default)]
pub struct Request {
    /// The output file (its extension names the format).
    pub output: PathBuf,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub spp: Option<u32>,
    pub seed: Option<u64>,
    pub max_depth: Option<u32>,
    pub sampler: Option<SamplerKind>,
    pub light_sampler: Option<LightSamplerKind>,
    pub guiding: Option<Guiding>,
    /// The guide's file: read when it exists, else written with the guide the render trains.
    pub guide: Option<PathBuf>,
    /// Output layers of light path expressions, besides the scene file's.
    pub aovs: Vec<Aov>,
    /// A layer for each light group.
    pub light_groups: bool,
    /// Cryptomatte's object and material mattes.
    pub cryptomatte: bool,
    pub accel: Backend,
    pub threads: Option<usize>,
    pub debug_nonfinite: bool,
    /// Image textures looked up at a point, not over the footprint.
    pub point_textures: bool,
    /// Adaptive sampling's threshold.
    pub adaptive: Option<f32>,
    /// Compute every feature, whatever the scene and the output need.
    pub all_features: bool,
    /// `I/N`, or `auto` (from the batch scheduler's environment).
    pub part: Option<String>,
    /// Seconds between checkpoints.
    pub checkpoint: Option<f64>,
    /// Seconds after which the render stops at a pass boundary.
    pub time_limit: Option<f64>,
    /// The part file to resume from.
    pub resume: Option<PathBuf>,
    /// The filter flags, over the scene file's `[filter]`.
    pub filter: Overrides,
    /// The layer a PNG or HDR shows.
    pub layer: Layer,
    /// Stops of exposure (PNG only).
    pub exposure: f32,
}

/// Why a job cannot run: bad input (exit status 2) or a failure while working on good input.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    #[error("{0}")]
    Input(String),
    #[error("{0}")]
    Failed(String),
}

impl Classify for JobError {
    fn is_input(&self) -> bool {
        matches!(self, JobError::Input(_))
    }
}

/// A layer's error as a job's, keeping whose fault it was.
fn classified(e: impl Classify) -> JobError {
    if e.is_input() {
        JobError::Input(e.to_string())
    } else {
        JobError::Failed(e.to_string())
    }
}

/// A layer's error as a job's, by [`classified`].
macro_rules! job_error_from {
    ($($t:ty),+) => {
        $(impl From<$t> for JobError {
            fn from(e: $t) -> Self {
                classified(e)
            }
        })+
    };
}
job_error_from!(film::WriteError, OutputError, RenderError);

/// A render, checked and ready to run.
pub struct Job<'s> {
    scene: &'s Scene,
    /// The render's options: the scene file's, the request's over them, the features decided.
    pub options: RenderOptions,
    /// The filter of the output (none for a part).
    pub setting: Setting,
    pub output: PathBuf,
    /// Its part file: the output of a part, else `NAME.part.exr` beside the output.
    pub part_path: PathBuf,
    part_mode: bool,
    resume: Option<Sums>,
    /// The guide's file, to be written with the guide the render trains (it did not exist).
    guide_out: Option<PathBuf>,
    /// The run key, computed before the render when a part file is to be written (so that a
    /// scene file changed meanwhile does not lend its key to samples of the old one).
    key: Option<String>,
    checkpoint: Option<f64>,
    time_limit: Option<f64>,
    layer: Layer,
    exposure: f32,
}

/// A render done, not yet written ([`Job::write`]).
pub struct Rendered(render::RenderOutput);

impl Rendered {
    /// The render itself, for a caller that keeps it in memory instead of writing it (the
    /// Python module).
    pub fn into_output(self) -> render::RenderOutput {
        self.0
    }
}

/// A finished (or stopped) job.
pub struct Done {
    pub stats: RenderStats,
    /// Seconds the filter took.
    pub filter_seconds: f64,
}

impl<'s> Job<'s> {
    /// Checks `request` against `scene` (whose `[filter]` section is `scene_filter`) before any
    /// work; `env` looks up the scheduler's environment for `--part auto`.
    pub fn new(
        scene: &'s Scene,
        scene_filter: &Setting,
        request: Request,
        env: impl Fn(&str) -> Option<OsString>,
    ) -> Result<Job<'s>, JobError> {
        let input = |e: String| JobError::Input(e);
        let output = request.output.clone();
        let format = film::check_output(&output)?;
        film::check_not_an_input(&output, &scene.inputs)?;

        let mut options = RenderOptions::from_scene(scene);
        options.accel = request.accel;
        options.threads = request.threads;
        options.debug_nonfinite = request.debug_nonfinite;
        options.texture_filter = !request.point_textures;
        options.spp = request.spp.unwrap_or(options.spp);
        options.seed = request.seed.unwrap_or(options.seed);
        options.width = request.width.unwrap_or(options.width);
        options.height = request.height.unwrap_or(options.height);
        options.max_depth = request.max_depth.unwrap_or(options.max_depth);
        options.sampler = request.sampler.unwrap_or(options.sampler);
        options.light_sampler = request.light_sampler.unwrap_or(options.light_sampler);
        options.guiding = request.guiding.unwrap_or(options.guiding);
        let mut guide_out = None;
        if let Some(path) = &request.guide {
            if options.guiding == Guiding::Off {
                return Err(input(format!(
                    "{}: --guide names the guide of a guided render: add --guiding",
                    path.display()
                )));
            }
            match std::fs::read(path) {
                Ok(bytes) => {
                    let guide = crate::render::guide::Guide::from_bytes(&bytes).map_err(|e| {
                        input(format!("{}: not a guide lightsplit wrote: {e}", path.display()))
                    })?;
                    options.guide = Some(std::sync::Arc::new(guide));
                }
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => guide_out = Some(path.clone()),
                Err(e) => return Err(input(format!("{}: {e}", path.display()))),
            }
        }
        options.adaptive = request.adaptive;
        let groups = if request.light_groups {
            if scene.light_groups.names.is_empty() {
                return Err(input(format!(
                    "{}: --light-groups: the scene has no light groups (`light_group` on a light or shape)",
                    scene.path.display()
                )));
            }
            scene.light_groups.aovs().map_err(input)?
        } else {
            Vec::new()
        };
        for aov in request.aovs.iter().chain(&groups) {
            if options.aovs.iter().any(|a| a.name == aov.name) {
                return Err(input(format!(
                    "AOV `{}` is asked for twice (scene file, --aov, --light-groups)",
                    aov.name
                )));
            }
            options.aovs.push(aov.clone());
        }
        if !options.aovs.is_empty() && format != Format::Exr {
            return Err(input("AOVs are layers of an EXR: the output must be .exr".into()));
        }
        options.cryptomatte = request.cryptomatte;
        if options.cryptomatte && format != Format::Exr {
            return Err(input("Cryptomatte's mattes are layers of an EXR: the output must be .exr".into()));
        }
        if options.aovs.len() > crate::render::paths::MAX_AOVS {
            return Err(input(format!("at most {} AOVs", crate::render::paths::MAX_AOVS)));
        }

        let part_mode = request.part.is_some();
        let setting = if part_mode {
            let setting = request.filter.over(&Setting::default()).map_err(input)?;
            request.layer.check(format, &setting)?;
            if format != Format::Exr {
                return Err(input(
                    "--part writes a part file for `lightsplit merge`: the output must be .exr".into(),
                ));
            }
            if setting.method.is_some() && setting.target != Target::None {
                return Err(input(
                    "a part is never filtered: give the filter to `lightsplit merge`, which filters the \
                     merged image once"
                        .into(),
                ));
            }
            setting
        } else {
            let setting = request.filter.over(scene_filter).map_err(input)?;
            request.layer.check(format, &setting)?;
            output::check_aov_target(
                &setting,
                &options.aovs.iter().map(|a| a.name.as_str()).collect::<Vec<_>>(),
            )?;
            setting
        };
        scene::limits::check_render_memory(options.width, options.height, render::layer_bytes(&options))
            .map_err(|e| input(e.0))?;
        if request.all_features {
            options.features = Features::ALL;
            options.build = Default::default();
        } else if part_mode {
            options.features = Features { split: true, guides: true, ..options.features };
        } else {
            // `from_scene` found what the scene needs; the output decides the split and the guides.
            let Outputs { split, guides } = request.layer.reads(format, &setting);
            options.features = Features { split, guides, ..options.features };
        }
        if let Some(text) = &request.part {
            let flag = if text == "auto" { "--part auto" } else { "--part" };
            let part = if text == "auto" { part::part_from_scheduler(env) } else { part::parse_part(text) };
            options.part = part.map_err(|e| input(format!("{flag}: {e}")))?;
            options.part.check(options.spp).map_err(|e| input(format!("{flag}: {e}")))?;
        }

        let part_path = if part_mode { output.clone() } else { part_file_of(&output) };
        film::check_not_an_input(&part_path, &scene.inputs)?;
        if !part_mode && (request.checkpoint.is_some() || request.time_limit.is_some()) {
            // It will be written, or most likely: its name must be one that can be.
            film::check_output(&part_path)?;
        }
        let resume = match &request.resume {
            None => None,
            Some(path) => {
                // A part's output is its part file, which a resumed part rewrites whole (a part
                // file too); any other output would replace the checkpoint with an image.
                if !part_mode {
                    film::check_not_an_input(&output, std::slice::from_ref(path))?;
                }
                let sums = part::read_checkpoint(path, scene, &mut options)
                    .map_err(|e| input(format!("--resume {}: {e}", path.display())))?;
                Some(sums)
            }
        };
        let needs_key = part_mode || request.checkpoint.is_some() || request.resume.is_some();
        let key = if needs_key { Some(part::run_key(scene, &options).map_err(input)?) } else { None };
        Ok(Job {
            scene,
            options,
            setting,
            output,
            part_path,
            part_mode,
            resume,
            key,
            guide_out,
            checkpoint: request.checkpoint,
            time_limit: request.time_limit,
            layer: request.layer,
            exposure: request.exposure,
        })
    }

    /// Whether this job renders a part for a merge.
    pub fn is_part(&self) -> bool {
        self.part_mode
    }

    /// The sample indices each pixel takes.
    pub fn samples(&self) -> Range<u32> {
        self.options.part.samples(self.options.spp.max(1))
    }

    /// The samples the job takes in all (pixels times the samples of each).
    pub fn total_samples(&self) -> u64 {
        let range = self.samples();
        self.options.width as u64 * self.options.height as u64 * (range.end - range.start) as u64
    }

    /// The samples the resumed file already holds.
    pub fn resumed_samples(&self) -> u64 {
        self.resume.as_ref().map_or(0, |r| r.samples.iter().map(|&n| n as u64).sum())
    }

    /// The filter an output's metadata names: `box3 on indirect`, or none.
    pub fn filter_label(&self) -> Option<String> {
        filter_label(&self.setting)
    }

    /// The part file's header for the sums of this render.
    fn header(&self, key: String, seconds: f64, complete: bool) -> part::Header {
        let options = &self.options;
        part::Header {
            key,
            part: options.part,
            spp: options.spp,
            adaptive: options.adaptive,
            complete,
            meta: render::metadata(self.scene, options, seconds),
        }
    }

    /// The part file's header of `stats`' render, for a caller that keeps the part in memory
    /// instead of writing it ([`Job::write`] writes the same).
    pub fn part_header(&self, stats: &RenderStats) -> Result<part::Header, JobError> {
        let key = match &self.key {
            Some(k) => k.clone(),
            None => part::run_key(self.scene, &self.options).map_err(JobError::Failed)?,
        };
        Ok(self.header(key, stats.seconds, !stats.interrupted))
    }

    /// Renders, calling `progress` with the samples done; `stop`, once set, ends the render
    /// after its pass (a checkpoint is written as the render goes). Nothing is written of the
    /// result until [`Job::write`]: a caller that stops gracefully while rendering and at once
    /// while writing switches between the two here.
    pub fn render(
        &mut self,
        progress: &(dyn Fn(u64) + Sync),
        stop: &AtomicBool,
    ) -> Result<Rendered, JobError> {
        let resume = self.resume.take();
        let checkpoint_key = self.key.clone().unwrap_or_default();
        let job = &*self;
        let write_checkpoint = |sums: &Sums| {
            if let Err(e) = part::write(&job.part_path, sums, &job.header(checkpoint_key.clone(), 0.0, false))
            {
                eprintln!("warning: checkpoint not written: {e}");
            }
        };
        let control = render::Control {
            progress,
            stop: Some(stop),
            time_limit: self.time_limit,
            checkpoint: self.checkpoint.map(|s| (s, &write_checkpoint as &render::Checkpoint)),
            resume,
            keep_sums: self.part_mode,
        };
        Ok(Rendered(render::render_controlled(self.scene, &self.options, control)?))
    }

    /// Writes what [`Job::render`] made: the part file when the job is a part or was stopped,
    /// the output otherwise (what a stopped render has, too); removes a checkpoint that has
    /// served.
    pub fn write(&mut self, rendered: Rendered) -> Result<Done, JobError> {
        let out = rendered.0;
        let interrupted = out.stats.interrupted;
        if let (Some(path), Some(guide)) = (&self.guide_out, &out.guide) {
            film::write_text(path, guide.to_bytes()).map_err(|e| JobError::Failed(e.to_string()))?;
        }
        if let Some(sums) = &out.sums {
            let header = self.part_header(&out.stats)?;
            part::write(&self.part_path, sums, &header).map_err(|e| JobError::Failed(e.to_string()))?;
        }
        let meta = film::Metadata {
            filter: self.filter_label(),
            ..render::metadata(self.scene, &self.options, out.stats.seconds)
        };
        let filter_seconds = if self.part_mode {
            0.0
        } else {
            output::write(out.film, &self.setting, &self.output, self.layer, self.exposure, &meta)?
        };
        if !self.part_mode && !interrupted && self.checkpoint.is_some() {
            // Complete: the checkpoint has served.
            let _ = std::fs::remove_file(&self.part_path);
        }
        Ok(Done { stats: out.stats, filter_seconds })
    }

    /// The summary `render --json` prints of a job that ran.
    pub fn summary(&self, done: &Done, scene_path: &Path) -> serde_json::Value {
        let (options, setting, s) = (&self.options, &self.setting, &done.stats);
        let per_second = |n: u64| n as f64 / s.seconds.max(1e-9);
        serde_json::json!({
            "scene": scene_path.to_string_lossy(),
            "seconds": s.seconds,
            "build_seconds": s.build_seconds,
            "spp": options.spp,
            "width": options.width,
            "height": options.height,
            "accel": options.accel,
            "sampler": options.sampler.name(),
            "light_sampler": options.light_sampler.name(),
            "guiding": options.guiding.name(),
            "seed": options.seed,
            "threads": options.threads.unwrap_or_else(rayon::current_num_threads),
            "samples": s.samples,
            "rays": s.rays,
            "samples_per_second": per_second(s.samples),
            "rays_per_second": per_second(s.rays),
            "nonfinite_samples": s.nonfinite_samples,
            "adaptive": options.adaptive,
            "stopped_early_pixels": s.stopped_early,
            "mean_spp": s.samples as f64 / (options.width as f64 * options.height as f64),
            "features": options.features,
            "embree": options.build,
            "buffer_bytes": s.buffer_bytes,
            "filter": setting.method.as_ref().map(Method::name),
            "filter_target": setting.target.name(),
            "edge_aware": setting.stops.object,
            "edge_normal_degrees": setting.stops.normal_degrees,
            "edge_depth_relative": setting.stops.depth_relative,
            "edge_pure": setting.stops.pure,
            "filter_seconds": done.filter_seconds,
            "max_depth": options.max_depth,
            "version": env!("CARGO_PKG_VERSION"),
            "part": options.part.to_string(),
            "samples_per_pixel_min": s.min_spp,
            "samples_per_pixel_max": s.max_spp,
            "interrupted": s.interrupted,
            "part_file": (self.part_mode || s.interrupted).then(|| self.part_path.to_string_lossy()),
            "outputs": [self.output.to_string_lossy()],
        })
    }
}

/// The filter a file's metadata names: `box3 on indirect`, or none.
pub fn filter_label(setting: &Setting) -> Option<String> {
    setting
        .method
        .as_ref()
        .filter(|_| setting.target != Target::None)
        .map(|k| format!("{} on {}", k.name(), setting.target.name()))
}

/// The part file beside `output`: its name with `.part.exr`.
pub fn part_file_of(output: &Path) -> PathBuf {
    output.with_extension("part.exr")
}
