//! The OBJ statements trilab does not draw, found in one pass over the text: lines (`l`), points
//! (`p`), faces of fewer than three vertices, free-form curves and surfaces, display and render
//! attributes, texture map libraries, `call`, `csh` and statements that are no OBJ statement at
//! all (tinyobjloader's `vw`, OpenSubdiv's `t`). Each is ignored with one warning per file and
//! key, naming its first line and how many more there are; docs/obj-mtl.md lists them all.
//!
//! tobj reads `l a b c ...` as a face (a polyline of three or more vertices became triangles),
//! so polylines are blanked ([`without_polylines`]) before tobj sees the text.

use std::borrow::Cow;
use std::path::Path;

use super::text;

/// Why a statement is ignored, by key; `None` for the statements trilab reads (and comments).
fn ignored(key: &str) -> Option<&'static str> {
    Some(match key {
        "v" | "vt" | "vn" | "f" | "o" | "g" | "s" | "usemtl" | "mtllib" => return None,
        k if k.starts_with('#') => return None,
        "l" => "(a polyline) is not a surface",
        "p" => "(points) is not a surface",
        "vp" | "cstype" | "deg" | "bmat" | "step" | "curv" | "curv2" | "surf" | "parm" | "trim" | "hole" | "scrv"
        | "sp" | "end" | "con" | "mg" => FREE_FORM,
        "bevel" | "c_interp" | "d_interp" | "lod" | "shadow_obj" | "trace_obj" | "ctech" | "stech" => {
            "(a display or render attribute) is not used"
        }
        "maplib" | "usemap" => "(texture maps) is not supported",
        "call" => "(reading another OBJ file) is not supported: that file's geometry is missing",
        "csh" => "(a shell command) is never run",
        _ => UNKNOWN,
    })
}

const FREE_FORM: &str = "(free-form geometry: curves and surfaces) is not supported";
const UNKNOWN: &str = "is not an OBJ statement trilab knows";

/// The key a face of fewer than three vertices is tallied under.
const SHORT_FACE: &str = "f<3";

/// At most this many different keys that are no OBJ statement are warned about one by one (a
/// file that is not OBJ text at all would give one per line); the rest are counted together.
const MAX_UNKNOWN_KEYS: usize = 16;

/// One ignored key: its first line (1-based) and how many lines hold it.
struct Tally {
    key: String,
    why: &'static str,
    first: usize,
    count: usize,
}

/// What [`survey`] found.
pub(super) struct Survey {
    tallies: Vec<Tally>,
    /// Lines of keys past [`MAX_UNKNOWN_KEYS`]: (first line, count).
    more_unknown: Option<(usize, usize)>,
}

/// Finds the statements trilab ignores. Reads each line's first word (and the first three
/// words of a face), allocating only per key found.
pub(super) fn survey(text: &str) -> Survey {
    let mut survey = Survey { tallies: Vec::new(), more_unknown: None };
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        let (key, why) = match ignored(key) {
            None if key == "f" && words.take(3).count() < 3 => (SHORT_FACE, "is not a surface"),
            None => continue,
            Some(why) => (key, why),
        };
        survey.add(key, why, n + 1);
    }
    survey
}

impl Survey {
    fn add(&mut self, key: &str, why: &'static str, line: usize) {
        if let Some(t) = self.tallies.iter_mut().find(|t| t.key == key) {
            t.count += 1;
            return;
        }
        if why == UNKNOWN && self.tallies.iter().filter(|t| t.why == UNKNOWN).count() >= MAX_UNKNOWN_KEYS {
            let (_, count) = self.more_unknown.get_or_insert((line, 0));
            *count += 1;
            return;
        }
        self.tallies.push(Tally { key: key.to_owned(), why, first: line, count: 1 });
    }

    /// Whether the text holds `l` lines, which tobj must not see ([`without_polylines`]).
    pub fn has_polylines(&self) -> bool {
        self.tallies.iter().any(|t| t.key == "l")
    }

    /// One warning per key, in the order of their first lines: "file:line: `key` why; ignored".
    pub fn warnings(&self, path: &Path) -> Vec<String> {
        let more = |count: usize| match count - 1 {
            0 => String::new(),
            n => format!(" ({} more such {})", n, if n == 1 { "line" } else { "lines" }),
        };
        let mut out: Vec<(usize, String)> = self
            .tallies
            .iter()
            .map(|t| {
                let what = if t.key == SHORT_FACE {
                    "`f` with fewer than three vertices".to_owned()
                } else {
                    format!("`{}`", text::shown(&t.key))
                };
                (t.first, format!("{}:{}: {what} {}; ignored{}", path.display(), t.first, t.why, more(t.count)))
            })
            .collect();
        if let Some((first, count)) = self.more_unknown {
            out.push((
                first,
                format!(
                    "{}:{first}: {count} more lines start with words that are no OBJ statement trilab knows; ignored",
                    path.display()
                ),
            ));
        }
        out.sort_by_key(|w| w.0);
        out.into_iter().map(|w| w.1).collect()
    }

    /// For a file that gives no triangles: the geometry it holds that trilab does not draw, as
    /// "; it holds ... (n lines), which trilab does not draw", or nothing.
    pub fn undrawn_geometry(&self) -> String {
        let mut free_form = 0;
        let mut held: Vec<String> = Vec::new();
        for t in &self.tallies {
            let what = match t.key.as_str() {
                "l" => "polylines (`l`)",
                "p" => "points (`p`)",
                SHORT_FACE => "faces of fewer than three vertices",
                _ if t.why == FREE_FORM => {
                    free_form += t.count;
                    continue;
                }
                _ => continue,
            };
            held.push(format!("{what} ({})", lines(t.count)));
        }
        if free_form > 0 {
            held.push(format!("free-form curves and surfaces ({})", lines(free_form)));
        }
        if held.is_empty() {
            String::new()
        } else {
            format!("; it holds {}, which trilab does not draw", held.join(" and "))
        }
    }
}

fn lines(n: usize) -> String {
    if n == 1 {
        "1 line".to_owned()
    } else {
        format!("{n} lines")
    }
}

/// `text` with every `l` line blank (line numbers kept), so tobj makes no faces of polylines.
pub(super) fn without_polylines(text: &str) -> Cow<'_, str> {
    text::edit_lines(text, |_, line| (line.split_whitespace().next() == Some("l")).then(String::new))
}

/// `text` with the colour of every coloured vertex (`v x y z r g b`) dropped, line for line.
/// tobj pairs colours with vertices by counting only the coloured ones, so a file that colours
/// some vertices and not others failed ("face vertex color index out of bounds"); trilab reads
/// no colours, and tinyobjloader accepts such files.
pub(super) fn without_vertex_colours(text: &str) -> Cow<'_, str> {
    text::edit_lines(text, |_, line| {
        let words: Vec<&str> = line.split_whitespace().collect();
        (words.len() == 7 && words[0] == "v").then(|| words[..4].join(" "))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_ignored_key_is_one_warning_with_its_first_line_and_count() {
        let text = "v 0 0 0\nl 1 2\ncurv 0 1 1 2\nl 2 3\nf 1 2\n# c\nvw 0 0 1\nl 1 3\nf 1 2 3\n";
        let s = survey(text);
        assert!(s.has_polylines());
        assert_eq!(
            s.warnings(Path::new("a.obj")),
            [
                "a.obj:2: `l` (a polyline) is not a surface; ignored (2 more such lines)",
                "a.obj:3: `curv` (free-form geometry: curves and surfaces) is not supported; ignored",
                "a.obj:5: `f` with fewer than three vertices is not a surface; ignored",
                "a.obj:7: `vw` is not an OBJ statement trilab knows; ignored",
            ]
        );
        assert_eq!(
            s.undrawn_geometry(),
            "; it holds polylines (`l`) (3 lines) and faces of fewer than three vertices (1 line) and free-form \
             curves and surfaces (1 line), which trilab does not draw"
        );
        assert_eq!(without_polylines(text).lines().filter(|l| l.is_empty()).count(), 3);
        assert_eq!(without_polylines(text).lines().count(), text.lines().count());
    }

    #[test]
    fn garbage_gives_a_bounded_number_of_warnings() {
        let text: String = (0..1000).map(|i| format!("k{i} 1\n")).collect();
        let w = survey(&text).warnings(Path::new("a.obj"));
        assert_eq!(w.len(), MAX_UNKNOWN_KEYS + 1);
        assert_eq!(
            w[MAX_UNKNOWN_KEYS],
            "a.obj:17: 984 more lines start with words that are no OBJ statement trilab knows; ignored"
        );
    }

    #[test]
    fn vertex_colours_are_dropped_line_for_line() {
        let text = "v 0 0 0\nv 1 0 0 1 0.5 0\nv 0 1 0 2\nvn 0 0 1 1 1 1\n";
        assert_eq!(without_vertex_colours(text), "v 0 0 0\nv 1 0 0\nv 0 1 0 2\nvn 0 0 1 1 1 1\n");
    }
}
