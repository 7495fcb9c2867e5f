//! One kernel cell of the matrix, and its name.

use std::fmt;

use crate::bvh::NodeOrder;
use crate::encoding::{AccessPath, Layout, Method, Raycast, SceneAccess, Traversal};
use crate::pipeline::SceneRequest;
use crate::rays::order::RayOrder;

/// What traces a cell's rays: a method's kernel walking a layout with a traversal, over a scene
/// read as `access` asks, with its nodes in `node_order`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KernelCell {
    pub method: Method,
    pub layout: Layout,
    pub traversal: Traversal,
    pub access: SceneAccess,
    pub node_order: NodeOrder,
}

impl KernelCell {
    /// The scene the cell's kernel reads.
    pub fn request(&self) -> SceneRequest {
        SceneRequest::new(self.method)
            .access(self.access)
            .layout(self.layout)
            .traversal(self.traversal)
            .node_order(self.node_order)
    }

    /// The paths a scene asked for as `access` may be read through: the one named, or for
    /// `auto` any of them (the scene's memory placement chooses; `encoding::placement`).
    pub fn paths(access: SceneAccess) -> &'static [AccessPath] {
        match access {
            SceneAccess::Auto => &AccessPath::ALL,
            SceneAccess::Texel => &[AccessPath::Texel],
            SceneAccess::Address => &[AccessPath::Address],
            SceneAccess::Storage => &[AccessPath::Storage],
        }
    }

    /// The path a planned cell names: the one asked for, or none for `auto` (measured: the row
    /// names the path the scene took).
    pub fn planned_path(&self) -> Option<AccessPath> {
        match Self::paths(self.access) {
            [one] => Some(*one),
            _ => None,
        }
    }

    /// Whether the registry holds a closest-hit kernel of this method, layout and traversal on
    /// a path the cell's scene may be read through (the traversal's support does not depend on
    /// the method: `encoding::variants`' test holds it).
    pub fn has_kernel(method: Method, layout: Layout, traversal: Traversal, access: SceneAccess) -> bool {
        Self::paths(access).iter().any(|&p| method.traversal_kernel(Raycast::Closest, p, layout, traversal).is_ok())
    }

    /// [`KernelCell::has_kernel`] for this cell.
    pub fn exists(&self) -> bool {
        Self::has_kernel(self.method, self.layout, self.traversal, self.access)
    }

    /// Its name in progress lines, when its scene is read through `path` and its rays dispatched
    /// in `order`.
    pub fn label(&self, path: AccessPath, order: RayOrder) -> KernelLabel {
        KernelLabel {
            method: self.method,
            layout: Some(self.layout),
            traversal: self.traversal,
            node_order: self.node_order,
            order,
            access: path,
        }
    }
}

/// A kernel's name: the method, then its layout (where given and not the default: progress
/// lines; tables give the layout a column), traversal, node order, ray order and access path
/// where they are not the defaults (`quad-unit bvh4 while-while treelets nodes octant-origin
/// address`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KernelLabel {
    pub method: Method,
    pub layout: Option<Layout>,
    pub traversal: Traversal,
    pub node_order: NodeOrder,
    pub order: RayOrder,
    pub access: AccessPath,
}

impl fmt::Display for KernelLabel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.method)?;
        if let Some(l) = self.layout.filter(|&l| l != Layout::DEFAULT) {
            write!(f, " {l}")?;
        }
        if self.traversal != Traversal::DEFAULT {
            write!(f, " {}", self.traversal)?;
        }
        if self.node_order != NodeOrder::DEFAULT {
            write!(f, " {} nodes", self.node_order)?;
        }
        if self.order != RayOrder::DEFAULT {
            write!(f, " {}", self.order)?;
        }
        if self.access != AccessPath::Texel {
            write!(f, " {}", self.access.name())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_label_names_only_what_is_not_the_default() {
        let cell = KernelCell {
            method: Method::QuadUnit,
            layout: Layout::DEFAULT,
            traversal: Traversal::DEFAULT,
            access: SceneAccess::Auto,
            node_order: NodeOrder::DEFAULT,
        };
        assert_eq!(cell.label(AccessPath::Texel, RayOrder::DEFAULT).to_string(), "quad-unit");
        let bvh4: Layout = "bvh4".parse().unwrap();
        let wide = KernelCell { layout: bvh4, traversal: "while-while".parse().unwrap(), ..cell };
        let octant: RayOrder = "octant-origin".parse().unwrap();
        assert_eq!(
            wide.label(AccessPath::Address, octant).to_string(),
            "quad-unit bvh4 while-while octant-origin address"
        );
        let tables = KernelLabel { layout: None, ..wide.label(AccessPath::Texel, RayOrder::DEFAULT) };
        assert_eq!(tables.to_string(), "quad-unit while-while");
    }

    #[test]
    fn auto_names_no_path_in_a_plan_and_may_take_any() {
        assert_eq!(KernelCell::paths(SceneAccess::Auto), &AccessPath::ALL);
        let cell = |access| KernelCell {
            method: Method::Mt,
            layout: Layout::DEFAULT,
            traversal: Traversal::DEFAULT,
            access,
            node_order: NodeOrder::DEFAULT,
        };
        assert_eq!(cell(SceneAccess::Auto).planned_path(), None);
        assert_eq!(cell(SceneAccess::Address).planned_path(), Some(AccessPath::Address));
        assert_eq!(cell(SceneAccess::Texel).planned_path(), Some(AccessPath::Texel));
    }
}
