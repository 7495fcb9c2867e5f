//! Möller–Trumbore in double precision on MT's data (`glsl/intersect/f64.glsl`): the kernel
//! widens the f32 vertices exactly and solves in the CPU reference's operation order, so its hits
//! are the f64 reference's rounded to f32: a GPU reference. Needs `shaderFloat64`; elsewhere its
//! kernels fail to create with `Error::Unsupported`.

use super::{mt, Intersector};
use crate::shared::BINDING_INDICES;

pub const INTERSECTOR: Intersector = Intersector {
    name: "f64",
    glsl: "f64",
    title: "Moller-Trumbore f64",
    about: "Möller–Trumbore in double on MT's data, equal bit for bit to the CPU f64 reference rounded \
            to f32 (a GPU reference; needs shaderFloat64).",
    in_paper: false,
    encode: mt::encode,
    placement: mt::placement,
    prim_binding: BINDING_INDICES,
    prim_struct: mt::LAYOUT,
};
