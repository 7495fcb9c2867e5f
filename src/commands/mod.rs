//! One room per command: each a library call that takes typed options and returns a typed
//! report, which the CLI (`src/cli/`) prints (text, or the struct as JSON) and writes. What
//! commands share lives below them in [`crate::services`]. A command that needs another's work
//! calls its typed options and report (the suite runs bench, study, accuracy and profile), never
//! a spelled command line; work that must run in a fresh process (another environment) goes
//! through the worker service ([`crate::services::worker`]), whose requests [`worker`] serves.

pub mod ab;
pub mod accuracy;
pub mod analyze;
pub mod bench;
pub mod bench_render;
pub mod build_bench;
pub mod bvh_stats;
pub mod devices;
pub mod gate;
pub mod hits;
pub mod make_rays;
pub mod merge;
pub mod methods;
pub mod profile;
pub mod raycast;
pub mod repro;
pub mod compare;
pub mod scale;
pub mod spirv;
pub mod steps;
pub mod study;
pub mod suite;
pub mod worker;
