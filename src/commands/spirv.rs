//! `trilab spirv`: SPIR-V instruction counts of every kernel variant, and the review files of
//! `spirv/` (disassembly and counts, which a test keeps current).

use std::path::Path;

use serde::Serialize;

use crate::error::{Error, Result};
use crate::report::{Report, Table};
use crate::spirv::{Disassembly, InstructionCounts};

/// One variant's counts.
#[derive(Clone, Debug, Serialize)]
pub struct VariantCounts {
    pub variant: &'static str,
    pub counts: InstructionCounts,
}

/// Every variant's counts, and the compiler that made them.
#[derive(Clone, Debug, Serialize)]
pub struct SpirvReport {
    /// [`crate::kernels::SPIRV_COMPILER`]: counts of two compilers are not comparable.
    pub compiler: &'static str,
    pub variants: Vec<VariantCounts>,
}

/// The counts of every embedded kernel variant.
pub fn counts() -> SpirvReport {
    SpirvReport {
        compiler: crate::kernels::SPIRV_COMPILER,
        variants: crate::spirv::all_counts()
            .into_iter()
            .map(|(k, counts)| VariantCounts { variant: k.name, counts })
            .collect(),
    }
}

/// Writes the review files of `which` kernels into `dir` (created if needed), each atomically,
/// removing disassembly there of variants that no longer exist or are not among `which`.
/// Returns how many files were written.
pub fn write(dir: &Path, which: Disassembly) -> Result<usize> {
    let mut folder = crate::services::results::Folder::create(dir)?;
    let files = crate::spirv::review_files(&crate::encoding::variants::disassembled(which));
    let keep: Vec<&String> = files.iter().map(|(n, _)| n).collect();
    for e in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if (name.ends_with(".spvasm") || name == "instruction_counts.csv" || name == crate::spirv::COMPILER_FILE)
            && !keep.contains(&&name)
        {
            std::fs::remove_file(e.path()).map_err(|err| Error::io(&e.path(), err))?;
        }
    }
    for (name, text) in &files {
        folder.put(name, text)?;
    }
    folder.rows(None, &rows(&counts()))?;
    Ok(folder.written().len())
}

/// Where SPIR-V counts come from: the compiler, before any driver sees them.
pub const SOURCE_DEVICE: &str = "SPIR-V (no device)";
pub const SOURCE_DRIVER: &str = "shaderc (build.rs)";

/// The counts as result rows (`rows.jsonl`, what `trilab compare` reads): one row per kernel
/// variant (cell `kernel`), each category of [`InstructionCounts`] a count figure
/// (`spirv_instructions` is the whole module), shader-db style: any change is real. Each row
/// names its compiler ([`crate::rows::SPIRV_COMPILER`]), so that `trilab compare` judges counts
/// only between modules of one compiler.
pub fn rows(report: &SpirvReport) -> Vec<crate::rows::Row> {
    use crate::rows::{cell, Figure, Row, Source};
    let source = Source {
        device: SOURCE_DEVICE.into(),
        driver: SOURCE_DRIVER.into(),
        commit: crate::services::provenance::commit(),
        date: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
        settings: [(crate::rows::SPIRV_COMPILER.to_owned(), report.compiler.to_owned())].into(),
        host: None,
    };
    report
        .variants
        .iter()
        .map(|v| {
            let c = &v.counts;
            let n = |x: u32| Figure::count(x as f64, "instructions");
            Row::new("spirv", cell([("kernel", v.variant)]), &source)
                .with("spirv_instructions", n(c.module))
                .with("function_instructions", n(c.functions))
                .with("arithmetic", n(c.arithmetic))
                .with("memory", n(c.memory))
                .with("control_flow", n(c.control_flow))
                .with("conversion", n(c.conversion))
                .with("image", n(c.image))
                .with("composite", n(c.composite))
                .with("other", n(c.other))
        })
        .collect()
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
        format!("compiler: {}\n{}", self.compiler, t.to_text())
    }
}

#[cfg(test)]
mod tests {
    /// The rows carry the counts of `instruction_counts.csv` (the review file, made by
    /// `crate::spirv::review_files`), one row per line, figure for column.
    #[test]
    fn rows_carry_the_review_files_counts() {
        let rows = super::rows(&super::counts());
        let files = crate::spirv::review_files(&crate::encoding::variants::studied());
        let csv = &files.iter().find(|(n, _)| n == "instruction_counts.csv").expect("counts file").1;
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let figure = |column: &str| {
            match column {
                "module_instructions" => "spirv_instructions",
                "function_instructions" => "function_instructions",
                other => other,
            }
            .to_owned()
        };
        let mut n = 0;
        for line in lines {
            let fields: Vec<&str> = line.split(',').collect();
            let row =
                rows.iter().find(|r| r.cell["kernel"] == fields[0]).unwrap_or_else(|| panic!("no row for {line}"));
            assert_eq!(row.command, "spirv");
            for (column, value) in header.iter().zip(&fields).skip(1) {
                let f = &row.figures[&figure(column)];
                assert_eq!(f.median, value.parse::<f64>().unwrap(), "{} {column}", fields[0]);
                assert_eq!(f.class, crate::rows::Class::Count);
            }
            n += 1;
        }
        assert_eq!(n, rows.len());
        assert!(n > 10);
    }
}
