//! The kernel registry: the SPIR-V modules build.rs compiled from `glsl/`, embedded in the
//! binary, one per kernel x intersector x variant, named `<kernel>.<method>.<variant>` with the
//! method's command-line name (`raycast.quad-mt.closest` from `glsl/intersect/quad_mt.glsl`),
//! and what each intersector's GLSL states about itself.
//!
//! This is the ground floor: it holds the kernels in build.rs's order, each with its place
//! ([`KernelSource::id`]) and the names the GLSL gives it (for display). Each kernel's typed key
//! (method, kind, access path, layout, traversal; the path tracer's BSDFs) is emitted by build.rs
//! beside this table, in the same order, into `encoding::variants` (`KernelKey`), where the
//! kernels are asked for by it: nothing reads a key back out of a name. The kernels without a
//! key (the ray-query peer, the roofline, the probes without an intersector) are found by kernel
//! file and variant ([`find`]).

/// One compiled kernel variant.
#[derive(Debug)]
pub struct KernelSource {
    /// Its place in [`KERNELS`] (`KERNELS[k.id]` is `k`): where build.rs put its typed key in
    /// `encoding::variants`.
    pub id: usize,
    /// `<kernel>.<method>.<variant>`, the method by its command-line name (the intersector's
    /// stem with `-` for `_`); also the file name under `spirv/`.
    pub name: &'static str,
    /// The `glsl/<kernel>.comp` it came from.
    pub kernel: &'static str,
    /// The intersector's file stem, `glsl/intersect/<intersector>.glsl` (`quad_mt`; the method's
    /// command-line name has `-` for `_`), or `none` for kernels that trace no rays (`//
    /// trilab:intersector none`).
    pub intersector: &'static str,
    /// The variant from the kernel's `// trilab:variants` line (with `_<layout>` for a variant
    /// compiled per layout: the kernel's `// trilab:layouts` line).
    pub variant: &'static str,
    /// The node layout it reads: `glsl/layout/<layout>.glsl`, or `bvh2` (the binary nodes).
    pub layout: &'static str,
    /// The module's little-endian bytes, raw-deflated by build.rs (a third of the size; the
    /// binary travels to lent GPUs under a size limit). [`KernelSource::spirv`] inflates it.
    pub spirv_deflate: &'static [u8],
}

/// What an intersector's GLSL (`glsl/intersect/<glsl>.glsl` with its includes) states about
/// itself, read by build.rs: the Rust side reads these instead of repeating them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IntersectorFacts {
    /// The file's stem.
    pub glsl: &'static str,
    /// `PRIM_TRIANGLES`: triangle slots one primitive holds (1, or 4 for the Quad forms).
    pub prim_triangles: u32,
    /// Whether it defines `CONSERVATIVE_TRAVERSAL` (traversal's conservative box test).
    pub conservative_traversal: bool,
}

include!(concat!(env!("OUT_DIR"), "/kernels.rs"));

/// One compiled stage of the ray-tracing-pipeline peer (`glsl/raytrace/<shader>.<stage>`,
/// `gpu::rtpipeline`). Not a kernel: kept out of [`KERNELS`] (and so out of `spirv/` and the
/// kernels' reflection tests, which are about compute kernels).
#[derive(Debug)]
pub struct RtShaderSource {
    /// `<shader>.<variant>.<stage>`.
    pub name: &'static str,
    /// The file's stem.
    pub shader: &'static str,
    /// The file's extension: `rgen`, `rchit` or `rmiss`.
    pub stage: &'static str,
    /// The variant from its `// trilab:variants` line (`main` without one).
    pub variant: &'static str,
    /// SPIR-V words, little-endian bytes.
    pub spirv: &'static [u8],
}

include!(concat!(env!("OUT_DIR"), "/rt_shaders.rs"));

impl RtShaderSource {
    /// The module as words.
    pub fn words(&self) -> Vec<u32> {
        words(self.spirv)
    }
}

/// The variant `variant` of the ray-tracing stage `glsl/raytrace/<shader>.<stage>`.
pub fn find_rt(shader: &str, stage: &str, variant: &str) -> Option<&'static RtShaderSource> {
    RT_SHADERS.iter().find(|s| s.shader == shader && s.stage == stage && s.variant == variant)
}

/// Little-endian bytes as words (`include_bytes!` gives no alignment guarantee).
fn words(spirv: &[u8]) -> Vec<u32> {
    spirv.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
}

/// The intersector of kernels that trace no rays.
pub const NO_INTERSECTOR: &str = "none";

impl KernelSource {
    /// The module's little-endian bytes, inflated from [`KernelSource::spirv_deflate`].
    pub fn spirv(&self) -> Vec<u8> {
        use std::io::Read as _;
        let mut bytes = Vec::with_capacity(self.spirv_deflate.len() * 4);
        flate2::read::DeflateDecoder::new(self.spirv_deflate)
            .read_to_end(&mut bytes)
            .unwrap_or_else(|e| panic!("embedded kernel {} does not inflate: {e}", self.name));
        bytes
    }

    /// The module as words.
    pub fn words(&self) -> Vec<u32> {
        words(&self.spirv())
    }
}

/// The variant `variant` of `glsl/<kernel>.comp` compiled with intersector `intersector`
/// ([`NO_INTERSECTOR`] for kernels without one).
pub fn find(kernel: &str, intersector: &str, variant: &str) -> Option<&'static KernelSource> {
    KERNELS.iter().find(|k| k.kernel == kernel && k.intersector == intersector && k.variant == variant)
}

/// What `glsl/intersect/<glsl>.glsl` states about itself; `None` if there is no such file.
pub fn facts(glsl: &str) -> Option<&'static IntersectorFacts> {
    INTERSECTOR_FACTS.iter().find(|f| f.glsl == glsl)
}

/// The intersectors build.rs found in `glsl/intersect/`.
pub fn intersectors() -> impl Iterator<Item = &'static str> {
    INTERSECTOR_FACTS.iter().map(|f| f.glsl)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_module_is_spirv_and_every_kernel_with_an_intersector_has_each_one() {
        for (i, k) in KERNELS.iter().enumerate() {
            assert_eq!(k.id, i, "{}: its id is its place", k.name);
            assert_eq!(k.spirv().len() % 4, 0, "{}", k.name);
            assert_eq!(k.words()[0], 0x0723_0203, "{}: SPIR-V magic", k.name);
            assert_eq!(k.name, format!("{}.{}.{}", k.kernel, k.intersector.replace('_', "-"), k.variant));
            if k.intersector != NO_INTERSECTOR {
                for glsl in intersectors() {
                    assert!(find(k.kernel, glsl, k.variant).is_some(), "{} has no {glsl} build", k.name);
                }
            }
        }
        assert!(find("raycast", "mt", "closest").is_some());
        assert!(find("raycast", "mt", "no-such-variant").is_none());
    }

    #[test]
    fn the_ray_tracing_stages_are_spirv_and_not_kernels() {
        for s in RT_SHADERS {
            assert_eq!(s.words()[0], 0x0723_0203, "{}: SPIR-V magic", s.name);
            assert_eq!(s.name, format!("{}.{}.{}", s.shader, s.variant, s.stage));
            assert!(KERNELS.iter().all(|k| k.kernel != s.shader), "{}", s.name);
        }
        for (shader, stage, variant) in [
            ("raygen", "rgen", "closest"),
            ("raygen", "rgen", "any"),
            ("closest", "rchit", "main"),
            ("miss", "rmiss", "main"),
        ] {
            assert!(find_rt(shader, stage, variant).is_some(), "{shader}.{variant}.{stage}");
        }
    }

    #[test]
    fn facts_are_read_from_the_glsl() {
        // The Quad forms test four triangles per primitive, and only watertight traverses
        // conservatively (glsl/intersect/*.glsl).
        assert_eq!(facts("quad_mt").map(|f| f.prim_triangles), Some(4));
        assert_eq!(facts("mt").map(|f| f.prim_triangles), Some(1));
        assert_eq!(facts("watertight").map(|f| f.conservative_traversal), Some(true));
        assert_eq!(facts("mt").map(|f| f.conservative_traversal), Some(false));
        assert!(facts("no_such_intersector").is_none());
    }
}
