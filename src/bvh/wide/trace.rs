//! The CPU traversal of a wide tree ([`WideBvh::trace`]): the loop a wide kernel runs.

use super::WideBvh;
use crate::bvh::hit::WideHit;
use crate::bvh::walk::{Walk, WideSteps};
use crate::rays::Ray;

impl<const N: usize> WideBvh<N> {
    /// Closest hit (`any = false`; ties to the lower triangle id, as the f64 reference:
    /// [`crate::bvh::hit`]) or the first hit found (`any = true`), with the work it took.
    /// `intersect(id, tmax)` is the triangle test: `(t, u, v)` when the ray (with its far end cut
    /// to `tmax`) meets triangle `id`; callers pass the f64 reference's (`reference::intersect`).
    ///
    /// The loop a wide kernel runs: test the root box; at a node, test every occupied child's
    /// box ([`slab_f64`]), push the hit children on the stack farthest first with their entry
    /// distance, pop the nearest; a popped entry farther than the closest hit so far is
    /// skipped; a leaf tests its triangles. The box test, the leaf loop and the result are the
    /// walk every CPU traversal shares (`bvh::walk`).
    ///
    /// [`slab_f64`]: crate::bvh::slab::slab_f64
    pub fn trace(
        &self,
        ray: &Ray,
        any: bool,
        mut intersect: impl FnMut(u32, f64) -> Option<(f64, f64, f64)>,
    ) -> (WideHit, WideSteps) {
        let mut walk = Walk::new(ray, any);
        // (child, count, entry distance): count 0 is a node.
        let mut stack: Vec<(u32, u32, f64)> = Vec::with_capacity(64);
        if let Some(t) = walk.enters(&self.bounds) {
            stack.push((0, 0, t));
        }
        let mut hits: Vec<(f64, usize)> = Vec::with_capacity(N);
        while let Some((child, count, tnear)) = stack.pop() {
            if tnear > walk.tmax {
                continue;
            }
            if count > 0 {
                let slots = &self.prim_ids[child as usize..(child + count) as usize];
                if walk.leaf(slots, &mut intersect) {
                    return walk.end();
                }
                continue;
            }
            walk.steps.nodes += 1;
            let n = &self.nodes[child as usize];
            hits.clear();
            for s in 0..N {
                if n.is_empty_slot(s) {
                    break;
                }
                walk.steps.boxes += 1;
                if let Some(t) = walk.enters(&n.child_box(s)) {
                    hits.push((t, s));
                }
            }
            // Nearest on top; equal distances keep slot order.
            hits.sort_by(|a, b| a.0.total_cmp(&b.0));
            for &(t, s) in hits.iter().rev() {
                stack.push((n.child[s], n.count[s], t));
            }
            walk.steps.stack_peak = walk.steps.stack_peak.max(stack.len() as u32);
        }
        walk.end()
    }
}

#[cfg(test)]
mod tests {
    use crate::bvh::testing::{grid, mt};
    use crate::bvh::{BuildOptions, Bvh, WideBvh};
    use crate::rays::Ray;

    fn rays(n: usize) -> Vec<Ray> {
        let mut s = 99u64;
        let mut rnd = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32) / (1u64 << 24) as f32
        };
        (0..n)
            .map(|_| Ray::new([rnd() * 40.0, rnd() * 80.0, -5.0], [0.2 * rnd() - 0.1, 0.2 * rnd() - 0.1, 1.0]))
            .collect()
    }

    #[test]
    fn traversal_finds_the_binary_trees_hits() {
        let mesh = grid(3000);
        let rays = rays(3000);
        for leaf in [1, 4, 16] {
            let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
            let w2 = WideBvh::<2>::collapse(&bvh);
            let w4 = WideBvh::<4>::collapse(&bvh);
            let w8 = WideBvh::<8>::collapse(&bvh);
            let mut hits = 0;
            let mut visits = [0u64; 3];
            for r in &rays {
                let test = |id, t| mt(&mesh, r, id, t);
                let (h2, s2) = w2.trace(r, false, test);
                let (h4, s4) = w4.trace(r, false, test);
                let (h8, s8) = w8.trace(r, false, test);
                assert_eq!(h2, h4, "leaf {leaf} {r:?}");
                assert_eq!(h2, h8, "leaf {leaf} {r:?}");
                for w in [w4.trace(r, true, test).0, w8.trace(r, true, test).0] {
                    assert_eq!(w.is_hit(), h2.is_hit());
                }
                hits += h2.is_hit() as usize;
                for (v, s) in visits.iter_mut().zip([s2, s4, s8]) {
                    *v += s.nodes as u64;
                }
            }
            assert!(hits > 250, "the rays should hit often ({hits})");
            assert!(visits[2] < visits[1] && visits[1] < visits[0], "{visits:?}");
        }
    }
}
