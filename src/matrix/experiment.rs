//! The whole experiment: scenes x leaf sizes (a group: one BVH built) x ray sets x kernel cells
//! x ray orders, crossed in one place, in one order.

use std::path::PathBuf;

use crate::rays::order::RayOrder;
use crate::services::rayset::RaySet;

use super::axes::KernelAxes;
use super::cell::KernelCell;

/// The values a command asks for on every axis of its matrix. The kernel axes are
/// [`KernelAxes`]; here are the axes around them:
///
/// - `scenes`: each a path or a scene's name, as `--scenes` gives it. None: the command brings
///   its own geometry (accuracy's closed meshes), and its groups name no scene;
/// - `leaf_sizes`: the BVH's largest leaf; none is [`crate::defaults::LEAF_SIZE`] alone;
/// - `sets`: the ray sets a cell is measured on. None: a cell is not per set (the study measures
///   every set inside one cell), and [`Experiment::cells`] gives the kernel cells alone.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Experiment {
    pub scenes: Vec<PathBuf>,
    pub leaf_sizes: Vec<u32>,
    pub sets: Vec<RaySet>,
    pub kernels: KernelAxes,
}

/// A group of cells: one scene (none where the command brings its own geometry) at one leaf
/// size: one BVH built, what a shard takes whole. The indices are the scene's and the leaf
/// size's places on their axes (what `services::shard::Split` counts in).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Group {
    pub scene: Option<PathBuf>,
    pub scene_index: usize,
    pub leaf: u32,
    pub leaf_index: usize,
}

impl Group {
    /// The scene's name in rows and progress lines (`crate::scene::scene_name`), if it has one.
    pub fn scene_name(&self) -> Option<String> {
        self.scene.as_deref().map(crate::scene::scene_name)
    }
}

/// One cell of the matrix: a group, the ray set (none where cells are not per set), the kernel
/// and the order its rays are dispatched in.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Cell {
    pub group: Group,
    pub set: Option<RaySet>,
    pub kernel: KernelCell,
    pub order: RayOrder,
}

impl Experiment {
    /// The leaf sizes asked for, or the default alone.
    pub fn leaf_sizes(&self) -> Vec<u32> {
        match self.leaf_sizes.is_empty() {
            true => vec![crate::defaults::LEAF_SIZE],
            false => self.leaf_sizes.clone(),
        }
    }

    /// Every group, scene major: each scene (or one scene-less group) at each leaf size.
    pub fn groups(&self) -> Vec<Group> {
        let scenes: Vec<Option<PathBuf>> = match self.scenes.is_empty() {
            true => vec![None],
            false => self.scenes.iter().cloned().map(Some).collect(),
        };
        let leaves = self.leaf_sizes();
        let mut out = vec![];
        for (scene_index, scene) in scenes.into_iter().enumerate() {
            for (leaf_index, &leaf) in leaves.iter().enumerate() {
                out.push(Group { scene: scene.clone(), scene_index, leaf, leaf_index });
            }
        }
        out
    }

    /// Every cell, in the order a plan lists them: group, ray set, kernel cell
    /// ([`KernelAxes::kernels`]: the registry's filter), ray order. Where there is no ray-set
    /// axis each group's cells are its kernel cells at the default ray order.
    pub fn cells(&self) -> Vec<Cell> {
        let kernels = self.kernels.kernels();
        let sets: Vec<Option<RaySet>> = match self.sets.is_empty() {
            true => vec![None],
            false => self.sets.iter().copied().map(Some).collect(),
        };
        let orders = match self.sets.is_empty() {
            true => vec![RayOrder::DEFAULT],
            false => self.kernels.orders(),
        };
        let mut out = vec![];
        for group in self.groups() {
            for &set in &sets {
                for &kernel in &kernels {
                    for &order in &orders {
                        out.push(Cell { group: group.clone(), set, kernel, order });
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encoding::{Layout, Method};

    fn bvh4() -> Layout {
        "bvh4".parse().unwrap()
    }

    #[test]
    fn cells_cross_every_axis_scene_major() {
        let e = Experiment {
            scenes: vec!["bunny".into(), "dragon".into()],
            leaf_sizes: vec![1, 8],
            sets: vec![RaySet::Primary, RaySet::Random],
            kernels: KernelAxes {
                methods: vec![Method::Mt, Method::QuadUnit],
                layouts: vec![Layout::DEFAULT, bvh4()],
                ..Default::default()
            },
        };
        let cells = e.cells();
        // 2 scenes x 2 leaf sizes x 2 sets x 2 methods x 2 layouts, each kernel on each layout.
        assert_eq!(cells.len(), 32);
        let first = &cells[0];
        assert_eq!(first.group.scene_name().as_deref(), Some("bunny"));
        assert_eq!((first.group.leaf, first.set), (1, Some(RaySet::Primary)));
        assert_eq!((first.kernel.method, first.kernel.layout), (Method::Mt, Layout::DEFAULT));
        assert_eq!((cells[1].kernel.method, cells[1].kernel.layout), (Method::Mt, bvh4()));
        assert_eq!(cells[4].set, Some(RaySet::Random));
        assert_eq!(cells[8].group.leaf, 8);
        assert_eq!((cells[16].group.scene_index, cells[16].group.leaf_index), (1, 0));
        assert_eq!(cells[31].group.scene_name().as_deref(), Some("dragon"));
    }

    #[test]
    fn empty_axes_take_their_defaults_or_are_not_crossed() {
        let e = Experiment {
            kernels: KernelAxes { methods: vec![Method::Unit], ..Default::default() },
            ..Default::default()
        };
        let groups = e.groups();
        assert_eq!(groups.len(), 1);
        assert_eq!((groups[0].scene.clone(), groups[0].leaf), (None, crate::defaults::LEAF_SIZE));
        let cells = e.cells();
        assert_eq!(cells.len(), 1);
        assert_eq!((cells[0].set, cells[0].order), (None, RayOrder::DEFAULT));
        // Ray orders are crossed only with ray sets: a cell without a set measures every set.
        let octant: RayOrder = "octant-origin".parse().unwrap();
        let ordered = Experiment {
            kernels: KernelAxes { orders: vec![RayOrder::DEFAULT, octant], ..e.kernels.clone() },
            ..e.clone()
        };
        assert_eq!(ordered.cells().len(), 1);
        let per_set = Experiment { sets: vec![RaySet::Diffuse], ..ordered };
        assert_eq!(per_set.cells().iter().map(|c| c.order).collect::<Vec<_>>(), [RayOrder::DEFAULT, octant]);
    }
}
