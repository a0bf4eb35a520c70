//! Pipelines built from embedded SPIR-V. Descriptor-set layouts and push-constant ranges come
//! from reflection (rspirv-reflect; spirv-reflect 0.2.3 aborts on SPIR-V >= 1.4 and on ray-query
//! modules). Set 0 is a push-descriptor set, so a pass binds its resources with one call and no
//! descriptor pools exist anywhere.

mod bind;
mod compute;
mod graphics;
mod layout;
mod reflect;

use std::collections::BTreeMap;
use std::sync::Arc;

use ash::vk;

use super::Gpu;
use crate::error::{Error, Result, VkContext};

pub use bind::Bind;
pub use graphics::GraphicsDesc;
pub use reflect::{reflect, Access, PushLayout, Reflected};

/// An embedded shader, named by its path below `shaders_glsl/` or by its row in build.rs's
/// variant table. Only the generated constants of [`shaders`] make one, so a misspelt shader
/// fails the build.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Shader(&'static str);

impl Shader {
    pub fn name(self) -> &'static str {
        self.0
    }
}

impl std::fmt::Display for Shader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0)
    }
}

// `pub mod shaders` (one constant per shader, and `ALL`) and the SPIR-V table.
include!(concat!(env!("OUT_DIR"), "/shaders.rs"));

/// The SPIR-V of an embedded shader, as words.
pub fn spirv(shader: Shader) -> Result<Vec<u32>> {
    let bytes = SPIRV
        .iter()
        .find(|(s, _)| *s == shader)
        .map(|(_, b)| *b)
        .ok_or_else(|| Error::Other(format!("no embedded shader named {shader}")))?;
    ash::util::read_spv(&mut std::io::Cursor::new(bytes))
        .map_err(|e| Error::Other(format!("shader {shader}: bad SPIR-V: {e}")))
}

/// The shader whose reflection gives `shader`'s layout. No reflection crate reads
/// cooperative-matrix modules yet, so a `*_cm.comp` kernel takes the layout of its portable twin
/// (`*.comp`), which by construction declares the same bindings.
pub fn layout_source(shader: Shader) -> Shader {
    let Some(stem) = shader.0.strip_suffix("_cm.comp") else {
        return shader;
    };
    let twin = format!("{stem}.comp");
    shaders::ALL
        .iter()
        .copied()
        .find(|s| s.0 == twin)
        .unwrap_or(shader)
}

pub struct Pipeline {
    pub gpu: Arc<Gpu>,
    pub raw: vk::Pipeline,
    pub layout: vk::PipelineLayout,
    pub set_layout: vk::DescriptorSetLayout,
    pub bind_point: vk::PipelineBindPoint,
    pub bindings: BTreeMap<u32, (vk::DescriptorType, u32)>,
    /// The bindings by name, with their access ([`Reflected::names`]).
    pub names: BTreeMap<String, (u32, Access)>,
    pub push_size: u32,
    pub stages: vk::ShaderStageFlags,
    pub workgroup: (u32, u32, u32),
    pub name: String,
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        unsafe {
            let d = &self.gpu.device;
            d.destroy_pipeline(self.raw, None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// A linear, clamp-to-edge sampler.
pub struct Sampler {
    gpu: Arc<Gpu>,
    pub raw: vk::Sampler,
}

impl Sampler {
    pub fn linear(gpu: &Arc<Gpu>) -> Result<Sampler> {
        let info = vk::SamplerCreateInfo::default()
            .mag_filter(vk::Filter::LINEAR)
            .min_filter(vk::Filter::LINEAR)
            .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE);
        let raw = unsafe { gpu.device.create_sampler(&info, None) }.vk("create sampler")?;
        Ok(Sampler {
            gpu: gpu.clone(),
            raw,
        })
    }
}

impl Drop for Sampler {
    fn drop(&mut self) {
        unsafe { self.gpu.device.destroy_sampler(self.raw, None) };
    }
}
