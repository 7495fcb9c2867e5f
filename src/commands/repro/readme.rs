//! The repro folder's README.md: for a driver developer who has GFXReconstruct and not trilab.

use super::folder::{self, Manifest, Query};

/// The README of the repro `m` describes.
pub fn text(m: &Manifest) -> String {
    let c = &m.cell;
    let k = &m.kernel;
    let features = if k.features.is_empty() { "none beyond Vulkan 1.2".to_owned() } else { k.features.join(", ") };
    let mut s = format!(
        "# trilab repro: `{}` on {}\n\n\
         One compute dispatch of trilab's ray tracing kernel `{}`: {} rays cast through a BVH of the \
         `{}` scene ({} triangles; {} intersection, {} node layout, {} traversal, {} access path, leaf \
         size {}, {} leaves, SAH priced in groups of {}, {}), {} query. Made with {} ({}, {}) on {} ({}).\n\n",
        k.name,
        m.made.device,
        k.name,
        m.rays.bytes / 32,
        c.scene,
        c.triangles,
        c.method,
        c.layout,
        c.traversal,
        c.access.name(),
        c.leaf_size,
        c.leaf_policy,
        c.sah_group,
        c.builder,
        match c.query {
            Query::Closest => "closest-hit",
            Query::Any => "any-hit (occlusion)",
        },
        m.made.trilab,
        m.made.commit,
        m.made.date,
        m.made.device,
        m.made.driver,
    );
    s += &format!(
        "The expected hits are this device's; trilab's f64 reference said: {} ({}).\n\n",
        if m.expected.passes { "agrees" } else { "DISAGREES" },
        m.expected.validation
    );
    s += "## Replay\n\n";
    match &m.capture.file {
        Some(f) => {
            s += &format!(
                "`{}` ({} bytes, {}) holds the whole program: instance and device creation (only the device \
                 features the kernel needs: {features}; workgroup size {}{}), the buffers and their contents, the \
                 pipeline, one dispatch and the read-back. With GFXReconstruct (0.9.18 or later):\n\n\
                 \x20   gfxrecon-replay {}                 # on the driver it was made on\n\
                 \x20   gfxrecon-replay -m remap {}        # on a device whose memory types differ\n\
                 \x20   gfxrecon-replay --replace-shaders DIR {}   # with your own SPIR-V (see gfxrecon-extract)\n\n",
                f.file,
                f.bytes,
                m.capture.note,
                k.local_size,
                if k.full_subgroups { ", full subgroups" } else { "" },
                f.file,
                f.file,
                f.file
            );
            match m.capture.differing {
                Some(0) => s += "The captured dispatch returned exactly the expected hits.\n\n",
                Some(n) => {
                    s += &format!("The captured dispatch returned {n} hits that differ from `expected.hits`.\n\n")
                }
                None => {}
            }
        }
        None => s += &format!("There is no capture: {}.\n\n", m.capture.note),
    }
    s += &format!(
        "To replay the dispatch from the files below and compare its hits with the expected ones ray by \
         ray (`same`, or how many rays differ and how): `trilab repro --check .` (the device is chosen as \
         trilab chooses it: `--device N`, or `VK_DRIVER_FILES` for another driver).\n\n\
         ## Files\n\n\
         | file | what |\n|---|---|\n\
         | `{}` | the SPIR-V module ({} bytes), entry point `main`, descriptor set 0 |\n\
         | `{}` | its disassembly |\n",
        k.spirv.file,
        k.spirv.bytes,
        folder::DISASSEMBLY
    );
    for b in &m.bindings {
        s += &format!(
            "| `{}` | binding {}: `{}`, {} bytes, read as {} texels ({}) |\n",
            b.data.file,
            b.binding,
            b.name,
            b.data.bytes,
            b.texel.name(),
            match c.access.name() {
                "storage" => "a storage buffer",
                _ => "a storage texel buffer",
            }
        );
    }
    s += &format!(
        "| `{}` | the rays: 32 bytes each, `origin.xyz, tmin, dir.xyz, tmax` as little-endian f32 (bound as a \
         storage buffer) |\n\
         | `{}` | the expected hits: 16 bytes each, `t` (f32), triangle id (u32), `u`, `v` (f32); a miss is \
         `t = +inf`, id `0xFFFFFFFF` |\n\
         | `{}` | all of the above as data, and where the cell came from |\n\n\
         ## What to look at\n\n\
         A ray whose hit differs from `expected.hits` on your driver is the finding: its index is the \
         invocation that traced it (`gl_GlobalInvocationID.x`, one ray per invocation unless the traversal \
         says otherwise). The kernel's arithmetic is in `{}`; the traversal loop reads the node buffer \
         (binding {}) and the leaf's primitives through the texel or storage reads listed above.\n",
        folder::RAYS,
        folder::EXPECTED,
        folder::MANIFEST,
        folder::DISASSEMBLY,
        crate::shared::BINDING_NODES
    );
    s
}
