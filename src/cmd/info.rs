//! `lightsplit info`: what a scene uses, and what a render of it with the outputs asked for computes.

use lightsplit::render::{Features, Outputs};
use lightsplit::{film, scene};

use crate::cli::InfoArgs;
use crate::{default_output, load_scene, Failure};

pub fn info_command(args: InfoArgs) -> Result<(), Failure> {
    let (scene, scene_filter) = load_scene(&args.scene, &args.defines)?;
    let output = args.output.clone().unwrap_or_else(|| default_output(&args.scene));
    let format = film::check_output(&output)?;
    let setting = args.out.check(&scene_filter, format)?;
    let analysis = scene::analysis::Analysis::of(&scene);
    say!("{}", args.scene.display());
    let film = &scene.film;
    let crop = film.window.map_or(String::new(), |w| {
        format!(", the window at ({}, {}) of a {}x{} film", w.x, w.y, w.film_width, w.film_height)
    });
    say!(
        "film: {}x{} at {} spp, pixel filter {}{crop}",
        film.width,
        film.height,
        film.spp,
        film.pixel_filter.describe()
    );
    say!("{}", analysis.to_string().trim_end_matches('\n'));
    let lights = lightsplit::render::lights::Lights::new(&scene, scene.render.light_sampler);
    say!("next-event estimation: {}", lights.describe());
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
