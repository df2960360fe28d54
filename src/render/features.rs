//! What a render computes, chosen once per render from the scene's analysis and from what its
//! outputs read. Each combination is its own monomorphised integrator and tile loop (a const bit
//! set, [`Features::bits`]), so a feature left out costs nothing per sample: no branch, no buffer.

use serde::Serialize;

use crate::scene::analysis::Analysis;

/// Emission at hits, lookups at infinity, MIS weights, and the ray after the last vertex: what
/// a path needs when it can hit a light. Off with only point and spot lights.
pub const MIS: u8 = 1;
/// The component split (emitted, direct, caustic, indirect) and its buffers.
pub const SPLIT: u8 = 2;
/// The guide buffers: object ID and coverage, normal, depth, albedo.
pub const GUIDES: u8 = 4;
/// Colour textures, bump maps and vertex colours: without them a hit computes neither its
/// texture coordinates nor its vertex colour.
pub const TEXTURES: u8 = 8;
/// Every feature: the general integrator.
pub const ALL: u8 = MIS | SPLIT | GUIDES | TEXTURES;

/// The features one render computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Features {
    /// [`MIS`]: what a path needs when it can hit a light.
    pub mis: bool,
    /// [`SPLIT`]: the component split and its buffers.
    pub split: bool,
    /// [`GUIDES`]: the guide buffers.
    pub guides: bool,
    /// [`TEXTURES`]: colour textures, bump maps and vertex colours.
    pub textures: bool,
}

/// What a render's outputs read besides the beauty: the output module decides it from the
/// output's format, layer and filter, so the renderer never sees them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Outputs {
    /// The component split: an EXR, a filter on `indirect`, or a component layer.
    pub split: bool,
    /// The guide buffers: an EXR, edge-aware filtering, or the albedo layer.
    pub guides: bool,
}

impl Outputs {
    /// Every layer (an EXR).
    pub const ALL: Outputs = Outputs { split: true, guides: true };
}

impl Features {
    /// Every feature on, whatever the scene: the general integrator, for comparison.
    pub const ALL: Features = Features { mis: true, split: true, guides: true, textures: true };

    /// Only what a scene with this analysis, written to these outputs, can use.
    pub fn needed(analysis: &Analysis, outputs: Outputs) -> Features {
        Features {
            mis: analysis.lights.hittable() > 0,
            split: outputs.split,
            guides: outputs.guides,
            textures: analysis.textured(),
        }
    }

    /// The const bit set the integrator is instantiated with.
    pub fn bits(self) -> u8 {
        (self.mis as u8 * MIS)
            | (self.split as u8 * SPLIT)
            | (self.guides as u8 * GUIDES)
            | (self.textures as u8 * TEXTURES)
    }

    /// The features on, by name, or "none".
    pub fn names(self) -> String {
        let names: Vec<&str> =
            [("mis", self.mis), ("split", self.split), ("guides", self.guides), ("textures", self.textures)]
                .iter()
                .filter(|(_, on)| *on)
                .map(|(n, _)| *n)
                .collect();
        if names.is_empty() {
            "none".into()
        } else {
            names.join("+")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_are_distinct_and_all_is_all() {
        let mut seen = std::collections::BTreeSet::new();
        for b in 0..16u8 {
            let f = Features { mis: b & 1 != 0, split: b & 2 != 0, guides: b & 4 != 0, textures: b & 8 != 0 };
            assert_eq!(f.bits(), b);
            seen.insert(f.names());
        }
        assert_eq!(seen.len(), 16);
        assert_eq!(Features::ALL.bits(), ALL);
    }
}
