//! Ray order before dispatch (issue 27, coherence): one ray per lane pays for divergence and for
//! a cache line per lane per gather, so incoherent rays traced next to each other cost more than
//! the same rays grouped by where they start and where they go. [`RayOrder::permutation`] gives
//! the order a set is traced in; the caller traces the permuted rays and puts the hits back in
//! the set's order ([`unpermute`]), and a benchmark counts both steps in its time.

use crate::named::named_enum;
use crate::rays::Ray;

named_enum! {
    /// The order a ray set is dispatched in.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum RayOrder: "ray order" {
        /// As the set holds them (a primary or diffuse set: pixel order).
        Given = "given" (default),
        /// Sorted by direction octant, then by the origin's cell of a 32^3 grid over the set's
        /// origins (in Morton order), stably: lanes of one subgroup start close together and
        /// head the same way, and within a cell rays keep the set's order.
        OctantOrigin = "octant-origin",
    }
}

impl RayOrder {
    /// The order to trace `rays` in: entry `k` is the index of the ray traced `k`-th; `None`
    /// for [`RayOrder::Given`] (trace them as they are).
    pub fn permutation(self, rays: &[Ray]) -> Option<Vec<u32>> {
        match self {
            RayOrder::Given => None,
            RayOrder::OctantOrigin => Some(sort_by_key(&octant_origin_keys(rays))),
        }
    }
}

/// Bits per axis of the origin's grid cell. A 32^3 grid measured as fast to trace as a 512^3 one
/// (bunny, diffuse and random sets, lavapipe) and its 18-bit key sorts in two passes, not four.
const CELL_BITS: u32 = 5;

/// Each ray's key: its direction's octant (3 bits; a component's sign bit, so -0 counts as
/// negative) above the Morton code of its origin's grid cell over the set's origin bounds.
fn octant_origin_keys(rays: &[Ray]) -> Vec<u32> {
    use rayon::prelude::*;
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for r in rays {
        for a in 0..3 {
            lo[a] = lo[a].min(r.origin[a]);
            hi[a] = hi[a].max(r.origin[a]);
        }
    }
    // A NaN origin leaves the bounds alone and quantises to 0 (`as` saturates, NaN -> 0); such
    // a ray's hit is whatever the kernel says, in the set's order, as without reordering.
    let top = ((1u32 << CELL_BITS) - 1) as f32;
    let scale: [f32; 3] = std::array::from_fn(|a| if hi[a] > lo[a] { top / (hi[a] - lo[a]) } else { 0.0 });
    rays.par_iter()
        .map(|r| {
            let q = |a: usize| ((r.origin[a] - lo[a]) * scale[a]) as u32;
            let octant = r.dir.iter().enumerate().fold(0, |o, (a, d)| o | (d.is_sign_negative() as u32) << a);
            octant << (3 * CELL_BITS) | spread3(q(0)) | spread3(q(1)) << 1 | spread3(q(2)) << 2
        })
        .collect()
}

/// The low [`CELL_BITS`] bits of `x` spread to every third bit (bit i to bit 3i).
fn spread3(x: u32) -> u32 {
    let mut x = x & ((1 << CELL_BITS) - 1);
    x = (x | x << 16) & 0x030000ff;
    x = (x | x << 8) & 0x0300f00f;
    x = (x | x << 4) & 0x030c30c3;
    (x | x << 2) & 0x09249249
}

/// The indices of `keys` in ascending key order, ties in index order: a least-significant-digit
/// radix sort in 9-bit passes, as many as the largest key needs (two for the 18-bit keys here;
/// the time is part of what a reordered benchmark reports).
fn sort_by_key(keys: &[u32]) -> Vec<u32> {
    const DIGIT: u32 = 9;
    let mut order: Vec<u32> = (0..keys.len() as u32).collect();
    let mut next = vec![0u32; keys.len()];
    let bits = 32 - keys.iter().fold(0, |a, &k| a | k).leading_zeros();
    for shift in (0..bits).step_by(DIGIT as usize) {
        let digit = |i: u32| (keys[i as usize] >> shift) as usize & ((1 << DIGIT) - 1);
        let mut start = [0usize; (1 << DIGIT) + 1];
        for &i in &order {
            start[digit(i) + 1] += 1;
        }
        if start[1..].contains(&keys.len()) {
            continue; // every key has this digit: the pass would not move anything
        }
        for d in 0..1 << DIGIT {
            start[d + 1] += start[d];
        }
        for &i in &order {
            let d = digit(i);
            next[start[d]] = i;
            start[d] += 1;
        }
        std::mem::swap(&mut order, &mut next);
    }
    order
}

/// `items` traced in `order` put back in the set's order: `out[order[k]] = items[k]`.
pub fn unpermute<T: Copy>(order: &[u32], items: &[T]) -> Vec<T> {
    let mut out = items.to_vec(); // every entry is overwritten: `order` is a permutation
    for (&i, &x) in order.iter().zip(items) {
        out[i as usize] = x;
    }
    out
}

/// `rays` in `order`.
pub fn permute(order: &[u32], rays: &[Ray]) -> Vec<Ray> {
    use rayon::prelude::*;
    order.par_iter().map(|&i| rays[i as usize]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(origin: [f32; 3], dir: [f32; 3]) -> Ray {
        Ray { origin, tmin: 0.0, dir, tmax: f32::INFINITY }
    }

    #[test]
    fn the_radix_sort_orders_like_a_stable_comparison_sort() {
        let mut x = 0x9e37_79b9u32;
        let keys: Vec<u32> = (0..5000)
            .map(|i| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                if i % 7 == 0 {
                    42 // ties, which must stay in index order
                } else {
                    x
                }
            })
            .collect();
        let mut expected: Vec<u32> = (0..keys.len() as u32).collect();
        expected.sort_by_key(|&i| keys[i as usize]);
        assert_eq!(sort_by_key(&keys), expected);
        assert_eq!(sort_by_key(&[]), Vec::<u32>::new());
        assert_eq!(sort_by_key(&[7, 7, 7]), vec![0, 1, 2]);
    }

    #[test]
    fn morton_bits_interleave() {
        assert_eq!(spread3(0b1), 0b1);
        assert_eq!(spread3(0b11), 0b1001);
        assert_eq!(spread3(0x1f), 0x1249);
        assert_eq!(spread3(0x20), 0, "bits above the 5th are dropped");
    }

    #[test]
    fn rays_group_by_octant_then_by_origin() {
        // Origins on a line from 0 to 9, directions alternating between two octants.
        let rays: Vec<Ray> = (0..10)
            .map(|i| ray([i as f32, 0.0, 0.0], if i % 2 == 0 { [1.0, 1.0, 1.0] } else { [-1.0, 1.0, 1.0] }))
            .collect();
        let order = RayOrder::OctantOrigin.permutation(&rays).unwrap();
        assert_eq!(order, vec![0, 2, 4, 6, 8, 1, 3, 5, 7, 9]);
        assert_eq!(RayOrder::Given.permutation(&rays), None);
        // Every octant bit counts, z's too: the farthest origin heading -z sorts after the
        // nearest heading +z, and the key's bits are not shifted out.
        let z =
            [ray([9.0, 9.0, 9.0], [1.0, 1.0, 1.0]), ray([0.0; 3], [1.0, 1.0, -1.0]), ray([1.0; 3], [1.0, 1.0, 1.0])];
        assert_eq!(RayOrder::OctantOrigin.permutation(&z).unwrap(), vec![2, 0, 1]);
        // Tracing in that order and putting the hits back gives each ray its own hit.
        let traced = permute(&order, &rays);
        let hits: Vec<f32> = traced.iter().map(|r| r.origin[0]).collect();
        let back = unpermute(&order, &hits);
        assert_eq!(back, (0..10).map(|i| i as f32).collect::<Vec<_>>());
    }

    #[test]
    fn a_degenerate_or_nan_set_still_permutes_every_ray_once() {
        let mut rays = vec![ray([1.0, 1.0, 1.0], [0.0, -0.0, 1.0]); 5];
        rays.push(ray([f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0]));
        let mut order = RayOrder::OctantOrigin.permutation(&rays).unwrap();
        order.sort_unstable();
        assert_eq!(order, (0..6).collect::<Vec<u32>>());
    }
}
