//! `lightsplit merge`: part files checked, added up, filtered once and written.

use lightsplit::filter::{Method, Setting};
use lightsplit::job::filter_label;
use lightsplit::{film, part};

use crate::cli::MergeArgs;
use crate::{progress_bar, Failure};

pub fn merge_command(args: MergeArgs) -> Result<(), Failure> {
    let start = std::time::Instant::now();
    let format = film::check_output(&args.output)?;
    film::check_not_an_input(&args.output, &args.parts)?;
    let setting = args.out.check(&Setting::default(), format)?;
    let named = args.parts.iter().map(|p| part::Named::read(p)).collect::<Result<Vec<_>, _>>()?;
    let (count, missing) = part::check(&named, args.allow_missing)?;
    if missing.count > 0 {
        eprintln!("warning: {missing} of {count} missing: merging the others");
    }
    let bar = progress_bar(named.len() as u64, args.json);
    let sums = part::merge(&named, &|| bar.inc(1))?;
    bar.finish_and_clear();
    let (lo, hi) = sums.spp_range();
    let merge_seconds = start.elapsed().as_secs_f64();
    let first = &named[0].header;
    let meta = film::Metadata {
        filter: filter_label(&setting),
        spp: Some(first.spp),
        extra: film::aov_attributes(&first.meta).collect(),
        ..first.meta.clone()
    };
    let film = sums.into_means();
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
