//! `trilab __dump-cli` (hidden): the command tree as JSON, for the tests that hold every command
//! to one option vocabulary and every argument to having help.

use clap::{Args, Command};
use trilab::error::Result;

/// Print every command's arguments as JSON (for tests).
#[derive(Args)]
pub struct DumpArgs {}

fn dump(cmd: &Command, path: &str) -> Vec<serde_json::Value> {
    let mut out = vec![serde_json::json!({
        "command": path,
        "about": cmd.get_about().map(|s| s.to_string()),
        "hidden": cmd.is_hide_set(),
        "args": cmd.get_arguments().filter(|a| a.get_id() != "help" && a.get_id() != "version").map(|a| serde_json::json!({
            "id": a.get_id().as_str(),
            "long": a.get_long(),
            "aliases": a.get_all_aliases().unwrap_or_default(),
            "hidden": a.is_hide_set(),
            "help": a.get_help().map(|s| s.to_string()),
            "value_names": a.get_value_names().map(|v| v.iter().map(|s| s.as_str().to_owned()).collect::<Vec<_>>()),
            "takes_value": a.get_action().takes_values(),
            "defaults": a.get_default_values().iter().map(|v| v.to_string_lossy().into_owned()).collect::<Vec<_>>(),
            "global": a.is_global_set(),
        })).collect::<Vec<_>>(),
    })];
    for sub in cmd.get_subcommands() {
        out.extend(dump(sub, &format!("{path} {}", sub.get_name())));
    }
    out
}

pub fn run(_: DumpArgs, mut cmd: Command) -> Result<()> {
    cmd.build();
    println!("{}", serde_json::Value::Array(dump(&cmd, "trilab")));
    Ok(())
}
