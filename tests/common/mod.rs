//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

use trilab::bvh::Bvh;
use trilab::encoding::Method;
use trilab::gpu::{raycast, Context, ContextOptions, GpuScene, Kernel, RaycastOptions, Validation};
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
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let ctx = Context::new(&ContextOptions { validation: Validation::Required, ..Default::default() })
            .unwrap_or_else(|e| {
                panic!("GPU tests need a Vulkan device and the validation layer (they fail, never skip): {e}")
            });
        assert!(ctx.validation_enabled(), "validation layer and debug messenger must be active in tests");
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

/// A method's closest-hit and any-hit ray-casting kernels, created once.
pub struct MethodKernels {
    pub method: Method,
    pub closest: Kernel,
    pub any: Kernel,
}

impl MethodKernels {
    pub fn new(ctx: &Context, method: Method) -> MethodKernels {
        MethodKernels {
            method,
            closest: ctx.create_kernel(trilab::kernels::raycast(method, false)).unwrap(),
            any: ctx.create_kernel(trilab::kernels::raycast(method, true)).unwrap(),
        }
    }

    /// Closest and any hit of `rays` over `mesh` (encoded for the method on `bvh`).
    pub fn cast(&self, ctx: &Context, mesh: &Mesh, bvh: &Bvh, rays: &[Ray]) -> (Vec<Hit>, Vec<Hit>) {
        let scene = GpuScene::upload(ctx, &self.method.encode(mesh, bvh)).unwrap();
        let opts = RaycastOptions { warmup: 0, repeat: 1, batch_rays: 1 << 20 };
        let c = raycast(ctx, &self.closest, &scene, rays, &opts).unwrap();
        let a = raycast(ctx, &self.any, &scene, rays, &opts).unwrap();
        (c.hits, a.hits)
    }
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
