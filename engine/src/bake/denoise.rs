//! Edge-aware denoising of irradiance maps (§4.1.1): `shaders_glsl/bake/denoise.comp`.

use crate::gpu::shaders;
use std::sync::Arc;

use glam::Vec3;

use super::views::{GpuViews, ViewData};
use crate::error::Result;
use crate::gpu::{bytes_of, vk, Bind, Buffer, Gpu, Graph, MemoryLocation, Pipeline};

/// Filter parameters: window radius (px; 0 = off), spatial sigma (px), tangent-plane distance
/// sigma (relative to depth), and the exponent on the normals' cosine.
#[derive(Clone, Copy, Debug)]
pub struct DenoiseParams {
    pub radius: i32,
    pub sigma_px: f32,
    pub sigma_depth: f32,
    pub normal_power: f32,
}

impl Default for DenoiseParams {
    fn default() -> Self {
        DenoiseParams {
            radius: 4,
            sigma_px: 2.5,
            sigma_depth: 0.02,
            normal_power: 32.0,
        }
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    view: u32,
    width: u32,
    height: u32,
    radius: i32,
    sigma_px: f32,
    sigma_depth: f32,
    normal_power: f32,
    with_base: u32,
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    Push,
    [shaders::BAKE_DENOISE],
    [
        view,
        width,
        height,
        radius,
        sigma_px,
        sigma_depth,
        normal_power,
        with_base
    ]
);

pub struct Denoise {
    pipeline: Pipeline,
}

impl Denoise {
    pub fn new(gpu: &Arc<Gpu>) -> Result<Denoise> {
        Ok(Denoise {
            pipeline: Pipeline::compute(gpu, shaders::BAKE_DENOISE)?,
        })
    }

    /// Records the filtering of `input` (this view's map) into `out`. With `base`, `input` is
    /// the noisy part of the map `base`: out = base − input + filtered input.
    #[allow(clippy::too_many_arguments)]
    pub fn record<'a>(
        &'a self,
        g: &mut Graph<'a, '_>,
        views: &'a GpuViews,
        view: u32,
        p: DenoiseParams,
        input: &'a Buffer,
        base: Option<&'a Buffer>,
        out: &'a Buffer,
    ) -> Result<()> {
        let push = Push {
            view,
            width: views.width,
            height: views.height,
            radius: p.radius,
            sigma_px: p.sigma_px,
            sigma_depth: p.sigma_depth,
            normal_power: p.normal_power,
            with_base: base.is_some() as u32,
        };
        let binds = [
            views.bind(),
            ("In", Bind::Buffer(input)),
            ("Out", Bind::Buffer(out)),
            ("Base", Bind::Buffer(base.unwrap_or(input))),
        ];
        let threads = (views.width * views.height, 1, 1);
        g.pass("denoise", &self.pipeline, binds, bytes_of(&push), threads)
    }

    pub fn run(
        &self,
        views: &GpuViews,
        view: u32,
        p: DenoiseParams,
        input: &[[f32; 4]],
        base: Option<&[[f32; 4]]>,
    ) -> Result<Vec<[f32; 4]>> {
        let gpu = &self.pipeline.gpu;
        let up =
            |name, data| Buffer::from_slice(gpu, name, vk::BufferUsageFlags::STORAGE_BUFFER, data);
        let ib = up("denoise in", input)?;
        let bb = base.map(|b| up("denoise base", b)).transpose()?;
        let ob = Buffer::new(
            gpu,
            "denoise out",
            ib.size,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        let mut res = Ok(());
        gpu.submit(|cmd| {
            let mut g = Graph::new(gpu, cmd, None);
            res = self.record(&mut g, views, view, p, &ib, bb.as_ref(), &ob)
        })?;
        res?;
        let mut v: Vec<[f32; 4]> = ob.download_vec()?;
        v.truncate(input.len());
        Ok(v)
    }
}

/// CPU reference.
pub fn reference(
    d: &ViewData,
    view: usize,
    p: DenoiseParams,
    input: &[[f32; 4]],
    with_base: Option<&[[f32; 4]]>,
) -> Vec<[f32; 4]> {
    let (w, h) = (d.width as i32, d.height as i32);
    let base = view * d.pixels();
    (0..d.pixels())
        .map(|pi| {
            let unfiltered = with_base.map_or(input[pi], |b| b[pi]);
            let c = d.pos[base + pi];
            if c[3] <= 0.0 {
                return unfiltered;
            }
            let n = Vec3::from_slice(&d.nrm[base + pi][..3]);
            let (x, y) = (pi as i32 % w, pi as i32 / w);
            let (mut sum, mut wsum) = (Vec3::ZERO, 0.0f32);
            for dy in -p.radius..=p.radius {
                for dx in -p.radius..=p.radius {
                    let (qx, qy) = (x + dx, y + dy);
                    if qx < 0 || qy < 0 || qx >= w || qy >= h {
                        continue;
                    }
                    let qi = (qy * w + qx) as usize;
                    let (g, e) = (d.pos[base + qi], input[qi]);
                    if g[3] <= 0.0 || e[3] <= 0.0 {
                        continue;
                    }
                    let rz = n.dot(Vec3::from_slice(&g[..3]) - Vec3::from_slice(&c[..3]))
                        / (p.sigma_depth * c[3]);
                    let cn = n.dot(Vec3::from_slice(&d.nrm[base + qi][..3])).max(0.0);
                    let wt = (-0.5 * (dx * dx + dy * dy) as f32 / (p.sigma_px * p.sigma_px)
                        - 0.5 * rz * rz)
                        .exp()
                        * cn.powf(p.normal_power)
                        * e[3];
                    sum += wt * Vec3::from_slice(&e[..3]);
                    wsum += wt;
                }
            }
            if wsum <= 0.0 {
                return unfiltered;
            }
            let f = sum / wsum;
            match with_base {
                Some(b) => {
                    let o = Vec3::from_slice(&b[pi][..3]) - Vec3::from_slice(&input[pi][..3]) + f;
                    [o.x, o.y, o.z, b[pi][3].max(1.0)]
                }
                None => [f.x, f.y, f.z, input[pi][3].max(1.0)],
            }
        })
        .collect()
}
