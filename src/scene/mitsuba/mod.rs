//! Mitsuba 3 scene XML (versions 2 and 3, and older files' camelCase names): [`xml`] reads a
//! file into a tree of objects (parameters, includes, references, transforms), `build` turns
//! that tree into a [`crate::scene::Scene`] (sensors, film, integrator, emitters, shapes,
//! instances, BSDFs, textures), saying in a note whatever it does not read. The BSDFs Mitsuba
//! has and lightsplit's own materials do not are [`materials`], rendered by
//! `render/bsdf/{conductor,dielectric,plastic}.rs`.

mod build;
mod cie;
pub mod materials;
mod props;
pub mod shapes;
pub mod xml;

pub use build::{named_conductor, scene};
