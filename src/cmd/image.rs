//! `lightsplit filter` and `lightsplit compare`: the commands that read images and do not render.

use lightsplit::filter::{Method, Setting};
use lightsplit::job::filter_label;
use lightsplit::metrics::regions::{by_region, Region};
use lightsplit::output::OutputError;
use lightsplit::{film, metrics};

use crate::cli::{CompareArgs, FilterCommandArgs, MatteArgs};
use crate::Failure;

pub fn filter_command(args: FilterCommandArgs) -> Result<(), Failure> {
    let format = film::check_output(&args.output)?;
    film::check_not_an_input(&args.output, std::slice::from_ref(&args.input))?;
    let setting = args.out.check(&Setting::default(), format)?;
    let film = film::read_film(&args.input)?;
    // What the input recorded of its render, and the filter that made this file.
    let meta = film::Metadata {
        filter: filter_label(&setting),
        ..film::Metadata::of_exr(&args.input).unwrap_or_default()
    };
    let seconds = args.out.write(film, &setting, &args.output, &meta).map_err(|e| match e {
        // Which file lacks them.
        OutputError::NoVariance(_) => Failure::input(format!("{}: {e}", args.input.display())),
        e => e.into(),
    })?;
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

pub fn compare_command(args: CompareArgs) -> Result<(), Failure> {
    if let Some(diff) = &args.diff {
        film::check_output(diff)?;
        let inputs: Vec<_> = [&args.test, &args.reference].into_iter().chain(&args.ids).cloned().collect();
        film::check_not_an_input(diff, &inputs)?;
    }
    let regions = args.regions.iter().map(|r| Region::parse(r)).collect::<Result<Vec<_>, _>>()?;
    let test = film::read_layer(&args.test, &args.layer)?;
    let reference = film::read_layer(&args.reference, &args.layer)?;
    let errors = metrics::compare(&test, &reference)?;
    let by_region = if args.by_object || !regions.is_empty() {
        let (width, height, ids) = film::read_object_ids(args.ids.as_ref().unwrap_or(&args.test))?;
        if (width, height) != (test.width, test.height) {
            return Err(Failure::input(format!(
                "the object IDs are {width}x{height} and the images {}x{}: not the same render",
                test.width, test.height
            )));
        }
        let mut all = if args.by_object { Region::each_object(&ids) } else { Vec::new() };
        all.extend(regions);
        Some(by_region(&test, &reference, &ids, &all)?)
    } else {
        None
    };
    if let Some(diff) = &args.diff {
        let image = metrics::difference_image(&test, &reference);
        film::write(&image, diff, 0.0)?;
    }
    let agreement = args.blocks.map(|n| metrics::agreement(&test, &reference, n));
    if args.json {
        /// The whole image's errors, in their order, then the regions'.
        #[derive(serde::Serialize)]
        struct WithRegions<'a> {
            #[serde(flatten)]
            errors: &'a metrics::Errors,
            #[serde(skip_serializing_if = "Option::is_none")]
            regions: Option<&'a [metrics::regions::RegionErrors]>,
            #[serde(skip_serializing_if = "Option::is_none")]
            agreement: Option<&'a metrics::Agreement>,
        }
        let json =
            WithRegions { errors: &errors, regions: by_region.as_deref(), agreement: agreement.as_ref() };
        say!("{}", serde_json::to_string(&json).map_err(Failure::failed)?);
        return Ok(());
    }
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
    if let Some(a) = &agreement {
        let rgb = |v: [f64; 3]| format!("{:.6} {:.6} {:.6}", v[0], v[1], v[2]);
        say!(
            "means: {} against {} (largest difference {:.3}%); worst {n}x{n} block at ({}, {}): {:.3}%",
            rgb(a.test_means),
            rgb(a.reference_means),
            100.0 * a.means_difference,
            a.worst_block_at.0,
            a.worst_block_at.1,
            100.0 * a.worst_block_difference,
            n = a.block
        );
    }
    if let Some(rows) = by_region {
        let width = rows.iter().map(|r| r.name.len()).max().unwrap_or(0).max(6);
        say!(
            "{:width$}  {:>7}  {:>7}  {:>10}  {:>10}  {:>7}  {:>6}",
            "region",
            "pixels",
            "inner",
            "rmse",
            "relmse",
            "ratio",
            "detail"
        );
        let or_dash = |v: Option<f64>, digits: usize| v.map_or("-".to_string(), |v| format!("{v:.digits$}"));
        for r in rows {
            say!(
                "{:width$}  {:>7}  {:>7}  {:>10.3e}  {:>10.3e}  {:>7}  {:>6}",
                r.name,
                r.pixels,
                r.inner,
                r.rmse,
                r.relmse,
                or_dash(r.ratio, 3),
                or_dash(r.detail, 2)
            );
        }
    }
    Ok(())
}

/// `lightsplit matte`: the summed coverage of the names asked for, from the ranks of one
/// Cryptomatte type of an EXR, as a compositor's Cryptomatte node reads them.
pub fn matte_command(args: MatteArgs) -> Result<(), Failure> {
    use lightsplit::film::cryptomatte::{self, Matte};
    film::check_output(&args.output)?;
    film::check_not_an_input(&args.output, std::slice::from_ref(&args.input))?;
    let at = |e: String| Failure::input(format!("{}: {e}", args.input.display()));
    let (width, height, channels) = film::read_exr_channels(&args.input).map_err(at)?;
    let meta = film::Metadata::of_exr(&args.input).map_err(at)?;
    let mattes = Matte::read_all(&meta.extra, &channels, width as usize * height as usize).map_err(at)?;
    let kinds: Vec<&str> = mattes.iter().map(|m| m.kind.as_str()).collect();
    let Some(matte) = mattes.iter().find(|m| m.kind == args.kind) else {
        return Err(at(match kinds.is_empty() {
            true => "no Cryptomatte layers (`cryptomatte/…/name` header attributes)".into(),
            false => format!("no Cryptomatte type `{}`; it has {}", args.kind, kinds.join(", ")),
        }));
    };
    // A manifest lists the names; one the file does not list is a typing error, not an empty
    // matte. (An empty manifest, `{}`, lists nothing to check against.)
    let manifest: serde_json::Map<String, serde_json::Value> = serde_json::from_str(&matte.manifest)
        .map_err(|e| at(format!("the `{}` manifest is not a JSON object: {e}", matte.kind)))?;
    if let Some(name) = args.names.iter().find(|n| !manifest.is_empty() && !manifest.contains_key(n.as_str()))
    {
        let mut known: Vec<&str> = manifest.keys().map(String::as_str).collect();
        known.truncate(20);
        return Err(at(format!(
            "`{name}` is not in the `{}` manifest ({}, ...)",
            matte.kind,
            known.join(", ")
        )));
    }
    let ids: Vec<u32> = args.names.iter().map(|n| cryptomatte::name_id(n)).collect();
    let values = matte.matte(&ids);
    let image = film::Image { width, height, pixels: values.iter().map(|&v| glam::Vec3::splat(v)).collect() };
    film::write(&image, &args.output, 0.0)?;
    let covered = values.iter().filter(|&&v| v > 0.0).count();
    let mean = values.iter().map(|&v| v as f64).sum::<f64>() / values.len().max(1) as f64;
    if args.json {
        say!(
            "{}",
            serde_json::json!({
                "input": args.input.to_string_lossy(),
                "output": args.output.to_string_lossy(),
                "type": matte.kind,
                "names": args.names,
                "pixels_covered": covered,
                "mean_coverage": mean,
                "width": width,
                "height": height,
            })
        );
    } else {
        eprintln!(
            "{} of {}: {covered} pixels covered, mean coverage {mean:.4}; wrote {}",
            args.names.join(", "),
            matte.kind,
            args.output.display()
        );
    }
    Ok(())
}
