//! AMD GPU chips as Mesa's RADV knows them, and the occupancy its compiler's statistics report.
//!
//! RADV's null device (`RADV_FORCE_FAMILY=<chip>` with no GPU present) compiles for any chip
//! Mesa knows: the chip names here are Mesa's family names (`ac_get_family_name`), which is
//! what `RADV_FORCE_FAMILY` reads. Each chip carries what decides how many subgroups (waves) of
//! a kernel a SIMD holds at once: its graphics IP level, its wave slots, and its register and
//! LDS budgets per SIMD, with the values RADV's null winsys gives the chip
//! (`radv_null_winsys_query_info`, Mesa 25.0).
//!
//! [`subgroups_per_simd`] is the statistic RADV reports as "Subgroups per SIMD"
//! (`radv_get_max_waves`, Mesa 25.0), computed from a kernel's VGPRs, SGPRs and LDS. Its
//! definition is RADV's, quirks included: on RDNA (GFX10 and later) it counts wave64 subgroups
//! twice, as pairs of wave32 slots. trilab computes it to find the **occupancy cliffs**
//! ([`Occupancy::of`]): the kernels that one more VGPR allocation granule would cost a
//! subgroup per SIMD, and how many VGPRs a kernel must give up to gain one. A test holds this
//! function equal to the figure the driver itself reported for every committed kernel and chip
//! (`results/radv/`).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// A graphics IP level, oldest first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum GfxLevel {
    /// GCN 1 (Southern Islands): HD 7000.
    Gfx6,
    /// GCN 2 (Sea Islands).
    Gfx7,
    /// GCN 3 and 4 (Volcanic Islands, Polaris).
    Gfx8,
    /// GCN 5 (Vega).
    Gfx9,
    /// RDNA 1.
    Gfx10,
    /// RDNA 2.
    Gfx10_3,
    /// RDNA 3.
    Gfx11,
    /// RDNA 3.5.
    Gfx11_5,
    /// RDNA 4.
    Gfx12,
}

impl GfxLevel {
    /// The architecture's name: `GCN 1`, `RDNA 2`.
    pub fn architecture(self) -> &'static str {
        match self {
            GfxLevel::Gfx6 => "GCN 1",
            GfxLevel::Gfx7 => "GCN 2",
            GfxLevel::Gfx8 => "GCN 3/4",
            GfxLevel::Gfx9 => "GCN 5",
            GfxLevel::Gfx10 => "RDNA 1",
            GfxLevel::Gfx10_3 => "RDNA 2",
            GfxLevel::Gfx11 => "RDNA 3",
            GfxLevel::Gfx11_5 => "RDNA 3.5",
            GfxLevel::Gfx12 => "RDNA 4",
        }
    }

    /// RDNA: a SIMD is 32 lanes wide, and a kernel may run as wave32 or wave64.
    pub fn is_rdna(self) -> bool {
        self >= GfxLevel::Gfx10
    }
}

/// One chip: Mesa's family name, its IP level and a product that carries it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Chip {
    /// Mesa's family name, what `RADV_FORCE_FAMILY` reads: `pitcairn`, `navi31`, `gfx1201`.
    pub name: &'static str,
    pub gfx: GfxLevel,
    /// A product with this chip, for a reader: `Radeon HD 7850`.
    pub product: &'static str,
}

/// The chips trilab knows, oldest first: every family of Mesa 25.0's null winsys with a
/// graphics pipeline.
pub const CHIPS: &[Chip] = &[
    Chip { name: "tahiti", gfx: GfxLevel::Gfx6, product: "Radeon HD 7970" },
    Chip { name: "pitcairn", gfx: GfxLevel::Gfx6, product: "Radeon HD 7850 (the paper's Table 4)" },
    Chip { name: "verde", gfx: GfxLevel::Gfx6, product: "Radeon HD 7770" },
    Chip { name: "oland", gfx: GfxLevel::Gfx6, product: "Radeon R7 250" },
    Chip { name: "hainan", gfx: GfxLevel::Gfx6, product: "Radeon R5 M330" },
    Chip { name: "bonaire", gfx: GfxLevel::Gfx7, product: "Radeon HD 7790" },
    Chip { name: "kaveri", gfx: GfxLevel::Gfx7, product: "A10-7850K" },
    Chip { name: "kabini", gfx: GfxLevel::Gfx7, product: "Athlon 5350" },
    Chip { name: "hawaii", gfx: GfxLevel::Gfx7, product: "Radeon R9 290X" },
    Chip { name: "tonga", gfx: GfxLevel::Gfx8, product: "Radeon R9 285" },
    Chip { name: "iceland", gfx: GfxLevel::Gfx8, product: "Radeon R7 M260" },
    Chip { name: "carrizo", gfx: GfxLevel::Gfx8, product: "A10-8700P" },
    Chip { name: "fiji", gfx: GfxLevel::Gfx8, product: "Radeon R9 Fury X" },
    Chip { name: "stoney", gfx: GfxLevel::Gfx8, product: "A9-9420" },
    Chip { name: "polaris10", gfx: GfxLevel::Gfx8, product: "Radeon RX 480" },
    Chip { name: "polaris11", gfx: GfxLevel::Gfx8, product: "Radeon RX 460" },
    Chip { name: "polaris12", gfx: GfxLevel::Gfx8, product: "Radeon RX 550" },
    Chip { name: "vegam", gfx: GfxLevel::Gfx8, product: "Radeon RX Vega M GH" },
    Chip { name: "vega10", gfx: GfxLevel::Gfx9, product: "Radeon RX Vega 64" },
    Chip { name: "vega12", gfx: GfxLevel::Gfx9, product: "Radeon Pro Vega 20" },
    Chip { name: "vega20", gfx: GfxLevel::Gfx9, product: "Radeon VII" },
    Chip { name: "raven", gfx: GfxLevel::Gfx9, product: "Ryzen 5 2400G" },
    Chip { name: "raven2", gfx: GfxLevel::Gfx9, product: "Athlon 300U" },
    Chip { name: "renoir", gfx: GfxLevel::Gfx9, product: "Ryzen 7 4800U" },
    Chip { name: "navi10", gfx: GfxLevel::Gfx10, product: "Radeon RX 5700 XT" },
    Chip { name: "navi12", gfx: GfxLevel::Gfx10, product: "Radeon Pro 5600M" },
    Chip { name: "navi14", gfx: GfxLevel::Gfx10, product: "Radeon RX 5500 XT" },
    Chip { name: "navi21", gfx: GfxLevel::Gfx10_3, product: "Radeon RX 6900 XT" },
    Chip { name: "navi22", gfx: GfxLevel::Gfx10_3, product: "Radeon RX 6700 XT" },
    Chip { name: "navi23", gfx: GfxLevel::Gfx10_3, product: "Radeon RX 6600 XT" },
    Chip { name: "navi24", gfx: GfxLevel::Gfx10_3, product: "Radeon RX 6500 XT" },
    Chip { name: "vangogh", gfx: GfxLevel::Gfx10_3, product: "Steam Deck" },
    Chip { name: "rembrandt", gfx: GfxLevel::Gfx10_3, product: "Ryzen 7 6800U" },
    Chip { name: "navi31", gfx: GfxLevel::Gfx11, product: "Radeon RX 7900 XTX" },
    Chip { name: "navi32", gfx: GfxLevel::Gfx11, product: "Radeon RX 7800 XT" },
    Chip { name: "navi33", gfx: GfxLevel::Gfx11, product: "Radeon RX 7600" },
    Chip { name: "phoenix", gfx: GfxLevel::Gfx11, product: "Ryzen 7 7840U" },
    Chip { name: "gfx1150", gfx: GfxLevel::Gfx11_5, product: "Ryzen AI 9 HX 370" },
    Chip { name: "gfx1151", gfx: GfxLevel::Gfx11_5, product: "Ryzen AI Max+ 395" },
    Chip { name: "gfx1200", gfx: GfxLevel::Gfx12, product: "Radeon RX 9060 XT" },
    Chip { name: "gfx1201", gfx: GfxLevel::Gfx12, product: "Radeon RX 9070 XT" },
];

impl Chip {
    /// The chip Mesa names `name` (case-insensitive, as RADV reads it).
    pub fn named(name: &str) -> Option<Chip> {
        CHIPS.iter().copied().find(|c| c.name.eq_ignore_ascii_case(name))
    }

    /// The chip of a RADV device name: `AMD Radeon RX 7900 XTX (RADV NAVI31)`, or the null
    /// device's `Null hardware (RADV NAVI31 (LLVM 15.0.6))`.
    pub fn of_device_name(device: &str) -> Option<Chip> {
        let rest = &device[device.find("(RADV ")? + "(RADV ".len()..];
        let name: String = rest.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
        Chip::named(&name)
    }

    /// The subgroup sizes a compute kernel may be compiled at: 64 on GCN, 32 or 64 on RDNA.
    pub fn subgroup_sizes(self) -> &'static [u32] {
        if self.gfx.is_rdna() {
            &[32, 64]
        } else {
            &[64]
        }
    }

    /// Wave slots per SIMD (`max_waves_per_simd`).
    pub fn max_waves_per_simd(self) -> u32 {
        match self.gfx {
            g if g >= GfxLevel::Gfx10_3 => 16,
            GfxLevel::Gfx10 => 20,
            _ if matches!(self.name, "polaris10" | "polaris11" | "polaris12" | "vegam") => 8,
            _ => 10,
        }
    }

    /// SGPRs per SIMD (`num_physical_sgprs_per_simd`).
    pub fn sgprs_per_simd(self) -> u32 {
        match self.gfx {
            g if g.is_rdna() => 128 * self.max_waves_per_simd(),
            g if g >= GfxLevel::Gfx8 => 800,
            _ => 512,
        }
    }

    /// VGPRs per SIMD counted in wave64 registers (`num_physical_wave64_vgprs_per_simd`): RDNA 3's
    /// navi31 and navi32 have half as many again.
    pub fn wave64_vgprs_per_simd(self) -> u32 {
        match self.gfx {
            _ if matches!(self.name, "navi31" | "navi32") => 768,
            g if g.is_rdna() => 512,
            _ => 256,
        }
    }

    /// LDS a workgroup may use, in bytes.
    pub fn lds_per_workgroup(self) -> u32 {
        match self.gfx {
            g if g.is_rdna() => 128 * 1024,
            g if g >= GfxLevel::Gfx7 => 64 * 1024,
            _ => 32 * 1024,
        }
    }

    /// The granule LDS is allocated in, bytes.
    pub fn lds_alloc_granularity(self) -> u32 {
        match self.gfx {
            g if g >= GfxLevel::Gfx10_3 => 1024,
            g if g >= GfxLevel::Gfx7 => 512,
            _ => 256,
        }
    }

    /// SIMDs per compute unit.
    pub fn simds_per_cu(self) -> u32 {
        if self.gfx.is_rdna() {
            2
        } else {
            4
        }
    }

    /// The granule of a kernel's VGPR allocation at `wave` lanes: a kernel's VGPRs are rounded
    /// up to it.
    pub fn vgpr_granule(self, wave: u32) -> u32 {
        let base = if wave == 32 { 8 } else { 4 };
        if self.gfx >= GfxLevel::Gfx10_3 {
            self.wave64_vgprs_per_simd() / 64 * if wave == 32 { 2 } else { 1 }
        } else {
            base
        }
    }

    /// The most VGPRs one kernel may use.
    pub const MAX_VGPRS: u32 = 256;
}

impl Serialize for Chip {
    /// A chip is its name.
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.name)
    }
}

impl fmt::Display for Chip {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name)
    }
}

impl FromStr for Chip {
    type Err = String;

    fn from_str(s: &str) -> Result<Chip, String> {
        Chip::named(s).ok_or_else(|| {
            format!(
                "no chip `{s}`: Mesa's family names are {}",
                CHIPS.iter().map(|c| c.name).collect::<Vec<_>>().join(", ")
            )
        })
    }
}

/// What a kernel's compiled code asks of a SIMD: the inputs of RADV's occupancy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Resources {
    /// Subgroup size the kernel was compiled at (32 or 64).
    pub wave: u32,
    pub vgprs: u32,
    pub sgprs: u32,
    /// LDS per workgroup, bytes.
    pub lds_bytes: u32,
    /// Invocations per workgroup.
    pub workgroup: u32,
}

/// "Subgroups per SIMD" as RADV reports it (`radv_get_max_waves`, Mesa 25.0): the wave slots,
/// less what the SGPRs (GCN only), the VGPRs and the LDS allow; on RDNA, wave64 counts twice.
pub fn subgroups_per_simd(chip: Chip, r: &Resources) -> u32 {
    let wave = r.wave.max(1);
    let mut waves = chip.max_waves_per_simd();
    if r.sgprs > 0 && !chip.gfx.is_rdna() {
        let s = r.sgprs.next_multiple_of(if chip.gfx >= GfxLevel::Gfx8 { 16 } else { 8 });
        waves = waves.min(chip.sgprs_per_simd() / s);
    }
    if r.vgprs > 0 {
        let physical = chip.wave64_vgprs_per_simd() * 64 / wave;
        let v = allocated_vgprs(chip, wave, r.vgprs);
        waves = waves.min(physical / v);
    }
    if r.lds_bytes > 0 {
        let lds_per_wave =
            r.lds_bytes.next_multiple_of(chip.lds_alloc_granularity()) / r.workgroup.max(1).div_ceil(wave);
        let simds = chip.simds_per_cu() * if chip.gfx.is_rdna() { 2 } else { 1 };
        let max_lds_per_simd = chip.lds_per_workgroup() / simds;
        if lds_per_wave > 0 {
            waves = waves.min(max_lds_per_simd.div_ceil(lds_per_wave));
        }
    }
    if chip.gfx.is_rdna() {
        waves * wave / 32
    } else {
        waves
    }
}

/// `vgprs` rounded up to what the chip allocates at `wave` lanes.
pub fn allocated_vgprs(chip: Chip, wave: u32, vgprs: u32) -> u32 {
    let v = vgprs.next_multiple_of(if wave == 32 { 8 } else { 4 });
    if chip.gfx >= GfxLevel::Gfx10_3 {
        v.next_multiple_of(chip.vgpr_granule(wave))
    } else {
        v
    }
}

/// Where a kernel stands on its chip's occupancy curve.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Occupancy {
    /// Subgroups per SIMD, as RADV counts them ([`subgroups_per_simd`]).
    pub subgroups: u32,
    /// VGPRs it may still add before it loses a subgroup per SIMD (`None`: none it could add
    /// would, the limit being elsewhere or the register file's end).
    pub vgprs_to_loss: Option<u32>,
    /// VGPRs it must give up to gain a subgroup per SIMD (`None`: fewer VGPRs gain nothing).
    pub vgprs_to_gain: Option<u32>,
}

impl Occupancy {
    /// `r`'s occupancy on `chip`.
    pub fn of(chip: Chip, r: &Resources) -> Occupancy {
        let at = |v: u32| subgroups_per_simd(chip, &Resources { vgprs: v, ..*r });
        let subgroups = at(r.vgprs);
        let vgprs_to_loss = (r.vgprs + 1..=Chip::MAX_VGPRS).find(|&v| at(v) < subgroups).map(|v| v - r.vgprs);
        let vgprs_to_gain = (1..r.vgprs).rev().find(|&v| at(v) > subgroups).map(|v| r.vgprs - v);
        Occupancy { subgroups, vgprs_to_loss, vgprs_to_gain }
    }

    /// One more VGPR costs a subgroup per SIMD: the kernel sits on a cliff's edge.
    pub fn on_cliff(&self) -> bool {
        self.vgprs_to_loss == Some(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chip(n: &str) -> Chip {
        Chip::named(n).unwrap()
    }

    fn r(wave: u32, vgprs: u32) -> Resources {
        Resources { wave, vgprs, sgprs: 0, lds_bytes: 0, workgroup: 64 }
    }

    /// The figures issue 50 read from RADV 25.0.7's null device (ACO, wave64, closest-hit
    /// kernels), VGPRs -> subgroups per SIMD, per chip: the model gives each.
    #[test]
    fn the_model_gives_what_radv_reported() {
        for (c, pairs) in [
            ("pitcairn", [(40, 6), (84, 3), (184, 1), (220, 1)]),
            ("vega10", [(40, 6), (84, 3), (184, 1), (220, 1)]),
            ("navi21", [(40, 24), (80, 12), (184, 4), (224, 4)]),
            ("navi31", [(48, 32), (84, 18), (180, 8), (228, 6)]),
            ("gfx1201", [(48, 20), (84, 10), (180, 4), (228, 4)]),
        ] {
            for (v, want) in pairs {
                assert_eq!(subgroups_per_simd(chip(c), &r(64, v)), want, "{c} {v} VGPRs");
            }
        }
        // LLVM's 128-VGPR cap on navi31 (wave64): 10, as RADV said.
        assert_eq!(subgroups_per_simd(chip("navi31"), &r(64, 128)), 10);
    }

    #[test]
    fn cliffs_are_where_one_more_register_costs_a_subgroup() {
        // GCN: 256 VGPRs per lane; 6 waves need at most 42, allocated in fours.
        let o = Occupancy::of(chip("pitcairn"), &r(64, 40));
        assert_eq!(o, Occupancy { subgroups: 6, vgprs_to_loss: Some(1), vgprs_to_gain: Some(4) });
        assert!(o.on_cliff());
        let o = Occupancy::of(chip("pitcairn"), &r(64, 36));
        assert_eq!((o.subgroups, o.vgprs_to_loss, o.on_cliff()), (7, Some(1), true));
        // At the wave-slot cap, no register gains a wave.
        let o = Occupancy::of(chip("pitcairn"), &r(64, 20));
        assert_eq!((o.subgroups, o.vgprs_to_gain), (10, None));
        assert_eq!(o.vgprs_to_loss, Some(5));
        // One wave: nothing more to lose inside the register file.
        let o = Occupancy::of(chip("pitcairn"), &r(64, 220));
        assert_eq!((o.subgroups, o.vgprs_to_loss), (1, None));
    }

    #[test]
    fn chips_read_from_names_and_device_names() {
        assert_eq!(Chip::of_device_name("Null hardware (RADV NAVI31 (LLVM 15.0.6))"), Some(chip("navi31")));
        assert_eq!(Chip::of_device_name("AMD Radeon RX 7900 XTX (RADV NAVI31)"), Some(chip("navi31")));
        assert_eq!(Chip::of_device_name("Null hardware (RADV GFX1201)"), Some(chip("gfx1201")));
        assert_eq!(Chip::of_device_name("llvmpipe (LLVM 15.0.6, 256 bits)"), None);
        assert!("navi99".parse::<Chip>().unwrap_err().contains("pitcairn"));
        assert_eq!(chip("pitcairn").subgroup_sizes(), &[64]);
        assert_eq!(chip("navi21").subgroup_sizes(), &[32, 64]);
        // Every name is unique.
        let mut names: Vec<&str> = CHIPS.iter().map(|c| c.name).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), CHIPS.len());
    }
}
