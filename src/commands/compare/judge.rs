//! One figure judged: its verdict by class (a count exactly, correctness by direction, a
//! timing by its min-max spread) and whether it passed the threshold.

use serde::Serialize;

use crate::rows::{Better, Class, Figure};

/// What a figure's comparison found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Verdict {
    /// A timing whose ranges do not overlap, NEW the faster.
    Faster,
    /// A timing whose ranges do not overlap, NEW the slower.
    Slower,
    /// A timing whose ranges overlap: no real difference.
    WithinSpread,
    /// A timing of one run on a side: no range to judge by.
    NoSpread,
    /// A count or correctness figure that improved.
    Better,
    /// A count or correctness figure that got worse.
    Worse,
    /// A count or correctness figure that is equal.
    Unchanged,
}

impl std::fmt::Display for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Verdict::Faster => "faster",
            Verdict::Slower => "slower",
            Verdict::WithinSpread => "within spread",
            Verdict::NoSpread => "no spread",
            Verdict::Better => "better",
            Verdict::Worse => "worse",
            Verdict::Unchanged => "unchanged",
        })
    }
}

/// One figure of one matched cell.
#[derive(Clone, Debug, Serialize)]
pub struct FigureChange {
    pub command: String,
    /// The cell's coordinates, `scene=bunny set=primary ...`.
    pub cell: String,
    pub figure: String,
    pub class: Class,
    pub unit: String,
    pub base: Figure,
    pub new: Figure,
    /// NEW's median over BASE's (`None` where BASE's is 0).
    pub ratio: Option<f64>,
    /// How many times worse NEW is (> 1) or better (< 1), oriented so that for a rate it is the
    /// inverse of `ratio` (a time's factor); `None` where a side is 0.
    pub factor: Option<f64>,
    /// Under the calibrated rule, a timing's factor over its command's geometric mean: what the
    /// verdict and the threshold judged (`None` under the raw rule and for other classes).
    pub relative_factor: Option<f64>,
    pub verdict: Verdict,
    /// A real change beyond the threshold (an improvement or a regression).
    pub beyond_threshold: bool,
    /// This change fails the comparison (exit status 1).
    pub regression: bool,
}

impl FigureChange {
    /// Whether the text prints it: real timing changes beyond the threshold, every count and
    /// correctness change.
    pub fn printed(&self) -> bool {
        match self.class {
            Class::Timing => self.beyond_threshold,
            Class::Count | Class::Correctness => self.verdict != Verdict::Unchanged,
        }
    }
}

/// NEW's figure against BASE's (same class and unit).
pub fn judge(base: &Figure, new: &Figure, threshold_pct: f64) -> (Verdict, Option<f64>, bool, bool) {
    let t = threshold_pct / 100.0;
    let factor = time_factor(base, new);
    let worse = match base.better {
        Better::Lower => new.median > base.median,
        Better::Higher => new.median < base.median,
    };
    // Beyond the threshold either way (1/f for an improvement); a change from or to 0 always is.
    let beyond = match factor {
        Some(f) if f > 0.0 => f.max(1.0 / f) - 1.0 > t,
        _ => base.median != new.median,
    };
    match base.class {
        Class::Timing => {
            let verdict = if base.runs < 2 || new.runs < 2 {
                Verdict::NoSpread
            } else if base.overlaps(new) {
                Verdict::WithinSpread
            } else if worse {
                Verdict::Slower
            } else {
                Verdict::Faster
            };
            let real = matches!(verdict, Verdict::Faster | Verdict::Slower);
            (verdict, factor, real && beyond, real && worse && beyond)
        }
        Class::Count | Class::Correctness => {
            let verdict = if base.median == new.median {
                Verdict::Unchanged
            } else if worse {
                Verdict::Worse
            } else {
                Verdict::Better
            };
            let regression = worse && (base.class == Class::Correctness || beyond);
            (verdict, factor, verdict != Verdict::Unchanged && beyond, regression)
        }
    }
}

/// How many times worse NEW is: a time's (or count's) ratio, a rate's inverse; `None` where the
/// divisor is 0.
pub(super) fn time_factor(base: &Figure, new: &Figure) -> Option<f64> {
    match base.better {
        Better::Lower => (base.median != 0.0).then(|| new.median / base.median),
        Better::Higher => (new.median != 0.0).then(|| base.median / new.median),
    }
}

/// `f` as if it took `factor` times less time: a time divided by it, a rate multiplied.
pub(super) fn scaled(f: &Figure, factor: f64) -> Figure {
    let k = match f.better {
        Better::Lower => 1.0 / factor,
        Better::Higher => factor,
    };
    Figure { median: f.median * k, min: f.min * k, max: f.max * k, ..f.clone() }
}
