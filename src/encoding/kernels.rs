//! A method's compiled kernels, by what they compute rather than by name: the ray-casting
//! variants of `glsl/raycast.comp` for each access path, and the layout probe.

use super::{AccessPath, Method};
use crate::error::{Error, Result};
use crate::kernels::{find, KernelSource};
use crate::named::named_enum;

named_enum! {
    /// What a ray-casting kernel computes per ray (the variants of `glsl/raycast.comp`).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum Raycast: "raycast variant" {
        /// The closest hit.
        Closest = "closest",
        /// Any hit in [tmin, tmax] (occlusion).
        Any = "any",
        /// The closest hit and the ray's traversal work (`TRAVERSAL_STATS` in `glsl/traverse.glsl`).
        Stats = "stats",
        /// The closest hit and the shader-clock ticks around its traversal (`trilab profile`).
        Clock = "clock",
    }
}

named_enum! {
    /// How the BVH's nodes are laid out for the ray-casting kernels (issue 15).
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum Layout: "BVH layout" {
        /// The paper's binary tree of 32-byte nodes (every kernel).
        Bvh2 = "bvh2" (default),
        /// The SAH tree collapsed into 4-wide 128-byte nodes (`bvh::Bvh4Node`), child boxes in
        /// the parent: only the closest-hit kernel on the texel path so far (`closest_bvh4`).
        Bvh4 = "bvh4",
    }
}

impl Method {
    /// The ray-casting kernel computing `kind` over a scene read through `access` with its nodes
    /// in `layout`; an error for a combination that has no kernel (yet).
    pub fn layout_kernel(self, kind: Raycast, access: AccessPath, layout: Layout) -> Result<&'static KernelSource> {
        match (layout, kind, access) {
            (Layout::Bvh2, ..) => Ok(self.raycast_kernel(kind, access)),
            (Layout::Bvh4, Raycast::Closest, AccessPath::Texel) => {
                Ok(find("raycast", self.glsl_name(), "closest_bvh4").unwrap_or_else(|| {
                    panic!("raycast.{}.closest_bvh4 was not compiled (glsl/raycast.comp)", self.name())
                }))
            }
            (Layout::Bvh4, ..) => Err(Error::Usage(format!(
                "the {layout} layout has only the closest-hit kernel on the texel path so far \
                 (asked for `{kind}` on the {} path)",
                access.name()
            ))),
        }
    }

    /// The ray-casting kernel computing `kind` over a scene read through `access`.
    pub fn raycast_kernel(self, kind: Raycast, access: AccessPath) -> &'static KernelSource {
        let variant = match (kind, access) {
            (k, AccessPath::Texel) => k.to_string(),
            // SCENE_ADDRESS (glsl/types.glsl): the same kernel reading buffer device addresses.
            (k, AccessPath::Address) => format!("{k}_bda"),
        };
        find("raycast", self.glsl_name(), &variant)
            .unwrap_or_else(|| panic!("raycast.{}.{variant} was not compiled (glsl/raycast.comp)", self.name()))
    }

    /// The layout probe (`glsl/probe.comp`): copies nodes, primitives and slot ids out through the
    /// kernels' own loaders.
    pub fn probe_kernel(self) -> &'static KernelSource {
        find("probe", self.glsl_name(), "main")
            .unwrap_or_else(|| panic!("probe.{}.main was not compiled (glsl/probe.comp)", self.glsl_name()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::KERNELS;
    use crate::named::Named;

    #[test]
    fn every_method_has_every_raycast_kernel_and_every_raycast_kernel_is_reachable() {
        let mut reached = vec![];
        for m in Method::ALL {
            for &kind in Raycast::ALL {
                for access in [AccessPath::Texel, AccessPath::Address] {
                    let k = m.raycast_kernel(kind, access);
                    assert_eq!((k.kernel, k.method), ("raycast", m.glsl_name()));
                    reached.push(k.name);
                }
            }
            assert_eq!(m.probe_kernel().kernel, "probe");
        }
        for m in Method::ALL {
            let k = m.layout_kernel(Raycast::Closest, AccessPath::Texel, Layout::Bvh4).unwrap();
            reached.push(k.name);
            assert!(m.layout_kernel(Raycast::Any, AccessPath::Texel, Layout::Bvh4).is_err());
            assert!(m.layout_kernel(Raycast::Closest, AccessPath::Address, Layout::Bvh4).is_err());
        }
        for k in KERNELS.iter().filter(|k| k.kernel == "raycast") {
            assert!(reached.contains(&k.name), "{} cannot be asked for by kind and access path", k.name);
        }
    }
}
