//! The measuring commands: `bench-accel`, `bench-features`, `stress` and `converge`.

use lightsplit::render::sampler::SamplerKind;
use lightsplit::render::RenderOptions;
use lightsplit::{film, scene};

use crate::cli::{BenchAccelArgs, BenchFeaturesArgs, ConvergeArgs, StressArgs};
use crate::{load_scene, progress_bar, Failure};

pub fn bench_accel_command(args: BenchAccelArgs) -> Result<(), Failure> {
    if let Some(plot) = &args.plot {
        if film::check_output(plot)? != film::Format::Png {
            return Err(Failure::input(format!("--plot {}: the plot is a PNG", plot.display())));
        }
    }
    if args.embree_settings && (args.scenes.len() > 1 || args.plot.is_some()) {
        return Err(Failure::input("--embree-settings measures one scene and draws no plot"));
    }
    let bvh_isa = match args.isa.as_deref() {
        None => None,
        Some(name) => Some(lightsplit::accel::bvh::simd::Isa::named(name).ok_or_else(|| {
            Failure::input(format!(
                "--isa {name}: this CPU does not run it (the BVH's kernels are avx512, avx2 and portable)"
            ))
        })?),
    };
    // Every scene loads before anything is measured, so a bad file costs no waiting.
    let mut scenes = Vec::new();
    for path in &args.scenes {
        scenes.push(load_scene(path, &crate::cli::Defines::default())?.0);
    }
    let options = lightsplit::bench::BenchAccelOptions {
        rays: args.rays,
        threads: args.threads.unwrap_or_else(rayon::current_num_threads),
        min_seconds: args.seconds,
        rounds: args.rounds,
        seed: 1,
        bvh_isa,
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
            bar.suspend(|| crate::print_line(format_args!("{}", table.trim_end_matches('\n'))))?;
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

pub fn bench_features_command(args: BenchFeaturesArgs) -> Result<(), Failure> {
    use lightsplit::bench::features;
    // Every scene is loaded before any is measured, so a bad file fails at once.
    let scenes = args
        .scenes
        .iter()
        .map(|p| load_scene(p, &args.defines).map(|(s, f)| (p, s, f)))
        .collect::<Result<Vec<_>, _>>()?;
    let options = features::BenchFeaturesOptions {
        width: args.width,
        height: args.height,
        spp: args.spp,
        rounds: args.rounds,
        threads: args.run.engine.threads,
        accel: args.run.engine.accel,
        aovs: args.aovs.clone(),
        light_groups: args.light_groups,
        cryptomatte: args.cryptomatte,
    };
    if let Some((path, ..)) =
        scenes.iter().find(|(_, s, _)| args.light_groups && s.light_groups.names.is_empty())
    {
        return Err(Failure::input(format!(
            "{}: --light-groups: the scene has no light groups",
            path.display()
        )));
    }
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

pub fn stress_command(args: StressArgs) -> Result<(), Failure> {
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
        rows.push(stress::run_row(name, engine.accel, engine.threads)?);
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

pub fn converge_command(args: ConvergeArgs) -> Result<(), Failure> {
    use lightsplit::converge::{self, Event, Plan};
    let (scene, _) = load_scene(&args.scene, &args.defines)?;
    if args.diff_spp.is_some_and(|d| !args.spp.contains(&d)) {
        return Err(Failure::input("--diff-spp must be one of the --spp values"));
    }
    // Custom kernels are written with ';' between weights here, since ',' separates filters.
    let filters: Vec<String> = args.filters.iter().map(|f| f.replace(';', ",")).collect();
    let choices = converge::choices(&filters, &args.targets, &args.edge_aware)?;
    let mut options = RenderOptions::from_scene(&scene);
    options.accel = args.engine.accel;
    options.threads = args.engine.threads;
    options.width = args.width.unwrap_or(options.width);
    options.height = args.height.unwrap_or(options.height);
    scene::limits::check_render_memory(
        options.width,
        options.height,
        lightsplit::render::layer_bytes(&options),
    )?;
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
