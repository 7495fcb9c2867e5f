//! trilab: GPU ray-triangle intersection laboratory.
//!
//! Data flows one way, and so do imports: every module imports only modules listed before it
//! here (`tests/layers.rs` checks it; `ARCHITECTURE.md` explains the layers).
//!
//! - Ground floor: each axis's default ([`defaults`]), the environment variables read ([`env`]), [`error`], atomic output ([`io`]), the run's timeline ([`trace`], `--timeline`), the processes trilab starts ([`children`]), tables and summaries ([`report`]), the host CPU a run ran on ([`host`]), the result rows `compare` and `merge` read ([`rows`]), named
//!   option values ([`named`]), the constants shared with GLSL ([`shared`]), the kernel registry
//!   ([`kernels`]) and SPIR-V counts, reflection and capabilities ([`spirv`]).
//! - [`scene`]: OBJ/MTL and synthetic meshes; [`rays`]: ray and hit files, cameras, ray sets,
//!   spawn offsets; [`bvh`]: the SAH build, 32-byte nodes.
//! - The CPU's truth: the f64 [`reference`], [`agreement`] with it, [`traversal`] (the
//!   kernels' loop mirrored on the CPU).
//! - [`encoding`]: the intersectors, one unit each (layout, encoder, memory placement), their
//!   registry and [`encoding::Method`].
//! - [`gpu`]: device, buffers, pipelines, dispatch, timestamps, faults, the driver's ray query.
//! - [`conditioning`]: a scene's conditioning and the method it needs (`--method auto`).
//! - [`pipeline`]: the one scene pipeline, mesh to scene on the device with its kernels.
//! - [`render`]: the path tracer.
//! - [`services`]: what the commands share: validation against the reference, ray sets,
//!   provenance, plots, result folders, shards, peers, the roofline, driver statistics.
//! - [`matrix`]: the experiment's axes, their defaults and the device's and registry's filters;
//!   the commands loop over its cells.
//! - [`commands`]: one room per command (bench, study, accuracy, profile, ab, compare, ...),
//!   each a library call returning a typed report; the CLI (`src/cli/`, in the binary) calls these.

pub mod defaults;
pub mod env;
pub mod error;
pub mod io;
pub mod timeline;
pub mod children;
pub mod memory;
pub mod report;
pub mod host;
pub mod rows;
pub mod named;
pub mod shared;
pub mod kernels;
pub mod spirv;
pub mod scene;
pub mod rays;
pub mod bvh;
pub mod reference;
pub mod agreement;
pub mod traversal;
pub mod encoding;
pub mod gpu;
pub mod conditioning;
pub mod pipeline;
pub mod render;
pub mod services;
pub mod matrix;
pub mod commands;

pub use error::{Error, Result};
