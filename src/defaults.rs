//! Each axis's default, in one place: what a command, a library option and build.rs take when
//! nothing else is asked for. Everything else reads these, typed where the axis has a type:
//! [`Layout::DEFAULT`] and [`Method::DEFAULT`] are found by the names below at compile time
//! (an unknown name is a compile error), `BuildOptions::default()` and `RaySetSizes::default()`
//! are made of the numbers below, and the command line's defaults are these values
//! (`tests/defaults.rs` holds it so, and finds no other spelling of them).
//!
//! The axes that are named enums (`named::named_enum!`) keep their default where their values
//! are listed, marked `(default)`, and have `DEFAULT` too: [`Traversal`] (`while-if`),
//! [`SceneAccess`] (`auto`), [`LeafPolicy`] (`fill`), [`NodeOrder`] (`built`), [`RayOrder`]
//! (`given`). The workgroup size is `glsl/shared.glsl`'s `WORKGROUP_SIZE` (`crate::shared`).
//!
//! Plain Rust without imports: build.rs includes this file (`#[path]`) to compile every kernel
//! variant without a layout suffix with [`LAYOUT`].
//!
//! [`Layout::DEFAULT`]: crate::encoding::Layout::DEFAULT
//! [`Method::DEFAULT`]: crate::encoding::Method::DEFAULT
//! [`Traversal`]: crate::encoding::Traversal::DEFAULT
//! [`SceneAccess`]: crate::encoding::SceneAccess::DEFAULT
//! [`LeafPolicy`]: crate::bvh::LeafPolicy::DEFAULT
//! [`NodeOrder`]: crate::bvh::NodeOrder::DEFAULT
//! [`RayOrder`]: crate::rays::order::RayOrder::DEFAULT

/// The intersection method (`--method`): Möller-Trumbore, `glsl/intersect/mt.glsl`.
pub const METHOD: &str = "mt";

/// The node layout (`--layout`, `--layouts`): the paper's binary nodes, `glsl/layout/bvh2.glsl`.
/// build.rs compiles every variant with it and names those variants without a layout suffix.
pub const LAYOUT: &str = "bvh2";

/// Most triangles in a BVH leaf (`--leaf-size`): the paper's best (sec. 3.1).
pub const LEAF_SIZE: u32 = 4;

/// The primary ray set's image width in pixels (`--width`).
pub const WIDTH: u32 = 800;
/// The primary ray set's image height in pixels (`--height`).
pub const HEIGHT: u32 = 600;
/// Diffuse rays per primary hit (`--diffuse-per-hit`).
pub const DIFFUSE_PER_HIT: u32 = 8;
/// Rays of the random set (`--random-rays`).
pub const RANDOM_RAYS: usize = 1_000_000;
/// Seed of the diffuse and random ray sets (`--seed`).
pub const SEED: u64 = 7;

/// Timed runs of a benchmark after its warm-up (`--repeat`); the median is reported.
pub const REPEAT: usize = 5;
/// Most rays per dispatch (`--batch-rays`); each dispatch is its own submit.
pub const BATCH_RAYS: usize = 1 << 20;
