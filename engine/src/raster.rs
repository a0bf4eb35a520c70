//! G-buffer of a mesh from a camera (`shaders_glsl/raster/gbuffer.{vert,frag}`): world position
//! with camera depth, geometric normal, triangle id. The per-view depth maps of the bake (§4.1)
//! and the novel-view G-buffer of the frame (§4.3) are this pass. Its reference is
//! [`crate::cpu::gbuffer`], a ray cast through the same pixel centres.

use crate::gpu::shaders;
use std::sync::Arc;

use crate::error::Result;
use crate::gpu::{
    bytes_of, image_barrier, image_barriers, vk, Gpu, GraphicsDesc, Image, Pipeline, RayScene,
};
use crate::scene::Camera;

pub const POS_DEPTH_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;
pub const NORMAL_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;
pub const TRI_FORMAT: vk::Format = vk::Format::R32_UINT;

/// The G-buffer's push block is one `Camera` (common/camera.glsl).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    crate::scene::GpuCamera,
    [shaders::RASTER_GBUFFER_VERT, shaders::RASTER_GBUFFER_FRAG],
    [r0, r1, r2, intrinsics, size_clip]
);
const DEPTH_FORMAT: vk::Format = vk::Format::D32_SFLOAT;

/// The G-buffer images, left in GENERAL layout after [`GbufferPass::record`].
pub struct Gbuffer {
    /// xyz = world position, w = camera depth (0 where nothing was hit).
    pub pos_depth: Image,
    /// xyz = geometric normal (counter-clockwise winding is the front).
    pub normal: Image,
    /// Triangle id + 1; 0 = background.
    pub tri: Image,
    depth: Image,
    pub width: u32,
    pub height: u32,
}

impl Gbuffer {
    pub fn new(gpu: &Arc<Gpu>, width: u32, height: u32) -> Result<Gbuffer> {
        let color = vk::ImageUsageFlags::COLOR_ATTACHMENT
            | vk::ImageUsageFlags::STORAGE
            | vk::ImageUsageFlags::SAMPLED;
        Ok(Gbuffer {
            pos_depth: Image::new(
                gpu,
                "gbuffer pos",
                POS_DEPTH_FORMAT,
                width,
                height,
                1,
                color,
            )?,
            normal: Image::new(
                gpu,
                "gbuffer normal",
                NORMAL_FORMAT,
                width,
                height,
                1,
                color,
            )?,
            tri: Image::new(gpu, "gbuffer tri", TRI_FORMAT, width, height, 1, color)?,
            depth: Image::new(
                gpu,
                "gbuffer depth",
                DEPTH_FORMAT,
                width,
                height,
                1,
                vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
            )?,
            width,
            height,
        })
    }

    /// Reads the three images back.
    pub fn download(&self) -> Result<GbufferPixels> {
        let l = vk::ImageLayout::GENERAL;
        Ok(GbufferPixels {
            pos_depth: bytemuck::pod_collect_to_vec(&self.pos_depth.download(l)?),
            normal: bytemuck::pod_collect_to_vec(&self.normal.download(l)?),
            tri: bytemuck::pod_collect_to_vec(&self.tri.download(l)?),
        })
    }
}

/// A G-buffer on the host, row-major.
pub struct GbufferPixels {
    pub pos_depth: Vec<[f32; 4]>,
    pub normal: Vec<[f32; 4]>,
    pub tri: Vec<u32>,
}

pub struct GbufferPass {
    pipeline: Pipeline,
}

impl GbufferPass {
    pub fn new(gpu: &Arc<Gpu>) -> Result<GbufferPass> {
        let pipeline = Pipeline::graphics(
            gpu,
            &GraphicsDesc {
                vert: shaders::RASTER_GBUFFER_VERT,
                frag: shaders::RASTER_GBUFFER_FRAG,
                color_formats: &[POS_DEPTH_FORMAT, NORMAL_FORMAT, TRI_FORMAT],
                depth_format: Some(DEPTH_FORMAT),
                // RayScene::corners: position, then the face normal.
                vertex_stride: 24,
                attributes: &[
                    (0, vk::Format::R32G32B32_SFLOAT, 0),
                    (1, vk::Format::R32G32B32_SFLOAT, 12),
                ],
                cull: vk::CullModeFlags::NONE,
            },
        )?;
        Ok(GbufferPass { pipeline })
    }

    /// The barrier commands `record` puts itself: the attachments' and the depth's layouts
    /// before, the attachments' after.
    pub const LAYOUT_BARRIERS: u32 = 3;

    /// Records the rasterization of `mesh` seen by `cam` into `out` (same size as the camera).
    pub fn record(
        &self,
        cmd: vk::CommandBuffer,
        mesh: &RayScene,
        cam: &Camera,
        near: f32,
        far: f32,
        out: &Gbuffer,
    ) -> Result<()> {
        let gpu = &self.pipeline.gpu;
        let d = &gpu.device;
        let color = vk::ImageAspectFlags::COLOR;
        let targets = [&out.pos_depth, &out.normal, &out.tri].map(|i| (i.raw, color));
        // The colour targets and the depth each change layout in one barrier command: the
        // G-buffer pass's own two (after it, the graph's).
        let attach = vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL;
        let undefined = vk::ImageLayout::UNDEFINED;
        image_barriers(gpu, cmd, &targets, undefined, attach);
        image_barrier(
            gpu,
            cmd,
            out.depth.raw,
            vk::ImageAspectFlags::DEPTH,
            undefined,
            vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL,
        );
        let clear = |c: vk::ClearValue, img: &Image| {
            vk::RenderingAttachmentInfo::default()
                .image_view(img.view)
                .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::STORE)
                .clear_value(c)
        };
        let zero_f = vk::ClearValue {
            color: vk::ClearColorValue { float32: [0.0; 4] },
        };
        let zero_u = vk::ClearValue {
            color: vk::ClearColorValue { uint32: [0; 4] },
        };
        let colors = [
            clear(zero_f, &out.pos_depth),
            clear(zero_f, &out.normal),
            clear(zero_u, &out.tri),
        ];
        let depth = vk::RenderingAttachmentInfo::default()
            .image_view(out.depth.view)
            .image_layout(vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::DONT_CARE)
            .clear_value(vk::ClearValue {
                depth_stencil: vk::ClearDepthStencilValue {
                    depth: 1.0,
                    stencil: 0,
                },
            });
        let area = vk::Rect2D {
            offset: vk::Offset2D::default(),
            extent: vk::Extent2D {
                width: out.width,
                height: out.height,
            },
        };
        let push = cam.to_gpu(near, far);
        unsafe {
            d.cmd_begin_rendering(
                cmd,
                &vk::RenderingInfo::default()
                    .render_area(area)
                    .layer_count(1)
                    .color_attachments(&colors)
                    .depth_attachment(&depth),
            );
            self.pipeline.bind(cmd, &[], bytes_of(&push))?;
            d.cmd_bind_vertex_buffers(cmd, 0, &[mesh.corners.raw], &[0]);
            d.cmd_set_viewport(
                cmd,
                0,
                &[vk::Viewport {
                    x: 0.0,
                    y: 0.0,
                    width: out.width as f32,
                    height: out.height as f32,
                    min_depth: 0.0,
                    max_depth: 1.0,
                }],
            );
            d.cmd_set_scissor(cmd, 0, &[area]);
            d.cmd_draw(cmd, mesh.triangle_count * 3, 1, 0, 0);
            d.cmd_end_rendering(cmd);
        }
        image_barriers(gpu, cmd, &targets, attach, vk::ImageLayout::GENERAL);
        Ok(())
    }

    /// Renders one G-buffer and waits for it.
    pub fn render(&self, mesh: &RayScene, cam: &Camera, near: f32, far: f32) -> Result<Gbuffer> {
        let out = Gbuffer::new(&self.pipeline.gpu, cam.width, cam.height)?;
        let mut res = Ok(());
        self.pipeline
            .gpu
            .submit(|cmd| res = self.record(cmd, mesh, cam, near, far, &out))?;
        res?;
        Ok(out)
    }
}
