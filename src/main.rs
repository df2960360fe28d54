//! The `lightsplit` command line: parse, call the library, print. No rendering logic here.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use lightsplit::accel::Backend;
use lightsplit::component::Component;
use lightsplit::film;
use lightsplit::filter::{EdgeStops, Kernel, Setting, Target};
use lightsplit::output::{self, Layer, OutputError};
use lightsplit::render::{self, Features, Outputs, RenderOptions};
use lightsplit::scene;

/// Bad input: a scene file, an argument or an output path that cannot work.
const EXIT_INPUT: u8 = 2;
/// A failure while working on valid input.
const EXIT_FAILURE: u8 = 1;

#[derive(Parser)]
#[command(name = "lightsplit", version, about = "A path tracer that filters only the indirect diffuse light")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene file to an image.
    Render(RenderArgs),
    /// Re-filter a saved multi-layer EXR without rendering again.
    Filter(FilterCommandArgs),
    /// Compare an image with a reference: the paper's sum of squares, RMSE, relMSE.
    Compare(CompareArgs),
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

#[derive(clap::Args)]
struct BenchFeaturesArgs {
    /// The scene files (TOML).
    #[arg(required = true)]
    scenes: Vec<PathBuf>,
    #[arg(long, default_value_t = 128)]
    width: u32,
    #[arg(long, default_value_t = 128)]
    height: u32,
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Rounds, each rendering every mode once; medians are reported.
    #[arg(long, default_value_t = 5)]
    rounds: usize,
    /// Ray tracing backend.
    #[arg(long, value_enum, default_value_t = Backend::Embree)]
    accel: Backend,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Print one JSON object on stdout instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct InfoArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// The output the render would write (its format decides which layers are kept).
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    out: OutputArgs,
}

#[derive(clap::Args)]
struct StressArgs {
    /// Ray tracing backend.
    #[arg(long, value_enum, default_value_t = Backend::Embree)]
    accel: Backend,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Run only the rows whose name contains this text.
    #[arg(long)]
    only: Option<String>,
    /// Print one JSON object on stdout instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct ConvergeArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// A reference image (.exr or .hdr) of the same size; without it one is rendered at
    /// --reference-spp and cached in the output directory.
    #[arg(long, conflicts_with = "reference_spp")]
    reference: Option<PathBuf>,
    /// Samples per pixel of the rendered reference.
    #[arg(long, default_value_t = 1024)]
    reference_spp: u32,
    /// The sample counts to measure.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8,16,32,64,128,256")]
    spp: Vec<u32>,
    /// The filters: none, box3, weighted3, median3, box5 (or custom kernels as 1;2;1;...).
    #[arg(long, value_delimiter = ',', default_value = "none,box3,weighted3,median3,box5")]
    filters: Vec<String>,
    /// What the filters apply to.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "indirect")]
    targets: Vec<Target>,
    /// Edge-aware filtering: off, on (the paper's object stop), pure (also leave mixed border
    /// pixels alone, as --edge-pure does); a list measures each.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "off")]
    edge_aware: Vec<lightsplit::converge::Edge>,
    /// Renders per spp, each with its own seed: the summary gives their mean and spread.
    #[arg(long, default_value_t = 1)]
    seeds: u32,
    /// Also render each spp with adaptive sampling at this relative-error threshold (the spp
    /// then is the most a pixel takes), compared with uniform sampling at equal time.
    #[arg(long, value_name = "THRESHOLD")]
    adaptive: Option<f32>,
    /// Ray tracing backend.
    #[arg(long, value_enum, default_value_t = Backend::Embree)]
    accel: Backend,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Image width (default: the scene file's).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (default: the scene file's).
    #[arg(long)]
    height: Option<u32>,
    /// The spp whose difference images (the paper's Figure 6) are written (default: the
    /// measured spp nearest 50).
    #[arg(long)]
    diff_spp: Option<u32>,
    /// The output directory.
    #[arg(long)]
    out: PathBuf,
}

/// How to filter: shared by `render` and `filter`.
#[derive(clap::Args, Clone)]
struct FilterArgs {
    /// Noise-reduction filter: box3 (the paper's A), weighted3 (B), median3 (C), box5, or an odd
    /// square kernel as comma-separated weights.
    #[arg(long)]
    filter: Option<String>,
    /// What the filter applies to (default: indirect, the paper's method, when a filter is named).
    #[arg(long, value_enum)]
    filter_target: Option<Target>,
    /// Average only neighbours that show the same object as the centre pixel.
    #[arg(long)]
    edge_aware: bool,
    /// Also stop at creases: only neighbours whose normal is within DEG degrees.
    #[arg(long, value_name = "DEG")]
    edge_normal: Option<f32>,
    /// Also stop at depth steps: only neighbours whose depth differs by at most REL (relative).
    #[arg(long, value_name = "REL")]
    edge_depth: Option<f32>,
    /// Beyond the paper: leave pixels whose samples saw more than one object (antialiased
    /// borders) unfiltered and out of their neighbours' windows.
    #[arg(long)]
    edge_pure: bool,
}

impl FilterArgs {
    /// The setting to use: these flags over `base` (a scene file's `[filter]`, or none).
    fn check(&self, base: &Setting) -> Result<Setting, Failure> {
        let kernel = match self.filter.as_deref() {
            Some(name) => Some(Kernel::parse(name).map_err(Failure::input)?),
            None => base.kernel.clone(),
        };
        let target = match (self.filter_target, &self.filter) {
            (Some(t), _) => t,
            // A filter named here applies to its default target, not to the scene's.
            (None, Some(_)) => Target::Indirect,
            (None, None) => base.target,
        };
        if target != Target::None && kernel.is_none() {
            return Err(Failure::input("--filter-target needs --filter"));
        }
        let stops = EdgeStops {
            object: self.edge_aware || base.stops.object,
            normal_degrees: self.edge_normal.or(base.stops.normal_degrees),
            depth_relative: self.edge_depth.or(base.stops.depth_relative),
            pure: self.edge_pure || base.stops.pure,
        };
        stops.check().map_err(|e| Failure::input(format!("--edge-normal/--edge-depth: {e}")))?;
        Ok(Setting { kernel, target, stops })
    }
}

/// How a render becomes its output: filtered, exposed, one layer or all. Shared by `render`
/// and `filter`.
#[derive(clap::Args)]
struct OutputArgs {
    #[command(flatten)]
    filter: FilterArgs,
    /// Exposure in stops for PNG output.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    exposure: f32,
    /// Which layer a PNG or HDR output shows (an EXR holds them all).
    #[arg(long, value_enum, default_value_t = LayerName::Final)]
    layer: LayerName,
}

impl OutputArgs {
    /// Checks before any work: the exposure, the filter (these flags over `base`), and that the
    /// layer can be written as `format` with that filter.
    fn check(&self, base: &Setting, format: film::Format) -> Result<Setting, Failure> {
        if !self.exposure.is_finite() {
            return Err(Failure::input("--exposure must be a finite number"));
        }
        let setting = self.filter.check(base)?;
        self.layer().check(format, &setting)?;
        Ok(setting)
    }

    /// The layer asked for.
    fn layer(&self) -> Layer {
        self.layer.into()
    }

    /// Filters `film` as `setting` says and writes it to `path`; returns the filter's seconds.
    fn write(&self, film: &film::Film, setting: &Setting, path: &Path) -> Result<f64, OutputError> {
        output::write(film, setting, path, self.layer(), self.exposure)
    }
}

#[derive(clap::Args)]
struct FilterCommandArgs {
    /// A multi-layer EXR written by `lightsplit render`.
    input: PathBuf,
    /// The output: .exr (every layer), .png or .hdr (the final image).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    out: OutputArgs,
}

#[derive(clap::Args)]
struct CompareArgs {
    /// The image to judge (.exr or .hdr).
    test: PathBuf,
    /// The reference (.exr or .hdr), e.g. a high-sample render of the same scene.
    reference: PathBuf,
    /// Write a brightened difference image (the paper's Figure 6): darker is a larger difference.
    #[arg(long)]
    diff: Option<PathBuf>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct BenchAccelArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Primary rays per set (shadow and incoherent rays start at their hits).
    #[arg(long, default_value_t = 1 << 20)]
    rays: usize,
    /// Threads for the multi-threaded rows (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Seconds each measurement runs at least.
    #[arg(long, default_value_t = 0.3)]
    seconds: f64,
    /// Rounds per row, each measuring both backends back to back; medians are reported.
    #[arg(long, default_value_t = 5)]
    rounds: usize,
    /// Instead of the backends, measure Embree's scene settings against each other: robust or
    /// not, build quality low, medium, high (build time, rays per second, answers changed).
    #[arg(long)]
    embree_settings: bool,
    /// Print one JSON object on stdout instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct RenderArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Output image: .exr (32-bit float), .png (8-bit sRGB) or .hdr (Radiance RGBE).
    /// Default: the scene's name with .exr, in the current directory.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Samples per pixel (default: the scene file's).
    #[arg(long)]
    spp: Option<u32>,
    /// Ray tracing backend.
    #[arg(long, value_enum, default_value_t = Backend::Embree)]
    accel: Backend,
    /// Worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Random seed (default: the scene file's).
    #[arg(long)]
    seed: Option<u64>,
    /// Image width (default: the scene file's).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (default: the scene file's).
    #[arg(long)]
    height: Option<u32>,
    /// Most scattering events per path (default: the scene file's).
    #[arg(long)]
    max_depth: Option<u32>,
    #[command(flatten)]
    out: OutputArgs,
    /// Print each dropped non-finite sample (the first 20): its pixel, sample index and path.
    #[arg(long)]
    debug_nonfinite: bool,
    /// Adaptive sampling: stop a pixel once the estimated relative error of its mean (standard
    /// error over mean luminance, checked after 16, 32, 64, ... samples) is at most THRESHOLD,
    /// e.g. 0.02; --spp is then the most a pixel takes. Converged tiles are skipped.
    #[arg(long, value_name = "THRESHOLD")]
    adaptive: Option<f32>,
    /// Compute every feature (MIS, the split, the guides, textures) whatever the scene and the
    /// output need, on Embree's robust high-quality build: the general renderer, for
    /// comparison. The beauty is the same.
    #[arg(long)]
    all_features: bool,
    /// Print one JSON object on stdout instead of the summary line.
    #[arg(long)]
    json: bool,
}

/// `--layer`'s spellings.
#[derive(Clone, Copy, clap::ValueEnum)]
enum LayerName {
    /// The final image (filtered when a filter is on).
    Final,
    /// The unfiltered beauty.
    Raw,
    Emitted,
    Direct,
    Caustic,
    Indirect,
    /// The filtered indirect component (needs a filter on `indirect`).
    IndirectFiltered,
    Albedo,
}

impl From<LayerName> for Layer {
    fn from(l: LayerName) -> Layer {
        match l {
            LayerName::Final => Layer::Final,
            LayerName::Raw => Layer::Raw,
            LayerName::Emitted => Layer::Component(Component::Emitted),
            LayerName::Direct => Layer::Component(Component::Direct),
            LayerName::Caustic => Layer::Component(Component::Caustic),
            LayerName::Indirect => Layer::Component(Component::Indirect),
            LayerName::IndirectFiltered => Layer::IndirectFiltered,
            LayerName::Albedo => Layer::Albedo,
        }
    }
}

/// A failure with its exit status.
struct Failure {
    code: u8,
    message: String,
}

impl Failure {
    fn input(message: impl ToString) -> Self {
        Failure { code: EXIT_INPUT, message: message.to_string() }
    }
    fn failed(message: impl ToString) -> Self {
        Failure { code: EXIT_FAILURE, message: message.to_string() }
    }
}

impl From<OutputError> for Failure {
    fn from(e: OutputError) -> Self {
        if e.is_input() {
            Failure::input(e)
        } else {
            Failure::failed(e)
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => render_command(args),
        Command::Filter(args) => filter_command(args),
        Command::Compare(args) => compare_command(args),
        Command::BenchAccel(args) => bench_accel_command(args),
        Command::Converge(args) => converge_command(args),
        Command::Stress(args) => stress_command(args),
        Command::Info(args) => info_command(args),
        Command::BenchFeatures(args) => bench_features_command(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("error: {}", f.message);
            ExitCode::from(f.code)
        }
    }
}

fn progress_bar(total: u64, quiet: bool) -> ProgressBar {
    let bar = ProgressBar::new(total);
    if quiet || !std::io::stderr().is_terminal() {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    } else if let Ok(style) =
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {wide_bar} {percent}% (eta {eta})")
    {
        bar.set_style(style);
    }
    bar
}

fn info_command(args: InfoArgs) -> Result<(), Failure> {
    let scene = scene::load(&args.scene).map_err(Failure::input)?;
    let output = args.output.clone().unwrap_or_else(|| default_output(&args.scene));
    let format = film::check_output(&output).map_err(Failure::input)?;
    let setting = args.out.check(&scene.filter, format)?;
    let analysis = scene::analysis::Analysis::of(&scene);
    println!("{}", args.scene.display());
    print!("{analysis}");
    let Outputs { split, guides } = args.out.layer().reads(format, &setting);
    println!(
        "and the outputs ({}, filter {}) need:",
        output.display(),
        setting.kernel.as_ref().map_or("none".to_string(), |k| k.name())
    );
    use scene::analysis::need_line;
    println!(
        "{}",
        need_line("the component split", split, "an EXR, a filter on indirect, or a component layer")
    );
    println!(
        "{}",
        need_line(
            "guide buffers (ID, normal, depth)",
            guides,
            "an EXR, edge-aware filtering, or the albedo layer"
        )
    );
    let features = Features::needed(&analysis, Outputs { split, guides });
    println!("so the render computes: {} (of mis+split+guides+textures)", features.names());
    Ok(())
}

fn stress_command(args: StressArgs) -> Result<(), Failure> {
    use lightsplit::stress;
    if args.threads == Some(0) {
        return Err(Failure::input("--threads must be at least 1"));
    }
    let names: Vec<&str> =
        stress::names().filter(|n| args.only.as_deref().is_none_or(|o| n.contains(o))).collect();
    if names.is_empty() {
        return Err(Failure::input(format!(
            "--only: no row matches; the rows are: {}",
            stress::names().collect::<Vec<_>>().join(", ")
        )));
    }
    let bar = progress_bar(names.len() as u64, args.json);
    let mut rows = Vec::new();
    for name in names {
        bar.set_message(name);
        rows.push(stress::run_row(name, args.accel, args.threads).map_err(Failure::failed)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let passed = rows.iter().filter(|r| r.pass).count();
    // A limit row may fail: it measures past what f32 holds, and says so.
    let failed = rows.iter().filter(|r| !r.pass && !r.limit).count();
    if args.json {
        let json =
            serde_json::json!({ "accel": args.accel, "passed": passed, "failed": failed, "rows": rows });
        println!("{json}");
    } else {
        let width = rows.iter().map(|r| r.name.len()).max().unwrap_or(0);
        let verdict = |r: &stress::Row| match (r.pass, r.limit) {
            (true, _) => "yes",
            (false, true) => "f32",
            (false, false) => "NO",
        };
        println!("{:width$}  {:4}  figure", "row", "pass");
        for r in &rows {
            println!("{:width$}  {:4}  {}", r.name, verdict(r), r.figure);
        }
        for r in rows.iter().filter(|r| !r.pass) {
            let what = if r.limit { "past f32's reach" } else { "FAILED" };
            println!("\n{} {what}: {}", r.name, r.note);
        }
        println!("\n{passed} of {} rows passed on {}, {failed} failed", rows.len(), args.accel);
    }
    if failed > 0 {
        return Err(Failure::failed(format!("{failed} stress rows failed")));
    }
    Ok(())
}

fn render_command(args: RenderArgs) -> Result<(), Failure> {
    let scene = scene::load(&args.scene).map_err(Failure::input)?;
    let output = args.output.clone().unwrap_or_else(|| default_output(&args.scene));
    let format = film::check_output(&output).map_err(Failure::input)?;

    let mut options = RenderOptions::from_scene(&scene);
    options.accel = args.accel;
    options.threads = args.threads;
    options.debug_nonfinite = args.debug_nonfinite;
    if let Some(v) = args.spp {
        options.spp = v;
    }
    if let Some(v) = args.seed {
        options.seed = v;
    }
    if let Some(v) = args.width {
        options.width = v;
    }
    if let Some(v) = args.height {
        options.height = v;
    }
    if let Some(v) = args.max_depth {
        options.max_depth = v;
    }
    for (name, value) in [
        ("spp", options.spp),
        ("width", options.width),
        ("height", options.height),
        ("max-depth", options.max_depth),
    ] {
        if value == 0 {
            return Err(Failure::input(format!("--{name} must be at least 1")));
        }
    }
    if args.threads == Some(0) {
        return Err(Failure::input("--threads must be at least 1"));
    }
    let setting = args.out.check(&scene.filter, format)?;
    check_adaptive(args.adaptive)?;
    options.adaptive = args.adaptive;
    if args.all_features {
        options.features = Features::ALL;
        options.embree = Default::default();
    } else {
        // `from_scene` found what the scene needs; the output decides the split and the guides.
        let Outputs { split, guides } = args.out.layer().reads(format, &setting);
        options.features = Features { split, guides, ..options.features };
    }

    let bar = progress_bar(options.width as u64 * options.height as u64 * options.spp as u64, args.json);
    let out = render::render(&scene, &options, &|n| bar.inc(n)).map_err(Failure::failed)?;
    bar.finish_and_clear();
    let filter_seconds = args.out.write(&out.film, &setting, &output)?;

    let s = out.stats;
    let samples_per_second = s.samples as f64 / s.seconds.max(1e-9);
    let rays_per_second = s.rays as f64 / s.seconds.max(1e-9);
    if args.json {
        let json = serde_json::json!({
            "scene": args.scene,
            "seconds": s.seconds,
            "build_seconds": s.build_seconds,
            "spp": options.spp,
            "width": options.width,
            "height": options.height,
            "accel": options.accel,
            "threads": rayon_threads(options.threads),
            "samples": s.samples,
            "rays": s.rays,
            "samples_per_second": samples_per_second,
            "rays_per_second": rays_per_second,
            "nonfinite_samples": s.nonfinite_samples,
            "adaptive": options.adaptive,
            "stopped_early_pixels": s.stopped_early,
            "mean_spp": s.samples as f64 / (options.width as f64 * options.height as f64),
            "features": options.features,
            "embree": options.embree,
            "buffer_bytes": s.buffer_bytes,
            "filter": setting.kernel.as_ref().map(Kernel::name),
            "filter_target": setting.target.name(),
            "edge_aware": setting.stops.object,
            "filter_seconds": filter_seconds,
            "outputs": [output],
        });
        println!("{json}");
    } else {
        let spp = match options.adaptive {
            Some(t) => format!(
                "up to {} spp (adaptive {t}: {:.1} spp a pixel, {} pixels stopped early)",
                options.spp,
                s.samples as f64 / (options.width as f64 * options.height as f64),
                s.stopped_early
            ),
            None => format!("{} spp", options.spp),
        };
        eprintln!(
            "{}: {}x{} at {spp} in {:.2} s ({:.3} s build): {:.3} M samples/s, {:.2} M rays/s{}; wrote {}",
            args.scene.display(),
            options.width,
            options.height,
            s.seconds,
            s.build_seconds,
            samples_per_second / 1e6,
            rays_per_second / 1e6,
            if s.nonfinite_samples > 0 {
                format!(", {} non-finite samples dropped", s.nonfinite_samples)
            } else {
                String::new()
            },
            output.display()
        );
    }
    Ok(())
}

/// An adaptive threshold must be a positive, finite relative error.
fn check_adaptive(threshold: Option<f32>) -> Result<(), Failure> {
    match threshold {
        Some(t) if !(t.is_finite() && t > 0.0) => {
            Err(Failure::input(format!("--adaptive must be a positive relative error such as 0.02, not {t}")))
        }
        _ => Ok(()),
    }
}

fn rayon_threads(threads: Option<usize>) -> usize {
    threads.unwrap_or_else(rayon::current_num_threads)
}

fn default_output(scene: &Path) -> PathBuf {
    let stem = scene.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "render".into());
    PathBuf::from(format!("{stem}.exr"))
}

fn bench_accel_command(args: BenchAccelArgs) -> Result<(), Failure> {
    let scene = scene::load(&args.scene).map_err(Failure::input)?;
    if args.rays == 0 {
        return Err(Failure::input("--rays must be at least 1"));
    }
    if args.threads == Some(0) {
        return Err(Failure::input("--threads must be at least 1"));
    }
    if !(args.seconds.is_finite() && args.seconds > 0.0) {
        return Err(Failure::input("--seconds must be a positive number"));
    }
    let options = lightsplit::bench::BenchAccelOptions {
        rays: args.rays,
        threads: args.threads.unwrap_or_else(rayon::current_num_threads),
        min_seconds: args.seconds,
        rounds: args.rounds.max(1),
        seed: 1,
    };
    let bar = progress_bar(0, args.json);
    if args.embree_settings {
        let rows = lightsplit::bench::bench_embree_settings(&scene, &options, &|done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })
        .map_err(Failure::failed)?;
        bar.finish_and_clear();
        if args.json {
            println!("{}", serde_json::json!({ "scene": args.scene, "rows": rows }));
        } else {
            print!("{}", lightsplit::bench::settings_table(&rows));
        }
        return Ok(());
    }
    let report = lightsplit::bench::bench_accel(&scene, &options, &|done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })
    .map_err(Failure::failed)?;
    bar.finish_and_clear();
    if args.json {
        let json = serde_json::to_string(&report).map_err(Failure::failed)?;
        println!("{json}");
    } else {
        print!("{}", report.table());
    }
    Ok(())
}

fn filter_command(args: FilterCommandArgs) -> Result<(), Failure> {
    let format = film::check_output(&args.output).map_err(Failure::input)?;
    let setting = args.out.check(&Setting::default(), format)?;
    let (width, height, channels) = film::read_exr_channels(&args.input).map_err(Failure::input)?;
    let film = film::Film::from_channels(width, height, &channels)
        .map_err(|e| Failure::input(format!("{}: {e} (not a lightsplit render?)", args.input.display())))?;
    args.out.write(&film, &setting, &args.output)?;
    Ok(())
}

fn converge_command(args: ConvergeArgs) -> Result<(), Failure> {
    use lightsplit::converge::{self, Event, Plan};
    let scene = scene::load(&args.scene).map_err(Failure::input)?;
    if args.spp.is_empty() || args.spp.contains(&0) {
        return Err(Failure::input("--spp must list sample counts of at least 1"));
    }
    if args.seeds == 0 || args.reference_spp == 0 || args.threads == Some(0) {
        return Err(Failure::input("--seeds, --reference-spp and --threads must be at least 1"));
    }
    check_adaptive(args.adaptive)?;
    if args.diff_spp.is_some_and(|d| !args.spp.contains(&d)) {
        return Err(Failure::input("--diff-spp must be one of the --spp values"));
    }
    // Custom kernels are written with ';' between weights here, since ',' separates filters.
    let filters: Vec<String> = args.filters.iter().map(|f| f.replace(';', ",")).collect();
    let choices = converge::choices(&filters, &args.targets, &args.edge_aware).map_err(Failure::input)?;
    let mut options = RenderOptions::from_scene(&scene);
    options.accel = args.accel;
    options.threads = args.threads;
    options.width = args.width.unwrap_or(options.width);
    options.height = args.height.unwrap_or(options.height);
    let mut spps = args.spp.clone();
    spps.sort_unstable();
    spps.dedup();
    let diff_spp = args.diff_spp.or_else(|| spps.iter().copied().min_by_key(|&s| (s as i64 - 50).abs()));
    let plan = Plan {
        scene_path: args.scene.clone(),
        options,
        spps,
        seeds: args.seeds,
        choices,
        reference: args.reference.clone(),
        reference_spp: args.reference_spp,
        diff_spp,
        adaptive: args.adaptive,
        out: args.out.clone(),
    };
    let bar = progress_bar(plan.total_samples(), false);
    let report = |e: Event| match e {
        Event::Samples(n) => bar.inc(n),
        Event::Message(m) => bar.suspend(|| eprintln!("{m}")),
    };
    let map = |e: converge::ConvergeError| match e {
        converge::ConvergeError::Input(m) => Failure::input(m),
        converge::ConvergeError::Failed(m) => Failure::failed(m),
    };
    let rows = converge::run(&plan, &scene, &report).map_err(map)?;
    bar.finish_and_clear();
    let md = converge::report(&plan, &rows).map_err(map)?;
    print!("{md}");
    eprintln!("wrote {}", plan.out.display());
    Ok(())
}

fn compare_command(args: CompareArgs) -> Result<(), Failure> {
    if let Some(diff) = &args.diff {
        film::check_output(diff).map_err(Failure::input)?;
    }
    let test = film::read_image(&args.test).map_err(Failure::input)?;
    let reference = film::read_image(&args.reference).map_err(Failure::input)?;
    let errors = lightsplit::metrics::compare(&test, &reference).map_err(Failure::input)?;
    if let Some(diff) = &args.diff {
        let image = lightsplit::metrics::difference_image(&test, &reference);
        film::write(&image, diff, 0.0).map_err(Failure::failed)?;
    }
    if args.json {
        println!("{}", serde_json::to_string(&errors).map_err(Failure::failed)?);
    } else {
        println!(
            "{} against {}: sse {:.6e}  rmse {:.6e}  relmse {:.6e}  (worst 0.1% dropped: rmse {:.6e}  relmse {:.6e})",
            args.test.display(),
            args.reference.display(),
            errors.sse,
            errors.rmse,
            errors.relmse,
            errors.rmse_trimmed,
            errors.relmse_trimmed
        );
    }
    Ok(())
}

fn bench_features_command(args: BenchFeaturesArgs) -> Result<(), Failure> {
    use lightsplit::bench::features;
    for (name, value) in [("width", args.width), ("height", args.height), ("spp", args.spp)] {
        if value == 0 {
            return Err(Failure::input(format!("--{name} must be at least 1")));
        }
    }
    if args.rounds == 0 || args.threads == Some(0) {
        return Err(Failure::input("--rounds and --threads must be at least 1"));
    }
    // Every scene is loaded before any is measured, so a bad file fails at once.
    let scenes = args
        .scenes
        .iter()
        .map(|p| scene::load(p).map(|s| (p, s)))
        .collect::<Result<Vec<_>, _>>()
        .map_err(Failure::input)?;
    let options = features::BenchFeaturesOptions {
        width: args.width,
        height: args.height,
        spp: args.spp,
        rounds: args.rounds,
        threads: args.threads,
        accel: args.accel,
    };
    let bar = progress_bar(scenes.len() as u64, args.json);
    let mut rows = Vec::new();
    for (path, scene) in &scenes {
        bar.set_message(path.display().to_string());
        rows.push(features::bench_scene(path, scene, &options).map_err(Failure::failed)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    if args.json {
        println!("{}", serde_json::json!({ "rows": rows }));
    } else {
        print!("{}", features::table(&rows, &options));
    }
    Ok(())
}
