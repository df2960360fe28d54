//! The film's layers, in one table: each buffer's EXR channels, which buffers it belongs with
//! (the beauty, the component split, the guides, the variances), how a render's sums of it
//! become the film's values, how parts add up, and what a part file's sums of it may hold.
//! Writing a film, reading one back, writing and reading part files, merging parts, the means
//! at the end of a render, the finite check and the buffer sizes all read [`LAYERS`].
//!
//! A new layer is a row here, its buffer in [`Film`] ([`Film::values`]) and, where the render
//! fills it, its sum in the integrator's sample (`render::integrator::PathSample`) and the tile
//! sums (`render::TileSums`): those stay typed fields, as the per-sample loop is the hot path.

use super::Film;
use crate::component::Component;

/// A buffer of the film.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Buffer {
    /// The unfiltered beauty.
    Raw,
    /// A light-path component.
    Component(Component),
    Albedo,
    /// Unit shading normals.
    Normal,
    Depth,
    /// The object of each pixel's sample 0 (-1 none).
    Object,
    /// The fraction of the samples that saw that object.
    Coverage,
    /// The fraction of the samples that hit a surface.
    Alpha,
    /// The variance of the pixel's mean luminance, of the beauty.
    Variance,
    /// The same for a component.
    ComponentVariance(Component),
    /// The beauty's share from one half of each pixel's samples (its sum over the samples of
    /// the second half, divided by all the samples): with [`Buffer::HalfShare`], the two halves'
    /// means, whose difference measures the noise of a Sobol render ([`super::halves`]).
    Half,
    /// The same for a component.
    ComponentHalf(Component),
    /// The share of each pixel's samples in its second half.
    HalfShare,
}

/// Which buffers a buffer is kept with: a render computes the split and the guides only when
/// an output reads them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Group {
    Beauty,
    Split,
    Guides,
    /// Made from the sums of squares at the end of a render; a part file holds the squares.
    Variance,
    /// The second half's share of the beauty and the components: kept with the split, all or
    /// none (files written before them have none, and a splatted film none).
    Halves,
}

/// How a render's sum of a buffer over a pixel's samples becomes its value, and so how parts
/// merge: every sum adds, but the object is that of sample 0 and must agree.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mean {
    /// Divided by the samples.
    Average,
    /// Normalised to unit length (a direction).
    Normalise,
    /// Kept as it is: the object of sample 0, never summed.
    First,
    /// Not a sum: made from the sums of squares ([`super::Sums::into_means`]).
    FromSquares,
}

/// What a part file's sums of a buffer may hold ([`crate::part`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rule {
    /// Light or albedo: finite, never negative, zero where no sample was taken.
    Light,
    /// Finite, zero where no sample was taken (a direction's sum may be negative).
    Direction,
    /// Finite, never negative, zero where no sample was taken.
    Scalar,
    /// A whole number from -1.
    Object,
    /// A whole number of samples, at most the pixel's.
    Count,
    /// Not in a part file.
    None,
}

/// One row: a buffer and everything the film's readers and writers need of it.
#[derive(Clone, Copy, Debug)]
pub struct LayerDef {
    pub buffer: Buffer,
    /// Its EXR channels, in the order of its values' components.
    pub channels: &'static [&'static str],
    pub group: Group,
    /// Whether a film read back from an EXR must have it; a missing optional layer takes
    /// [`LayerDef::missing`] (files written before it existed).
    pub required: bool,
    /// The value of a pixel of an optional layer a file lacks, and of a fresh film's.
    pub missing: f32,
    pub mean: Mean,
    pub rule: Rule,
}

const fn row(
    buffer: Buffer,
    channels: &'static [&'static str],
    group: Group,
    required: bool,
    missing: f32,
    mean: Mean,
    rule: Rule,
) -> LayerDef {
    LayerDef { buffer, channels, group, required, missing, mean, rule }
}

use Buffer as B;
use Component::{Caustic, Direct, Emitted, Indirect};
use Group as G;
use Mean as M;
use Rule as R;

/// Every layer of a film, in the order of its EXR's layers.
#[rustfmt::skip]
pub const LAYERS: [LayerDef; 22] = [
    row(B::Raw, &["raw.R", "raw.G", "raw.B"], G::Beauty, true, 0.0, M::Average, R::Light),
    row(B::Component(Emitted), &["emitted.R", "emitted.G", "emitted.B"], G::Split, true, 0.0, M::Average, R::Light),
    row(B::Component(Direct), &["direct.R", "direct.G", "direct.B"], G::Split, true, 0.0, M::Average, R::Light),
    row(B::Component(Caustic), &["caustic.R", "caustic.G", "caustic.B"], G::Split, true, 0.0, M::Average, R::Light),
    row(B::Component(Indirect), &["indirect.R", "indirect.G", "indirect.B"], G::Split, true, 0.0, M::Average, R::Light),
    row(B::Albedo, &["albedo.R", "albedo.G", "albedo.B"], G::Guides, false, 0.0, M::Average, R::Light),
    row(B::Normal, &["normal.X", "normal.Y", "normal.Z"], G::Guides, true, 0.0, M::Normalise, R::Direction),
    row(B::Depth, &["depth.Z"], G::Guides, true, 0.0, M::Average, R::Scalar),
    row(B::Object, &["objectid.ID"], G::Guides, true, -1.0, M::First, R::Object),
    row(B::Coverage, &["objectid.coverage"], G::Guides, false, 1.0, M::Average, R::Count),
    row(B::Alpha, &["A"], G::Guides, false, 1.0, M::Average, R::Count),
    row(B::Variance, &["raw_variance.Y"], G::Variance, false, 0.0, M::FromSquares, R::None),
    row(B::ComponentVariance(Emitted), &["emitted_variance.Y"], G::Variance, false, 0.0, M::FromSquares, R::None),
    row(B::ComponentVariance(Direct), &["direct_variance.Y"], G::Variance, false, 0.0, M::FromSquares, R::None),
    row(B::ComponentVariance(Caustic), &["caustic_variance.Y"], G::Variance, false, 0.0, M::FromSquares, R::None),
    row(B::ComponentVariance(Indirect), &["indirect_variance.Y"], G::Variance, false, 0.0, M::FromSquares, R::None),
    row(B::Half, &["raw_half.R", "raw_half.G", "raw_half.B"], G::Halves, false, 0.0, M::Average, R::Light),
    row(B::ComponentHalf(Emitted), &["emitted_half.R", "emitted_half.G", "emitted_half.B"], G::Halves, false, 0.0, M::Average, R::Light),
    row(B::ComponentHalf(Direct), &["direct_half.R", "direct_half.G", "direct_half.B"], G::Halves, false, 0.0, M::Average, R::Light),
    row(B::ComponentHalf(Caustic), &["caustic_half.R", "caustic_half.G", "caustic_half.B"], G::Halves, false, 0.0, M::Average, R::Light),
    row(B::ComponentHalf(Indirect), &["indirect_half.R", "indirect_half.G", "indirect_half.B"], G::Halves, false, 0.0, M::Average, R::Light),
    row(B::HalfShare, &["half_share.Y"], G::Halves, false, 0.0, M::Average, R::Count),
];

/// Whether `name` is taken by a layer the film or a part file has (an AOV may not have it).
pub fn is_reserved(name: &str) -> bool {
    let taken =
        |l: &LayerDef| l.name() == name || l.channels.iter().any(|c| c.split('.').next() == Some(name));
    LAYERS.iter().any(taken)
        || ["R", "G", "B", "A", "indirect_filtered", "samples", "sums"].contains(&name)
        || name.starts_with("Crypto")
}

/// The row of `buffer`.
pub fn layer(buffer: Buffer) -> &'static LayerDef {
    // The table is small; every buffer has a row (a test checks).
    LAYERS.iter().find(|l| l.buffer == buffer).unwrap_or(&LAYERS[0])
}

impl LayerDef {
    /// The layer's name: its channels' prefix (`raw`, `objectid.coverage`, `A`).
    pub fn name(&self) -> &'static str {
        let first = self.channels[0];
        if self.channels.len() == 1 {
            first
        } else {
            first.rsplit_once('.').map_or(first, |(prefix, _)| prefix)
        }
    }

    /// Values a pixel.
    pub fn width(&self) -> usize {
        self.channels.len()
    }
}

impl Film {
    /// A buffer's values, pixel after pixel (three a pixel for colours and normals); empty when
    /// the film does not hold it.
    pub fn values(&self, buffer: Buffer) -> &[f32] {
        match buffer {
            B::Raw => bytemuck::cast_slice(&self.raw.pixels),
            B::Component(c) => bytemuck::cast_slice(&self.components[c].pixels),
            B::Albedo => bytemuck::cast_slice(&self.albedo.pixels),
            B::Normal => bytemuck::cast_slice(&self.normal.pixels),
            B::Depth => &self.depth,
            B::Object => &self.object,
            B::Coverage => &self.coverage,
            B::Alpha => &self.alpha,
            B::Variance => &self.variance,
            B::ComponentVariance(c) => &self.component_variance[c],
            B::Half => bytemuck::cast_slice(&self.half.pixels),
            B::ComponentHalf(c) => bytemuck::cast_slice(&self.component_half[c].pixels),
            B::HalfShare => &self.half_share,
        }
    }

    /// [`Film::values`], to change in place.
    pub fn values_mut(&mut self, buffer: Buffer) -> &mut [f32] {
        match buffer {
            B::Raw => bytemuck::cast_slice_mut(&mut self.raw.pixels),
            B::Component(c) => bytemuck::cast_slice_mut(&mut self.components[c].pixels),
            B::Albedo => bytemuck::cast_slice_mut(&mut self.albedo.pixels),
            B::Normal => bytemuck::cast_slice_mut(&mut self.normal.pixels),
            B::Depth => &mut self.depth,
            B::Object => &mut self.object,
            B::Coverage => &mut self.coverage,
            B::Alpha => &mut self.alpha,
            B::Variance => &mut self.variance,
            B::ComponentVariance(c) => &mut self.component_variance[c],
            B::Half => bytemuck::cast_slice_mut(&mut self.half.pixels),
            B::ComponentHalf(c) => bytemuck::cast_slice_mut(&mut self.component_half[c].pixels),
            B::HalfShare => &mut self.half_share,
        }
    }

    /// Takes a buffer's values out of the film (as [`Film::values`]), leaving it empty.
    pub fn take_values(&mut self, buffer: Buffer) -> Vec<f32> {
        let image = |i: &mut super::Image| -> Vec<f32> {
            let pixels = std::mem::take(&mut i.pixels);
            *i = super::Image::empty();
            bytemuck::allocation::cast_vec(pixels)
        };
        match buffer {
            B::Raw => image(&mut self.raw),
            B::Component(c) => image(&mut self.components[c]),
            B::Albedo => image(&mut self.albedo),
            B::Normal => image(&mut self.normal),
            B::Depth => std::mem::take(&mut self.depth),
            B::Object => std::mem::take(&mut self.object),
            B::Coverage => std::mem::take(&mut self.coverage),
            B::Alpha => std::mem::take(&mut self.alpha),
            B::Variance => std::mem::take(&mut self.variance),
            B::ComponentVariance(c) => std::mem::take(&mut self.component_variance[c]),
            B::Half => image(&mut self.half),
            B::ComponentHalf(c) => image(&mut self.component_half[c]),
            B::HalfShare => std::mem::take(&mut self.half_share),
        }
    }

    /// Replaces a buffer with `values` (pixel after pixel, as [`Film::values`]), or empties it.
    pub fn set_values(&mut self, buffer: Buffer, values: Vec<f32>) {
        let image = |v: Vec<f32>, (w, h): (u32, u32)| {
            let pixels = v.chunks_exact(3).map(glam::Vec3::from_slice).collect::<Vec<_>>();
            let (width, height) = if pixels.is_empty() { (0, 0) } else { (w, h) };
            super::Image { width, height, pixels }
        };
        let size = (self.width, self.height);
        match buffer {
            B::Raw => self.raw = image(values, size),
            B::Component(c) => self.components[c] = image(values, size),
            B::Albedo => self.albedo = image(values, size),
            B::Normal => self.normal = image(values, size),
            B::Depth => self.depth = values,
            B::Object => self.object = values,
            B::Coverage => self.coverage = values,
            B::Alpha => self.alpha = values,
            B::Variance => self.variance = values,
            B::ComponentVariance(c) => self.component_variance[c] = values,
            B::Half => self.half = image(values, size),
            B::ComponentHalf(c) => self.component_half[c] = image(values, size),
            B::HalfShare => self.half_share = values,
        }
    }

    /// The layers the film holds (its buffers that are not empty), with their values.
    pub fn layers(&self) -> impl Iterator<Item = (&'static LayerDef, &[f32])> {
        LAYERS.iter().map(|l| (l, self.values(l.buffer))).filter(|(_, v)| !v.is_empty())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_buffer_has_one_row_and_every_channel_one_name() {
        let buffers = [
            B::Raw,
            B::Albedo,
            B::Normal,
            B::Depth,
            B::Object,
            B::Coverage,
            B::Alpha,
            B::Variance,
            B::Half,
            B::HalfShare,
        ]
        .into_iter()
        .chain(
            Component::ALL
                .into_iter()
                .flat_map(|c| [B::Component(c), B::ComponentVariance(c), B::ComponentHalf(c)]),
        );
        for b in buffers {
            assert_eq!(LAYERS.iter().filter(|l| l.buffer == b).count(), 1, "{b:?}");
            assert_eq!(layer(b).buffer, b);
        }
        let mut names: Vec<&str> = LAYERS.iter().flat_map(|l| l.channels.iter().copied()).collect();
        let all = names.len();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), all, "a channel named twice");
    }

    #[test]
    fn a_film_holds_the_values_of_each_layer_it_has() {
        let mut film = Film::with_buffers(2, 1, true, false);
        assert_eq!(film.layers().count(), 1 + 4 + 5 + 6, "the beauty, the split, its variances and halves");
        film.set_values(B::Component(Direct), vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(film.components[Direct].pixels[1], glam::Vec3::new(4.0, 5.0, 6.0));
        film.values_mut(B::Variance)[0] = 7.0;
        assert_eq!(film.variance, [7.0, 0.0]);
        assert_eq!(layer(B::Coverage).name(), "objectid.coverage");
        assert_eq!(layer(B::Normal).name(), "normal");
    }
}
