//! `trilab man`: manual pages, and the Markdown command reference (docs/commands.md), both from
//! the clap command tree.

use super::OutArgs;
use std::collections::BTreeSet;

use clap::{Arg, Args, Command};
use trilab::error::{Error, Result};

/// Man pages, or the Markdown command reference, generated from the command line
///
/// Manual pages: trilab.1 and one page per command (trilab-raycast.1, trilab-rays-primary.1,
/// ...); with
/// --markdown, the command reference docs/commands.md instead (every command, its help and its
/// options, and the environment variables).
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("Directory to write every page into (created if needed); default: print trilab.1 to stdout")))]
pub struct ManArgs {
    #[command(flatten)]
    out: OutArgs,
    /// Print the Markdown command reference instead (`trilab man --markdown > docs/commands.md`).
    #[arg(long, conflicts_with = "out")]
    markdown: bool,
}

/// The command tree as clap builds it for help: the `help` subcommand left out.
fn built(cmd: Command) -> Command {
    let mut cmd = cmd.disable_help_subcommand(true);
    cmd.build();
    cmd
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
    let mut out = vec![];
    walk(&built(cmd), &mut out)?;
    Ok(out)
}

/// `<` outside code spans as `\<`, so `<out>.json` is text, not an HTML tag, in Markdown.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut code = false;
    for c in text.chars() {
        match c {
            '`' => code = !code,
            '<' if !code => out.push('\\'),
            _ => {}
        }
        out.push(c);
    }
    out
}

/// `--name <VALUE>`, `-s, --name`, or `<NAME>` for a positional argument.
fn arg_name(a: &Arg) -> String {
    let values = a.get_value_names().map(|v| v.iter().map(|n| format!("<{n}>")).collect::<Vec<_>>().join(" "));
    let values = values.unwrap_or_else(|| format!("<{}>", a.get_id().as_str().to_uppercase()));
    match a.get_long() {
        None => values,
        Some(long) => {
            let mut s = a.get_short().map(|c| format!("-{c}, ")).unwrap_or_default() + "--" + long;
            if a.get_action().takes_values() {
                s += &format!(" {values}");
            }
            s
        }
    }
}

/// One option as a list item: name, help (a help of several lines keeps its lines, as a code
/// block), default and possible values.
fn arg_item(a: &Arg) -> String {
    let help = a.get_long_help().or_else(|| a.get_help()).map(|h| h.to_string()).unwrap_or_default();
    let mut lines = help.trim_end().lines();
    let mut s = format!("- `{}`: {}", arg_name(a), escape(lines.next().unwrap_or_default().trim()));
    let defaults: Vec<String> = a.get_default_values().iter().map(|d| d.to_string_lossy().into_owned()).collect();
    if !defaults.is_empty() && a.get_action().takes_values() {
        s += &format!(" (default: `{}`)", defaults.join(","));
    }
    let rest: Vec<&str> = lines.collect();
    if !rest.is_empty() {
        s += "\n\n";
        for l in rest {
            s += format!("      {l}").trim_end();
            s.push('\n');
        }
    }
    let values: Vec<_> = if a.is_hide_possible_values_set() {
        vec![]
    } else {
        a.get_possible_values().into_iter().filter(|v| !v.is_hide_set()).collect()
    };
    if values.iter().any(|v| v.get_help().is_some()) {
        if !s.ends_with('\n') {
            s.push('\n');
        }
        for v in &values {
            let help = v.get_help().map(|h| format!(": {}", escape(&h.to_string()))).unwrap_or_default();
            s += &format!("  - `{}`{help}\n", v.get_name());
        }
    } else if !values.is_empty() {
        let names: Vec<String> = values.iter().map(|v| format!("`{}`", v.get_name())).collect();
        s += &format!(" Values: {}.", names.join(", "));
    }
    if !s.ends_with('\n') {
        s.push('\n');
    }
    s
}

/// The arguments a command lists: not `--help`/`--version`, not hidden, and not the global ones
/// its parent already lists (clap copies those into every subcommand).
fn listed_args<'a>(cmd: &'a Command, inherited: &BTreeSet<String>) -> Vec<&'a Arg> {
    cmd.get_arguments()
        .filter(|a| !matches!(a.get_id().as_str(), "help" | "version"))
        .filter(|a| !a.is_hide_set())
        .filter(|a| !(a.is_global_set() && inherited.contains(a.get_id().as_str())))
        .collect()
}

/// The heading (and so the anchor) of a command's section.
fn heading(path: &str) -> String {
    format!("`{path}`")
}

fn anchor(path: &str) -> String {
    path.replace(' ', "-")
}

/// `cmd`'s section, then its subcommands' (`path` is its name as typed: `trilab rays primary`).
fn section(cmd: &Command, path: &str, inherited: &BTreeSet<String>, out: &mut String) {
    *out += &format!("## {}\n\n", heading(path));
    let about = cmd.get_long_about().or_else(|| cmd.get_about()).map(|s| s.to_string()).unwrap_or_default();
    *out += &format!("{}\n\n", escape(about.trim()));
    let usage = cmd.clone().render_usage().to_string();
    let usage = usage.trim().trim_start_matches("Usage:").trim();
    *out += &format!("    {usage}\n\n");
    let args = listed_args(cmd, inherited);
    if !args.is_empty() {
        for a in &args {
            *out += &arg_item(a);
        }
        *out += "\n";
    }
    let subs: Vec<&Command> = cmd.get_subcommands().filter(|s| !s.is_hide_set()).collect();
    if !subs.is_empty() {
        *out += "Subcommands:\n\n";
        for s in &subs {
            let sub = format!("{path} {}", s.get_name());
            *out += &format!("- [`{}`](#{}): {}\n", s.get_name(), anchor(&sub), escape(&about_of(s)));
        }
        *out += "\n";
    }
    let mut inherited = inherited.clone();
    inherited.extend(cmd.get_arguments().filter(|a| a.is_global_set()).map(|a| a.get_id().to_string()));
    for s in subs {
        section(s, &format!("{path} {}", s.get_name()), &inherited, out);
    }
}

fn about_of(cmd: &Command) -> String {
    cmd.get_about().map(|s| s.to_string()).unwrap_or_default()
}

/// docs/commands.md: every visible command with its one-line summary, then each command's help
/// and options (the same text `trilab CMD --help` prints), then the environment variables.
pub fn markdown(cmd: Command) -> String {
    let cmd = built(cmd);
    let mut out = String::from(
        "# Command reference\n\n\
         <!-- Generated from the command line: `cargo run --release -- man --markdown > docs/commands.md`. \
         Do not edit; tests/cli_vocabulary.rs fails when this file differs from the generator's output. -->\n\n",
    );
    out += &format!("{}\n\n", escape(&about_of(&cmd)));
    out += "`trilab CMD --help` prints one command's part of this page; the manual ([docs/README.md](README.md)) \
            says how the commands fit together.\n\n";
    out += "| command | what it does |\n|---|---|\n";
    fn rows(cmd: &Command, path: &str, out: &mut String) {
        for s in cmd.get_subcommands().filter(|s| !s.is_hide_set()) {
            let sub = format!("{path} {}", s.get_name());
            *out += &format!("| [`{}`](#{}) | {} |\n", &sub["trilab ".len()..], anchor(&sub), escape(&about_of(s)));
            rows(s, &sub, out);
        }
    }
    rows(&cmd, "trilab", &mut out);
    out += "\n## Options of every command\n\n";
    for a in listed_args(&cmd, &BTreeSet::new()) {
        out += &arg_item(a);
    }
    out += "\n## Options by name\n\nThe commands that take each option; each command's section below gives its help there.\n\n";
    let mut by_name: std::collections::BTreeMap<String, Vec<String>> = Default::default();
    fn index(
        cmd: &Command,
        path: &str,
        inherited: &BTreeSet<String>,
        by_name: &mut std::collections::BTreeMap<String, Vec<String>>,
    ) {
        for a in listed_args(cmd, inherited) {
            if let Some(long) = a.get_long() {
                by_name.entry(format!("--{long}")).or_default().push(path.to_owned());
            }
        }
        let mut inherited = inherited.clone();
        inherited.extend(cmd.get_arguments().filter(|a| a.is_global_set()).map(|a| a.get_id().to_string()));
        for s in cmd.get_subcommands().filter(|s| !s.is_hide_set()) {
            index(s, &format!("{path} {}", s.get_name()), &inherited, by_name);
        }
    }
    index(&cmd, "trilab", &BTreeSet::new(), &mut by_name);
    for (name, paths) in &by_name {
        let links: Vec<String> = paths
            .iter()
            .map(|p| {
                if p == "trilab" {
                    "every command".to_owned()
                } else {
                    format!("[`{}`](#{})", &p["trilab ".len()..], anchor(p))
                }
            })
            .collect();
        out += &format!("- `{name}`: {}\n", links.join(", "));
    }
    out += "\n## Environment variables\n\n";
    out += &escape(&trilab::env::markdown());
    out += "\n";
    let inherited: BTreeSet<String> =
        cmd.get_arguments().filter(|a| a.is_global_set()).map(|a| a.get_id().to_string()).collect();
    for s in cmd.get_subcommands().filter(|s| !s.is_hide_set()) {
        section(s, &format!("trilab {}", s.get_name()), &inherited, &mut out);
    }
    while out.ends_with("\n\n") {
        out.pop();
    }
    out
}

pub fn run(a: ManArgs, cmd: Command) -> Result<()> {
    if a.markdown {
        print!("{}", markdown(cmd));
        return Ok(());
    }
    let pages = pages(cmd)?;
    match &a.out.dir {
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
