//! Buffers, images, uploads/readbacks (direct when memory is host-visible and coherent, through a
//! staging buffer otherwise), one-shot command submission and barriers.

mod buffer;
mod image;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::Gpu;
use crate::error::{Error, Result, VkContext};

pub use buffer::Buffer;
pub use image::{texel_size, Image};

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

/// A full memory barrier between two commands: only for work outside any pass graph (the
/// acceleration structures' build, between BLAS and TLAS).
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
    image_barriers(gpu, cmd, &[(image, aspect)], old, new)
}

/// Moves every mip and layer of each of `images` (with its aspect) from `old` to `new` in one
/// barrier command, waiting on all prior work.
pub fn image_barriers(
    gpu: &Gpu,
    cmd: vk::CommandBuffer,
    images: &[(vk::Image, vk::ImageAspectFlags)],
    old: vk::ImageLayout,
    new: vk::ImageLayout,
) {
    let ib: Vec<vk::ImageMemoryBarrier2> = (images.iter())
        .map(|&(image, aspect)| {
            vk::ImageMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
                .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
                .dst_access_mask(vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE)
                .old_layout(old)
                .new_layout(new)
                .image(image)
                .subresource_range(every_subresource(aspect))
        })
        .collect();
    unsafe {
        gpu.device.cmd_pipeline_barrier2(
            cmd,
            &vk::DependencyInfo::default().image_memory_barriers(&ib),
        )
    };
}

/// Every mip and layer of an image's `aspect`.
pub fn every_subresource(aspect: vk::ImageAspectFlags) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange::default()
        .aspect_mask(aspect)
        .level_count(vk::REMAINING_MIP_LEVELS)
        .layer_count(vk::REMAINING_ARRAY_LAYERS)
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
