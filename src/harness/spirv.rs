//! `trilab spirv`: SPIR-V instruction counts of every kernel variant, and the review files of
//! `spirv/` (disassembly and counts, which a test keeps current).

use std::path::Path;

use serde::Serialize;

use crate::error::{Error, Result};
use crate::report::{Report, Table};
use crate::spirv::InstructionCounts;

/// One variant's counts.
#[derive(Clone, Debug, Serialize)]
pub struct VariantCounts {
    pub variant: &'static str,
    pub counts: InstructionCounts,
}

/// Every variant's counts (serialised as the list).
#[derive(Clone, Debug, Serialize)]
#[serde(transparent)]
pub struct SpirvReport {
    pub variants: Vec<VariantCounts>,
}

/// The counts of every embedded kernel variant.
pub fn counts() -> SpirvReport {
    SpirvReport {
        variants: crate::spirv::all_counts()
            .into_iter()
            .map(|(k, counts)| VariantCounts { variant: k.name, counts })
            .collect(),
    }
}

/// Writes every review file into `dir` (created if needed), each atomically, removing stale
/// disassembly of variants that no longer exist. Returns how many files were written.
pub fn write(dir: &Path) -> Result<usize> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let files = crate::spirv::review_files();
    let keep: Vec<&String> = files.iter().map(|(n, _)| n).collect();
    for e in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if (name.ends_with(".spvasm") || name == "instruction_counts.csv") && !keep.contains(&&name) {
            std::fs::remove_file(e.path()).map_err(|err| Error::io(&e.path(), err))?;
        }
    }
    for (name, text) in &files {
        crate::io::write_atomic(&dir.join(name), text.as_bytes())?;
    }
    Ok(files.len())
}

impl Report for SpirvReport {
    fn to_json(&self) -> String {
        crate::report::value_json(self)
    }

    fn to_text(&self) -> String {
        let mut t = Table::new([
            "variant",
            "module",
            "functions",
            "arithmetic",
            "memory",
            "control flow",
            "conversion",
            "image",
            "composite",
            "other",
        ]);
        for v in &self.variants {
            let c = &v.counts;
            t.row([
                v.variant.to_string(),
                c.module.to_string(),
                c.functions.to_string(),
                c.arithmetic.to_string(),
                c.memory.to_string(),
                c.control_flow.to_string(),
                c.conversion.to_string(),
                c.image.to_string(),
                c.composite.to_string(),
                c.other.to_string(),
            ]);
        }
        t.to_text()
    }
}
