//! The GPU targets axis: the chips, compilers, subgroup sizes and Mesa builds that
//! `driver-stats --targets` and the study compile for through RADV's null device, with their
//! defaults and their check, crossed here into [`GpuTarget`]s (what a target is and how its
//! worker compiles: `crate::services::driver_stats::target`).

use std::fmt;
use std::str::FromStr;

use crate::gpu::amd::Chip;
use crate::services::driver_stats::target::{Compiler, GpuTarget, MesaBuild};

/// The chips compiled for when no target is named (and by `--targets default`): the paper's
/// HD 7850 (pitcairn, GCN 1), then one chip of each later generation: Polaris (GCN 4), Vega
/// (GCN 5), RDNA 2, RDNA 3, RDNA 4.
pub const DEFAULT_CHIPS: [&str; 6] = ["pitcairn", "polaris10", "vega10", "navi21", "navi31", "gfx1201"];

/// One target asked for: a chip, with a compiler and a subgroup size where they were named
/// (`CHIP[:COMPILER[:WAVE]]`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TargetItem {
    pub chip: Chip,
    /// `None`: every compiler ([`Compiler::ALL`]).
    pub compiler: Option<Compiler>,
    /// `None`: every subgroup size the chip allows ([`Chip::subgroup_sizes`]).
    pub wave: Option<u32>,
}

impl TargetItem {
    /// A chip alone: every compiler, every subgroup size it allows.
    pub fn chip(chip: Chip) -> TargetItem {
        TargetItem { chip, compiler: None, wave: None }
    }

    /// The compilers this item stands for.
    pub fn compilers(&self) -> Vec<Compiler> {
        self.compiler.map_or_else(|| Compiler::ALL.to_vec(), |c| vec![c])
    }

    /// The subgroup sizes this item stands for.
    pub fn waves(&self) -> Vec<u32> {
        self.wave.map_or_else(|| self.chip.subgroup_sizes().to_vec(), |w| vec![w])
    }

    /// A subgroup size the chip cannot compile compute kernels at (wave32 on GCN), named.
    pub fn check(&self) -> Result<(), String> {
        match self.wave {
            Some(w) if !self.chip.subgroup_sizes().contains(&w) => Err(format!(
                "{} ({}) compiles compute kernels at {} lanes only",
                self.chip,
                self.chip.gfx.architecture(),
                self.chip.subgroup_sizes().iter().map(|s| s.to_string()).collect::<Vec<_>>().join(" or ")
            )),
            _ => Ok(()),
        }
    }
}

impl fmt::Display for TargetItem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.chip)?;
        match (self.compiler, self.wave) {
            (None, None) => Ok(()),
            (Some(c), None) => write!(f, ":{c}"),
            (c, Some(w)) => write!(f, ":{}:{w}", c.map(|c| c.to_string()).unwrap_or_default()),
        }
    }
}

impl FromStr for TargetItem {
    type Err = String;

    /// `CHIP[:COMPILER[:WAVE]]` (a part left empty is left out; `wave32` reads as `32`), an
    /// error naming the item and its wrong part.
    fn from_str(item: &str) -> Result<TargetItem, String> {
        let wrong = |e: String| format!("--targets {item}: {e}");
        let mut parts = item.split(':');
        let chip: Chip = parts.next().unwrap_or_default().parse().map_err(wrong)?;
        let compiler = match parts.next() {
            None | Some("") => None,
            Some(c) => Some(c.parse::<Compiler>().map_err(wrong)?),
        };
        let wave = match parts.next() {
            None | Some("") => None,
            Some(w) => Some(
                w.trim_start_matches("wave")
                    .parse::<u32>()
                    .map_err(|_| wrong(format!("subgroup size `{w}` is not a number")))?,
            ),
        };
        let t = TargetItem { chip, compiler, wave };
        t.check().map_err(wrong)?;
        if let Some(rest) = parts.next() {
            return Err(wrong(format!("`{rest}` after CHIP:COMPILER:WAVE")));
        }
        Ok(t)
    }
}

/// The GPU targets asked for: the items and the Mesa builds that compile them. An empty field
/// means its default, applied by [`TargetAxes::targets`] alone: no item, [`DEFAULT_CHIPS`]; no
/// Mesa build, the installed one.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TargetAxes {
    pub items: Vec<TargetItem>,
    pub mesa: Vec<MesaBuild>,
}

impl TargetAxes {
    /// Reads `--targets`: comma-separated `CHIP[:COMPILER[:WAVE]]`, or `default`
    /// ([`DEFAULT_CHIPS`]), with the Mesa builds of `--mesa`. An error names the part that is
    /// wrong (an unknown chip, wave32 on GCN) before any work starts; a spec that names no
    /// target is one.
    pub fn parse(spec: &str, mesa: &[MesaBuild]) -> Result<TargetAxes, String> {
        let mut items = vec![];
        let mut named = false;
        for s in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            named = true;
            match s {
                "default" => items.extend(Self::default_items()),
                _ => items.push(s.parse()?),
            }
        }
        if !named {
            return Err("--targets: no target given".into());
        }
        Ok(TargetAxes { items, mesa: mesa.to_vec() })
    }

    /// The items of [`DEFAULT_CHIPS`]: each chip with every compiler and subgroup size.
    pub fn default_items() -> Vec<TargetItem> {
        DEFAULT_CHIPS.iter().map(|c| TargetItem::chip(Chip::named(c).expect("a chip of gpu::amd::CHIPS"))).collect()
    }

    /// The items asked for, or the default ones.
    pub fn items(&self) -> Vec<TargetItem> {
        match self.items.is_empty() {
            true => Self::default_items(),
            false => self.items.clone(),
        }
    }

    /// The Mesa builds asked for, or the installed one.
    pub fn mesa(&self) -> Vec<MesaBuild> {
        match self.mesa.is_empty() {
            true => vec![MesaBuild::Installed],
            false => self.mesa.clone(),
        }
    }

    /// Every target: each Mesa build x item x compiler x subgroup size, in that order, each
    /// once; an item the chip cannot compile (wave32 on GCN) is an error naming it.
    pub fn targets(&self) -> Result<Vec<GpuTarget>, String> {
        let items = self.items();
        for item in &items {
            item.check().map_err(|e| format!("--targets {item}: {e}"))?;
        }
        let mut out = vec![];
        for mesa in self.mesa() {
            for item in &items {
                for compiler in item.compilers() {
                    for wave in item.waves() {
                        let t = GpuTarget { chip: item.chip, compiler, wave, mesa: mesa.clone() };
                        if !out.contains(&t) {
                            out.push(t);
                        }
                    }
                }
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(ts: &[GpuTarget]) -> Vec<String> {
        ts.iter().map(|t| t.to_string()).collect()
    }

    fn targets(spec: &str, mesa: &[MesaBuild]) -> Result<Vec<String>, String> {
        TargetAxes::parse(spec, mesa)?.targets().map(|t| names(&t))
    }

    #[test]
    fn targets_expand_to_every_compiler_and_size_a_chip_allows() {
        let installed = [MesaBuild::Installed];
        assert_eq!(
            targets("pitcairn", &installed).unwrap(),
            ["pitcairn:aco:64@installed", "pitcairn:llvm:64@installed"]
        );
        // Mesa build first, then item, compiler, subgroup size.
        assert_eq!(
            targets("navi31:aco", &[MesaBuild::Installed, MesaBuild::Stock]).unwrap(),
            ["navi31:aco:32@installed", "navi31:aco:64@installed", "navi31:aco:32@stock", "navi31:aco:64@stock"]
        );
        assert_eq!(targets("navi21:llvm:wave32, navi21:llvm:32", &installed).unwrap(), ["navi21:llvm:32@installed"]);
        assert_eq!(
            targets("vega10::64,NAVI21", &installed).unwrap(),
            [
                "vega10:aco:64@installed",
                "vega10:llvm:64@installed",
                "navi21:aco:32@installed",
                "navi21:aco:64@installed",
                "navi21:llvm:32@installed",
                "navi21:llvm:64@installed"
            ]
        );
        // The default set: 3 GCN chips x 2 compilers + 3 RDNA chips x 2 compilers x 2 sizes.
        let t = targets("default", &installed).unwrap();
        assert_eq!(t.len(), 3 * 2 + 3 * 2 * 2);
        assert_eq!(t[0], "pitcairn:aco:64@installed");
        // `default` beside a chip of its own set adds nothing.
        assert_eq!(targets("default,navi31:aco:32", &installed).unwrap(), t);
    }

    #[test]
    fn empty_axes_are_the_default_chips_every_compiler_and_size_on_the_installed_mesa() {
        let t = names(&TargetAxes::default().targets().unwrap());
        let mut want = vec![];
        for chip in ["pitcairn", "polaris10", "vega10"] {
            want.push(format!("{chip}:aco:64@installed"));
            want.push(format!("{chip}:llvm:64@installed"));
        }
        for chip in ["navi21", "navi31", "gfx1201"] {
            for c in ["aco", "llvm"] {
                want.push(format!("{chip}:{c}:32@installed"));
                want.push(format!("{chip}:{c}:64@installed"));
            }
        }
        assert_eq!(t, want);
        assert_eq!(
            TargetAxes::parse("default", &[]).unwrap().targets().unwrap(),
            TargetAxes::default().targets().unwrap()
        );
    }

    #[test]
    fn a_wrong_target_is_named_before_any_work() {
        let installed = [MesaBuild::Installed];
        let e = targets("pitcairn:aco:32", &installed).unwrap_err();
        assert_eq!(e, "--targets pitcairn:aco:32: pitcairn (GCN 1) compiles compute kernels at 64 lanes only");
        let e = targets("navi99", &installed).unwrap_err();
        assert!(e.contains("--targets navi99: no chip `navi99`"), "{e}");
        let e = targets("navi31:gcc", &installed).unwrap_err();
        assert!(e.contains("--targets navi31:gcc: no compiler `gcc`"), "{e}");
        let e = targets("navi31:aco:x64", &installed).unwrap_err();
        assert!(e.contains("subgroup size `x64` is not a number"), "{e}");
        let e = targets("navi31:aco:64:x", &installed).unwrap_err();
        assert!(e.contains("`x` after"), "{e}");
        assert_eq!(targets(" , ", &installed).unwrap_err(), "--targets: no target given");
        // Axes built in code are checked too.
        let chip = Chip::named("vega10").unwrap();
        let axes = TargetAxes { items: vec![TargetItem { chip, compiler: None, wave: Some(32) }], mesa: vec![] };
        assert_eq!(
            axes.targets().unwrap_err(),
            "--targets vega10::32: vega10 (GCN 5) compiles compute kernels at 64 lanes only"
        );
    }
}
