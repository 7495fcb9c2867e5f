//! The experiment matrix: the axes a measurement crosses, in one place.
//!
//! A command that measures kernels (bench, ab's sides, ...) names the values it was asked for on
//! each axis ([`KernelAxes`]: methods, layouts, traversals, access paths, node orders, ray
//! orders) and loops over the cells this module gives it ([`KernelCell`]). Here, and nowhere
//! else:
//!
//! - each axis's default is applied, once: an axis left empty takes its typed default
//!   (`T::DEFAULT`, `src/defaults.rs`) alone ([`KernelAxes::resolved`]);
//! - the device's filter: what the device cannot run is left out with the reason
//!   `gpu::Capabilities` gives ([`KernelAxes::for_device`]);
//! - the registry's filter: a combination without a compiled kernel is left out with a note
//!   ([`KernelAxes::kernels`], [`KernelAxes::notes`]);
//! - a cell's name in progress lines and tables ([`KernelLabel`]).
//!
//! The access path a cell's scene is read through is not decided here: `--scene-access auto`
//! leaves it to the scene's memory placement (`encoding::placement::Placement::choose`, the one
//! place it is chosen), so a planned `auto` cell names no path, and its row names the one taken.

mod axes;
mod cell;

pub use axes::KernelAxes;
pub use cell::{KernelCell, KernelLabel};
