//! `trilab devices`.

use clap::Args;
use trilab::error::Result;

use super::JsonArg;

/// List Vulkan devices, their drivers and the features trilab uses.
#[derive(Args)]
pub struct DevicesArgs {
    #[command(flatten)]
    json: JsonArg,
}

pub fn run(a: DevicesArgs) -> Result<()> {
    a.json.print(&trilab::commands::devices::run()?);
    Ok(())
}
