//! The command line speaks one vocabulary (issue 14, defects 7, 8, 9 and `--repeat 0` of 6):
//! every argument has help, old spellings still work as hidden aliases, `--repeat 0` is refused
//! at parse time everywhere, `--help` gives each command one line and names the environment
//! variables, shell completions, man pages and docs/commands.md come from clap, text reports are
//! readable and narrow, and with `--json` an error is JSON too. Every run has a wall-clock limit; GPU runs have validation on.

mod common;

use common::cli::{s, stderr};

use std::path::Path;
use std::process::Output;

use serde_json::Value;
use trilab::encoding::Method;

fn trilab(args: &[&str], timeout_s: u64) -> Output {
    common::cli::trilab(args, timeout_s)
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn ok(args: &[&str], timeout_s: u64) -> String {
    let o = trilab(args, timeout_s);
    assert!(o.status.success(), "trilab {args:?} failed: {}", stderr(&o));
    stdout(&o)
}

fn bunny() -> String {
    s(&common::root().join("scenes/bunny.obj"))
}

fn tiny_scene(dir: &Path) -> String {
    let p = dir.join("tri.obj");
    std::fs::write(&p, "v 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\nf 1 2 3\nf 2 4 3\n").unwrap();
    s(&p)
}

/// Every command (`trilab`, `trilab raycast`, `trilab rays random`, ...) with its arguments, as
/// the hidden `trilab __dump-cli` prints the clap tree.
fn cli_tree() -> Vec<Value> {
    let out = ok(&["__dump-cli"], 30);
    let v: Value = serde_json::from_str(&out).expect("__dump-cli prints JSON");
    v.as_array().unwrap().iter().filter(|c| !c["hidden"].as_bool().unwrap()).cloned().collect()
}

fn command<'a>(tree: &'a [Value], path: &str) -> &'a Value {
    tree.iter().find(|c| c["command"] == path).unwrap_or_else(|| panic!("no command `{path}`"))
}

fn arg<'a>(cmd: &'a Value, long: &str) -> Option<&'a Value> {
    cmd["args"].as_array().unwrap().iter().find(|a| a["long"] == long)
}

/// `trilab help ...`, clap's own.
fn is_help(path: &str) -> bool {
    path.split(' ').any(|w| w == "help")
}

/// Commands a user runs (not `help`, the parents of subcommands or the top level).
fn leaf_commands(tree: &[Value]) -> Vec<&Value> {
    tree.iter()
        .filter(|c| {
            let p = c["command"].as_str().unwrap();
            p != "trilab"
                && !is_help(p)
                && !tree.iter().any(|d| d["command"].as_str().unwrap().starts_with(&format!("{p} ")))
        })
        .collect()
}

#[test]
fn every_argument_of_every_command_has_help() {
    let tree = cli_tree();
    let mut missing = vec![];
    for c in &tree {
        for a in c["args"].as_array().unwrap() {
            let help = a["help"].as_str().unwrap_or("");
            if !a["hidden"].as_bool().unwrap() && help.trim().is_empty() {
                missing.push(format!("{} {}", c["command"].as_str().unwrap(), a["id"].as_str().unwrap()));
            }
        }
    }
    assert!(missing.is_empty(), "arguments without help: {missing:?}");
    // The ones the issue named, in the help a user reads.
    for (cmd, opt) in [
        (&["raycast", "--help"][..], "--scene"),
        (&["raycast", "--help"], "--rays"),
        (&["raycast", "--help"], "--json"),
        (&["rays", "random", "--help"], "--out"),
        (&["spirv", "--help"], "--out"),
        (&["bench", "--help"], "--repeat"),
    ] {
        let help = ok(cmd, 30);
        let lines: Vec<&str> = help.lines().collect();
        let i =
            lines.iter().position(|l| l.trim_start().starts_with(opt)).unwrap_or_else(|| panic!("{cmd:?}: no {opt}"));
        // `--opt <VALUE>  help` on one line, or the help on the next.
        let rest = lines[i].trim_start()[opt.len()..].trim_start();
        let rest = if rest.starts_with('<') { rest.split_once('>').map_or("", |(_, r)| r) } else { rest };
        let next = lines.get(i + 1).map_or("", |l| l.trim());
        assert!(
            !rest.trim().is_empty() || (!next.is_empty() && !next.starts_with('-')),
            "{cmd:?}: {opt} has no help:\n{help}"
        );
    }
}

#[test]
fn one_vocabulary_with_the_old_spellings_hidden() {
    let tree = cli_tree();
    // Old spellings are hidden aliases of the new options, never visible options of their own.
    for (path, new, old) in [
        ("trilab raycast", "reference", "validate"),
        ("trilab scale", "reference-rays", "validate"),
        ("trilab scale", "ray-count", "rays"),
        ("trilab scale", "ray-set", "ray-kind"),
        ("trilab scale", "placement-only", "plan-only"),
        ("trilab accuracy", "leak-rays", "rays"),
        ("trilab rays random", "random-rays", "count"),
        ("trilab rays diffuse", "diffuse-per-hit", "per-hit"),
        ("trilab spirv", "out", "write"),
        ("trilab bvh", "leaf-sizes", "leaf-size"),
    ] {
        let c = command(&tree, path);
        let a = arg(c, new).unwrap_or_else(|| panic!("{path}: no --{new}"));
        assert!(
            a["aliases"].as_array().unwrap().iter().any(|x| x == old),
            "{path}: --{old} is not an alias of --{new}"
        );
        assert!(arg(c, old).is_none(), "{path}: --{old} is still an option of its own");
    }
    for path in ["trilab bench", "trilab bench-render"] {
        let c = command(&tree, path);
        assert_eq!(arg(c, "out").unwrap()["value_names"][0], "DIR", "{path}");
        for old in ["json-out", "md-out"] {
            assert!(arg(c, old).unwrap()["hidden"].as_bool().unwrap(), "{path}: --{old} is hidden");
        }
    }
    let mut wrong = vec![];
    for c in leaf_commands(&tree) {
        let path = c["command"].as_str().unwrap();
        // --json on every command that prints a report.
        if !["trilab completions", "trilab man"].contains(&path) && arg(c, "json").is_none() {
            wrong.push(format!("{path}: no --json"));
        }
        // No visible option with an old spelling.
        for old in ["validate", "count", "per-hit", "write", "json-out", "md-out", "ray-kind"] {
            if arg(c, old).is_some_and(|a| !a["hidden"].as_bool().unwrap()) {
                wrong.push(format!("{path}: visible --{old}"));
            }
        }
        // --out says FILE or DIR; --rays is always a ray file; --threads and --leaf-sizes are lists.
        if let Some(a) = arg(c, "out") {
            let v = a["value_names"][0].as_str().unwrap_or("");
            if v != "FILE" && v != "DIR" {
                wrong.push(format!("{path}: --out <{v}>"));
            }
        }
        if let Some(a) = arg(c, "rays") {
            if a["value_names"][0] != "FILE" {
                wrong.push(format!("{path}: --rays is not a FILE"));
            }
        }
        for list in ["threads", "leaf-sizes"] {
            if let Some(a) = arg(c, list) {
                if !a["value_names"][0].as_str().unwrap_or("").contains(',') {
                    wrong.push(format!("{path}: --{list} is not a list"));
                }
            }
        }
        for one in ["scene", "scenes"] {
            if let Some(a) = arg(c, one) {
                if !a["help"].as_str().unwrap_or("").contains("bunny, dragon, buddha, cornell, bsdfs") {
                    wrong.push(format!("{path}: --{one} does not say it takes a scene name"));
                }
            }
        }
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}

#[test]
fn old_spellings_still_work() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let rays = s(&dir.path().join("r.rays"));
    ok(&["rays", "random", "--scene", &scene, "--out", &rays, "--count", "10"], 60);
    assert_eq!(std::fs::metadata(&rays).unwrap().len(), 10 * 32);
    let j: Value =
        serde_json::from_str(&ok(&["bvh", "--scene", &scene, "--leaf-size", "2", "--leaf-size", "4", "--json"], 60))
            .unwrap();
    assert_eq!(j.as_array().unwrap().len(), 4, "two leaf sizes, two builders");
    let j: Value = serde_json::from_str(&ok(
        &[
            "raycast",
            "--scene",
            &scene,
            "--rays",
            &rays,
            "--out",
            &s(&dir.path().join("h.hits")),
            "--validate",
            "--json",
        ],
        60,
    ))
    .unwrap();
    assert!(j["validation"].is_object(), "--validate still checks against the reference");
}

#[test]
fn bvh_takes_lists_of_leaf_sizes_and_threads_and_fits_100_columns() {
    let out = ok(&["bvh", "--scene", &bunny(), "--leaf-sizes", "4,16", "--threads", "1,2", "--json"], 120);
    let rows: Value = serde_json::from_str(&out).unwrap();
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 2 * 2 * 2, "leaf sizes x threads x builders");
    let threads: Vec<u64> = rows.iter().map(|r| r["stats"]["build_threads"].as_u64().unwrap()).collect();
    assert!(threads.contains(&1) && threads.contains(&2), "{threads:?}");
    let text = ok(&["bvh", "--scene", &bunny()], 180);
    for line in text.lines() {
        assert!(line.chars().count() <= 100, "bvh text is wider than 100 columns:\n{line}");
    }
    assert!(text.contains("nodes") && text.contains("MB quad-unit"), "{text}");
}

#[test]
fn repeat_zero_is_refused_at_parse_time_everywhere() {
    for cmd in [
        &["raycast", "--scene", "s.obj", "--rays", "r.rays", "--out", "h.hits"][..],
        &["bench"],
        &["bench-render"],
        &["study", "--preset", "smoke"],
        &["profile", "--scene", "s.obj"],
        &["scale"],
        &["build-bench", "--scenes", "s.obj"],
    ] {
        let mut args = cmd.to_vec();
        args.extend(["--repeat", "0"]);
        let o = trilab(&args, 30);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: refused as a usage error: {e}");
        assert!(e.contains("--repeat") && e.contains("at least 1"), "{args:?}: {e}");
        assert!(o.stdout.is_empty(), "{args:?}: no work, no report");
    }
}

#[test]
fn help_lists_the_methods_the_environment_and_the_formats() {
    let top = ok(&["--help"], 30);
    assert!(
        top.contains(&format!("{} methods", Method::ALL.len())),
        "the top line counts the registry's methods:\n{top}"
    );
    for v in trilab::env::ENV_VARS {
        assert!(top.contains(v.name), "--help names {}:\n{top}", v.name);
    }
    for page in ["docs/formats.md", "docs/commands.md", "docs/README.md"] {
        assert!(top.contains(page), "--help points at {page}:\n{top}");
    }
    for name in [
        "TRILAB_VALIDATION",
        "TRILAB_COMMIT",
        "TRILAB_INJECT_FAULT",
        "TRILAB_MAX_SCENE_BYTES",
        "TRILAB_TEST_LIMITS",
        "TRILAB_SCENES",
        "LP_NUM_THREADS",
        "LP_NATIVE_VECTOR_WIDTH",
    ] {
        assert!(trilab::env::ENV_VARS.iter().any(|v| v.name == name), "trilab::env lists {name}");
    }
    for cmd in [&["raycast", "-h"][..], &["raycast", "--help"], &["render", "-h"]] {
        let help = ok(cmd, 30);
        for m in Method::ALL {
            let line = help.lines().find(|l| l.split_whitespace().next() == Some(m.name()));
            assert!(line.is_some_and(|l| l.contains(m.title())), "{cmd:?} lists {} with its title:\n{help}", m.name());
        }
    }
    for c in leaf_commands(&cli_tree()) {
        let mut args: Vec<&str> = c["command"].as_str().unwrap().split(' ').skip(1).collect();
        args.push("--help");
        let help = ok(&args, 30);
        assert!(!help.contains("../shared/formats.md"), "{args:?} points outside the repository:\n{help}");
    }
    assert!(ok(&["rays", "--help"], 30).contains("docs/formats.md"));
}

/// The part of `text` from `heading` to the next heading of its level.
fn section<'a>(text: &'a str, heading: &str) -> &'a str {
    let start = text.find(heading).unwrap_or_else(|| panic!("docs/commands.md has {heading:?}")) + heading.len();
    let end = text[start..].find("\n## ").map_or(text.len(), |e| start + e);
    &text[start..end]
}

/// docs/commands.md, the command reference, is what `trilab man --markdown` prints from the clap
/// tree: every visible command with its help and its options, the options by name, the
/// environment variables.
#[test]
fn docs_commands_md_is_the_generated_reference() {
    let want = ok(&["man", "--markdown"], 30);
    let have = std::fs::read_to_string(common::root().join("docs/commands.md")).unwrap_or_default();
    assert!(
        have == want,
        "docs/commands.md is stale (or edited by hand): regenerate it with \
         `cargo run --release -- man --markdown > docs/commands.md`"
    );
    for c in leaf_commands(&cli_tree()) {
        let path = c["command"].as_str().unwrap();
        assert!(want.contains(&format!("## `{path}`")), "docs/commands.md has a section for {path}");
        for a in c["args"].as_array().unwrap() {
            if let (Some(long), false) = (a["long"].as_str(), a["hidden"].as_bool().unwrap()) {
                assert!(want.contains(&format!("- `--{long}")), "docs/commands.md lists {path} --{long}");
            }
        }
    }
}

/// The options several commands share are one vocabulary: docs/commands.md lists each by name
/// with the commands that take it, and its environment section is `src/env.rs`'s list.
#[test]
fn the_docs_document_the_options_and_the_environment() {
    let doc = std::fs::read_to_string(common::root().join("docs/commands.md")).unwrap();
    let by_name = section(&doc, "\n## Options by name\n");
    for opt in [
        "--scene",
        "--scenes",
        "--scene-dir",
        "--validation",
        "--device",
        "--reference",
        "--reference-rays",
        "--leaf-sizes",
        "--leaf-size",
        "--threads",
        "--methods",
        "--random-rays",
        "--diffuse-per-hit",
        "--ray-count",
        "--ray-set",
        "--leak-rays",
        "--rays",
        "--out",
        "--json",
        "--repeat",
        "--shard",
        "--embree",
        "--tinybvh",
        "--tinybvh-layouts",
    ] {
        assert!(by_name.contains(&format!("\n- `{opt}`: ")), "docs/commands.md's Options by name lists {opt}");
    }
    let scene = by_name.lines().find(|l| l.starts_with("- `--scene`: ")).unwrap();
    for cmd in ["raycast", "render", "hits check", "accuracy"] {
        assert!(scene.contains(&format!("[`{cmd}`]")), "--scene is taken by {cmd}: {scene}");
    }
    let env = section(&doc, "\n## Environment variables\n\n");
    assert_eq!(
        env.replace("\\<", "<").trim_end(),
        trilab::env::markdown().trim_end(),
        "docs/commands.md's environment list is src/env.rs's"
    );
    let using = std::fs::read_to_string(common::root().join("docs/using.md")).unwrap();
    let shared = section(&using, "\n## Options shared by several commands\n");
    assert!(shared.contains("](commands.md)"), "docs/using.md's shared options point at the reference");
}

/// `trilab --help` gives each command one line, as cargo and git do, and stays short; the detail
/// is in `trilab CMD --help`, whose first line is the same summary.
#[test]
fn help_gives_each_command_one_line() {
    let top = ok(&["--help"], 30);
    let lines = top.lines().count();
    assert!(lines <= 45, "trilab --help is {lines} lines; keep it under 45:\n{top}");
    assert!(
        top.lines().all(|l| l.chars().count() <= 100 || l.contains("--scene-dir")),
        "lines of at most 100 columns:\n{top}"
    );
    let list: Vec<&str> = top.lines().skip_while(|l| *l != "Commands:").skip(1).take_while(|l| !l.is_empty()).collect();
    let tree = cli_tree();
    let commands: Vec<&Value> =
        tree.iter().filter(|c| c["command"].as_str().unwrap().split(' ').count() == 2).collect();
    assert!(list.len() >= commands.len() && commands.len() > 20, "one line per command:\n{top}");
    for c in &tree {
        let path = c["command"].as_str().unwrap();
        if path == "trilab" || is_help(path) {
            continue;
        }
        let about = c["about"].as_str().unwrap_or("");
        assert!(!about.is_empty(), "{path} has a one-line summary");
        assert!(
            about.chars().count() <= 80 && !about.contains('\n'),
            "{path}: the summary `trilab --help` lists is one line of at most 80 characters; the detail goes in a \
             second paragraph of its doc comment (clap shows it under `{path} --help`): {about}"
        );
    }
    for c in commands {
        let path = c["command"].as_str().unwrap();
        let name = path.rsplit(' ').next().unwrap();
        let about = c["about"].as_str().unwrap();
        assert!(
            list.iter().any(|l| l.split_whitespace().next() == Some(name) && l.trim_end().ends_with(about)),
            "trilab --help lists {name} with its summary on one line:\n{top}"
        );
    }
    let compare = ok(&["compare", "--help"], 30);
    assert!(compare.contains("Exit status: 0 no regression"), "the detail stays in `compare --help`:\n{compare}");
    let ab = ok(&["ab", "--help"], 30);
    assert!(ab.contains("as gpu-trace-perf and Mesa's shader-db compare builds"), "and in `ab --help`:\n{ab}");
}

#[test]
fn completions_and_man_pages_cover_every_command() {
    let tree = cli_tree();
    let bash = ok(&["completions", "bash"], 30);
    for c in &tree {
        let name = c["command"].as_str().unwrap().rsplit(' ').next().unwrap();
        assert!(bash.contains(name), "the bash completion mentions {name}");
    }
    for shell in ["zsh", "fish", "elvish", "powershell"] {
        assert!(ok(&["completions", shell], 30).contains("raycast"), "{shell}");
    }
    let dir = tempfile::tempdir().unwrap();
    ok(&["man", "--out", &s(dir.path())], 30);
    for c in &tree {
        let path = c["command"].as_str().unwrap();
        if is_help(path) {
            continue;
        }
        let page = dir.path().join(format!("{}.1", path.replace(' ', "-")));
        let text = std::fs::read_to_string(&page).unwrap_or_else(|e| panic!("{}: {e}", page.display()));
        for a in c["args"].as_array().unwrap() {
            if let (Some(long), false) = (a["long"].as_str(), a["hidden"].as_bool().unwrap()) {
                let roff = format!("\\-\\-{}", long.replace('-', "\\-"));
                assert!(text.contains(&roff), "{}: renders --{long}", page.display());
            }
        }
    }
    assert!(ok(&["man"], 30).starts_with(".ie"), "trilab man prints trilab.1");
}

#[test]
fn raycast_text_prints_the_reference_check_as_sentences() {
    let dir = tempfile::tempdir().unwrap();
    let rays = s(&dir.path().join("r.rays"));
    ok(&["rays", "random", "--scene", &bunny(), "--out", &rays, "--random-rays", "2000"], 120);
    let out = s(&dir.path().join("h.hits"));
    let text = ok(
        &[
            "raycast",
            "--scene",
            &bunny(),
            "--rays",
            &rays,
            "--out",
            &out,
            "--reference",
            "--repeat",
            "1",
            "--validation",
        ],
        120,
    );
    let line =
        text.lines().find(|l| l.starts_with("reference:")).unwrap_or_else(|| panic!("no reference line:\n{text}"));
    assert!(!text.contains('{') && !text.contains('"'), "no JSON in text mode:\n{text}");
    assert!(line.contains("agrees with the f64 reference") && line.contains("2000/2000 rays agree"), "{line}");
}

#[test]
fn profile_names_the_device_once() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(&dir.path().join("profile"));
    let text = ok(
        &[
            "profile",
            "--scene",
            &bunny(),
            "--methods",
            "mt",
            "--width",
            "16",
            "--height",
            "12",
            "--random-rays",
            "500",
            "--diffuse-per-hit",
            "1",
            "--repeat",
            "1",
            "--no-threads",
            "--workgroup-sizes",
            "32,64",
            "--out",
            &out,
            "--validation",
        ],
        300,
    );
    let json: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("profile/profile.json")).unwrap()).unwrap();
    let device = json["device"].as_str().unwrap();
    let lines = text.lines().filter(|l| l.contains(device)).count();
    assert!(lines <= 2, "the device is named in the header, not on every row ({lines} lines):\n{text}");
    assert!(!text.contains("device / driver"), "{text}");
    let md = std::fs::read_to_string(dir.path().join("profile/profile.md")).unwrap();
    assert!(md.lines().filter(|l| l.contains(device)).count() <= 2, "{md}");
}

#[test]
fn with_json_errors_are_json_with_the_same_exit_code() {
    let dir = tempfile::tempdir().unwrap();
    let rays = s(&dir.path().join("r.rays"));
    let out = s(&dir.path().join("h.hits"));
    let args = ["raycast", "--scene", "/no/such/scene.obj", "--rays", &rays, "--out", &out];
    let plain = trilab(&args, 60);
    let mut with_json = args.to_vec();
    with_json.push("--json");
    let json = trilab(&with_json, 60);
    assert!(!plain.status.success());
    assert_eq!(json.status.code(), plain.status.code(), "the same exit code");
    let v: Value = serde_json::from_str(stdout(&json).trim()).unwrap_or_else(|e| panic!("{e}: {}", stdout(&json)));
    assert_eq!(v["error"]["kind"], "bad-input");
    assert!(v["error"]["message"].as_str().unwrap().contains("/no/such/scene.obj"), "{v}");
    // An argument clap refuses: JSON too, with clap's exit code.
    let o = trilab(&["bvh", "--scene", "x.obj", "--leaf-sizes", "four", "--json"], 30);
    assert_eq!(o.status.code(), Some(2));
    let v: Value = serde_json::from_str(stdout(&o).trim()).unwrap_or_else(|e| panic!("{e}: {}", stdout(&o)));
    assert_eq!(v["error"]["kind"], "arguments");
    assert!(v["error"]["message"].as_str().unwrap().contains("--leaf-sizes"), "{v}");
}

#[test]
fn kernel_variants_are_named_after_the_methods() {
    let v: Value = serde_json::from_str(&ok(&["spirv", "--json"], 30)).unwrap();
    let compiler = v["compiler"].as_str().unwrap();
    assert!(compiler.contains("SPIRV-Tools"), "the compiler names its SPIRV-Tools: {compiler}");
    let names: Vec<&str> = v["variants"].as_array().unwrap().iter().map(|k| k["variant"].as_str().unwrap()).collect();
    for m in Method::ALL {
        assert!(names.contains(&format!("raycast.{}.closest", m.name()).as_str()), "{m}: {names:?}");
    }
    assert!(names.iter().all(|n| !n.split('.').nth(1).unwrap().contains('_')), "{names:?}");
    assert!(common::root().join("spirv/raycast.baldwin-weber.closest.spvasm").exists(), "spirv/ uses the names");
}
