//! One file a command (or a few that share their work): each turns its arguments into the
//! library's terms, calls it, and prints.

pub mod image;
pub mod info;
pub mod measure;
pub mod merge;
pub mod render;
