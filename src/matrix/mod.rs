//! The experiment matrix: the axes a measurement crosses, in one place.
//!
//! A command that measures kernels (bench, the study, accuracy, profile, ab's sides, ...) names
//! the values it was asked for on each axis ([`Experiment`]: scenes, leaf sizes, ray sets, and the
//! kernel axes [`KernelAxes`]: methods, layouts, traversals, access paths, node orders, ray
//! orders) and loops over the cells this module gives it ([`Cell`], [`KernelCell`]), mapping
//! each to its own typed cell (`BenchCell`, `StudyCell`, ...) for its rows. Here, and nowhere
//! else:
//!
//! - each axis's default is applied, once: an axis left empty takes its typed default
//!   (`T::DEFAULT`, `src/defaults.rs`) alone ([`KernelAxes::resolved`]);
//! - the device's filter: what the device cannot run is left out with the reason
//!   `gpu::Capabilities` gives ([`KernelAxes::for_device`]);
//! - the registry's filter: a combination without a compiled kernel is left out with a note
//!   ([`KernelAxes::kernels`], [`KernelAxes::notes`]);
//! - the crossing, in one order: group (scene x leaf size, what a shard takes), ray set, kernel,
//!   ray order ([`Experiment::cells`]);
//! - a cell's name in progress lines and tables ([`KernelLabel`]).
//!
//! The GPU targets that `driver-stats --targets` and the study compile for through RADV's null
//! device are an axis too ([`TargetAxes`]: chips, compilers, subgroup sizes, Mesa builds).
//!
//! The access path a cell's scene is read through is not decided here: `--scene-access auto`
//! leaves it to the scene's memory placement (`encoding::placement::Placement::choose`, the one
//! place it is chosen), so a planned `auto` cell names no path, and its row names the one taken.

mod axes;
mod cell;
mod experiment;
mod targets;

pub use axes::KernelAxes;
pub use cell::{KernelCell, KernelLabel};
pub use experiment::{Cell, Experiment, Group};
pub use targets::{TargetAxes, TargetItem, DEFAULT_CHIPS};
