//! Which of its node's 8 slots each child takes ([`SlotOrder`]): the octant order of the
//! paper's sec. 3.2, greedy or exact, or the collapse's plain order.

use glam::Vec3;
use serde::Serialize;

use super::CW_WIDTH;

/// How a node's children are assigned to its 8 slots (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SlotOrder {
    /// Cheapest (child, slot) pair first, repeatedly.
    Greedy,
    /// The assignment of least total cost (the optimum the paper's auction approximates).
    Exact,
    /// The collapse's slot order, slots 0.. (no octant ordering; for comparison).
    Plain,
}

/// `cost[i][s]`: child `i` (box centre `c`) in slot `s` of a node with box centre `parent`.
pub(super) fn slot_costs(parent: Vec3, centres: &[Vec3]) -> Vec<[f64; CW_WIDTH]> {
    centres
        .iter()
        .map(|c| {
            let d = (*c - parent).as_dvec3();
            std::array::from_fn(|s| {
                let sign = |k: usize| if s >> k & 1 == 1 { -1.0 } else { 1.0 };
                d.x * sign(0) + d.y * sign(1) + d.z * sign(2)
            })
        })
        .collect()
}

/// Slot of each child under `how`.
pub(super) fn assign_slots(how: SlotOrder, cost: &[[f64; CW_WIDTH]]) -> Vec<usize> {
    let n = cost.len();
    match how {
        SlotOrder::Plain => (0..n).collect(),
        SlotOrder::Greedy => {
            let mut pairs: Vec<(f64, usize, usize)> =
                (0..n).flat_map(|i| (0..CW_WIDTH).map(move |s| (cost[i][s], i, s))).collect();
            pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
            let mut slot = vec![usize::MAX; n];
            let mut taken = [false; CW_WIDTH];
            for (_, i, s) in pairs {
                if slot[i] == usize::MAX && !taken[s] {
                    slot[i] = s;
                    taken[s] = true;
                }
            }
            slot
        }
        SlotOrder::Exact => {
            // Depth-first over children, slots free; prune with the cost so far plus each
            // remaining child's cheapest slot.
            let best_row: Vec<f64> = cost.iter().map(|r| r.iter().copied().fold(f64::INFINITY, f64::min)).collect();
            let mut rest = vec![0.0; n + 1];
            for i in (0..n).rev() {
                rest[i] = rest[i + 1] + best_row[i];
            }
            struct Search<'a> {
                cost: &'a [[f64; CW_WIDTH]],
                rest: Vec<f64>,
                cur: Vec<usize>,
                best: Vec<usize>,
                best_cost: f64,
            }
            fn go(st: &mut Search, i: usize, taken: u32, sum: f64) {
                if sum + st.rest[i] >= st.best_cost {
                    return;
                }
                if i == st.cost.len() {
                    st.best_cost = sum;
                    st.best = st.cur.clone();
                    return;
                }
                let mut order: [usize; CW_WIDTH] = std::array::from_fn(|s| s);
                order.sort_by(|&a, &b| st.cost[i][a].total_cmp(&st.cost[i][b]));
                for s in order {
                    if taken >> s & 1 == 0 {
                        st.cur[i] = s;
                        go(st, i + 1, taken | 1 << s, sum + st.cost[i][s]);
                    }
                }
            }
            // Start from the greedy assignment's cost (a bound to beat, and the answer on ties).
            let greedy = assign_slots(SlotOrder::Greedy, cost);
            let gcost: f64 = greedy.iter().enumerate().map(|(i, &s)| cost[i][s]).sum();
            let mut st = Search { cost, rest, cur: vec![0; n], best: greedy, best_cost: gcost };
            go(&mut st, 0, 0, 0.0);
            st.best
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slot_orders_are_permutations_and_exact_is_cheapest() {
        let mut s = 5u64;
        let mut rnd = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32) / (1u64 << 24) as f32 - 0.5
        };
        for n in 1..=8 {
            for _ in 0..50 {
                let centres: Vec<Vec3> = (0..n).map(|_| Vec3::new(rnd(), rnd(), rnd())).collect();
                let cost = slot_costs(Vec3::ZERO, &centres);
                let total = |a: &[usize]| a.iter().enumerate().map(|(i, &s)| cost[i][s]).sum::<f64>();
                let mut best = f64::INFINITY;
                // Brute force over all injective maps for small n.
                if n <= 4 {
                    let mut a = vec![0; n];
                    fn all(i: usize, a: &mut Vec<usize>, used: u32, f: &mut dyn FnMut(&[usize])) {
                        if i == a.len() {
                            f(a);
                            return;
                        }
                        for s in 0..8 {
                            if used >> s & 1 == 0 {
                                a[i] = s;
                                all(i + 1, a, used | 1 << s, f);
                            }
                        }
                    }
                    all(0, &mut a, 0, &mut |a| best = best.min(total(a)));
                }
                for how in [SlotOrder::Greedy, SlotOrder::Exact, SlotOrder::Plain] {
                    let a = assign_slots(how, &cost);
                    let mut sorted = a.clone();
                    sorted.sort_unstable();
                    sorted.dedup();
                    assert_eq!(sorted.len(), n, "{how:?} {a:?}");
                    assert!(a.iter().all(|&s| s < 8));
                }
                let (g, e) =
                    (total(&assign_slots(SlotOrder::Greedy, &cost)), total(&assign_slots(SlotOrder::Exact, &cost)));
                assert!(e <= g + 1e-12);
                if n <= 4 {
                    assert!((e - best).abs() < 1e-12, "n {n}: exact {e} brute {best}");
                }
            }
        }
        // A child towards -x-y-z goes to the slot of rays in octant 0 (all positive): they meet it first.
        let cost = slot_costs(Vec3::ZERO, &[Vec3::splat(-1.0), Vec3::splat(1.0)]);
        assert_eq!(assign_slots(SlotOrder::Exact, &cost), vec![0, 7]);
    }
}
