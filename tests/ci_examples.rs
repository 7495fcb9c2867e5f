//! examples/ci/ (a GitLab CI file and a GitHub Actions workflow) cannot run here, so their
//! structure is checked: the jobs exist; the merge-request jobs run the suite, compare its counts
//! and correctness with the committed baseline without judging its timings, and time the two
//! drivers in one `ab` job with a stated threshold (docs/gate.md: timings only inside one run); the nightly matrix gives every device every shard 1/N..N/N exactly once
//! (expanded the way each CI system expands it); the merge job needs the shard jobs and runs
//! when a shard failed; and every trilab invocation in a script, with each matrix combination's
//! variables put in, parses with trilab's own CLI (`trilab <args> --help`: clap rejects an
//! unknown command, an unknown option or a bad value before it prints the help).
//!
//! The checks are also run on copies with a shard dropped, a device's shard doubled, the merge
//! job's dependency removed and a misspelt option, and must fail there.

mod common;

use std::collections::BTreeMap;

use serde_yaml::{Mapping, Value};

/// Subcommands the CI files use that another branch of issue 16 adds (`trilab suite`: the lead;
/// `trilab compare`: H1). Until they are on this branch, an invocation of one is reported, not
/// parsed; once merged, this list must be emptied (the test then parses them too).
const PENDING: &[&str] = &[];

fn load(name: &str) -> Value {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/ci").join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut doc: Value = serde_yaml::from_str(&text).unwrap_or_else(|e| panic!("{}: not YAML: {e}", path.display()));
    // GitLab's `<<: *anchor` merge keys, applied as GitLab applies them.
    doc.apply_merge().unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    doc
}

fn s(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        Value::Number(n) => n.to_string(),
        Value::Bool(b) => b.to_string(),
        _ => String::new(),
    }
}

fn list(v: &Value) -> Vec<Value> {
    match v {
        Value::Sequence(xs) => xs.clone(),
        Value::Null => vec![],
        x => vec![x.clone()],
    }
}

fn strings(v: &Value) -> Vec<String> {
    list(v).iter().map(s).collect()
}

type Vars = BTreeMap<String, String>;

fn vars(v: &Value) -> Vars {
    v.as_mapping().map(|m| m.iter().map(|(k, v)| (s(k), s(v))).collect()).unwrap_or_default()
}

/// `$NAME`, `${NAME}` and `${{ matrix.name }}` / `${{ strategy.job-index }}` replaced from
/// `vars` (the CI's own variables, such as `$CI_NODE_INDEX`, become `0`).
fn substitute(text: &str, vars: &Vars) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(i) = rest.find('$') {
        out.push_str(&rest[..i]);
        let after = &rest[i + 1..];
        let (name, len) = if let Some(expr) = after.strip_prefix("{{") {
            let end = expr.find("}}").expect("closed ${{ }}");
            let e = expr[..end].trim();
            (e.strip_prefix("matrix.").unwrap_or(e).to_owned(), end + 4)
        } else if let Some(braced) = after.strip_prefix('{') {
            let end = braced.find('}').expect("closed ${}");
            (braced[..end].to_owned(), end + 2)
        } else {
            let end = after.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(after.len());
            (after[..end].to_owned(), end)
        };
        if name.is_empty() || name == "?" {
            out.push('$');
            rest = after;
            continue;
        }
        out.push_str(vars.get(&name).map_or("0", String::as_str));
        rest = &after[len..];
    }
    out.push_str(rest);
    out
}

/// The trilab invocations (arguments after the binary) in a script's lines: each command of a
/// line (split at `;`, `&&`, `||`, `|`) whose first word is the trilab binary, up to a redirect.
fn invocations(script: &str, vars: &Vars) -> Vec<Vec<String>> {
    let mut out = vec![];
    for line in substitute(script, vars).lines() {
        for cmd in line.split([';', '|']).flat_map(|c| c.split("&&")) {
            let words: Vec<String> = cmd.split_whitespace().map(|w| w.trim_matches(['"', '\'']).to_owned()).collect();
            if words.first().is_some_and(|w| w == "trilab" || w.ends_with("/trilab")) {
                out.push(
                    words[1..].iter().take_while(|w| !w.starts_with('>') && !w.starts_with("2>")).cloned().collect(),
                );
            }
        }
    }
    out
}

/// Parses one invocation with trilab's CLI; Err names it and says why.
fn parses(args: &[String]) -> Result<(), String> {
    let sub = args.first().map(String::as_str).unwrap_or("");
    let mut with_help: Vec<&str> = args.iter().map(String::as_str).collect();
    with_help.push("--help");
    let (o, _) = common::cli::run(&with_help, None, &[], 60);
    let (out, err) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    if o.status.success() && out.contains(&format!("Usage: trilab {sub}")) {
        return Ok(());
    }
    if PENDING.contains(&sub) && err.contains("unrecognized subcommand") {
        eprintln!("note: `trilab {}` not parsed: `{sub}` is added by another branch of issue 16", args.join(" "));
        return Ok(());
    }
    Err(format!("`trilab {}` does not parse: {err}", args.join(" ")))
}

/// Checks that every device has every shard 1/N..N/N exactly once (one N for all devices).
fn shards_complete(combos: &[(String, String)]) -> Result<usize, String> {
    let mut by_device: BTreeMap<&str, Vec<(u32, u32)>> = BTreeMap::new();
    for (device, shard) in combos {
        let (i, n) = shard.split_once('/').ok_or_else(|| format!("{device}: shard `{shard}` is not I/N"))?;
        let (i, n) = (i.parse().map_err(|_| format!("shard `{shard}`"))?, n.parse().map_err(|_| format!("`{shard}`"))?);
        by_device.entry(device).or_default().push((i, n));
    }
    if by_device.is_empty() {
        return Err("the matrix has no shard job".into());
    }
    let n = by_device.values().next().unwrap()[0].1;
    for (device, mut shards) in by_device.clone() {
        shards.sort();
        let want: Vec<(u32, u32)> = (1..=n).map(|i| (i, n)).collect();
        if shards != want {
            return Err(format!("device {device} runs shards {shards:?}, not each of 1/{n}..{n}/{n} once"));
        }
    }
    Ok(by_device.len())
}

fn needs(job: &Value) -> Vec<String> {
    list(&job["needs"]).iter().map(|n| if n.is_mapping() { s(&n["job"]) } else { s(n) }).collect()
}

// ---- GitLab CI ----

/// A GitLab `parallel: matrix:` expanded: each entry's lists multiplied out.
fn gitlab_matrix(job: &Value) -> Vec<Vars> {
    let mut out = vec![];
    for entry in list(&job["parallel"]["matrix"]) {
        let mut combos: Vec<Vars> = vec![Vars::new()];
        for (k, v) in entry.as_mapping().expect("a matrix entry is a mapping") {
            combos = combos
                .into_iter()
                .flat_map(|c| {
                    strings(v).into_iter().map(move |x| {
                        let mut c = c.clone();
                        c.insert(s(k), x);
                        c
                    })
                })
                .collect();
        }
        out.extend(combos);
    }
    out
}

fn gitlab_check(doc: &Value) -> Result<Vec<Vec<String>>, String> {
    let jobs = ["build", "suite", "compare", "ab", "study-shard", "merge"];
    for j in jobs {
        if !doc[j].is_mapping() {
            return Err(format!("no job `{j}`"));
        }
    }
    let global = vars(&doc["variables"]);
    let script = |job: &Value| {
        ["before_script", "script", "after_script"]
            .iter()
            .flat_map(|k| strings(&job[*k]))
            .collect::<Vec<_>>()
            .join("\n")
    };
    let mr = |j: &str| list(&doc[j]["rules"]).iter().any(|r| s(&r["if"]).contains("merge_request_event"));
    if !mr("suite") || !mr("compare") || !mr("ab") {
        return Err("suite, compare and ab must run on merge requests".into());
    }
    if !needs(&doc["compare"]).contains(&"suite".to_owned()) {
        return Err("compare must need suite (its results)".into());
    }
    let combos = gitlab_matrix(&doc["study-shard"]);
    let pairs: Vec<(String, String)> = combos.iter().map(|c| (c["DEVICE"].clone(), c["SHARD"].clone())).collect();
    shards_complete(&pairs)?;
    if !strings(&doc["study-shard"]["tags"]).iter().any(|t| t.contains("$DEVICE")) {
        return Err("each shard job must run on its device's runner (tags: [$DEVICE])".into());
    }
    if !needs(&doc["merge"]).contains(&"study-shard".to_owned()) {
        return Err("merge must need study-shard (every shard's rows)".into());
    }
    if !list(&doc["merge"]["rules"]).iter().any(|r| s(&r["when"]) == "always") {
        return Err("merge must run when a shard failed (when: always) to list its cells as missing".into());
    }
    let mut all = vec![];
    for j in jobs {
        let job = &doc[j];
        let mut job_vars = global.clone();
        job_vars.extend(vars(&job["variables"]));
        let variants = if j == "study-shard" { combos.clone() } else { vec![Vars::new()] };
        for m in variants {
            let mut v = job_vars.clone();
            v.extend(m);
            all.extend(invocations(&script(job), &v));
        }
    }
    Ok(all)
}

// ---- GitHub Actions ----

/// A GitHub Actions matrix expanded: the product of its lists, `exclude` removed, each
/// `include` added to the combinations it matches on the original keys (or as its own).
fn github_matrix(matrix: &Value) -> Vec<Vars> {
    let m = matrix.as_mapping().cloned().unwrap_or_else(Mapping::new);
    let mut combos: Vec<Vars> = vec![Vars::new()];
    let mut base_keys = vec![];
    for (k, v) in &m {
        let k = s(k);
        if k == "include" || k == "exclude" {
            continue;
        }
        base_keys.push(k.clone());
        combos = combos
            .into_iter()
            .flat_map(|c| {
                let k = k.clone();
                strings(v).into_iter().map(move |x| {
                    let mut c = c.clone();
                    c.insert(k.clone(), x);
                    c
                })
            })
            .collect();
    }
    let matches =
        |c: &Vars, o: &Vars| o.iter().filter(|(k, _)| base_keys.contains(k)).all(|(k, v)| c.get(k) == Some(v));
    for ex in list(&m.get("exclude").cloned().unwrap_or(Value::Null)) {
        let ex = vars(&ex);
        combos.retain(|c| !matches(c, &ex));
    }
    for inc in list(&m.get("include").cloned().unwrap_or(Value::Null)) {
        let inc = vars(&inc);
        let mut hit = false;
        for c in combos.iter_mut().filter(|c| matches(c, &inc)) {
            c.extend(inc.clone());
            hit = true;
        }
        if !hit {
            combos.push(inc);
        }
    }
    combos
}

fn github_check(doc: &Value) -> Result<Vec<Vec<String>>, String> {
    let jobs = ["build", "suite", "compare", "ab", "study-shard", "merge"];
    for j in jobs {
        if !doc["jobs"][j].is_mapping() {
            return Err(format!("no job `{j}`"));
        }
    }
    let job = |j: &str| &doc["jobs"][j];
    for j in ["suite", "compare", "ab"] {
        if !s(&job(j)["if"]).contains("pull_request") {
            return Err(format!("{j} must run on pull requests"));
        }
    }
    if !needs(job("compare")).contains(&"suite".to_owned()) {
        return Err("compare must need suite (its results)".into());
    }
    let combos = github_matrix(&job("study-shard")["strategy"]["matrix"]);
    let pairs: Vec<(String, String)> = combos
        .iter()
        .map(|c| (c.get("device").cloned().unwrap_or_default(), c.get("shard").cloned().unwrap_or_default()))
        .collect();
    shards_complete(&pairs)?;
    let runs_on = s(&job("study-shard")["runs-on"]);
    for c in &combos {
        if substitute(&runs_on, c).is_empty() || substitute(&runs_on, c) == "0" {
            return Err(format!("device {} has no runner", c["device"]));
        }
    }
    if !needs(job("merge")).contains(&"study-shard".to_owned()) {
        return Err("merge must need study-shard (every shard's rows)".into());
    }
    if !s(&job("merge")["if"]).contains("always()") {
        return Err("merge must run when a shard failed (if: always()) to list its cells as missing".into());
    }
    let global = vars(&doc["env"]);
    let mut all = vec![];
    for j in jobs {
        let variants = if j == "study-shard" { combos.clone() } else { vec![Vars::new()] };
        for m in variants {
            for step in list(&job(j)["steps"]) {
                let mut v = global.clone();
                v.extend(vars(&job(j)["env"]));
                v.extend(m.clone());
                // A step's env may itself name matrix values.
                let step_env: Vars = vars(&step["env"]).into_iter().map(|(k, x)| (k, substitute(&x, &v))).collect();
                v.extend(step_env);
                all.extend(invocations(&s(&step["run"]), &v));
            }
        }
    }
    Ok(all)
}

/// A CI file's structural check: the trilab invocations, or what is wrong.
type Check = fn(&Value) -> Result<Vec<Vec<String>>, String>;

/// Timings are judged only inside one run (issue 36): every compare against the committed
/// baseline leaves timings out (`--timings ignore`: the baseline ran on another host), and an
/// `ab` names both sides' drivers (or builds) and states its threshold (a number, in percent).
fn timings_judged_in_one_run(invocations: &[Vec<String>]) -> Result<(), String> {
    let compares: Vec<&Vec<String>> = invocations.iter().filter(|a| a[0] == "compare").collect();
    if compares.is_empty() {
        return Err("no `trilab compare`".into());
    }
    for a in compares {
        if !a.windows(2).any(|w| w[0] == "--timings" && w[1] == "ignore") {
            return Err(format!(
                "`trilab {}` judges timings against a committed baseline (measured on another host): give --timings ignore",
                a.join(" ")
            ));
        }
    }
    let abs: Vec<&Vec<String>> = invocations.iter().filter(|a| a[0] == "ab").collect();
    if abs.is_empty() {
        return Err("no `trilab ab`: nothing times the change against its base in one run".into());
    }
    for a in abs {
        let t =
            a.iter().position(|w| w == "--threshold").and_then(|i| a.get(i + 1)).and_then(|t| t.parse::<f64>().ok());
        if !t.is_some_and(|t| t > 0.0) {
            return Err(format!("`trilab {}` states no threshold", a.join(" ")));
        }
        let names = |x: &str| a.iter().any(|w| w == &format!("--a-{x}")) && a.iter().any(|w| w == &format!("--b-{x}"));
        if !names("icd") && !names("bin") {
            return Err(format!(
                "`trilab {}` does not name both sides (--a-icd/--b-icd or --a-bin/--b-bin)",
                a.join(" ")
            ));
        }
    }
    Ok(())
}

fn check_all_parse(invocations: &[Vec<String>]) {
    let mut distinct = invocations.to_vec();
    distinct.sort();
    distinct.dedup();
    for a in &distinct {
        parses(a).unwrap();
    }
    for cmd in ["suite", "compare", "ab", "study", "merge"] {
        assert!(invocations.iter().any(|a| a[0] == cmd), "no `trilab {cmd}`");
    }
    assert!(
        invocations.iter().any(|a| a[0] == "suite" && a.contains(&"--size".to_owned())),
        "the merge-request suite pins its sizes (--size), so every cell matches the baseline's"
    );
}

#[test]
fn the_gitlab_file_has_the_jobs_a_complete_shard_matrix_and_parsing_invocations() {
    let doc = load("gitlab-ci.yml");
    let inv = gitlab_check(&doc).unwrap();
    timings_judged_in_one_run(&inv).unwrap();
    // Every device x shard combination gives its own study invocation.
    assert_eq!(inv.iter().filter(|a| a[0] == "study").count(), gitlab_matrix(&doc["study-shard"]).len());
    assert!(inv.iter().filter(|a| a[0] == "study").all(|a| a.contains(&"--shard".to_owned())));
    check_all_parse(&inv);
}

#[test]
fn the_github_workflow_has_the_jobs_a_complete_shard_matrix_and_parsing_invocations() {
    let doc = load("github-actions.yml");
    let inv = github_check(&doc).unwrap();
    timings_judged_in_one_run(&inv).unwrap();
    let combos = github_matrix(&doc["jobs"]["study-shard"]["strategy"]["matrix"]);
    assert!(combos.len() >= 2 * 4, "{combos:?}");
    assert_eq!(inv.iter().filter(|a| a[0] == "study").count(), combos.len());
    // lavapipe runs at both vector widths.
    let widths: Vec<&str> = combos.iter().filter_map(|c| c.get("lp_width").map(String::as_str)).collect();
    assert!(widths.contains(&"128") && widths.contains(&"256"), "{widths:?}");
    check_all_parse(&inv);
}

/// Drops the last shard of the first device's list (GitLab) or of the matrix (GitHub).
fn drop_a_shard(doc: &mut Value, gitlab: bool) {
    let shards = if gitlab {
        &mut doc["study-shard"]["parallel"]["matrix"][0]["SHARD"]
    } else {
        &mut doc["jobs"]["study-shard"]["strategy"]["matrix"]["shard"]
    };
    shards.as_sequence_mut().unwrap().pop();
}

#[test]
fn the_checks_fail_on_a_dropped_shard_a_doubled_shard_a_lost_dependency_and_a_bad_option() {
    for gitlab in [true, false] {
        let (name, check): (_, Check) =
            if gitlab { ("gitlab-ci.yml", gitlab_check) } else { ("github-actions.yml", github_check) };
        let doc = load(name);
        let mut d = doc.clone();
        drop_a_shard(&mut d, gitlab);
        let e = check(&d).unwrap_err();
        assert!(e.contains("not each of"), "{name}: {e}");

        let mut d = doc.clone();
        if gitlab {
            let extra = serde_yaml::from_str("{DEVICE: lavapipe-w4, SHARD: '2/4'}").unwrap();
            d["study-shard"]["parallel"]["matrix"].as_sequence_mut().unwrap().push(extra);
        } else {
            let extra = serde_yaml::from_str("{device: gpu-extra, shard: '2/4', runner: gpu-extra}").unwrap();
            d["jobs"]["study-shard"]["strategy"]["matrix"]["include"].as_sequence_mut().unwrap().push(extra);
        }
        assert!(check(&d).unwrap_err().contains("not each of"), "{name}: a doubled or lone shard");

        let mut d = doc.clone();
        let merge = if gitlab { &mut d["merge"] } else { &mut d["jobs"]["merge"] };
        merge["needs"] = serde_yaml::from_str("[build]").unwrap();
        assert!(check(&d).unwrap_err().contains("merge must need study-shard"), "{name}");
    }
    assert!(parses(&["study".into(), "--shard".into(), "5/4".into()]).is_err());
    assert!(parses(&["study".into(), "--no-such-option".into()]).is_err());
    assert!(parses(&["merge".into(), "x".into(), "--out".into(), "y".into()]).is_ok());
    let words = |w: &str| w.split(' ').map(String::from).collect::<Vec<String>>();
    let ab = words("ab --a-icd a.json --b-icd b.json --judge kernels --threshold 10");
    let judged = |c: &str| timings_judged_in_one_run(&[words(c), ab.clone()]);
    assert!(judged("compare a b --timings ignore --count-threshold 0").is_ok());
    assert!(judged("compare a b").is_err(), "raw timings against a baseline");
    assert!(judged("compare a b --timings calibrated --threshold 40").is_err(), "calibrated timings of another host");
    assert!(timings_judged_in_one_run(&[words("compare a b --timings ignore")]).is_err(), "no ab");
    let one_side = words("ab --b-icd b.json --threshold 10");
    assert!(timings_judged_in_one_run(&[words("compare a b --timings ignore"), one_side]).is_err());
    let no_threshold = words("ab --a-bin a --b-bin b");
    assert!(timings_judged_in_one_run(&[words("compare a b --timings ignore"), no_threshold]).is_err());
    let v: Vars = [("SHARD".to_owned(), "2/4".to_owned())].into();
    assert_eq!(
        invocations("chmod +x x/trilab && x/trilab study --shard ${SHARD} > log; echo", &v),
        vec![vec!["study".to_owned(), "--shard".into(), "2/4".into()]]
    );
}
