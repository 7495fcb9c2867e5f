//! `--shard I/N`, the one way bench, build-bench, accuracy and study split their matrix: a shard
//! takes every N-th unit, round-robin from unit I, a unit being what must be measured side by
//! side in one run (a scene's methods, layouts and peers; a (scene, leaf size) group; a (leaf
//! size, layout) group). Every shard plans the whole matrix in its rows file ([`crate::rows::Plan`]),
//! so that `trilab merge` can name the cells no shard measured, and its report says how much of
//! the matrix it measured ([`partial`]).

use crate::error::{Error, Result};
pub use crate::rows::Shard;
use crate::rows::{plan_matches, Cell, Row};

/// A command's matrix as units to share out: an `outer` x `inner` grid, numbered outer-major
/// (unit `(i, j)` is number `i * inner + j`), and the shard this run took, if any.
#[derive(Clone, Copy, Debug)]
pub struct Split {
    pub shard: Option<Shard>,
    pub outer: usize,
    pub inner: usize,
}

impl Split {
    pub fn new(shard: Option<Shard>, outer: usize, inner: usize) -> Split {
        Split { shard, outer, inner }
    }

    /// How many units the matrix has.
    pub fn units(&self) -> usize {
        self.outer * self.inner
    }

    /// Whether this run measures unit `(i, j)`: always without a shard, else round-robin over
    /// the units ([`Shard::owns`]).
    pub fn runs(&self, i: usize, j: usize) -> bool {
        self.shard.is_none_or(|s| s.owns(i * self.inner + j))
    }

    /// Whether this run measures any unit of row `i`.
    pub fn runs_any(&self, i: usize) -> bool {
        (0..self.inner).any(|j| self.runs(i, j))
    }

    /// How many units this run measures.
    pub fn owned(&self) -> usize {
        (0..self.outer).map(|i| (0..self.inner).filter(|&j| self.runs(i, j)).count()).sum()
    }

    /// Refuses more shards than units, naming `--shard`, before any work; `takes` says what a
    /// shard of this command takes whole and how many this run has.
    pub fn check(&self, takes: &str) -> Result<()> {
        match self.shard {
            Some(shard) if shard.count as usize > self.units() => {
                Err(Error::Usage(format!("--shard {shard}: {takes}; use at most {} shard(s)", self.units())))
            }
            _ => Ok(()),
        }
    }
}

/// `partial: shard I/N, X of Y cells of the matrix (whole ...); ...` for a sharded run (`whole`:
/// the units it takes), `None` for a whole one: X counts the planned cells some row fills
/// ([`plan_matches`]).
pub fn partial(shard: Option<Shard>, plan: &[Cell], rows: &[Row], whole: &str) -> Option<String> {
    let shard = shard?;
    let measured = plan.iter().filter(|c| rows.iter().any(|r| plan_matches(c, &r.cell))).count();
    Some(format!(
        "partial: shard {shard}, {measured} of {} cells of the matrix ({whole}); `trilab merge` of every shard's \
         folder joins the matrix",
        plan.len()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Units are numbered outer-major and dealt round-robin: every unit to exactly one shard.
    #[test]
    fn a_split_deals_every_unit_to_one_shard() {
        let shards: Vec<Split> = (1..=3).map(|i| Split::new(Some(Shard { index: i, count: 3 }), 2, 4)).collect();
        for i in 0..2 {
            for j in 0..4 {
                assert_eq!(shards.iter().filter(|s| s.runs(i, j)).count(), 1, "unit ({i}, {j})");
            }
        }
        assert!(shards[0].runs(0, 0) && shards[1].runs(0, 1) && shards[1].runs(1, 0) && shards[2].runs(1, 1));
        assert_eq!(shards.iter().map(Split::owned).collect::<Vec<_>>(), [3, 3, 2]);
        let whole = Split::new(None, 2, 4);
        assert!(whole.runs_any(1) && whole.owned() == 8 && whole.check("x").is_ok());
        let e = Split::new(Some(Shard { index: 1, count: 9 }), 2, 4).check("it has 8").unwrap_err().to_string();
        assert!(e.contains("--shard 1/9: it has 8; use at most 8 shard(s)"), "{e}");
    }
}
