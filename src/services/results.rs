//! The one way a command writes its results: a report that is [`Results`] is written by
//! [`write`] (to the files a user named: bench, bench-render) or [`Folder::results`] (into an
//! output folder: every other results-writing command) as `<stem>.json`, its plots,
//! `<stem>.md` and `rows.jsonl` (the plan first, through [`crate::rows::write`]), every file
//! atomically, and the paths written kept in order for the command to list.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::report::Report;
use crate::rows::{Plan, Row};
use crate::services::plots::Plot;

/// A command's results: its report (`to_json`, `to_text`), its Markdown, its rows and plan,
/// and the files of its own (CSV, plots), all written by [`write`] or [`Folder::results`].
pub trait Results: Report {
    /// The files' stem: `<stem>.json`, `<stem>.md`.
    const STEM: &'static str;

    /// Whether `<stem>.json`, [`Report::to_json`], ends in a newline (study's, scale's and
    /// merge's always have).
    const JSON_NEWLINE: bool = false;

    /// The Markdown file's name, `<stem>.md` unless the command names it otherwise.
    fn markdown_file() -> String {
        format!("{}.md", Self::STEM)
    }

    /// The Markdown file's text; `plots` are those [`Results::plots`] drew, for it to link.
    fn markdown(&self, plots: &[Plot]) -> String;

    /// The rows of `rows.jsonl`; `None` for a command that writes none.
    fn rows(&self) -> Option<Vec<Row>>;

    /// The plan of the whole matrix the rows belong to (commands with `--shard`), written first.
    fn plan(&self) -> Option<Plan> {
        None
    }

    /// Text files of the command's own (CSV), by name, written before the JSON.
    fn files(&self) -> Result<Vec<(&'static str, String)>> {
        Ok(vec![])
    }

    /// Draws the command's plots into `dir` (after the JSON, before the Markdown that links them).
    fn plots(&self, _dir: &Path) -> Result<Vec<Plot>> {
        Ok(vec![])
    }
}

/// Writes `r` where asked, each file atomically: the JSON to `json`; its plots, then its
/// Markdown to `md`; `rows.jsonl` (the plan first) and the plots into the JSON file's folder
/// (else the Markdown's). Returns the paths written, in order. [`Results::files`] are
/// [`Folder::results`]'s.
pub fn write<R: Results>(r: &R, json: Option<&Path>, md: Option<&Path>) -> Result<Vec<PathBuf>> {
    let mut written = vec![];
    let Some(first) = json.or(md) else { return Ok(written) };
    let dir = first.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if let Some(p) = json {
        let newline = if R::JSON_NEWLINE { "\n" } else { "" };
        crate::io::write_atomic(p, (r.to_json() + newline).as_bytes())?;
        written.push(p.to_owned());
    }
    let plots = r.plots(dir)?;
    written.extend(plots.iter().map(|p| p.path.clone()));
    if let Some(p) = md {
        crate::io::write_atomic(p, r.markdown(&plots).as_bytes())?;
        written.push(p.to_owned());
    }
    if let Some(rows) = r.rows() {
        written.push(crate::rows::write(dir, r.plan().as_ref(), &rows)?);
    }
    Ok(written)
}

/// Writes `r` into the folder `dir` (created if needed) as [`Folder::results`] does; returns
/// the paths written, in order.
pub fn write_folder<R: Results>(dir: &Path, r: &R) -> Result<Vec<PathBuf>> {
    let mut folder = Folder::create(dir)?;
    folder.results(r)?;
    Ok(folder.written())
}

/// A command's output folder and the files written into it so far.
#[derive(Debug)]
pub struct Folder {
    dir: PathBuf,
    written: Vec<PathBuf>,
}

impl Folder {
    /// `dir`, created if needed.
    pub fn create(dir: &Path) -> Result<Folder> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        Ok(Folder { dir: dir.to_owned(), written: vec![] })
    }

    /// Writes the file `name` atomically.
    pub fn put(&mut self, name: &str, bytes: impl AsRef<[u8]>) -> Result<()> {
        let path = self.dir.join(name);
        crate::io::write_atomic(&path, bytes.as_ref())?;
        self.written.push(path);
        Ok(())
    }

    /// Writes `rows.jsonl`: the plan of the whole matrix (commands with `--shard`), then the rows.
    pub fn rows(&mut self, plan: Option<&Plan>, rows: &[Row]) -> Result<()> {
        self.written.push(crate::rows::write(&self.dir, plan, rows)?);
        Ok(())
    }

    /// Writes `r` into the folder: its own files ([`Results::files`]), then `<stem>.json`, its
    /// plots, `<stem>.md` and `rows.jsonl` as [`write`] writes them.
    pub fn results<R: Results>(&mut self, r: &R) -> Result<()> {
        for (name, text) in r.files()? {
            self.put(name, text)?;
        }
        let json = self.dir.join(format!("{}.json", R::STEM));
        let md = self.dir.join(R::markdown_file());
        self.written.extend(write(r, Some(&json), Some(&md))?);
        Ok(())
    }

    /// The paths written, in order.
    pub fn written(self) -> Vec<PathBuf> {
        self.written
    }
}

/// A CSV file's text: the `header`, then one line per record (quoted as [`csv::Writer`] quotes
/// fields); errors name `file`.
pub fn csv<H, R>(file: &str, header: H, records: impl IntoIterator<Item = R>) -> Result<String>
where
    H: IntoIterator,
    H::Item: AsRef<[u8]>,
    R: IntoIterator,
    R::Item: AsRef<[u8]>,
{
    let err = |e: csv::Error| Error::Usage(format!("writing {file}: {e}"));
    let mut w = csv::Writer::from_writer(vec![]);
    w.write_record(header).map_err(err)?;
    for r in records {
        w.write_record(r).map_err(err)?;
    }
    let bytes = w.into_inner().map_err(|e| Error::Usage(format!("writing {file}: {e}")))?;
    Ok(String::from_utf8(bytes).expect("CSV of UTF-8 fields"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rows::{cell, Figure, Source};

    /// A command's results in miniature: one CSV of its own, one plot (a text file standing in
    /// for a PNG), a plan and two rows.
    #[derive(serde::Serialize)]
    struct Demo {
        name: &'static str,
    }

    impl Report for Demo {
        fn to_text(&self) -> String {
            format!("text {}", self.name)
        }
    }

    impl Results for Demo {
        const STEM: &'static str = "demo";

        fn markdown(&self, plots: &[Plot]) -> String {
            let links: Vec<String> = plots.iter().map(|p| format!("![{}]({})", p.title, p.path.display())).collect();
            format!("# {}\n{}\n", self.name, links.join("\n"))
        }

        fn rows(&self) -> Option<Vec<Row>> {
            let s = Source::default();
            Some(vec![
                Row::new("demo", cell([("scene", "a")]), &s).with("n", Figure::count(1.0, "rays")),
                Row::new("demo", cell([("scene", "b")]), &s).with("n", Figure::count(2.0, "rays")),
            ])
        }

        fn plan(&self) -> Option<Plan> {
            let cells = vec![cell([("scene", "a")]), cell([("scene", "b")])];
            Some(Plan { command: "demo".into(), shard: None, cells, source: Source::default() })
        }

        fn files(&self) -> Result<Vec<(&'static str, String)>> {
            Ok(vec![("demo.csv", "scene\na\nb\n".into())])
        }

        fn plots(&self, dir: &Path) -> Result<Vec<Plot>> {
            let path = dir.join("demo.png");
            crate::io::write_atomic(&path, b"png")?;
            Ok(vec![Plot { title: "a plot".into(), path }])
        }
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        v.sort();
        v
    }

    #[test]
    fn a_folder_gets_the_files_then_json_plots_markdown_and_rows_with_the_plan_first() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("out");
        std::fs::create_dir(&dir).unwrap();
        // A stale demo.json hard-linked to a file outside: an atomic write replaces the name,
        // never writes through it.
        let outside = tmp.path().join("outside.json");
        std::fs::write(&outside, "old").unwrap();
        std::fs::hard_link(&outside, dir.join("demo.json")).unwrap();

        let mut folder = Folder::create(&dir).unwrap();
        folder.results(&Demo { name: "d" }).unwrap();
        let written = folder.written();
        let expected: Vec<PathBuf> =
            ["demo.csv", "demo.json", "demo.png", "demo.md", "rows.jsonl"].iter().map(|n| dir.join(n)).collect();
        assert_eq!(written, expected);
        assert_eq!(names(&dir), ["demo.csv", "demo.json", "demo.md", "demo.png", "rows.jsonl"], "no temporary left");

        assert_eq!(std::fs::read_to_string(&outside).unwrap(), "old");
        assert_eq!(std::fs::read_to_string(dir.join("demo.json")).unwrap(), Demo { name: "d" }.to_json());
        let md = std::fs::read_to_string(dir.join("demo.md")).unwrap();
        assert_eq!(md, format!("# d\n![a plot]({})\n", dir.join("demo.png").display()));
        assert_eq!(std::fs::read_to_string(dir.join("demo.csv")).unwrap(), "scene\na\nb\n");

        let text = std::fs::read_to_string(dir.join("rows.jsonl")).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3);
        assert!(lines[0].contains("\"type\":\"plan\""), "{}", lines[0]);
        let read = crate::rows::read_file(&dir.join("rows.jsonl")).unwrap();
        assert_eq!(read.plans, vec![Demo { name: "d" }.plan().unwrap()]);
        assert_eq!(read.rows, Demo { name: "d" }.rows().unwrap());
    }

    #[test]
    fn named_files_put_the_rows_beside_the_json_else_the_markdown() {
        let tmp = tempfile::tempdir().unwrap();
        let (j, m) = (tmp.path().join("j"), tmp.path().join("m"));
        for d in [&j, &m] {
            std::fs::create_dir(d).unwrap();
        }
        let demo = Demo { name: "d" };
        let written = write(&demo, Some(&j.join("r.json")), Some(&m.join("r.md"))).unwrap();
        assert_eq!(written, [j.join("r.json"), j.join("demo.png"), m.join("r.md"), j.join("rows.jsonl")]);
        assert_eq!(names(&m), ["r.md"]);
        assert!(names(&j).iter().all(|n| !n.starts_with(".trilab-")));

        let md_only = tmp.path().join("md-only");
        std::fs::create_dir(&md_only).unwrap();
        write(&demo, None, Some(&md_only.join("r.md"))).unwrap();
        assert_eq!(names(&md_only), ["demo.png", "r.md", "rows.jsonl"], "no JSON, no CSV of its own");
        assert!(write(&demo, None, None).unwrap().is_empty());
    }
}
