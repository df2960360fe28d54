//! `lightsplit render`: the arguments as a [`Request`], the job run with a progress bar and
//! graceful stops, and its summary printed. The rules are the library's ([`lightsplit::job`]).

use std::sync::atomic::Ordering;

use lightsplit::job::{Job, Request};
use lightsplit::{film, output, scene};

use crate::cli::RenderArgs;
use crate::{default_output, load_scene_with, progress_bar, Failure, GRACEFUL, STOP, STOPPED_BY};

pub fn render_command(args: RenderArgs) -> Result<(), Failure> {
    let (mut scene, scene_filter) = load_scene_with(
        &args.scene,
        &scene::LoadOptions { camera: args.camera.clone(), defines: args.defines.define.clone() },
    )?;
    if let Some(environment) = &args.environment {
        scene.set_environment(environment)?;
    }
    if let Some(warning) = lightsplit::scene::analysis::no_light_warning(&scene) {
        eprintln!("warning: {}: {warning}", args.scene.display());
    }
    let request = Request {
        output: args.output.clone().unwrap_or_else(|| default_output(&args.scene)),
        width: args.width,
        height: args.height,
        spp: args.spp,
        seed: args.seed,
        max_depth: args.max_depth,
        sampler: args.sampler,
        light_sampler: args.light_sampler,
        guiding: args.guiding,
        guide: args.guide.clone(),
        aovs: args.aovs.clone(),
        light_groups: args.light_groups,
        cryptomatte: args.cryptomatte,
        accel: args.run.engine.accel,
        threads: args.run.engine.threads,
        debug_nonfinite: args.debug_nonfinite,
        point_textures: args.point_textures,
        adaptive: args.adaptive,
        all_features: args.all_features,
        part: args.part.clone(),
        checkpoint: args.checkpoint,
        time_limit: args.time_limit,
        resume: args.resume.clone(),
        filter: args.out.filter.overrides(),
        layer: args.out.layer,
        exposure: args.out.exposure,
    };
    // Said before the job's checks, as a warning is (the output's name is checked first).
    if let Ok(format) = film::Format::from_path(&request.output) {
        if let Some(warning) = output::exposure_warning(request.exposure, format) {
            eprintln!("warning: {warning}");
        }
    }
    let mut job = Job::new(&scene, &scene_filter, request, |name| std::env::var_os(name))?;
    let bar = progress_bar(job.total_samples(), args.run.json);
    bar.inc(job.resumed_samples());
    // A signal while rendering stops the render after its pass, and what it has is written; a
    // signal while writing ends the process, leaving the output as it was.
    GRACEFUL.store(true, Ordering::SeqCst);
    let rendered = job.render(&|n| bar.inc(n), &STOP);
    GRACEFUL.store(false, Ordering::SeqCst);
    let rendered = rendered?;
    bar.finish_and_clear();
    let done = job.write(rendered)?;

    let (options, s) = (&job.options, &done.stats);
    if args.run.json {
        say!("{}", job.summary(&done, &args.scene));
    } else {
        let per_second = |n: u64| n as f64 / s.seconds.max(1e-9) / 1e6;
        let mean_spp = s.samples as f64 / (options.width as f64 * options.height as f64);
        let spp = match options.adaptive {
            Some(t) => format!(
                "up to {} spp (adaptive {t}: {mean_spp:.1} spp a pixel, {} pixels stopped early)",
                options.spp, s.stopped_early
            ),
            None => format!("{} spp", options.spp),
        };
        let range = job.samples();
        let spp = if job.is_part() {
            format!("part {} of {spp}: samples {}..{}", options.part, range.start, range.end)
        } else {
            spp
        };
        let dropped = if s.nonfinite_samples > 0 {
            format!(", {} non-finite samples dropped", s.nonfinite_samples)
        } else {
            String::new()
        };
        eprintln!(
            "{}: {}x{} at {spp} ({}) in {:.2} s ({:.3} s build): {:.3} M samples/s, {:.2} M rays/s{dropped}; wrote {}",
            args.scene.display(),
            options.width,
            options.height,
            options.sampler,
            s.seconds,
            s.build_seconds,
            per_second(s.samples),
            per_second(s.rays),
            job.output.display()
        );
    }
    if s.interrupted {
        let (lo, hi) = (s.min_spp, s.max_spp);
        let got = if lo == hi { format!("{lo}") } else { format!("{lo} to {hi}") };
        let why = match STOPPED_BY.load(Ordering::SeqCst) {
            0 => "the time limit".to_string(),
            sig => format!("signal {sig}"),
        };
        let range = job.samples();
        eprintln!(
            "stopped by {why}: each pixel has {got} of its {} samples; the part file {} holds them (--resume it to go on)",
            range.end - range.start,
            job.part_path.display()
        );
    }
    match STOPPED_BY.load(Ordering::SeqCst) {
        0 => Ok(()),
        sig => Err(Failure { code: (128 + sig).clamp(0, 255) as u8, message: String::new() }),
    }
}
