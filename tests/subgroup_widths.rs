//! Every subgroup width a driver may choose (issue 16, item 5): GPUs run 8 to 64 lanes, lavapipe
//! 8 or 4 (`LP_NATIVE_VECTOR_WIDTH=128`), so the widths this machine cannot run are proved here
//! on the CPU, and the host's guard on the GPU:
//! - a lane-level model of the cooperative and packet kernels' node fetch (glsl/node_spread.glsl:
//!   `spread_load`, `spread_texel`, `spread_field`) at 4, 8, 16, 32 and 64 lanes on every node of the
//!   bunny's bvh4 and bvh8 trees: each lane must receive exactly its child's fields as the node
//!   holds them, every child must be taken by exactly one lane, and no lane may load a texel
//!   outside the node. `subgroupShuffle` is modelled as the SPIR-V defines it: the value is the
//!   one the SOURCE lane computed, so a lane-dependent choice of what to shuffle is caught (the
//!   kernel before this test read the wrong block at 16 lanes on bvh8: the model shows it);
//! - the leaf step (units k, k + S, ... per lane, smallest t over the lanes, ties to the higher
//!   slot) and the push order of a node's hit children (farthest first by subgroup maxima) equal
//!   the sequential rule at every width; the uvec4 ballot visits every valid lane once, in lane
//!   order, up to 128 lanes;
//! - the GLSL has none of the width assumptions the audit removed (glsl/README.md, "Subgroup
//!   widths"), and every kernel that reads a lane's index or uses lane-to-lane operations is one
//!   the host creates with full subgroups;
//! - on the device: the cooperative kernel at workgroup sizes that are multiples of the subgroup
//!   size gives while-if's hits (and passes the f64 check), and a workgroup size that is not is
//!   refused with an error naming the kernel and both sizes.

mod common;

use trilab::bvh::wide::EMPTY_CHILD;
use trilab::bvh::{BuildOptions, Bvh4Node, Bvh8Node, WideBvh};
use trilab::encoding::{Layout, Method, Raycast, Traversal};
use trilab::error::Error;
use trilab::kernels::KERNELS;
use trilab::pipeline::{HostScene, SceneRequest};
use trilab::services::rayset::{ray_sets, RaySetSizes};
use trilab::services::validate::validate_hits;
use trilab::shared::SPEC_ID_WORKGROUP_SIZE;
use trilab::spirv::reflect::reads_subgroup_lanes;

/// The widths Vulkan drivers report for compute (powers of two; the cooperative kernel needs 4).
const WIDTHS: [usize; 5] = [4, 8, 16, 32, 64];

/// How a lane picks which of its four loaded texel blocks to hand out in `coop_texel`.
#[derive(Clone, Copy, Debug, PartialEq)]
enum BlockRule {
    /// The kernel's: from the field alone (`2f / S`), the same in every lane.
    Uniform,
    /// The kernel before the fix: from the lane's own texel index (`t / S`).
    PerLane,
}

/// A wide node as the kernel reads it: 16-byte texels, and what child `c`'s fields are.
trait CoopNode {
    const WIDTH: usize;
    const TEXELS: usize;
    fn texels(&self) -> Vec<[u32; 4]>;
    /// (min x, y, z, max x, y, z, child, count) of child `c`, as bits.
    fn fields(&self, c: usize) -> [u32; 8];
    /// The texel holding field `f` of child `ch` (the layout's SoA order).
    fn texel_of(f: usize, ch: usize) -> usize;
    /// The block a lane asks for under `rule` at width `s`.
    fn block(rule: BlockRule, f: usize, ch: usize, s: usize) -> usize;
}

macro_rules! coop_node {
    ($t:ty, $w:expr) => {
        impl CoopNode for $t {
            const WIDTH: usize = $w;
            const TEXELS: usize = $w * 2;
            fn texels(&self) -> Vec<[u32; 4]> {
                bytemuck::cast_slice(bytemuck::bytes_of(self)).to_vec()
            }
            fn fields(&self, c: usize) -> [u32; 8] {
                [
                    self.min_x[c].to_bits(),
                    self.min_y[c].to_bits(),
                    self.min_z[c].to_bits(),
                    self.max_x[c].to_bits(),
                    self.max_y[c].to_bits(),
                    self.max_z[c].to_bits(),
                    self.child[c],
                    self.count[c],
                ]
            }
            fn texel_of(f: usize, ch: usize) -> usize {
                // bvh4: texel f; bvh8: texels 2f (children 0-3) and 2f + 1 (4-7).
                if $w == 4 {
                    f
                } else {
                    2 * f + ((ch >> 2) & 1)
                }
            }
            fn block(rule: BlockRule, f: usize, ch: usize, s: usize) -> usize {
                match rule {
                    BlockRule::Uniform => Self::texel_of(f, 0) / s,
                    // The old kernel: `2f + (ch >> 2)` without the mask, block t / S.
                    BlockRule::PerLane => (if $w == 4 { f } else { 2 * f + (ch >> 2) }) / s,
                }
            }
        }
    };
}
coop_node!(Bvh4Node, 4);
coop_node!(Bvh8Node, 8);

/// What went wrong in one node's fetch at one width, if anything.
fn fetch_errors<N: CoopNode>(node: &N, s: usize, rule: BlockRule) -> Vec<String> {
    let texels = node.texels();
    assert_eq!(texels.len(), N::TEXELS);
    let mut errors = vec![];
    // spread_load: lane k loads block b = texel b*S + k when that index is inside the node.
    let mut lanes = vec![[[0u32; 4]; 4]; s];
    for (k, lane) in lanes.iter_mut().enumerate() {
        for (b, block) in lane.iter_mut().enumerate() {
            let t = b * s + k;
            if t < N::TEXELS {
                *block = texels[t];
            }
        }
    }
    // Every texel loaded by exactly one (lane, block).
    let mut loaded = vec![0; N::TEXELS];
    for k in 0..s {
        for b in 0..4 {
            if b * s + k < N::TEXELS {
                loaded[b * s + k] += 1;
            }
        }
    }
    if loaded.iter().any(|&n| n != 1) {
        errors.push(format!("texels loaded {loaded:?} times"));
    }
    // Lane k's children: k, and k + S where the node is wider than the subgroup.
    let mut taken = vec![0; N::WIDTH];
    for k in 0..s {
        let mut mine = vec![k];
        if s < N::WIDTH {
            mine.push(k + s);
        }
        for ch in mine {
            let mut got = [0u32; 8];
            for (f, g) in got.iter_mut().enumerate() {
                // coop_texel: lane k asks for texel t from lane t % S; subgroupShuffle hands it
                // the block the SOURCE lane selected (by the source lane's own child index).
                let t = match rule {
                    BlockRule::Uniform => N::texel_of(f, ch),
                    BlockRule::PerLane => {
                        if N::WIDTH == 4 {
                            f
                        } else {
                            2 * f + (ch >> 2)
                        }
                    }
                };
                let src = t % s;
                let src_ch = src; // the source lane's first child (the same call in every lane)
                let src_ch = if ch >= s { src_ch + s } else { src_ch };
                let block = N::block(rule, f, src_ch, s).min(3);
                *g = lanes[src][block][ch & 3];
            }
            if ch < N::WIDTH {
                taken[ch] += 1;
                if got != node.fields(ch) {
                    errors.push(format!("lane {k} child {ch}: got {got:?}, the node holds {:?}", node.fields(ch)));
                }
            }
        }
    }
    if taken.iter().any(|&n| n != 1) {
        errors.push(format!("children taken {taken:?} times"));
    }
    errors
}

fn trees() -> (WideBvh<4>, WideBvh<8>) {
    let bunny = common::bunny();
    let bvh = trilab::bvh::Bvh::build(&bunny, &BuildOptions::new(4));
    (WideBvh::collapse(&bvh), WideBvh::collapse(&bvh))
}

fn fetch_failures<N: CoopNode>(nodes: &[N], s: usize, rule: BlockRule) -> (usize, Option<String>) {
    let mut first = None;
    let mut bad = 0;
    for (i, n) in nodes.iter().enumerate() {
        let e = fetch_errors(n, s, rule);
        if !e.is_empty() {
            bad += 1;
            first.get_or_insert_with(|| format!("node {i}: {}", e.join("; ")));
        }
    }
    (bad, first)
}

#[test]
fn coop_node_fetch_gives_every_lane_its_child_at_every_width() {
    let (b4, b8) = trees();
    assert!(b4.nodes.len() > 100 && b8.nodes.len() > 50);
    // The model needs nodes with empty slots and leaves in every slot position to mean anything.
    assert!(b8.nodes.iter().any(|n| n.child.contains(&EMPTY_CHILD)));
    assert!((0..8).all(|c| b8.nodes.iter().any(|n| n.count[c] > 0)));
    for s in WIDTHS {
        let (bad4, e4) = fetch_failures(&b4.nodes, s, BlockRule::Uniform);
        assert_eq!(bad4, 0, "bvh4 at {s} lanes: {e4:?}");
        let (bad8, e8) = fetch_failures(&b8.nodes, s, BlockRule::Uniform);
        assert_eq!(bad8, 0, "bvh8 at {s} lanes: {e8:?}");
    }
}

/// The model has teeth: the kernel's old per-lane block choice is right at 4, 8, 32 and 64 lanes
/// and reads the `count` field from the wrong block at 16 lanes on bvh8 (every node).
#[test]
fn the_model_catches_the_old_per_lane_block_choice() {
    let (b4, b8) = trees();
    for s in WIDTHS {
        let (bad4, _) = fetch_failures(&b4.nodes, s, BlockRule::PerLane);
        assert_eq!(bad4, 0, "bvh4 at {s}: the old rule was right there");
        let (bad8, e8) = fetch_failures(&b8.nodes, s, BlockRule::PerLane);
        if s == 16 {
            // Lanes 14 and 15 hand out `count` from block 1 (zeros at 16 lanes): every node with
            // a leaf child reads it as an inner node.
            let with_leaf = b8.nodes.iter().filter(|n| n.count.iter().any(|&c| c > 0)).count();
            assert_eq!(bad8, with_leaf, "bvh8 at 16 lanes: the old rule should fail on every node with a leaf child");
            assert!(e8.unwrap().contains("child"), "the failure names the lane and child");
        } else {
            assert_eq!(bad8, 0, "bvh8 at {s}: {e8:?}");
        }
    }
}

/// A small deterministic generator (the test needs variety, not quality).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> u32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 33) as u32
    }
}

/// The leaf step: per unit (slot) a hit distance or a miss; ties are frequent (few distinct t).
/// Sequential (leaf.glsl's leaf loop): in slot order, a hit at t <= best is kept.
fn leaf_sequential(t: &[Option<f32>], tmax: f32) -> Option<(f32, usize)> {
    let mut best = None;
    let mut bt = tmax;
    for (slot, &x) in t.iter().enumerate() {
        if let Some(x) = x.filter(|&x| x <= bt) {
            bt = x;
            best = Some((x, slot));
        }
    }
    best
}

/// coop_leaf with S lanes over `units` units of `per` slots each (4 for the quad intersectors):
/// lane k runs the same chain over units k, k + S, ... with its own bound, then the smallest t
/// over the lanes wins, ties to the higher slot (subgroupMin, then subgroupMax of slot + 1).
fn leaf_coop(t: &[Option<f32>], tmax: f32, s: usize, per: usize) -> Option<(f32, usize)> {
    let units = t.len().div_ceil(per);
    let mut lane_best: Vec<Option<(f32, usize)>> = vec![None; s];
    let mut tested = vec![0; t.len()];
    for (k, lb) in lane_best.iter_mut().enumerate() {
        let mut bt = tmax;
        let mut i = 0;
        while i < units {
            if i + k < units {
                for c in 0..per {
                    let slot = (i + k) * per + c;
                    if slot < t.len() {
                        tested[slot] += 1;
                        if let Some(x) = t[slot].filter(|&x| x <= bt) {
                            bt = x;
                            *lb = Some((x, slot));
                        }
                    }
                }
            }
            i += s;
        }
    }
    assert!(tested.iter().all(|&n| n == 1), "S = {s}: slots tested {tested:?} times");
    let best = lane_best.iter().flatten().map(|b| b.0).fold(f32::INFINITY, f32::min);
    lane_best.iter().flatten().filter(|b| b.0 == best).map(|b| b.1).max().map(|slot| (best, slot))
}

#[test]
fn coop_leaf_step_equals_the_sequential_leaf_loop_at_every_width() {
    let mut rng = Lcg(16);
    for count in 1..=31usize {
        for trial in 0..40 {
            let t: Vec<Option<f32>> = (0..count)
                .map(|_| match rng.next() % 4 {
                    0 => None,
                    r => Some((r + rng.next() % 3) as f32),
                })
                .collect();
            let tmax = if trial % 3 == 0 { 3.0 } else { f32::INFINITY };
            let want = leaf_sequential(&t, tmax);
            for s in WIDTHS {
                for per in [1, 4] {
                    assert_eq!(leaf_coop(&t, tmax, s, per), want, "count {count} S {s} per {per}: {t:?}");
                }
            }
        }
    }
}

/// The push order of an inner node's hit children at S lanes: lane k holds children k (t0) and
/// k + S (t1); each step takes the farthest (subgroupMax of t), ties to the higher slot
/// (subgroupMax of slot + 1); the last one left is visited next.
fn push_order(t: &[Option<f32>], s: usize) -> (Vec<usize>, Option<usize>) {
    let w = t.len();
    let get = |c: usize| if c < w { t[c].unwrap_or(f32::NEG_INFINITY) } else { f32::NEG_INFINITY };
    let mut t0: Vec<f32> = (0..s).map(get).collect();
    let mut t1: Vec<f32> = (0..s).map(|k| if s < w { get(k + s) } else { f32::NEG_INFINITY }).collect();
    let hits = t0.iter().chain(&t1).filter(|&&x| x > f32::NEG_INFINITY).count();
    let mut pushed = vec![];
    if hits == 0 {
        return (pushed, None);
    }
    for _ in 1..hits {
        let far = t0.iter().chain(&t1).copied().fold(f32::NEG_INFINITY, f32::max);
        let slot = (0..s)
            .map(|k| {
                if t1[k] == far {
                    k + s + 1
                } else if t0[k] == far {
                    k + 1
                } else {
                    0
                }
            })
            .max()
            .unwrap()
            - 1;
        pushed.push(slot);
        if slot < s {
            t0[slot] = f32::NEG_INFINITY;
        } else {
            t1[slot - s] = f32::NEG_INFINITY;
        }
    }
    let next = (0..s)
        .find(|&k| t0[k] > f32::NEG_INFINITY)
        .or_else(|| (0..s).find(|&k| t1[k] > f32::NEG_INFINITY).map(|k| k + s));
    (pushed, next)
}

#[test]
fn coop_child_order_is_far_to_near_and_the_same_at_every_width() {
    let mut rng = Lcg(4);
    for w in [2usize, 4, 8] {
        for _ in 0..2000 {
            let t: Vec<Option<f32>> = (0..w)
                .map(|_| match rng.next() % 3 {
                    0 => None,
                    _ => Some((rng.next() % 4) as f32),
                })
                .collect();
            // The rule: by t descending, ties by slot descending; all but the last pushed.
            let mut order: Vec<usize> = (0..w).filter(|&c| t[c].is_some()).collect();
            order.sort_by(|&a, &b| t[b].partial_cmp(&t[a]).unwrap().then(b.cmp(&a)));
            let next = order.pop();
            for s in WIDTHS {
                assert_eq!(push_order(&t, s), (order.clone(), next), "width {w}, S {s}: {t:?}");
            }
        }
    }
}

/// main's loop over the lanes' rays: a uvec4 ballot, the lowest set bit each round, cleared in
/// word j / 32.
#[test]
fn ballot_loop_visits_each_valid_lane_once_in_order_up_to_128_lanes() {
    let mut rng = Lcg(64);
    for s in [4usize, 8, 16, 32, 64, 128] {
        for _ in 0..200 {
            let valid: Vec<bool> = (0..s).map(|_| !rng.next().is_multiple_of(3)).collect();
            let mut todo = [0u32; 4];
            for (k, _) in valid.iter().enumerate().filter(|(_, &v)| v) {
                todo[k / 32] |= 1 << (k % 32);
            }
            let mut seen = vec![];
            while todo.iter().map(|w| w.count_ones()).sum::<u32>() > 0 {
                let j = todo
                    .iter()
                    .enumerate()
                    .find(|(_, &w)| w != 0)
                    .map(|(i, w)| 32 * i + w.trailing_zeros() as usize)
                    .unwrap();
                todo[j / 32] &= !(1 << (j % 32));
                seen.push(j);
            }
            let want: Vec<usize> = (0..s).filter(|&k| valid[k]).collect();
            assert_eq!(seen, want, "S = {s}");
        }
    }
}

/// GLSL sources, comments stripped (line comments only: the kernels use no block comments).
fn glsl_files() -> Vec<(String, String)> {
    let mut out = vec![];
    let mut dirs = vec![common::root().join("glsl")];
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "glsl" || x == "comp") {
                let text = std::fs::read_to_string(&p).unwrap();
                assert!(!text.contains("/*"), "{}: block comment (the scan strips // only)", p.display());
                let code: String = text.lines().map(|l| l.split("//").next().unwrap()).collect::<Vec<_>>().join("\n");
                out.push((p.strip_prefix(common::root()).unwrap().display().to_string(), code));
            }
        }
    }
    assert!(out.len() > 20);
    out
}

/// Identifiers, numbers and operators of GLSL code (two-character operators kept whole).
fn tokens(code: &str) -> Vec<String> {
    let c: Vec<char> = code.chars().collect();
    let mut out = vec![];
    let mut i = 0;
    while i < c.len() {
        let start = i;
        if c[i].is_whitespace() {
            i += 1;
            continue;
        } else if c[i].is_ascii_alphabetic() || c[i] == '_' {
            while i < c.len() && (c[i].is_ascii_alphanumeric() || c[i] == '_') {
                i += 1;
            }
        } else if c[i].is_ascii_digit() {
            while i < c.len() && (c[i].is_ascii_alphanumeric() || c[i] == '.') {
                i += 1;
            }
        } else {
            let two: String = c[i..(i + 2).min(c.len())].iter().collect();
            i += if ["==", "!=", "<=", ">=", "<<", ">>", "&&", "||", "+=", "-="].contains(&two.as_str()) {
                2
            } else {
                1
            };
        }
        out.push(c[start..i].iter().collect());
    }
    out
}

fn is_number(t: &str) -> bool {
    t.starts_with(|c: char| c.is_ascii_digit())
}

/// The tokens of the call whose name is at `at` (name, `(`, ..., `)`), or None.
fn call_args(t: &[String], at: usize) -> Option<&[String]> {
    if t.get(at + 1).map(String::as_str) != Some("(") {
        return None;
    }
    let mut depth = 0;
    for j in at + 1..t.len() {
        match t[j].as_str() {
            "(" => depth += 1,
            ")" => {
                depth -= 1;
                if depth == 0 {
                    return Some(&t[at + 2..j]);
                }
            }
            _ => {}
        }
    }
    None
}

/// The width assumptions the audit removed (glsl/README.md, "Subgroup widths"), in `code`.
fn width_assumptions(code: &str) -> Vec<String> {
    let t = tokens(code);
    let mut found = vec![];
    const ARITH: [&str; 9] = ["==", "!=", "<=", ">=", "<", ">", "%", "&", "/"];
    for i in 0..t.len() {
        let tok = t[i].as_str();
        let next = |k: usize| t.get(i + k).map(String::as_str).unwrap_or("");
        let prev = |k: usize| if i >= k { t[i - k].as_str() } else { "" };
        // A ballot is a uvec4: one word holds 32 lanes, not 64.
        if tok == "subgroupBallot" {
            if let Some(args) = call_args(&t, i) {
                let after = i + 3 + args.len();
                let a = t.get(after).map(String::as_str).unwrap_or("");
                let b = t.get(after + 1).map(String::as_str).unwrap_or("");
                if (a == "." && ["x", "y", "z", "w", "r", "s"].contains(&b)) || (a == "[" && is_number(b)) {
                    found.push("a ballot read as one uint".into());
                } else if prev(1) == "=" && prev(3) == "uint" {
                    found.push("a ballot kept in one uint".into());
                }
            }
        }
        // A literal width tied to the lanes.
        if tok == "gl_SubgroupSize" || tok == "gl_SubgroupInvocationID" {
            if ARITH.contains(&next(1)) && is_number(next(2)) {
                found.push(format!("`{tok} {} {}`: a literal subgroup width", next(1), next(2)));
            }
            if ARITH.contains(&prev(1)) && is_number(prev(2)) {
                found.push(format!("`{} {} {tok}`: a literal subgroup width", prev(2), prev(1)));
            }
        }
        // Workgroup memory sized for an assumed width.
        if tok == "shared" && next(3) == "[" && is_number(next(4)) {
            found.push(format!("`shared {} {}[{}]`: a shared array sized by a literal", next(1), next(2), next(4)));
        }
        // A literal source lane.
        if tok.starts_with("subgroupShuffle") || tok == "subgroupBroadcast" {
            if let Some(args) = call_args(&t, i) {
                if let Some(p) = args.iter().rposition(|a| a == ",") {
                    if args.len() == p + 2 && is_number(&args[p + 1]) {
                        found.push(format!("{tok}(.., {}): a literal lane index", args[p + 1]));
                    }
                }
            }
        }
        // coop_texel's block from a lane's own texel index: the source lane's choice wins.
        if tok == "block" && next(1) == "=" && next(2) == "t" && next(3) == "/" {
            found.push("`block = t / ...`: a lane-dependent block shuffled".into());
        }
    }
    found
}

/// The scanner finds what it looks for (each pattern once in a snippet written for it).
#[test]
fn the_width_scan_finds_each_pattern() {
    for (code, what) in [
        ("uint live = subgroupBallot(valid).x;", "one uint"),
        ("uint live = subgroupBallot(valid);", "kept in one uint"),
        ("if (gl_SubgroupSize == 32u) {}", "literal subgroup width"),
        ("uint lane = gl_SubgroupInvocationID & 7u;", "literal subgroup width"),
        ("uint w = 8u / gl_SubgroupSize;", "literal subgroup width"),
        ("shared float tile[64];", "shared array"),
        ("float x = subgroupShuffle(y, 3u);", "literal lane"),
        ("uint block = t / s;", "lane-dependent block"),
    ] {
        let f = width_assumptions(code);
        assert!(f.len() == 1 && f[0].contains(what), "{code}: {f:?}");
    }
    assert!(width_assumptions(
        "uvec4 b = subgroupBallot(v); shared float tile[WORKGROUP_SIZE]; x = subgroupShuffle(y, t % gl_SubgroupSize);"
    )
    .is_empty());
}

#[test]
fn glsl_assumes_no_subgroup_width() {
    let mut found = vec![];
    let mut lane_code = 0;
    for (path, code) in glsl_files() {
        found.extend(width_assumptions(&code).into_iter().map(|f| format!("{path}: {f}")));
        lane_code += code.matches("gl_SubgroupSize").count();
    }
    assert!(lane_code > 0, "the scan saw no subgroup code at all");
    assert!(found.is_empty(), "width assumptions in glsl/:\n{}", found.join("\n"));
}

/// A kernel that hands work to lanes by index must be created with full subgroups; the host
/// recognises one by its SPIR-V (`reads_subgroup_lanes`). Every module that moves values between
/// lanes by a lane's index (shuffle, ballot, broadcast of a given lane) is such a kernel, and the
/// cooperative kernels are among them. Broadcasting the first active lane's value
/// (`subgroupBroadcastFirst`, the packet kernels on bvh2 and qbvh4) names no lane: it is defined
/// in a partial subgroup too, so it does not count.
#[test]
fn every_lane_indexing_kernel_is_recognised_for_full_subgroups() {
    // GroupNonUniformBallot 339, Broadcast 337, Shuffle 345, ShuffleXor 346, ShuffleUp 347,
    // ShuffleDown 348 (SPIR-V spec 3.52.24).
    const LANE_OPS: [u32; 6] = [337, 339, 345, 346, 347, 348];
    let mut coop = 0;
    for k in KERNELS {
        let words = k.words();
        let reads = reads_subgroup_lanes(&words).unwrap();
        let mut i = 5;
        let mut lane_op = false;
        while i < words.len() {
            let (n, op) = ((words[i] >> 16) as usize, words[i] & 0xffff);
            lane_op |= LANE_OPS.contains(&op);
            i += n.max(1);
        }
        if lane_op {
            assert!(reads, "{}: moves values between lanes but reads no lane index", k.name);
        }
        if k.kernel == "raycast_coop" {
            assert!(reads, "{}", k.name);
            coop += 1;
        }
        // The packet kernels on the structure-of-arrays layouts load a node spread over the lanes.
        if k.kernel == "raycast_packet" && (k.layout == "bvh4" || k.layout == "bvh8") {
            assert!(reads, "{}", k.name);
        }
        if k.kernel == "raycast" || k.kernel == "pathtrace" {
            assert!(!reads, "{}: would be refused where full subgroups are missing", k.name);
        }
    }
    assert!(coop > 0);
}

#[test]
fn coop_runs_at_workgroup_multiples_of_the_subgroup_and_refuses_others() {
    let lines = common::with_gpu(600, |ctx| {
        let s = ctx.info().subgroup_size;
        let bunny = common::bunny();
        let host = HostScene::build("bunny", &bunny, &BuildOptions::new(4)).unwrap();
        let reference = host.reference();
        let sizes = RaySetSizes { width: 40, height: 30, diffuse_per_hit: 1, random_rays: 2000, seed: 5 };
        let sets = ray_sets(&bunny, "bunny", &reference, &sizes, None).unwrap();
        let rays = &sets.iter().find(|(n, _)| n.to_string() == "random").unwrap().1;
        let ref_hits = reference.trace_all(rays, false);
        let mut lines = vec![format!("{} subgroup {s}", ctx.info().name)];
        for layout in [Layout::Bvh2, Layout::Bvh4, Layout::Bvh8] {
            let mut scene = host.upload(ctx, &SceneRequest::new(Method::Watertight).layout(layout)).unwrap();
            let base = scene.cast(ctx, Raycast::Closest, rays, &common::ONCE).unwrap().hits;
            scene.traversal = Traversal::Coop;
            let src = scene.kernel_source(Raycast::Closest).unwrap();
            for wg in [s, 2 * s, 64.max(s)] {
                let k = ctx.create_kernel_specialized(src, &[(SPEC_ID_WORKGROUP_SIZE, wg)]).unwrap();
                let h = scene.cast_with(ctx, &k, rays, &common::ONCE).unwrap().hits;
                let a = validate_hits(&bunny, rays, &h, &ref_hits).unwrap_or_else(|e| panic!("{layout} wg {wg}: {e}"));
                let differ = (0..rays.len()).filter(|&i| h[i] != base[i]).count();
                assert_eq!(differ, 0, "{layout} coop, workgroup {wg}, subgroup {s}: hits differ from while-if's");
                lines.push(format!("{layout} coop wg {wg}: {}", a.summary()));
            }
            let odd = s + s / 2;
            match ctx.create_kernel_specialized(src, &[(SPEC_ID_WORKGROUP_SIZE, odd)]) {
                Err(Error::Unsupported(m)) => {
                    assert!(
                        m.contains(src.name)
                            && m.contains(&format!("workgroup size {odd}"))
                            && m.contains(&format!("subgroup size {s}")),
                        "{m}"
                    );
                }
                Err(e) => panic!("{layout} workgroup {odd}: wrong error {e}"),
                Ok(_) => panic!("{layout}: workgroup {odd} with subgroups of {s} was accepted"),
            }
        }
        lines
    });
    println!("{}", lines.join("\n"));
}
