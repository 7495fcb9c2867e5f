//! What two or more commands share, below every command: checking a cast's hits against the
//! CPU f64 reference before any time is reported ([`validate`]), the ray sets ([`rayset`]),
//! where a run ran ([`provenance`]), the host's calibration ([`calibration`]), plots
//! ([`plots`]), result folders ([`results`]), shards ([`shard`]), the CPU peers ([`peers`],
//! [`peer_report`]), timing renders ([`render_measure`]), the traversal roofline ([`roofline`]) and efficiency against it
//! ([`efficiency`]), driver-level statistics of compiled kernels ([`driver_stats`]), and running
//! trilab again in another environment, with typed requests and answers ([`worker`]).
//!
//! A service never imports a command (`tests/layers.rs`).

pub mod calibration;
pub mod driver_stats;
pub mod efficiency;
pub mod peer_report;
pub mod peers;
pub mod plots;
pub mod provenance;
pub mod rayset;
pub mod render_measure;
pub mod results;
pub mod roofline;
pub mod shard;
pub mod validate;
pub mod worker;
