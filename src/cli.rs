//! The command line's grammar: every subcommand's arguments, the value parsers that check ranges
//! as they parse (so a bad value is clap's usage error, exit status 2), and the small enums that
//! spell the library's choices (`embree`, `indirect`, `final`, ...) without the library knowing clap.

use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use clap::{Parser, Subcommand};

use lightsplit::accel::Backend;
use lightsplit::converge::Edge;
use lightsplit::film::{Film, Format};
use lightsplit::filter::{Overrides, Setting, Target};
use lightsplit::output::{self, Layer, OutputError};
use lightsplit::render::sampler::SamplerKind;
use lightsplit::scene::{limits, Environment};
use lightsplit::scene::{Aov, Guiding, LightSamplerKind};

use crate::Failure;

/// The whole command line.
#[derive(Parser)]
#[command(name = "lightsplit", version, about = "A path tracer that filters only the indirect diffuse light")]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Subcommand)]
pub enum Command {
    /// Render a scene file to an image.
    #[command(mut_arg("json", |a| a.help("Print one JSON object on stdout instead of the summary line")))]
    Render(RenderArgs),
    /// Re-filter a saved multi-layer EXR without rendering again.
    Filter(FilterCommandArgs),
    /// Add up the part files of a render split across machines (`render --part`), exactly,
    /// then filter once and write the image.
    Merge(MergeArgs),
    /// Compare an image with a reference: the paper's sum of squares, RMSE, relMSE.
    Compare(CompareArgs),
    /// A Cryptomatte matte of an EXR (`render --cryptomatte`, or another renderer's): each
    /// pixel's coverage by the objects or materials named, as a compositor reads it.
    Matte(MatteArgs),
    /// Measure Embree and the BVH side by side on identical ray sets.
    BenchAccel(BenchAccelArgs),
    /// Run time against error: render each spp once per seed, filter it every way, compare
    /// with a reference, and write results.csv, summary.md and log-log plots.
    Converge(ConvergeArgs),
    /// Numerical stability: adversarial scenes (far from the origin, at extreme scales, grazing,
    /// degenerate, dark, tiny, overflowing, seamed), each with its measured figure and a verdict.
    Stress(StressArgs),
    /// What a scene uses (material lobes, lights, textures) and so what a render of it, with
    /// the outputs asked for, needs.
    Info(InfoArgs),
    /// Samples per second, buffer memory and images of scenes rendered with only what they
    /// need and with every feature forced on, side by side.
    BenchFeatures(BenchFeaturesArgs),
}

/// Where the rays are traced: shared by every command that renders.
#[derive(clap::Args)]
pub struct Engine {
    /// Ray tracing backend.
    #[arg(long, default_value = "embree", value_enum)]
    pub accel: Backend,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = threads)]
    pub threads: Option<usize>,
}

/// `--accel`, `--threads` and `--json`: shared by `render`, `stress` and `bench-features`.
#[derive(clap::Args)]
pub struct RunArgs {
    /// `--accel` and `--threads`.
    #[command(flatten)]
    pub engine: Engine,
    /// Print one JSON object on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// `-D name=value`: a Mitsuba XML scene's parameters, as Mitsuba's own `-D`. Shared by the
/// commands that read a scene.
#[derive(clap::Args, Clone, Default)]
pub struct Defines {
    /// Set the Mitsuba XML scene's parameter `$NAME` (over its `<default>`); repeatable.
    #[arg(short = 'D', value_name = "NAME=VALUE", value_parser = define)]
    pub define: Vec<(String, String)>,
}

/// `bench-features`.
#[derive(clap::Args)]
pub struct BenchFeaturesArgs {
    /// The scene files (TOML).
    #[arg(required = true)]
    pub scenes: Vec<PathBuf>,
    /// Image width of every render.
    #[arg(long, default_value_t = 128, value_parser = size)]
    pub width: u32,
    /// Image height of every render.
    #[arg(long, default_value_t = 128, value_parser = size)]
    pub height: u32,
    /// Samples per pixel of every render.
    #[arg(long, default_value_t = 16, value_parser = samples)]
    pub spp: u32,
    /// Rounds, each rendering every mode once; medians are reported.
    #[arg(long, default_value_t = 5, value_parser = count::<usize>)]
    pub rounds: usize,
    /// Also measure what these AOVs cost (as `render --aov`; repeatable).
    #[arg(long = "aov", value_name = "NAME=EXPR|NAME", value_parser = aov)]
    pub aovs: Vec<Aov>,
    /// Also measure what a layer a light group costs (each scene must have groups).
    #[arg(long)]
    pub light_groups: bool,
    /// Also measure what Cryptomatte's mattes cost.
    #[arg(long)]
    pub cryptomatte: bool,
    /// `--accel`, `--threads` and `--json`.
    #[command(flatten)]
    pub run: RunArgs,
    /// `-D name=value`.
    #[command(flatten)]
    pub defines: Defines,
}

/// `info`.
#[derive(clap::Args)]
pub struct InfoArgs {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// The output the render would write (its format decides which layers are kept).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// The filter, exposure and layer of the output.
    #[command(flatten)]
    pub out: OutputArgs,
    /// `-D name=value`.
    #[command(flatten)]
    pub defines: Defines,
}

/// `stress`.
#[derive(clap::Args)]
pub struct StressArgs {
    /// Run only the rows whose name contains this text.
    #[arg(long)]
    pub only: Option<String>,
    /// `--accel`, `--threads` and `--json`.
    #[command(flatten)]
    pub run: RunArgs,
}

/// `converge`.
#[derive(clap::Args)]
pub struct ConvergeArgs {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// A reference image (.exr or .hdr) of the same size; without it one is rendered at
    /// --reference-spp and cached in the output directory.
    #[arg(long, conflicts_with = "reference_spp")]
    pub reference: Option<PathBuf>,
    /// Samples per pixel of the rendered reference.
    #[arg(long, default_value_t = 1024, value_parser = samples)]
    pub reference_spp: u32,
    /// The sample counts to measure.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "1,2,4,8,16,32,64,128,256",
        value_parser = samples
    )]
    pub spp: Vec<u32>,
    /// The filters: none, box3, weighted3, median3, box5 (or custom kernels as 1;2;1;...).
    #[arg(long, value_delimiter = ',', default_value = "none,box3,weighted3,median3,box5")]
    pub filters: Vec<String>,
    /// What the filters apply to: indirect, components, image, none.
    #[arg(long, value_delimiter = ',', default_value = "indirect", value_parser = named_target)]
    pub targets: Vec<Target>,
    /// Edge-aware filtering: off, on (the paper's object stop), pure (also leave mixed border
    /// pixels alone, as --edge-pure does); a list measures each.
    #[arg(long, value_delimiter = ',', default_value = "off", value_enum)]
    pub edge_aware: Vec<Edge>,
    /// Renders per spp, each with its own seed: the summary gives their mean and spread.
    #[arg(long, default_value_t = 1, value_parser = count::<u32>)]
    pub seeds: u32,
    /// The samplers to measure: sobol, independent, or both (independent,sobol), which the
    /// summary compares: what sobol is worth in samples, and what each filter gains under each.
    #[arg(long, value_delimiter = ',', default_value = "sobol", value_enum)]
    pub sampler: Vec<SamplerKind>,
    /// Also render each spp with adaptive sampling at this relative-error threshold (the spp
    /// then is the most a pixel takes), compared with uniform sampling at equal time.
    #[arg(long, value_name = "THRESHOLD", value_parser = relative_error)]
    pub adaptive: Option<f32>,
    /// `--accel` and `--threads`.
    #[command(flatten)]
    pub engine: Engine,
    /// Image width (default: the scene file's).
    #[arg(long, value_parser = size)]
    pub width: Option<u32>,
    /// Image height (default: the scene file's).
    #[arg(long, value_parser = size)]
    pub height: Option<u32>,
    /// The spp whose difference images (the paper's Figure 6) are written (default: the
    /// measured spp nearest 50).
    #[arg(long)]
    pub diff_spp: Option<u32>,
    /// The output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// `-D name=value`.
    #[command(flatten)]
    pub defines: Defines,
}

/// How to filter: shared by `render` and `filter`.
#[derive(clap::Args, Clone)]
pub struct FilterArgs {
    /// Noise-reduction filter: box3 (the paper's A), weighted3 (B), median3 (C), box5, an odd
    /// square kernel as comma-separated weights, or atrous (variance-guided à-trous wavelets,
    /// with settings: atrous:passes=5:sigma_l=4:sigma_n=128:sigma_z=1:taps=5).
    #[arg(long)]
    pub filter: Option<String>,
    /// Denoise with the best setting measured (docs/RESULTS.md, "Denoising"): the à-trous
    /// filter (atrous:taps=3:passes=4:sigma_l=5:linear=2, --edge-pure) on each component,
    /// emitted light left alone, kept only where the halves of the samples say it lowers the
    /// error.
    #[arg(
        long,
        conflicts_with_all = ["filter", "filter_target", "edge_aware", "edge_normal", "edge_depth", "edge_pure"]
    )]
    pub denoise: bool,
    /// What the filter applies to (default: indirect, the paper's method, when a filter is
    /// named): indirect, components, image, none, or the name of an AOV of the render (the
    /// image is then the beauty less the AOV plus the AOV filtered).
    #[arg(long, value_name = "TARGET", value_parser = target)]
    pub filter_target: Option<Target>,
    /// Average only neighbours that show the same object as the centre pixel.
    #[arg(long)]
    pub edge_aware: bool,
    /// Also stop at creases: only neighbours whose normal is within DEG degrees.
    #[arg(long, value_name = "DEG")]
    pub edge_normal: Option<f32>,
    /// Also stop at depth steps: only neighbours whose depth differs by at most REL (relative).
    #[arg(long, value_name = "REL")]
    pub edge_depth: Option<f32>,
    /// Beyond the paper: leave pixels whose samples saw more than one object (antialiased
    /// borders) unfiltered and out of their neighbours' windows.
    #[arg(long)]
    pub edge_pure: bool,
}

impl FilterArgs {
    /// The flags, for the library to lay over a base setting.
    pub fn overrides(&self) -> Overrides {
        Overrides {
            method: self.filter.clone(),
            denoise: self.denoise,
            target: self.filter_target,
            object: self.edge_aware,
            normal_degrees: self.edge_normal,
            depth_relative: self.edge_depth,
            pure: self.edge_pure,
        }
    }
}

/// How a render becomes its output: filtered, exposed, one layer or all. Shared by `render`,
/// `filter` and `info`.
#[derive(clap::Args)]
pub struct OutputArgs {
    /// The filter setting.
    #[command(flatten)]
    pub filter: FilterArgs,
    /// Exposure in stops for PNG output.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = finite)]
    pub exposure: f32,
    /// Which layer a PNG or HDR output shows (an EXR holds them all).
    #[arg(long, default_value = "final", value_enum)]
    pub layer: Layer,
    /// How an EXR output is compressed, all lossless: zip (the smallest files), piz, rle
    /// (faster to write; a render's file about 1.35x zip's size) or none.
    #[arg(long, default_value = "zip", value_enum)]
    pub exr_compression: lightsplit::film::ExrCompression,
}

impl OutputArgs {
    /// Checks before any work: the filter (these flags over `base`), and that the layer can be
    /// written as `format` with that filter.
    pub fn check(&self, base: &Setting, format: Format) -> Result<Setting, Failure> {
        let setting = self.filter.overrides().over(base).map_err(Failure::input)?;
        self.layer.check(format, &setting)?;
        if let Some(warning) = output::exposure_warning(self.exposure, format) {
            eprintln!("warning: {warning}");
        }
        Ok(setting)
    }

    /// Filters `film` as `setting` says and writes it to `path`; returns the filter's seconds.
    pub fn write(
        &self,
        film: Film,
        setting: &Setting,
        path: &Path,
        meta: &lightsplit::film::Metadata,
    ) -> Result<f64, OutputError> {
        let meta = lightsplit::film::Metadata { compression: self.exr_compression, ..meta.clone() };
        output::write(film, setting, path, self.layer, self.exposure, &meta)
    }
}

/// `filter`.
#[derive(clap::Args)]
pub struct FilterCommandArgs {
    /// A multi-layer EXR written by `lightsplit render`.
    pub input: PathBuf,
    /// The output: .exr (every layer), .png or .hdr (the final image).
    #[arg(short, long)]
    pub output: PathBuf,
    /// The filter, exposure and layer of the output.
    #[command(flatten)]
    pub out: OutputArgs,
    /// Print what was done as JSON on stdout: the filter, its target and its seconds.
    #[arg(long)]
    pub json: bool,
}

/// `compare`.
#[derive(clap::Args)]
pub struct CompareArgs {
    /// The image to judge (.exr or .hdr).
    pub test: PathBuf,
    /// The reference (.exr or .hdr), e.g. a high-sample render of the same scene.
    pub reference: PathBuf,
    /// Write a brightened difference image (the paper's Figure 6): darker is a larger difference.
    #[arg(long)]
    pub diff: Option<PathBuf>,
    /// Also give the errors of each object (by the object-ID layer of the test image, or of
    /// --ids): RMSE, relMSE, mean colours and their ratio, and the detail kept.
    #[arg(long)]
    pub by_object: bool,
    /// Also give the errors of a named group of objects, NAME=ID,ID,... (-1 the background);
    /// repeatable.
    #[arg(long = "region", value_name = "NAME=IDS")]
    pub regions: Vec<String>,
    /// Also give how two renders of one scene agree: the channel means of both, and the worst
    /// block of N x N pixels (its mean's largest relative difference in a channel).
    #[arg(long, value_name = "N", value_parser = count::<u32>)]
    pub blocks: Option<u32>,
    /// Compare this layer of two EXRs (`direct`, an AOV, any with R, G, B channels) instead of
    /// their final images.
    #[arg(long, value_name = "NAME", default_value = "final")]
    pub layer: String,
    /// The EXR whose object-ID layer says which object each pixel shows (default: the test
    /// image), for --by-object and --region.
    #[arg(long, value_name = "EXR")]
    pub ids: Option<PathBuf>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `matte`: the coverage of names in a Cryptomatte type of an EXR.
#[derive(clap::Args)]
pub struct MatteArgs {
    /// A multi-layer EXR with Cryptomatte layers and their header attributes.
    pub input: PathBuf,
    /// The names whose coverage is summed, as the type's manifest has them (an object's name,
    /// a material's).
    #[arg(required = true)]
    pub names: Vec<String>,
    /// The Cryptomatte type, by its name in the file.
    #[arg(long = "type", value_name = "TYPE", default_value = "CryptoObject")]
    pub kind: String,
    /// The matte, R = G = B = coverage: .exr or .pfm (32-bit float, exact), .hdr, or .png (8-bit
    /// sRGB, as every PNG lightsplit writes).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `bench-accel`: both backends, so no `--accel`.
#[derive(clap::Args)]
pub struct BenchAccelArgs {
    /// The scene files (TOML), measured one after another (with `--json`, one object a line).
    #[arg(required = true)]
    pub scenes: Vec<PathBuf>,
    /// Also draw Mrays/s on one thread against each scene's triangle count, both backends and
    /// every ray kind, log-log, into this PNG (meant for several sizes of one scene).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Primary rays per set (shadow and incoherent rays start at their hits).
    #[arg(long, default_value_t = 1 << 20, value_parser = count::<usize>)]
    pub rays: usize,
    /// Threads for the multi-threaded rows (default: one per core).
    #[arg(long, value_parser = threads)]
    pub threads: Option<usize>,
    /// Seconds each measurement runs at least.
    #[arg(long, default_value_t = 0.3, value_parser = seconds)]
    pub seconds: f64,
    /// Rounds per row, each measuring both backends back to back; medians are reported.
    #[arg(long, default_value_t = 5, value_parser = count::<usize>)]
    pub rounds: usize,
    /// Instead of the backends, measure Embree's scene settings against each other: robust or
    /// not, build quality low, medium, high (build time, rays per second, answers changed).
    #[arg(long)]
    pub embree_settings: bool,
    /// The BVH's kernels: avx512, avx2 or portable (default: the best this CPU runs). With
    /// `LIGHTSPLIT_EMBREE_CONFIG=isa=avx2` for Embree, both measure AVX2 alone on a CPU that
    /// also has AVX-512.
    #[arg(long, value_name = "KERNELS")]
    pub isa: Option<String>,
    /// Print one JSON object on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// `render`.
#[derive(clap::Args)]
pub struct RenderArgs {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// Output image: .exr (32-bit float), .png (8-bit sRGB) or .hdr (Radiance RGBE).
    /// Default: the scene's name with .exr, in the current directory.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Samples per pixel (default: the scene file's).
    #[arg(long, value_parser = samples)]
    pub spp: Option<u32>,
    /// `--accel`, `--threads` and `--json`.
    #[command(flatten)]
    pub run: RunArgs,
    /// Random seed (default: the scene file's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Image width (default: the scene file's).
    #[arg(long, value_parser = size)]
    pub width: Option<u32>,
    /// Image height (default: the scene file's).
    #[arg(long, value_parser = size)]
    pub height: Option<u32>,
    /// Most scattering events per path (default: the scene file's).
    #[arg(long, value_parser = depth)]
    pub max_depth: Option<u32>,
    /// The random numbers: sobol (Owen-scrambled Sobol points, the default) or independent
    /// (PCG streams). Default: the scene file's.
    #[arg(long, value_enum)]
    pub sampler: Option<SamplerKind>,
    /// How next-event estimation picks a light among more than eight: tree (a light tree:
    /// by what each light can send to the shading point, the default), power or uniform.
    /// Default: the scene file's.
    #[arg(long, value_enum)]
    pub light_sampler: Option<LightSamplerKind>,
    /// Guide directions at diffuse-like vertices by the incident light learned in a first,
    /// short training pass (path guiding): `--guiding` alone or `all` learns all the light a
    /// bounce brings, `indirect` only what it brings after a further bounce, `off` none.
    /// Default: the scene file's (off).
    #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "all")]
    pub guiding: Option<Guiding>,
    /// The guide's file: read when it exists (every part of a split render can share one),
    /// else written with the guide this render trains.
    #[arg(long, value_name = "FILE")]
    pub guide: Option<PathBuf>,
    /// An output layer of the light of the paths a light path expression matches (OSL's
    /// grammar; docs/usage.md): NAME=EXPR, or NAME alone for a built-in expression (emission,
    /// diffuse_direct, diffuse_indirect, arnold_direct, arnold_indirect, arnold_albedo). Repeatable; added
    /// to the scene file's [[aov]] tables. Written as the EXR layer NAME.
    #[arg(long = "aov", value_name = "NAME=EXPR|NAME", value_parser = aov)]
    pub aovs: Vec<Aov>,
    /// One layer a light group of the scene (`light_group` on its lights and shapes; a glTF
    /// file's lights and emissive materials by their names): `group_NAME`, its light along
    /// every path.
    #[arg(long)]
    pub light_groups: bool,
    /// Cryptomatte's object and material mattes (specification 1.2): layers CryptoObject00..02
    /// and CryptoMaterial00..02, six ranks each, with their manifests in the header, from each
    /// sample's first hit (so antialiased edges carry their coverage). EXR output only.
    #[arg(long)]
    pub cryptomatte: bool,
    /// The filter, exposure and layer of the output.
    #[command(flatten)]
    pub out: OutputArgs,
    /// What lights the scene from infinity, replacing its sky or environment map (or the
    /// default white sky of a model rendered directly): an HDRI (.hdr, .exr, .pfm), `white` (a
    /// uniform sky of radiance 1) or `none`; its other lights and emission are kept.
    #[arg(long, value_name = "FILE|white|none", value_parser = environment)]
    pub environment: Option<Environment>,
    /// A glTF file's camera to render through: its index from 0 (in the order of the node
    /// hierarchy) or its name (the camera's, else its node's); the first by default.
    #[arg(long, value_name = "NAME|INDEX")]
    pub camera: Option<String>,
    /// `-D name=value`.
    #[command(flatten)]
    pub defines: Defines,
    /// Print each dropped non-finite sample (the first 20): its pixel, sample index and path.
    #[arg(long)]
    pub debug_nonfinite: bool,
    /// Look image textures up at a point (bilinear, at full resolution), as before texture
    /// filtering, instead of over the camera ray cone's footprint through their mipmaps.
    #[arg(long)]
    pub point_textures: bool,
    /// Adaptive sampling: stop a pixel once the estimated relative error of its mean (standard
    /// error over mean luminance, checked after 16, 32, 64, ... samples) is at most THRESHOLD,
    /// e.g. 0.02; --spp is then the most a pixel takes. Converged tiles are skipped.
    #[arg(long, value_name = "THRESHOLD", value_parser = relative_error)]
    pub adaptive: Option<f32>,
    /// Compute every feature (MIS, the split, the guides, textures) whatever the scene and the
    /// output need, on Embree's robust high-quality build: the general renderer, for
    /// comparison. The beauty is the same.
    #[arg(long)]
    pub all_features: bool,
    /// Render part I of N of each pixel's samples (0 <= I < N): the output is then a part
    /// file (.exr) for `lightsplit merge`, never filtered. `auto` reads I and N from a Slurm
    /// job array (SLURM_ARRAY_TASK_ID less SLURM_ARRAY_TASK_MIN, of SLURM_ARRAY_TASK_COUNT) or
    /// a Kubernetes Indexed Job (JOB_COMPLETION_INDEX, of LIGHTSPLIT_PART_COUNT).
    #[arg(long, value_name = "I/N|auto")]
    pub part: Option<String>,
    /// Every SECONDS, at the end of a pass, write the render so far as a part file: the
    /// output itself with --part, else the output's name with `.part.exr` (removed when the
    /// render completes). `--resume` continues from it.
    #[arg(long, value_name = "SECONDS", value_parser = seconds)]
    pub checkpoint: Option<f64>,
    /// Continue from a checkpoint (or an interrupted render's part file) to the full spp: the
    /// same image as a render never stopped. The scene and settings must be the same.
    #[arg(long, value_name = "PART.exr")]
    pub resume: Option<PathBuf>,
    /// End before SECONDS of rendering, at a pass boundary (the first pass always runs), and
    /// write what was rendered, with its part file.
    #[arg(long, value_name = "SECONDS", value_parser = seconds)]
    pub time_limit: Option<f64>,
}

/// `merge`.
#[derive(clap::Args)]
pub struct MergeArgs {
    /// The part files (`render --part I/N`), in any order.
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// The output: .exr (every layer), .png or .hdr (the final image).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Merge the parts there are when some are missing (each is named on stderr).
    #[arg(long)]
    pub allow_missing: bool,
    /// The filter, exposure and layer of the output, applied once after the merge.
    #[command(flatten)]
    pub out: OutputArgs,
    /// Print what was done as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `text` as a `T` that passes `ok`: otherwise the parse error, or that it "must be `what`".
fn number<T>(text: &str, ok: impl Fn(T) -> bool, what: &str) -> Result<T, String>
where
    T: FromStr + Copy,
    T::Err: Display,
{
    let value = text.parse().map_err(|e: T::Err| e.to_string())?;
    if ok(value) {
        Ok(value)
    } else {
        Err(format!("must be {what}"))
    }
}

/// A count of at least one: sizes, samples, seeds, threads, rays, rounds.
fn count<T>(text: &str) -> Result<T, String>
where
    T: FromStr + Copy + PartialOrd + From<u8>,
    T::Err: Display,
{
    number(text, |n| n >= T::from(1), "at least 1")
}

/// `NAME=VALUE` of `-D`: a parameter name as Mitsuba's (letters, digits, `_`), any value.
fn define(text: &str) -> Result<(String, String), String> {
    let (name, value) = text.split_once('=').ok_or("expected NAME=VALUE")?;
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(format!("`{name}` is not a parameter name (letters, digits and _)"));
    }
    Ok((name.to_owned(), value.to_owned()))
}

/// An image side: 1 to [`limits::MAX_SIZE`] pixels, as in a scene file.
fn size(text: &str) -> Result<u32, String> {
    number(text, |n| (1..=limits::MAX_SIZE).contains(&n), &format!("1 to {}", limits::MAX_SIZE))
}

/// Samples per pixel: 1 to [`limits::MAX_SPP`], as in a scene file.
fn samples(text: &str) -> Result<u32, String> {
    number(text, |n| (1..=limits::MAX_SPP).contains(&n), &format!("1 to {}", limits::MAX_SPP))
}

/// `--filter-target`: a target's name or an AOV's.
fn target(text: &str) -> Result<Target, String> {
    Target::from_name(text)
        .ok_or_else(|| format!("`{text}` is neither indirect, components, image, none nor an AOV's name"))
}

/// `--targets` of `converge`: a target's name (not an AOV's).
fn named_target(text: &str) -> Result<Target, String> {
    Target::NAMED
        .into_iter()
        .find(|t| t.name() == text)
        .ok_or_else(|| format!("`{text}` is not indirect, components, image or none"))
}

/// An AOV: NAME=EXPR, or the name of a built-in expression.
fn aov(text: &str) -> Result<Aov, String> {
    Aov::parse(text)
}

/// Scattering events per path: 1 to [`limits::MAX_DEPTH`], as in a scene file.
fn depth(text: &str) -> Result<u32, String> {
    number(text, |n| (1..=limits::MAX_DEPTH).contains(&n), &format!("1 to {}", limits::MAX_DEPTH))
}

/// Worker threads: 1 to [`limits::max_threads`] (16 a core).
fn threads(text: &str) -> Result<usize, String> {
    let max = limits::max_threads();
    number(text, |n| (1..=max).contains(&n), &format!("1 to {max} (16 a core)"))
}

/// `--environment`: `white`, `none` or a file.
fn environment(text: &str) -> Result<Environment, String> {
    if text.is_empty() {
        return Err("an HDRI's path, `white` or `none`".into());
    }
    Ok(Environment::parse(text))
}

/// `--exposure`: any finite number of stops.
fn finite(text: &str) -> Result<f32, String> {
    number(text, f32::is_finite, "a finite number")
}

/// `--adaptive`: a relative standard error above zero.
fn relative_error(text: &str) -> Result<f32, String> {
    number(text, |t: f32| t.is_finite() && t > 0.0, "a positive relative error such as 0.02")
}

/// `--seconds`: a positive duration.
fn seconds(text: &str) -> Result<f64, String> {
    number(text, |t: f64| t.is_finite() && t > 0.0, "a positive number")
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::{CommandFactory, ValueEnum};

    #[test]
    fn the_command_line_is_consistent() {
        Cli::command().debug_assert();
    }

    /// The name the command line accepts for `value`.
    fn spelled(value: &impl ValueEnum) -> String {
        value.to_possible_value().map(|v| v.get_name().to_string()).unwrap_or_default()
    }

    /// The library's values are the command line's: each spelling is the name the library
    /// prints and reads back (in JSON, in files, in messages).
    #[test]
    fn every_spelling_is_the_library_name() {
        for layer in Layer::value_variants() {
            if let Layer::Component(c) = layer {
                assert_eq!(spelled(layer), c.name());
            }
        }
        for t in Target::NAMED {
            assert_eq!(target(t.name()), Ok(t));
            assert_eq!(named_target(t.name()), Ok(t));
        }
        assert_eq!(target("glossy").map(|t| t.name().to_string()), Ok("glossy".into()));
        assert!(target("2x").is_err() && named_target("glossy").is_err());
        for accel in Backend::value_variants() {
            assert_eq!(spelled(accel), accel.to_string());
        }
        for sampler in SamplerKind::value_variants() {
            assert_eq!(spelled(sampler), sampler.name());
        }
        for edge in Edge::value_variants() {
            assert_eq!(Edge::parse(&spelled(edge)), Some(*edge));
        }
    }

    #[test]
    fn counts_and_numbers_are_checked_as_they_parse() {
        assert_eq!(count::<u32>("3"), Ok(3));
        assert_eq!(count::<usize>("0"), Err("must be at least 1".into()));
        assert!(count::<u32>("x").is_err_and(|e| e.contains("invalid digit")));
        assert_eq!(finite("-2.5"), Ok(-2.5));
        assert!(finite("inf").is_err());
        assert!(relative_error("0").is_err() && relative_error("nan").is_err());
        assert_eq!(seconds("0.3"), Ok(0.3));
    }
}
