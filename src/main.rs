//! The `lightsplit` command line: parse (the grammar is in `cli.rs`), call the library, print.
//! No rendering logic and no output rules here: those live in the library.

mod cli;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::Parser;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};

use cli::{
    BenchAccelArgs, BenchFeaturesArgs, Cli, Command, CompareArgs, ConvergeArgs, FilterCommandArgs, InfoArgs,
    MergeArgs, RenderArgs, StressArgs,
};
use lightsplit::film;
use lightsplit::filter::{Method, Setting, Target};
use lightsplit::output::OutputError;
use lightsplit::render::sampler::SamplerKind;
use lightsplit::render::{self, Features, Outputs, RenderOptions};
use lightsplit::scene;

/// Bad input: a scene file, an argument or an output path that cannot work.
const EXIT_INPUT: u8 = 2;
/// A failure while working on valid input.
const EXIT_FAILURE: u8 = 1;

/// A failure with its exit status.
struct Failure {
    code: u8,
    message: String,
}

impl Failure {
    /// Nothing more to say: standard output's reader has gone (a closed pipe, as in `| head`).
    /// The work is done; the command ends quietly with status 0, as `rg` and `fd` do.
    fn reader_gone() -> Self {
        Failure { code: 0, message: String::new() }
    }
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

/// Writes one line to standard output, as `println!` would, but a closed pipe ends the command
/// quietly ([`Failure::reader_gone`]) instead of panicking.
macro_rules! say {
    ($($arg:tt)*) => {
        print_line(format_args!($($arg)*))?
    };
}

fn print_line(line: std::fmt::Arguments) -> Result<(), Failure> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{line}").and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(Failure::reader_gone()),
        Err(e) => Err(Failure::failed(format!("cannot write to standard output: {e}"))),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    remove_temporaries_on_signals();
    let result = match cli.command {
        Command::Render(args) => render_command(args),
        Command::Filter(args) => filter_command(args),
        Command::Merge(args) => merge_command(args),
        Command::Compare(args) => compare_command(args),
        Command::BenchAccel(args) => bench_accel_command(args),
        Command::Converge(args) => converge_command(args),
        Command::Stress(args) => stress_command(args),
        Command::Info(args) => info_command(args),
        Command::BenchFeatures(args) => bench_features_command(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) if f.message.is_empty() => ExitCode::from(f.code),
        Err(f) => {
            eprintln!("error: {}", printable(&f.message));
            ExitCode::from(f.code)
        }
    }
}

/// The filter a file's metadata names: `box3 on indirect`, or none.
fn filter_label(setting: &Setting) -> Option<String> {
    setting
        .method
        .as_ref()
        .filter(|_| setting.target != Target::None)
        .map(|k| format!("{} on {}", k.name(), setting.target.name()))
}

/// While a render runs, the first SIGINT, SIGTERM or SIGHUP sets this: the render ends after
/// its pass, and what it has is written.
static STOP: AtomicBool = AtomicBool::new(false);
/// Whether a signal now stops the render gracefully ([`STOP`]) instead of ending the process.
static GRACEFUL: AtomicBool = AtomicBool::new(false);
/// The signal that set [`STOP`] (0 for none).
static STOPPED_BY: AtomicI32 = AtomicI32::new(0);

/// On SIGINT, SIGTERM or SIGHUP: while a render runs ([`GRACEFUL`]), the first asks it to stop
/// after the pass under way ([`STOP`]) and the program to end, once it has written what was
/// rendered, with 128 + the signal's number. Otherwise (a second signal, or one outside a
/// render) removes the temporary file of a write under way (the output it would replace is left
/// as it was) and exits with 128 + the signal's number, the status a shell reports for a
/// process the signal stopped.
fn remove_temporaries_on_signals() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    match signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) {
        Ok(mut signals) => {
            std::thread::spawn(move || {
                for signal in signals.forever() {
                    if GRACEFUL.load(Ordering::SeqCst) && !STOP.swap(true, Ordering::SeqCst) {
                        STOPPED_BY.store(signal, Ordering::SeqCst);
                        eprintln!(
                            "\nstopping after the pass under way, then writing what was rendered (again to stop now)"
                        );
                        continue;
                    }
                    film::remove_temporaries_and_exit(128 + signal)
                }
            });
        }
        Err(e) => {
            eprintln!("warning: no signal handler ({e}): a stop during a write may leave a temporary file")
        }
    }
}

/// `text` with its control characters (a NUL or an ESC from a file name, say) escaped, so that
/// an error message cannot move the cursor, recolour or clear the terminal it is printed on.
fn printable(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_control() && c != '\n' && c != '\t' {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
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

/// Loads a scene and the filter setting its `[filter]` section asks for: a bad section is a bad
/// scene, whether or not the command filters.
fn load_scene(path: &Path) -> Result<(scene::Scene, Setting), Failure> {
    let scene = scene::load(path).map_err(Failure::input)?;
    for note in &scene.notes {
        eprintln!("note: {}: {note}", path.display());
    }
    let filter = Setting::of_scene(&scene).map_err(Failure::input)?;
    Ok((scene, filter))
}

fn info_command(args: InfoArgs) -> Result<(), Failure> {
    let (scene, scene_filter) = load_scene(&args.scene)?;
    let output = args.output.clone().unwrap_or_else(|| default_output(&args.scene));
    let format = film::check_output(&output).map_err(Failure::input)?;
    let setting = args.out.check(&scene_filter, format)?;
    let analysis = scene::analysis::Analysis::of(&scene);
    say!("{}", args.scene.display());
    say!("{}", analysis.to_string().trim_end_matches('\n'));
    let Outputs { split, guides } = args.out.layer.reads(format, &setting);
    say!(
        "and the outputs ({}, filter {}) need:",
        output.display(),
        setting.method.as_ref().map_or("none".to_string(), |k| k.name())
    );
    use scene::analysis::need_line;
    say!("{}", need_line("the component split", split, "an EXR, a filter on indirect, or a component layer"));
    say!(
        "{}",
        need_line(
            "guide buffers (ID, normal, depth)",
            guides,
            "an EXR, edge-aware filtering, or the albedo layer"
        )
    );
    let features = Features::needed(&analysis, Outputs { split, guides });
    say!("so the render computes: {} (of mis+split+guides+textures)", features.names());
    if args.out.exposure != 0.0 && format == film::Format::Png {
        say!("and the PNG is exposed by {} stops", args.out.exposure);
    }
    Ok(())
}

fn stress_command(args: StressArgs) -> Result<(), Failure> {
    use lightsplit::stress;
    let engine = &args.run.engine;
    let names: Vec<&str> =
        stress::names().filter(|n| args.only.as_deref().is_none_or(|o| n.contains(o))).collect();
    if names.is_empty() {
        return Err(Failure::input(format!(
            "--only: no row matches; the rows are: {}",
            stress::names().collect::<Vec<_>>().join(", ")
        )));
    }
    let bar = progress_bar(names.len() as u64, args.run.json);
    let mut rows = Vec::new();
    for name in names {
        bar.set_message(name);
        rows.push(stress::run_row(name, engine.accel, engine.threads).map_err(Failure::failed)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let passed = rows.iter().filter(|r| r.pass).count();
    let failed = rows.iter().filter(|r| !r.pass).count();
    if args.run.json {
        let json =
            serde_json::json!({ "accel": engine.accel, "passed": passed, "failed": failed, "rows": rows });
        say!("{json}");
    } else {
        let width = rows.iter().map(|r| r.name.len()).max().unwrap_or(0);
        let verdict = |r: &stress::Row| if r.pass { "yes" } else { "NO" };
        say!("{:width$}  {:4}  figure", "row", "pass");
        for r in &rows {
            say!("{:width$}  {:4}  {}", r.name, verdict(r), r.figure);
        }
        for r in rows.iter().filter(|r| !r.pass) {
            say!("\n{} FAILED: {}", r.name, r.note);
        }
        say!("\n{passed} of {} rows passed on {}, {failed} failed", rows.len(), engine.accel);
    }
    if failed > 0 {
        return Err(Failure::failed(format!("{failed} stress rows failed")));
    }
    Ok(())
}

fn render_command(args: RenderArgs) -> Result<(), Failure> {
    let (scene, scene_filter) = load_scene(&args.scene)?;
    let output = args.output.clone().unwrap_or_else(|| default_output(&args.scene));
    let format = film::check_output(&output).map_err(Failure::input)?;
    film::check_not_an_input(&output, &scene.inputs).map_err(Failure::input)?;

    let mut options = RenderOptions::from_scene(&scene);
    options.accel = args.run.engine.accel;
    options.threads = args.run.engine.threads;
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
    if let Some(v) = args.sampler {
        options.sampler = v;
    }
    // A part file is never filtered (the merge filters once): the scene's `[filter]` does not
    // apply to it, and a filter on the command line is an error.
    let part_mode = args.part.is_some();
    let setting = if part_mode {
        let setting = args.out.check(&Setting::default(), format)?;
        if format != film::Format::Exr {
            return Err(Failure::input(
                "--part writes a part file for `lightsplit merge`: the output must be .exr",
            ));
        }
        if setting.method.is_some() && setting.target != Target::None {
            return Err(Failure::input(
                "a part is never filtered: give the filter to `lightsplit merge`, which filters the merged image once",
            ));
        }
        setting
    } else {
        args.out.check(&scene_filter, format)?
    };
    scene::limits::check_render_memory(options.width, options.height).map_err(Failure::input)?;
    options.adaptive = args.adaptive;
    if args.all_features {
        options.features = Features::ALL;
        options.build = Default::default();
    } else if part_mode {
        // A merge may filter any way: a part keeps the split and the guides.
        options.features = Features { split: true, guides: true, ..options.features };
    } else {
        // `from_scene` found what the scene needs; the output decides the split and the guides.
        let Outputs { split, guides } = args.out.layer.reads(format, &setting);
        options.features = Features { split, guides, ..options.features };
    }
    if let Some(text) = &args.part {
        options.part = part_from(text)?;
        options.part.check(options.spp).map_err(|e| Failure::input(format!("{}: {e}", part_flag(text))))?;
    }

    // The part file: the output of a part, else beside the output (checkpoints, a stop).
    let part_path = if part_mode { output.clone() } else { part_file_of(&output) };
    film::check_not_an_input(&part_path, &scene.inputs).map_err(Failure::input)?;
    if !part_mode && (args.checkpoint.is_some() || args.time_limit.is_some()) {
        // It will be written, or most likely: its name must be one that can be.
        film::check_output(&part_path).map_err(Failure::input)?;
    }
    let resume = match &args.resume {
        None => None,
        Some(path) => {
            let bad = |e: String| Failure::input(format!("--resume {}: {e}", path.display()));
            // A part's output is its part file, which a resumed part rewrites whole (a part
            // file too); any other output would replace the checkpoint with an image.
            if !part_mode {
                film::check_not_an_input(&output, std::slice::from_ref(path)).map_err(Failure::input)?;
            }
            Some(lightsplit::part::read_checkpoint(path, &scene, &mut options).map_err(bad)?)
        }
    };
    let needs_key = part_mode || args.checkpoint.is_some() || args.resume.is_some();
    let mut key = if needs_key {
        Some(lightsplit::part::run_key(&scene, &options).map_err(Failure::input)?)
    } else {
        None
    };
    let header = |key: String, seconds: f64, complete: bool| lightsplit::part::Header {
        key,
        part: options.part,
        spp: options.spp,
        adaptive: options.adaptive,
        complete,
        meta: render::metadata(&scene, &options, seconds),
    };
    let checkpoint_key = key.clone().unwrap_or_default();
    let write_checkpoint = |sums: &render::Accumulated| {
        if let Err(e) = lightsplit::part::write(&part_path, sums, &header(checkpoint_key.clone(), 0.0, false))
        {
            eprintln!("warning: checkpoint not written: {e}");
        }
    };

    let range = options.part.samples(options.spp.max(1));
    let total = options.width as u64 * options.height as u64 * (range.end - range.start) as u64;
    let bar = progress_bar(total, args.run.json);
    if let Some(r) = &resume {
        bar.inc(r.samples.iter().map(|&n| n as u64).sum());
    }
    let control = render::Control {
        progress: &|n| bar.inc(n),
        stop: Some(&STOP),
        time_limit: args.time_limit,
        checkpoint: args.checkpoint.map(|s| (s, &write_checkpoint as &render::Checkpoint)),
        resume,
        keep_sums: part_mode,
    };
    GRACEFUL.store(true, Ordering::SeqCst);
    let rendered = render::render_controlled(&scene, &options, control);
    GRACEFUL.store(false, Ordering::SeqCst);
    let out = rendered.map_err(|e| if e.is_input() { Failure::input(e) } else { Failure::failed(e) })?;
    bar.finish_and_clear();
    let interrupted = out.stats.interrupted;
    if let Some(sums) = &out.sums {
        let key = match key.take() {
            Some(k) => k,
            None => lightsplit::part::run_key(&scene, &options).map_err(Failure::failed)?,
        };
        lightsplit::part::write(&part_path, sums, &header(key, out.stats.seconds, !interrupted))
            .map_err(Failure::failed)?;
    }
    let meta = film::Metadata {
        filter: filter_label(&setting),
        ..render::metadata(&scene, &options, out.stats.seconds)
    };
    let filter_seconds = if part_mode { 0.0 } else { args.out.write(out.film, &setting, &output, &meta)? };
    if !part_mode && !interrupted && args.checkpoint.is_some() {
        // Complete: the checkpoint has served.
        let _ = std::fs::remove_file(&part_path);
    }

    let s = out.stats;
    let samples_per_second = s.samples as f64 / s.seconds.max(1e-9);
    let rays_per_second = s.rays as f64 / s.seconds.max(1e-9);
    if args.run.json {
        let json = serde_json::json!({
            "scene": args.scene.to_string_lossy(),
            "seconds": s.seconds,
            "build_seconds": s.build_seconds,
            "spp": options.spp,
            "width": options.width,
            "height": options.height,
            "accel": options.accel,
            "sampler": options.sampler.name(),
            "seed": options.seed,
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
            "embree": options.build,
            "buffer_bytes": s.buffer_bytes,
            "filter": setting.method.as_ref().map(Method::name),
            "filter_target": setting.target.name(),
            "edge_aware": setting.stops.object,
            "edge_normal_degrees": setting.stops.normal_degrees,
            "edge_depth_relative": setting.stops.depth_relative,
            "edge_pure": setting.stops.pure,
            "filter_seconds": filter_seconds,
            "max_depth": options.max_depth,
            "version": env!("CARGO_PKG_VERSION"),
            "part": options.part.to_string(),
            "samples_per_pixel_min": s.min_spp,
            "samples_per_pixel_max": s.max_spp,
            "interrupted": interrupted,
            "part_file": (part_mode || interrupted).then(|| part_path.to_string_lossy()),
            "outputs": [output.to_string_lossy()],
        });
        say!("{json}");
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
        let spp = if part_mode {
            format!("part {} of {spp}: samples {}..{}", options.part, range.start, range.end)
        } else {
            spp
        };
        let spp = format!("{spp} ({})", options.sampler);
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
    if interrupted {
        let (lo, hi) = (s.min_spp, s.max_spp);
        let got = if lo == hi { format!("{lo}") } else { format!("{lo} to {hi}") };
        let why = match STOPPED_BY.load(Ordering::SeqCst) {
            0 => "the time limit".to_string(),
            sig => format!("signal {sig}"),
        };
        eprintln!(
            "stopped by {why}: each pixel has {got} of its {} samples; the part file {} holds them (--resume it to go on)",
            range.end - range.start,
            part_path.display()
        );
    }
    match STOPPED_BY.load(Ordering::SeqCst) {
        0 => Ok(()),
        sig => Err(Failure { code: (128 + sig).clamp(0, 255) as u8, message: String::new() }),
    }
}

/// The part a render takes: `I/N`, or `auto` from the scheduler's environment.
fn part_from(text: &str) -> Result<render::Part, Failure> {
    let part = if text == "auto" {
        lightsplit::part::part_from_scheduler(|name| std::env::var_os(name))
    } else {
        lightsplit::part::parse_part(text)
    };
    part.map_err(|e| Failure::input(format!("{}: {e}", part_flag(text))))
}

/// The flag a part came from, for a message: `--part`, or `--part auto`.
fn part_flag(text: &str) -> &'static str {
    if text == "auto" {
        "--part auto"
    } else {
        "--part"
    }
}

/// The part file beside `output`: its name with `.part.exr`.
fn part_file_of(output: &Path) -> PathBuf {
    output.with_extension("part.exr")
}

fn merge_command(args: MergeArgs) -> Result<(), Failure> {
    use lightsplit::part;
    let start = std::time::Instant::now();
    let format = film::check_output(&args.output).map_err(Failure::input)?;
    film::check_not_an_input(&args.output, &args.parts).map_err(Failure::input)?;
    let setting = args.out.check(&Setting::default(), format)?;
    let mut named = Vec::new();
    for path in &args.parts {
        let header =
            part::read_header(path).map_err(|e| Failure::input(format!("{}: {e}", path.display())))?;
        named.push(part::Named { path: path.clone(), header });
    }
    let (count, missing) = part::check(&named, args.allow_missing).map_err(Failure::input)?;
    if missing.count > 0 {
        eprintln!("warning: {missing} of {count} missing: merging the others");
    }
    let bar = progress_bar(named.len() as u64, args.json);
    let sums = part::merge(&named, &|| bar.inc(1)).map_err(Failure::input)?;
    bar.finish_and_clear();
    let (lo, hi) =
        (sums.samples.iter().copied().min().unwrap_or(0), sums.samples.iter().copied().max().unwrap_or(0));
    let merge_seconds = start.elapsed().as_secs_f64();
    let first = &named[0].header;
    let meta = film::Metadata {
        filter: filter_label(&setting),
        spp: Some(first.spp),
        extra: Vec::new(),
        ..first.meta.clone()
    };
    let film = sums.into_means();
    if lightsplit::output::filter_reads(&setting).variance && film.variance.is_empty() {
        return Err(Failure::input("atrous reads each pixel's variance, which these parts do not hold"));
    }
    let filter_seconds = args.out.write(film, &setting, &args.output, &meta)?;
    if args.json {
        say!(
            "{}",
            serde_json::json!({
                "parts": named.len(),
                "of": count,
                "missing": missing.first,
                "missing_count": missing.count,
                "samples_per_pixel_min": lo,
                "samples_per_pixel_max": hi,
                "merge_seconds": merge_seconds,
                "filter": setting.method.as_ref().map(Method::name),
                "filter_target": setting.target.name(),
                "filter_seconds": filter_seconds,
                "seconds": start.elapsed().as_secs_f64(),
                "output": args.output.to_string_lossy(),
            })
        );
    } else {
        let got = if lo == hi { format!("{lo}") } else { format!("{lo} to {hi}") };
        eprintln!(
            "merged {} of {count} parts ({got} samples a pixel) in {merge_seconds:.2} s; wrote {}",
            named.len(),
            args.output.display()
        );
    }
    Ok(())
}

fn rayon_threads(threads: Option<usize>) -> usize {
    threads.unwrap_or_else(rayon::current_num_threads)
}

fn default_output(scene: &Path) -> PathBuf {
    let stem = scene.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "render".into());
    PathBuf::from(format!("{stem}.exr"))
}

fn bench_accel_command(args: BenchAccelArgs) -> Result<(), Failure> {
    if let Some(plot) = &args.plot {
        if film::check_output(plot).map_err(Failure::input)? != film::Format::Png {
            return Err(Failure::input(format!("--plot {}: the plot is a PNG", plot.display())));
        }
    }
    if args.embree_settings && (args.scenes.len() > 1 || args.plot.is_some()) {
        return Err(Failure::input("--embree-settings measures one scene and draws no plot"));
    }
    // Every scene loads before anything is measured, so a bad file costs no waiting.
    let mut scenes = Vec::new();
    for path in &args.scenes {
        scenes.push(load_scene(path)?.0);
    }
    let options = lightsplit::bench::BenchAccelOptions {
        rays: args.rays,
        threads: args.threads.unwrap_or_else(rayon::current_num_threads),
        min_seconds: args.seconds,
        rounds: args.rounds,
        seed: 1,
    };
    let bar = progress_bar(0, args.json);
    if args.embree_settings {
        let rows = lightsplit::bench::bench_embree_settings(&scenes[0], &options, &|done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })
        .map_err(Failure::failed)?;
        bar.finish_and_clear();
        if args.json {
            say!("{}", serde_json::json!({ "scene": args.scenes[0].to_string_lossy(), "rows": rows }));
        } else {
            say!("{}", lightsplit::bench::settings_table(&rows).trim_end_matches('\n'));
        }
        return Ok(());
    }
    let mut reports = Vec::new();
    for (i, scene) in scenes.iter().enumerate() {
        bar.set_message(format!("{} of {}", i + 1, scenes.len()));
        let report = lightsplit::bench::bench_accel(scene, &options, &|done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })
        .map_err(Failure::failed)?;
        if !args.json {
            let table = report.table();
            bar.suspend(|| print_line(format_args!("{}", table.trim_end_matches('\n'))))?;
        }
        reports.push(report);
    }
    bar.finish_and_clear();
    if let Some(plot) = &args.plot {
        lightsplit::bench::plot::scaling_plot(&reports, plot).map_err(Failure::failed)?;
    }
    if args.json {
        // One JSON object a scene, one a line.
        for report in &reports {
            let json = serde_json::to_string(report).map_err(Failure::failed)?;
            say!("{json}");
        }
    }
    Ok(())
}

fn filter_command(args: FilterCommandArgs) -> Result<(), Failure> {
    let format = film::check_output(&args.output).map_err(Failure::input)?;
    film::check_not_an_input(&args.output, std::slice::from_ref(&args.input)).map_err(Failure::input)?;
    let setting = args.out.check(&Setting::default(), format)?;
    let (width, height, channels) = film::read_exr_channels(&args.input).map_err(Failure::input)?;
    let film = film::Film::from_channels(width, height, &channels)
        .map_err(|e| Failure::input(format!("{}: {e}", args.input.display())))?;
    if lightsplit::output::filter_reads(&setting).variance && film.variance.is_empty() {
        return Err(Failure::input(format!(
            "{}: atrous reads each pixel's variance, and this file has no `*_variance` layers \
             (written before they existed): render it again",
            args.input.display()
        )));
    }
    // What the input recorded of its render, and the filter that made this file.
    let meta = film::Metadata {
        filter: filter_label(&setting),
        ..film::Metadata::of_exr(&args.input).unwrap_or_default()
    };
    let seconds = args.out.write(film, &setting, &args.output, &meta)?;
    if args.json {
        say!(
            "{}",
            serde_json::json!({
                "input": args.input.to_string_lossy(),
                "output": args.output.to_string_lossy(),
                "filter": setting.method.as_ref().map(Method::name),
                "filter_target": setting.target.name(),
                "filter_seconds": seconds,
            })
        );
    }
    Ok(())
}

fn converge_command(args: ConvergeArgs) -> Result<(), Failure> {
    use lightsplit::converge::{self, Event, Plan};
    let (scene, _) = load_scene(&args.scene)?;
    if args.diff_spp.is_some_and(|d| !args.spp.contains(&d)) {
        return Err(Failure::input("--diff-spp must be one of the --spp values"));
    }
    // Custom kernels are written with ';' between weights here, since ',' separates filters.
    let filters: Vec<String> = args.filters.iter().map(|f| f.replace(';', ",")).collect();
    let choices = converge::choices(&filters, &args.targets, &args.edge_aware).map_err(Failure::input)?;
    let mut options = RenderOptions::from_scene(&scene);
    options.accel = args.engine.accel;
    options.threads = args.engine.threads;
    options.width = args.width.unwrap_or(options.width);
    options.height = args.height.unwrap_or(options.height);
    scene::limits::check_render_memory(options.width, options.height).map_err(Failure::input)?;
    // Compared against independent sampling, the base of the comparison: it goes first.
    let mut samplers = args.sampler.clone();
    samplers.sort_by_key(|s| *s != SamplerKind::Independent);
    samplers.dedup();
    let mut spps = args.spp.clone();
    spps.sort_unstable();
    spps.dedup();
    let diff_spp = args.diff_spp.or_else(|| spps.iter().copied().min_by_key(|&s| (s as i64 - 50).abs()));
    let plan = Plan {
        scene_path: args.scene.clone(),
        options,
        spps,
        seeds: args.seeds,
        samplers,
        choices,
        reference: args.reference.clone(),
        reference_spp: args.reference_spp,
        diff_spp,
        adaptive: args.adaptive,
        out: args.out.clone(),
    };
    let bar = progress_bar(plan.total_samples(&scene), false);
    let report = |e: Event| match e {
        Event::Samples(n) => bar.inc(n),
        Event::Message(m) => bar.suspend(|| eprintln!("{m}")),
    };
    let map = |e: converge::ConvergeError| match e {
        converge::ConvergeError::Input(m) => Failure::input(m),
        converge::ConvergeError::Failed(m) => Failure::failed(m),
    };
    let measured = converge::run(&plan, &scene, &report).map_err(map)?;
    bar.finish_and_clear();
    let md = converge::report(&plan, &measured).map_err(map)?;
    say!("{}", md.trim_end_matches('\n'));
    eprintln!("wrote {}", plan.out.display());
    Ok(())
}

fn compare_command(args: CompareArgs) -> Result<(), Failure> {
    if let Some(diff) = &args.diff {
        film::check_output(diff).map_err(Failure::input)?;
        film::check_not_an_input(diff, &[args.test.clone(), args.reference.clone()])
            .map_err(Failure::input)?;
    }
    let test = film::read_image(&args.test).map_err(Failure::input)?;
    let reference = film::read_image(&args.reference).map_err(Failure::input)?;
    let errors = lightsplit::metrics::compare(&test, &reference).map_err(Failure::input)?;
    if let Some(diff) = &args.diff {
        let image = lightsplit::metrics::difference_image(&test, &reference);
        film::write(&image, diff, 0.0).map_err(Failure::failed)?;
    }
    if args.json {
        say!("{}", serde_json::to_string(&errors).map_err(Failure::failed)?);
    } else {
        say!(
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
    // Every scene is loaded before any is measured, so a bad file fails at once.
    let scenes =
        args.scenes.iter().map(|p| load_scene(p).map(|(s, f)| (p, s, f))).collect::<Result<Vec<_>, _>>()?;
    let options = features::BenchFeaturesOptions {
        width: args.width,
        height: args.height,
        spp: args.spp,
        rounds: args.rounds,
        threads: args.run.engine.threads,
        accel: args.run.engine.accel,
    };
    let bar = progress_bar(scenes.len() as u64, args.run.json);
    let mut rows = Vec::new();
    for (path, scene, filter) in &scenes {
        bar.set_message(path.display().to_string());
        rows.push(features::bench_scene(path, scene, filter, &options).map_err(Failure::failed)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    if args.run.json {
        say!("{}", serde_json::json!({ "rows": rows }));
    } else {
        say!("{}", features::table(&rows, &options).trim_end_matches('\n'));
    }
    Ok(())
}
