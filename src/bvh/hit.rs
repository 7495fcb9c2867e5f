//! The closest hit of the CPU traversals ([`WideBvh::trace`], [`CwBvh::trace`]) and the rule
//! that picks it when two triangles are hit at the same distance.
//!
//! # Equal distances go to the lower triangle id
//!
//! A hit replaces the closest so far when it is nearer, or exactly as near and on a triangle of
//! lower id ([`closer`]). The rule does not depend on the order in which leaves and their
//! triangles are tested, so every CPU walk of one scene returns the same hit bit for bit: the
//! 2-, 4- and 8-wide trees in either collapse, the compressed tree in any slot order, any node
//! order (tested here on a constructed tie), and the f64 reference they are checked against with
//! `==` (`reference::brute_force` keeps the first of equal hits over ascending ids, and
//! `reference::Reference::trace`, the binary tree's walk, calls [`wins`]).
//!
//! The GPU kernels do not break ties this way. Their one leaf loop (`glsl/leaf.glsl`,
//! `intersect_leaf`, used by every layout and traversal; `raycast_coop.comp` reproduces it)
//! accepts a hit at `t <= h.t`, so of equal hits the one tested last wins, which depends on the
//! visiting order. A kernel's hit that ties with the reference's on another triangle is judged
//! by the agreement rule (`agreement`: a different triangle whose hit point is within rounding
//! of the reference's is explained), not by this one.
//!
//! [`WideBvh::trace`]: crate::bvh::WideBvh::trace
//! [`CwBvh::trace`]: crate::bvh::CwBvh::trace

use crate::shared::MISS_ID;

/// A hit of a CPU traversal, in the f64 of the triangle test it was given. `id == MISS_ID` and
/// `t = inf` on a miss.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideHit {
    pub t: f64,
    pub id: u32,
    pub u: f64,
    pub v: f64,
}

impl WideHit {
    pub const MISS: WideHit = WideHit { t: f64::INFINITY, id: MISS_ID, u: 0.0, v: 0.0 };

    pub fn is_hit(&self) -> bool {
        self.id != MISS_ID
    }
}

/// Whether a hit at `t` on triangle `id` replaces `best`, the closest so far: it is nearer, or
/// as near and on a lower id (the module docs say why).
#[inline]
pub fn closer(t: f64, id: u32, best: &WideHit) -> bool {
    wins(t, id, best.t, best.id)
}

/// The rule itself, for a closest hit held in another type (the f64 reference's `RefHit`): a
/// hit at `t` on `id` beats one at `best_t` on `best_id`.
#[inline]
pub fn wins(t: f64, id: u32, best_t: f64, best_id: u32) -> bool {
    t < best_t || (t == best_t && id < best_id)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::{BuildOptions, Bvh, CwBvh, SlotOrder, WideBvh};
    use crate::rays::Ray;
    use crate::scene::Mesh;

    fn at(t: f64, id: u32) -> WideHit {
        WideHit { t, id, u: 0.0, v: 0.0 }
    }

    #[test]
    fn nearer_wins_and_equal_t_goes_to_the_lower_id() {
        // Distance first, whatever the ids.
        assert!(closer(1.0, 9, &at(2.0, 1)));
        assert!(!closer(2.0, 1, &at(1.0, 9)));
        // Equal distance: the lower id, whichever came first.
        assert!(closer(1.0, 3, &at(1.0, 5)));
        assert!(!closer(1.0, 5, &at(1.0, 3)));
        // The same hit again changes nothing.
        assert!(!closer(1.0, 3, &at(1.0, 3)));
        // Any hit beats a miss.
        assert!(closer(1e30, MISS_ID - 1, &WideHit::MISS));
    }

    /// `copies` copies of one triangle (the same vertices), so every ray through it hits all of
    /// them at the same t.
    fn copies(n: usize) -> Mesh {
        let pos = (0..n).flat_map(|_| [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]).collect();
        let tris = (0..n as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        Mesh::from_triangles(pos, tris)
    }

    /// An exact tie in every layout's traversal: the triangles' order in the leaves (and so the
    /// order the walk meets them in) is permuted, and every layout still returns the lowest id.
    /// Keeping the first or the last of the equal hits would return another triangle for most
    /// orders, so this fails unless the rule is applied in every layout.
    #[test]
    fn every_layout_breaks_an_exact_tie_the_same_way() {
        let n = 5;
        let mesh = copies(n);
        let ray = Ray::new([0.25, 0.25, 0.0], [0.0, 0.0, 1.0]);
        // The triangle test: every copy is hit at t = 1, as far as the ray reaches.
        let test = |_: u32, tmax: f64| (1.0 <= tmax).then_some((1.0, 0.25, 0.25));
        let orders: [[u32; 5]; 4] = [[4, 3, 2, 1, 0], [2, 4, 0, 3, 1], [1, 0, 2, 3, 4], [3, 1, 4, 2, 0]];
        let lowest = *orders[0].iter().min().unwrap();
        let mut checked = 0;
        for leaf in [1, 2, 4, 8] {
            for order in orders {
                let mut bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
                assert_eq!(bvh.prim_ids.len(), n);
                bvh.prim_ids = order.to_vec();
                bvh.validate(&mesh).unwrap();
                let mut hits = vec![];
                let w2 = WideBvh::<2>::collapse(&bvh);
                let w4 = WideBvh::<4>::collapse(&bvh);
                let w8 = WideBvh::<8>::collapse(&bvh);
                for e in [w2.validate(&bvh, &mesh), w4.validate(&bvh, &mesh), w8.validate(&bvh, &mesh)] {
                    e.unwrap();
                }
                hits.push(("bvh2", w2.trace(&ray, false, test).0));
                hits.push(("bvh4", w4.trace(&ray, false, test).0));
                hits.push(("bvh8", w8.trace(&ray, false, test).0));
                for how in [SlotOrder::Greedy, SlotOrder::Exact, SlotOrder::Plain] {
                    let cw = CwBvh::build_with(&bvh, how).unwrap();
                    cw.validate(&bvh, &mesh).unwrap();
                    hits.push(("cwbvh", cw.trace(&ray, false, test).0));
                }
                for (layout, h) in hits {
                    assert_eq!(
                        h,
                        WideHit { t: 1.0, id: lowest, u: 0.25, v: 0.25 },
                        "leaf {leaf}, slots {order:?}: {layout}"
                    );
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 4 * 4 * 6);
    }
}
