//! Buffers, images, uploads/readbacks (direct when memory is host-visible and coherent, through a
//! staging buffer otherwise), one-shot command submission and barriers.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::Gpu;
use crate::error::{Error, Result, VkContext};

impl Gpu {
    /// Records commands with `f`, submits them and waits. Simple and synchronous: the engine's
    /// passes are long compute dispatches, so per-submit overhead does not matter.
    pub fn submit<R>(&self, f: impl FnOnce(vk::CommandBuffer) -> R) -> Result<R> {
        self.submit_sync(&[], &[], f)
    }

    /// [`Gpu::submit`] that waits on `wait` semaphores (at the given stages) and signals
    /// `signal` (presenting to a swapchain).
    pub fn submit_sync<R>(
        &self,
        wait: &[(vk::Semaphore, vk::PipelineStageFlags)],
        signal: &[vk::Semaphore],
        f: impl FnOnce(vk::CommandBuffer) -> R,
    ) -> Result<R> {
        let pool = self
            .cmd_pool
            .lock()
            .map_err(|_| Error::Other("command pool lock poisoned".into()))?;
        let d = &self.device;
        unsafe {
            let cmd = d
                .allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(*pool)
                        .command_buffer_count(1),
                )
                .vk("allocate command buffer")?[0];
            let result = (|| {
                d.begin_command_buffer(
                    cmd,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .vk("begin command buffer")?;
                let r = f(cmd);
                d.end_command_buffer(cmd).vk("end command buffer")?;
                let fence = d
                    .create_fence(&vk::FenceCreateInfo::default(), None)
                    .vk("create fence")?;
                let cmds = [cmd];
                let (ws, wst): (Vec<_>, Vec<_>) = wait.iter().copied().unzip();
                let submit = vk::SubmitInfo::default()
                    .command_buffers(&cmds)
                    .wait_semaphores(&ws)
                    .wait_dst_stage_mask(&wst)
                    .signal_semaphores(signal);
                let waited = d
                    .queue_submit(self.queue, &[submit], fence)
                    .and_then(|_| d.wait_for_fences(&[fence], true, u64::MAX));
                d.destroy_fence(fence, None);
                waited.vk("queue submit")?;
                Ok(r)
            })();
            d.free_command_buffers(*pool, &[cmd]);
            result
        }
    }

    fn allocate(
        &self,
        name: &str,
        req: vk::MemoryRequirements,
        location: MemoryLocation,
        linear: bool,
    ) -> Result<Allocation> {
        let mut guard = self
            .allocator
            .lock()
            .map_err(|_| Error::Other("allocator lock poisoned".into()))?;
        let alloc = guard
            .as_mut()
            .ok_or_else(|| Error::Other("allocator gone".into()))?;
        alloc
            .allocate(&AllocationCreateDesc {
                name,
                requirements: req,
                location,
                linear,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .map_err(|e| allocation_error(name, req.size, e))
    }

    fn free(&self, a: Allocation) {
        if let Ok(mut g) = self.allocator.lock() {
            if let Some(alloc) = g.as_mut() {
                let _ = alloc.free(a);
            }
        }
    }
}

/// A full memory barrier between two commands. The engine's passes are few and large, so a
/// coarse barrier costs nothing measurable and keeps every hazard covered.
pub fn full_barrier(gpu: &Gpu, cmd: vk::CommandBuffer) {
    let mb = [vk::MemoryBarrier2::default()
        .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
        .dst_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        .dst_access_mask(vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE)];
    unsafe {
        gpu.device
            .cmd_pipeline_barrier2(cmd, &vk::DependencyInfo::default().memory_barriers(&mb))
    };
}

/// Moves every mip and layer of `image` from `old` to `new`, waiting on all prior work.
pub fn image_barrier(
    gpu: &Gpu,
    cmd: vk::CommandBuffer,
    image: vk::Image,
    aspect: vk::ImageAspectFlags,
    old: vk::ImageLayout,
    new: vk::ImageLayout,
) {
    let ib = [vk::ImageMemoryBarrier2::default()
        .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
        .dst_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        .dst_access_mask(vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE)
        .old_layout(old)
        .new_layout(new)
        .image(image)
        .subresource_range(
            vk::ImageSubresourceRange::default()
                .aspect_mask(aspect)
                .level_count(vk::REMAINING_MIP_LEVELS)
                .layer_count(vk::REMAINING_ARRAY_LAYERS),
        )];
    unsafe {
        gpu.device.cmd_pipeline_barrier2(
            cmd,
            &vk::DependencyInfo::default().image_memory_barriers(&ib),
        )
    };
}

/// A buffer with its memory. Every buffer can be a transfer source and destination, so that
/// uploads and readbacks work whatever memory it landed in.
pub struct Buffer {
    pub gpu: Arc<Gpu>,
    pub raw: vk::Buffer,
    pub size: u64,
    /// Device address (0 unless created with SHADER_DEVICE_ADDRESS usage).
    pub address: u64,
    alloc: Option<Allocation>,
}

impl Buffer {
    pub fn new(
        gpu: &Arc<Gpu>,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Buffer> {
        let size = size.max(4);
        // Shaders bind whole buffers: a storage buffer beyond the device's range cannot be bound.
        if usage.contains(vk::BufferUsageFlags::STORAGE_BUFFER)
            && size > gpu.caps.max_storage_buffer_range as u64
        {
            return Err(Error::Device(format!(
                "buffer \"{name}\" needs {:.1} MiB; the device binds at most {:.1} MiB per storage \
                 buffer (maxStorageBufferRange): use a smaller resolution, fewer views or fp16 storage",
                size as f64 / 1048576.0,
                gpu.caps.max_storage_buffer_range as f64 / 1048576.0
            )));
        }
        let usage = usage | vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST;
        let d = &gpu.device;
        let raw = unsafe {
            d.create_buffer(
                &vk::BufferCreateInfo::default()
                    .size(size)
                    .usage(usage)
                    .sharing_mode(vk::SharingMode::EXCLUSIVE),
                None,
            )
        }
        .map_err(|r| creation_error(name, size, r))?;
        let req = unsafe { d.get_buffer_memory_requirements(raw) };
        let alloc = match gpu.allocate(name, req, location, true) {
            Ok(a) => a,
            Err(e) => {
                unsafe { d.destroy_buffer(raw, None) };
                return Err(e);
            }
        };
        if let Err(e) = unsafe { d.bind_buffer_memory(raw, alloc.memory(), alloc.offset()) } {
            unsafe { d.destroy_buffer(raw, None) };
            gpu.free(alloc);
            return Err(Error::Vk {
                what: "bind buffer memory",
                result: e,
            });
        }
        let address = if usage.contains(vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS) {
            unsafe {
                d.get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(raw))
            }
        } else {
            0
        };
        Ok(Buffer {
            gpu: gpu.clone(),
            raw,
            size,
            address,
            alloc: Some(alloc),
        })
    }

    /// A device-local storage buffer filled with `data`.
    pub fn from_slice<T: bytemuck::Pod>(
        gpu: &Arc<Gpu>,
        name: &str,
        usage: vk::BufferUsageFlags,
        data: &[T],
    ) -> Result<Buffer> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let b = Buffer::new(
            gpu,
            name,
            bytes.len() as u64,
            usage,
            MemoryLocation::GpuOnly,
        )?;
        b.upload(bytes)?;
        Ok(b)
    }

    /// Host access to the memory, when it is host-visible and coherent and staging is not forced.
    fn direct(&self) -> bool {
        let a = self.alloc.as_ref().expect("buffer allocation");
        !self.gpu.force_staging()
            && a.mapped_ptr().is_some()
            && a.memory_properties()
                .contains(vk::MemoryPropertyFlags::HOST_COHERENT)
    }

    pub fn upload(&self, bytes: &[u8]) -> Result<()> {
        self.upload_at(0, bytes)
    }

    /// Writes `bytes` at byte `offset` (a buffer filled piece by piece, without a host copy of
    /// the whole).
    pub fn upload_at(&self, offset: u64, bytes: &[u8]) -> Result<()> {
        if offset + bytes.len() as u64 > self.size {
            return Err(Error::Other(format!(
                "upload of {} bytes at {offset} into a {}-byte buffer",
                bytes.len(),
                self.size
            )));
        }
        if self.direct() {
            let a = self.alloc.as_ref().expect("allocation");
            let p = a.mapped_ptr().expect("mapped").as_ptr() as *mut u8;
            unsafe {
                std::ptr::copy_nonoverlapping(bytes.as_ptr(), p.add(offset as usize), bytes.len())
            };
            return Ok(());
        }
        let staging = Staging::new(&self.gpu, bytes.len() as u64, MemoryLocation::CpuToGpu)?;
        staging.write(bytes);
        self.gpu.submit(|cmd| unsafe {
            let region = [vk::BufferCopy::default()
                .dst_offset(offset)
                .size(bytes.len() as u64)];
            self.gpu
                .device
                .cmd_copy_buffer(cmd, staging.0.raw, self.raw, &region);
        })
    }

    pub fn download(&self) -> Result<Vec<u8>> {
        self.download_range(0, self.size)
    }

    pub fn download_range(&self, offset: u64, len: u64) -> Result<Vec<u8>> {
        let len = len.min(self.size.saturating_sub(offset));
        if self.direct() {
            let a = self.alloc.as_ref().expect("allocation");
            let p = a.mapped_ptr().expect("mapped").as_ptr() as *const u8;
            let mut out = vec![0u8; len as usize];
            unsafe {
                std::ptr::copy_nonoverlapping(
                    p.add(offset as usize),
                    out.as_mut_ptr(),
                    len as usize,
                )
            };
            return Ok(out);
        }
        let staging = Staging::new(&self.gpu, len, MemoryLocation::GpuToCpu)?;
        self.gpu.submit(|cmd| unsafe {
            let region = [vk::BufferCopy::default().src_offset(offset).size(len)];
            self.gpu
                .device
                .cmd_copy_buffer(cmd, self.raw, staging.0.raw, &region);
        })?;
        Ok(staging.read(len as usize))
    }

    pub fn download_vec<T: bytemuck::Pod>(&self) -> Result<Vec<T>> {
        let bytes = self.download()?;
        let n = bytes.len() / std::mem::size_of::<T>();
        Ok(bytemuck::pod_collect_to_vec(
            &bytes[..n * std::mem::size_of::<T>()],
        ))
    }

    pub fn fill_zero(&self) -> Result<()> {
        self.gpu.submit(|cmd| unsafe {
            self.gpu
                .device
                .cmd_fill_buffer(cmd, self.raw, 0, vk::WHOLE_SIZE, 0)
        })
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        unsafe { self.gpu.device.destroy_buffer(self.raw, None) };
        if let Some(a) = self.alloc.take() {
            self.gpu.free(a);
        }
    }
}

/// A host-visible transfer buffer: always mapped, whatever `force_staging` says.
struct Staging(Buffer);

impl Staging {
    fn new(gpu: &Arc<Gpu>, size: u64, location: MemoryLocation) -> Result<Staging> {
        let b = Buffer::new(
            gpu,
            "staging",
            size,
            vk::BufferUsageFlags::empty(),
            location,
        )?;
        Ok(Staging(b))
    }

    fn ptr(&self) -> *mut u8 {
        let a = self.0.alloc.as_ref().expect("allocation");
        a.mapped_ptr()
            .expect("staging memory is host-visible")
            .as_ptr() as *mut u8
    }

    fn write(&self, bytes: &[u8]) {
        unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), self.ptr(), bytes.len()) };
    }

    fn read(&self, len: usize) -> Vec<u8> {
        let mut out = vec![0u8; len];
        unsafe { std::ptr::copy_nonoverlapping(self.ptr(), out.as_mut_ptr(), len) };
        out
    }
}

/// A 2D image (array) with one view over all layers.
pub struct Image {
    pub gpu: Arc<Gpu>,
    pub raw: vk::Image,
    pub view: vk::ImageView,
    pub format: vk::Format,
    pub width: u32,
    pub height: u32,
    pub layers: u32,
    pub aspect: vk::ImageAspectFlags,
    alloc: Option<Allocation>,
}

/// Bytes per texel of the uncompressed formats the engine reads back.
pub fn texel_size(format: vk::Format) -> Option<u32> {
    Some(match format {
        vk::Format::R8G8B8A8_UNORM | vk::Format::R8G8B8A8_SRGB | vk::Format::B8G8R8A8_UNORM => 4,
        vk::Format::R32_SFLOAT | vk::Format::R32_UINT | vk::Format::D32_SFLOAT => 4,
        vk::Format::R16G16B16A16_SFLOAT => 8,
        vk::Format::R32G32B32A32_SFLOAT => 16,
        vk::Format::R16_SFLOAT => 2,
        _ => return None,
    })
}

impl Image {
    pub fn new(
        gpu: &Arc<Gpu>,
        name: &str,
        format: vk::Format,
        width: u32,
        height: u32,
        layers: u32,
        usage: vk::ImageUsageFlags,
    ) -> Result<Image> {
        Image::create(
            gpu,
            name,
            format,
            (width, height, layers),
            usage,
            layers > 1,
        )
    }

    /// An image whose view is a 2D array even with one layer (`sampler2DArray` in shaders).
    pub fn new_array(
        gpu: &Arc<Gpu>,
        name: &str,
        format: vk::Format,
        width: u32,
        height: u32,
        layers: u32,
        usage: vk::ImageUsageFlags,
    ) -> Result<Image> {
        Image::create(gpu, name, format, (width, height, layers), usage, true)
    }

    fn create(
        gpu: &Arc<Gpu>,
        name: &str,
        format: vk::Format,
        (width, height, layers): (u32, u32, u32),
        usage: vk::ImageUsageFlags,
        array: bool,
    ) -> Result<Image> {
        let d = &gpu.device;
        let aspect = if format == vk::Format::D32_SFLOAT {
            vk::ImageAspectFlags::DEPTH
        } else {
            vk::ImageAspectFlags::COLOR
        };
        let usage = usage | vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST;
        let raw = unsafe {
            d.create_image(
                &vk::ImageCreateInfo::default()
                    .image_type(vk::ImageType::TYPE_2D)
                    .format(format)
                    .extent(vk::Extent3D {
                        width,
                        height,
                        depth: 1,
                    })
                    .mip_levels(1)
                    .array_layers(layers)
                    .samples(vk::SampleCountFlags::TYPE_1)
                    .tiling(vk::ImageTiling::OPTIMAL)
                    .usage(usage)
                    .initial_layout(vk::ImageLayout::UNDEFINED),
                None,
            )
        }
        .map_err(|r| {
            let texel = 16u64; // the widest format the engine uses (RGBA32F)
            creation_error(
                name,
                width as u64 * height as u64 * layers as u64 * texel,
                r,
            )
        })?;
        let req = unsafe { d.get_image_memory_requirements(raw) };
        let alloc = match gpu.allocate(name, req, MemoryLocation::GpuOnly, false) {
            Ok(a) => a,
            Err(e) => {
                unsafe { d.destroy_image(raw, None) };
                return Err(e);
            }
        };
        let bound = unsafe { d.bind_image_memory(raw, alloc.memory(), alloc.offset()) };
        let view = bound.and_then(|_| unsafe {
            d.create_image_view(
                &vk::ImageViewCreateInfo::default()
                    .image(raw)
                    .view_type(if array {
                        vk::ImageViewType::TYPE_2D_ARRAY
                    } else {
                        vk::ImageViewType::TYPE_2D
                    })
                    .format(format)
                    .subresource_range(
                        vk::ImageSubresourceRange::default()
                            .aspect_mask(aspect)
                            .level_count(1)
                            .layer_count(layers),
                    ),
                None,
            )
        });
        let view = match view {
            Ok(v) => v,
            Err(e) => {
                unsafe { d.destroy_image(raw, None) };
                gpu.free(alloc);
                return Err(Error::Vk {
                    what: "bind image memory / create view",
                    result: e,
                });
            }
        };
        Ok(Image {
            gpu: gpu.clone(),
            raw,
            view,
            format,
            width,
            height,
            layers,
            aspect,
            alloc: Some(alloc),
        })
    }

    /// Uploads tightly packed texels (all layers, layer-major) and leaves the image in `layout`.
    pub fn upload(&self, bytes: &[u8], layout: vk::ImageLayout) -> Result<()> {
        let staging = Staging::new(&self.gpu, bytes.len() as u64, MemoryLocation::CpuToGpu)?;
        staging.write(bytes);
        self.gpu.submit(|cmd| unsafe {
            image_barrier(
                &self.gpu,
                cmd,
                self.raw,
                self.aspect,
                vk::ImageLayout::UNDEFINED,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            );
            let region = [self.copy_region()];
            self.gpu.device.cmd_copy_buffer_to_image(
                cmd,
                staging.0.raw,
                self.raw,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &region,
            );
            image_barrier(
                &self.gpu,
                cmd,
                self.raw,
                self.aspect,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                layout,
            );
        })
    }

    /// Reads all layers back (tightly packed), the image being in `layout`, which it keeps.
    pub fn download(&self, layout: vk::ImageLayout) -> Result<Vec<u8>> {
        let texel = texel_size(self.format).ok_or_else(|| {
            Error::Other(format!(
                "readback of {:?} images is not supported",
                self.format
            ))
        })? as u64;
        let len = texel * self.width as u64 * self.height as u64 * self.layers as u64;
        let staging = Staging::new(&self.gpu, len, MemoryLocation::GpuToCpu)?;
        self.gpu.submit(|cmd| unsafe {
            image_barrier(
                &self.gpu,
                cmd,
                self.raw,
                self.aspect,
                layout,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
            );
            let region = [self.copy_region()];
            self.gpu.device.cmd_copy_image_to_buffer(
                cmd,
                self.raw,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                staging.0.raw,
                &region,
            );
            image_barrier(
                &self.gpu,
                cmd,
                self.raw,
                self.aspect,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                layout,
            );
        })?;
        Ok(staging.read(len as usize))
    }

    fn copy_region(&self) -> vk::BufferImageCopy {
        vk::BufferImageCopy::default()
            .image_subresource(
                vk::ImageSubresourceLayers::default()
                    .aspect_mask(self.aspect)
                    .layer_count(self.layers),
            )
            .image_extent(vk::Extent3D {
                width: self.width,
                height: self.height,
                depth: 1,
            })
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        unsafe {
            self.gpu.device.destroy_image_view(self.view, None);
            self.gpu.device.destroy_image(self.raw, None);
        }
        if let Some(a) = self.alloc.take() {
            self.gpu.free(a);
        }
    }
}

/// An allocation failure in the user's terms: which resource, how big, and what to change
/// (gpu-allocator's own words, such as "Invalid AllocationCreateDesc", name none of these).
fn allocation_error(name: &str, size: u64, e: gpu_allocator::AllocationError) -> Error {
    use gpu_allocator::AllocationError as A;
    let mib = size as f64 / 1048576.0;
    let why = match e {
        A::OutOfMemory => "the device is out of memory".to_string(),
        A::InvalidAllocationCreateDesc | A::NoCompatibleMemoryTypeFound => {
            "no memory of the kind it needs can hold it (too large for the device)".to_string()
        }
        other => format!("the allocator refused it ({other})"),
    };
    Error::Device(format!(
        "cannot allocate \"{name}\" ({mib:.1} MiB): {why}; use a smaller resolution, fewer views \
         or fp16 storage"
    ))
}

/// A failed vkCreateBuffer/vkCreateImage: out-of-memory results in the user's terms, others as
/// Vulkan reports them.
fn creation_error(name: &str, size: u64, r: vk::Result) -> Error {
    match r {
        vk::Result::ERROR_OUT_OF_DEVICE_MEMORY | vk::Result::ERROR_OUT_OF_HOST_MEMORY => {
            Error::Device(format!(
                "cannot create \"{name}\" (about {:.1} MiB): the device is out of memory; use a \
                 smaller resolution, fewer views or fp16 storage",
                size as f64 / 1048576.0
            ))
        }
        result => Error::Vk {
            what: "create buffer or image",
            result,
        },
    }
}
