//! Source mirror images `M_src_i` (§4.2.1): `shaders_glsl/bake/mirror.comp`.

use crate::gpu::shaders;
use std::sync::Arc;

use glam::Vec3;

use super::views::{facing_normal, GpuViews, ViewData};
use crate::error::Result;
use crate::gpu::{bytes_of, Bind, Buffer, Gpu, Graph, Pipeline, RayScene};
use crate::scene::Mesh;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    view: u32,
    width: u32,
    height: u32,
    nviews: u32,
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout =
    crate::push_layout!(Push, [shaders::BAKE_MIRROR], [view, width, height, nviews]);

pub struct Mirror {
    pipeline: Pipeline,
}

impl Mirror {
    pub fn new(gpu: &Arc<Gpu>) -> Result<Mirror> {
        Ok(Mirror {
            pipeline: Pipeline::compute(gpu, shaders::BAKE_MIRROR)?,
        })
    }

    /// Records M_src of `view` into `out` (vec4 per pixel: rgb, w = 1 where a view was found).
    pub fn record<'a>(
        &self,
        g: &mut Graph<'a, '_>,
        mesh: &'a RayScene,
        views: &'a GpuViews,
        view: u32,
        out: &'a Buffer,
    ) -> Result<()> {
        let push = Push {
            view,
            width: views.width,
            height: views.height,
            nviews: views.count,
        };
        let mut binds = vec![
            ("tlas", Bind::Accel(mesh.tlas.raw)),
            ("Out", Bind::Buffer(out)),
        ];
        binds.extend([views.bind()]);
        g.pass(
            "mirror",
            &self.pipeline,
            binds,
            bytes_of(&push),
            (views.width * views.height, 1, 1),
        )
    }

    pub fn run(&self, mesh: &RayScene, views: &GpuViews, view: u32) -> Result<Vec<[f32; 4]>> {
        let gpu = &self.pipeline.gpu;
        super::views::run_pixels(gpu, views, |cmd, out| {
            self.record(&mut Graph::new(gpu, cmd, None), mesh, views, view, out)
        })
    }
}

/// CPU reference.
pub fn reference(mesh: &Mesh, d: &ViewData, view: usize) -> Vec<[f32; 4]> {
    let npix = d.pixels();
    let eye = d.cameras[view].center();
    (0..npix)
        .map(|p| {
            let gi = view * npix + p;
            if d.pos[gi][3] <= 0.0 {
                return [0.0; 4];
            }
            let x = Vec3::from_slice(&d.pos[gi][..3]);
            let n = facing_normal(d, gi, view);
            let v = (x - eye).normalize();
            let r = v - 2.0 * n.dot(v) * n;
            let o = x + n * 1e-3;
            let Some(h) = crate::cpu::closest_hit(mesh, o, r, 1e-3, 1e4) else {
                return [0.0; 4];
            };
            match d.best_view(o + r * h.t, r, view) {
                Some(q) => [d.img[q][0], d.img[q][1], d.img[q][2], 1.0],
                None => [0.0; 4],
            }
        })
        .collect()
}
