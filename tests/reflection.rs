//! Host structs against the kernels' SPIR-V: at every binding, the array stride and element
//! member offsets the kernel declares must equal the Rust `#[repr(C)]` layout the host writes
//! there; and every kernel's bindings, push constants and workgroup size must be what the host
//! binds and dispatches.

use std::mem::{offset_of, size_of};

use ash::vk;
use trilab::bvh::BvhNode;
use trilab::encoding::{AccessPath, Method, Raycast};
use trilab::gpu::roofline::RooflinePush;
use trilab::gpu::TraversalCounts;
use trilab::kernels::KERNELS;
use trilab::named::Named;
use trilab::rays::{Hit, Ray};
use trilab::render::bsdf::{ProbeIn, ProbeOut, ProbePush};
use trilab::render::{GpuParams, PathtracePush};
use trilab::shared::*;
use trilab::spirv::reflect::{buffer_layouts, reflect, BufferLayout};

/// The registry's method whose intersector is `glsl/intersect/<glsl>.glsl`.
fn method_of(glsl: &str) -> Option<Method> {
    Method::ALL.into_iter().find(|m| m.glsl_name() == glsl)
}

/// The scene bindings `method`'s encoding provides (nodes, slot ids, its primitive buffers).
fn scene_bindings(method: Method) -> Vec<u32> {
    let mesh = trilab::scene::Mesh::from_triangles(vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]]);
    let bvh = trilab::bvh::Bvh::build(&mesh, &trilab::bvh::BuildOptions::new(4));
    method.encode(&mesh, &bvh).buffers().iter().map(|b| b.binding).collect()
}

/// The texel size of a scene binding read as a storage buffer (the `*_storage` variants, issue 38:
/// `SCENE_STORAGE` in glsl/types.glsl declares each an array of its texels, uvec4 or uint), or
/// `None` where the binding is no scene buffer: the encoding's texel for its buffers, a vec4 for
/// the path tracer's shading records and lights.
fn storage_texel_size(method: Option<Method>, binding: u32) -> Option<usize> {
    if binding == BINDING_SHADING || binding == BINDING_LIGHTS {
        return Some(16);
    }
    let mesh = trilab::scene::Mesh::from_triangles(vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]]);
    let bvh = trilab::bvh::Bvh::build(&mesh, &trilab::bvh::BuildOptions::new(4));
    method?.encode(&mesh, &bvh).buffers().iter().find(|b| b.binding == binding).map(|b| b.texel.size())
}

fn array_of(size: usize, offsets: &[usize]) -> BufferLayout {
    BufferLayout { array_stride: Some(size as u32), member_offsets: offsets.iter().map(|&o| o as u32).collect() }
}

/// What the host writes at (raycast) or reads from (probe) each storage-buffer binding.
fn host_layout(method: &str, binding: u32, storage: bool) -> BufferLayout {
    let node = || {
        array_of(
            size_of::<BvhNode>(),
            &[
                offset_of!(BvhNode, min),
                offset_of!(BvhNode, left_or_first),
                offset_of!(BvhNode, max),
                offset_of!(BvhNode, count),
            ],
        )
    };
    match (method, binding) {
        (_, BINDING_RAYS) => array_of(
            size_of::<Ray>(),
            &[offset_of!(Ray, origin), offset_of!(Ray, tmin), offset_of!(Ray, dir), offset_of!(Ray, tmax)],
        ),
        (_, BINDING_HITS) => array_of(
            size_of::<Hit>(),
            &[offset_of!(Hit, t), offset_of!(Hit, id), offset_of!(Hit, u), offset_of!(Hit, v)],
        ),
        (_, BINDING_TRAVERSAL_STATS) => array_of(
            size_of::<TraversalCounts>(),
            &[
                offset_of!(TraversalCounts, inner),
                offset_of!(TraversalCounts, leaves),
                offset_of!(TraversalCounts, triangles),
                offset_of!(TraversalCounts, slots),
                offset_of!(TraversalCounts, boxes),
                offset_of!(TraversalCounts, alone),
            ],
        ),
        (_, BINDING_PROBE_NODES) => node(),
        (_, BINDING_PROBE_SLOT_IDS) => array_of(size_of::<u32>(), &[]),
        // The method's primitive struct, as its Rust file declares it (the registry's
        // `Intersector::prim_struct`).
        (glsl, BINDING_PROBE_PRIMS) if method_of(glsl).is_some() => {
            let l = method_of(glsl).unwrap().intersector().prim_struct;
            array_of(l.size, l.offsets)
        }
        // raycast's `*_address` variants: each scene binding is a uniform block holding the scene
        // buffer's 8-byte device address (gpu::raycast uploads `address.to_le_bytes()`).
        // roofline's `storage` variant: the nodes as uvec4 texels, two per `RooflineNode`.
        ("none", BINDING_NODES) if storage => BufferLayout { array_stride: Some(16), member_offsets: vec![] },
        (_, BINDING_NODES | BINDING_SLOT_IDS | BINDING_PRIMS | BINDING_INDICES) => {
            BufferLayout { array_stride: None, member_offsets: vec![0] }
        }
        (_, BINDING_PARAMS) => BufferLayout {
            array_stride: None,
            member_offsets: [
                offset_of!(GpuParams, cam_eye),
                offset_of!(GpuParams, cam_right),
                offset_of!(GpuParams, cam_up),
                offset_of!(GpuParams, cam_forward),
                offset_of!(GpuParams, env),
                offset_of!(GpuParams, width),
                offset_of!(GpuParams, height),
                offset_of!(GpuParams, max_depth),
                offset_of!(GpuParams, rr_depth),
                offset_of!(GpuParams, seed),
                offset_of!(GpuParams, light_count),
                offset_of!(GpuParams, ray_eps),
                offset_of!(GpuParams, scene_extent),
                offset_of!(GpuParams, sky_zenith),
                offset_of!(GpuParams, sky_horizon),
                offset_of!(GpuParams, sun_dir),
                offset_of!(GpuParams, sun_radiance),
            ]
            .iter()
            .map(|&o| o as u32)
            .collect(),
        },
        (_, BINDING_ACCUM) => array_of(size_of::<[f32; 4]>(), &[]),
        // rng_probe: draws as uvec4 bits, then as vec4 floats (read back as words in tests/render.rs).
        ("none", BINDING_RNG_PROBE_OUT) => array_of(32, &[0, 16]),
        // subgroup_probe: eleven uvec4 per invocation (read back as words in tests/subgroup_probe.rs),
        // its input words uvec4.
        ("none", BINDING_SUBGROUP_PROBE_OUT) => array_of(176, &(0..11).map(|m| 16 * m).collect::<Vec<_>>()),
        ("none", BINDING_SUBGROUP_PROBE_WORDS) => array_of(16, &[]),
        (_, BINDING_STATS) => array_of(size_of::<u32>(), &[]),
        // raycast's `clock` variants: shader-clock ticks per ray, read back as u32.
        (glsl, BINDING_CYCLES) if method_of(glsl).is_some() => array_of(size_of::<u32>(), &[]),
        // raycast_persistent's next-ray counter: one u32 (gpu::raycast zeroes 4 bytes).
        (glsl, BINDING_RAY_COUNTER) if method_of(glsl).is_some() => {
            BufferLayout { array_stride: None, member_offsets: vec![0] }
        }
        ("none", BINDING_BSDF_PROBE_IN) => array_of(
            size_of::<ProbeIn>(),
            &[offset_of!(ProbeIn, wo), offset_of!(ProbeIn, material), offset_of!(ProbeIn, v), offset_of!(ProbeIn, pad)],
        ),
        ("none", BINDING_BSDF_PROBE_OUT) => array_of(
            size_of::<ProbeOut>(),
            &[
                offset_of!(ProbeOut, wi),
                offset_of!(ProbeOut, pdf),
                offset_of!(ProbeOut, weight),
                offset_of!(ProbeOut, flags),
                offset_of!(ProbeOut, f),
                offset_of!(ProbeOut, eval_pdf),
            ],
        ),
        // roofline: one checksum per invocation (gpu::roofline::run reads them back as u32).
        ("none", BINDING_ROOFLINE_OUT) => array_of(size_of::<u32>(), &[]),
        (m, b) => panic!("no host layout for storage-buffer binding {b} of method {m}"),
    }
}

/// Push constants: the raycast kernels take the ray count (`u32`); probe takes three counts;
/// bsdf_probe a `ProbePush` (mode, count).
fn host_push(kernel: &str) -> Vec<u32> {
    match kernel {
        "raycast" | "raycast_coop" | "raycast_persistent" | "raycast_packet" | "rayquery" => vec![0],
        "probe" => vec![0, 4, 8],
        "pathtrace" => vec![
            offset_of!(PathtracePush, sample_first) as u32,
            offset_of!(PathtracePush, sample_count) as u32,
            offset_of!(PathtracePush, pixel_first) as u32,
            offset_of!(PathtracePush, pixel_count) as u32,
        ],
        "rng_probe" => vec![0, 4],
        "subgroup_probe" => vec![0, 4],
        "bsdf_probe" => {
            vec![offset_of!(ProbePush, mode) as u32, offset_of!(ProbePush, count) as u32]
        }
        "roofline" => [
            offset_of!(RooflinePush, mask),
            offset_of!(RooflinePush, steps),
            offset_of!(RooflinePush, count),
            offset_of!(RooflinePush, seed),
        ]
        .iter()
        .map(|&o| o as u32)
        .collect(),
        k => panic!("unknown kernel {k}"),
    }
}

#[test]
fn rust_structs_match_spirv_offsets_and_strides() {
    let mut checked_structs = 0;
    for k in KERNELS {
        let layouts = buffer_layouts(&k.words()).unwrap();
        for (&binding, spirv) in &layouts {
            if binding == u32::MAX {
                assert_eq!(spirv.member_offsets, host_push(k.kernel), "{}: push constants", k.name);
                continue;
            }
            let sb = k.variant.contains("_storage");
            let host = match storage_texel_size(method_of(k.intersector), binding).filter(|_| sb) {
                Some(texel) => array_of(texel, &[]),
                None => host_layout(k.intersector, binding, k.kernel == "roofline" && k.variant == "storage"),
            };
            assert_eq!(spirv, &host, "{}: binding {binding}: SPIR-V declares {spirv:?}, host uses {host:?}", k.name);
            checked_structs += !host.member_offsets.is_empty() as usize;
        }
    }
    // Guard against a vacuous pass: Ray and Hit in every raycast kernel, BvhNode and the
    // primitive struct in every probe kernel, ProbeIn and ProbeOut in bsdf_probe; pathtrace:
    // the Params block (its other buffers are arrays of vectors and scalars).
    // rng_probe: its one output struct. The raycast `stats` variants add TraversalCounts.
    let expected: usize = KERNELS
        .iter()
        .map(|k| match (k.kernel, k.variant) {
            ("pathtrace" | "rng_probe" | "subgroup_probe", _) => 1,
            // roofline: its push constants only (nodes are uvec4 texels, checksums u32).
            ("roofline", _) => 0,
            ("raycast" | "raycast_coop" | "raycast_packet", v) if v.starts_with("stats") => 3,
            _ => 2,
        })
        .sum();
    assert!(checked_structs >= expected, "only {checked_structs} of {expected} struct layouts checked");
}

#[test]
fn kernels_bind_what_the_host_provides() {
    for k in KERNELS {
        let l = reflect(k.name, &k.words()).unwrap();
        assert_eq!(l.local_size, (WORKGROUP_SIZE, 1, 1), "{}", k.name);
        let push_bytes = match k.kernel {
            "bsdf_probe" => size_of::<ProbePush>() as u32,
            "roofline" => size_of::<RooflinePush>() as u32,
            _ => 4 * host_push(k.kernel).len() as u32,
        };
        assert_eq!(l.push_constants, Some((0, push_bytes)), "{}: push constants", k.name);
        assert_eq!(l.sets.keys().copied().collect::<Vec<_>>(), vec![0], "{}", k.name);
        let set = &l.sets[&0];
        let method = method_of(k.intersector);
        // The scene bindings of the method's encoding (watertight and f64 read MT's buffers).
        let scene = method.map(scene_bindings).unwrap_or_default();
        let texels = match (k.kernel, method) {
            // The BSDF probe reads only materials.
            ("bsdf_probe", _) => vec![BINDING_MATERIALS],
            ("rng_probe", _) => vec![],
            ("subgroup_probe", _) => vec![BINDING_SUBGROUP_PROBE_TEXELS],
            // roofline's nodes: a texel buffer, a storage buffer or an address (below).
            ("roofline", _) => vec![BINDING_NODES],
            ("raycast" | "raycast_coop" | "raycast_persistent" | "raycast_packet", Some(_)) => scene,
            // The driver's structure replaces ours; the BLAS primitive -> OBJ id table remains.
            ("rayquery", _) => vec![BINDING_SLOT_IDS],
            // The path tracer shades by slot and never reads the slot -> OBJ id table.
            ("pathtrace", Some(_)) => scene
                .into_iter()
                .filter(|&b| b != BINDING_SLOT_IDS)
                .chain([BINDING_MATERIALS, BINDING_SHADING, BINDING_LIGHTS])
                .collect(),
            // The probe loads nodes, slot ids and the primitive structs (for MT's layout the
            // index triples, not the vertices).
            ("probe", Some(m)) => vec![BINDING_NODES, BINDING_SLOT_IDS, m.intersector().prim_binding],
            (kernel, m) => panic!("{}: unknown kernel {kernel} (method {m:?})", k.name),
        };
        let accels = if k.kernel == "rayquery" { vec![BINDING_TLAS] } else { vec![] };
        let buffers = match (k.kernel, k.variant) {
            ("raycast" | "raycast_coop" | "raycast_packet", v) if v.starts_with("stats") => {
                vec![BINDING_RAYS, BINDING_HITS, BINDING_TRAVERSAL_STATS]
            }
            ("raycast", v) if v.starts_with("clock") => vec![BINDING_RAYS, BINDING_HITS, BINDING_CYCLES],
            ("raycast_persistent", _) => vec![BINDING_RAYS, BINDING_HITS, BINDING_RAY_COUNTER],
            ("raycast" | "raycast_coop" | "raycast_packet" | "rayquery", _) => vec![BINDING_RAYS, BINDING_HITS],
            ("pathtrace", _) => vec![BINDING_PARAMS, BINDING_ACCUM, BINDING_STATS],
            ("bsdf_probe", _) => vec![BINDING_BSDF_PROBE_IN, BINDING_BSDF_PROBE_OUT],
            ("rng_probe", _) => vec![BINDING_RNG_PROBE_OUT],
            ("subgroup_probe", _) => vec![BINDING_SUBGROUP_PROBE_OUT, BINDING_SUBGROUP_PROBE_WORDS],
            ("roofline", _) => vec![BINDING_ROOFLINE_OUT],
            _ => vec![BINDING_PROBE_NODES, BINDING_PROBE_PRIMS, BINDING_PROBE_SLOT_IDS],
        };
        let mut expected: Vec<u32> = texels.iter().chain(&buffers).chain(&accels).copied().collect();
        expected.sort();
        assert_eq!(set.keys().copied().collect::<Vec<_>>(), expected, "{} bindings", k.name);
        for (b, d) in set {
            let want = if k.kernel == "roofline" && *b == BINDING_NODES {
                match k.variant {
                    "texel" => vk::DescriptorType::STORAGE_TEXEL_BUFFER,
                    "storage" => vk::DescriptorType::STORAGE_BUFFER,
                    "address" | "address32" => vk::DescriptorType::UNIFORM_BUFFER,
                    v => panic!("{}: unknown roofline variant {v}", k.name),
                }
            } else if texels.contains(b) && k.variant.contains("_address") {
                // The address path: a uniform block holding the buffer's device address.
                vk::DescriptorType::UNIFORM_BUFFER
            } else if texels.contains(b) && k.variant.contains("_storage") && *b != BINDING_MATERIALS {
                // The storage path: the scene (and the path tracer's shading and lights) in
                // storage buffers; materials stay a texel buffer.
                vk::DescriptorType::STORAGE_BUFFER
            } else if texels.contains(b) {
                vk::DescriptorType::STORAGE_TEXEL_BUFFER
            } else if accels.contains(b) {
                vk::DescriptorType::ACCELERATION_STRUCTURE_KHR
            } else if *b == BINDING_PARAMS {
                vk::DescriptorType::UNIFORM_BUFFER
            } else {
                vk::DescriptorType::STORAGE_BUFFER
            };
            assert_eq!(d.ty, want, "{}: binding {b}", k.name);
        }
    }
}

#[test]
fn every_encoding_provides_every_scene_binding_its_kernels_read() {
    let mesh = trilab::scene::Mesh::from_triangles(vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]]);
    let bvh = trilab::bvh::Bvh::build(&mesh, &trilab::bvh::BuildOptions::new(4));
    for m in Method::ALL {
        let provided: Vec<u32> = m.encode(&mesh, &bvh).buffers().iter().map(|b| b.binding).collect();
        for k in [Raycast::Closest, Raycast::Any, Raycast::Stats].map(|kind| m.raycast_kernel(kind, AccessPath::Texel))
        {
            let l = reflect(k.name, &k.words()).unwrap();
            let per_ray = [BINDING_RAYS, BINDING_HITS, BINDING_TRAVERSAL_STATS];
            for b in l.sets[&0].keys().filter(|b| !per_ray.contains(b)) {
                assert!(provided.contains(b), "{}: binding {b} not provided by the {m} encoding", k.name);
            }
        }
    }
}

#[test]
fn clock_variant_adds_only_the_cycles_buffer() {
    let mut clock_kernels = 0;
    for k in KERNELS.iter().filter(|k| k.kernel == "raycast") {
        let l = reflect(k.name, &k.words()).unwrap();
        let set = &l.sets[&0];
        let layouts = buffer_layouts(&k.words()).unwrap();
        if k.variant.starts_with("clock") {
            clock_kernels += 1;
            assert_eq!(set[&BINDING_CYCLES].ty, vk::DescriptorType::STORAGE_BUFFER, "{}", k.name);
            // One u32 per ray, as the host reads it back.
            assert_eq!(layouts[&BINDING_CYCLES], array_of(size_of::<u32>(), &[]), "{}", k.name);
            // Its twin without the clock: closest, on the same access path.
            let twin = k.variant.replace("clock", "closest");
            let closest = trilab::kernels::find("raycast", k.intersector, &twin).unwrap();
            let closest_set = reflect(closest.name, &closest.words()).unwrap().sets[&0].clone();
            let mut without: Vec<u32> = set.keys().copied().filter(|&b| b != BINDING_CYCLES).collect();
            without.sort();
            assert_eq!(without, closest_set.keys().copied().collect::<Vec<_>>(), "{}: bindings besides cycles", k.name);
        } else {
            assert!(!set.contains_key(&BINDING_CYCLES), "{}: only the clock variants bind the cycles buffer", k.name);
        }
    }
    // One per method, access path and layout.
    assert_eq!(clock_kernels, 2 * Method::ALL.len() * trilab::encoding::Layout::ALL.len());
}

#[test]
fn raycast_workgroup_size_is_a_specialisation_constant() {
    for k in KERNELS {
        let mut l = reflect(k.name, &k.words()).unwrap();
        if !matches!(k.kernel, "raycast" | "raycast_coop" | "raycast_persistent" | "raycast_packet") {
            assert_eq!(l.local_size_spec_ids, [None; 3], "{}", k.name);
            continue;
        }
        assert_eq!(l.local_size, (WORKGROUP_SIZE, 1, 1), "{}: default", k.name);
        assert_eq!(l.local_size_spec_ids, [Some(SPEC_ID_WORKGROUP_SIZE), None, None], "{}", k.name);
        // Other constant ids leave it alone; the last value given for the id wins.
        l.specialize(&[(SPEC_ID_WORKGROUP_SIZE + 1, 7)]);
        assert_eq!(l.local_size, (WORKGROUP_SIZE, 1, 1), "{}", k.name);
        l.specialize(&[(SPEC_ID_WORKGROUP_SIZE, 32), (SPEC_ID_WORKGROUP_SIZE, 128)]);
        assert_eq!(l.local_size, (128, 1, 1), "{}", k.name);
    }
}

#[test]
fn rayquery_binds_the_tlas_as_an_acceleration_structure_beside_the_raycast_buffers() {
    for variant in ["closest", "any"] {
        let k = trilab::kernels::find("rayquery", trilab::kernels::NO_INTERSECTOR, variant).unwrap();
        let l = reflect(k.name, &k.words()).unwrap();
        let set: Vec<(u32, vk::DescriptorType)> = l.sets[&0].iter().map(|(&b, d)| (b, d.ty)).collect();
        assert_eq!(
            set,
            vec![
                (BINDING_RAYS, vk::DescriptorType::STORAGE_BUFFER),
                (BINDING_HITS, vk::DescriptorType::STORAGE_BUFFER),
                (BINDING_SLOT_IDS, vk::DescriptorType::STORAGE_TEXEL_BUFFER),
                (BINDING_TLAS, vk::DescriptorType::ACCELERATION_STRUCTURE_KHR),
            ],
            "{}",
            k.name
        );
        assert_eq!(l.push_constants, Some((0, 4)), "{}: Push {{ uint ray_count; }}", k.name);
        // The same Ray and Hit layouts as raycast.comp; the TLAS is no buffer block.
        let layouts = buffer_layouts(&k.words()).unwrap();
        assert_eq!(
            layouts.keys().copied().collect::<Vec<_>>(),
            vec![BINDING_RAYS, BINDING_HITS, u32::MAX],
            "{}",
            k.name
        );
        let raycast = buffer_layouts(&Method::Mt.raycast_kernel(Raycast::Closest, AccessPath::Texel).words()).unwrap();
        assert_eq!(layouts, raycast, "{}: buffer layouts differ from raycast.mt.closest", k.name);
    }
}
