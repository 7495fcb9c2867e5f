//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod cli;
pub mod running;
pub mod source;
pub mod unpacked;

use std::path::PathBuf;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

use trilab::bvh::Bvh;
use trilab::encoding::{Method, Raycast};
use trilab::gpu::{Context, ContextOptions, RaycastOptions, Validation};
use trilab::pipeline::{HostScene, SceneRequest};
use trilab::rays::{Hit, Ray};
use trilab::scene::{load_obj, Mesh};

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn bunny() -> Mesh {
    load_obj(&root().join("scenes/bunny.obj")).expect("bundled bunny loads")
}

/// Runs `f` on a Vulkan context with the validation layer required, on its own thread with a
/// wall-clock limit (lavapipe has no watchdog: a hung kernel must fail the test, not CI).
/// Fails (never skips) when there is no device or no validation layer, and when the layer
/// reported anything, teardown included.
pub fn with_gpu<T: Send + 'static>(timeout_s: u64, f: impl FnOnce(&Context) -> T + Send + 'static) -> T {
    with_gpu_options(timeout_s, ContextOptions::default(), f)
}

/// [`with_gpu`] on a context made with `options` (the validation layer is required whatever
/// they say).
pub fn with_gpu_options<T: Send + 'static>(
    timeout_s: u64,
    options: ContextOptions,
    f: impl FnOnce(&Context) -> T + Send + 'static,
) -> T {
    // lavapipe 25.0.7 reuses image functions its disk cache holds from another SIMD width
    // (docs/driver-defects.md): a test process at a chosen width keeps its own cache. The trilab
    // executable sees to it itself (trilab::env::keep_lavapipe_cache_per_target); a test binary
    // is multi-threaded from its start and cannot, so whoever sets the width names the cache.
    // The same for the CPU lavapipe compiles for (GALLIUM_OVERRIDE_CPU_CAPS=sse4.1 changes the width too).
    for setting in ["LP_NATIVE_VECTOR_WIDTH", "GALLIUM_OVERRIDE_CPU_CAPS"] {
        if let Ok(value) = std::env::var(setting) {
            assert!(
                std::env::var_os("MESA_SHADER_CACHE_DIR").is_some()
                    || std::env::var_os("MESA_SHADER_CACHE_DISABLE").is_some(),
                "{setting}={value} without MESA_SHADER_CACHE_DIR: lavapipe would reuse image functions cached at \
                 another width (set a cache folder per setting, as scripts/test-width.sh does)"
            );
        }
    }
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let ctx = Context::new(&ContextOptions { validation: Validation::Required, ..options }).unwrap_or_else(|e| {
            panic!("GPU tests need a Vulkan device and the validation layer (they fail, never skip): {e}")
        });
        assert!(ctx.validation_enabled(), "validation layer and debug messenger must be active in tests");
        // scripts/test-width.sh: the pass at another lavapipe width must really run at it.
        if let Ok(want) = std::env::var("TRILAB_EXPECT_SUBGROUP_SIZE") {
            let want: u32 = want.parse().expect("TRILAB_EXPECT_SUBGROUP_SIZE is a number of lanes");
            assert_eq!(
                ctx.info().subgroup_size,
                want,
                "TRILAB_EXPECT_SUBGROUP_SIZE={want}: {} reports subgroup size {}",
                ctx.info().name,
                ctx.info().subgroup_size
            );
        }
        let log = ctx.validation_log();
        let out = f(&ctx);
        drop(ctx);
        let _ = tx.send((out, log.messages()));
    });
    match rx.recv_timeout(Duration::from_secs(timeout_s)) {
        Ok((out, messages)) => {
            assert!(messages.is_empty(), "{} validation message(s):\n{}", messages.len(), messages.join("\n"));
            out
        }
        Err(RecvTimeoutError::Timeout) => panic!("GPU test did not finish within {timeout_s} s"),
        Err(RecvTimeoutError::Disconnected) => panic!("GPU test failed (see the panic above)"),
    }
}

/// One untimed run.
pub const ONCE: RaycastOptions = RaycastOptions { warmup: 0, repeat: 1, batch_rays: 1 << 20 };

/// Closest and any hit of `rays` over `mesh` with `method`, on the tree `bvh`, through the scene
/// pipeline.
pub fn cast_both(ctx: &Context, method: Method, mesh: &Mesh, bvh: &Bvh, rays: &[Ray]) -> (Vec<Hit>, Vec<Hit>) {
    let host = HostScene::with_bvh("test", mesh, bvh.clone());
    let scene = host.upload(ctx, &SceneRequest::new(method)).unwrap();
    let c = scene.cast(ctx, Raycast::Closest, rays, &ONCE).unwrap();
    let a = scene.cast(ctx, Raycast::Any, rays, &ONCE).unwrap();
    (c.hits, a.hits)
}

/// A method's casts through the scene pipeline (its kernels are created once per context).
pub struct MethodKernels {
    pub method: Method,
}

impl MethodKernels {
    pub fn new(ctx: &Context, method: Method) -> MethodKernels {
        // Create the kernels now, so a method the device cannot run fails here.
        for kind in [Raycast::Closest, Raycast::Any] {
            ctx.kernel(method.raycast_kernel(kind, trilab::encoding::AccessPath::Texel)).unwrap();
        }
        MethodKernels { method }
    }

    /// Closest and any hit of `rays` over `mesh` (encoded for the method on `bvh`).
    pub fn cast(&self, ctx: &Context, mesh: &Mesh, bvh: &Bvh, rays: &[Ray]) -> (Vec<Hit>, Vec<Hit>) {
        cast_both(ctx, self.method, mesh, bvh, rays)
    }
}

/// Closest hits and per-ray traversal counts of `method`'s `stats` kernel on `bvh`.
pub fn cast_stats(
    ctx: &Context,
    method: Method,
    mesh: &Mesh,
    bvh: &Bvh,
    rays: &[Ray],
) -> (Vec<Hit>, Vec<trilab::gpu::TraversalCounts>) {
    let host = HostScene::with_bvh("test", mesh, bvh.clone());
    let scene = host.upload(ctx, &SceneRequest::new(method)).unwrap();
    let r = scene.cast(ctx, Raycast::Stats, rays, &ONCE).unwrap();
    (r.hits, r.traversal.expect("the stats kernel writes counters"))
}

/// Closest hits of `rays` over `mesh` with `method` on `bvh`.
pub fn cast_closest(ctx: &Context, method: Method, mesh: &Mesh, bvh: &Bvh, rays: &[Ray]) -> Vec<Hit> {
    let host = HostScene::with_bvh("test", mesh, bvh.clone());
    let scene = host.upload(ctx, &SceneRequest::new(method)).unwrap();
    scene.cast(ctx, Raycast::Closest, rays, &ONCE).unwrap().hits
}

/// No hit has a NaN t, u or v.
pub fn no_nan(hits: &[Hit]) -> bool {
    hits.iter().all(|h| !h.t.is_nan() && !h.u.is_nan() && !h.v.is_nan())
}

/// A 12 x 12 grid of unit squares in z = 0, two triangles each with unshared vertices, and
/// the rays `grid_rays` sends through it. `sound` is the grid as built; in the returned
/// positions every third triangle is already collapsed (a repeated vertex) or flattened (its
/// third vertex on its first edge) while staying inside its old box, so a BVH built on `sound`
/// keeps them in leaves and the kernel's own test must reject them.
pub struct DegenerateGrid {
    pub sound: Mesh,
    pub positions: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    /// Ids of the collapsed and flattened triangles, ascending.
    pub zero_area: Vec<u32>,
}

pub fn degenerate_grid() -> DegenerateGrid {
    let mut pos = vec![];
    let mut tris = vec![];
    for i in 0..12 {
        for j in 0..12 {
            let (x, y) = (i as f32, j as f32);
            for t in [[[x, y], [x + 1.0, y], [x + 1.0, y + 1.0]], [[x, y], [x + 1.0, y + 1.0], [x, y + 1.0]]] {
                let b = pos.len() as u32;
                pos.extend(t.map(|[px, py]| [px, py, 0.0]));
                tris.push([b, b + 1, b + 2]);
            }
        }
    }
    let sound = Mesh::from_triangles(pos.clone(), tris.clone());
    let mut zero_area = vec![];
    for id in (0..tris.len()).step_by(3) {
        let [a, b, c] = tris[id].map(|v| v as usize);
        pos[c] = if id % 2 == 0 { pos[a] } else { [(pos[a][0] + pos[b][0]) / 2.0, (pos[a][1] + pos[b][1]) / 2.0, 0.0] };
        zero_area.push(id as u32);
    }
    DegenerateGrid { sound, positions: pos, triangles: tris, zero_area }
}

/// Rays through every square of `degenerate_grid`: interiors, edge midpoints and vertices,
/// straight down and slanted from below.
pub fn grid_rays() -> Vec<Ray> {
    let mut rays = vec![];
    for i in 0..12 {
        for j in 0..12 {
            let (x, y) = (i as f32, j as f32);
            for p in [[x + 0.7, y + 0.2], [x + 0.2, y + 0.7], [x + 0.5, y], [x + 0.5, y + 0.5], [x, y]] {
                rays.push(Ray::new([p[0], p[1], 1.0], [0.0, 0.0, -1.0]));
                rays.push(Ray::new([p[0] + 0.3, p[1] - 0.2, -1.0], [-0.3, 0.2, 1.0]));
            }
        }
    }
    rays
}

/// Four triangles: 0 and 2 zero-area (left out of the BLAS, so primitive index != OBJ id),
/// 1 at z = 1, 3 at z = 2 behind it, offset so that a ray can reach 3 alone.
pub fn tiny_accel_mesh() -> Mesh {
    Mesh::from_triangles(
        vec![
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [0.0, 1.0, 1.0],
            [2.0, 0.0, 2.0],
            [3.5, 0.25, 2.0],
            [2.25, 1.75, 2.0],
            [5.0, 5.0, 5.0],
        ],
        vec![[0, 0, 1], [0, 1, 2], [6, 6, 6], [3, 4, 5]],
    )
}
