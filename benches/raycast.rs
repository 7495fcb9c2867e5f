//! `cargo bench --bench raycast`: the ray-casting benchmark on the bundled scenes (primary,
//! diffuse and random rays, every method at leaf size 4), each result validated against the
//! f64 reference before its speed is printed. Same code as `trilab bench`; set
//! `TRILAB_BENCH_SCENES=scenes/bunny.obj,...` to choose scenes and `TRILAB_EMBREE=path` to run
//! the Embree peer beside it.

use std::path::PathBuf;

use trilab::commands::bench::{run, BenchOptions};
use trilab::gpu::{Context, ContextOptions, Validation};
use trilab::report::Report;

fn main() {
    // `cargo bench` passes --bench; `cargo test --benches` passes nothing and expects a quick
    // exit, so only run when asked to bench.
    if !std::env::args().any(|a| a == "--bench") {
        return;
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scenes =
        std::env::var("TRILAB_BENCH_SCENES").map(|s| s.split(',').map(PathBuf::from).collect()).unwrap_or_else(|_| {
            ["bunny", "dragon", "buddha"].iter().map(|s| root.join("scenes").join(format!("{s}.obj"))).collect()
        });
    let opts =
        BenchOptions { scenes, embree: std::env::var("TRILAB_EMBREE").ok().map(PathBuf::from), ..Default::default() };
    let ctx =
        Context::new(&ContextOptions { validation: Validation::Off, ..Default::default() }).expect("a Vulkan device");
    let report = run(&ctx, &opts, |m| eprintln!("  {m}")).expect("benchmark");
    print!("{}", report.to_text());
}
