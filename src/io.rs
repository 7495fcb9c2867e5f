//! File output that never corrupts or overwrites inputs: outputs go to a temporary file in the
//! destination directory and are renamed into place. And text input that may be stored
//! gzip-compressed ([`read_text`]): bulky committed results are (`results/README.md`).

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Writes `bytes` to `path` atomically (temporary file in the same directory, then rename).
/// Every error names `path`, never the temporary file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = parent_dir(path);
    // tempfile's errors carry the temporary file's name ("... at path .trilab-XXXX.tmp"); the
    // user never named it, so keep only the error's kind and OS message.
    let err = |e: std::io::Error| Error::io(path, plain(e));
    if path.is_dir() {
        return Err(Error::Usage(format!("output {}: is a directory, not a file", path.display())));
    }
    if let Some(kind) = special_file(path) {
        return Err(Error::Usage(format!("output {}: {}", path.display(), refusal(kind))));
    }
    let mut tmp = tempfile::Builder::new().prefix(".trilab-").suffix(".tmp").tempfile_in(&dir).map_err(err)?;
    tmp.write_all(bytes).map_err(err)?;
    // tempfile creates 0600; an output is an ordinary file (0644, as `File::create` under the
    // usual umask would make it).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file().set_permissions(std::fs::Permissions::from_mode(0o644)).map_err(err)?;
    }
    tmp.as_file().sync_all().map_err(err)?;
    tmp.persist(path).map_err(|e| err(e.error))?;
    Ok(())
}

/// The suffix of a gzip-compressed file (`rows.jsonl.gz`, `accuracy.csv.gz`).
pub const GZ: &str = ".gz";

/// `path`, or `path` + [`GZ`] where only the compressed file exists: the file a reader of
/// results opens for a name it knows (`frontier.csv`, say).
pub fn existing_form(path: &Path) -> PathBuf {
    let mut gz = path.as_os_str().to_owned();
    gz.push(GZ);
    let gz = PathBuf::from(gz);
    if !path.exists() && gz.is_file() {
        gz
    } else {
        path.to_owned()
    }
}

/// The text of `path`, inflated when its name ends in [`GZ`]. Errors name `path` (a truncated or
/// corrupt archive, text that is not UTF-8).
pub fn read_text(path: &Path) -> Result<String> {
    use std::io::Read as _;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let bytes = if path.to_string_lossy().ends_with(GZ) {
        let mut out = Vec::with_capacity(bytes.len() * 8);
        flate2::read::MultiGzDecoder::new(&bytes[..])
            .read_to_end(&mut out)
            .map_err(|e| Error::bad_input(path, None, format!("not a readable gzip file: {e}")))?;
        out
    } else {
        bytes
    };
    String::from_utf8(bytes).map_err(|e| Error::bad_input(path, None, format!("not UTF-8 text: {e}")))
}

/// What `path` is when it exists and is not a regular file or a directory: a symbolic link, a
/// device, a FIFO or a socket. Outputs are written by renaming a new file over the path, which
/// would replace such a thing (a device node, `/dev/full`, a link to another file) with a
/// regular file; they are refused instead ([`write_atomic`], [`check_output`]).
fn special_file(path: &Path) -> Option<&'static str> {
    let meta = std::fs::symlink_metadata(path).ok()?;
    let t = meta.file_type();
    if t.is_file() || t.is_dir() {
        return None;
    }
    if t.is_symlink() {
        return Some("a symbolic link");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_char_device() || t.is_block_device() {
            return Some("a device");
        }
        if t.is_fifo() {
            return Some("a FIFO");
        }
        if t.is_socket() {
            return Some("a socket");
        }
    }
    Some("not a regular file")
}

fn refusal(kind: &str) -> String {
    format!("is {kind}, not a regular file; outputs replace a file by renaming a new one over it, so give a new path or a regular file")
}

/// The directory a file `path` lands in (`.` for a bare name).
fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_owned(),
        _ => PathBuf::from("."),
    }
}

/// `e` without any path text a wrapper added: its kind and the OS's message only.
fn plain(e: std::io::Error) -> std::io::Error {
    match e.raw_os_error() {
        Some(code) => std::io::Error::from_raw_os_error(code),
        None => std::io::Error::new(e.kind(), e.kind().to_string()),
    }
}

/// A command's output, as [`check_output`] checks it.
#[derive(Clone, Copy, Debug)]
pub enum Output<'a> {
    /// One file.
    File(&'a Path),
    /// A folder and the files the command writes into it.
    Dir(&'a Path, &'a [&'a str]),
}

/// Checks, before any work, that a command can write its output, and names the option and the
/// user's path when it cannot. A FILE: its folder exists and is writable (probed by creating and
/// removing a temporary file there), the path is not an existing directory, and it is not one
/// of `inputs`. A DIR: not an existing file; writable if it exists, creatable (its nearest
/// existing ancestor is a writable folder) if not; none of its files is one of `inputs`.
pub fn check_output(option: &str, output: Output, inputs: &[&Path]) -> Result<()> {
    match output {
        Output::File(path) => check_output_file(option, path, inputs),
        Output::Dir(dir, files) => check_output_dir(option, dir, files, inputs),
    }
}

fn check_output_file(option: &str, path: &Path, inputs: &[&Path]) -> Result<()> {
    let bad = |why: String| Error::Usage(format!("{option} {}: {why}", path.display()));
    if path.as_os_str().is_empty() {
        return Err(bad("empty path".into()));
    }
    if let Some(kind) = special_file(path) {
        return Err(bad(refusal(kind)));
    }
    if path.is_dir() {
        return Err(bad("is an existing directory; give a file name".into()));
    }
    let dir = parent_dir(path);
    if !dir.exists() {
        return Err(bad(format!("folder {} does not exist", dir.display())));
    }
    if !dir.is_dir() {
        return Err(bad(format!("{} is not a folder", dir.display())));
    }
    probe_writable(&dir).map_err(|e| bad(format!("cannot write in {}: {e}", dir.display())))?;
    ensure_not_input(path, inputs).map_err(|e| Error::Usage(format!("{option}: {e}")))
}

fn check_output_dir(option: &str, dir: &Path, files: &[&str], inputs: &[&Path]) -> Result<()> {
    let bad = |why: String| Error::Usage(format!("{option} {}: {why}", dir.display()));
    if dir.as_os_str().is_empty() {
        return Err(bad("empty path".into()));
    }
    if dir.exists() {
        if !dir.is_dir() {
            return Err(bad("is an existing file; give a folder".into()));
        }
        probe_writable(dir).map_err(|e| bad(format!("cannot write in it: {e}")))?;
    } else {
        let mut ancestor = dir.to_path_buf();
        loop {
            ancestor = parent_dir(&ancestor);
            if ancestor.exists() || ancestor == Path::new(".") || ancestor == Path::new("/") {
                break;
            }
        }
        if !ancestor.is_dir() {
            return Err(bad(format!("cannot create it: {} is not a folder", ancestor.display())));
        }
        probe_writable(&ancestor).map_err(|e| bad(format!("cannot create it in {}: {e}", ancestor.display())))?;
    }
    check_outputs(dir, files, inputs).map_err(|e| Error::Usage(format!("{option}: {e}")))
}

/// Creates and removes a temporary file in `dir` (the only reliable test: permissions, root,
/// read-only file systems and ACLs all answer it).
fn probe_writable(dir: &Path) -> std::io::Result<()> {
    tempfile::Builder::new().prefix(".trilab-probe-").tempfile_in(dir).map(drop).map_err(plain)
}

/// Whether two paths name the same file (after resolving links and `..`; either may not exist
/// yet): two outputs of one command that would overwrite each other.
pub fn same_file(a: &Path, b: &Path) -> bool {
    resolve(a) == resolve(b)
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

/// [`ensure_not_input`] for each of `files` in the output directory `dir`, and none of them
/// a link, device, FIFO or socket.
pub fn check_outputs(dir: &Path, files: &[&str], inputs: &[&Path]) -> Result<()> {
    files.iter().try_for_each(|f| {
        let path = dir.join(f);
        if let Some(kind) = special_file(&path) {
            return Err(Error::Usage(format!("output {}: {}", path.display(), refusal(kind))));
        }
        ensure_not_input(&path, inputs)
    })
}

/// [`check_output`] for the `--out` file of a command that read `scene`, the MTL files
/// `mtls` it names, and `other` inputs (ray files): writable, and none of them.
pub fn ensure_not_inputs(output: &Path, scene: &Path, mtls: &[PathBuf], other: &[&Path]) -> Result<()> {
    let mut inputs: Vec<&Path> = vec![scene];
    inputs.extend(mtls.iter().map(PathBuf::as_path));
    inputs.extend_from_slice(other);
    check_output("--out", Output::File(output), &inputs)
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

    fn gzip(bytes: &[u8]) -> Vec<u8> {
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        e.write_all(bytes).unwrap();
        e.finish().unwrap()
    }

    #[test]
    fn compressed_text_reads_as_the_plain_text_and_a_broken_one_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("a.csv");
        std::fs::write(&plain, "x,y\n1,2\n").unwrap();
        let gz = dir.path().join("b.csv.gz");
        std::fs::write(&gz, gzip(b"x,y\n1,2\n")).unwrap();
        assert_eq!(read_text(&gz).unwrap(), read_text(&plain).unwrap());
        // The name a reader knows finds the compressed file, and the plain one where both are.
        assert_eq!(existing_form(&dir.path().join("b.csv")), gz);
        assert_eq!(existing_form(&plain), plain);
        let broken = dir.path().join("c.csv.gz");
        let whole = gzip(&[b'x'; 4096]);
        std::fs::write(&broken, &whole[..whole.len() / 2]).unwrap();
        let e = read_text(&broken).unwrap_err().to_string();
        assert!(e.contains("c.csv.gz") && e.contains("gzip"), "{e}");
    }

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
    fn write_errors_name_the_output_not_the_temporary_file() {
        let e = write_atomic(Path::new("/nonexistent-trilab-dir/x.exr"), b"x").unwrap_err().to_string();
        assert!(e.contains("/nonexistent-trilab-dir/x.exr"), "{e}");
        assert!(!e.contains(".tmp"), "{e}");
    }

    #[test]
    fn outputs_are_checked_before_work() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("f.txt");
        std::fs::write(&file, "x").unwrap();
        // A file where a folder is wanted, a folder where a file is wanted, a missing folder.
        assert!(check_output_dir("--out", &file, &[], &[]).unwrap_err().to_string().contains("existing file"));
        assert!(check_output_file("--out", dir.path(), &[]).unwrap_err().to_string().contains("directory"));
        let missing = dir.path().join("no/x.exr");
        assert!(check_output_file("--out", &missing, &[]).unwrap_err().to_string().contains("does not exist"));
        assert!(check_output_dir("--out", &file.join("sub"), &[], &[]).is_err());
        // Fine: a new file, a new nested folder, an existing folder; nothing left behind.
        check_output_file("--out", &dir.path().join("new.exr"), &[]).unwrap();
        check_output_dir("--out", &dir.path().join("a/b"), &[], &[]).unwrap();
        check_output_dir("--out", dir.path(), &["r.json"], &[]).unwrap();
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        // Not an input.
        assert!(check_output_file("--out", &file, &[&file]).is_err());
    }

    /// A link, a FIFO or a device named as an output is refused before work and at the write,
    /// and stays what it was (renaming over it replaced `/dev/full` with a regular file).
    #[cfg(unix)]
    #[test]
    fn special_files_are_never_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("target.txt");
        std::fs::write(&target, "keep").unwrap();
        let link = dir.path().join("link.exr");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let fifo = dir.path().join("fifo.hits");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: `c` is a NUL-terminated path that outlives the call.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
        for (p, kind) in [(&link, "symbolic link"), (&fifo, "FIFO"), (&PathBuf::from("/dev/null"), "device")] {
            let e = check_output_file("--out", p, &[]).unwrap_err().to_string();
            assert!(e.contains(&p.display().to_string()) && e.contains(kind), "{e}");
            let e = write_atomic(p, b"x").unwrap_err().to_string();
            assert!(e.contains(kind), "{e}");
        }
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep");
        use std::os::unix::fs::FileTypeExt;
        assert!(std::fs::symlink_metadata("/dev/null").unwrap().file_type().is_char_device());
        // In an output folder too.
        let e = check_outputs(dir.path(), &["fifo.hits"], &[]).unwrap_err().to_string();
        assert!(e.contains("FIFO"), "{e}");
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
