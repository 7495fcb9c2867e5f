//! Everything that measures and reports, each a library call returning a typed report that the
//! CLI prints (text, or the struct as JSON) and writes: the ray-casting benchmark, the paper's
//! study, accuracy, the driver-level profile, large scenes, the BVH build benchmark, traversal
//! steps, the render benchmark. What they share lives here too: provenance, the host calibration, the ray sets,
//! validation against the f64 reference before any time is reported, and plots.

pub mod ab;
pub mod accuracy;
pub mod analyze;
pub mod bench;
pub mod bench_render;
pub mod build_bench;
pub mod bvh_stats;
pub mod calibration;
pub mod devices;
pub mod efficiency;
pub mod gate;
pub mod hits;
pub mod make_rays;
pub mod merge;
pub mod methods;
pub mod peer_report;
pub mod peers;
pub mod plots;
pub mod profile;
pub mod provenance;
pub mod raycast;
pub mod rayset;
pub mod roofline;
pub mod results;
pub mod compare;
pub mod scale;
pub mod shard;
pub mod spirv;
pub mod steps;
pub mod study;
pub mod suite;
pub mod validate;
