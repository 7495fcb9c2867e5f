//! A method's compiled kernels, by what they compute rather than by name: a ray-casting kernel
//! is asked for by its [`RaycastKey`] (method, kind, access path, layout, traversal), a
//! path-tracing kernel by its [`PathtraceKey`] (method, BSDFs carried, layout), and the layout
//! probe by its method: each a [`KernelKey`].
//!
//! build.rs emits every kernel's key (`kernel_key` there, from what the variant is compiled with)
//! beside the registry (`crate::kernels`), in its order; [`KernelKey::of`] reads a kernel's,
//! [`KernelKey::source`] finds a key's kernel, and nothing reads a variant's name.
//! [`RaycastKey::all`] is the support matrix every other place reads (the pipeline, `trilab
//! methods --traversals`, the CLI's help, ARCHITECTURE.md's table, the tests).

use std::collections::HashMap;
use std::sync::OnceLock;

use super::{AccessPath, Layout, Method};
use crate::error::{Error, Result};
use crate::kernels::{KernelSource, KERNELS};
use crate::named::{named_enum, Named};
use crate::scene::BsdfKind;

named_enum! {
    /// What a ray-casting kernel computes per ray (the variants of `glsl/raycast.comp`).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum Raycast: "raycast variant" {
        /// The closest hit.
        Closest = "closest",
        /// Any hit in [tmin, tmax] (occlusion).
        Any = "any",
        /// The closest hit and the ray's traversal work (`TRAVERSAL_STATS`, `glsl/counts.glsl`).
        Stats = "stats",
        /// The closest hit and the shader-clock ticks around its traversal (`trilab profile`).
        Clock = "clock",
    }
}

named_enum! {
    /// How a ray-casting kernel walks the tree (issue 15: traversals measured side by side).
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum Traversal: "traversal" {
        /// One ray per invocation, stack-based while-if, nearest child first (glsl/traversal/while_if.glsl,
        /// glsl/layout/).
        WhileIf = "while-if" (default),
        /// One ray per invocation, Aila & Laine's while-while with leaf postponing (HPG 2009;
        /// glsl/traversal/while_while.glsl).
        WhileWhile = "while-while",
        /// The subgroup traces one ray at a time, a child box and a leaf triangle per lane (Lier,
        /// Stamminger & Selgrad, HPG 2018; glsl/raycast_coop.comp).
        Coop = "coop",
        /// Persistent threads with dynamic ray fetch (Aila & Laine, HPG 2009): a fixed number of
        /// workgroups, each invocation takes ray indices from an atomic counter and starts the
        /// next ray inside the traversal loop (glsl/raycast_persistent.comp).
        Persistent = "persistent",
        /// Packets: the subgroup's lanes walk one path together, each with its own ray, on one
        /// shared stack, so a node's loads are uniform (Wald et al., EG 2001;
        /// glsl/raycast_packet.comp).
        Packet = "packet",
        /// Packets while enough lanes take part in a node, then each ray alone with while-if on
        /// the same stack (Benthin et al., TVCG 2012; glsl/raycast_packet.comp's HYBRID).
        Hybrid = "hybrid",
    }
}

impl Traversal {
    /// The lanes of a subgroup walk one path together (packets, and the hybrid until it lets
    /// them go), so a ray's walk, and its traversal counts, depend on which rays share its
    /// subgroup: on the order the rays are dispatched in. Every other traversal walks a ray's
    /// path whatever its neighbours.
    pub fn walks_together(self) -> bool {
        matches!(self, Traversal::Packet | Traversal::Hybrid)
    }
}

/// `VkSubgroupFeatureFlags` the cooperative kernel uses: basic, vote, arithmetic, ballot,
/// shuffle.
pub const COOP_SUBGROUP_OPERATIONS: u32 = 0x1 | 0x2 | 0x4 | 0x8 | 0x10;

/// `VkSubgroupFeatureFlags` the packet kernel uses: basic, vote, arithmetic, ballot, shuffle.
pub const PACKET_SUBGROUP_OPERATIONS: u32 = 0x1 | 0x2 | 0x4 | 0x8 | 0x10;

/// A ray-casting kernel by what it computes and how: the key the pipeline asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct RaycastKey {
    pub method: Method,
    pub kind: Raycast,
    pub access: AccessPath,
    pub layout: Layout,
    pub traversal: Traversal,
}

/// A compiled kernel by what it computes: the typed key build.rs emits for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum KernelKey {
    /// A ray-casting kernel (`glsl/raycast*.comp`).
    Raycast(RaycastKey),
    /// A path-tracing kernel (`glsl/pathtrace.comp`).
    Pathtrace(PathtraceKey),
    /// A method's layout probe (`glsl/probe.comp`).
    Probe(Method),
}

include!(concat!(env!("OUT_DIR"), "/kernel_keys.rs"));

/// Every key's kernel.
fn by_key() -> &'static HashMap<KernelKey, &'static KernelSource> {
    static BY_KEY: OnceLock<HashMap<KernelKey, &'static KernelSource>> = OnceLock::new();
    BY_KEY.get_or_init(|| KERNELS.iter().filter_map(|k| KernelKey::of(k).map(|key| (key, k))).collect())
}

impl KernelKey {
    /// The key build.rs emitted for a registry entry; `None` for a kernel without one (the
    /// ray-query peer, the roofline, the probes without an intersector: `kernels::find`).
    pub fn of(k: &KernelSource) -> Option<KernelKey> {
        KEYS[k.id]
    }

    /// The kernel of this key, where the registry holds one.
    pub fn source(self) -> Option<&'static KernelSource> {
        by_key().get(&self).copied()
    }

    /// Every key the registry holds that `pick` takes, sorted.
    fn all<K: Ord>(pick: fn(KernelKey) -> Option<K>) -> Vec<K> {
        let mut keys: Vec<K> = KEYS.iter().flatten().filter_map(|&k| pick(k)).collect();
        keys.sort();
        keys
    }

    fn raycast(self) -> Option<RaycastKey> {
        match self {
            KernelKey::Raycast(key) => Some(key),
            _ => None,
        }
    }

    fn pathtrace(self) -> Option<PathtraceKey> {
        match self {
            KernelKey::Pathtrace(key) => Some(key),
            _ => None,
        }
    }
}

impl RaycastKey {
    /// The key of a registry entry; `None` for a kernel that is not ray casting (the path
    /// tracer, the probes).
    pub fn of(k: &KernelSource) -> Option<RaycastKey> {
        KernelKey::of(k)?.raycast()
    }

    /// Every ray-casting key the registry holds, sorted: the support matrix.
    pub fn all() -> Vec<RaycastKey> {
        KernelKey::all(KernelKey::raycast)
    }

    /// The kernel of this key, or an error saying what this traversal has instead.
    pub fn source(self) -> Result<&'static KernelSource> {
        KernelKey::Raycast(self).source().ok_or_else(|| {
            Error::Usage(format!(
                "no {} kernel: the {} traversal has no `{}` kernel for the {} layout on the {} path (it has: {})",
                self.method.name(),
                self.traversal,
                self.kind,
                self.layout,
                self.access.name(),
                support(self.traversal)
            ))
        })
    }
}

/// What `traversal` has kernels for, as one line: `bvh2, bvh4; texel path; closest, any` (the
/// same for every method, which the tests hold).
pub fn support(traversal: Traversal) -> String {
    use std::collections::BTreeSet;
    let keys: Vec<RaycastKey> =
        RaycastKey::all().into_iter().filter(|k| k.traversal == traversal && k.method == Method::ALL[0]).collect();
    let layouts: BTreeSet<Layout> = keys.iter().map(|k| k.layout).collect();
    let access: BTreeSet<AccessPath> = keys.iter().map(|k| k.access).collect();
    let kinds: BTreeSet<Raycast> = keys.iter().map(|k| k.kind).collect();
    let join = |v: Vec<&str>, sep: &str| v.join(sep);
    format!(
        "{}; {} path{}; {}",
        join(layouts.iter().map(|l| l.name()).collect(), ", "),
        join(access.iter().map(|a| a.name()).collect(), ", "),
        if access.len() > 1 { "s" } else { "" },
        join(kinds.iter().map(|k| k.name()).collect(), ", ")
    )
}

/// The support matrix as a Markdown table, one row per traversal (ARCHITECTURE.md holds it,
/// checked by `tests/readme.rs`).
pub fn support_table() -> String {
    let mut s = String::from("| traversal | layouts; access paths; kinds |\n|---|---|\n");
    for &t in Traversal::ALL {
        s += &format!("| `{t}` | {} |\n", support(t));
    }
    s
}

/// The kernels a reader studies, whose disassembly `spirv/` keeps, in the registry's order: the
/// paper's study (every method's closest-hit and any-hit kernels on the default layout), the
/// layouts study's (closest hit on every other layout), both with the default traversal on the
/// texel path, and the ray-query peer.
pub fn studied() -> Vec<&'static KernelSource> {
    let study = |key: RaycastKey| {
        (key.traversal, key.access) == (Traversal::DEFAULT, AccessPath::Texel)
            && (key.kind == Raycast::Closest || (key.kind == Raycast::Any && key.layout == Layout::DEFAULT))
    };
    KERNELS.iter().filter(|k| RaycastKey::of(k).map_or(k.kernel == "rayquery", study)).collect()
}

/// The kernels whose disassembly a review folder holds (`crate::spirv::review_files`).
pub fn disassembled(which: crate::spirv::Disassembly) -> Vec<&'static KernelSource> {
    match which {
        crate::spirv::Disassembly::Studied => studied(),
        crate::spirv::Disassembly::All => KERNELS.iter().collect(),
    }
}

/// The BSDFs a path-tracing kernel carries: every one (`all`: the specialisation constant narrows
/// them to a scene's), or one (its single-BSDF variant, named as the BSDF's GLSL file).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BsdfSet {
    All,
    One(BsdfKind),
}

/// A path-tracing kernel (`glsl/pathtrace.comp`) by what it computes: the key render asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PathtraceKey {
    pub method: Method,
    pub bsdfs: BsdfSet,
    pub layout: Layout,
    /// The texel path, or the storage path (`all_storage`: every BSDF only).
    pub access: AccessPath,
}

impl PathtraceKey {
    /// The key of a registry entry; `None` for a kernel that is not the path tracer.
    pub fn of(k: &KernelSource) -> Option<PathtraceKey> {
        KernelKey::of(k)?.pathtrace()
    }

    /// Every path-tracing key the registry holds, sorted.
    pub fn all() -> Vec<PathtraceKey> {
        KernelKey::all(KernelKey::pathtrace)
    }

    /// The kernel of this key, or an error naming the key.
    pub fn source(self) -> Result<&'static KernelSource> {
        KernelKey::Pathtrace(self).source().ok_or_else(|| {
            let bsdfs = match self.bsdfs {
                BsdfSet::All => "every BSDF".to_owned(),
                BsdfSet::One(b) => format!("the {} BSDF alone", b.name()),
            };
            Error::Usage(format!(
                "no {} path-tracing kernel for {bsdfs} on the {} layout on the {} path (the wide layouts and the \
                 storage path have the all-BSDF kernel only)",
                self.method.name(),
                self.layout,
                self.access.name()
            ))
        })
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
        RaycastKey { method: self, kind, access, layout, traversal }.source()
    }

    /// The ray-casting kernel of the default traversal (while-if) computing `kind` over a scene
    /// read through `access` with its nodes in `layout`.
    pub fn layout_kernel(self, kind: Raycast, access: AccessPath, layout: Layout) -> Result<&'static KernelSource> {
        self.traversal_kernel(kind, access, layout, Traversal::DEFAULT)
    }

    /// The ray-casting kernel computing `kind` over a scene read through `access` (the default
    /// layout: binary nodes).
    pub fn raycast_kernel(self, kind: Raycast, access: AccessPath) -> &'static KernelSource {
        self.layout_kernel(kind, access, Layout::DEFAULT).unwrap_or_else(|e| panic!("{e}"))
    }

    /// The layout probe (`glsl/probe.comp`): copies nodes, primitives and slot ids out through the
    /// kernels' own loaders.
    pub fn probe_kernel(self) -> &'static KernelSource {
        KernelKey::Probe(self)
            .source()
            .unwrap_or_else(|| panic!("no probe kernel of {self} was compiled (glsl/probe.comp)"))
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
                for access in AccessPath::ALL {
                    // The storage path (issue 38) serves devices without a shader clock.
                    let k = m.layout_kernel(kind, access, Layout::Bvh2);
                    assert_eq!(
                        k.is_ok(),
                        access != AccessPath::Storage || kind != Raycast::Clock,
                        "{m} {kind} {access:?}"
                    );
                    let Ok(k) = k else { continue };
                    assert_eq!((k.kernel, k.intersector), ("raycast", m.glsl_name()));
                    reached.push(k.name);
                }
            }
            assert_eq!(m.probe_kernel().kernel, "probe");
            // The path tracer: every BSDF alone and all of them on the binary nodes, all of them on
            // every other layout.
            for &layout in Layout::ALL {
                for access in [AccessPath::Texel, AccessPath::Storage] {
                    let all = PathtraceKey { method: m, bsdfs: BsdfSet::All, layout, access };
                    assert!(all.source().is_ok(), "{m} {layout} {access:?}");
                    for b in BsdfKind::ALL {
                        let k = PathtraceKey { method: m, bsdfs: BsdfSet::One(b), layout, access };
                        let want = layout == Layout::Bvh2 && access == AccessPath::Texel;
                        assert_eq!(k.source().is_ok(), want, "{m} {layout} {} {access:?}", b.name());
                    }
                }
            }
        }
        // Every layout has every kind on the texel and address paths and all but the clock on the
        // storage path, named after it.
        for m in Method::ALL {
            for &layout in Layout::ALL {
                for &kind in Raycast::ALL {
                    for access in AccessPath::ALL {
                        if access == AccessPath::Storage && kind == Raycast::Clock {
                            assert!(m.layout_kernel(kind, access, layout).is_err());
                            continue;
                        }
                        let k = m.layout_kernel(kind, access, layout).unwrap();
                        assert_eq!(k.layout, layout.name(), "{}", k.name);
                        reached.push(k.name);
                    }
                }
            }
        }
        // The other traversals: while-while on the binary nodes (closest, any, stats), the
        // cooperative kernel on every layout that gives a step, all but cwbvh (closest, stats; it
        // reads their node formats through layout_interface.glsl, and cwbvh's traversal is its
        // own); persistent threads on the same layouts (closest); packets on the same layouts
        // (closest, any, stats; texel and storage paths); the others on the texel path only.
        for m in Method::ALL {
            for &layout in Layout::ALL {
                for &kind in Raycast::ALL {
                    for t in [
                        Traversal::WhileWhile,
                        Traversal::Coop,
                        Traversal::Persistent,
                        Traversal::Packet,
                        Traversal::Hybrid,
                    ] {
                        let k = m.traversal_kernel(kind, AccessPath::Texel, layout, t);
                        let expected = match t {
                            Traversal::WhileWhile => layout == Layout::Bvh2 && kind != Raycast::Clock,
                            Traversal::Persistent => layout != Layout::Cwbvh && kind == Raycast::Closest,
                            Traversal::Packet | Traversal::Hybrid => layout != Layout::Cwbvh && kind != Raycast::Clock,
                            _ => matches!(kind, Raycast::Closest | Raycast::Stats) && layout != Layout::Cwbvh,
                        };
                        assert_eq!(k.is_ok(), expected, "{m} {layout} {kind} {t}");
                        if let Ok(k) = k {
                            assert_eq!(k.layout, layout.name(), "{}", k.name);
                            reached.push(k.name);
                        }
                        assert!(m.traversal_kernel(kind, AccessPath::Address, layout, t).is_err());
                        // Packets read storage buffers too (uniform loads: issue 53).
                        let storage = m.traversal_kernel(kind, AccessPath::Storage, layout, t);
                        assert_eq!(
                            storage.is_ok(),
                            expected && t == Traversal::Packet,
                            "{m} {layout} {kind} {t} storage"
                        );
                        if let Ok(k) = storage {
                            reached.push(k.name);
                        }
                    }
                }
            }
        }
        for k in KERNELS.iter().filter(|k| k.kernel.starts_with("raycast")) {
            assert!(reached.contains(&k.name), "{} cannot be asked for by kind and access path", k.name);
            // Its key finds it again.
            let key = RaycastKey::of(k).unwrap_or_else(|| panic!("{}: no key", k.name));
            assert_eq!(key.source().unwrap().name, k.name);
        }
        for k in KERNELS.iter().filter(|k| k.kernel == "pathtrace") {
            let key = PathtraceKey::of(k).unwrap_or_else(|| panic!("{}: no key", k.name));
            assert_eq!(key.source().unwrap().name, k.name);
        }
        // Every kernel with an intersector has a key (build.rs's), and its key finds it again;
        // those without one are found by file and variant (`kernels::find`).
        for k in KERNELS {
            match KernelKey::of(k) {
                Some(key) => assert!(std::ptr::eq(key.source().unwrap(), k), "{}: {key:?}", k.name),
                None => assert_eq!(k.intersector, crate::kernels::NO_INTERSECTOR, "{}: no key", k.name),
            }
        }
        // Every method has the same kernels (what `support` and the CLI's help assume).
        let shape = |m: Method| -> Vec<_> {
            RaycastKey::all()
                .into_iter()
                .filter(|k| k.method == m)
                .map(|k| (k.kind, k.access, k.layout, k.traversal))
                .collect()
        };
        for m in Method::ALL {
            assert_eq!(shape(m), shape(Method::ALL[0]), "{m}");
        }
        // What spirv/ keeps: every method's closest hit on every layout and any hit on the
        // default one (while-if, texel path), and the ray-query peer's two.
        let studied = studied();
        assert_eq!(studied.len(), Method::ALL.len() * (Layout::ALL.len() + 1) + 2);
        assert!(studied.iter().filter_map(|k| RaycastKey::of(k)).all(|k| k.traversal == Traversal::WhileIf));
        assert_eq!(studied.iter().filter(|k| k.kernel == "rayquery").count(), 2);
        assert_eq!(support(Traversal::Persistent), "bvh2, bvh4, bvh8, qbvh4; texel path; closest");
        assert_eq!(support(Traversal::WhileWhile), "bvh2; texel path; closest, any, stats");
        assert_eq!(support(Traversal::Packet), "bvh2, bvh4, bvh8, qbvh4; texel, storage paths; closest, any, stats");
        assert_eq!(support(Traversal::Hybrid), "bvh2, bvh4, bvh8, qbvh4; texel path; closest, any, stats");
        assert_eq!(
            support(Traversal::WhileIf),
            "bvh2, bvh4, bvh8, cwbvh, qbvh4; texel, address, storage paths; closest, any, stats, clock"
        );
    }
}
