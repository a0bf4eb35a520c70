//! Graphics pipelines: a vertex and a fragment shader, dynamic rendering and viewport.

use std::sync::Arc;

use ash::vk;

use super::layout::{make_layout, make_module, Layout};
use super::{reflect, Gpu, Pipeline, Shader};
use crate::error::{Error, Result};

/// Fixed-function state for a graphics pipeline (dynamic rendering, dynamic viewport).
pub struct GraphicsDesc<'a> {
    pub vert: Shader,
    pub frag: Shader,
    pub color_formats: &'a [vk::Format],
    pub depth_format: Option<vk::Format>,
    /// Vertex buffer stride and (location, format, offset) of each attribute (binding 0).
    pub vertex_stride: u32,
    pub attributes: &'a [(u32, vk::Format, u32)],
    pub cull: vk::CullModeFlags,
}

impl Pipeline {
    pub fn graphics(gpu: &Arc<Gpu>, desc: &GraphicsDesc) -> Result<Pipeline> {
        let name = format!("{}+{}", desc.vert, desc.frag);
        let parts = [
            (reflect(desc.vert)?, vk::ShaderStageFlags::VERTEX),
            (reflect(desc.frag)?, vk::ShaderStageFlags::FRAGMENT),
        ];
        let Layout {
            set_layout,
            layout,
            bindings,
            names,
            push_size,
        } = make_layout(gpu, &name, &parts)?;
        let vm = make_module(gpu, desc.vert)?;
        let fm = make_module(gpu, desc.frag)?;
        let res = create_raw(gpu, desc, (vm, fm), layout);
        unsafe {
            gpu.device.destroy_shader_module(vm, None);
            gpu.device.destroy_shader_module(fm, None);
        }
        let raw = match res {
            Ok(p) => p[0],
            Err((_, e)) => {
                unsafe {
                    gpu.device.destroy_pipeline_layout(layout, None);
                    gpu.device.destroy_descriptor_set_layout(set_layout, None);
                }
                return Err(Error::Vk {
                    what: "create graphics pipeline",
                    result: e,
                });
            }
        };
        Ok(Pipeline {
            gpu: gpu.clone(),
            raw,
            layout,
            set_layout,
            bind_point: vk::PipelineBindPoint::GRAPHICS,
            bindings,
            names,
            push_size,
            stages: vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
            workgroup: (1, 1, 1),
            name,
        })
    }
}

/// The pipeline's fixed-function state from `desc` around the vertex and fragment modules,
/// created; the caller destroys the modules and, on failure, the layout.
fn create_raw(
    gpu: &Gpu,
    desc: &GraphicsDesc,
    (vm, fm): (vk::ShaderModule, vk::ShaderModule),
    layout: vk::PipelineLayout,
) -> std::result::Result<Vec<vk::Pipeline>, (Vec<vk::Pipeline>, vk::Result)> {
    let stages = [
        vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::VERTEX)
            .module(vm)
            .name(c"main"),
        vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::FRAGMENT)
            .module(fm)
            .name(c"main"),
    ];
    let vb = [vk::VertexInputBindingDescription::default()
        .binding(0)
        .stride(desc.vertex_stride)
        .input_rate(vk::VertexInputRate::VERTEX)];
    let attrs: Vec<_> = desc
        .attributes
        .iter()
        .map(|(loc, fmt, off)| {
            vk::VertexInputAttributeDescription::default()
                .location(*loc)
                .binding(0)
                .format(*fmt)
                .offset(*off)
        })
        .collect();
    let mut vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
    if !desc.attributes.is_empty() {
        vertex_input = vertex_input
            .vertex_binding_descriptions(&vb)
            .vertex_attribute_descriptions(&attrs);
    }
    let ia = vk::PipelineInputAssemblyStateCreateInfo::default()
        .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
    let vp = vk::PipelineViewportStateCreateInfo::default()
        .viewport_count(1)
        .scissor_count(1);
    let rs = vk::PipelineRasterizationStateCreateInfo::default()
        .polygon_mode(vk::PolygonMode::FILL)
        .cull_mode(desc.cull)
        .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
        .line_width(1.0);
    let ms = vk::PipelineMultisampleStateCreateInfo::default()
        .rasterization_samples(vk::SampleCountFlags::TYPE_1);
    let ds = vk::PipelineDepthStencilStateCreateInfo::default()
        .depth_test_enable(desc.depth_format.is_some())
        .depth_write_enable(desc.depth_format.is_some())
        .depth_compare_op(vk::CompareOp::LESS);
    let blend: Vec<_> = desc
        .color_formats
        .iter()
        .map(|_| {
            vk::PipelineColorBlendAttachmentState::default()
                .color_write_mask(vk::ColorComponentFlags::RGBA)
        })
        .collect();
    let cb = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend);
    let dyn_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
    let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dyn_states);
    let mut rendering = vk::PipelineRenderingCreateInfo::default()
        .color_attachment_formats(desc.color_formats)
        .depth_attachment_format(desc.depth_format.unwrap_or(vk::Format::UNDEFINED));
    let info = [vk::GraphicsPipelineCreateInfo::default()
        .stages(&stages)
        .vertex_input_state(&vertex_input)
        .input_assembly_state(&ia)
        .viewport_state(&vp)
        .rasterization_state(&rs)
        .multisample_state(&ms)
        .depth_stencil_state(&ds)
        .color_blend_state(&cb)
        .dynamic_state(&dynamic)
        .layout(layout)
        .push_next(&mut rendering)];
    unsafe {
        gpu.device
            .create_graphics_pipelines(vk::PipelineCache::null(), &info, None)
    }
}
