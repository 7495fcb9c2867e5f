//! A replay's hits against the repro's expected ones, ray by ray: what a driver developer reads
//! first ("same", or how many rays differ and how).

use serde::Serialize;

use crate::commands::hits::{change, DiffTolerance};
use crate::rays::Hit;

use super::folder::Query;

/// Rays listed one by one in a report (the rest are counted).
pub const LISTED: usize = 10;

/// How two hit lists of the same rays differ.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Differences {
    pub rays: usize,
    /// Rays whose hit records are equal bit for bit, or both misses (for an any-hit query: whose
    /// hit or miss is the same, which is all such a query promises).
    pub identical: usize,
    /// Closest hits on the same triangle whose t, u or v differ in their bits.
    pub same_triangle: usize,
    /// The largest difference in t among those, in units in the last place of f32.
    pub max_t_ulps: u32,
    /// Rays that hit another triangle, or hit where the other misses (either way).
    pub different_hit: usize,
    /// The first [`LISTED`] differing rays.
    pub first: Vec<RayDifference>,
}

/// One ray's two hits, written as `t=... id=... u=... v=...` or `miss` (t, u, v in full).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct RayDifference {
    pub ray: usize,
    pub expected: String,
    pub got: String,
}

impl Differences {
    /// `got` against `expected` (the same rays in the same order).
    pub fn of(query: Query, expected: &[Hit], got: &[Hit]) -> Differences {
        assert_eq!(expected.len(), got.len(), "hits of the same rays");
        let mut d = Differences {
            rays: expected.len(),
            identical: 0,
            same_triangle: 0,
            max_t_ulps: 0,
            different_hit: 0,
            first: vec![],
        };
        for (ray, (e, g)) in expected.iter().zip(got).enumerate() {
            // `hits diff`'s rule at zero tolerance; an occlusion query promises hit or miss only.
            let what = match query {
                Query::Closest => change(e, g, &DiffTolerance::EXACT),
                Query::Any => (e.is_hit() != g.is_hit()).then_some("hit or miss"),
            };
            match what {
                None => {
                    d.identical += 1;
                    continue;
                }
                Some("t" | "u/v") => {
                    d.same_triangle += 1;
                    d.max_t_ulps = d.max_t_ulps.max(ulps(e.t, g.t));
                }
                Some(_) => d.different_hit += 1,
            }
            if d.first.len() < LISTED {
                d.first.push(RayDifference { ray, expected: show(e), got: show(g) });
            }
        }
        d
    }

    pub fn same(&self) -> bool {
        self.identical == self.rays
    }

    /// One line: `same: ...` or `N of M rays differ: ...`.
    pub fn verdict(&self) -> String {
        if self.same() {
            return format!("same: all {} rays' hits are identical to the expected ones", self.rays);
        }
        let mut parts = vec![];
        if self.different_hit > 0 {
            parts.push(format!("{} hit another triangle or hit/miss the other way", self.different_hit));
        }
        if self.same_triangle > 0 {
            parts.push(format!(
                "{} hit the same triangle at another t, u or v (t up to {} ulps apart)",
                self.same_triangle, self.max_t_ulps
            ));
        }
        format!("{} of {} rays differ: {}", self.rays - self.identical, self.rays, parts.join("; "))
    }

    /// The verdict and the first differing rays, as lines.
    pub fn to_text(&self) -> String {
        let mut s = format!("{}\n", self.verdict());
        for r in &self.first {
            s += &format!("  ray {:>7}: expected {}  got {}\n", r.ray, r.expected, r.got);
        }
        let unlisted = self.rays - self.identical - self.first.len();
        if unlisted > 0 {
            s += &format!("  ... and {unlisted} more\n");
        }
        s
    }
}

/// A hit as `t=... id=... u=... v=...`, or `miss`.
fn show(h: &Hit) -> String {
    if h.is_hit() {
        format!("t={:e} id={} u={:e} v={:e}", h.t, h.id, h.u, h.v)
    } else {
        "miss".into()
    }
}

/// Units in the last place between two finite f32 of the same sign (their distance in the
/// ordered integers of the format); `u32::MAX` across signs or for a non-finite value.
fn ulps(a: f32, b: f32) -> u32 {
    if !(a.is_finite() && b.is_finite()) || a.is_sign_negative() != b.is_sign_negative() {
        return if a == b { 0 } else { u32::MAX };
    }
    a.to_bits().abs_diff(b.to_bits())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hit(t: f32, id: u32) -> Hit {
        Hit { t, id, u: 0.25, v: 0.5 }
    }

    #[test]
    fn equal_hits_are_the_same_and_each_kind_of_difference_is_counted() {
        let expected = vec![hit(1.0, 3), hit(2.0, 4), Hit::MISS, hit(5.0, 7), hit(6.0, 8)];
        assert!(Differences::of(Query::Closest, &expected, &expected).same());

        let mut got = expected.clone();
        got[1].t = f32::from_bits(2.0f32.to_bits() + 3); // same triangle, 3 ulps further
        got[2] = hit(9.0, 1); // hits where the expected misses
        got[4].id = 9; // another triangle
        let d = Differences::of(Query::Closest, &expected, &got);
        assert_eq!((d.rays, d.identical, d.same_triangle, d.max_t_ulps, d.different_hit), (5, 2, 1, 3, 2));
        assert_eq!(d.first.iter().map(|r| r.ray).collect::<Vec<_>>(), [1, 2, 4]);
        assert!(d.verdict().starts_with("3 of 5 rays differ: 2 hit another triangle"), "{}", d.verdict());
        assert!(d.verdict().contains("t up to 3 ulps"), "{}", d.verdict());
    }

    #[test]
    fn an_any_hit_query_compares_hit_or_miss_only() {
        let expected = vec![hit(1.0, 3), Hit::MISS];
        let got = vec![hit(4.0, 9), hit(1.0, 1)];
        let d = Differences::of(Query::Any, &expected, &got);
        assert_eq!((d.identical, d.different_hit, d.same_triangle), (1, 1, 0));
    }

    #[test]
    fn only_the_first_rays_are_listed_and_the_rest_counted() {
        let expected = vec![hit(1.0, 1); 25];
        let got = vec![hit(1.0, 2); 25];
        let d = Differences::of(Query::Closest, &expected, &got);
        assert_eq!(d.first.len(), LISTED);
        assert!(d.to_text().ends_with("  ... and 15 more\n"), "{}", d.to_text());
    }

    #[test]
    fn ulps_count_representable_floats_between() {
        assert_eq!(ulps(1.0, 1.0), 0);
        assert_eq!(ulps(1.0, f32::from_bits(1.0f32.to_bits() + 1)), 1);
        assert_eq!(ulps(1.0, -1.0), u32::MAX);
        assert_eq!(ulps(f32::INFINITY, f32::INFINITY), 0);
    }
}
