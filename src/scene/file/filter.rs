//! `[filter]`: the filter a render of this scene asks for, kept as written. The scene checks only
//! its keys and that its numbers are finite; `filter::Setting::from_section` reads it (kernel
//! names and weights, targets and edge stops belong to the filters).

use serde::{Deserialize, Deserializer};

use super::F;

/// The `[filter]` section as written.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FilterSection {
    /// The kernel, by name or by its weights.
    pub kernel: KernelSpec,
    /// What the filter applies to (`indirect`, `image` or `none`).
    pub target: Option<String>,
    /// Only neighbours that show the centre's object.
    pub edge_aware: Option<bool>,
    /// The normal tolerance of the edge stops, in degrees.
    #[serde(default, deserialize_with = "finite")]
    pub edge_normal: Option<f32>,
    /// The relative depth tolerance of the edge stops.
    #[serde(default, deserialize_with = "finite")]
    pub edge_depth: Option<f32>,
    /// Leave pixels that saw more than one object unfiltered.
    pub edge_pure: Option<bool>,
    /// The line of the section's header, for the errors of whoever reads it.
    #[serde(skip)]
    pub line: usize,
}

/// A kernel by name or by its weights (row by row).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum KernelSpec {
    /// A named kernel (`box3`, `weighted3`, ...), or weights written as one string.
    Name(String),
    /// The weights of an odd square kernel.
    Weights(#[serde(deserialize_with = "finite_weights")] Vec<f32>),
}

/// An optional finite number, as a plain `f32`.
fn finite<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f32>, D::Error> {
    Ok(Option::<F>::deserialize(d)?.map(|f| f.0))
}

/// Finite weights, as plain `f32`s.
fn finite_weights<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f32>, D::Error> {
    Ok(Vec::<F>::deserialize(d)?.into_iter().map(|f| f.0).collect())
}
