//! Mitsuba 3 scene XML (issue 38, in progress): [`xml`] reads a file into a tree of objects;
//! turning that tree into a [`crate::scene::Scene`] is next.

mod build;
mod cie;
pub mod materials;
mod props;
pub mod shapes;
pub mod xml;

pub use build::scene;
