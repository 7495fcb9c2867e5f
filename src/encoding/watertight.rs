//! Woop, Benthin & Wald's watertight test (S. Woop, C. Benthin, I. Wald, "Watertight
//! Ray/Triangle Intersection", JCGT 2(1), 2013) on Möller–Trumbore's data
//! (`glsl/intersect/watertight.glsl`): shear to ray space, FMA-free (`precise`) edge functions,
//! two-sided, with the conservative box test of its sec. 5 (no leaks by construction).

use super::{mt, Intersector};
use crate::shared::BINDING_INDICES;

pub const INTERSECTOR: Intersector = Intersector {
    name: "watertight",
    glsl: "watertight",
    title: "Watertight",
    about: "Woop, Benthin & Wald (JCGT 2(1), 2013) on MT's data: shear to ray space, FMA-free edge \
            functions, two-sided, conservative traversal (no leaks by construction).",
    in_paper: false,
    encode: mt::encode,
    placement: mt::placement,
    prim_binding: BINDING_INDICES,
    prim_struct: mt::LAYOUT,
};
