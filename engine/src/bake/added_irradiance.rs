//! Added irradiance `E_add_i,l` (§4.1.3): `shaders_glsl/bake/added_irradiance.comp`. One map per
//! view and user light, so that light intensities mix linearly at run time.

use crate::gpu::shaders;
use std::sync::Arc;

use glam::Vec3;

use super::added_light::{AddedParams, GpuLight};
use super::random::rand2;
use super::surface_cache::{CacheLayout, GpuCacheLayout};
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
    samples: u32,
    seed: u32,
    pad: [u32; 3],
    light: GpuLight,
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    Push,
    [shaders::BAKE_ADDED_IRRADIANCE],
    [
        view,
        width,
        height,
        samples,
        seed,
        pad,
        light.p0,
        light.p1,
        light.p2,
        light.radiance
    ]
);

pub struct AddedIrradiance {
    pipeline: Pipeline,
}

impl AddedIrradiance {
    pub fn new(gpu: &Arc<Gpu>) -> Result<AddedIrradiance> {
        Ok(AddedIrradiance {
            pipeline: Pipeline::compute(gpu, shaders::BAKE_ADDED_IRRADIANCE)?,
        })
    }

    /// Records E_add of `view` for `light` into `out` (vec4 per pixel): direct light per pixel
    /// plus the light's surface cache `cache` (vec4 per texel of `layout`).
    #[allow(clippy::too_many_arguments)]
    pub fn record<'a>(
        &self,
        g: &mut Graph<'a, '_>,
        mesh: &'a RayScene,
        views: &'a GpuViews,
        layout: &'a GpuCacheLayout,
        cache: &'a Buffer,
        view: u32,
        light: &GpuLight,
        p: AddedParams,
        out: &'a Buffer,
    ) -> Result<()> {
        let push = Push {
            view,
            width: views.width,
            height: views.height,
            samples: p.samples,
            seed: p.seed,
            pad: [0; 3],
            light: *light,
        };
        let mut binds = vec![
            ("tlas", Bind::Accel(mesh.tlas.raw)),
            ("Verts", Bind::Buffer(&mesh.positions)),
            ("Indices", Bind::Buffer(&mesh.indices)),
            ("Cache", Bind::Buffer(cache)),
            ("Corners", Bind::Buffer(&layout.corners)),
            ("Out", Bind::Buffer(out)),
        ];
        binds.extend([views.bind()]);
        g.pass(
            "added irradiance",
            &self.pipeline,
            binds,
            bytes_of(&push),
            (views.width * views.height, 1, 1),
        )
    }

    /// Runs one view: E_add, vec4 per pixel.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        &self,
        mesh: &RayScene,
        views: &GpuViews,
        layout: &GpuCacheLayout,
        cache: &Buffer,
        view: u32,
        light: &GpuLight,
        p: AddedParams,
    ) -> Result<Map> {
        let gpu = &self.pipeline.gpu;
        super::views::run_pixels(gpu, views, |cmd, out| {
            let g = &mut Graph::new(gpu, cmd, None);
            self.record(g, mesh, views, layout, cache, view, light, p, out)
        })
    }
}

/// One vec4 per pixel of a view.
pub type Map = Vec<[f32; 4]>;

/// CPU reference of added_irradiance.comp: direct light per pixel plus the cache lookup.
#[allow(clippy::too_many_arguments)]
pub fn reference(
    mesh: &Mesh,
    d: &ViewData,
    layout: &CacheLayout,
    cache: &[[f32; 4]],
    view: usize,
    light: &GpuLight,
    p: AddedParams,
) -> Map {
    let npix = d.pixels();
    (0..npix)
        .map(|px| {
            let gi = view * npix + px;
            if d.pos[gi][3] <= 0.0 || d.tri[gi] == 0 {
                return [0.0; 4];
            }
            let n = facing_normal(d, gi, view);
            let x = Vec3::from_slice(&d.pos[gi][..3]);
            let dir = (0..p.samples)
                .map(|s| light.direct(mesh, x, n, rand2([gi as u32, s * 64, p.seed]), light.lift()))
                .sum::<Vec3>()
                / p.samples as f32;
            let e = dir + layout.lookup(mesh, cache, d.tri[gi] as usize - 1, x);
            e.extend(1.0).into()
        })
        .collect()
}
