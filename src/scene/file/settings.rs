//! `[camera]`, `[film]` and `[render]`: the pinhole or orthographic camera, the image size and samples per pixel,
//! the path length limit and the seed. Each is one table of fixed keys.

use serde::Deserialize;
use toml::Spanned;

use glam::{DVec3, Vec3};

use super::{dv3, v3, Ctx, F, V3};
use crate::scene::{limits, Camera, FilmSettings, Lens, PixelFilter, RenderSettings, SceneError};
use crate::scene::{Guiding, LightSamplerKind, SamplerKind};

/// `[camera]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct FileCamera {
    position: V3,
    look_at: V3,
    up: Option<V3>,
    fov: Option<Spanned<F>>,
    /// An orthographic camera's view height, in scene units.
    orthographic: Option<Spanned<F>>,
    /// A thin lens: its aperture radius in scene units, or its f-number.
    aperture: Option<Spanned<F>>,
    f_number: Option<Spanned<F>>,
    /// The distance along the view that is in focus, or a point on that plane.
    focus_distance: Option<Spanned<F>>,
    focus_on: Option<Spanned<V3>>,
}

/// `[film]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct FileFilm {
    width: Option<Spanned<u32>>,
    height: Option<Spanned<u32>>,
    spp: Option<Spanned<u32>>,
    pixel_filter: Option<Spanned<String>>,
    pixel_filter_radius: Option<Spanned<f64>>,
    pixel_filter_stddev: Option<Spanned<f64>>,
}

/// `[render]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct FileRender {
    max_depth: Option<Spanned<u32>>,
    seed: Option<u64>,
    sampler: Option<Spanned<String>>,
    diffuse_roughness: Option<Spanned<F>>,
    light_sampler: Option<Spanned<String>>,
    /// true, false, or the mode's name.
    guiding: Option<Spanned<toml::Value>>,
}

/// The camera, checked: a field of view inside (0, 180) degrees and a view it can orient. With
/// it, the scene's origin: the camera's position, in f64. The scene is rendered relative to it
/// (the camera at zero), so f32 keeps its precision around the camera however far it is from
/// the world's origin.
pub(super) fn camera(ctx: &Ctx, c: &Spanned<FileCamera>) -> Result<(Camera, DVec3), SceneError> {
    let span = c.span();
    let c = c.get_ref();
    let origin = dv3(c.position);
    let position = Vec3::ZERO;
    let look_at = (dv3(c.look_at) - origin).as_vec3();
    let up = c.up.map(v3).unwrap_or(Vec3::Y);
    let fov = match &c.fov {
        Some(f) if !(f.get_ref().0 > 0.0 && f.get_ref().0 < 180.0) => {
            return ctx.err(f.span(), "`fov` must lie strictly between 0 and 180 degrees")
        }
        Some(f) => f.get_ref().0,
        None => 40.0,
    };
    let orthographic = match &c.orthographic {
        Some(h) if !(h.get_ref().0 > 0.0 && h.get_ref().0 < 1e30) => {
            return ctx.err(h.span(), "`orthographic` (the view's height) must be a positive number")
        }
        Some(h) => Some(h.get_ref().0),
        None => None,
    };
    let forward = look_at - position;
    if forward.length_squared() == 0.0 {
        return ctx.err(span, "the camera's `position` and `look_at` are the same point");
    }
    if forward.cross(up).length_squared() <= 1e-12 * forward.length_squared() * up.length_squared() {
        return ctx.err(span, "the camera's `up` is zero or parallel to its view direction");
    }
    let lens = lens(ctx, c, span, origin, forward, fov)?;
    Ok((Camera { position, look_at, up, fov, orthographic, lens }, origin))
}

/// The thin lens of `[camera]`, when it has an `aperture` (a radius) or an `f_number`: in focus
/// at `focus_distance`, or on the plane through `focus_on`, or (neither) through `look_at`.
fn lens(
    ctx: &Ctx,
    c: &FileCamera,
    span: std::ops::Range<usize>,
    origin: DVec3,
    forward: Vec3,
    fov: f32,
) -> Result<Option<Lens>, SceneError> {
    let positive = |v: &Spanned<F>, key: &str| -> Result<f64, SceneError> {
        let x = v.get_ref().0 as f64;
        if x > 0.0 && x < 1e30 {
            Ok(x)
        } else {
            ctx.err(v.span(), format!("`{key}` must be a positive number"))
        }
    };
    let radius = match (&c.aperture, &c.f_number) {
        (Some(a), Some(_)) => {
            return ctx.err(a.span(), "a camera takes `aperture` (a radius) or `f_number`, not both")
        }
        (Some(a), None) => positive(a, "aperture")?,
        (None, Some(n)) => {
            if c.orthographic.is_some() {
                return ctx.err(
                    n.span(),
                    "an orthographic camera's lens takes `aperture` (a radius), not `f_number`",
                );
            }
            Lens::radius_of_f_number(positive(n, "f_number")?, fov as f64)
        }
        (None, None) => {
            if let Some(f) = c.focus_distance.as_ref() {
                return ctx.err(f.span(), "`focus_distance` needs a lens: an `aperture` or an `f_number`");
            }
            if let Some(f) = c.focus_on.as_ref() {
                return ctx.err(f.span(), "`focus_on` needs a lens: an `aperture` or an `f_number`");
            }
            return Ok(None);
        }
    };
    let view = forward.as_dvec3().normalize();
    let focus_distance = match (&c.focus_distance, &c.focus_on) {
        (Some(f), Some(_)) => {
            return ctx.err(f.span(), "a camera takes `focus_distance` or `focus_on`, not both")
        }
        (Some(f), None) => positive(f, "focus_distance")?,
        (None, Some(p)) => {
            let d = (dv3(*p.get_ref()) - origin).dot(view);
            if d.is_nan() || d <= 0.0 {
                return ctx.err(p.span(), "`focus_on` must lie in front of the camera");
            }
            d
        }
        (None, None) => forward.as_dvec3().length(),
    };
    if !(radius.is_finite() && focus_distance.is_finite()) {
        return ctx.err(span, "the lens's aperture or focus distance is not finite");
    }
    Ok(Some(Lens { radius: radius as f32, focus_distance: focus_distance as f32 }))
}

/// The film settings, with their defaults (256 x 256, 16 samples per pixel).
pub(super) fn film(ctx: &Ctx, f: Option<&FileFilm>) -> Result<FilmSettings, SceneError> {
    let get = |v: Option<&Spanned<u32>>, name: &str, default: u32, max: u32| -> Result<u32, SceneError> {
        match v {
            Some(v) if *v.get_ref() == 0 || *v.get_ref() > max => {
                ctx.err(v.span(), format!("`{name}` must lie between 1 and {max}"))
            }
            Some(v) => Ok(*v.get_ref()),
            None => Ok(default),
        }
    };
    Ok(FilmSettings {
        width: get(f.and_then(|f| f.width.as_ref()), "width", 256, limits::MAX_SIZE)?,
        height: get(f.and_then(|f| f.height.as_ref()), "height", 256, limits::MAX_SIZE)?,
        spp: get(f.and_then(|f| f.spp.as_ref()), "spp", 16, limits::MAX_SPP)?,
        pixel_filter: match f {
            Some(f) => pixel_filter(ctx, f)?,
            None => PixelFilter::default(),
        },
        window: None,
    })
}

/// `pixel_filter` with its `pixel_filter_radius` (box, tent) or `pixel_filter_stddev`
/// (gaussian), Mitsuba's defaults: a box of radius 0.5 (each sample in its own pixel), a tent
/// of radius 1, a Gaussian of stddev 0.5.
fn pixel_filter(ctx: &Ctx, f: &FileFilm) -> Result<PixelFilter, SceneError> {
    let value = |v: &Option<Spanned<f64>>, name: &str, default: f64| -> Result<f32, SceneError> {
        match v {
            Some(v) if !(*v.get_ref() > 0.0 && *v.get_ref() <= 16.0) => {
                ctx.err(v.span(), format!("`{name}` must lie in (0, 16] pixels"))
            }
            Some(v) => Ok(*v.get_ref() as f32),
            None => Ok(default as f32),
        }
    };
    let kind = f.pixel_filter.as_ref().map(|k| (k.get_ref().as_str(), k.span()));
    let (radius, stddev) = (&f.pixel_filter_radius, &f.pixel_filter_stddev);
    let misplaced = match kind.as_ref().map(|k| k.0) {
        Some("gaussian") => radius
            .as_ref()
            .map(|r| (r.span(), "pixel_filter_radius", "a gaussian takes `pixel_filter_stddev`")),
        _ => stddev.as_ref().map(|s| (s.span(), "pixel_filter_stddev", "only a gaussian takes it")),
    };
    if let Some((span, name, why)) = misplaced {
        return ctx.err(span, format!("`{name}` does not apply here: {why}"));
    }
    Ok(match kind {
        None | Some(("box", _)) => PixelFilter::Box { radius: value(radius, "pixel_filter_radius", 0.5)? },
        Some(("tent", _)) => PixelFilter::Tent { radius: value(radius, "pixel_filter_radius", 1.0)? },
        Some(("gaussian", _)) => PixelFilter::Gaussian { stddev: value(stddev, "pixel_filter_stddev", 0.5)? },
        Some((other, span)) => {
            return ctx.err(span, format!("unknown pixel_filter `{other}`: use box, tent or gaussian"))
        }
    })
}

/// The render settings, with their defaults (8 bounces, seed 0, the Sobol sampler).
pub(super) fn render(ctx: &Ctx, r: Option<&FileRender>) -> Result<RenderSettings, SceneError> {
    Ok(RenderSettings {
        max_depth: match r.and_then(|r| r.max_depth.as_ref()) {
            Some(d) if !(1..=limits::MAX_DEPTH).contains(d.get_ref()) => {
                return ctx.err(d.span(), format!("`max_depth` must lie between 1 and {}", limits::MAX_DEPTH))
            }
            Some(d) => *d.get_ref(),
            None => 8,
        },
        seed: r.and_then(|r| r.seed).unwrap_or(0),
        sampler: named(
            ctx,
            r.and_then(|r| r.sampler.as_ref()),
            SamplerKind::parse,
            "sampler",
            "independent or sobol",
        )?,
        light_sampler: named(
            ctx,
            r.and_then(|r| r.light_sampler.as_ref()),
            LightSamplerKind::parse,
            "light sampler",
            "tree, power or uniform",
        )?,
        guiding: match r.and_then(|r| r.guiding.as_ref()) {
            Some(g) => {
                let parsed = match g.get_ref() {
                    toml::Value::Boolean(true) => Some(Guiding::ON),
                    toml::Value::Boolean(false) => Some(Guiding::Off),
                    toml::Value::String(name) => Guiding::parse(name),
                    _ => None,
                };
                match parsed {
                    Some(g) => g,
                    None => return ctx.err(g.span(), "`guiding` is true, false, \"indirect\" or \"all\""),
                }
            }
            None => Guiding::default(),
        },
    })
}

/// A key whose value is one of a fixed set of names, read by `parse`: its default when absent;
/// an unknown name is an error at its place naming `what` and the `choices`.
fn named<T: Default>(
    ctx: &Ctx,
    value: Option<&Spanned<String>>,
    parse: impl Fn(&str) -> Option<T>,
    what: &str,
    choices: &str,
) -> Result<T, SceneError> {
    match value {
        None => Ok(T::default()),
        Some(s) => match parse(s.get_ref()) {
            Some(kind) => Ok(kind),
            None => ctx.err(s.span(), format!("unknown {what} `{}`: use {choices}", s.get_ref())),
        },
    }
}

/// `diffuse_roughness`: the roughness from which a metallic-roughness material's GGX lobe is a D
/// vertex in the split, in [0, 1] (above 1: never).
pub(super) fn diffuse_roughness(ctx: &Ctx, r: Option<&FileRender>) -> Result<f32, SceneError> {
    match r.and_then(|r| r.diffuse_roughness.as_ref()) {
        Some(d) if d.get_ref().0 < 0.0 => ctx.err(d.span(), "`diffuse_roughness` must not be negative"),
        Some(d) => Ok(d.get_ref().0),
        None => Ok(crate::scene::DIFFUSE_ROUGHNESS),
    }
}

#[cfg(test)]
mod tests {
    use crate::scene::file::tests::{error_line, parse_str, MINIMAL};
    use crate::scene::{LightSamplerKind, SamplerKind};

    #[test]
    fn minimal_scene_has_defaults() {
        let s = parse_str(MINIMAL).expect("parses");
        assert_eq!((s.film.width, s.film.height, s.film.spp), (256, 256, 16));
        assert_eq!(s.render.max_depth, 8);
        assert_eq!(s.camera.fov, 40.0);
        assert_eq!(s.render.sampler, SamplerKind::Sobol);
    }

    #[test]
    fn the_light_sampler_is_read_and_an_unknown_one_names_its_line() {
        let s = parse_str(MINIMAL).expect("parses");
        assert_eq!(s.render.light_sampler, LightSamplerKind::Tree);
        let s = parse_str(&format!("{MINIMAL}[render]\nlight_sampler = \"power\"\n")).expect("parses");
        assert_eq!(s.render.light_sampler, LightSamplerKind::Power);
        let (line, msg) = error_line(&format!("{MINIMAL}[render]\nseed = 3\nlight_sampler = \"bvh\"\n"));
        assert_eq!(line, Some(6), "{msg}");
        assert!(msg.contains("unknown light sampler `bvh`") && msg.contains("tree"), "{msg}");
    }

    #[test]
    fn the_sampler_is_read_and_an_unknown_one_names_its_line() {
        let s = parse_str(&format!("{MINIMAL}[render]\nsampler = \"independent\"\n")).expect("parses");
        assert_eq!(s.render.sampler, SamplerKind::Independent);
        let (line, msg) = error_line(&format!("{MINIMAL}[render]\nseed = 3\nsampler = \"halton\"\n"));
        assert_eq!(line, Some(6), "{msg}");
        assert!(msg.contains("halton") && msg.contains("sobol"), "{msg}");
    }

    #[test]
    fn unknown_key_names_its_line() {
        let (line, msg) = error_line(&format!("{MINIMAL}[film]\nwidth = 64\nhieght = 64\n"));
        assert_eq!(line, Some(6), "{msg}");
        assert!(msg.contains("hieght"), "{msg}");
    }
}
