//! Quantized 4-wide BVH (`qbvh4`): the bvh4 tree ([`WideBvh<4>`], the SAH collapse) with each
//! node's four child boxes quantized to 8 bits per plane on a power-of-two grid anchored at the
//! node's box, as Ylitie, Karras & Laine's compressed 8-wide nodes do (HPG 2017, sec. 3.1; our
//! `cwbvh`), but at width 4 and with the bvh4 traversal: 64 bytes a node instead of 128.
//!
//! The tree, its child order, node indices and leaves are bvh4's exactly; only the boxes change,
//! each to a box that contains it (outward rounding checked in the kernel's f32 decode:
//! `bvh::quantize`, shared with cwbvh). So a ray visits a superset of the nodes bvh4 visits and
//! finds the same closest hit.
//!
//! # Node ([`QNode4`], `#[repr(C)]`, 64 bytes = 4 `uvec4` texels, one cache line)
//!
//! | bytes | texel | field | meaning |
//! |---|---|---|---|
//! | 0..12  | 0.xyz | `p[3]` | grid origin: the union of the children's boxes, min corner (f32) |
//! | 12..15 | 0.w   | `e[3]` | per-axis scale `2^(e - 127)`, the biased exponent (`uintBitsToFloat(e << 23)`) |
//! | 15     | 0.w   | `spare` | 0 |
//! | 16..28 | 1.xyz | `q_lo[3]` | per axis, the four children's low planes, child 0 in the lowest byte |
//! | 28..40 | 1.w, 2.xy | `q_hi[3]` | the high planes |
//! | 40..48 | 2.zw  | `spare_words` | 0 |
//! | 48..64 | 3     | `entry[4]` | `leaf_entry(first, count)` (`crate::shared`; count 0: an inner node's index), or [`EMPTY_CHILD`] |
//!
//! Child `s`'s box on axis `k` decodes as `p[k] + float(q_lo[k] byte s) * scale[k]` ..
//! `p[k] + float(q_hi[k] byte s) * scale[k]` in f32 (`bvh::quantize::Grid::decode`), the only box
//! arithmetic the kernel may use (the cwbvh module docs say why). Empty slots come last (as
//! bvh4's), with entry [`EMPTY_CHILD`] and planes 0; the kernel checks the entry, never the box.
//! Why 64 bytes and not 48: four packed entries and the grid take 28 bytes beside the 24 plane
//! bytes; 48 needs cwbvh's leaf table (an extra load per leaf) or leaf ranges a node's leaves
//! share, which the encodings' leaves do not guarantee.
//!
//! # Files
//!
//! Everything is here: the node, the tree ([`Qbvh4::quantize`] from a bvh4 tree), the boxes the
//! kernel tests ([`Qbvh4::decoded`]: a [`WideBvh<4>`] whose walk, stack bound, SAH cost and
//! locality are the CPU model's), and the invariants ([`Qbvh4::validate`]). The grid arithmetic
//! is `bvh::quantize`'s; the walk `WideBvh::trace`'s.

use bytemuck::{Pod, Zeroable};

use super::quantize::{check_contains, quantize_boxes, Grid, Planes};
use super::wide::EMPTY_CHILD;
use super::{Aabb, BuildOptions, Bvh, WideBvh, WideNode};
use crate::bvh::hit::WideHit;
use crate::bvh::walk::WideSteps;
use crate::rays::Ray;
use crate::scene::Mesh;
use crate::shared::{leaf_entry, leaf_entry_count, leaf_entry_first, LEAF_ENTRY_FIRST_LIMIT};

/// Children per node.
pub const Q4_WIDTH: usize = 4;
/// 16-byte texels per node.
pub const Q4_NODE_TEXELS: usize = 4;

/// One quantized 4-wide node (see the module docs for the fields).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct QNode4 {
    pub p: [f32; 3],
    pub e: [u8; 3],
    pub spare: u8,
    /// Per axis: the four children's low planes, child `s` in byte `s`.
    pub q_lo: [[u8; 4]; 3],
    pub q_hi: [[u8; 4]; 3],
    pub spare_words: [u32; 2],
    pub entry: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<QNode4>() == 64);
const _: () = assert!(std::mem::size_of::<QNode4>() == 16 * Q4_NODE_TEXELS);
const _: () = assert!(std::mem::align_of::<QNode4>() == 4);

impl QNode4 {
    pub fn grid(&self) -> Grid {
        Grid { p: self.p, e: self.e }
    }

    /// Child `s`'s planes on the grid.
    pub fn planes(&self, s: usize) -> Planes {
        (self.q_lo.map(|a| a[s]), self.q_hi.map(|a| a[s]))
    }

    pub fn is_empty_slot(&self, s: usize) -> bool {
        self.entry[s] == EMPTY_CHILD
    }

    /// Child `s`'s box as the kernel decodes it (without flushing).
    pub fn child_box(&self, s: usize) -> Aabb {
        self.grid().decode(self.planes(s))
    }

    /// The node with `wide`'s children, their boxes quantized on the grid of their union.
    pub fn quantize(wide: &WideNode<4>) -> Result<QNode4, String> {
        let k = wide.children();
        let boxes: Vec<Aabb> = (0..k).map(|s| wide.child_box(s)).collect();
        let (grid, planes) = quantize_boxes(&boxes)?;
        let mut n = QNode4 { p: grid.p, e: grid.e, entry: [EMPTY_CHILD; 4], ..QNode4::zeroed() };
        for (s, (lo, hi)) in planes.into_iter().enumerate() {
            for a in 0..3 {
                (n.q_lo[a][s], n.q_hi[a][s]) = (lo[a], hi[a]);
            }
            if u64::from(wide.child[s]) >= LEAF_ENTRY_FIRST_LIMIT {
                return Err(format!("child {} does not fit a packed entry", wide.child[s]));
            }
            n.entry[s] = leaf_entry(wide.child[s], wide.count[s]);
        }
        Ok(n)
    }

    /// The node as the kernel reads it: its decoded boxes, the entries unpacked.
    pub fn decoded(&self) -> WideNode<4> {
        let mut w = WideNode::<4>::EMPTY;
        for s in (0..Q4_WIDTH).filter(|&s| !self.is_empty_slot(s)) {
            w.set_child_box(s, &self.child_box(s));
            (w.child[s], w.count[s]) = (leaf_entry_first(self.entry[s]), leaf_entry_count(self.entry[s]));
        }
        w
    }
}

/// A quantized 4-wide tree over the same nodes, leaves and `prim_ids` as the bvh4 tree it was
/// quantized from.
#[derive(Clone, Debug)]
pub struct Qbvh4 {
    /// Root at 0; node `i` is the bvh4 tree's node `i`.
    pub nodes: Vec<QNode4>,
    /// The root's box (the binary root's).
    pub bounds: Aabb,
    /// Leaf slot -> triangle id (the binary tree's); empty when quantized from an encoding's
    /// nodes.
    pub prim_ids: Vec<u32>,
    pub max_leaf_size: u32,
}

impl Qbvh4 {
    /// The binary tree collapsed into 4-wide nodes ([`WideBvh::collapse`]) and quantized.
    pub fn build(bvh: &Bvh) -> Result<Qbvh4, String> {
        Self::quantize(&WideBvh::<4>::collapse(bvh))
    }

    /// `wide`'s nodes quantized one by one (same indices, same children).
    pub fn quantize(wide: &WideBvh<4>) -> Result<Qbvh4, String> {
        Ok(Qbvh4 {
            nodes: wide.nodes.iter().map(QNode4::quantize).collect::<Result<_, _>>()?,
            bounds: wide.bounds,
            prim_ids: wide.prim_ids.clone(),
            max_leaf_size: wide.max_leaf_size,
        })
    }

    /// The tree the kernel walks: bvh4's nodes with the decoded boxes. Its walk
    /// ([`WideBvh::trace`]), stack bound, SAH cost and locality are this tree's.
    pub fn decoded(&self) -> WideBvh<4> {
        WideBvh {
            nodes: self.nodes.iter().map(QNode4::decoded).collect(),
            bounds: self.bounds,
            prim_ids: self.prim_ids.clone(),
            max_leaf_size: self.max_leaf_size,
            collapse_seconds: 0.0,
        }
    }

    /// Closest (or any) hit as the kernel finds it: bvh4's walk over the decoded boxes
    /// ([`WideBvh::trace`]; decodes the tree first: for many rays, trace [`Qbvh4::decoded`]).
    pub fn trace(
        &self,
        ray: &Ray,
        any: bool,
        intersect: impl FnMut(u32, f64) -> Option<(f64, f64, f64)>,
    ) -> (WideHit, WideSteps) {
        self.decoded().trace(ray, any, intersect)
    }

    /// Most entries the traversal stack can hold: bvh4's (the same tree).
    pub fn stack_bound(&self) -> usize {
        self.decoded().stack_bound()
    }

    /// The SAH cost over the decoded boxes, priced as [`WideBvh::sah_cost`].
    pub fn sah_cost(&self, o: &BuildOptions) -> f64 {
        self.decoded().sah_cost(o)
    }

    /// Checks the tree against the bvh4 tree of `bvh` (itself validated against `bvh` and the
    /// mesh): the same nodes, children and leaves, every exponent a normal scale, every
    /// occupied child's decoded box (both decode variants, `bvh::quantize::decode_plane`)
    /// containing bvh4's box of that child, and so everything under it. Returns the first
    /// violation.
    pub fn validate(&self, bvh: &Bvh, mesh: &Mesh) -> Result<(), String> {
        let truth = WideBvh::<4>::collapse(bvh);
        truth.validate(bvh, mesh).map_err(|e| format!("the bvh4 tree: {e}"))?;
        if self.nodes.len() != truth.nodes.len() || self.prim_ids != truth.prim_ids || self.bounds != truth.bounds {
            return Err(format!("{} nodes, not the bvh4 tree's {}", self.nodes.len(), truth.nodes.len()));
        }
        for (i, (n, w)) in self.nodes.iter().zip(&truth.nodes).enumerate() {
            if n.e.iter().any(|&e| e == 0 || e == 255) {
                return Err(format!("node {i}: exponent {:?} is not a normal scale", n.e));
            }
            for s in 0..Q4_WIDTH {
                let d = n.decoded();
                if (d.child[s], d.count[s]) != (w.child[s], w.count[s]) {
                    return Err(format!("node {i} slot {s}: entry {:#x} is not bvh4's child", n.entry[s]));
                }
                let b = w.child_box(s);
                if !n.is_empty_slot(s) && !b.is_empty() {
                    check_contains(&n.grid(), n.planes(s), &b).map_err(|e| format!("node {i} slot {s}: {e}"))?;
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::testing::{grid, grid_tree, mt, refuses};
    use crate::bvh::NodeTree;
    use glam::Vec3;

    #[test]
    fn node_texels_are_the_documented_ones() {
        let mut n = QNode4::zeroed();
        n.p = [1.0, 2.0, 3.0];
        n.e = [10, 11, 12];
        n.q_lo[0] = [1, 2, 3, 4];
        n.q_hi[2] = [5, 6, 7, 8];
        n.entry = [9, 10, 11, EMPTY_CHILD];
        let w: &[u32] = bytemuck::cast_slice(std::slice::from_ref(&n));
        assert_eq!(w.len(), 16);
        assert_eq!(&w[0..3], &[1.0f32.to_bits(), 2.0f32.to_bits(), 3.0f32.to_bits()]);
        assert_eq!(w[3], 10 | 11 << 8 | 12 << 16);
        // Texel 1: q_lo x, y, z, q_hi x; texel 2: q_hi y, z; texel 3: the entries.
        assert_eq!(w[4], 0x0403_0201);
        assert_eq!(w[9], 0x0807_0605);
        assert_eq!(&w[12..16], &[9, 10, 11, EMPTY_CHILD]);
    }

    /// Valid on grids of every leaf size; the same tree as bvh4 (nodes, stack); the decoded boxes
    /// contain bvh4's and are no smaller in SAH cost.
    #[test]
    fn grid_trees_are_valid_and_bvh4_shaped() {
        let mesh = grid(3000);
        for leaf in [1, 4, 16] {
            let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
            let w4 = WideBvh::<4>::collapse(&bvh);
            let q = Qbvh4::build(&bvh).unwrap();
            q.validate(&bvh, &mesh).unwrap_or_else(|e| panic!("leaf {leaf}: {e}"));
            assert_eq!((q.nodes.len(), q.stack_bound()), (w4.nodes.len(), w4.stack_bound()));
            let (cq, c4) = (q.sah_cost(&bvh.options), w4.sah_cost(&bvh.options));
            assert!(cq >= c4 && cq < 1.5 * c4, "leaf {leaf}: SAH {cq} against bvh4's {c4}");
            let d = q.decoded();
            let (t4, tq) =
                (NodeTree::wide(&w4.nodes, &w4.bounds).unwrap(), NodeTree::wide(&d.nodes, &d.bounds).unwrap());
            assert_eq!(t4.depths(), tq.depths());
        }
    }

    /// The model's hits equal the binary tree's (so bvh4's), closest and any; it visits at least
    /// the nodes bvh4 visits.
    #[test]
    fn traversal_finds_the_binary_trees_hits() {
        let mesh = grid(3000);
        let mut s = 5u64;
        let mut rnd = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32) / (1u64 << 24) as f32
        };
        let rays: Vec<Ray> = (0..2000)
            .map(|_| Ray::new([rnd() * 40.0, rnd() * 80.0, -5.0], [0.2 * rnd() - 0.1, 0.2 * rnd() - 0.1, 1.0]))
            .collect();
        for leaf in [1, 4] {
            let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
            let w2 = WideBvh::<2>::collapse(&bvh);
            let w4 = WideBvh::<4>::collapse(&bvh);
            let q = Qbvh4::build(&bvh).unwrap().decoded();
            let (mut hits, mut nodes) = (0, [0u64; 2]);
            for r in &rays {
                let test = |id, t| mt(&mesh, r, id, t);
                let (h2, _) = w2.trace(r, false, test);
                let (h4, s4) = w4.trace(r, false, test);
                assert_eq!(h2, h4);
                let (hq, sq) = q.trace(r, false, test);
                assert_eq!(h2, hq, "leaf {leaf} {r:?}");
                assert_eq!(q.trace(r, true, test).0.is_hit(), h2.is_hit());
                hits += h2.is_hit() as usize;
                nodes[0] += s4.nodes as u64;
                nodes[1] += sq.nodes as u64;
            }
            assert!(hits > 200, "{hits}");
            assert!(nodes[1] >= nodes[0], "{nodes:?}");
        }
    }

    /// Boxes at extreme scales (tiny near huge, flat, far from the origin) stay contained after
    /// quantization in both decode variants.
    #[test]
    fn extreme_boxes_are_contained() {
        let b = |lo: [f32; 3], hi: [f32; 3]| Aabb { min: Vec3::from_array(lo), max: Vec3::from_array(hi) };
        let sets = [
            vec![b([-1e-20; 3], [1e-20; 3]), b([-2e30, 0.0, 5.0], [3e30, 0.0, 5.0])],
            vec![b([1e-38, 1e-39, -1e-40], [2e-38, 1e-39, 0.0]), b([0.0; 3], [1e-45, 0.0, 1e-45])],
            vec![b([-7.3e10, 1.0, 1.0], [-7.3e10, 1.0 + f32::EPSILON, 1.0]), b([1e7, 1e7, 1e7], [1e7 + 1.0; 3])],
            vec![b([-3.4e38; 3], [3.4e38; 3]), b([1.0; 3], [1.0; 3])],
        ];
        for (i, boxes) in sets.iter().enumerate() {
            let mut w = WideNode::<4>::EMPTY;
            for (s, bx) in boxes.iter().enumerate() {
                w.set_child_box(s, bx);
                (w.child[s], w.count[s]) = (s as u32, 1);
            }
            let n = QNode4::quantize(&w).unwrap_or_else(|e| panic!("set {i}: {e}"));
            for (s, bx) in boxes.iter().enumerate() {
                check_contains(&n.grid(), n.planes(s), bx).unwrap_or_else(|e| panic!("set {i} child {s}: {e}"));
                assert!(n.child_box(s).contains(bx), "set {i} child {s}");
            }
            assert!(n.is_empty_slot(3) && n.entry[0] == leaf_entry(0, 1));
        }
    }

    #[test]
    fn corruption_is_caught() {
        let (mesh, bvh) = grid_tree();
        let q = Qbvh4::build(&bvh).unwrap();
        let expect = refuses(&q, |c| c.validate(&bvh, &mesh));
        let (ni, si) = (0..q.nodes.len())
            .flat_map(|i| (0..4).map(move |s| (i, s)))
            .find(|&(i, s)| !q.nodes[i].is_empty_slot(s) && q.nodes[i].q_hi[0][s] > 0 && q.nodes[i].q_lo[1][s] < 255)
            .unwrap();
        expect(&|c| c.nodes[ni].q_hi[0][si] -= 1, "decoded max");
        expect(&|c| c.nodes[ni].q_lo[1][si] += 1, "decoded min");
        expect(&|c| c.nodes[ni].p[2] += 1.0, "decoded");
        expect(&|c| c.nodes[ni].e[0] = 0, "normal scale");
        expect(&|c| c.nodes[ni].entry[si] ^= 1 << 5, "not bvh4's child");
        expect(&|c| c.nodes.truncate(1), "nodes, not the bvh4 tree's");
    }
}
