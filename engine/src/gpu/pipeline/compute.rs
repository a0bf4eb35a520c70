//! Compute pipelines, optionally with specialization constants.

use std::sync::Arc;

use ash::vk;

use super::layout::{make_layout, make_module, Layout};
use super::{reflect, Gpu, Pipeline, Shader};
use crate::error::{Error, Result};

impl Pipeline {
    pub fn compute(gpu: &Arc<Gpu>, shader: Shader) -> Result<Pipeline> {
        Pipeline::compute_specialized(gpu, shader, &[])
    }

    /// A compute pipeline whose specialization constants 0, 1, … take `spec` (u32 each).
    pub fn compute_specialized(gpu: &Arc<Gpu>, shader: Shader, spec: &[u32]) -> Result<Pipeline> {
        let r = reflect(shader)?;
        let workgroup = r.workgroup.unwrap_or((1, 1, 1));
        let Layout {
            set_layout,
            layout,
            bindings,
            names,
            push_size,
        } = make_layout(gpu, shader.name(), &[(r, vk::ShaderStageFlags::COMPUTE)])?;
        let module = make_module(gpu, shader)?;
        let entries: Vec<vk::SpecializationMapEntry> = (0..spec.len() as u32)
            .map(|i| vk::SpecializationMapEntry {
                constant_id: i,
                offset: i * 4,
                size: 4,
            })
            .collect();
        let spec_info = vk::SpecializationInfo::default()
            .map_entries(&entries)
            .data(bytemuck::cast_slice(spec));
        let mut stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main");
        if !spec.is_empty() {
            stage = stage.specialization_info(&spec_info);
        }
        let info = [vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(layout)];
        let res = unsafe {
            gpu.device
                .create_compute_pipelines(vk::PipelineCache::null(), &info, None)
        };
        unsafe { gpu.device.destroy_shader_module(module, None) };
        let raw = match res {
            Ok(p) => p[0],
            Err((_, e)) => {
                unsafe {
                    gpu.device.destroy_pipeline_layout(layout, None);
                    gpu.device.destroy_descriptor_set_layout(set_layout, None);
                }
                return Err(Error::Vk {
                    what: "create compute pipeline",
                    result: e,
                });
            }
        };
        Ok(Pipeline {
            gpu: gpu.clone(),
            raw,
            layout,
            set_layout,
            bind_point: vk::PipelineBindPoint::COMPUTE,
            bindings,
            names,
            push_size,
            stages: vk::ShaderStageFlags::COMPUTE,
            workgroup,
            name: shader.name().to_string(),
        })
    }
}
