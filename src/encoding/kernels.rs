//! A method's compiled kernels, by what they compute rather than by name: the ray-casting
//! variants of `glsl/raycast.comp` for each access path, and the layout probe.

use super::{AccessPath, Layout, Method};
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

impl Method {
    /// The ray-casting kernel computing `kind` over a scene read through `access` with its nodes
    /// in `layout`; an error for a combination that has no kernel (yet).
    pub fn layout_kernel(self, kind: Raycast, access: AccessPath, layout: Layout) -> Result<&'static KernelSource> {
        let variant = match access {
            AccessPath::Texel => format!("{kind}{}", layout.variant_suffix()),
            // SCENE_ADDRESS (glsl/types.glsl): the same kernel reading buffer device addresses.
            AccessPath::Address => format!("{kind}_bda{}", layout.variant_suffix()),
        };
        find("raycast", self.glsl_name(), &variant).ok_or_else(|| {
            Error::Usage(format!(
                "no raycast.{}.{variant} kernel: the {layout} layout has no `{kind}` kernel on the {} path \
                 (glsl/raycast.comp's `// trilab:layouts` line)",
                self.name(),
                access.name()
            ))
        })
    }

    /// The ray-casting kernel computing `kind` over a scene read through `access` (binary nodes).
    pub fn raycast_kernel(self, kind: Raycast, access: AccessPath) -> &'static KernelSource {
        self.layout_kernel(kind, access, Layout::Bvh2).unwrap_or_else(|e| panic!("{e}"))
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
        // Every layout has every kind on both paths, named after it.
        for m in Method::ALL {
            for &layout in Layout::ALL {
                for &kind in Raycast::ALL {
                    for access in [AccessPath::Texel, AccessPath::Address] {
                        let k = m.layout_kernel(kind, access, layout).unwrap();
                        assert_eq!(k.layout, layout.name(), "{}", k.name);
                        reached.push(k.name);
                    }
                }
            }
        }
        for k in KERNELS.iter().filter(|k| k.kernel == "raycast") {
            assert!(reached.contains(&k.name), "{} cannot be asked for by kind and access path", k.name);
        }
    }
}
