//! Compiles every GLSL compute kernel in `glsl/` to SPIR-V with shaderc and embeds the modules.
//!
//! Layout of `glsl/` (see `glsl/README.md`):
//! - `*.comp` are kernels. A kernel's first lines may declare its variants:
//!   `// trilab:variants closest any=ANY_HIT` (a variant name, optionally `=MACRO[,MACRO...]`).
//! - `intersect/<method>.glsl` are the intersectors. Every kernel is compiled once per
//!   intersector × variant; inside a kernel `#include "intersector.glsl"` resolves to the
//!   intersector of that variant, and `METHOD_<METHOD>` is defined.
//! - `layout/<name>.glsl` are node layouts (their node format and step,
//!   `glsl/layout_interface.glsl`). `layout/bvh2.glsl`, the binary nodes, is the default: every
//!   variant compiles with it, `#include "layout.glsl"` resolving to it. A kernel's line
//!   `// trilab:layouts closest any ...` (or `// trilab:layouts(bvh4,bvh8) ...`: those layouts
//!   only; `(stepped)`: the layouts that give a step, all but cwbvh) names variants compiled once more per other layout, as `<variant>_<name>` with
//!   `WIDE_LAYOUT` and `LAYOUT_<NAME>` defined and `layout.glsl` resolving to the layout's file.
//!   The registry records each module's layout. Modules compile on every core, each thread with
//!   its own compiler.
//! - A kernel whose first lines say `// trilab:intersector none` uses no intersector (the BSDF
//!   probe, say): it is compiled once per variant, with method `none`.
//! - `shared.glsl` holds the constants shared with Rust: every `#define NAME <integer>` becomes
//!   `pub const NAME: u32` in `$OUT_DIR/shared_consts.rs`.
//!
//! - What an intersector states about itself is read from its GLSL, not repeated in Rust: the
//!   triangles per primitive (`#define PRIM_TRIANGLES n`) and whether it asks for conservative
//!   traversal (`#define CONSERVATIVE_TRAVERSAL`), found by preprocessing the intersector with
//!   its includes.
//!
//! A variant's name is `<kernel>.<method>.<variant>` with the method's command-line name, the
//! intersector's file stem with `-` for `_` (`raycast.quad-mt.closest` from `quad_mt.glsl`; a
//! test in `src/encoding` holds every method's name to it), made in `kernel_name` only: names
//! are for display. A variant's typed key (method, kind, access path, layout, traversal; the
//! path tracer's BSDFs) is read once, here, from what it is compiled with (`kernel_key`), and
//! the library asks for kernels by it.
//!
//! Outputs in `$OUT_DIR`: one `<kernel>.<method>.<variant>.spv` per variant and its raw-deflate
//! twin `.spv.deflate`, `kernels.rs` (the registry that embeds the deflated modules, and the
//! intersectors' facts), `kernel_keys.rs` (every kernel's typed key, in the registry's order,
//! included by `src/encoding/variants.rs`) and `shared_consts.rs`.
//!
//! The ray-tracing-pipeline stages in `glsl/raytrace/` are compiled apart from the kernels
//! (`ray_tracing_stages`, at the end): their table is `rt_shaders.rs` (4 small modules, embedded
//! as they are).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::fs;
use std::path::{Component, Path, PathBuf};

/// Vulkan 1.2 / SPIR-V 1.5, performance optimisation: fixed for every module so that
/// instruction counts are comparable between kernels and across commits.
const OPT_LEVEL: shaderc::OptimizationLevel = shaderc::OptimizationLevel::Performance;

/// Each axis's default (`src/defaults.rs`, the library's `trilab::defaults`): the variants
/// without a layout suffix compile with the default layout, `defaults::LAYOUT` (the binary nodes,
/// `glsl/layout/<LAYOUT>.glsl`).
#[path = "src/defaults.rs"]
#[allow(dead_code)]
mod defaults;

#[derive(Clone)]
struct Variant {
    name: String,
    /// The name on the kernel's `// trilab:variants` line (`name` without its layout suffix).
    base: String,
    macros: Vec<String>,
    /// `glsl/layout/<layout>.glsl`, for a variant compiled per layout; `None`: the binary nodes.
    layout: Option<String>,
}

/// A module's SPIR-V words, or shaderc's messages.
type Compiled = Result<Vec<u32>, String>;

struct Job {
    name: String,
    kernel: String,
    path: PathBuf,
    source: String,
    method: String,
    variant: Variant,
}

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let glsl_dir = manifest.join("glsl");
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").unwrap());

    println!("cargo:rerun-if-changed={}", glsl_dir.display());
    println!("cargo:rerun-if-changed={}", manifest.join("src/defaults.rs").display());
    let mut all_files = Vec::new();
    collect_files(&glsl_dir, &mut all_files);
    all_files.sort();
    for f in &all_files {
        println!("cargo:rerun-if-changed={}", f.display());
    }

    let consts = shared_constants(&glsl_dir.join("shared.glsl"));
    fs::write(out_dir.join("shared_consts.rs"), consts).unwrap();

    let kernels: Vec<PathBuf> = all_files
        .iter()
        .filter(|p| p.parent() == Some(glsl_dir.as_path()))
        .filter(|p| p.extension().is_some_and(|e| e == "comp"))
        .cloned()
        .collect();
    let mut methods: Vec<String> = all_files
        .iter()
        .filter(|p| p.parent() == Some(glsl_dir.join("intersect").as_path()))
        .filter(|p| p.extension().is_some_and(|e| e == "glsl"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    methods.sort();
    if kernels.is_empty() || methods.is_empty() {
        fail("glsl/ must contain at least one *.comp kernel and one intersect/*.glsl intersector");
    }

    let layouts: Vec<String> = {
        let mut l: Vec<String> = all_files
            .iter()
            .filter(|p| p.parent() == Some(glsl_dir.join("layout").as_path()))
            .filter(|p| p.extension().is_some_and(|e| e == "glsl"))
            .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
            .filter(|l| l != defaults::LAYOUT)
            .collect();
        l.sort();
        l
    };
    // The layouts that give the traversals a step (glsl/layout_interface.glsl): all but those whose
    // traversal is their own (a `#define LAYOUT_TRACE` line: cwbvh).
    let stepped: Vec<String> = layouts
        .iter()
        .filter(|l| {
            let text = fs::read_to_string(glsl_dir.join("layout").join(format!("{l}.glsl"))).unwrap_or_default();
            !text.lines().any(|line| line.trim() == "#define LAYOUT_TRACE")
        })
        .cloned()
        .collect();

    // Every (kernel, method, variant) to compile, in registry order.
    let mut jobs: Vec<Job> = Vec::new();
    for kernel_path in &kernels {
        let kernel = kernel_path.file_stem().unwrap().to_string_lossy().into_owned();
        let source = fs::read_to_string(kernel_path).unwrap();
        let variants = with_layouts(kernel_path, &source, parse_variants(kernel_path, &source), &layouts, &stepped);
        let no_intersector = source.lines().any(|l| l.trim() == "// trilab:intersector none");
        let none = [String::from("none")];
        let kernel_methods: &[String] = if no_intersector { &none } else { &methods };
        for method in kernel_methods {
            for variant in &variants {
                jobs.push(Job {
                    name: kernel_name(&kernel, method, &variant.name),
                    kernel: kernel.clone(),
                    path: kernel_path.clone(),
                    source: source.clone(),
                    method: method.clone(),
                    variant: variant.clone(),
                });
            }
        }
    }
    // Compiled on every core (each thread its own compiler); the registry keeps the job order.
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(jobs.len().max(1));
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<std::sync::Mutex<Option<Compiled>>> = jobs.iter().map(|_| std::sync::Mutex::new(None)).collect();
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| {
                let compiler = shaderc::Compiler::new().unwrap_or_else(|e| fail(&format!("shaderc: {e}")));
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(j) = jobs.get(i) else { break };
                    let r = compile(&compiler, &glsl_dir, &j.path, &j.source, &j.method, &j.variant);
                    *results[i].lock().unwrap() = Some(r);
                }
            });
        }
    });
    let compiler = shaderc::Compiler::new().unwrap_or_else(|e| fail(&format!("shaderc: {e}")));
    let mut registry = String::new();
    writeln!(registry, "// @generated by build.rs from glsl/. Do not edit.").unwrap();
    writeln!(registry, "pub static KERNELS: &[KernelSource] = &[").unwrap();
    let mut errors = Vec::new();
    let mut keys = String::new();
    writeln!(keys, "// @generated by build.rs from glsl/. Do not edit.").unwrap();
    writeln!(keys, "/// Every kernel's typed key (`kernel_key` in build.rs), in `KERNELS` order: `KEYS[k.id]`.")
        .unwrap();
    writeln!(keys, "static KEYS: &[Option<KernelKey>] = &[").unwrap();
    let mut seen = BTreeMap::new();
    for (id, (j, r)) in jobs.iter().zip(results).enumerate() {
        let name = &j.name;
        match kernel_key(&j.kernel, &j.method, &j.variant) {
            Ok(Some(key)) => {
                if let Some(other) = seen.insert(key.clone(), name.clone()) {
                    errors.push(format!("kernel variants {other} and {name} have one key: {key}"));
                }
                writeln!(keys, "    Some({key}),").unwrap();
            }
            Ok(None) => writeln!(keys, "    None,").unwrap(),
            Err(e) => errors.push(format!("kernel variant {name}: {e}")),
        }
        match r.into_inner().unwrap().expect("every job ran") {
            Ok(words) => {
                let bytes = bytemuck_bytes(&words);
                fs::write(out_dir.join(format!("{name}.spv")), &bytes).unwrap();
                // Embedded deflated (a third of the size): 445 modules are most of the binary,
                // and the binary travels to lent GPUs under a size limit (issue 23).
                let file = out_dir.join(format!("{name}.spv.deflate"));
                fs::write(&file, deflate(&bytes)).unwrap();
                writeln!(
                    registry,
                    "    KernelSource {{ id: {id}, name: {name:?}, kernel: {:?}, intersector: {:?}, variant: {:?}, \
                     layout: {:?}, spirv_deflate: include_bytes!({:?}) }},",
                    j.kernel,
                    j.method,
                    j.variant.name,
                    j.variant.layout.as_deref().unwrap_or(defaults::LAYOUT),
                    file.display().to_string()
                )
                .unwrap();
            }
            Err(e) => errors.push(format!("kernel variant {name}:\n{e}")),
        }
    }
    writeln!(registry, "];").unwrap();
    writeln!(registry, "/// The compiler that made every module above (see `spirv_compiler` in build.rs).").unwrap();
    writeln!(registry, "pub const SPIRV_COMPILER: &str = {:?};", spirv_compiler()).unwrap();
    writeln!(registry, "pub static INTERSECTOR_FACTS: &[IntersectorFacts] = &[").unwrap();
    for method in &methods {
        match intersector_facts(&compiler, &glsl_dir, method) {
            Ok((prim_triangles, conservative)) => writeln!(
                registry,
                "    IntersectorFacts {{ glsl: {method:?}, prim_triangles: {prim_triangles}, \
                 conservative_traversal: {conservative} }},"
            )
            .unwrap(),
            Err(e) => errors.push(format!("intersector {method}:\n{e}")),
        }
    }
    writeln!(registry, "];").unwrap();
    if !errors.is_empty() {
        fail(&errors.join("\n\n"));
    }
    writeln!(keys, "];").unwrap();
    fs::write(out_dir.join("kernels.rs"), registry).unwrap();
    fs::write(out_dir.join("kernel_keys.rs"), keys).unwrap();
    ray_tracing_stages(&compiler, &glsl_dir, &out_dir, &all_files);
    readback_layer(&manifest, &out_dir);
}

/// `trilab repro --check --gfxrecon`'s Vulkan layer (`src/commands/repro/readback_layer.c`),
/// built with the system's C compiler into `$OUT_DIR/libtrilab_readback.so` and embedded. Where
/// it cannot be built (no C compiler, no Vulkan headers: libvulkan-dev) the file is empty and
/// the check says so; the rest of trilab does not need it.
fn readback_layer(manifest: &Path, out_dir: &Path) {
    let src = manifest.join("src/commands/repro/readback_layer.c");
    println!("cargo:rerun-if-changed={}", src.display());
    println!("cargo:rerun-if-env-changed=CC");
    let out = out_dir.join("libtrilab_readback.so");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let built = std::process::Command::new(&cc)
        .args(["-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-Wall", "-o"])
        .arg(&out)
        .arg(&src)
        .arg("-lpthread")
        .output();
    match built {
        Ok(o) if o.status.success() => {}
        Ok(o) => {
            println!(
                "cargo:warning=the repro read-back layer was not built ({cc}: {}); `repro --check --gfxrecon` will say so",
                String::from_utf8_lossy(&o.stderr).lines().next().unwrap_or("failed")
            );
            fs::write(&out, b"").unwrap();
        }
        Err(e) => {
            println!("cargo:warning=the repro read-back layer was not built (no C compiler `{cc}`: {e})");
            fs::write(&out, b"").unwrap();
        }
    }
}

/// A kernel variant's name, `<kernel>.<method>.<variant>` with the method's command-line name
/// (the intersector's stem with `-` for `_`): the one place a name is made. Names are for
/// display (reports, the files of `spirv/`); code asks for a kernel by its key ([`kernel_key`]).
fn kernel_name(kernel: &str, method: &str, variant: &str) -> String {
    format!("{kernel}.{}.{variant}", method.replace('_', "-"))
}

/// The typed key of a kernel variant (`trilab::encoding::variants::KernelKey`) as Rust source,
/// from what the variant is compiled with: its kernel file, intersector, layout and macros
/// (`None`: a kernel the library asks for otherwise, the ray-query peer, the roofline and the
/// probes without an intersector). A method's and a layout's Rust name is their file's stem in
/// CamelCase (`quad_mt` -> `Method::QuadMt`, `bvh4` -> `Layout::Bvh4`; the generated code
/// does not compile where they differ), and so is a BSDF's (`oren_nayar` -> `BsdfKind::OrenNayar`).
///
/// - `raycast*.comp`: the kind (`ANY_HIT`: any, `TRAVERSAL_STATS`: stats, `SHADER_CLOCK`:
///   clock, none: closest), the access path (`SCENE_ADDRESS`: address, `SCENE_STORAGE`:
///   storage, none: texel) and the traversal (the kernel file: `raycast_coop` coop,
///   `raycast_persistent` persistent, `raycast_packet` packet or with `HYBRID` hybrid; in
///   `raycast`, `WHILE_WHILE` while-while, else while-if).
/// - `pathtrace.comp`: the BSDFs (`BSDF_MASK`: the one its variant names, none: all of them)
///   and the access path.
/// - `probe.comp`: the method's layout probe.
///
/// A macro it does not know is an error: a new axis needs its line here.
fn kernel_key(kernel: &str, method: &str, v: &Variant) -> Result<Option<String>, String> {
    let layout = camel(v.layout.as_deref().unwrap_or(defaults::LAYOUT));
    let method = camel(method);
    let macros: Vec<&str> = v
        .macros
        .iter()
        .map(|m| m.split(':').next().unwrap_or(m))
        .filter(|m| *m != "WIDE_LAYOUT" && !m.starts_with("LAYOUT_"))
        .collect();
    let has = |m: &str| macros.contains(&m);
    let unknown = |known: &[&str]| -> Result<(), String> {
        match macros.iter().find(|m| !known.contains(m)) {
            Some(m) => Err(format!("macro {m} is on no axis of its key (build.rs, kernel_key)")),
            None => Ok(()),
        }
    };
    let access = if has("SCENE_ADDRESS") {
        "Address"
    } else if has("SCENE_STORAGE") {
        "Storage"
    } else {
        "Texel"
    };
    match kernel {
        "raycast" | "raycast_coop" | "raycast_persistent" | "raycast_packet" => {
            unknown(&[
                "ANY_HIT",
                "TRAVERSAL_STATS",
                "SHADER_CLOCK",
                "SCENE_ADDRESS",
                "SCENE_STORAGE",
                "WHILE_WHILE",
                "HYBRID",
            ])?;
            let kinds: Vec<&str> = [("ANY_HIT", "Any"), ("TRAVERSAL_STATS", "Stats"), ("SHADER_CLOCK", "Clock")]
                .into_iter()
                .filter(|(m, _)| has(m))
                .map(|(_, k)| k)
                .collect();
            let kind = match kinds[..] {
                [] => "Closest",
                [k] => k,
                _ => return Err(format!("more than one kind: {kinds:?}")),
            };
            let traversal = match (kernel, has("WHILE_WHILE"), has("HYBRID")) {
                ("raycast", false, false) => "WhileIf",
                ("raycast", true, false) => "WhileWhile",
                ("raycast_coop", false, false) => "Coop",
                ("raycast_persistent", false, false) => "Persistent",
                ("raycast_packet", false, false) => "Packet",
                ("raycast_packet", false, true) => "Hybrid",
                _ => return Err("WHILE_WHILE is raycast.comp's, HYBRID raycast_packet.comp's".into()),
            };
            Ok(Some(format!(
                "KernelKey::Raycast(RaycastKey {{ method: Method::{method}, kind: Raycast::{kind}, access: \
                 AccessPath::{access}, layout: Layout::{layout}, traversal: Traversal::{traversal} }})"
            )))
        }
        "pathtrace" => {
            unknown(&["BSDF_MASK", "SCENE_STORAGE"])?;
            let bsdfs = if has("BSDF_MASK") {
                format!("BsdfSet::One(BsdfKind::{})", camel(&v.base))
            } else {
                "BsdfSet::All".into()
            };
            Ok(Some(format!(
                "KernelKey::Pathtrace(PathtraceKey {{ method: Method::{method}, bsdfs: {bsdfs}, layout: \
                 Layout::{layout}, access: AccessPath::{access} }})"
            )))
        }
        "probe" => {
            unknown(&[])?;
            Ok(Some(format!("KernelKey::Probe(Method::{method})")))
        }
        _ => Ok(None),
    }
}

/// `quad_mt` -> `QuadMt`.
fn camel(stem: &str) -> String {
    stem.split('_')
        .map(|w| {
            let mut c = w.chars();
            c.next().map_or(String::new(), |f| f.to_ascii_uppercase().to_string() + c.as_str())
        })
        .collect()
}

/// The compiler this build script was linked against, as the SPIR-V counts name it: the Debian
/// packages' versions when `crates/shaderc-link` linked the system's static libraries ("shaderc
/// 2023.2-1, glslang 12.0.0-2, SPIRV-Tools 2023.1-2 (static system libraries)"), or the
/// `shaderc-sys` release that built it from source and the SPIRV-Tools it bundles ("shaderc-sys
/// 0.10.1 from source, SPIRV-Tools v2025.3"). glslang (the front end) and SPIRV-Tools (the
/// optimiser) decide the instruction counts: a count is comparable only between modules of one
/// compiler.
fn spirv_compiler() -> String {
    if !shaderc_link::from_source() {
        return format!("{} (static system libraries)", shaderc_link::SYSTEM_LIBRARIES);
    }
    extern "C" {
        fn spvSoftwareVersionString() -> *const std::ffi::c_char;
    }
    // SAFETY: SPIRV-Tools' C API (libspirv.h) returns a pointer to a static NUL-terminated
    // string; it is linked into this build script through shaderc_combined, and only read.
    let spirv_tools = unsafe { std::ffi::CStr::from_ptr(spvSoftwareVersionString()) }.to_string_lossy().into_owned();
    let lock = fs::read_to_string(Path::new(&std::env::var("CARGO_MANIFEST_DIR").unwrap()).join("Cargo.lock"))
        .unwrap_or_default();
    let version = lock
        .split("[[package]]")
        .find(|p| p.contains("name = \"shaderc-sys\""))
        .and_then(|p| p.lines().find_map(|l| l.strip_prefix("version = ")))
        .map_or("?".to_string(), |v| v.trim_matches('"').to_string());
    format!("shaderc-sys {version} from source, SPIRV-Tools {spirv_tools}")
}

// ---- Ray-tracing pipeline stages (glsl/raytrace/) ------------------------------------------
//
// Not kernels: `glsl/raytrace/*.{rgen,rchit,rmiss}` are the stages of the ray-tracing-pipeline
// peer (`gpu::rtpipeline`). Each is compiled once per variant on its `// trilab:variants` line
// (`main` without one), with the stage's shader kind, no intersector and no layout, into
// `<stem>.<variant>.<ext>.spv`; `$OUT_DIR/rt_shaders.rs` holds the table `RT_SHADERS` of
// `RtShaderSource`s that embeds them (included by src/kernels.rs). They stay out of `KERNELS`:
// the kernel registry, its reflection tests and `spirv/` are about compute kernels.

/// Compiles every ray-tracing stage in `glsl/raytrace/` and writes `rt_shaders.rs`.
fn ray_tracing_stages(compiler: &shaderc::Compiler, glsl_dir: &Path, out_dir: &Path, all_files: &[PathBuf]) {
    let dir = glsl_dir.join("raytrace");
    let mut table = String::from("// @generated by build.rs from glsl/raytrace/. Do not edit.\n");
    table.push_str("pub static RT_SHADERS: &[RtShaderSource] = &[\n");
    let mut errors = Vec::new();
    for path in all_files.iter().filter(|p| p.parent() == Some(dir.as_path())) {
        let ext = path.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default();
        let kind = match ext.as_str() {
            "rgen" => shaderc::ShaderKind::RayGeneration,
            "rchit" => shaderc::ShaderKind::ClosestHit,
            "rmiss" => shaderc::ShaderKind::Miss,
            _ => continue,
        };
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        let source = fs::read_to_string(path).unwrap();
        for variant in parse_variants(path, &source) {
            let name = format!("{stem}.{}.{ext}", variant.name);
            match compile_stage(compiler, glsl_dir, path, &source, kind, &variant) {
                Ok(words) => {
                    let file = out_dir.join(format!("{name}.spv"));
                    fs::write(&file, bytemuck_bytes(&words)).unwrap();
                    writeln!(
                        table,
                        "    RtShaderSource {{ name: {name:?}, shader: {stem:?}, stage: {ext:?}, variant: {:?}, \
                         spirv: include_bytes!({:?}) }},",
                        variant.name,
                        file.display().to_string()
                    )
                    .unwrap();
                }
                Err(e) => errors.push(format!("ray-tracing stage {name}:\n{e}")),
            }
        }
    }
    table.push_str("];\n");
    if !errors.is_empty() {
        fail(&errors.join("\n\n"));
    }
    fs::write(out_dir.join("rt_shaders.rs"), table).unwrap();
}

/// One ray-tracing stage: the kernels' settings (Vulkan 1.2, SPIR-V 1.5 — ray tracing needs
/// 1.4 or later —, the same optimisation, warnings as errors), no intersector, no layout.
fn compile_stage(
    compiler: &shaderc::Compiler,
    glsl_dir: &Path,
    path: &Path,
    source: &str,
    kind: shaderc::ShaderKind,
    variant: &Variant,
) -> Compiled {
    let mut options = shaderc::CompileOptions::new().map_err(|e| e.to_string())?;
    options.set_target_env(shaderc::TargetEnv::Vulkan, shaderc::EnvVersion::Vulkan1_2 as u32);
    options.set_target_spirv(shaderc::SpirvVersion::V1_5);
    options.set_optimization_level(OPT_LEVEL);
    options.set_warnings_as_errors();
    for m in &variant.macros {
        options.add_macro_definition(m, Some("1"));
    }
    let dir = glsl_dir.to_path_buf();
    options.set_include_callback(move |requested, _ty, requesting, _depth| {
        resolve_include(&dir, "none", None, requested, requesting)
    });
    let artifact = compiler
        .compile_into_spirv(source, kind, &path.display().to_string(), "main", Some(&options))
        .map_err(|e| e.to_string())?;
    Ok(artifact.as_binary().to_vec())
}

fn fail(msg: &str) -> ! {
    eprintln!("\nerror: GLSL compilation failed\n\n{msg}\n");
    std::process::exit(1);
}

fn collect_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            println!("cargo:rerun-if-changed={}", p.display());
            collect_files(&p, out);
        } else {
            out.push(p);
        }
    }
}

/// `// trilab:variants closest any=ANY_HIT` → [(closest, []), (any, [ANY_HIT])].
/// A kernel without the directive has one variant, `main`.
fn parse_variants(path: &Path, source: &str) -> Vec<Variant> {
    let Some(line) = source.lines().find_map(|l| l.trim().strip_prefix("// trilab:variants")) else {
        return vec![Variant { name: "main".into(), base: "main".into(), macros: vec![], layout: None }];
    };
    let variants: Vec<Variant> = line
        .split_whitespace()
        .map(|tok| match tok.split_once('=') {
            Some((n, m)) => Variant {
                name: n.into(),
                base: n.into(),
                macros: m.split(',').map(str::to_owned).collect(),
                layout: None,
            },
            None => Variant { name: tok.into(), base: tok.into(), macros: vec![], layout: None },
        })
        .collect();
    if variants.is_empty() {
        fail(&format!("{}: empty `// trilab:variants` line", path.display()));
    }
    variants
}

/// `// trilab:layouts closest any ...`: those variants are compiled once more per layout in
/// `glsl/layout/` but the default (bvh2) as `<variant>_<layout>`, with `WIDE_LAYOUT` and `LAYOUT_<LAYOUT>` defined and
/// `#include "layout.glsl"` resolving to `layout/<layout>.glsl`.
fn with_layouts(
    path: &Path,
    source: &str,
    mut variants: Vec<Variant>,
    layouts: &[String],
    stepped: &[String],
) -> Vec<Variant> {
    let Some(line) = source.lines().find_map(|l| l.trim().strip_prefix("// trilab:layouts")) else {
        return variants;
    };
    // `// trilab:layouts(bvh4,bvh8) closest ...`: only those layouts; `(stepped)`: every layout
    // that gives a step (a kernel that drives layout_visit itself, like raycast_coop.comp).
    let (only, line) = match line.strip_prefix('(') {
        Some(rest) => {
            let Some((list, line)) = rest.split_once(')') else {
                fail(&format!("{}: `// trilab:layouts(` without `)`", path.display()))
            };
            let only: Vec<String> = if list.trim() == "stepped" {
                stepped.to_vec()
            } else {
                list.split(',').map(|l| l.trim().to_owned()).collect()
            };
            for l in &only {
                if !layouts.contains(l) {
                    fail(&format!(
                        "{}: `// trilab:layouts({list})` names `{l}`, not a file in glsl/layout/",
                        path.display()
                    ));
                }
            }
            (Some(only), line)
        }
        None => (None, line),
    };
    let mut extra = Vec::new();
    for layout in layouts.iter().filter(|l| only.as_ref().is_none_or(|o| o.contains(l))) {
        for name in line.split_whitespace() {
            let Some(v) = variants.iter().find(|v| v.name == name) else {
                fail(&format!(
                    "{}: `// trilab:layouts` names `{name}`, which is not one of its variants",
                    path.display()
                ))
            };
            let mut macros = v.macros.clone();
            macros.push("WIDE_LAYOUT".into());
            macros.push(format!("LAYOUT_{}", layout.to_uppercase()));
            extra.push(Variant {
                name: format!("{name}_{layout}"),
                base: v.base.clone(),
                macros,
                layout: Some(layout.clone()),
            });
        }
    }
    variants.extend(extra);
    variants
}

fn compile(
    compiler: &shaderc::Compiler,
    glsl_dir: &Path,
    kernel_path: &Path,
    source: &str,
    method: &str,
    variant: &Variant,
) -> Result<Vec<u32>, String> {
    let mut options = shaderc::CompileOptions::new().map_err(|e| e.to_string())?;
    options.set_target_env(shaderc::TargetEnv::Vulkan, shaderc::EnvVersion::Vulkan1_2 as u32);
    options.set_target_spirv(shaderc::SpirvVersion::V1_5);
    options.set_optimization_level(OPT_LEVEL);
    options.set_warnings_as_errors();
    options.add_macro_definition(&format!("METHOD_{}", method.to_uppercase()), Some("1"));
    for m in &variant.macros {
        match m.split_once(':') {
            Some((k, v)) => options.add_macro_definition(k, Some(v)),
            None => options.add_macro_definition(m, Some("1")),
        }
    }
    let glsl_dir = glsl_dir.to_path_buf();
    let method = method.to_owned();
    let layout = variant.layout.clone();
    options.set_include_callback(move |requested, _ty, requesting, _depth| {
        resolve_include(&glsl_dir, &method, layout.as_deref(), requested, requesting)
    });
    let name = kernel_path.display().to_string();
    let artifact = compiler
        .compile_into_spirv(source, shaderc::ShaderKind::Compute, &name, "main", Some(&options))
        .map_err(|e| e.to_string())?;
    Ok(artifact.as_binary().to_vec())
}

/// What `glsl/intersect/<method>.glsl` states about itself: (PRIM_TRIANGLES, whether it defines
/// CONSERVATIVE_TRAVERSAL). The intersector is preprocessed (its includes too) with a tail that
/// expands the macros into marker lines.
fn intersector_facts(compiler: &shaderc::Compiler, glsl_dir: &Path, method: &str) -> Result<(u32, bool), String> {
    let source = "#version 460\n#extension GL_GOOGLE_include_directive : require\n\
                  #include \"intersector.glsl\"\n\
                  trilab_fact_prim_triangles PRIM_TRIANGLES\n\
                  #ifdef CONSERVATIVE_TRAVERSAL\ntrilab_fact_conservative_traversal\n#endif\n";
    let mut options = shaderc::CompileOptions::new().map_err(|e| e.to_string())?;
    options.set_target_env(shaderc::TargetEnv::Vulkan, shaderc::EnvVersion::Vulkan1_2 as u32);
    options.add_macro_definition(&format!("METHOD_{}", method.to_uppercase()), Some("1"));
    let dir = glsl_dir.to_path_buf();
    let m = method.to_owned();
    options.set_include_callback(move |requested, _ty, requesting, _depth| {
        resolve_include(&dir, &m, None, requested, requesting)
    });
    let text = compiler
        .preprocess(source, &format!("facts of intersect/{method}.glsl"), "main", Some(&options))
        .map_err(|e| e.to_string())?
        .as_text();
    let prim = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("trilab_fact_prim_triangles"))
        .map(|v| v.trim().trim_end_matches(['u', 'U']).to_owned())
        .ok_or("no PRIM_TRIANGLES line after preprocessing")?;
    let prim: u32 = prim.parse().map_err(|_| format!("PRIM_TRIANGLES must be an integer literal, got `{prim}`"))?;
    if !matches!(prim, 1 | 4) {
        return Err(format!("PRIM_TRIANGLES is {prim}; the leaf loop in leaf.glsl handles 1 or 4"));
    }
    let conservative = text.lines().any(|l| l.trim() == "trilab_fact_conservative_traversal");
    Ok((prim, conservative))
}

/// Includes resolve inside `glsl/` only; `intersector.glsl` is the variant's intersector and
/// `layout.glsl` its layout (the default, bvh2, for a variant without one).
fn resolve_include(
    glsl_dir: &Path,
    method: &str,
    layout: Option<&str>,
    requested: &str,
    requesting: &str,
) -> Result<shaderc::ResolvedInclude, String> {
    let rel = if requested == "intersector.glsl" && method == "none" {
        return Err(format!("{requesting}: `// trilab:intersector none` kernels cannot include intersector.glsl"));
    } else if requested == "intersector.glsl" {
        PathBuf::from("intersect").join(format!("{method}.glsl"))
    } else if requested == "layout.glsl" {
        match layout {
            Some(l) => PathBuf::from("layout").join(format!("{l}.glsl")),
            None => PathBuf::from("layout").join(format!("{}.glsl", defaults::LAYOUT)),
        }
    } else {
        PathBuf::from(requested)
    };
    if rel.is_absolute() || rel.components().any(|c| !matches!(c, Component::Normal(_))) {
        return Err(format!("{requesting}: #include \"{requested}\": includes must be relative paths inside glsl/"));
    }
    let path = glsl_dir.join(&rel);
    let content = fs::read_to_string(&path)
        .map_err(|e| format!("{requesting}: #include \"{requested}\": {}: {e}", path.display()))?;
    Ok(shaderc::ResolvedInclude { resolved_name: path.display().to_string(), content })
}

/// Every `#define NAME <integer>` in shared.glsl becomes a Rust `pub const NAME: u32`.
fn shared_constants(path: &Path) -> String {
    let text = fs::read_to_string(path).unwrap_or_else(|e| fail(&format!("{}: {e}", path.display())));
    let mut consts = BTreeMap::new();
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("#define") {
            continue;
        }
        let (Some(name), Some(value)) = (words.next(), words.next()) else {
            continue;
        };
        if name.contains('(') {
            // A function-like macro over the constants: its Rust twin is written by hand.
            continue;
        }
        let v = value.trim_end_matches(['u', 'U']);
        let parsed = match v.strip_prefix("0x").or_else(|| v.strip_prefix("0X")) {
            Some(hex) => u32::from_str_radix(hex, 16),
            None => v.parse::<u32>(),
        };
        match parsed {
            Ok(x) => {
                consts.insert(name.to_owned(), (x, n + 1));
            }
            Err(_) => fail(&format!(
                "{}:{}: shared constant {name} must be an unsigned integer literal (got {value})",
                path.display(),
                n + 1
            )),
        }
    }
    let mut out = String::from("// @generated by build.rs from glsl/shared.glsl. Do not edit.\n");
    for (name, (value, line)) in consts {
        writeln!(out, "/// `glsl/shared.glsl` line {line}.\npub const {name}: u32 = {value:#x};").unwrap();
    }
    out
}

/// `bytes` compressed with raw deflate at the best level ([`KernelSource::words`] inflates).
fn deflate(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write as _;
    let mut e = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

fn bytemuck_bytes(words: &[u32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}
