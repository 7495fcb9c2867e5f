//! Plain-text, Markdown and CSV tables for command output and results files, and the median /
//! min / max summary every timing is reported as.

/// What a command hands back: a serde struct, printed as JSON (`--json`) or as text made from
/// the same struct.
pub trait Report: serde::Serialize {
    /// The text the command prints without `--json`.
    fn to_text(&self) -> String;

    /// The struct as pretty JSON.
    fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("reports serialise")
    }
}

/// `value` as pretty JSON through `serde_json::Value`: keys sorted, f32 values written as the
/// f64 they widen to. The reports that were built as JSON values before they were structs
/// (raycast, render, bvh, steps, spirv, analyze) print this way, so their output stays
/// byte-comparable with earlier versions.
pub fn value_json(value: &impl serde::Serialize) -> String {
    let v = serde_json::to_value(value).expect("reports serialise");
    serde_json::to_string_pretty(&v).expect("values serialise")
}

/// A table of strings; numeric-looking columns are right-aligned in text output.
#[derive(Clone, Debug, Default)]
pub struct Table {
    pub headers: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

impl Table {
    pub fn new<S: Into<String>>(headers: impl IntoIterator<Item = S>) -> Table {
        Table { headers: headers.into_iter().map(Into::into).collect(), rows: vec![] }
    }

    pub fn row<S: Into<String>>(&mut self, cells: impl IntoIterator<Item = S>) {
        let r: Vec<String> = cells.into_iter().map(Into::into).collect();
        assert_eq!(r.len(), self.headers.len(), "row width");
        self.rows.push(r);
    }

    fn numeric(&self, col: usize) -> bool {
        self.rows.iter().all(|r| {
            let c = r[col].trim_end_matches('%');
            c.is_empty() || c == "-" || c.split(['(', ' ', '/']).next().is_some_and(|x| x.parse::<f64>().is_ok())
        })
    }

    pub fn to_text(&self) -> String {
        let n = self.headers.len();
        let widths: Vec<usize> = (0..n)
            .map(|c| {
                self.rows.iter().map(|r| r[c].chars().count()).chain([self.headers[c].chars().count()]).max().unwrap()
            })
            .collect();
        let right: Vec<bool> = (0..n).map(|c| self.numeric(c)).collect();
        let fmt = |cells: &[String]| {
            let parts: Vec<String> = cells
                .iter()
                .enumerate()
                .map(
                    |(c, s)| {
                        if right[c] {
                            format!("{s:>w$}", w = widths[c])
                        } else {
                            format!("{s:<w$}", w = widths[c])
                        }
                    },
                )
                .collect();
            parts.join("  ").trim_end().to_owned()
        };
        let mut out = fmt(&self.headers) + "\n";
        out += &widths.iter().map(|&w| "-".repeat(w)).collect::<Vec<_>>().join("  ");
        out.push('\n');
        for r in &self.rows {
            out += &fmt(r);
            out.push('\n');
        }
        out
    }

    pub fn to_markdown(&self) -> String {
        let right: Vec<bool> = (0..self.headers.len()).map(|c| self.numeric(c)).collect();
        let mut out = format!("| {} |\n", self.headers.join(" | "));
        out += &format!("|{}|\n", right.iter().map(|&r| if r { "---:" } else { "---" }).collect::<Vec<_>>().join("|"));
        for r in &self.rows {
            out += &format!("| {} |\n", r.join(" | "));
        }
        out
    }
}

/// Median, min and max of a sample.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Summary {
    pub median: f64,
    pub min: f64,
    pub max: f64,
    pub runs: usize,
}

impl Summary {
    pub fn of(xs: &[f64]) -> Option<Summary> {
        if xs.is_empty() {
            return None;
        }
        let mut v = xs.to_vec();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) };
        Some(Summary { median, min: v[0], max: v[n - 1], runs: n })
    }
}

/// Whether a part of a report could be measured, and if not, why not (a profile section, the
/// driver statistics of a device).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Measured,
    Unsupported,
    NotApplicable,
    Skipped,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_median_min_max() {
        let s = Summary::of(&[3.0, 1.0, 2.0]).unwrap();
        assert_eq!((s.median, s.min, s.max, s.runs), (2.0, 1.0, 3.0, 3));
        assert_eq!(Summary::of(&[4.0, 1.0, 2.0, 3.0]).unwrap().median, 2.5);
        assert!(Summary::of(&[]).is_none());
    }

    #[test]
    fn aligns_text_and_renders_markdown() {
        let mut t = Table::new(["method", "Mrays/s"]);
        t.row(["mt", "12.5"]);
        t.row(["quad-unit", "3.25"]);
        let text = t.to_text();
        assert_eq!(text.lines().nth(2).unwrap(), "mt            12.5");
        assert!(t.to_markdown().contains("|---|---:|"));
    }
}
