//! File output that never corrupts or overwrites inputs: outputs go to a temporary file in the
//! destination directory and are renamed into place.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Writes `bytes` to `path` atomically (temporary file in the same directory, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_owned(),
        _ => PathBuf::from("."),
    };
    let mut tmp =
        tempfile::Builder::new().prefix(".trilab-").suffix(".tmp").tempfile_in(&dir).map_err(|e| Error::io(path, e))?;
    tmp.write_all(bytes).map_err(|e| Error::io(path, e))?;
    // tempfile creates 0600; an output is an ordinary file (0644, as `File::create` under the
    // usual umask would make it).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file().set_permissions(std::fs::Permissions::from_mode(0o644)).map_err(|e| Error::io(path, e))?;
    }
    tmp.as_file().sync_all().map_err(|e| Error::io(path, e))?;
    tmp.persist(path).map_err(|e| Error::io(path, e.error))?;
    Ok(())
}

/// Refuses an output path that names one of the inputs (after resolving links and `..`).
pub fn ensure_not_input(output: &Path, inputs: &[&Path]) -> Result<()> {
    let out = resolve(output);
    for input in inputs {
        if resolve(input) == out {
            return Err(Error::Usage(format!(
                "output {} is the input {}; refusing to overwrite an input",
                output.display(),
                input.display()
            )));
        }
    }
    Ok(())
}

/// [`ensure_not_input`] for each of `files` in the output directory `dir`.
pub fn check_outputs(dir: &Path, files: &[&str], inputs: &[&Path]) -> Result<()> {
    files.iter().try_for_each(|f| ensure_not_input(&dir.join(f), inputs))
}

/// [`ensure_not_input`] for an output of a command that read `scene`, the MTL files `mtls` it
/// names, and `other` inputs (ray files).
pub fn ensure_not_inputs(output: &Path, scene: &Path, mtls: &[PathBuf], other: &[&Path]) -> Result<()> {
    let mut inputs: Vec<&Path> = vec![scene];
    inputs.extend(mtls.iter().map(PathBuf::as_path));
    inputs.extend_from_slice(other);
    ensure_not_input(output, &inputs)
}

fn resolve(p: &Path) -> PathBuf {
    if let Ok(c) = p.canonicalize() {
        return c;
    }
    // Not there yet: resolve the directory and keep the file name.
    match (p.parent(), p.file_name()) {
        (Some(dir), Some(name)) => {
            let dir = if dir.as_os_str().is_empty() { Path::new(".") } else { dir };
            dir.canonicalize().map(|d| d.join(name)).unwrap_or_else(|_| p.to_owned())
        }
        _ => p.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_write_replaces_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.bin");
        write_atomic(&p, b"first").unwrap();
        write_atomic(&p, b"second").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"second");
        let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(leftovers.len(), 1, "temporary files left behind");
    }

    #[test]
    fn output_over_input_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("scene.obj");
        std::fs::write(&input, "x").unwrap();
        let same = dir.path().join(".").join("scene.obj");
        assert!(ensure_not_input(&same, &[&input]).is_err());
        assert!(ensure_not_input(&dir.path().join("other.hits"), &[&input]).is_ok());
    }
}
