//! The kernel axes a measurement crosses, with their defaults and the two filters: what the
//! device runs and what the registry holds.

use crate::bvh::NodeOrder;
use crate::encoding::{Layout, Method, SceneAccess, Traversal};
use crate::error::Result;
use crate::gpu::Capabilities;
use crate::rays::order::RayOrder;

use super::cell::KernelCell;

/// The values asked for on each kernel axis. An empty axis means its default alone: it is
/// applied by [`KernelAxes::resolved`] and read through the accessors, never spelled by a caller.
/// `methods` has no default here: each command has its own set (bench and the study every
/// method the device runs, the suite the paper's).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KernelAxes {
    pub methods: Vec<Method>,
    pub layouts: Vec<Layout>,
    pub traversals: Vec<Traversal>,
    pub access: Vec<SceneAccess>,
    pub node_orders: Vec<NodeOrder>,
    pub orders: Vec<RayOrder>,
}

/// An axis's values, or its default alone when none was asked for.
fn values<T: Copy + Default>(v: &[T]) -> Vec<T> {
    match v.is_empty() {
        true => vec![T::default()],
        false => v.to_vec(),
    }
}

impl KernelAxes {
    /// The same axes with every empty one (but `methods`) holding its default.
    pub fn resolved(&self) -> KernelAxes {
        KernelAxes {
            methods: self.methods.clone(),
            layouts: self.layouts(),
            traversals: self.traversals(),
            access: self.access(),
            node_orders: self.node_orders(),
            orders: self.orders(),
        }
    }

    pub fn layouts(&self) -> Vec<Layout> {
        values(&self.layouts)
    }

    pub fn traversals(&self) -> Vec<Traversal> {
        values(&self.traversals)
    }

    pub fn access(&self) -> Vec<SceneAccess> {
        values(&self.access)
    }

    pub fn node_orders(&self) -> Vec<NodeOrder> {
        values(&self.node_orders)
    }

    pub fn orders(&self) -> Vec<RayOrder> {
        values(&self.orders)
    }

    /// The device's filter: the methods, traversals and access paths `caps` cannot run are
    /// left out, each with a note giving its reason (an error when an axis keeps nothing).
    pub fn for_device(&self, caps: &Capabilities, notes: &mut Vec<String>) -> Result<KernelAxes> {
        let mut o = self.resolved();
        o.methods = caps.keep("methods", &o.methods, Capabilities::method, notes)?;
        o.traversals = caps.keep("traversals", &o.traversals, Capabilities::traversal, notes)?;
        o.access = caps.keep(
            "scene access paths",
            &o.access,
            // `auto` runs anywhere: the scene's placement takes a path the device has.
            |c, a| match KernelCell::paths(a) {
                [one] => c.access(*one),
                _ => Ok(()),
            },
            notes,
        )?;
        Ok(o)
    }

    /// The registry's filter: every cell asked for whose method, layout and traversal have a
    /// closest-hit kernel on a path its access may take, in the order methods, layouts,
    /// traversals, access paths, node orders.
    pub fn kernels(&self) -> Vec<KernelCell> {
        let mut out = vec![];
        for &method in &self.methods {
            for (layout, traversal, access) in self.combinations() {
                if !KernelCell::has_kernel(method, layout, traversal, access) {
                    continue;
                }
                for node_order in self.node_orders() {
                    out.push(KernelCell { method, layout, traversal, access, node_order });
                }
            }
        }
        out
    }

    /// The layout x traversal x access combinations asked for that have no kernel, a note each.
    pub fn notes(&self) -> Vec<String> {
        let Some(&m) = self.methods.first() else { return vec![] };
        self.combinations()
            .into_iter()
            .filter(|&(l, t, a)| !KernelCell::has_kernel(m, l, t, a))
            .map(|(l, t, a)| {
                let path = match KernelCell::paths(a) {
                    [one] => format!("{} path", one.name()),
                    _ => "any path".to_owned(),
                };
                format!(
                    "{t} traversal on {l} ({path}): not run, no kernel ({t} has: {})",
                    crate::encoding::traversal_support(t)
                )
            })
            .collect()
    }

    /// Every layout x traversal x access asked for.
    fn combinations(&self) -> Vec<(Layout, Traversal, SceneAccess)> {
        let (traversals, access) = (self.traversals(), self.access());
        let mut out = vec![];
        for l in self.layouts() {
            for &t in &traversals {
                for &a in &access {
                    out.push((l, t, a));
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encoding::{AccessPath, Raycast};

    #[test]
    fn an_empty_axis_takes_its_default_alone() {
        let axes = KernelAxes { methods: vec![Method::Mt], ..Default::default() };
        let r = axes.resolved();
        assert_eq!(r.layouts, [Layout::DEFAULT]);
        assert_eq!(r.traversals, [Traversal::DEFAULT]);
        assert_eq!(r.access, [SceneAccess::DEFAULT]);
        assert_eq!(r.node_orders, [NodeOrder::DEFAULT]);
        assert_eq!(r.orders, [RayOrder::DEFAULT]);
        assert_eq!(r.resolved(), r, "resolving twice changes nothing");
        let cells = axes.kernels();
        assert_eq!(cells.len(), 1);
        assert_eq!(cells[0].request().layout, Layout::DEFAULT);
    }

    #[test]
    fn a_combination_without_a_kernel_is_a_note_not_a_cell() {
        let coop: Traversal = "coop".parse().unwrap();
        let axes = KernelAxes {
            methods: vec![Method::Mt, Method::Unit],
            traversals: vec![Traversal::DEFAULT, coop],
            access: vec![SceneAccess::Texel, SceneAccess::Storage],
            ..Default::default()
        };
        let has = |t, a| Method::Mt.traversal_kernel(Raycast::Closest, a, Layout::DEFAULT, t).is_ok();
        let expected: usize = [Traversal::DEFAULT, coop]
            .iter()
            .flat_map(|&t| [AccessPath::Texel, AccessPath::Storage].map(move |a| has(t, a)))
            .filter(|&h| h)
            .count();
        assert!(expected < 4, "the cooperative kernel reads texel buffers only");
        assert_eq!(axes.kernels().len(), 2 * expected);
        let notes = axes.notes();
        assert_eq!(notes.len(), 4 - expected, "{notes:?}");
        assert!(notes.iter().all(|n| n.starts_with("coop traversal on bvh2 (storage path): not run")), "{notes:?}");
    }

    #[test]
    fn auto_is_kept_wherever_some_path_has_the_kernel() {
        // What makes the registry's filter for `auto` exact before a scene is placed: every
        // method, layout and traversal with a kernel on any path has one on the texel path,
        // which auto takes wherever the scene fits it.
        for m in Method::ALL {
            for &l in <Layout as crate::named::Named>::ALL {
                for &t in <Traversal as crate::named::Named>::ALL {
                    let texel = KernelCell::has_kernel(m, l, t, SceneAccess::Texel);
                    assert_eq!(KernelCell::has_kernel(m, l, t, SceneAccess::Auto), texel, "{m} {l} {t}");
                }
            }
        }
    }
}
