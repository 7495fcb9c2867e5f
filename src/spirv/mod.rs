//! SPIR-V as a review surface: instruction counts per opcode class, disassembly, reflection.
//!
//! `spirv/` in the repository holds a row of `spirv/instruction_counts.csv` for every kernel
//! variant, and the disassembly of the kernels a reader studies (`encoding::variants::studied`,
//! from the kernels' keys: the paper's study kernels and the layouts study's); `tests/spirv_review.rs` regenerates both and fails
//! when the committed files differ (`trilab spirv --out spirv --studied` refreshes them).
//! `trilab spirv --out DIR` writes every variant's disassembly: the other 400-odd modules are
//! 20 MiB of text that the tree, which travels to lent GPUs under a size limit, does not carry.

pub mod capabilities;
pub mod counts;
pub mod reflect;

pub use capabilities::{required_features, Feature, Requirement};
pub use counts::{count, InstructionCounts, OpClass};

use rspirv::binary::Disassemble;

use crate::kernels::{KernelSource, KERNELS};

/// Header of `spirv/instruction_counts.csv`.
pub const CSV_HEADER: &str =
    "variant,module_instructions,function_instructions,arithmetic,memory,control_flow,conversion,image,composite,other";

/// The file of a review folder that names the compiler its counts and disassembly come from
/// ([`crate::kernels::SPIRV_COMPILER`], one line).
pub const COMPILER_FILE: &str = "compiler.txt";

/// The rspirv disassembly of a module (deterministic for a given Cargo.lock).
pub fn disassemble(words: &[u32]) -> Result<String, String> {
    let module = rspirv::dr::load_words(words).map_err(|e| e.to_string())?;
    Ok(module.disassemble() + "\n")
}

/// Counts for every embedded kernel, in registry order.
pub fn all_counts() -> Vec<(&'static KernelSource, InstructionCounts)> {
    KERNELS
        .iter()
        .map(|k| (k, count(&k.words()).unwrap_or_else(|e| panic!("embedded kernel {} is malformed: {e}", k.name))))
        .collect()
}

/// `spirv/instruction_counts.csv`, sorted by variant name.
pub fn counts_csv() -> String {
    let mut rows: Vec<_> = all_counts().into_iter().map(|(k, c)| (k.name, c)).collect();
    rows.sort_by_key(|(n, _)| *n);
    let mut s = String::from(CSV_HEADER);
    s.push('\n');
    for (name, c) in rows {
        s.push_str(&format!(
            "{name},{},{},{},{},{},{},{},{},{}\n",
            c.module, c.functions, c.arithmetic, c.memory, c.control_flow, c.conversion, c.image, c.composite, c.other
        ));
    }
    s
}

/// Which kernels' disassembly a review folder holds (`encoding::variants::disassembled` lists
/// them, from the kernels' keys).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Disassembly {
    /// The kernels a reader studies (`encoding::variants::studied`: what `spirv/` keeps).
    Studied,
    /// Every variant's.
    All,
}

/// Every file a review folder holds: (file name, contents): `instruction_counts.csv` (every
/// variant), [`COMPILER_FILE`] and the disassembly of the `disassembled` kernels. `spirv/` holds
/// those of [`Disassembly::Studied`].
pub fn review_files(disassembled: &[&KernelSource]) -> Vec<(String, String)> {
    let mut files: Vec<(String, String)> = disassembled
        .iter()
        .map(|k| {
            let text =
                disassemble(&k.words()).unwrap_or_else(|e| panic!("embedded kernel {} is malformed: {e}", k.name));
            (format!("{}.spvasm", k.name), text)
        })
        .collect();
    files.push(("instruction_counts.csv".into(), counts_csv()));
    files.push((COMPILER_FILE.into(), format!("{}\n", crate::kernels::SPIRV_COMPILER)));
    files.sort();
    files
}
