//! `trilab spirv`.

use super::OutArgs;

use clap::Args;
use trilab::error::Result;
use trilab::spirv::Disassembly;

use super::JsonArg;

/// SPIR-V instruction counts of every kernel variant, or their disassembly
///
/// SPIR-V instruction counts of every kernel variant (`<kernel>.<method>.<variant>`); `--out
/// DIR` writes the review files instead: every variant's disassembly and
/// instruction_counts.csv (`trilab spirv --out spirv --studied` refreshes spirv/, which keeps
/// the studied kernels' disassembly only).
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("Directory to write every variant's disassembly and instruction_counts.csv into (stale disassembly there is removed; was `--write`)").alias("write")))]
pub struct SpirvArgs {
    #[command(flatten)]
    out: OutArgs,
    /// With --out: only the disassembly of the kernels a reader studies (what spirv/ keeps:
    /// raycast closest and any on the binary nodes, closest on each wide layout, every
    /// intersector; the ray-query peer); other disassembly in DIR is removed.
    #[arg(long, requires = "out")]
    studied: bool,
    #[command(flatten)]
    json: JsonArg,
}

pub fn run(a: SpirvArgs) -> Result<()> {
    match &a.out.dir {
        Some(dir) => {
            OutArgs::check(dir, &[], &[])?;
            let which = if a.studied { Disassembly::Studied } else { Disassembly::All };
            let n = trilab::commands::spirv::write(dir, which)?;
            println!("wrote {n} files to {}", dir.display());
        }
        None => a.json.print(&trilab::commands::spirv::counts()),
    }
    Ok(())
}
