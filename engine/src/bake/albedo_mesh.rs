//! Albedo mesh `a(v)` (§4.1.2): `shaders_glsl/bake/albedo_mesh.comp`. `a = π·I/E_src`: the
//! paper's `I/E` with E as irradiance in W/m² (a Lambertian surface has I = ρ/π·E).

use std::sync::Arc;

use glam::Vec3;

use super::views::{GpuViews, ViewData};
use crate::error::Result;
use crate::gpu::{bytes_of, vk, Bind, Buffer, Gpu, MemoryLocation, Pipeline, RayScene};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    nverts: u32,
    width: u32,
    height: u32,
    nviews: u32,
}

pub struct AlbedoMesh {
    pipeline: Pipeline,
}

impl AlbedoMesh {
    pub fn new(gpu: &Arc<Gpu>) -> Result<AlbedoMesh> {
        Ok(AlbedoMesh {
            pipeline: Pipeline::compute(gpu, "bake/albedo_mesh.comp")?,
        })
    }

    /// Per-vertex albedo (rgb, w = weight sum; 0 where no view sees the vertex) from the E_src of
    /// all views (`e_src`: view-major vec4 per pixel).
    pub fn run(
        &self,
        mesh: &RayScene,
        nverts: u32,
        views: &GpuViews,
        e_src: &Buffer,
    ) -> Result<Vec<[f32; 4]>> {
        let gpu = &self.pipeline.gpu;
        let out = Buffer::new(
            gpu,
            "albedo",
            nverts as u64 * 16,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        let push = Push {
            nverts,
            width: views.width,
            height: views.height,
            nviews: views.count,
        };
        let mut binds = vec![
            (4, Bind::Buffer(&mesh.positions)),
            (5, Bind::Buffer(e_src)),
            (6, Bind::Buffer(&out)),
        ];
        binds.extend(views.binds(0));
        let mut res = Ok(());
        gpu.submit(|cmd| {
            res = self
                .pipeline
                .dispatch(cmd, &binds, bytes_of(&push), (nverts, 1, 1))
        })?;
        res?;
        let mut v: Vec<[f32; 4]> = out.download_vec()?;
        v.truncate(nverts as usize);
        Ok(v)
    }
}

/// CPU reference.
pub fn reference(positions: &[[f32; 3]], d: &ViewData, e_src: &[[f32; 4]]) -> Vec<[f32; 4]> {
    positions
        .iter()
        .map(|p| {
            let p = Vec3::from(*p);
            let (mut sum, mut wsum) = (Vec3::ZERO, 0.0f32);
            for j in 0..d.cameras.len() {
                let Some(q) = d.visible_pixel(j, p) else {
                    continue;
                };
                let e = e_src[q];
                if e[3] <= 0.0 || e[0].max(e[1]).max(e[2]) <= 1e-6 {
                    continue;
                }
                let w = 1.0 / (d.cameras[j].center() - p).length().max(1e-3);
                let i = Vec3::from_slice(&d.img[q][..3]);
                sum +=
                    w * std::f32::consts::PI * i / Vec3::from_slice(&e[..3]).max(Vec3::splat(1e-6));
                wsum += w;
            }
            let a = if wsum > 0.0 { sum / wsum } else { Vec3::ZERO };
            [a.x, a.y, a.z, wsum]
        })
        .collect()
}
