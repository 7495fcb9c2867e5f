//! The kernels read the scene through load_* functions that assemble each struct from 16-byte
//! texels. probe.comp calls the same functions and writes the structs to std430 buffers; here
//! every node, primitive struct and slot id must come back byte for byte as the encoder wrote it,
//! for every method (tests/reflection.rs checks those buffers' std430 offsets against Rust).

mod common;

use ash::vk;
use gpu_allocator::MemoryLocation;
use trilab::bvh::BuildOptions;
use trilab::encoding::Method;
use trilab::gpu::Resource;
use trilab::pipeline::{HostScene, SceneRequest};
use trilab::shared::{BINDING_PROBE_NODES, BINDING_PROBE_PRIMS, BINDING_PROBE_SLOT_IDS, WORKGROUP_SIZE};

#[test]
fn texel_loaders_return_exactly_what_the_encoders_wrote() {
    common::with_gpu(300, |ctx| {
        let mesh = common::bunny();
        for leaf in [1, 4, 16] {
            let host = HostScene::build("bunny", &mesh, &BuildOptions::new(leaf)).unwrap();
            for method in Method::ALL {
                // The encoding as uploaded, kept for the comparison.
                let mut enc = None;
                let placement = host.place(ctx, &SceneRequest::new(method)).unwrap();
                let scene = placement.upload_with(ctx, None, |e| enc = Some(e.clone())).unwrap();
                let enc = enc.unwrap();
                let kernel = ctx.create_kernel(method.probe_kernel()).unwrap();
                let (prims, size) = enc.prim_structs();
                let counts = [enc.nodes.len() as u32, (prims.bytes.len() / size) as u32, enc.slot_ids.len() as u32];
                let want: [&[u8]; 3] =
                    [bytemuck::cast_slice(&enc.nodes), &prims.bytes, bytemuck::cast_slice(&enc.slot_ids)];
                let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
                let outs: Vec<_> = ["probe nodes", "probe prims", "probe slot ids"]
                    .iter()
                    .zip(want)
                    .map(|(name, w)| ctx.create_buffer(name, w.len() as u64, usage, MemoryLocation::GpuOnly).unwrap())
                    .collect();
                let mut resources: Vec<(u32, Resource)> = scene.resources().collect();
                for (b, out) in
                    [BINDING_PROBE_NODES, BINDING_PROBE_PRIMS, BINDING_PROBE_SLOT_IDS].into_iter().zip(&outs)
                {
                    resources.push((b, Resource::whole(out)));
                }
                let groups = counts.iter().max().unwrap().div_ceil(WORKGROUP_SIZE);
                ctx.dispatch(&kernel, &resources, bytemuck::cast_slice(&counts), groups).unwrap();
                for ((out, w), what) in outs.iter().zip(want).zip(["nodes", "primitive structs", "slot ids"]) {
                    let got = ctx.download(out, w.len() as u64).unwrap();
                    let first_diff = got.iter().zip(w).position(|(a, b)| a != b);
                    assert!(first_diff.is_none(), "{method} leaf {leaf}: {what} differ first at byte {first_diff:?}");
                }
            }
        }
    });
}
