//! A method's compiled kernels, by what they compute rather than by name: the ray-casting
//! variants of `glsl/raycast.comp` for each access path, and the layout probe.

use super::{AccessPath, Layout, Method};
use crate::error::{Error, Result};
use crate::kernels::{find, KernelSource};
use crate::named::{named_enum, Named};

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
    /// How a ray-casting kernel walks the tree (issue 15: traversals measured side by side).
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum Traversal: "traversal" {
        /// One ray per invocation, stack-based while-if, nearest child first (glsl/traverse.glsl,
        /// glsl/layout/): every layout, kind and access path.
        WhileIf = "while-if" (default),
        /// One ray per invocation, Aila & Laine's while-while with leaf postponing (HPG 2009;
        /// glsl/while_while.glsl): binary nodes, texel path, closest, any and stats.
        WhileWhile = "while-while",
        /// The subgroup traces one ray at a time, a child box and a leaf triangle per lane (Lier,
        /// Stamminger & Selgrad, HPG 2018; glsl/raycast_coop.comp): bvh2, bvh4, bvh8, texel path,
        /// closest and stats.
        Coop = "coop",
        /// Persistent threads with dynamic ray fetch (Aila & Laine, HPG 2009): a fixed number of
        /// workgroups, each invocation takes ray indices from an atomic counter and starts the
        /// next ray inside the traversal loop (glsl/raycast_persistent.comp): bvh2 (the control)
        /// and bvh4, texel path, closest.
        Persistent = "persistent",
    }
}

/// `VkSubgroupFeatureFlags` the cooperative kernel uses: basic, vote, arithmetic, ballot,
/// shuffle.
pub const COOP_SUBGROUP_OPERATIONS: u32 = 0x1 | 0x2 | 0x4 | 0x8 | 0x10;

impl Traversal {
    /// The kernel file (`glsl/<kernel>.comp`) and the variant suffix of this traversal's
    /// ray-casting kernels.
    fn kernel(self) -> (&'static str, &'static str) {
        match self {
            Traversal::WhileIf => ("raycast", ""),
            Traversal::WhileWhile => ("raycast", "_ww"),
            Traversal::Coop => ("raycast_coop", ""),
            Traversal::Persistent => ("raycast_persistent", ""),
        }
    }

    /// Why a device cannot run this traversal's kernels (`None`: it can): the cooperative kernel
    /// needs subgroup operations in compute shaders ([`COOP_SUBGROUP_OPERATIONS`]) and at least
    /// four lanes.
    pub fn unsupported(self, subgroup_size: u32, subgroup_operations: u32) -> Option<String> {
        match self {
            Traversal::Coop if subgroup_operations & COOP_SUBGROUP_OPERATIONS != COOP_SUBGROUP_OPERATIONS => {
                Some(format!(
                "--traversal coop needs subgroup basic, vote, arithmetic, ballot and shuffle operations in compute \
                 shaders (the device has {subgroup_operations:#x})"
            ))
            }
            Traversal::Coop if subgroup_size < 4 => {
                Some(format!("--traversal coop needs a subgroup of at least 4 lanes (the device has {subgroup_size})"))
            }
            _ => None,
        }
    }
}

impl Method {
    /// The ray-casting kernel computing `kind` with `traversal` over a scene read through
    /// `access` with its nodes in `layout`; an error naming what is missing for a combination
    /// that has no kernel.
    pub fn traversal_kernel(
        self,
        kind: Raycast,
        access: AccessPath,
        layout: Layout,
        traversal: Traversal,
    ) -> Result<&'static KernelSource> {
        if traversal == Traversal::WhileIf {
            return self.layout_kernel(kind, access, layout);
        }
        let (kernel, suffix) = traversal.kernel();
        let variant = format!("{kind}{suffix}{}", layout.variant_suffix());
        match access {
            AccessPath::Texel => find(kernel, self.glsl_name(), &variant),
            AccessPath::Address => None,
        }
        .ok_or_else(|| {
            Error::Usage(format!(
                "no {kernel}.{}.{variant} kernel: the {traversal} traversal has no `{kind}` kernel for the {layout} \
                 layout on the {} path ({})",
                self.name(),
                access.name(),
                traversal.help()
            ))
        })
    }

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
                    assert_eq!((k.kernel, k.intersector), ("raycast", m.glsl_name()));
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
        // The other traversals: while-while on the binary nodes (closest, any, stats), the
        // cooperative kernel on bvh2, bvh4 and bvh8 (closest, stats; it reads their node formats
        // itself, and cwbvh's it does not); persistent threads on bvh2 and bvh4 (closest); texel path only.
        for m in Method::ALL {
            for &layout in Layout::ALL {
                for &kind in Raycast::ALL {
                    for t in [Traversal::WhileWhile, Traversal::Coop, Traversal::Persistent] {
                        let k = m.traversal_kernel(kind, AccessPath::Texel, layout, t);
                        let expected = match t {
                            Traversal::WhileWhile => layout == Layout::Bvh2 && kind != Raycast::Clock,
                            Traversal::Persistent => {
                                matches!(layout, Layout::Bvh2 | Layout::Bvh4) && kind == Raycast::Closest
                            }
                            _ => {
                                matches!(kind, Raycast::Closest | Raycast::Stats)
                                    && matches!(layout, Layout::Bvh2 | Layout::Bvh4 | Layout::Bvh8)
                            }
                        };
                        assert_eq!(k.is_ok(), expected, "{m} {layout} {kind} {t}");
                        if let Ok(k) = k {
                            assert_eq!(k.layout, layout.name(), "{}", k.name);
                            reached.push(k.name);
                        }
                        assert!(m.traversal_kernel(kind, AccessPath::Address, layout, t).is_err());
                    }
                }
            }
        }
        for k in KERNELS.iter().filter(|k| k.kernel.starts_with("raycast")) {
            assert!(reached.contains(&k.name), "{} cannot be asked for by kind and access path", k.name);
        }
    }
}
