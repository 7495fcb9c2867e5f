//! `trilab spirv`.

use std::path::PathBuf;

use clap::Args;
use trilab::error::Result;

use super::JsonArg;

/// SPIR-V instruction counts of every kernel variant (`<kernel>.<method>.<variant>`); `--out
/// DIR` writes the review files instead (`trilab spirv --out spirv` refreshes spirv/).
#[derive(Args)]
pub struct SpirvArgs {
    /// Directory to write every variant's disassembly and instruction_counts.csv into (stale
    /// disassembly there is removed; was `--write`).
    #[arg(long, value_name = "DIR", alias = "write")]
    out: Option<PathBuf>,
    #[command(flatten)]
    json: JsonArg,
}

pub fn run(a: SpirvArgs) -> Result<()> {
    match &a.out {
        Some(dir) => {
            trilab::io::check_output("--write", trilab::io::Output::Dir(dir, &[]), &[])?;
            let n = trilab::harness::spirv::write(dir)?;
            println!("wrote {n} files to {}", dir.display());
        }
        None => a.json.print(&trilab::harness::spirv::counts()),
    }
    Ok(())
}
