//! The optional device features a SPIR-V module needs, read from its `OpCapability`
//! instructions: kernel creation checks them against what the context enabled, and
//! `gpu::Capabilities` asks which kernels and methods a device can run.

/// An optional device feature a SPIR-V capability needs (the `EnabledFeatures` that gate it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feature {
    ShaderFloat64,
    ShaderInt64,
    ShaderSubgroupClock,
    RayQuery,
    RayTracingPipeline,
    BufferDeviceAddress,
}

impl Feature {
    /// The Vulkan feature's name.
    pub fn name(self) -> &'static str {
        match self {
            Feature::ShaderFloat64 => "shaderFloat64",
            Feature::ShaderInt64 => "shaderInt64",
            Feature::ShaderSubgroupClock => "shaderSubgroupClock",
            Feature::RayQuery => "rayQuery",
            Feature::RayTracingPipeline => "rayTracingPipeline",
            Feature::BufferDeviceAddress => "bufferDeviceAddress",
        }
    }
}

/// A capability a module declares that needs an optional feature.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Requirement {
    /// The SPIR-V capability's name.
    pub capability: &'static str,
    pub feature: Feature,
}

/// The optional features a SPIR-V module's `OpCapability` instructions need (capabilities every
/// Vulkan 1.2 device has, such as `Shader`, are not listed). Scans the header and the
/// instruction stream (word count in the high 16 bits, opcode in the low 16); a malformed
/// stream is an error.
pub fn required_features(words: &[u32]) -> std::result::Result<Vec<Requirement>, String> {
    const MAGIC: u32 = 0x0723_0203;
    const OP_CAPABILITY: u32 = 17;
    // SPIR-V 1.5 spec, "Capability": Float64 = 10, Int64 = 11, RayQueryKHR = 4472,
    // RayTracingKHR = 4479, ShaderClockKHR = 5055, PhysicalStorageBufferAddresses = 5347.
    const TABLE: [(u32, &str, Feature); 6] = [
        (10, "Float64", Feature::ShaderFloat64),
        (11, "Int64", Feature::ShaderInt64),
        (4472, "RayQueryKHR", Feature::RayQuery),
        (4479, "RayTracingKHR", Feature::RayTracingPipeline),
        (5055, "ShaderClockKHR", Feature::ShaderSubgroupClock),
        (5347, "PhysicalStorageBufferAddresses", Feature::BufferDeviceAddress),
    ];
    if words.len() < 5 || words[0] != MAGIC {
        return Err("not a SPIR-V module (no magic number)".into());
    }
    let mut out = vec![];
    let mut i = 5;
    while i < words.len() {
        let count = (words[i] >> 16) as usize;
        let op = words[i] & 0xFFFF;
        if count == 0 || i + count > words.len() {
            return Err(format!("malformed instruction at word {i}"));
        }
        if op == OP_CAPABILITY && count == 2 {
            if let Some(&(_, capability, feature)) = TABLE.iter().find(|(c, _, _)| *c == words[i + 1]) {
                out.push(Requirement { capability, feature });
            }
        }
        i += count;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn module(body: &[u32]) -> Vec<u32> {
        let mut w = vec![0x0723_0203, 0x0001_0500, 0, 1, 0];
        w.extend_from_slice(body);
        w
    }

    #[test]
    fn capability_scan_finds_what_needs_a_feature() {
        let cap = |c: u32| [(2 << 16) | 17, c];
        // Shader (1) and ImageBuffer (47) need nothing; Float64 and Int64 do.
        let w = module(&[cap(1), cap(47), cap(10), cap(11), [(2 << 16) | 14, 0]].concat());
        let got: Vec<_> = required_features(&w).unwrap().iter().map(|r| r.feature).collect();
        assert_eq!(got, [Feature::ShaderFloat64, Feature::ShaderInt64]);
        assert_eq!(required_features(&module(&cap(1))).unwrap(), []);
        // Malformed: a zero word count, an instruction running past the end, no magic.
        assert!(required_features(&module(&[0])).is_err());
        assert!(required_features(&module(&[(3 << 16) | 17, 10])).is_err());
        assert!(required_features(&[1, 2, 3, 4, 5]).is_err());
    }

    #[test]
    fn only_the_f64_kernels_need_shader_float64() {
        for k in crate::kernels::KERNELS {
            let needs = required_features(&k.words()).unwrap();
            let f64 = needs.iter().any(|r| r.feature == Feature::ShaderFloat64);
            // The f64 probe only copies integers and floats; every kernel that traces needs it.
            let want = k.intersector == "f64" && k.kernel != "probe";
            assert_eq!(f64, want, "{}: {needs:?}", k.name);
            let clock = needs.iter().any(|r| r.feature == Feature::ShaderSubgroupClock);
            assert_eq!(clock, k.variant.starts_with("clock"), "{}: {needs:?}", k.name);
        }
    }
}
