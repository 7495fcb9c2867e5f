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
        /// Screen tiles: by the 2D Morton code of where each ray's direction crosses the plane
        /// across the set's mean direction (a gnomonic projection). A pinhole camera's rays cross
        /// it on the image's pixel grid, so a primary set is traced in nested square tiles and
        /// every power-of-two run of lanes (4 to 64) covers a compact block of pixels; other sets
        /// are grouped by where they head. Rays heading away from the mean come last.
        Tiles = "tiles",
    }
}

impl RayOrder {
    /// The order to trace `rays` in: entry `k` is the index of the ray traced `k`-th; `None`
    /// for [`RayOrder::Given`] (trace them as they are).
    pub fn permutation(self, rays: &[Ray]) -> Option<Vec<u32>> {
        match self {
            RayOrder::Given => None,
            RayOrder::OctantOrigin => Some(sort_by_key(&octant_origin_keys(rays))),
            RayOrder::Tiles => Some(sort_by_key(&tile_keys(rays))),
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

/// Bits per axis of a ray's position on the tiles' plane: 15, so that the key (with the
/// heading-away bit above the 30-bit Morton code) sorts in four 9-bit passes.
const TILE_BITS: u32 = 15;

/// Each ray's tile key: the Morton code of its direction's crossing of the plane one unit along
/// the set's mean direction `m` (coordinates `(d.u, d.v) / d.m` for a basis `u, v` across `m`,
/// quantised over the set's bounds), with bit 30 set for a ray whose direction does not head
/// along `m` (`d.m <= 0`, or not finite) so that those sort last.
fn tile_keys(rays: &[Ray]) -> Vec<u32> {
    use glam::Vec3;
    use rayon::prelude::*;
    let sum: Vec3 = rays.iter().map(|r| Vec3::from_array(r.dir)).filter(|d| d.is_finite()).sum();
    let m = sum.try_normalize().unwrap_or(Vec3::Z);
    let (u, v) = m.any_orthonormal_pair();
    let plane = |d: [f32; 3]| {
        let d = Vec3::from_array(d);
        let along = d.dot(m);
        let p = [d.dot(u) / along, d.dot(v) / along];
        (along > 0.0 && p.iter().all(|x| x.is_finite())).then_some(p)
    };
    let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
    for p in rays.iter().filter_map(|r| plane(r.dir)) {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    // One scale for both axes, so that a Morton block is square on the image.
    let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let scale = if extent > 0.0 { ((1u32 << TILE_BITS) - 1) as f32 / extent } else { 0.0 };
    rays.par_iter()
        .map(|r| match plane(r.dir) {
            Some(p) => {
                let q = |a: usize| ((p[a] - lo[a]) * scale).round() as u32;
                spread2(q(0)) | spread2(q(1)) << 1
            }
            None => 1 << (2 * TILE_BITS),
        })
        .collect()
}

/// The low [`TILE_BITS`] bits of `x` spread to every other bit (bit i to bit 2i).
fn spread2(x: u32) -> u32 {
    let mut x = x & ((1 << TILE_BITS) - 1);
    x = (x | x << 8) & 0x00ff00ff;
    x = (x | x << 4) & 0x0f0f0f0f;
    x = (x | x << 2) & 0x33333333;
    (x | x << 1) & 0x55555555
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
    fn tiles_keep_a_subgroup_of_a_pinhole_image_in_a_compact_block() {
        // A 64 x 48 pinhole image, row by row, looking down -z with a 60 degree field: pixel
        // (x, y)'s direction crosses the plane z = -1 at a point on a uniform grid.
        let (w, h) = (64usize, 48usize);
        let rays: Vec<Ray> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
                let d = glam::Vec3::new((2.0 * x / w as f32 - 1.0) * 0.77, (1.0 - 2.0 * y / h as f32) * 0.58, -1.0);
                ray([1.0, 2.0, 3.0], d.normalize().to_array())
            })
            .collect();
        let order = RayOrder::Tiles.permutation(&rays).unwrap();
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..(w * h) as u32).collect::<Vec<_>>(), "a permutation");
        // Each run of 16 lanes spans few pixels in x and in y; in the given order it is a row
        // segment 16 pixels wide.
        let span = |group: &[u32]| {
            let xs = group.iter().map(|&i| i as usize % w);
            let ys = group.iter().map(|&i| i as usize / w);
            (xs.clone().max().unwrap() - xs.min().unwrap() + 1) * (ys.clone().max().unwrap() - ys.min().unwrap() + 1)
        };
        let given: Vec<u32> = (0..(w * h) as u32).collect();
        let mean = |o: &[u32]| o.chunks(16).map(span).sum::<usize>() as f64 / (w * h / 16) as f64;
        assert_eq!(mean(&given), 16.0);
        // Square Morton blocks on a grid whose sides are multiples of 4: 4 x 4 tiles, up to a
        // rounding step at a block's edge.
        assert!(mean(&order) <= 18.0, "16 lanes cover {} pixels' box on average", mean(&order));
        let widest = order.chunks(16).map(span).max().unwrap();
        assert!(widest <= 32, "the widest group of 16 spans a box of {widest} pixels");
        // A 4-lane run is a 2 x 2 block (a 2 x 3 box at most).
        assert!(order.chunks(4).all(|g| span(g) <= 6));
    }

    #[test]
    fn tiles_put_rays_heading_away_last_and_survive_nan() {
        let rays = vec![
            ray([0.0; 3], [0.0, 0.0, -1.0]),
            ray([0.0; 3], [0.0, 0.0, 1.0]),
            ray([0.0; 3], [f32::NAN, 0.0, -1.0]),
            ray([0.0; 3], [0.1, 0.0, -1.0]),
            ray([0.0; 3], [0.0, 0.1, -1.0]),
        ];
        let order = RayOrder::Tiles.permutation(&rays).unwrap();
        // The mean heads down -z (the NaN direction is left out of it); +z and NaN go last, in
        // the set's order.
        assert_eq!(&order[3..], &[1, 2]);
        let mut first = order[..3].to_vec();
        first.sort_unstable();
        assert_eq!(first, vec![0, 3, 4]);
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
