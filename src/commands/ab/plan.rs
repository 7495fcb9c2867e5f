//! What the rounds run: the cells both sides ran, matched by what they are rather than by their
//! place in each side's list, the kernels those cells group into, and whether each round pairs
//! a cell's two sides back to back.

use super::worker::{self, CellInfo};
use crate::error::{Error, Result};

/// The matched cells of a run and how its rounds go.
pub(super) struct Plan<'a> {
    /// Side A's cells and side B's, as each side's worker listed them.
    pub(super) cells: [&'a [CellInfo]; 2],
    pub(super) matching: Matching,
    /// The kernels over the matched cells.
    pub(super) groups: Vec<KernelGroup>,
    /// Both sides speak protocol 2: each cell's two sides run back to back, which side first
    /// alternating, so a moment's load on the host lands on both (paired intervals). An older
    /// worker times whole rounds only: rounds A B B A, unpaired intervals
    /// ([`super::whole_rounds`]).
    pub(super) paired: bool,
}

impl<'a> Plan<'a> {
    /// The plan of two sides that listed `cells` and speak `protocols`; an error when they have
    /// no cell in common.
    pub(super) fn new(cells: [&'a [CellInfo]; 2], protocols: [u32; 2]) -> Result<Plan<'a>> {
        let [cells_a, cells_b] = cells;
        let matching = match_cells(cells_a, cells_b);
        if matching.pairs.is_empty() {
            let labels = |c: &[CellInfo]| c.iter().map(CellInfo::label).collect::<Vec<_>>();
            return Err(Error::Usage(format!(
                "the sides have no cell in common (A: {:?}; B: {:?})",
                labels(cells_a),
                labels(cells_b)
            )));
        }
        let groups = kernel_groups(matching.pairs.iter().map(|&(_, ib)| &cells_b[ib]));
        let paired = protocols.iter().all(|&p| p >= worker::PROTOCOL_CELL);
        Ok(Plan { cells, matching, groups, paired })
    }

    /// (index in A's cells, index in B's) of each matched cell, in B's order.
    pub(super) fn pairs(&self) -> &[(usize, usize)] {
        &self.matching.pairs
    }

    /// Each side's matched cells: with `--b-layout`, B's name the kernel B ran.
    pub(super) fn matched(&self) -> [Vec<CellInfo>; 2] {
        [0, 1]
            .map(|s| self.pairs().iter().map(|&(ia, ib)| [&self.cells[0][ia], &self.cells[1][ib]][s].clone()).collect())
    }

    /// The cells only side A ran, and only side B, by their labels.
    pub(super) fn only_in(&self) -> [Vec<String>; 2] {
        [
            self.matching.only_a.iter().map(|&i| self.cells[0][i].label()).collect(),
            self.matching.only_b.iter().map(|&i| self.cells[1][i].label()).collect(),
        ]
    }
}

/// How the two sides' cells pair up.
#[derive(Debug, Default, PartialEq)]
pub(super) struct Matching {
    /// (index in A's cells, index in B's), in B's order.
    pairs: Vec<(usize, usize)>,
    only_a: Vec<usize>,
    only_b: Vec<usize>,
    /// Cells both name that are not the same work (other ray counts): not compared.
    pub(super) mismatched: Vec<String>,
}

/// Pairs the cells of the two sides by [`CellInfo::key`]: a newer build may add cells (a new
/// method), drop some or list them in another order, and still be timed against an older one
/// on the cells both run. A cell both name but whose work differs (another ray count: the
/// builds generate other rays) is not compared, and named.
fn match_cells(a: &[CellInfo], b: &[CellInfo]) -> Matching {
    let index: std::collections::HashMap<_, usize> = a.iter().enumerate().map(|(i, c)| (c.key(), i)).collect();
    let mut m = Matching::default();
    let mut used = vec![false; a.len()];
    for (ib, c) in b.iter().enumerate() {
        match index.get(&c.key()) {
            Some(&ia) if a[ia].rays == c.rays => {
                used[ia] = true;
                m.pairs.push((ia, ib));
            }
            Some(&ia) => {
                used[ia] = true;
                m.mismatched.push(format!(
                    "{}: A traced {} rays, B {} (the builds made other rays)",
                    c.label(),
                    a[ia].rays,
                    c.rays
                ));
            }
            None => m.only_b.push(ib),
        }
    }
    m.only_a = (0..a.len()).filter(|&i| !used[i]).collect();
    m
}

/// A kernel's cells ([`CellInfo::kernel_label`]) among the matched cells.
pub(super) struct KernelGroup {
    pub(super) kernel: String,
    /// Its first cell (the kernel's kind, method, layout and traversal).
    pub(super) first: CellInfo,
    /// Indices into the matched cells.
    pub(super) members: Vec<usize>,
}

fn kernel_groups<'c>(cells: impl Iterator<Item = &'c CellInfo>) -> Vec<KernelGroup> {
    let mut groups: Vec<KernelGroup> = vec![];
    for (p, c) in cells.enumerate() {
        let k = c.kernel_label();
        match groups.iter_mut().find(|g| g.kernel == k) {
            Some(g) => g.members.push(p),
            None => groups.push(KernelGroup { kernel: k, first: c.clone(), members: vec![p] }),
        }
    }
    groups
}

#[cfg(test)]
mod tests {
    use super::super::worker::CellKind;
    use super::*;

    fn cell(method: &str, set: &str, rays: usize) -> CellInfo {
        CellInfo {
            kind: CellKind::Raycast,
            scene: "bunny".into(),
            set: set.into(),
            method: method.into(),
            layout: "bvh2".into(),
            traversal: "while-if".into(),
            rays,
            kernel: format!("raycast.{method}.closest"),
            coordinates: crate::rows::cell([("method", method), ("set", set)]),
        }
    }

    #[test]
    fn cells_pair_by_what_they_are_whatever_each_build_lists() {
        // B lists the cells in another order, adds a method and made other rays for one cell.
        let a = [cell("mt", "primary", 100), cell("mt", "random", 50), cell("unit", "primary", 100)];
        let mut renamed = cell("unit", "primary", 100);
        renamed.kernel = "raycast.unit.closest_v2".into();
        renamed.coordinates = crate::rows::cell([("method", "unit"), ("set", "primary"), ("new", "axis")]);
        let b = [renamed, cell("mt", "primary", 100), cell("quad-mt", "primary", 100), cell("mt", "random", 60)];
        let m = match_cells(&a, &b);
        assert_eq!(m.pairs, [(2, 0), (0, 1)], "{m:?}");
        assert_eq!((m.only_a.as_slice(), m.only_b.as_slice()), (&[][..], &[2usize][..]));
        assert_eq!(m.mismatched.len(), 1, "{m:?}");
        assert!(m.mismatched[0].contains("bunny random mt bvh2") && m.mismatched[0].contains("A traced 50 rays, B 60"));
        // Cells a build of protocol 1 names (no traversal field) are while-if's.
        let old: CellInfo = serde_json::from_str(
            r#"{"kind":"raycast","scene":"bunny","set":"primary","method":"mt","layout":"bvh2","rays":100,
                "kernel":"raycast.mt.closest","coordinates":{"method":"mt","set":"primary"}}"#,
        )
        .unwrap();
        assert_eq!(old.key(), cell("mt", "primary", 100).key());
    }

    #[test]
    fn kernels_group_cells_by_kind_method_layout_and_traversal() {
        let mut ww = cell("mt", "primary", 10);
        ww.traversal = "while-while".into();
        let cells = [cell("mt", "primary", 10), cell("mt", "random", 10), ww, cell("unit", "primary", 10)];
        let g = kernel_groups(cells.iter());
        let got: Vec<(&str, &[usize])> = g.iter().map(|g| (g.kernel.as_str(), g.members.as_slice())).collect();
        assert_eq!(
            got,
            [
                ("raycast mt bvh2", &[0usize, 1][..]),
                ("raycast mt bvh2 while-while", &[2][..]),
                ("raycast unit bvh2", &[3][..])
            ]
        );
    }
}
