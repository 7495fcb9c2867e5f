//! `trilab methods`.

use clap::Args;
use trilab::error::Result;

use super::JsonArg;

/// List the intersection methods and what each needs
///
/// The intersection methods: names, titles, GLSL files, triangles per test, what they need.
#[derive(Args)]
pub struct MethodsArgs {
    /// Print the README's method list (Markdown) instead.
    #[arg(long, conflicts_with = "json")]
    markdown: bool,
    #[command(flatten)]
    json: JsonArg,
}

pub fn run(a: MethodsArgs) -> Result<()> {
    let report = trilab::commands::methods::run();
    if a.markdown {
        print!("{}", report.markdown());
    } else {
        a.json.print(&report);
    }
    Ok(())
}
