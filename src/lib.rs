//! lightsplit: a path tracer that splits each pixel's radiance into light-path components and
//! low-pass filters only the indirect diffuse part (Jensen & Christensen, "Optimizing Path
//! Tracing using Noise Reduction Filters"). Rays go through Embree or the project's own BVH.
//! `unsafe` is denied everywhere but in the Embree wrapper and the BVH's SIMD module.
#![deny(unsafe_code)]

pub mod accel;
pub mod bench;
pub mod component;
pub mod converge;
pub mod error;
pub mod film;
pub mod filter;
pub mod job;
pub mod lpe;
pub mod math;
pub mod metrics;
pub mod output;
pub mod part;
pub mod render;
pub mod scene;
pub mod stress;
