//! `trilab man`.

use std::path::PathBuf;

use clap::{Args, Command};
use trilab::error::{Error, Result};

/// Manual pages generated from the command line itself: trilab.1 and one page per command
/// (trilab-raycast.1, trilab-rays-primary.1, ...).
#[derive(Args)]
pub struct ManArgs {
    /// Directory to write every page into (created if needed); default: print trilab.1 to stdout.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

/// Every visible command's page: (file name, roff text), the top-level page first.
pub fn pages(cmd: Command) -> Result<Vec<(String, Vec<u8>)>> {
    fn walk(cmd: &Command, out: &mut Vec<(String, Vec<u8>)>) -> Result<()> {
        let man = clap_mangen::Man::new(cmd.clone());
        let mut text = vec![];
        man.render(&mut text).map_err(|e| Error::Usage(format!("man page of {}: {e}", cmd.get_name())))?;
        out.push((man.get_filename(), text));
        for sub in cmd.get_subcommands().filter(|s| !s.is_hide_set()) {
            walk(sub, out)?;
        }
        Ok(())
    }
    let mut cmd = cmd.disable_help_subcommand(true);
    cmd.build();
    let mut out = vec![];
    walk(&cmd, &mut out)?;
    Ok(out)
}

pub fn run(a: ManArgs, cmd: Command) -> Result<()> {
    let pages = pages(cmd)?;
    match &a.out {
        None => {
            use std::io::Write;
            let _ = std::io::stdout().write_all(&pages[0].1);
        }
        Some(dir) => {
            if dir.is_file() {
                return Err(Error::Usage(format!("--out {}: is a file; man pages go into a directory", dir.display())));
            }
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            for (name, text) in &pages {
                trilab::io::write_atomic(&dir.join(name), text)?;
            }
            eprintln!("wrote {} man pages to {}", pages.len(), dir.display());
        }
    }
    Ok(())
}
