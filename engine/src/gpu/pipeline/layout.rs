//! Shader modules and the one pipeline layout (push-descriptor set 0, one push range) that
//! both compute and graphics pipelines build from their stages' reflections.

use std::collections::BTreeMap;

use ash::vk;

use super::{spirv, Access, Gpu, Reflected, Shader};
use crate::error::{Error, Result, VkContext};

pub(super) fn make_module(gpu: &Gpu, shader: Shader) -> Result<vk::ShaderModule> {
    let words = spirv(shader)?;
    unsafe {
        gpu.device
            .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
    }
    .vk("create shader module")
}

/// A pipeline layout with its push-descriptor set layout and what it was built from.
pub(super) struct Layout {
    pub(super) set_layout: vk::DescriptorSetLayout,
    pub(super) layout: vk::PipelineLayout,
    pub(super) bindings: BTreeMap<u32, (vk::DescriptorType, u32)>,
    pub(super) names: BTreeMap<String, (u32, Access)>,
    pub(super) push_size: u32,
}

/// Merges per-stage reflections into one set-0 layout and push range.
pub(super) fn make_layout(
    gpu: &Gpu,
    name: &str,
    parts: &[(Reflected, vk::ShaderStageFlags)],
) -> Result<Layout> {
    let mut bindings: BTreeMap<u32, (vk::DescriptorType, u32, vk::ShaderStageFlags)> =
        BTreeMap::new();
    let mut push_size = 0;
    let mut names: BTreeMap<String, (u32, Access)> = BTreeMap::new();
    for (r, _) in parts {
        for (n, &(b, a)) in &r.names {
            let e = names.entry(n.clone()).or_insert((b, a));
            if e.0 != b {
                return Err(Error::Other(format!(
                    "{name}: \"{n}\" is binding {} in one stage and {b} in another",
                    e.0
                )));
            }
            e.1 = e.1.merge(a);
        }
    }
    for (r, stage) in parts {
        for (set, b) in &r.sets {
            if *set != 0 {
                return Err(Error::Other(format!(
                    "{name}: uses descriptor set {set}; Relit's pipelines use set 0 only"
                )));
            }
            for (binding, (ty, count)) in b {
                let e = bindings.entry(*binding).or_insert((
                    *ty,
                    *count,
                    vk::ShaderStageFlags::empty(),
                ));
                if e.0 != *ty {
                    return Err(Error::Other(format!(
                        "{name}: binding {binding} has type {:?} in one stage and {ty:?} in another",
                        e.0
                    )));
                }
                e.2 |= *stage;
            }
        }
        push_size = push_size.max(r.push_size);
    }
    let all_stages: vk::ShaderStageFlags = parts
        .iter()
        .fold(vk::ShaderStageFlags::empty(), |a, (_, s)| a | *s);
    let vk_bindings: Vec<vk::DescriptorSetLayoutBinding> = bindings
        .iter()
        .map(|(b, (ty, count, stages))| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(*b)
                .descriptor_type(*ty)
                .descriptor_count(*count)
                .stage_flags(*stages)
        })
        .collect();
    let d = &gpu.device;
    let set_layout = unsafe {
        d.create_descriptor_set_layout(
            &vk::DescriptorSetLayoutCreateInfo::default()
                .flags(vk::DescriptorSetLayoutCreateFlags::PUSH_DESCRIPTOR_KHR)
                .bindings(&vk_bindings),
            None,
        )
    }
    .vk("create descriptor set layout")?;
    let ranges = [vk::PushConstantRange::default()
        .stage_flags(all_stages)
        .offset(0)
        .size(push_size)];
    let set_layouts = [set_layout];
    let mut info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
    if push_size > 0 {
        info = info.push_constant_ranges(&ranges);
    }
    let layout = match unsafe { d.create_pipeline_layout(&info, None) } {
        Ok(l) => l,
        Err(e) => {
            unsafe { d.destroy_descriptor_set_layout(set_layout, None) };
            return Err(Error::Vk {
                what: "create pipeline layout",
                result: e,
            });
        }
    };
    let bindings = bindings
        .into_iter()
        .map(|(b, (t, c, _))| (b, (t, c)))
        .collect();
    Ok(Layout {
        set_layout,
        layout,
        bindings,
        names,
        push_size,
    })
}
