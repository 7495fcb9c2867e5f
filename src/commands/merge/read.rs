//! The merge's input: every rows file below the folders given, each file read once, and the
//! rows and plans they hold, each with the file it came from.

use std::path::PathBuf;

use crate::error::{Error, Result};
use crate::rows::{self, Plan, Row};

/// What the rows files hold.
pub(super) struct Input {
    /// The rows files read, each once.
    pub files: Vec<PathBuf>,
    pub rows: Vec<(Row, PathBuf)>,
    pub plans: Vec<(Plan, PathBuf)>,
}

/// Reads every rows file under `inputs`, each once; refuses inputs that hold no measured row.
pub(super) fn read(inputs: &[PathBuf]) -> Result<Input> {
    if inputs.is_empty() {
        return Err(Error::Usage("merge: name at least one folder of results".into()));
    }
    let files = rows_files(inputs)?;
    let mut rows = vec![];
    let mut plans = vec![];
    for f in &files {
        let set = rows::read_file(f)?;
        rows.extend(set.rows.into_iter().map(|row| (row, f.clone())));
        plans.extend(set.plans.into_iter().map(|p| (p, f.clone())));
    }
    if rows.is_empty() {
        return Err(nothing_to_merge(&files));
    }
    Ok(Input { files, rows, plans })
}

/// The rows files under `inputs`, in order, each once however many inputs reach it (a folder
/// and its sub-folder).
fn rows_files(inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = vec![];
    let mut seen: Vec<PathBuf> = vec![];
    for input in inputs {
        for f in rows::read(input)?.files {
            let canon = f.canonicalize().map_err(|e| Error::io(&f, e))?;
            if !seen.contains(&canon) {
                seen.push(canon);
                files.push(f);
            }
        }
    }
    Ok(files)
}

/// The refusal of rows files without a measured row: a report of only missing cells (or none)
/// would read as a merge.
fn nothing_to_merge(files: &[PathBuf]) -> Error {
    let why = "holds no measured row (it is empty or holds only plans): nothing to merge";
    match files {
        [one] => Error::bad_input(one, None, why),
        _ => Error::Usage(format!(
            "none of {} holds a measured row (each is empty or holds only plans): nothing to merge",
            files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>().join(", ")
        )),
    }
}
