//! `[filter]`: the filter a render of this scene asks for, kept as written. The scene checks only
//! its keys and that its numbers are finite; `filter::Setting::from_section` reads it (kernel
//! names and weights, targets and edge stops belong to the filters).

use std::fmt;

use serde::de::{self, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer};

use super::F;
use crate::scene::limits;

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
#[derive(Clone, Debug, PartialEq)]
pub enum KernelSpec {
    /// A named kernel (`box3`, `weighted3`, ...), or weights written as one string.
    Name(String),
    /// The weights of an odd square kernel, at most [`limits::MAX_KERNEL`] on a side.
    Weights(Vec<f32>),
}

impl<'de> Deserialize<'de> for KernelSpec {
    /// A string or an array of finite numbers; a bad weight is named as such (not "did not
    /// match any variant"), and an array longer than the largest kernel is refused as it is read.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Spec;
        impl<'de> Visitor<'de> for Spec {
            type Value = KernelSpec;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a kernel name such as \"box3\", or an array of weights")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<KernelSpec, E> {
                Ok(KernelSpec::Name(v.to_string()))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<KernelSpec, A::Error> {
                let most = limits::MAX_KERNEL * limits::MAX_KERNEL;
                let mut weights = Vec::new();
                while let Some(F(w)) = seq.next_element::<F>()? {
                    if weights.len() == most {
                        let side = limits::MAX_KERNEL;
                        return Err(de::Error::custom(format!("a kernel has at most {side}x{side} weights")));
                    }
                    weights.push(w);
                }
                Ok(KernelSpec::Weights(weights))
            }
        }
        d.deserialize_any(Spec)
    }
}

/// An optional finite number, as a plain `f32`.
fn finite<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f32>, D::Error> {
    Ok(Option::<F>::deserialize(d)?.map(|f| f.0))
}
