//! `trilab study`.

use super::OutArgs;
use super::ShardArg;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::Arc;

use clap::Args;
use trilab::commands::study::{self, Preset, StudyOptions};
use trilab::encoding::Layout;
use trilab::error::Result;

use super::choice::choice;
use super::{repeat, results_dir, signals, GpuArgs, JsonArg, MethodsArg, SahGroupArg};

/// The paper's study on this device: scene x leaf size x method, validated
///
/// The paper's study on this device: scene x leaf size {1,2,3,4,8,16} x method, path-trace
/// seconds and Mrays/s per ray set, validated; writes study.csv/json/md and plots.
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("Output directory for study.csv/json/md and plots. Default: results/<device>/study/ (lavapipe, or the device name)")))]
#[command(mut_arg("shard", |a| a.help("Run only shard I of N of the matrix: every N-th (scene, leaf size) group, round-robin from group I, so each leaf size's methods and layouts still run side by side. rows.jsonl names the shard and plans the whole matrix; the report's claims judge this shard's cells only and say so; `trilab merge` joins the shards' folders")))]
pub struct StudyArgs {
    #[arg(long, value_name = "A,B", value_delimiter = ',', help = concat!(super::scenes_help!(),
          "; default: the preset's (bunny, dragon, buddha; the smoke preset only the bunny)"))]
    scenes: Vec<String>,
    /// paper: 800x600, 500 spp, depth 16; lavapipe: scaled to about 20 minutes on 2 CPU cores;
    /// smoke: seconds, for CI.
    #[arg(long, value_parser = choice::<Preset>(), default_value_t = Preset::Lavapipe)]
    preset: Preset,
    #[command(flatten)]
    out: OutArgs,
    /// Leaf sizes, comma-separated (default: 1,2,3,4,8,16).
    #[arg(long, value_name = "N,...", value_delimiter = ',')]
    leaf_sizes: Vec<u32>,
    /// Methods (default: the paper's four, mt,unit,quad-mt,quad-unit).
    #[command(flatten)]
    methods: MethodsArg,
    /// BVH node layouts, comma-separated (`bvh2`, `bvh4`, `bvh8`, ...): every method and leaf size
    /// runs on each, interleaved; claims are judged per layout and study.md answers whether the
    /// best intersector and leaf size change with it (default: bvh2).
    #[arg(long, value_name = "L,...", value_parser = choice::<Layout>(), value_delimiter = ',')]
    layouts: Vec<Layout>,
    /// Timed rounds after the warm-up round (at least 1; default: the preset's).
    #[arg(long, value_name = "N", value_parser = repeat)]
    repeat: Option<usize>,
    #[command(flatten)]
    sah_group: SahGroupArg,
    #[command(flatten)]
    shard: ShardArg,
    /// Leave out the section that compiles the study's kernels for AMD GPUs (pitcairn, the
    /// paper's HD 7850, then polaris10, navi21, navi31, gfx1201) through RADV's null device and
    /// bounds claim (c) by their occupancy.
    #[arg(long)]
    no_compiled: bool,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: StudyArgs) -> Result<()> {
    let mut o = StudyOptions::preset(a.preset);
    if !a.scenes.is_empty() {
        o.scenes = a.scenes.iter().map(|s| study::scene_path(s)).collect();
    }
    if !a.leaf_sizes.is_empty() {
        o.leaf_sizes = a.leaf_sizes.clone();
    }
    if !a.methods.methods.is_empty() {
        o.methods = a.methods.methods.clone();
    }
    if !a.layouts.is_empty() {
        o.layouts = a.layouts.clone();
    }
    if let Some(r) = a.repeat {
        o.repeat = r;
    }
    o.sah_group = a.sah_group.sah_group;
    o.shard = a.shard.shard;
    if !a.no_compiled {
        o.compiled = Some(study::compiled::CompiledOptions {
            exe: trilab::services::worker::this_exe()?,
            validation: a.gpu.validation_required(),
        });
    }
    o.check()?;
    let ctx = a.gpu.context()?;
    let out = results_dir(&ctx, a.out.dir.clone(), "study");
    let inputs: Vec<&Path> = o.scenes.iter().map(PathBuf::as_path).collect();
    let files = ["study.csv", "study.json", "study.md", trilab::rows::FILE];
    OutArgs::check(&out, &files, &inputs)?;
    eprintln!("study: {}", o.scaling());
    if let Some(shard) = o.shard {
        let split = o.split();
        eprintln!("study: shard {shard}: {} of {} (scene, leaf size) groups", split.owned(), split.units());
    }
    // Ctrl-C, SIGTERM or SIGHUP: finish the (scene, leaf size) group under way, write what is
    // finished, then exit 128 + the signal's number. A second signal ends it at once, its
    // children (the driver's, none today) with it.
    let stop = Arc::new(AtomicBool::new(false));
    let first = Arc::new(AtomicI32::new(0));
    o.stop = Some(stop.clone());
    let signal = first.clone();
    let handler = signals::on_stop(move |sig| {
        if stop.swap(true, Ordering::SeqCst) {
            eprintln!("study: {} again: stopping without writing", signals::name(sig));
            trilab::children::signal_all(sig);
            signals::exit_now(sig);
        }
        signal.store(sig, Ordering::SeqCst);
        eprintln!("study: {}: finishing the group under way, then writing what is done", signals::name(sig));
    });
    if let Err(e) = handler {
        super::note(&format!("warning: cannot catch Ctrl-C or SIGTERM ({e}); a stopped study will not be written"));
    }
    let report = study::run(&ctx, &o, |m| eprintln!("  {m}"))?;
    a.json.print(&report);
    let written = study::write(&report, &out)?;
    eprintln!("study took {:.0} s; wrote:", report.seconds);
    for w in written {
        eprintln!("  {}", w.display());
    }
    match first.load(Ordering::SeqCst) {
        0 => Ok(()),
        sig => {
            eprintln!("study: {}", report.stopped.as_deref().unwrap_or("stopped after its last group"));
            super::exit_interrupted(sig)
        }
    }
}
