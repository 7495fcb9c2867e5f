//! Named GPU buffers, uploads, downloads and one-shot command submission.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::commands::memory_barrier;
use super::context::{Context, Device};
use crate::error::{Error, Result, VkContext};
use crate::shared::Texel;

/// Most bytes one staging buffer holds; larger uploads reuse it chunk by chunk.
pub const STAGING_CHUNK: usize = 64 << 20;

/// A buffer and its memory; both are released on drop.
pub struct Buffer {
    pub(crate) device: Arc<Device>,
    pub(crate) raw: vk::Buffer,
    allocation: Option<Allocation>,
    pub size: u64,
    pub name: String,
}

impl Drop for Buffer {
    fn drop(&mut self) {
        // SAFETY: users of the buffer finish before it is dropped (every submit waits on its
        // fence); the allocation came from this device's allocator.
        unsafe { self.device.raw.destroy_buffer(self.raw, None) };
        if let Some(a) = self.allocation.take() {
            let _ = self.device.allocator.lock().unwrap().free(a);
        }
    }
}

impl Buffer {
    pub fn mapped(&self) -> Option<&[u8]> {
        self.allocation.as_ref().and_then(|a| a.mapped_slice()).map(|s| &s[..self.size as usize])
    }

    pub(crate) fn mapped_mut(&mut self) -> Option<&mut [u8]> {
        let size = self.size as usize;
        self.allocation.as_mut().and_then(|a| a.mapped_slice_mut()).map(|s| &mut s[..size])
    }
}

/// A buffer read by kernels as texels (a storage texel buffer): the buffer and its view.
pub struct TexelBuffer {
    pub buffer: Buffer,
    pub(crate) view: vk::BufferView,
    pub texel: Texel,
    pub texels: u64,
}

impl Drop for TexelBuffer {
    fn drop(&mut self) {
        // SAFETY: no pending submit uses the view (all were waited for); the buffer field is
        // dropped after this, so the view goes first.
        unsafe { self.buffer.device.raw.destroy_buffer_view(self.view, None) };
    }
}

fn texel_format(t: Texel) -> vk::Format {
    match t {
        Texel::Rgba32Uint => vk::Format::R32G32B32A32_UINT,
        Texel::Rgba32Float => vk::Format::R32G32B32A32_SFLOAT,
        Texel::R32Uint => vk::Format::R32_UINT,
    }
}

impl Context {
    /// Uploads `bytes` as a storage texel buffer of `texel`s (device-local, named `name`).
    pub fn upload_texels(&self, name: &str, bytes: &[u8], texel: Texel) -> Result<TexelBuffer> {
        assert_eq!(bytes.len() % texel.size(), 0, "`{name}` is not a whole number of texels");
        let texels = (bytes.len() / texel.size()).max(1) as u64;
        let limit = self.info().max_texel_buffer_elements as u64;
        if texels > limit {
            return Err(Error::Usage(format!(
                "scene buffer `{name}` has {texels} texels, more than this device's maxTexelBufferElements ({limit})"
            )));
        }
        let buffer = if bytes.is_empty() {
            // Views need at least one texel; an empty scene buffer gets one zero texel.
            self.upload(name, &vec![0u8; texel.size()], vk::BufferUsageFlags::STORAGE_TEXEL_BUFFER)?
        } else {
            self.upload(name, bytes, vk::BufferUsageFlags::STORAGE_TEXEL_BUFFER)?
        };
        self.texel_view(name, buffer, texel)
    }

    /// `buffer` (made with STORAGE_TEXEL_BUFFER usage, a whole number of `texel`s, at most
    /// maxTexelBufferElements of them: the caller checked) with a texel view over all of it.
    pub(crate) fn texel_view(&self, name: &str, buffer: Buffer, texel: Texel) -> Result<TexelBuffer> {
        let texels = (buffer.size / texel.size() as u64).max(1);
        let info = vk::BufferViewCreateInfo::default()
            .buffer(buffer.raw)
            .format(texel_format(texel))
            .offset(0)
            .range(vk::WHOLE_SIZE);
        // SAFETY: the buffer was created with STORAGE_TEXEL_BUFFER usage and is bound to memory;
        // the format is one every Vulkan device supports for storage texel buffers.
        let view = unsafe { self.device.raw.create_buffer_view(&info, None) }
            .during(&format!("creating the texel view of `{name}`"))?;
        Ok(TexelBuffer { buffer, view, texel, texels })
    }

    /// Creates a buffer of `size` bytes (at least 4) with the allocation named `name`.
    pub fn create_buffer(
        &self,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Buffer> {
        let d = &self.device;
        let size = size.max(4);
        let info = vk::BufferCreateInfo::default().size(size).usage(usage).sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid device and create info.
        let raw = unsafe { d.raw.create_buffer(&info, None) }.during(&format!("creating buffer `{name}`"))?;
        let requirements = unsafe { d.raw.get_buffer_memory_requirements(raw) };
        let allocation = self.before_allocation(name).and_then(|()| {
            d.allocator
                .lock()
                .unwrap()
                .allocate(&AllocationCreateDesc {
                    name,
                    requirements,
                    location,
                    linear: true,
                    allocation_scheme: AllocationScheme::GpuAllocatorManaged,
                })
                .map_err(|source| Error::Allocation { name: name.into(), source })
        });
        let allocation = match allocation {
            Ok(a) => a,
            Err(e) => {
                unsafe { d.raw.destroy_buffer(raw, None) };
                // Out of memory names the last dispatch (gpu::markers).
                return Err(self.fault(e));
            }
        };
        // SAFETY: memory and offset come from an allocation made for these requirements.
        if let Err(e) = unsafe { d.raw.bind_buffer_memory(raw, allocation.memory(), allocation.offset()) } {
            unsafe { d.raw.destroy_buffer(raw, None) };
            let _ = d.allocator.lock().unwrap().free(allocation);
            return Err(e).during(&format!("binding memory of `{name}`"));
        }
        Ok(Buffer { device: d.clone(), raw, allocation: Some(allocation), size, name: name.into() })
    }

    /// A device-local buffer holding `bytes`, filled through a staging buffer of at most
    /// [`STAGING_CHUNK`] bytes reused chunk by chunk (so a large scene needs no host-visible
    /// copy of its own size, nor an allocation beyond maxMemoryAllocationSize for it).
    pub fn upload(&self, name: &str, bytes: &[u8], usage: vk::BufferUsageFlags) -> Result<Buffer> {
        let buf = self.create_buffer(
            name,
            bytes.len() as u64,
            usage | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuOnly,
        )?;
        if bytes.is_empty() {
            return Ok(buf);
        }
        let mut staging = self.create_buffer(
            &format!("{name} (staging)"),
            bytes.len().min(STAGING_CHUNK) as u64,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::CpuToGpu,
        )?;
        let chunks = bytes.len().div_ceil(STAGING_CHUNK);
        for (i, part) in bytes.chunks(STAGING_CHUNK).enumerate() {
            staging
                .mapped_mut()
                .ok_or_else(|| Error::NoDevice(format!("staging buffer for `{name}` is not host-visible")))?
                [..part.len()]
                .copy_from_slice(part);
            let what = if chunks == 1 {
                format!("uploading `{name}`")
            } else {
                format!("uploading `{name}` ({}/{chunks})", i + 1)
            };
            let region = vk::BufferCopy::default().dst_offset((i * STAGING_CHUNK) as u64).size(part.len() as u64);
            // The previous chunk's copy finished (one_shot waited for its fence) before the host
            // overwrote the staging buffer above.
            self.one_shot(&what, |d, cmd| unsafe {
                // SAFETY: both buffers are alive until one_shot returns (it waits for the fence).
                d.cmd_copy_buffer(cmd, staging.raw, buf.raw, &[region]);
                // Make the copy visible to any later shader read or write.
                memory_barrier(
                    d,
                    cmd,
                    (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
                    (
                        vk::PipelineStageFlags::COMPUTE_SHADER,
                        vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
                    ),
                );
            })?;
        }
        Ok(buf)
    }

    /// Uploads `bytes` into a buffer the kernels reach by its device address (the scene's
    /// address path, `encoding::placement`); returns the buffer and its address.
    pub fn upload_addressed(&self, name: &str, bytes: &[u8]) -> Result<(Buffer, vk::DeviceAddress)> {
        if !self.enabled().buffer_device_address {
            return Err(Error::Unsupported(format!(
                "scene buffer `{name}`: bufferDeviceAddress is not enabled on {}",
                self.info().name
            )));
        }
        // At least one texel, as a texel view would have.
        let pad = [0u8; 16];
        let bytes = if bytes.is_empty() { &pad[..] } else { bytes };
        let buf = self.upload(name, bytes, vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS)?;
        // SAFETY: the buffer has SHADER_DEVICE_ADDRESS usage and is bound to memory allocated
        // with the device-address flag (gpu-allocator sets it when the context enables
        // bufferDeviceAddress, checked above).
        let address = unsafe {
            self.device.raw.get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(buf.raw))
        };
        Ok((buf, address))
    }

    /// Copies `len` bytes from the start of a device buffer back to the host.
    pub fn download(&self, buf: &Buffer, len: u64) -> Result<Vec<u8>> {
        let readback = self.create_buffer(
            &format!("{} (readback)", buf.name),
            len,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        self.one_shot(&format!("downloading `{}`", buf.name), |d, cmd| unsafe {
            // SAFETY: both buffers outlive the wait in one_shot.
            read_back(d, cmd, buf, &readback, len);
        })?;
        let bytes = readback
            .mapped()
            .ok_or_else(|| Error::NoDevice(format!("readback buffer for `{}` is not host-visible", buf.name)))?;
        Ok(bytes[..len as usize].to_vec())
    }

    /// Records commands with `record`, submits them and waits (with the submit timeout).
    pub fn one_shot(&self, what: &str, record: impl FnOnce(&ash::Device, vk::CommandBuffer)) -> Result<()> {
        let cmd = self.allocate_command_buffers(1)?.remove(0);
        let result = (|| {
            let d = &self.device.raw;
            let begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            // SAFETY: freshly allocated primary command buffer.
            unsafe { d.begin_command_buffer(cmd, &begin) }.during(what)?;
            record(d, cmd);
            unsafe { d.end_command_buffer(cmd) }.during(what)?;
            self.submit_and_wait(cmd, what)
        })();
        if !matches!(result, Err(Error::Timeout { .. })) {
            // A timed-out buffer may still be executing: leak it rather than free it.
            self.free_command_buffers(&[cmd]);
        }
        result
    }

    pub(crate) fn allocate_command_buffers(&self, n: u32) -> Result<Vec<vk::CommandBuffer>> {
        let pool = self.device.command_pool.lock().unwrap();
        let info = vk::CommandBufferAllocateInfo::default()
            .command_pool(*pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(n);
        // SAFETY: the pool is externally synchronised by the mutex.
        unsafe { self.device.raw.allocate_command_buffers(&info) }.during("allocating command buffers")
    }

    pub(crate) fn free_command_buffers(&self, cmds: &[vk::CommandBuffer]) {
        let pool = self.device.command_pool.lock().unwrap();
        // SAFETY: the buffers are not pending (every submit was waited for).
        unsafe { self.device.raw.free_command_buffers(*pool, cmds) };
        self.forget_command_buffers(cmds);
    }

    /// Submits one command buffer and waits for it, failing after the submit timeout.
    pub(crate) fn submit_and_wait(&self, cmd: vk::CommandBuffer, what: &str) -> Result<()> {
        // A device that only compiles has no queue to run on (its driver would crash): every
        // submission stops here, the last guard behind the refusal when the context is made.
        if let Err(u) = self.capabilities().runs() {
            return Err(Error::Unsupported(format!("{what}: {u}")));
        }
        let d = &self.device.raw;
        // SAFETY: valid device; the fence is destroyed below after it is no longer in use.
        let fence = unsafe { d.create_fence(&vk::FenceCreateInfo::default(), None) }.during(what)?;
        let cmds = [cmd];
        let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
        // The dispatch log and fault injection (gpu::markers) see every submit.
        let submitted = self
            .before_submit(cmd, what)
            .and_then(|()| unsafe { d.queue_submit(self.device.queue, &submit, fence) }.during(what));
        let result = submitted.and_then(|_| {
            match unsafe { d.wait_for_fences(&[fence], true, self.device.submit_timeout.as_nanos() as u64) } {
                Ok(()) => Ok(()),
                Err(vk::Result::TIMEOUT) => {
                    Err(Error::Timeout { what: what.to_owned(), seconds: self.device.submit_timeout.as_secs_f64() })
                }
                Err(e) => Err(e).during(what),
            }
        });
        // A lost device or out-of-memory names the dispatch it happened in.
        let result = result.map(|()| self.after_submit(what)).map_err(|e| self.fault(e));
        if !matches!(result, Err(Error::Timeout { .. })) {
            // SAFETY: the fence is signalled or was never submitted.
            unsafe { d.destroy_fence(fence, None) };
        }
        result
    }
}

/// Records a copy of the first `len` bytes of `buf` (last written by a compute shader) into the
/// host-visible `readback`, made visible to the host once the submit completes.
///
/// # Safety
/// As [`memory_barrier`]; both buffers outlive the submit.
pub(crate) unsafe fn read_back(d: &ash::Device, cmd: vk::CommandBuffer, buf: &Buffer, readback: &Buffer, len: u64) {
    memory_barrier(
        d,
        cmd,
        (vk::PipelineStageFlags::COMPUTE_SHADER, vk::AccessFlags::SHADER_WRITE),
        (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_READ),
    );
    d.cmd_copy_buffer(cmd, buf.raw, readback.raw, &[vk::BufferCopy::default().size(len)]);
    memory_barrier(
        d,
        cmd,
        (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
        (vk::PipelineStageFlags::HOST, vk::AccessFlags::HOST_READ),
    );
}
