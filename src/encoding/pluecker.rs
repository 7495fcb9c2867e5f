//! Ray-triangle test in Plücker coordinates, Embree's robust form (Wald et al., "Embree: A
//! Kernel Framework for Efficient CPU Ray Tracing", ACM TOG 33(4), 2014): edge side products about
//! the ray origin, exactly antisymmetric on shared edges (so watertight along edges, not at
//! vertices), with conservative traversal (`glsl/intersect/pluecker.glsl`). On Möller–Trumbore's
//! data, so a comparison with MT measures the arithmetic only.

use super::{mt, Intersector};
use crate::shared::BINDING_INDICES;

pub const INTERSECTOR: Intersector = Intersector {
    name: "pluecker",
    glsl: "pluecker",
    title: "Pluecker",
    about: "Embree's robust test in Plücker coordinates (Wald et al., TOG 33(4), 2014) on MT's data: edge \
            side products about the ray origin, FMA-free, two-sided, conservative traversal; no leaks through edges (at vertices a few).",
    in_paper: false,
    encode: mt::encode,
    placement: mt::placement,
    prim_binding: BINDING_INDICES,
    prim_struct: mt::LAYOUT,
};
