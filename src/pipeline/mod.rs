//! The scene pipeline every command, harness and test shares, from a mesh to a scene on the
//! device with its kernels:
//!
//! mesh → BVH ([`HostScene::build`], once per mesh and build options, shared by every method) →
//! method, or `auto` ([`conditioning::resolve`]) → memory placement, checked against the
//! device's limits, and the access path, chosen once ([`HostScene::place`] → [`ScenePlacement`])
//! → encoding → upload ([`ScenePlacement::upload`] → [`DeviceScene`]) → kernels
//! ([`DeviceScene::kernel`]), which always read the scene through the path it was uploaded for.
//!
//! Nothing else uploads a scene. A scene that cannot fit is refused at its placement, before
//! anything is encoded or allocated, with [`Error::SceneTooLarge`] naming the buffer and the limit, the
//! same way in every command; `TRILAB_TEST_LIMITS` (or [`ContextOptions::test_limits`]) lowers the
//! device's limits so tests can show it.
//!
//! [`ContextOptions::test_limits`]: crate::gpu::ContextOptions::test_limits

mod upload;

use std::sync::Arc;

use crate::bvh::{BuildOptions, Bvh, NodeOrder};
use crate::conditioning::{self, MethodChoice, Recommendation};
use crate::encoding::placement::check_extras;
use crate::encoding::{
    AccessPath, BufferPlacement, DeviceLimits, EncodedScene, Layout, LayoutNodes, Method, Placement, Raycast,
    RaycastKey, SceneAccess, SceneCounts, Traversal,
};
use crate::error::{Error, Result};
use crate::gpu::raycast::cast_rays;
use crate::gpu::{Context, Kernel, RaycastOptions, RaycastResult, Resource};
use crate::kernels::KernelSource;
use crate::reference::Reference;
use crate::scene::Mesh;

pub use upload::HostBinding;
use upload::SceneBuffers;

/// A mesh and its BVH, on the host: what every method's encoding of it starts from.
pub struct HostScene<'m> {
    /// The scene's name in tables and messages (`scene::scene_name`).
    pub name: String,
    pub mesh: &'m Mesh,
    pub bvh: Bvh,
}

/// What a device scene must serve.
#[derive(Clone, Copy, Debug)]
pub struct SceneRequest {
    /// A method, or `auto`: the cheapest meeting the default accuracy target on this scene and
    /// device (`trilab analyze`).
    pub method: MethodChoice,
    /// How the kernels read the scene: `auto` takes texel buffers when every buffer fits one
    /// binding, else buffer device addresses.
    pub access: SceneAccess,
    /// A reader of the scene without the address path (the path tracer), and why: the placement
    /// takes texel or storage buffers, and a "does not fit" error says what helps that reader.
    pub without_address: Option<&'static str>,
    /// The node layout the kernels read ([`Layout::DEFAULT`] unless asked): a wide layout binds its
    /// nodes, made from the encoding's binary nodes, where the binary ones would be; every
    /// kernel exists for every layout (`encoding::layout`).
    pub layout: Layout,
    /// How the ray-casting kernels walk the tree ([`Traversal::DEFAULT`] unless asked; the
    /// others have kernels for some layouts, kinds and paths only: `Method::traversal_kernel`).
    pub traversal: Traversal,
    /// Where the layout's nodes sit in its node buffer ([`NodeOrder::DEFAULT`] unless asked:
    /// `bvh::order`); every layout, kernel and traversal reads any order.
    pub node_order: NodeOrder,
}

impl<M: Into<MethodChoice>> From<M> for SceneRequest {
    fn from(method: M) -> SceneRequest {
        SceneRequest::new(method)
    }
}

impl SceneRequest {
    /// `method` (or `auto`), read through whichever path fits.
    pub fn new(method: impl Into<MethodChoice>) -> SceneRequest {
        SceneRequest {
            method: method.into(),
            access: SceneAccess::DEFAULT,
            without_address: None,
            layout: Layout::DEFAULT,
            traversal: Traversal::DEFAULT,
            node_order: NodeOrder::DEFAULT,
        }
    }

    /// The same, read through `access`.
    pub fn access(self, access: SceneAccess) -> SceneRequest {
        SceneRequest { access, ..self }
    }

    /// The same, with the nodes in `layout`.
    pub fn layout(self, layout: Layout) -> SceneRequest {
        SceneRequest { layout, ..self }
    }

    /// The same, its ray-casting kernels walking the tree with `traversal`.
    pub fn traversal(self, traversal: Traversal) -> SceneRequest {
        SceneRequest { traversal, ..self }
    }

    /// The same, the layout's nodes in `order`.
    pub fn node_order(self, node_order: NodeOrder) -> SceneRequest {
        SceneRequest { node_order, ..self }
    }

    /// The same, for a reader without the address path (`why` names it).
    pub fn without_address(self, why: &'static str) -> SceneRequest {
        SceneRequest { without_address: Some(why), ..self }
    }
}

impl<'m> HostScene<'m> {
    /// Builds the BVH of `mesh` (after checking the options: leaf size and SAH grouping).
    pub fn build(name: impl Into<String>, mesh: &'m Mesh, options: &BuildOptions) -> Result<HostScene<'m>> {
        options.check()?;
        Ok(HostScene { name: name.into(), mesh, bvh: Bvh::build(mesh, options) })
    }

    /// A scene over a BVH built elsewhere (a hand-made or depth-limited tree in tests).
    pub fn with_bvh(name: impl Into<String>, mesh: &'m Mesh, bvh: Bvh) -> HostScene<'m> {
        HostScene { name: name.into(), mesh, bvh }
    }

    /// The counts every method's memory placement is made of.
    pub fn counts(&self) -> SceneCounts {
        SceneCounts::of(self.mesh, &self.bvh)
    }

    /// The CPU f64 reference on the same tree.
    pub fn reference(&self) -> Reference<'_> {
        Reference::new(self.mesh, &self.bvh)
    }

    /// Resolves the method, places every buffer of its encoding and chooses the access path,
    /// against `ctx`'s limits; nothing is encoded or allocated.
    pub fn place(&self, ctx: &Context, request: &SceneRequest) -> Result<ScenePlacement<'_, 'm>> {
        let (method, auto) = conditioning::resolve(request.method, self.mesh, &ctx.capabilities(), None)?;
        self.place_for(method, auto, request, &ctx.limits()?)
    }

    /// [`HostScene::place`] for a resolved method against given limits (no device needed: the
    /// bytes-per-triangle tables of `trilab scale --placement-only` and unit tests).
    pub fn place_for(
        &self,
        method: Method,
        auto: Option<Recommendation>,
        request: &SceneRequest,
        limits: &DeviceLimits,
    ) -> Result<ScenePlacement<'_, 'm>> {
        let memory = Placement::of(method, &self.counts()).with_layout(request.layout);
        let access = match request.without_address {
            Some(why) => memory.choose_without_address(&self.name, request.access, limits, why)?,
            None => memory.choose_for_kernel(&self.name, request.access, limits, request.layout, request.traversal)?,
        };
        Ok(ScenePlacement {
            host: self,
            method,
            auto,
            memory,
            access,
            layout: request.layout,
            traversal: request.traversal,
            node_order: request.node_order,
            limits: *limits,
        })
    }

    /// [`HostScene::place`] then [`ScenePlacement::upload`]: `request`'s scene on the device.
    pub fn upload(&self, ctx: &Context, request: &SceneRequest) -> Result<DeviceScene> {
        self.place(ctx, request)?.upload(ctx)
    }
}

/// A method's encoding of a [`HostScene`], placed: what it will allocate and how the kernels
/// will read it.
pub struct ScenePlacement<'h, 'm> {
    host: &'h HostScene<'m>,
    pub method: Method,
    /// Why `auto` picked the method (`None` when it was given).
    pub auto: Option<Recommendation>,
    pub memory: Placement,
    pub access: AccessPath,
    /// The node layout. The memory placement prices its node buffer by the layout's bound from
    /// counts; the built buffer and the stack it needs are checked again before upload.
    pub layout: Layout,
    /// How the ray-casting kernels walk the tree.
    pub traversal: Traversal,
    /// Where the layout's nodes sit in its buffer.
    pub node_order: NodeOrder,
    /// The limits it was checked against.
    pub limits: DeviceLimits,
}

impl<'m> ScenePlacement<'_, 'm> {
    /// The mesh being placed.
    pub fn mesh(&self) -> &'m Mesh {
        self.host.mesh
    }

    /// Checks buffers a higher layer will upload beside the scene (the path tracer's), each with
    /// whether it is a storage buffer bound whole, against the same limits.
    pub fn check_extras(&self, extras: &[(BufferPlacement, bool)]) -> Result<()> {
        check_extras(&self.host.name, self.method, extras, &self.limits)
    }

    /// Encodes and uploads every buffer of the scene.
    pub fn upload(self, ctx: &Context) -> Result<DeviceScene> {
        self.upload_with(ctx, None, |_| ())
    }

    /// Encodes and uploads the scene: only the buffers `reader` reads when given (the path
    /// tracer never reads the slot -> OBJ id table), and hands the encoding to `inspect` before
    /// it is dropped (the path tracer's per-slot shading follows its slot order).
    pub fn upload_with(
        self,
        ctx: &Context,
        reader: Option<&'static KernelSource>,
        inspect: impl FnOnce(&EncodedScene),
    ) -> Result<DeviceScene> {
        let span = crate::timeline::span_with("upload", || format!("scene to device: {} {}", self.method, self.layout));
        if span.records() {
            span.arg("scene", self.host.name.clone());
            span.arg("access", self.access.name());
            span.arg("node_order", self.node_order.to_string());
        }
        let encode = crate::timeline::span("upload", "encode");
        let (encoded, wide) = self.encode(inspect)?;
        drop(encode);
        let copy = crate::timeline::span("upload", "buffers to device");
        let buffers = SceneBuffers::upload(ctx, &encoded, self.access, reader, wide.as_ref().map(|w| &w.bytes[..]))?;
        drop(copy);
        span.arg("bytes", buffers.bytes());
        Ok(DeviceScene {
            name: self.host.name.clone(),
            method: self.method,
            layout: self.layout,
            traversal: self.traversal,
            node_order: self.node_order,
            leaf_size: encoded.leaf_size,
            auto: self.auto,
            placement: self.memory,
            access: self.access,
            unrepresentable: encoded.unrepresentable,
            bytes: buffers.bytes(),
            buffers,
        })
    }
}

impl ScenePlacement<'_, '_> {
    /// The key of its ray-casting kernel computing `kind` (what [`DeviceScene::key`] will be).
    pub fn key(&self, kind: Raycast) -> RaycastKey {
        RaycastKey { method: self.method, kind, access: self.access, layout: self.layout, traversal: self.traversal }
    }

    /// The scene's buffers as its kernels bind them, kept on the host: what
    /// [`ScenePlacement::upload`] uploads (`trilab repro` writes them to files). Not on the address
    /// path, whose buffers hold device addresses.
    pub fn host_bindings(&self) -> Result<Vec<HostBinding>> {
        if self.access == AccessPath::Address {
            return Err(Error::Usage(format!(
                "scene `{}`: the address path's buffers hold this device's addresses and cannot be kept on the host",
                self.host.name
            )));
        }
        let (encoded, wide) = self.encode(|_| ())?;
        Ok(upload::bound(&encoded, wide.as_ref().map(|w| &w.bytes[..]))
            .into_iter()
            .map(|b| HostBinding {
                name: b.name.to_owned(),
                binding: b.binding,
                texel: b.texel,
                bytes: b.bytes.to_vec(),
            })
            .collect())
    }

    /// The encoding (handed to `inspect` first) and, for a wide layout, its node buffer, as
    /// they are uploaded.
    fn encode(&self, inspect: impl FnOnce(&EncodedScene)) -> Result<(EncodedScene, Option<LayoutNodes>)> {
        let mut encoded = self.method.encode(self.host.mesh, &self.host.bvh);
        inspect(&encoded);
        if self.layout.spec().build.is_none() {
            // The binary layout's nodes are the encoding's own.
            self.node_order.reorder_binary(&mut encoded.nodes).map_err(|e| self.refused(e))?;
        }
        let wide = self.layout_nodes(&encoded)?;
        Ok((encoded, wide))
    }

    /// The error for a node buffer this layout cannot make in this order.
    fn refused(&self, e: String) -> Error {
        let order = match self.node_order {
            NodeOrder::Built => String::new(),
            o => format!(" in {o} order"),
        };
        Error::Usage(format!("scene `{}`: its {} nodes cannot be built{order}: {e}", self.host.name, self.layout))
    }

    /// The layout's node buffer made from the encoding's binary nodes (`None` for the binary
    /// layout), refused when the kernel's fixed stack could overflow on this tree or the buffer
    /// exceeds what the access path can bind.
    fn layout_nodes(&self, encoded: &EncodedScene) -> Result<Option<LayoutNodes>> {
        let built = self
            .layout
            .nodes_in(&encoded.nodes, &self.host.bvh.options, self.node_order)
            .map_err(|e| self.refused(e))?;
        let Some(built) = built else {
            return Ok(None);
        };
        let spec = self.layout.spec();
        if built.stack_bound > spec.stack_size as usize {
            return Err(Error::Usage(format!(
                "scene `{}`: its {} tree needs a traversal stack of {} entries; the kernel has {} \
                 (glsl/shared.glsl)",
                self.host.name, self.layout, built.stack_bound, spec.stack_size
            )));
        }
        let texels = built.bytes.len() as u64 / 16;
        let limit = self.access.max_texels(&self.limits, 16);
        if texels > limit {
            return Err(Error::Usage(format!(
                "scene `{}`: its {} nodes need {texels} texels; one binding holds {limit}",
                self.host.name, self.layout
            )));
        }
        Ok(Some(built))
    }
}

/// Scene buffers kept on the host ([`ScenePlacement::host_bindings`]), uploaded again for `access`
/// (texel or storage): what a repro's dispatch binds.
pub struct BoundScene(SceneBuffers);

impl BoundScene {
    pub fn upload(ctx: &Context, access: AccessPath, bindings: &[HostBinding]) -> Result<BoundScene> {
        Ok(BoundScene(SceneBuffers::upload_host(ctx, access, bindings)?))
    }

    /// The bindings, for a descriptor set.
    pub fn resources(&self) -> impl Iterator<Item = (u32, Resource<'_>)> {
        self.0.resources()
    }
}

/// A method's encoding of a scene on the device, read through the access path it was placed
/// for; its kernels come from it.
pub struct DeviceScene {
    pub name: String,
    pub method: Method,
    /// The node layout its kernels read.
    pub layout: Layout,
    /// How its ray-casting kernels walk the tree. The same buffers serve every traversal of the
    /// layout, so a caller may change it between casts (the traversal figures do).
    pub traversal: Traversal,
    /// Where the layout's nodes sit in its node buffer.
    pub node_order: NodeOrder,
    pub leaf_size: u32,
    /// Why `auto` picked the method (`None` when it was given).
    pub auto: Option<Recommendation>,
    pub placement: Placement,
    pub access: AccessPath,
    /// Triangles the encoding could not represent (their map overflows f32): never hit.
    pub unrepresentable: Vec<u32>,
    /// Bytes uploaded.
    pub bytes: usize,
    buffers: SceneBuffers,
}

impl DeviceScene {
    /// The key of its ray-casting kernel computing `kind`: its method, access path, layout and
    /// traversal, fixed when the scene was placed (the one place a scene's kernel is named).
    pub fn key(&self, kind: Raycast) -> RaycastKey {
        RaycastKey { method: self.method, kind, access: self.access, layout: self.layout, traversal: self.traversal }
    }

    /// That kernel's source; an error where there is no such kernel.
    pub fn kernel_source(&self, kind: Raycast) -> Result<&'static KernelSource> {
        self.key(kind).source()
    }

    /// That kernel, created once per context; an error where the device cannot run the
    /// traversal (the cooperative kernel's subgroup operations).
    pub fn kernel(&self, ctx: &Context, kind: Raycast) -> Result<Arc<Kernel>> {
        let source = self.kernel_source(kind)?;
        ctx.capabilities().traversal(self.traversal)?;
        ctx.kernel(source)
    }

    /// The scene's bindings, for a descriptor set.
    pub fn resources(&self) -> impl Iterator<Item = (u32, Resource<'_>)> {
        self.buffers.resources()
    }

    /// Casts `rays` with this scene's `kind` kernel: `opts.warmup` untimed runs, then
    /// `opts.repeat` timed ones; the hits (and, for [`Raycast::Stats`], the traversal counts)
    /// are the last run's.
    pub fn cast(
        &self,
        ctx: &Context,
        kind: Raycast,
        rays: &[crate::rays::Ray],
        opts: &RaycastOptions,
    ) -> Result<RaycastResult> {
        let kernel = self.kernel(ctx, kind)?;
        self.cast_with(ctx, &kernel, rays, opts)
    }

    /// [`DeviceScene::cast`] with a pipeline made elsewhere (`trilab profile` varies subgroup
    /// and workgroup sizes); it must be one of this scene's ray-casting kernels.
    pub fn cast_with(
        &self,
        ctx: &Context,
        kernel: &Kernel,
        rays: &[crate::rays::Ray],
        opts: &RaycastOptions,
    ) -> Result<RaycastResult> {
        self.check_kernel(kernel)?;
        let resources: Vec<(u32, Resource)> = self.resources().collect();
        // What the dispatches of this cast are, for the trace's GPU track.
        let _labels = crate::timeline::labels(|| {
            vec![
                ("method", self.method.to_string().into()),
                ("layout", self.layout.to_string().into()),
                ("traversal", self.traversal.to_string().into()),
                ("access", self.access.name().into()),
                ("node_order", self.node_order.to_string().into()),
            ]
        });
        cast_rays(ctx, kernel, &resources, rays, opts)
    }

    /// The key of `kernel` when it is one of this scene's ray-casting kernels (its method, path,
    /// layout and traversal; any kind), else an error.
    pub fn check_kernel(&self, kernel: &Kernel) -> Result<RaycastKey> {
        let key = RaycastKey::of(kernel.source).filter(|k| *k == self.key(k.kind));
        key.ok_or_else(|| {
            Error::Usage(format!(
                "kernel {} cannot read scene `{}` ({} on the {} path, {} layout)",
                kernel.name,
                self.name,
                self.method,
                self.access.name(),
                self.layout
            ))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encoding::Raycast;

    use crate::scene::test_grid as grid;

    use crate::encoding::placement::tests::limits;

    #[test]
    fn bad_build_options_are_refused_before_building() {
        let m = grid(10);
        for o in [BuildOptions::new(0), BuildOptions::new(17), BuildOptions { sah_group: 0, ..BuildOptions::new(4) }] {
            assert!(matches!(HostScene::build("grid", &m, &o), Err(Error::Usage(_))), "{o:?}");
        }
    }

    #[test]
    fn the_access_path_is_chosen_once_and_read_by_the_kernels() {
        let m = grid(100);
        let host = HostScene::build("grid", &m, &BuildOptions::new(4)).unwrap();
        let mut l = limits();
        let p = host.place_for(Method::Unit, None, &SceneRequest::new(Method::Unit), &l).unwrap();
        assert_eq!(p.access, AccessPath::Texel);
        assert_eq!(p.method.raycast_kernel(Raycast::Closest, p.access).variant, "closest");
        l.max_texel_buffer_elements = 200; // unit triangles: 300 texels
        let p = host.place_for(Method::Unit, None, &SceneRequest::new(Method::Unit), &l).unwrap();
        assert_eq!(p.access, AccessPath::Address);
        assert_eq!(p.method.raycast_kernel(Raycast::Stats, p.access).variant, "stats_address");
        // A reader without the address path takes storage buffers; beyond those it is refused,
        // and told what helps it.
        let why = "the path tracer reads scenes through texel or storage buffers";
        let r = SceneRequest::new(Method::Unit).without_address(why);
        assert_eq!(host.place_for(Method::Unit, None, &r, &l).unwrap().access, AccessPath::Storage);
        l.max_storage_buffer_range = 200 * 16;
        match host.place_for(Method::Unit, None, &r, &l) {
            Err(Error::SceneTooLarge(t)) => {
                assert!(t.hint.ends_with(&format!("({why})")), "{}", t.hint);
                assert_eq!((t.scene.as_str(), t.buffer.as_str()), ("grid", "unit triangles"));
            }
            Err(e) => panic!("expected SceneTooLarge, got {e}"),
            Ok(_) => panic!("expected SceneTooLarge, got a placement"),
        }
    }
}
