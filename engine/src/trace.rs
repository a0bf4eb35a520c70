//! Generic ray casting with VK_KHR_ray_query (`shaders_glsl/trace/rays.comp`): closest hits or
//! occlusion for a batch of rays. The device tests check it against [`crate::cpu`], and
//! `relit bench rays` measures it.

use crate::gpu::shaders;
use std::sync::Arc;

use crate::error::Result;
use crate::gpu::{bytes_of, vk, Bind, Buffer, Gpu, Graph, Pipeline, RayScene};

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Ray {
    pub origin: [f32; 3],
    pub tmin: f32,
    pub dir: [f32; 3],
    pub tmax: f32,
}

/// `tri == u32::MAX` when nothing was hit.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Hit {
    pub t: f32,
    pub tri: u32,
    pub bary: [f32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    count: u32,
    occlusion: u32,
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout =
    crate::push_layout!(Push, [shaders::TRACE_RAYS], [count, occlusion]);

pub struct RayCaster {
    pub pipeline: Pipeline,
}

impl RayCaster {
    pub fn new(gpu: &Arc<Gpu>) -> Result<RayCaster> {
        Ok(RayCaster {
            pipeline: Pipeline::compute(gpu, shaders::TRACE_RAYS)?,
        })
    }

    /// Records the cast of `count` rays from `rays` into `hits`.
    pub fn record(
        &self,
        g: &mut Graph,
        scene: &RayScene,
        rays: &Buffer,
        hits: &Buffer,
        count: u32,
        occlusion: bool,
    ) -> Result<()> {
        let push = Push {
            count,
            occlusion: occlusion as u32,
        };
        g.dispatch_with(
            "ray cast",
            &self.pipeline,
            &[
                ("tlas", Bind::Accel(scene.tlas.raw)),
                ("Rays", Bind::Buffer(rays)),
                ("Hits", Bind::Buffer(hits)),
            ],
            bytes_of(&push),
            (count, 1, 1),
        )
    }

    /// Casts `rays` and reads the hits back.
    pub fn cast(&self, scene: &RayScene, rays: &[Ray], occlusion: bool) -> Result<Vec<Hit>> {
        let gpu = &self.pipeline.gpu;
        let rb = Buffer::from_slice(gpu, "rays", vk::BufferUsageFlags::STORAGE_BUFFER, rays)?;
        let hb = Buffer::new(
            gpu,
            "hits",
            (rays.len() * std::mem::size_of::<Hit>()) as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            crate::gpu::MemoryLocation::GpuOnly,
        )?;
        let mut res = Ok(());
        gpu.submit(|cmd| {
            let g = &mut Graph::new(gpu, cmd, None);
            res = self.record(g, scene, &rb, &hb, rays.len() as u32, occlusion)
        })?;
        res?;
        let mut hits: Vec<Hit> = hb.download_vec()?;
        hits.truncate(rays.len());
        Ok(hits)
    }
}
