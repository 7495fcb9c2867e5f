//! The SPIR-V modules build.rs compiled from `glsl/`, embedded in the binary: one per
//! kernel x intersector x variant, named `<kernel>.<method>.<variant>` (`raycast.mt.closest`).

use crate::encoding::Method;

/// One compiled kernel variant.
#[derive(Debug)]
pub struct KernelSource {
    /// `<kernel>.<method>.<variant>`; also the file name under `spirv/`.
    pub name: &'static str,
    /// The `glsl/<kernel>.comp` it came from.
    pub kernel: &'static str,
    /// The intersector, `glsl/intersect/<method>.glsl`, or `none` for kernels that trace no rays
    /// (`// trilab:intersector none`).
    pub method: &'static str,
    /// The variant from the kernel's `// trilab:variants` line.
    pub variant: &'static str,
    /// SPIR-V words, little-endian bytes.
    pub spirv: &'static [u8],
}

include!(concat!(env!("OUT_DIR"), "/kernels.rs"));

impl KernelSource {
    /// The module as words (`include_bytes!` gives no alignment guarantee).
    pub fn words(&self) -> Vec<u32> {
        self.spirv.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
    }
}

/// The raycast kernel for a method: closest hit or, with `any_hit`, occlusion.
pub fn raycast(method: Method, any_hit: bool) -> &'static KernelSource {
    find("raycast", method, if any_hit { "any" } else { "closest" })
}

/// The raycast kernel for a scene read through `access` (`gpu::plan`): the default variants
/// for texel buffers, `closest_bda`/`any_bda` for device addresses.
pub fn raycast_via(method: Method, any_hit: bool, access: crate::gpu::AccessPath) -> &'static KernelSource {
    match (access, any_hit) {
        (crate::gpu::AccessPath::Texel, _) => raycast(method, any_hit),
        (crate::gpu::AccessPath::Address, false) => find("raycast", method, "closest_bda"),
        (crate::gpu::AccessPath::Address, true) => find("raycast", method, "any_bda"),
    }
}

/// The raycast kernel that also writes each ray's traversal work (closest hit; the `stats`
/// variant, `TRAVERSAL_STATS` in `glsl/traverse.glsl`).
pub fn raycast_stats(method: Method) -> &'static KernelSource {
    find("raycast", method, "stats")
}

/// Looks a variant up; every `Method` has every variant of every kernel (build.rs compiles
/// each kernel for each intersector file; `tests` below checks the two lists agree).
pub fn find(kernel: &str, method: Method, variant: &str) -> &'static KernelSource {
    KERNELS
        .iter()
        .find(|k| k.kernel == kernel && k.method == method.glsl_name() && k.variant == variant)
        .unwrap_or_else(|| panic!("no kernel {kernel}.{}.{variant} was compiled", method.glsl_name()))
}

/// Looks up a variant of a kernel that uses no intersector (`// trilab:intersector none`, method
/// `none`), such as the BSDF probe.
pub fn find_no_intersector(kernel: &str, variant: &str) -> &'static KernelSource {
    KERNELS
        .iter()
        .find(|k| k.kernel == kernel && k.method == "none" && k.variant == variant)
        .unwrap_or_else(|| panic!("no kernel {kernel}.none.{variant} was compiled"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_method_has_its_kernels_and_every_kernel_a_method() {
        for m in Method::ALL {
            for any in [false, true] {
                let k = raycast(m, any);
                assert_eq!(k.spirv.len() % 4, 0);
                assert_eq!(k.words()[0], 0x0723_0203, "SPIR-V magic");
            }
            assert_eq!(raycast_stats(m).variant, "stats");
            assert_eq!(raycast_via(m, false, crate::gpu::AccessPath::Address).variant, "closest_bda");
            assert_eq!(raycast_via(m, true, crate::gpu::AccessPath::Address).variant, "any_bda");
        }
        for k in KERNELS {
            assert!(
                k.method == "none" || Method::ALL.iter().any(|m| m.glsl_name() == k.method),
                "glsl/intersect/{}.glsl has no Method arm",
                k.method
            );
        }
    }
}
