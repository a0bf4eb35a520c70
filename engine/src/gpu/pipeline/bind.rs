//! Binding resources by the names the shader gives them, push constants and dispatch.

use ash::vk;

use super::Pipeline;
use crate::error::{Error, Result};
use crate::gpu::memory::{Buffer, Image};

/// A resource bound at one binding of set 0.
#[derive(Clone, Copy)]
pub enum Bind<'a> {
    Buffer(&'a Buffer),
    /// A window of a buffer: (buffer, offset, size) in bytes.
    BufferRange(&'a Buffer, u64, u64),
    /// A storage image in GENERAL layout.
    StorageImage(&'a Image),
    /// A combined image sampler in SHADER_READ_ONLY_OPTIMAL layout.
    Sampled(&'a Image, vk::Sampler),
    Accel(vk::AccelerationStructureKHR),
}

impl Pipeline {
    /// Whether the shader declares a binding named `name`.
    pub fn has_binding(&self, name: &str) -> bool {
        self.names.contains_key(name)
    }

    /// Binds and dispatches with the resources of `binds` that the shader declares (passes
    /// that share one table of named resources, like the frame's).
    pub fn dispatch_subset(
        &self,
        cmd: vk::CommandBuffer,
        binds: &[(&str, Bind)],
        push: &[u8],
        threads: (u32, u32, u32),
    ) -> Result<()> {
        let mine: Vec<(&str, Bind)> = (binds.iter())
            .filter(|(n, _)| self.has_binding(n))
            .copied()
            .collect();
        self.dispatch(cmd, &mine, push, threads)
    }

    /// The binding numbers of `binds`: each name must be one the shader declares, and each
    /// binding it declares must be given.
    fn numbered<'b>(&self, binds: &[(&str, Bind<'b>)]) -> Result<Vec<(u32, Bind<'b>)>> {
        let known = || self.names.keys().cloned().collect::<Vec<_>>().join(", ");
        let mut out = Vec::with_capacity(binds.len());
        for (n, b) in binds {
            let (i, _) = self.names.get(*n).ok_or_else(|| {
                Error::Other(format!(
                    "{}: no binding named \"{n}\" (it declares {})",
                    self.name,
                    known()
                ))
            })?;
            out.push((*i, *b));
        }
        if let Some(missing) =
            (self.names.iter()).find(|(_, (i, _))| !out.iter().any(|o| o.0 == *i))
        {
            return Err(Error::Other(format!(
                "{}: binding \"{}\" not given",
                self.name, missing.0
            )));
        }
        Ok(out)
    }

    /// Binds the pipeline, pushes set 0 (each resource to the binding of its name) and the
    /// push constants. Each binding the shader declares must be given exactly once, with a
    /// resource of the reflected type.
    pub fn bind(&self, cmd: vk::CommandBuffer, binds: &[(&str, Bind)], push: &[u8]) -> Result<()> {
        let binds = self.numbered(binds)?;
        self.bind_numbered(cmd, &binds, push)
    }

    fn bind_numbered(
        &self,
        cmd: vk::CommandBuffer,
        binds: &[(u32, Bind)],
        push: &[u8],
    ) -> Result<()> {
        if push.len() as u32 != self.push_size {
            return Err(Error::Other(format!(
                "{}: push constants are {} bytes, shader declares {}",
                self.name,
                push.len(),
                self.push_size
            )));
        }
        let mut buf_infos = Vec::with_capacity(binds.len());
        let mut img_infos = Vec::with_capacity(binds.len());
        let mut accels = Vec::with_capacity(binds.len());
        for (binding, b) in binds {
            let (ty, _) = self.bindings.get(binding).ok_or_else(|| {
                Error::Other(format!("{}: shader has no binding {binding}", self.name))
            })?;
            let ok = matches!(
                (b, *ty),
                (
                    Bind::Buffer(_) | Bind::BufferRange(..),
                    vk::DescriptorType::STORAGE_BUFFER | vk::DescriptorType::UNIFORM_BUFFER
                ) | (Bind::StorageImage(_), vk::DescriptorType::STORAGE_IMAGE)
                    | (
                        Bind::Sampled(..),
                        vk::DescriptorType::COMBINED_IMAGE_SAMPLER
                    )
                    | (
                        Bind::Accel(_),
                        vk::DescriptorType::ACCELERATION_STRUCTURE_KHR
                    )
            );
            if !ok {
                let name = (self.names.iter())
                    .find(|(_, (i, _))| i == binding)
                    .map_or(String::new(), |(n, _)| n.clone());
                return Err(Error::Other(format!(
                    "{}: binding \"{name}\" is {ty:?} in the shader",
                    self.name
                )));
            }
            match b {
                Bind::Buffer(buf) => buf_infos.push(
                    vk::DescriptorBufferInfo::default()
                        .buffer(buf.raw)
                        .range(vk::WHOLE_SIZE),
                ),
                Bind::BufferRange(buf, offset, size) => buf_infos.push(
                    vk::DescriptorBufferInfo::default()
                        .buffer(buf.raw)
                        .offset(*offset)
                        .range(*size),
                ),
                Bind::StorageImage(img) => img_infos.push(
                    vk::DescriptorImageInfo::default()
                        .image_view(img.view)
                        .image_layout(vk::ImageLayout::GENERAL),
                ),
                Bind::Sampled(img, s) => img_infos.push(
                    vk::DescriptorImageInfo::default()
                        .image_view(img.view)
                        .sampler(*s)
                        .image_layout(vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL),
                ),
                Bind::Accel(a) => accels.push([*a]),
            }
        }
        let mut as_writes: Vec<vk::WriteDescriptorSetAccelerationStructureKHR> = accels
            .iter()
            .map(|a| {
                vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(a)
            })
            .collect();
        let (mut bi, mut ii) = (0, 0);
        let mut as_iter = as_writes.iter_mut();
        let mut writes = Vec::with_capacity(binds.len());
        for (binding, b) in binds {
            let ty = self.bindings[binding].0;
            let w = vk::WriteDescriptorSet::default()
                .dst_binding(*binding)
                .descriptor_type(ty);
            let w = match b {
                Bind::Buffer(_) | Bind::BufferRange(..) => {
                    bi += 1;
                    w.buffer_info(std::slice::from_ref(&buf_infos[bi - 1]))
                }
                Bind::StorageImage(_) | Bind::Sampled(..) => {
                    ii += 1;
                    w.image_info(std::slice::from_ref(&img_infos[ii - 1]))
                }
                // The count is not implied by a pNext struct: set it explicitly.
                Bind::Accel(_) => w
                    .descriptor_count(1)
                    .push_next(as_iter.next().expect("one write per accel")),
            };
            writes.push(w);
        }
        unsafe {
            let d = &self.gpu.device;
            d.cmd_bind_pipeline(cmd, self.bind_point, self.raw);
            if !writes.is_empty() {
                self.gpu.push_desc.cmd_push_descriptor_set(
                    cmd,
                    self.bind_point,
                    self.layout,
                    0,
                    &writes,
                );
            }
            if !push.is_empty() {
                d.cmd_push_constants(cmd, self.layout, self.stages, 0, push);
            }
        }
        Ok(())
    }

    /// Binds and dispatches exactly `groups` workgroups (tile-based kernels).
    pub fn dispatch_groups(
        &self,
        cmd: vk::CommandBuffer,
        binds: &[(&str, Bind)],
        push: &[u8],
        groups: (u32, u32, u32),
    ) -> Result<()> {
        self.bind(cmd, binds, push)?;
        unsafe {
            self.gpu
                .device
                .cmd_dispatch(cmd, groups.0, groups.1, groups.2)
        };
        Ok(())
    }

    /// Binds and dispatches enough workgroups to cover `threads` invocations.
    pub fn dispatch(
        &self,
        cmd: vk::CommandBuffer,
        binds: &[(&str, Bind)],
        push: &[u8],
        threads: (u32, u32, u32),
    ) -> Result<()> {
        self.bind(cmd, binds, push)?;
        let (wx, wy, wz) = self.workgroup;
        unsafe {
            self.gpu.device.cmd_dispatch(
                cmd,
                threads.0.div_ceil(wx),
                threads.1.div_ceil(wy),
                threads.2.div_ceil(wz),
            )
        };
        Ok(())
    }
}
