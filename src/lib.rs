//! trilab: GPU ray-triangle intersection laboratory.
//!
//! Data flows one way, one module per stage:
//! [`scene`] (OBJ/MTL -> mesh) -> [`bvh`] (SAH build, 32-byte nodes) -> [`encoding`] (each
//! method's GPU layout) -> [`gpu`] (buffers, pipelines, dispatch, timing) -> results
//! ([`rays`] hit files, [`compare`] against the f64 [`reference`], [`report`] tables,
//! [`render`] path-traced images).
//! The kernels live in `glsl/`; [`kernels`] embeds their SPIR-V and [`spirv`] counts and
//! reflects it.

pub mod accuracy;
pub mod analyze;
pub mod bench;
pub mod bsdf;
pub mod build_bench;
pub mod bvh;
pub mod compare;
pub mod encoding;
pub mod error;
pub mod gpu;
pub mod io;
pub mod kernels;
pub mod named;
pub mod profile;
pub mod rays;
pub mod reference;
pub mod render;
pub mod report;
pub mod scale;
pub mod scene;
pub mod shared;
pub mod spirv;
pub mod study;
pub mod traversal;

pub use error::{Error, Result};
