//! Per-resource barriers: the pass graph's record of what was written, and one barrier command
//! that makes exactly those writes visible to everything after it.

use ash::vk;

use super::memory::every_subresource;
use super::{Bind, Gpu};

/// What a barrier names: a whole buffer, an image in the layout its binding uses (no layout
/// change), or all memory (an acceleration structure, whose barriers Vulkan defines as global).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Target {
    Buffer(vk::Buffer),
    Image(vk::Image, vk::ImageAspectFlags, vk::ImageLayout),
    Global,
}

impl Target {
    pub(crate) fn of(b: &Bind) -> Target {
        match b {
            // A window is barriered whole: two windows of one buffer are one resource.
            Bind::Buffer(buf) | Bind::BufferRange(buf, ..) => Target::Buffer(buf.raw),
            Bind::StorageImage(img) => Target::Image(img.raw, img.aspect, vk::ImageLayout::GENERAL),
            Bind::Sampled(img, _) => Target::Image(
                img.raw,
                img.aspect,
                vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
            ),
            Bind::Accel(_) => Target::Global,
        }
    }
}

/// A write still waiting for its barrier: where, and by which stage and access.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Write {
    pub target: Target,
    pub stage: vk::PipelineStageFlags2,
    pub access: vk::AccessFlags2,
}

/// Barriers recorded by a graph: commands, and the buffer, image and global memory barriers
/// they carry (a command with none is an execution dependency only, counted in `memory`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BarrierCount {
    pub commands: u32,
    pub buffers: u32,
    pub images: u32,
    pub memory: u32,
    /// Commands recorded only because a timer span began on a CPU device (lavapipe takes a
    /// timestamp's time when work is flushed, and a barrier flushes): none without a timer or
    /// on a GPU.
    pub for_timer: u32,
}

impl BarrierCount {
    pub fn add(&mut self, o: &BarrierCount) {
        self.commands += o.commands;
        self.buffers += o.buffers;
        self.images += o.images;
        self.memory += o.memory;
        self.for_timer += o.for_timer;
    }
}

impl std::fmt::Display for BarrierCount {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "{} barrier commands ({} buffer, {} image, {} global memory barriers; {} for timer spans)",
            self.commands, self.buffers, self.images, self.memory, self.for_timer
        )
    }
}

/// Records one barrier command after work of stages `after`: each of `writes` becomes visible
/// to every later command, and later writes wait for earlier reads (the execution dependency
/// from `after`). With no writes it is an execution dependency only.
pub(crate) fn record(
    gpu: &Gpu,
    cmd: vk::CommandBuffer,
    writes: &[Write],
    after: vk::PipelineStageFlags2,
    count: &mut BarrierCount,
) {
    let dst_stage = vk::PipelineStageFlags2::ALL_COMMANDS;
    let dst_access = vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE;
    let (mut bufs, mut imgs, mut mems) = (Vec::new(), Vec::new(), Vec::new());
    for w in writes {
        let src = after | w.stage;
        match w.target {
            Target::Buffer(b) => bufs.push(
                vk::BufferMemoryBarrier2::default()
                    .src_stage_mask(src)
                    .src_access_mask(w.access)
                    .dst_stage_mask(dst_stage)
                    .dst_access_mask(dst_access)
                    .buffer(b)
                    .size(vk::WHOLE_SIZE),
            ),
            Target::Image(i, aspect, layout) => imgs.push(
                vk::ImageMemoryBarrier2::default()
                    .src_stage_mask(src)
                    .src_access_mask(w.access)
                    .dst_stage_mask(dst_stage)
                    .dst_access_mask(dst_access)
                    .old_layout(layout)
                    .new_layout(layout)
                    .image(i)
                    .subresource_range(every_subresource(aspect)),
            ),
            Target::Global => mems.push(
                vk::MemoryBarrier2::default()
                    .src_stage_mask(src)
                    .src_access_mask(w.access)
                    .dst_stage_mask(dst_stage)
                    .dst_access_mask(dst_access),
            ),
        }
    }
    if bufs.is_empty() && imgs.is_empty() && mems.is_empty() {
        mems.push(
            vk::MemoryBarrier2::default()
                .src_stage_mask(after)
                .dst_stage_mask(dst_stage),
        );
    }
    count.commands += 1;
    count.buffers += bufs.len() as u32;
    count.images += imgs.len() as u32;
    count.memory += mems.len() as u32;
    let dep = vk::DependencyInfo::default()
        .buffer_memory_barriers(&bufs)
        .image_memory_barriers(&imgs)
        .memory_barriers(&mems);
    unsafe { gpu.device.cmd_pipeline_barrier2(cmd, &dep) };
}
