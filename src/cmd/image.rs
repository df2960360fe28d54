//! `lightsplit filter` and `lightsplit compare`: the commands that read images and do not render.

use lightsplit::filter::{Method, Setting};
use lightsplit::job::filter_label;
use lightsplit::{film, metrics};

use crate::cli::{CompareArgs, FilterCommandArgs};
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

pub fn compare_command(args: CompareArgs) -> Result<(), Failure> {
    if let Some(diff) = &args.diff {
        film::check_output(diff)?;
        film::check_not_an_input(diff, &[args.test.clone(), args.reference.clone()])?;
    }
    let test = film::read_image(&args.test)?;
    let reference = film::read_image(&args.reference)?;
    let errors = metrics::compare(&test, &reference)?;
    if let Some(diff) = &args.diff {
        let image = metrics::difference_image(&test, &reference);
        film::write(&image, diff, 0.0)?;
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
