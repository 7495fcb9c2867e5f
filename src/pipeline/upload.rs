//! A scene's buffers on the device, bound where the kernels read them: storage texel buffers; on
//! the address path the data in device-address buffers and, at each binding, a uniform block
//! holding the address (`SCENE_ADDRESS` in `glsl/types.glsl`); or on the storage path storage
//! buffers (`SCENE_STORAGE`).

use ash::vk;

use crate::encoding::{AccessPath, EncodedScene, SceneBufferRef};
use crate::error::{Error, Result};
use crate::gpu::{Buffer, Context, Resource, TexelBuffer};
use crate::kernels::KernelSource;
use crate::shared::{Texel, BINDING_NODES};

/// One scene buffer as the kernels reach it.
enum SceneBinding {
    /// A storage texel buffer (the default kernels).
    Texels(TexelBuffer),
    /// The data in a device-address buffer, and a uniform buffer holding its address, bound where
    /// the texel buffer would be (the `*_address` kernels).
    Address { data: Buffer, pointer: Buffer },
    /// A storage buffer (the `*_storage` kernels).
    Storage(Buffer),
}

/// The scene's buffers by binding.
pub(super) struct SceneBuffers(Vec<(u32, SceneBinding)>);

impl SceneBuffers {
    /// Uploads `scene` for `access`: every buffer, or only those `reader` reads; with `nodes`,
    /// those bytes (a wide layout's nodes) at `BINDING_NODES` instead of the binary nodes.
    pub(super) fn upload(
        ctx: &Context,
        scene: &EncodedScene,
        access: AccessPath,
        reader: Option<&'static KernelSource>,
        nodes: Option<&[u8]>,
    ) -> Result<SceneBuffers> {
        scene
            .check_limits()
            .map_err(|e| Error::Usage(format!("scene too large for the {} kernels: {e}", scene.method)))?;
        let read = match reader {
            Some(k) => {
                Some(crate::spirv::reflect::reflect(k.name, &k.words())?.sets.get(&0).cloned().unwrap_or_default())
            }
            None => None,
        };
        let buffers = bound(scene, nodes)
            .into_iter()
            .filter(|b| read.as_ref().is_none_or(|r| r.contains_key(&b.binding)))
            .map(|b| Ok((b.binding, upload_one(ctx, access, b.name, b.texel, b.bytes)?)))
            .collect::<Result<Vec<_>>>()?;
        Ok(SceneBuffers(buffers))
    }

    /// Uploads buffers kept on the host ([`HostBinding`]s: a repro's), as [`SceneBuffers::upload`]
    /// would have uploaded the encoding they were taken from.
    pub(super) fn upload_host(ctx: &Context, access: AccessPath, bindings: &[HostBinding]) -> Result<SceneBuffers> {
        let buffers = bindings
            .iter()
            .map(|b| Ok((b.binding, upload_one(ctx, access, &b.name, b.texel, &b.bytes)?)))
            .collect::<Result<Vec<_>>>()?;
        Ok(SceneBuffers(buffers))
    }

    /// Bytes of scene data on the device.
    pub(super) fn bytes(&self) -> usize {
        self.0
            .iter()
            .map(|(_, b)| match b {
                SceneBinding::Texels(t) => t.buffer.size as usize,
                SceneBinding::Address { data, .. } | SceneBinding::Storage(data) => data.size as usize,
            })
            .sum()
    }

    /// The bindings, for a descriptor set.
    pub(super) fn resources(&self) -> impl Iterator<Item = (u32, Resource<'_>)> {
        self.0.iter().map(|(b, t)| {
            (
                *b,
                match t {
                    SceneBinding::Texels(t) => Resource::Texels(t),
                    SceneBinding::Address { pointer, .. } | SceneBinding::Storage(pointer) => Resource::whole(pointer),
                },
            )
        })
    }
}

/// One buffer of a scene, on the host, where a kernel binds it: what [`SceneBuffers::upload`]
/// uploads, kept (`trilab repro` writes these to files and uploads them again elsewhere).
#[derive(Clone, Debug, PartialEq)]
pub struct HostBinding {
    pub name: String,
    pub binding: u32,
    /// How the kernel reads its elements on the texel path (also the storage path's element
    /// size: an empty buffer is bound as one zero element).
    pub texel: Texel,
    pub bytes: Vec<u8>,
}

/// The buffers of `scene` where its kernels bind them; with `nodes`, those bytes (a wide layout's
/// nodes) at `BINDING_NODES` instead of the binary nodes.
pub(super) fn bound<'a>(scene: &'a EncodedScene, nodes: Option<&'a [u8]>) -> Vec<SceneBufferRef<'a>> {
    scene
        .buffers()
        .into_iter()
        .map(|b| match nodes {
            Some(bytes) if b.binding == BINDING_NODES => SceneBufferRef { bytes, ..b },
            _ => b,
        })
        .collect()
}

/// Uploads one scene buffer for `access`.
fn upload_one(ctx: &Context, access: AccessPath, name: &str, texel: Texel, bytes: &[u8]) -> Result<SceneBinding> {
    Ok(match access {
        AccessPath::Texel => SceneBinding::Texels(ctx.upload_texels(name, bytes, texel)?),
        AccessPath::Address => {
            let (data, address) = ctx.upload_addressed(name, bytes)?;
            // `uniform <name>Address { Scene.. <name>; }` (std140): the 8-byte address.
            let pointer =
                ctx.upload(&format!("{name} (address)"), &address.to_le_bytes(), vk::BufferUsageFlags::UNIFORM_BUFFER)?;
            SceneBinding::Address { data, pointer }
        }
        AccessPath::Storage => {
            // A binding cannot be empty: an empty buffer gets one zero texel, as on the texel
            // path.
            let one = vec![0u8; texel.size()];
            let bytes = if bytes.is_empty() { &one[..] } else { bytes };
            SceneBinding::Storage(ctx.upload(name, bytes, vk::BufferUsageFlags::STORAGE_BUFFER)?)
        }
    })
}
