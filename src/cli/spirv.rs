//! `trilab spirv`.

use std::path::PathBuf;

use clap::Args;
use trilab::error::Result;

use super::JsonArg;

/// SPIR-V instruction counts of every kernel variant; `--write DIR` refreshes spirv/.
#[derive(Args)]
pub struct SpirvArgs {
    #[arg(long)]
    write: Option<PathBuf>,
    #[command(flatten)]
    json: JsonArg,
}

pub fn run(a: SpirvArgs) -> Result<()> {
    match &a.write {
        Some(dir) => {
            trilab::io::check_output("--write", trilab::io::Output::Dir(dir, &[]), &[])?;
            let n = trilab::harness::spirv::write(dir)?;
            println!("wrote {n} files to {}", dir.display());
        }
        None => a.json.print(&trilab::harness::spirv::counts()),
    }
    Ok(())
}
