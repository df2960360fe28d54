//! What an output needs and how it is written: the layer a PNG or HDR shows, the buffers
//! (component split, guides) that the output and its filter read, so a render fills only those,
//! and the filtered film written to its file.

use std::borrow::Cow;
use std::path::Path;
use std::time::Instant;

use crate::component::Component;
use crate::film::{self, Film, Format, Image};
use crate::filter::{composite, EdgeStops, Pixels, Reads, Setting, Target};
use crate::render::Outputs;

/// A layer of a render, as a single-image output (PNG, HDR) shows it; an EXR holds them all.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Layer {
    /// The final image (filtered when a filter is on; the default).
    #[default]
    Final,
    /// The unfiltered beauty.
    Raw,
    /// One light-path component, unfiltered.
    Component(Component),
    /// The filtered indirect component (needs a filter on `indirect`).
    IndirectFiltered,
    /// The albedo guide buffer.
    Albedo,
}

/// An output that cannot be written as asked.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// A layer other than the final image was asked of an EXR.
    #[error("--layer picks the layer of a PNG or HDR output; an EXR holds every layer")]
    LayerOfExr,
    /// The filtered indirect layer was asked without a filter on indirect.
    #[error("--layer indirect-filtered needs a filter on indirect")]
    NoFilteredIndirect,
    /// The filtered image overflows 32-bit floats: values so large that their weighted sums,
    /// or the components added up, are beyond the largest float.
    #[error("{0} pixels of the filtered image overflow 32-bit floats: the image holds values too large to filter and add up")]
    Overflow(usize),
    /// The filter reads each pixel's variance, and the film has none (a file written before
    /// the variance layers existed).
    #[error("{0} reads each pixel's variance, and this input has no `*_variance` layers (written before they existed): render it again")]
    NoVariance(String),
    /// The filter's target is an AOV the film does not have.
    #[error("--filter-target {0}: there is no AOV of that name (the AOVs: {1})")]
    NoAov(String, String),
    /// The file could not be written.
    #[error(transparent)]
    Write(#[from] film::WriteError),
}

/// Refuses a filter on an AOV that `aovs` (the names of a render's) does not hold.
pub fn check_aov_target(setting: &Setting, aovs: &[&str]) -> Result<(), OutputError> {
    match setting.target {
        Target::Aov(name) if setting.method.is_some() && !aovs.contains(&name.as_str()) => {
            let have = if aovs.is_empty() { "none".to_string() } else { aovs.join(", ") };
            Err(OutputError::NoAov(name.as_str().to_string(), have))
        }
        _ => Ok(()),
    }
}

impl crate::error::Classify for OutputError {
    /// Whether the request itself was bad (rather than the writing).
    fn is_input(&self) -> bool {
        match self {
            OutputError::Write(e) => e.is_input(),
            _ => true,
        }
    }
}

/// The command line's spellings of the layers, from their names: the component layers are
/// spelled as the components are named.
#[cfg(feature = "cli")]
impl clap::ValueEnum for Layer {
    fn value_variants<'a>() -> &'a [Self] {
        use Component::*;
        &[
            Layer::Final,
            Layer::Raw,
            Layer::Component(Emitted),
            Layer::Component(Direct),
            Layer::Component(Caustic),
            Layer::Component(Indirect),
            Layer::IndirectFiltered,
            Layer::Albedo,
        ]
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        use clap::builder::PossibleValue;
        Some(match self {
            Layer::Final => {
                PossibleValue::new("final").help("The final image (filtered when a filter is on)")
            }
            Layer::Raw => PossibleValue::new("raw").help("The unfiltered beauty"),
            Layer::Component(c) => PossibleValue::new(c.name()),
            Layer::IndirectFiltered => PossibleValue::new("indirect-filtered")
                .help("The filtered indirect component (needs a filter on `indirect`)"),
            Layer::Albedo => PossibleValue::new("albedo"),
        })
    }
}

/// Whether `setting` filters `indirect`, and so makes the filtered indirect layer.
fn filters_indirect(setting: &Setting) -> bool {
    setting.method.is_some() && matches!(setting.target, Target::Indirect | Target::Components)
}

/// What `setting`'s filter reads besides the image (nothing when it filters nothing).
pub fn filter_reads(setting: &Setting) -> Reads {
    match &setting.method {
        Some(method) if setting.target != Target::None => method.reads(&setting.stops),
        _ => Reads::default(),
    }
}

/// `exposure` applies to PNG only: EXR, HDR and PFM keep the linear values.
pub fn exposure_warning(exposure: f32, format: Format) -> Option<String> {
    (exposure != 0.0 && format != Format::Png).then(|| {
        format!(
            "--exposure {exposure} is ignored: it applies to PNG output only, and {} keeps linear values",
            format!("{format:?}").to_uppercase()
        )
    })
}

impl Layer {
    /// Checks before any work that this layer can be written as `format` with `setting`.
    pub fn check(self, format: Format, setting: &Setting) -> Result<(), OutputError> {
        if self != Layer::Final && format == Format::Exr {
            return Err(OutputError::LayerOfExr);
        }
        if self == Layer::IndirectFiltered && !filters_indirect(setting) {
            return Err(OutputError::NoFilteredIndirect);
        }
        Ok(())
    }

    /// The buffers besides the beauty that an output of this layer as `format`, filtered with
    /// `setting`, reads: an EXR keeps every layer; a PNG or HDR its one layer (a component layer
    /// needs the split, the albedo layer the guides) and what the filter reads to make it.
    pub fn reads(self, format: Format, setting: &Setting) -> Outputs {
        let exr = format == Format::Exr;
        let component = matches!(self, Layer::Component(_) | Layer::IndirectFiltered);
        Outputs {
            split: exr || filters_indirect(setting) || component || filter_reads(setting).variance,
            guides: exr
                || setting.stops != EdgeStops::default()
                || self == Layer::Albedo
                || filter_reads(setting).guides,
        }
    }

    /// This layer of `film`, given its final image and filtered indirect component.
    fn image<'a>(
        self,
        film: &'a Film,
        final_image: &'a Image,
        filtered: Option<&Pixels>,
    ) -> Result<Cow<'a, Image>, OutputError> {
        Ok(Cow::Borrowed(match self {
            Layer::Final => final_image,
            Layer::Raw => &film.raw,
            Layer::Component(c) => &film.components[c],
            Layer::IndirectFiltered => {
                let filtered = filtered.ok_or(OutputError::NoFilteredIndirect)?;
                return Ok(Cow::Owned(filtered.to_image(film.width, film.height)));
            }
            Layer::Albedo => &film.albedo,
        }))
    }
}

/// Filters `film` as `setting` says and writes it to `path`: every layer to an EXR, or `layer`
/// alone to a PNG or HDR at `exposure` stops. Returns the seconds the filter took.
pub fn write(
    film: Film,
    setting: &Setting,
    path: &Path,
    layer: Layer,
    exposure: f32,
    meta: &film::Metadata,
) -> Result<f64, OutputError> {
    if let (Some(method), true) =
        (&setting.method, filter_reads(setting).variance && film.variance.is_empty())
    {
        return Err(OutputError::NoVariance(method.name()));
    }
    check_aov_target(setting, &film.aovs.iter().map(|a| a.name.as_str()).collect::<Vec<_>>())?;
    let start = Instant::now();
    let (final_image, filtered) = composite(&film, setting.method.as_ref(), setting.target, &setting.stops);
    let seconds = start.elapsed().as_secs_f64();
    // Finite values whose sums overflow: an error, never an image of infinities.
    let overflowing = |pixels: &[glam::Vec3]| pixels.iter().filter(|p| !p.is_finite()).count();
    let bad = overflowing(&final_image.pixels) + filtered.as_ref().map_or(0, |f| overflowing(f));
    if bad > 0 {
        return Err(OutputError::Overflow(bad));
    }
    if layer == Layer::Final {
        // An EXR keeps the beauty twice (the final image and `raw`); a PNG or HDR only reads it.
        match film::Format::from_path(path)? {
            film::Format::Exr => {
                let final_image = final_image.into_owned();
                let filtered = filtered.map(|f| f.to_image(film.width, film.height));
                film::write_film(film, final_image, filtered, path, exposure, meta)?
            }
            _ => film::write_with(&final_image, path, exposure, meta)?,
        }
    } else {
        film::write_with(&*layer.image(&film, &final_image, filtered.as_ref())?, path, exposure, meta)?;
    }
    Ok(seconds)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Classify;
    use crate::filter::Method;

    fn indirect_filter() -> Setting {
        Setting { method: Method::parse("box3").ok(), target: Target::Indirect, stops: EdgeStops::default() }
    }

    #[test]
    fn an_exr_reads_everything_and_a_png_only_its_layer_and_filter() {
        let none = Setting::default();
        assert_eq!(Layer::Final.reads(Format::Exr, &none), Outputs::ALL);
        assert_eq!(Layer::Final.reads(Format::Png, &none), Outputs { split: false, guides: false });
        assert_eq!(Layer::Raw.reads(Format::Hdr, &none), Outputs { split: false, guides: false });
        let direct = Layer::Component(Component::Direct);
        assert_eq!(direct.reads(Format::Png, &none), Outputs { split: true, guides: false });
        assert_eq!(Layer::Albedo.reads(Format::Png, &none), Outputs { split: false, guides: true });
        assert_eq!(
            Layer::Final.reads(Format::Png, &indirect_filter()),
            Outputs { split: true, guides: false }
        );
        let image = Setting { target: Target::Image, ..indirect_filter() };
        assert_eq!(Layer::Final.reads(Format::Png, &image), Outputs { split: false, guides: false });
        let edges = Setting { stops: EdgeStops { object: true, ..EdgeStops::default() }, ..image };
        assert_eq!(Layer::Final.reads(Format::Png, &edges), Outputs { split: false, guides: true });
    }

    #[test]
    fn layers_are_checked_against_the_format_and_the_filter() {
        let none = Setting::default();
        assert!(Layer::Final.check(Format::Exr, &none).is_ok());
        assert!(matches!(Layer::Raw.check(Format::Exr, &none), Err(OutputError::LayerOfExr)));
        assert!(matches!(
            Layer::IndirectFiltered.check(Format::Png, &none),
            Err(OutputError::NoFilteredIndirect)
        ));
        assert!(Layer::IndirectFiltered.check(Format::Png, &indirect_filter()).is_ok());
        assert!(OutputError::LayerOfExr.is_input());
    }
}
