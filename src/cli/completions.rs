//! `trilab completions <SHELL>`.

use clap::{Args, Command};
use clap_complete::Shell;
use trilab::error::Result;

/// Print a shell completion script (bash, zsh, fish, elvish, powershell)
///
/// Print a shell completion script to stdout, e.g. `trilab completions bash >
/// ~/.local/share/bash-completion/completions/trilab`.
#[derive(Args)]
pub struct CompletionsArgs {
    /// The shell: bash, zsh, fish, elvish or powershell.
    #[arg(value_enum, value_name = "SHELL")]
    shell: Shell,
}

pub fn run(a: CompletionsArgs, mut cmd: Command) -> Result<()> {
    clap_complete::generate(a.shell, &mut cmd, "trilab", &mut std::io::stdout());
    Ok(())
}
