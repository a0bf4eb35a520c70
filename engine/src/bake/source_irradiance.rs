//! Source irradiance `E_src_i` (§4.1.1, Fig. 3): `shaders_glsl/bake/source_irradiance.comp`.

use std::sync::Arc;

use glam::Vec3;

use super::random::{cosine_dir, rand2};
use super::views::{facing_normal, GpuViews, ViewData};
use crate::error::Result;
use crate::gpu::{bytes_of, vk, Bind, Buffer, Gpu, Pipeline, RayScene};
use crate::scene::Mesh;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    view: u32,
    width: u32,
    height: u32,
    nviews: u32,
    samples: u32,
    seed: u32,
}

pub struct SourceIrradiance {
    pipeline: Pipeline,
}

impl SourceIrradiance {
    pub fn new(gpu: &Arc<Gpu>) -> Result<SourceIrradiance> {
        Ok(SourceIrradiance {
            pipeline: Pipeline::compute(gpu, "bake/source_irradiance.comp")?,
        })
    }

    /// Records E_src of `view` into `out` (one vec4 per pixel: rgb irradiance, w = rays used).
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        cmd: vk::CommandBuffer,
        mesh: &RayScene,
        views: &GpuViews,
        view: u32,
        samples: u32,
        seed: u32,
        out: &Buffer,
    ) -> Result<()> {
        let push = Push {
            view,
            width: views.width,
            height: views.height,
            nviews: views.count,
            samples,
            seed,
        };
        let mut binds = vec![(0, Bind::Accel(mesh.tlas.raw)), (5, Bind::Buffer(out))];
        binds.extend(views.binds(1));
        self.pipeline.dispatch(
            cmd,
            &binds,
            bytes_of(&push),
            (views.width * views.height, 1, 1),
        )
    }

    /// One tiny dispatch so that the driver compiles the shader (lavapipe compiles at first
    /// use), keeping compilation out of timings.
    pub fn record_warm(
        &self,
        gpu: &Arc<Gpu>,
        mesh: &RayScene,
        views: &GpuViews,
        out: &Buffer,
    ) -> Result<()> {
        let mut res = Ok(());
        gpu.submit(|cmd| res = self.record(cmd, mesh, views, 0, 1, 0, out))?;
        res
    }

    /// Runs one view and reads the result back.
    pub fn run(
        &self,
        mesh: &RayScene,
        views: &GpuViews,
        view: u32,
        samples: u32,
        seed: u32,
    ) -> Result<Vec<[f32; 4]>> {
        super::views::run_pixels(&self.pipeline.gpu, views, |cmd, out| {
            self.record(cmd, mesh, views, view, samples, seed, out)
        })
    }
}

/// CPU reference of the same estimator (same random numbers, brute-force ray casting).
pub fn reference(mesh: &Mesh, d: &ViewData, view: usize, samples: u32, seed: u32) -> Vec<[f32; 4]> {
    let npix = d.pixels();
    (0..npix)
        .map(|p| {
            let gi = view * npix + p;
            if d.pos[gi][3] <= 0.0 {
                return [0.0; 4];
            }
            let x = Vec3::from_slice(&d.pos[gi][..3]);
            let n = facing_normal(d, gi, view);
            let (mut sum, mut valid) = (Vec3::ZERO, 0u32);
            for s in 0..samples {
                let dir = cosine_dir(n, rand2([gi as u32, s, seed]));
                let o = x + n * 1e-3;
                let Some(h) = crate::cpu::closest_hit(mesh, o, dir, 1e-3, 1e4) else {
                    continue;
                };
                let y = o + dir * h.t;
                if let Some(q) = d.best_view(y, dir, view) {
                    sum += Vec3::from_slice(&d.img[q][..3]);
                    valid += 1;
                }
            }
            let e = if valid > 0 {
                sum * std::f32::consts::PI / valid as f32
            } else {
                Vec3::ZERO
            };
            [e.x, e.y, e.z, valid as f32]
        })
        .collect()
}
