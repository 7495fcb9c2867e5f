//! Validation, synchronization validation included: proof that it is active (a deliberately
//! missing barrier is reported as a SYNC-HAZARD), and every kernel family running clean under
//! it (`common::with_gpu` fails on any message).

mod common;

use ash::vk;
use trilab::gpu::shared::{BINDING_HITS, BINDING_RAYS, BINDING_RNG_PROBE_OUT};
use trilab::gpu::{Context, ContextOptions, Resource, Validation};

/// Two dispatches in one command buffer: the rng probe writes a buffer, then a raycast kernel
/// reads it as its rays. Without a barrier between them synchronization validation must report
/// a read-after-write hazard; with one, nothing.
fn write_then_read(with_barrier: bool) -> Vec<String> {
    let ctx = Context::new(&ContextOptions { validation: Validation::Required, ..Default::default() }).unwrap();
    assert!(ctx.sync_validation_enabled(), "the validation layer offers VK_EXT_validation_features");
    let log = ctx.validation_log();
    {
        let writer = ctx.create_kernel(trilab::kernels::find_no_intersector("rng_probe", "main")).unwrap();
        let reader = ctx.create_kernel(trilab::kernels::raycast(trilab::encoding::Method::Mt, false)).unwrap();
        let mesh = common::bunny();
        let bvh = trilab::bvh::Bvh::build(&mesh, &trilab::bvh::BuildOptions::new(4));
        let scene = trilab::gpu::GpuScene::upload(&ctx, &trilab::encoding::Method::Mt.encode(&mesh, &bvh)).unwrap();
        const N: u32 = 64;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let gpu = gpu_allocator::MemoryLocation::GpuOnly;
        let shared = ctx.create_buffer("written then read", N as u64 * 32, usage, gpu).unwrap();
        let hits = ctx.create_buffer("hits", N as u64 * 16, usage, gpu).unwrap();
        let mut reader_res: Vec<(u32, Resource)> = scene.resources().collect();
        reader_res.push((BINDING_RAYS, Resource::whole(&shared)));
        reader_res.push((BINDING_HITS, Resource::whole(&hits)));
        let writer_res = [(BINDING_RNG_PROBE_OUT, Resource::whole(&shared))];
        let push_w: Vec<u8> = [1u32, N].iter().flat_map(|x| x.to_le_bytes()).collect();
        ctx.dispatch_chain(
            &[
                (&writer, &writer_res, &push_w, N / 64),
                (&reader, &reader_res, &N.to_le_bytes(), N.div_ceil(reader.layout.local_size.0)),
            ],
            with_barrier,
        )
        .unwrap();
    }
    drop(ctx);
    log.messages()
}

#[test]
fn a_missing_barrier_is_reported_as_a_sync_hazard() {
    let messages = write_then_read(false);
    assert!(
        messages.iter().any(|m| m.contains("SYNC-HAZARD-READ-AFTER-WRITE")),
        "synchronization validation did not see the missing barrier: {messages:#?}"
    );
    let clean = write_then_read(true);
    assert!(clean.is_empty(), "with the barrier: {clean:#?}");
}
