//! The one way a command writes its results into its output folder (study, accuracy,
//! build-bench, profile, scale, merge, ab): the folder created if needed, every file written
//! atomically, `rows.jsonl` through [`crate::rows::write`], and the paths written kept in order
//! for the command to list.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::rows::{Plan, Row};

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

    /// Lists files written into the folder by other means (the plots).
    pub fn add(&mut self, paths: impl IntoIterator<Item = PathBuf>) {
        self.written.extend(paths);
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
