//! The traversal roofline's kernel (`glsl/roofline.comp`): a pointer chase through 32-byte nodes
//! shaped like a traversal step, read three ways ([`RooflineAccess`]), timed with GPU
//! timestamps; the node buffer it walks ([`nodes`]) and the same walk on the CPU
//! ([`reference`]), which its checksums equal bit for bit. `services::roofline` sweeps it over
//! working-set sizes (`trilab roofline`).

use std::mem::size_of;
use std::time::Instant;

use ash::vk;
use gpu_allocator::MemoryLocation;

use super::accel::device_address;
use super::buffer::{Buffer, TexelBuffer};
use super::commands::memory_barrier;
use super::context::Context;
use super::descriptors::{write_set, DescriptorPool, Resource};
use super::kernel::Kernel;
use super::timestamps::Timestamps;
use crate::encoding::DeviceLimits;
use crate::error::{Error, Result};
use crate::kernels::{KernelSource, NO_INTERSECTOR};
use crate::named::{named_enum, Named};
use crate::shared::{Texel, BINDING_NODES, BINDING_ROOFLINE_OUT, WORKGROUP_SIZE};

named_enum! {
    /// How the roofline kernel reads its nodes (`glsl/roofline.comp`'s variants).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum RooflineAccess: "access path" {
        /// A storage texel buffer read with imageLoad (the scene's texel path).
        Texel = "texel",
        /// A readonly storage buffer of uvec4.
        Storage = "storage",
        /// GL_EXT_buffer_reference through the buffer's device address, a 16-byte texel as two
        /// 64-bit words (the scene's address path).
        Address = "address",
        /// The same, a texel as one uvec4 of four 32-bit words (the address path's form before
        /// issue 27: llvmpipe gathers once per component).
        Address32 = "address32",
    }
}

impl RooflineAccess {
    /// The kernel variant reading nodes this way.
    pub fn kernel(self) -> Result<&'static KernelSource> {
        crate::kernels::find("roofline", NO_INTERSECTOR, self.name())
            .ok_or_else(|| Error::Usage(format!("roofline has no variant `{self}` (rebuild trilab)")))
    }

    /// The probe of a scene's access path.
    pub fn of_scene(path: crate::encoding::AccessPath) -> RooflineAccess {
        match path {
            crate::encoding::AccessPath::Texel => RooflineAccess::Texel,
            crate::encoding::AccessPath::Address => RooflineAccess::Address,
            crate::encoding::AccessPath::Storage => RooflineAccess::Storage,
        }
    }
}

/// One node as the kernel reads it: two 16-byte texels, as bvh2's `BvhNode` (box min and a word,
/// box max and a word). The words are the next node's index when the box is missed
/// (`next_miss`, one random cycle through every node) and when it is hit (`next_hit`, random).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct RooflineNode {
    pub min: [f32; 3],
    pub next_miss: u32,
    pub max: [f32; 3],
    pub next_hit: u32,
}

/// `Push` in `glsl/roofline.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct RooflinePush {
    /// Nodes - 1 (the node count is a power of two).
    pub mask: u32,
    /// Dependent steps per invocation.
    pub steps: u32,
    /// Invocations.
    pub count: u32,
    /// Seed of the start indices and the ray state.
    pub seed: u32,
}

const _: () = assert!(size_of::<RooflineNode>() == 32);
const _: () = assert!(size_of::<RooflinePush>() == 16);

/// Bytes of one node: the unit of a working set.
pub const NODE_BYTES: u64 = size_of::<RooflineNode>() as u64;

/// lowbias32 (C. Wellons, 2018): `roofline_hash` in the kernel.
pub fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// A small deterministic generator for the node buffer (splitmix64).
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (n > 0; the bias of a 64-bit modulo is far below anything measured).
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// `count` nodes (a power of two, at least 2) for `seed`: `next_miss` makes one cycle through
/// every node (Sattolo's shuffle), `next_hit` is a random node; the boxes lie on a 2^-16 grid in
/// [0, 1.5)^3, each side 2^-16 to 0.5 long.
pub fn nodes(count: usize, seed: u64) -> Result<Vec<RooflineNode>> {
    if count < 2 || !count.is_power_of_two() || count > 1 << 30 {
        return Err(Error::Usage(format!("roofline: {count} nodes; the count must be a power of two from 2 to 2^30")));
    }
    let mut rng = SplitMix(seed ^ 0x726F_6F66_6C69_6E65);
    let mut cycle: Vec<u32> = (0..count as u32).collect();
    for i in (1..count).rev() {
        let j = rng.below(i as u64) as usize;
        cycle.swap(i, j);
    }
    // `cycle` is now one cycle as a permutation: node i's successor is cycle[i].
    let grid = |k: u64| k as f32 * (1.0 / 65536.0);
    Ok(cycle
        .iter()
        .map(|&next_miss| {
            let mut min = [0.0f32; 3];
            let mut max = [0.0f32; 3];
            for a in 0..3 {
                let lo = rng.below(65536);
                let side = 1 + rng.below(32768);
                min[a] = grid(lo);
                max[a] = grid(lo + side);
            }
            RooflineNode { min, next_miss, max, next_hit: rng.below(count as u64) as u32 }
        })
        .collect())
}

/// Invocation `i`'s checksum: the kernel's walk on the CPU, operation for operation (each float
/// operation exact or one correctly rounded product, so the GPU's must be equal bit for bit).
/// `nodes` holds `push.mask + 1` nodes, as [`reference`] checks (every index is masked, so a
/// shorter buffer would be read past its end).
pub fn reference_one(nodes: &[RooflineNode], push: &RooflinePush, i: u32) -> u32 {
    let base = hash(i ^ hash(push.seed));
    let h: Vec<u32> = (0..7u32).map(|j| hash(base.wrapping_add(j.wrapping_mul(0x9E37_79B9)))).collect();
    let o: [f32; 3] = std::array::from_fn(|a| ((h[1 + a] >> 16) as f32 + 0.5) * (1.0 / 65536.0));
    let inv: [f32; 3] = std::array::from_fn(|a| {
        let mag = (h[4 + a] & 0xFFF) as f32 + 256.0;
        let signed = if h[4 + a] >> 31 != 0 { -mag } else { mag };
        signed * (1.0 / 1024.0)
    });
    let (tmin, tmax) = (0.0f32, 64.0f32);
    let (mut hit_near, mut hit_far, mut miss_near, mut miss_far) = (f32::MAX, -f32::MAX, f32::MAX, -f32::MAX);
    let mut node = h[0] & push.mask;
    let mut acc = base;
    for _ in 0..push.steps {
        let n = &nodes[node as usize];
        let t0: [f32; 3] = std::array::from_fn(|a| (n.min[a] - o[a]) * inv[a]);
        let t1: [f32; 3] = std::array::from_fn(|a| (n.max[a] - o[a]) * inv[a]);
        let near: [f32; 3] = std::array::from_fn(|a| t0[a].min(t1[a]));
        let far: [f32; 3] = std::array::from_fn(|a| t0[a].max(t1[a]));
        let tn = near[0].max(near[1]).max(near[2].max(tmin));
        let tf = far[0].min(far[1]).min(far[2].min(tmax));
        let hit = tn <= tf;
        if hit {
            hit_near = hit_near.min(tn);
            hit_far = hit_far.max(tf);
        } else {
            miss_near = miss_near.min(tn);
            miss_far = miss_far.max(tf);
        }
        node = if hit { n.next_hit } else { n.next_miss } & push.mask;
        acc = (acc ^ node).wrapping_mul(0x0100_0193);
    }
    for f in [hit_near, hit_far, miss_near, miss_far] {
        acc = hash(acc ^ f.to_bits());
    }
    acc
}

/// Every invocation's checksum ([`reference_one`]) for `push.count` invocations over `nodes`
/// (`push.mask` + 1 of them).
pub fn reference(nodes: &[RooflineNode], push: &RooflinePush) -> Result<Vec<u32>> {
    if nodes.len() != push.mask as usize + 1 {
        return Err(Error::Usage(format!("roofline: {} nodes given for mask {:#x}", nodes.len(), push.mask)));
    }
    Ok((0..push.count).map(|i| reference_one(nodes, push, i)).collect())
}

/// Why a working set of `bytes` cannot be read `access`'s way within `limits` (a device's,
/// `Context::limits`, lowered by `TRILAB_TEST_LIMITS` in tests); `None`: it can.
pub fn unsupported(limits: &DeviceLimits, access: RooflineAccess, bytes: u64) -> Option<String> {
    let texels = bytes / 16;
    match access {
        RooflineAccess::Texel if texels > limits.max_texel_buffer_elements => {
            Some(format!("{texels} texels, more than maxTexelBufferElements ({})", limits.max_texel_buffer_elements))
        }
        RooflineAccess::Storage if bytes > limits.max_storage_buffer_range => {
            Some(format!("{bytes} bytes, more than maxStorageBufferRange ({})", limits.max_storage_buffer_range))
        }
        RooflineAccess::Address | RooflineAccess::Address32 if !limits.buffer_device_address => {
            Some("bufferDeviceAddress is not enabled on this device".into())
        }
        // The kernel's texel indices are 32-bit, and SPIR-V's access-chain indices signed.
        RooflineAccess::Address | RooflineAccess::Address32 if texels > i32::MAX as u64 => {
            Some(format!("{texels} texels, more than 2^31 - 1"))
        }
        _ => None,
    }
}

/// A node buffer on the device, bound every way this device can read it.
pub struct RooflineData {
    /// Nodes (a power of two).
    pub nodes: u64,
    /// The texel view where the texel path can read it; else the plain buffer.
    store: Store,
    /// A uniform buffer holding the buffer's device address (the address path), where enabled.
    pointer: Option<Buffer>,
    /// The ways it cannot be read, and why.
    pub unsupported: Vec<(RooflineAccess, String)>,
}

enum Store {
    Texels(TexelBuffer),
    Plain(Buffer),
}

impl RooflineData {
    fn buffer(&self) -> &Buffer {
        match &self.store {
            Store::Texels(t) => &t.buffer,
            Store::Plain(b) => b,
        }
    }

    /// Bytes on the device (the working set).
    pub fn bytes(&self) -> u64 {
        self.nodes * NODE_BYTES
    }

    /// Why `access` cannot read it, if it cannot.
    pub fn why_not(&self, access: RooflineAccess) -> Option<&str> {
        self.unsupported.iter().find(|(a, _)| *a == access).map(|(_, w)| w.as_str())
    }

    fn resource(&self, access: RooflineAccess) -> Result<Resource<'_>> {
        if let Some(why) = self.why_not(access) {
            return Err(Error::Unsupported(format!("roofline {access} path: {why}")));
        }
        Ok(match (access, &self.store, &self.pointer) {
            (RooflineAccess::Texel, Store::Texels(t), _) => Resource::Texels(t),
            (RooflineAccess::Storage, _, _) => Resource::whole(self.buffer()),
            (RooflineAccess::Address | RooflineAccess::Address32, _, Some(p)) => Resource::whole(p),
            _ => return Err(Error::Unsupported(format!("roofline {access} path: not bound"))),
        })
    }
}

/// Uploads `nodes` once, with every usage the device allows for its size: a texel view, storage
/// buffer usage, and a device address.
pub fn upload(ctx: &Context, name: &str, nodes: &[RooflineNode]) -> Result<RooflineData> {
    let count = nodes.len() as u64;
    let bytes = count * NODE_BYTES;
    let limits = ctx.limits()?;
    let mut unsupported: Vec<(RooflineAccess, String)> =
        RooflineAccess::ALL.iter().filter_map(|&a| unsupported(&limits, a, bytes).map(|w| (a, w))).collect();
    // The 64-bit words of the address path (a device limit does not say it; the features do:
    // gpu::Capabilities). The address32 form loads 32-bit words and needs no shaderInt64.
    if let Err(u) = ctx.capabilities().access(crate::encoding::AccessPath::Address) {
        if !unsupported.iter().any(|(a, _)| *a == RooflineAccess::Address) {
            unsupported.push((RooflineAccess::Address, u.why));
        }
    }
    let can = |a: RooflineAccess| !unsupported.iter().any(|(u, _)| *u == a);
    let addressed = can(RooflineAccess::Address) || can(RooflineAccess::Address32);
    let mut usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    if can(RooflineAccess::Texel) {
        usage |= vk::BufferUsageFlags::STORAGE_TEXEL_BUFFER;
    }
    if addressed {
        usage |= vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
    }
    let buffer = ctx.upload(name, bytemuck::cast_slice(nodes), usage)?;
    let pointer = match addressed {
        true => {
            let address = device_address(ctx, &buffer);
            // `uniform NodesAddress { RooflineTexels nodes; }` (std140): the 8-byte address.
            Some(ctx.upload(
                &format!("{name} (address)"),
                &address.to_le_bytes(),
                vk::BufferUsageFlags::UNIFORM_BUFFER,
            )?)
        }
        false => None,
    };
    let store = match can(RooflineAccess::Texel) {
        true => Store::Texels(ctx.texel_view(name, buffer, Texel::Rgba32Uint)?),
        false => Store::Plain(buffer),
    };
    Ok(RooflineData { nodes: count, store, pointer, unsupported })
}

/// The kernel reading nodes `access`'s way, created once per context.
pub fn kernel(ctx: &Context, access: RooflineAccess) -> Result<std::sync::Arc<Kernel>> {
    ctx.kernel(access.kernel()?)
}

/// What one [`run`] measured.
#[derive(Clone, Debug)]
pub struct RooflineTimes {
    /// GPU time of each timed dispatch, milliseconds (timestamps; host wall time where the
    /// device has none: `timed_on_gpu` false).
    pub ms: Vec<f64>,
    pub timed_on_gpu: bool,
    /// The checksums of the last dispatch, when asked for.
    pub checksums: Option<Vec<u32>>,
}

/// Runs the walk over `data` `access`'s way with `push` (`push.mask` must be its nodes - 1):
/// `warmup` untimed dispatches, then `repeat` timed ones, each its own submit; the checksums of
/// the last when `checksums`.
pub fn run(
    ctx: &Context,
    data: &RooflineData,
    access: RooflineAccess,
    push: &RooflinePush,
    warmup: usize,
    repeat: usize,
    checksums: bool,
) -> Result<RooflineTimes> {
    if push.mask as u64 + 1 != data.nodes {
        return Err(Error::Usage(format!("roofline: mask {:#x} for {} nodes", push.mask, data.nodes)));
    }
    let kernel = kernel(ctx, access)?;
    let groups = push.count.div_ceil(WORKGROUP_SIZE);
    let most = ctx.info().max_compute_workgroup_count[0];
    if push.count == 0 || groups > most {
        return Err(Error::Usage(format!(
            "roofline: {} invocations; one dispatch holds 1 to {} on this device",
            push.count,
            most as u64 * WORKGROUP_SIZE as u64
        )));
    }
    let out_bytes = push.count as u64 * 4;
    let out = ctx.create_buffer(
        "roofline checksums",
        out_bytes,
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryLocation::GpuOnly,
    )?;
    let (_pool, sets) = DescriptorPool::new(ctx, &*kernel, 1)?;
    let resources = [(BINDING_NODES, data.resource(access)?), (BINDING_ROOFLINE_OUT, Resource::whole(&out))];
    write_set(ctx, &*kernel, sets[0], &resources)?;
    let timestamps = Timestamps::supported(ctx);
    let queries = Timestamps::new(ctx, 1)?;
    let what = format!("{} ({} nodes, {} invocations x {} steps)", kernel.name, data.nodes, push.count, push.steps);
    let mut ms = vec![];
    for run in 0..warmup + repeat.max(1) {
        let t0 = Instant::now();
        ctx.one_shot(&what, |d, cmd| {
            // SAFETY: `cmd` is recording; the pipeline, the set, the buffers it binds and the
            // query pool outlive one_shot's wait.
            unsafe {
                queries.reset(d, cmd, 0);
                // The previous run's dispatch wrote the same checksums (and the uploads came before).
                memory_barrier(
                    d,
                    cmd,
                    (
                        vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
                        vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE,
                    ),
                    (
                        vk::PipelineStageFlags::COMPUTE_SHADER,
                        vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
                    ),
                );
                let marker = ctx.mark_begin(d, cmd, what.clone());
                queries.start(d, cmd, 0);
                kernel.record(d, cmd, sets[0], bytemuck::bytes_of(push), groups);
                queries.end(d, cmd, 0);
                ctx.mark_end(d, cmd, marker);
            }
        })?;
        let wall = t0.elapsed().as_secs_f64() * 1e3;
        if run < warmup {
            continue;
        }
        ms.push(if timestamps { queries.read_ms()?[0] } else { wall });
    }
    let checksums = match checksums {
        true => Some(bytemuck::cast_slice::<u8, u32>(&ctx.download(&out, out_bytes)?).to_vec()),
        false => None,
    };
    Ok(RooflineTimes { ms, timed_on_gpu: timestamps, checksums })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_miss_words_make_one_cycle_through_every_node() {
        for count in [2usize, 8, 1024] {
            let n = nodes(count, 7).unwrap();
            let mut seen = vec![false; count];
            let mut i = 0usize;
            for _ in 0..count {
                assert!(!seen[i], "{count} nodes: node {i} visited twice before the cycle closed");
                seen[i] = true;
                i = n[i].next_miss as usize;
            }
            assert_eq!(i, 0, "{count} nodes: the walk did not return to its start");
            assert!(n.iter().all(|x| (x.next_hit as usize) < count));
            assert!(n.iter().all(|x| (0..3).all(|a| x.min[a] < x.max[a] && x.max[a] < 1.5)));
        }
        assert!(nodes(6, 1).is_err());
        assert!(nodes(1, 1).is_err());
        assert_eq!(nodes(64, 3).unwrap(), nodes(64, 3).unwrap());
        assert_ne!(nodes(64, 3).unwrap(), nodes(64, 4).unwrap());
    }

    #[test]
    fn the_walk_both_hits_and_misses_and_depends_on_every_input() {
        let n = nodes(256, 1).unwrap();
        let push = RooflinePush { mask: 255, steps: 64, count: 512, seed: 9 };
        // Count the outcomes on a hand-written slab test of each visited node (not the
        // reference's code path): the walk must take both words.
        let mut hits = 0;
        let mut steps = 0;
        for i in 0..push.count {
            let base = hash(i ^ hash(push.seed));
            let h = |j: u32| hash(base.wrapping_add(j.wrapping_mul(0x9E37_79B9)));
            let o: Vec<f64> = (1..4).map(|j| ((h(j) >> 16) as f64 + 0.5) / 65536.0).collect();
            let d: Vec<f64> = (4..7)
                .map(|j| {
                    let m = ((h(j) & 0xFFF) as f64 + 256.0) / 1024.0;
                    if h(j) >> 31 != 0 {
                        -1.0 / m
                    } else {
                        1.0 / m
                    }
                })
                .collect();
            let mut node = (h(0) & push.mask) as usize;
            for _ in 0..push.steps {
                let x = &n[node];
                // The box is hit when some t in [0, 64] puts o + t d inside it on every axis.
                let (mut lo, mut hi) = (0.0f64, 64.0f64);
                for a in 0..3 {
                    let t0 = (x.min[a] as f64 - o[a]) / d[a];
                    let t1 = (x.max[a] as f64 - o[a]) / d[a];
                    lo = lo.max(t0.min(t1));
                    hi = hi.min(t0.max(t1));
                }
                let hit = lo <= hi;
                hits += hit as usize;
                steps += 1;
                node = (if hit { x.next_hit } else { x.next_miss } & push.mask) as usize;
            }
        }
        assert!(hits > steps / 20 && hits < steps * 19 / 20, "{hits} hits of {steps} steps");
        let r = reference(&n, &push).unwrap();
        assert_eq!(r.len(), 512);
        // Distinct invocations, seeds, step counts and node buffers give other checksums.
        assert!(r.iter().collect::<std::collections::BTreeSet<_>>().len() > 500);
        assert_ne!(r, reference(&n, &RooflinePush { seed: 10, ..push }).unwrap());
        assert_ne!(r, reference(&n, &RooflinePush { steps: 63, ..push }).unwrap());
        assert_ne!(r, reference(&nodes(256, 2).unwrap(), &push).unwrap());
        assert!(reference(&n, &RooflinePush { mask: 127, ..push }).is_err());
    }
}
