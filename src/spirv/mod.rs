//! SPIR-V as a review surface: instruction counts per opcode class, disassembly, reflection.
//!
//! `spirv/` in the repository holds, for every kernel variant, its disassembly and a row of
//! `spirv/instruction_counts.csv`; `tests/spirv_review.rs` regenerates both and fails when the
//! committed files differ (`trilab spirv --out spirv` refreshes them).

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

/// Every file `spirv/` should hold: (file name, contents).
pub fn review_files() -> Vec<(String, String)> {
    let mut files: Vec<(String, String)> = KERNELS
        .iter()
        .map(|k| {
            let text =
                disassemble(&k.words()).unwrap_or_else(|e| panic!("embedded kernel {} is malformed: {e}", k.name));
            (format!("{}.spvasm", k.name), text)
        })
        .collect();
    files.push(("instruction_counts.csv".into(), counts_csv()));
    files.sort();
    files
}
