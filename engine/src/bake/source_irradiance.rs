//! Source irradiance `E_src_i` (§4.1.1, Fig. 3): `shaders_glsl/bake/source_irradiance.comp`.
//! Declared original lights give their direct part by next-event estimation (the shader's
//! header says how it joins the views' indirect part without counting light twice).

use crate::gpu::shaders;
use std::sync::Arc;

use glam::Vec3;

use super::random::{cosine_dir, rand2};
use super::views::{facing_normal, GpuViews, ViewData};
use super::GpuLight;
use crate::error::Result;
use crate::gpu::{bytes_of, vk, Bind, Buffer, Gpu, Graph, Pipeline, RayScene};
use crate::scene::{Light, Mesh};

pub use crate::constants::{LEAK_PX, LIGHT_SKIN};

/// Whether view pixel `q` (global index) shows, or bleeds from, a declared light.
pub(super) fn near_light(d: &ViewData, lights: &[GpuLight], q: usize) -> bool {
    let g = d.pos[q];
    let margin = LEAK_PX * g[3] / d.cameras[q / d.pixels()].fx;
    let p = Vec3::from_slice(&g[..3]);
    lights
        .iter()
        .any(|l| l.near(p, LIGHT_SKIN + margin, margin))
}

/// Which terms of the estimator a pass computes (`parts` in the shader): the declared lights'
/// next-event estimation, the cosine rays gathering the views' radiance, or both.
pub const PART_DIRECT: u32 = 1;
pub const PART_INDIRECT: u32 = 2;
pub const PART_ALL: u32 = PART_DIRECT | PART_INDIRECT;

/// The push constants of every pass that includes `source_irradiance.glsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct Push {
    pub view: u32,
    pub width: u32,
    pub height: u32,
    pub nviews: u32,
    pub samples: u32,
    pub seed: u32,
    pub nlights: u32,
    pub count: u32,
    pub parts: u32,
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    Push,
    [
        shaders::BAKE_SOURCE_IRRADIANCE,
        shaders::BAKE_SOURCE_IRRADIANCE_VERTICES,
        shaders::BAKE_SOURCE_CACHE
    ],
    [view, width, height, nviews, samples, seed, nlights, count, parts]
);

/// Random streams of vertices start past every pixel's (`VERTEX_KEY` in the shader).
const VERTEX_KEY: u32 = 0x8000_0000;

pub struct SourceIrradiance {
    pipeline: Pipeline,
    /// The same estimator at mesh vertices (for the radiance mesh).
    vertices: Pipeline,
    /// The scene's declared original lights (one zero light when there are none: Vulkan has
    /// no empty buffers).
    lights: Buffer,
    nlights: u32,
}

/// The declared original lights of `lights`, as the shader reads them.
pub fn original_lights(lights: &[Light]) -> Vec<GpuLight> {
    lights
        .iter()
        .filter(|l| l.original)
        .map(GpuLight::new)
        .collect()
}

/// The declared original lights of `lights` in a storage buffer, and their count (one zero
/// light when there are none: Vulkan has no empty buffers).
pub(super) fn lights_buffer(gpu: &Arc<Gpu>, lights: &[Light]) -> Result<(Buffer, u32)> {
    let gl = original_lights(lights);
    let n = gl.len() as u32;
    let data = if gl.is_empty() {
        vec![bytemuck::Zeroable::zeroed()]
    } else {
        gl
    };
    let buf = Buffer::from_slice(
        gpu,
        "original lights",
        vk::BufferUsageFlags::STORAGE_BUFFER,
        &data,
    )?;
    Ok((buf, n))
}

impl SourceIrradiance {
    /// `lights`: the scene's lights; the original ones among them are sampled directly.
    pub fn new(gpu: &Arc<Gpu>, lights: &[Light]) -> Result<SourceIrradiance> {
        let (lights, nlights) = lights_buffer(gpu, lights)?;
        Ok(SourceIrradiance {
            pipeline: Pipeline::compute(gpu, shaders::BAKE_SOURCE_IRRADIANCE)?,
            vertices: Pipeline::compute(gpu, shaders::BAKE_SOURCE_IRRADIANCE_VERTICES)?,
            lights,
            nlights,
        })
    }

    /// Records E_src of `view` into `out` (one vec4 per pixel: rgb irradiance, w = rays used).
    /// `radiance`: the filled radiance mesh (`radiance_mesh`), for hits no view sees.
    #[allow(clippy::too_many_arguments)]
    pub fn record<'a>(
        &'a self,
        g: &mut Graph<'a, '_>,
        mesh: &'a RayScene,
        radiance: &'a Buffer,
        views: &'a GpuViews,
        view: u32,
        samples: u32,
        seed: u32,
        out: &'a Buffer,
    ) -> Result<()> {
        let r = (view, samples, seed, PART_ALL);
        self.record_parts(g, mesh, radiance, views, r, out)
    }

    /// `record` of the estimator's `parts` alone ([`PART_DIRECT`], [`PART_INDIRECT`]).
    fn record_parts<'a>(
        &'a self,
        g: &mut Graph<'a, '_>,
        mesh: &'a RayScene,
        radiance: &'a Buffer,
        views: &'a GpuViews,
        (view, samples, seed, parts): (u32, u32, u32, u32),
        out: &'a Buffer,
    ) -> Result<()> {
        let push = Push {
            view,
            width: views.width,
            height: views.height,
            nviews: views.count,
            samples,
            seed,
            nlights: self.nlights,
            count: 0,
            parts,
        };
        let mut binds = vec![
            ("tlas", Bind::Accel(mesh.tlas.raw)),
            ("Out", Bind::Buffer(out)),
            ("Lights", Bind::Buffer(&self.lights)),
            ("Indices", Bind::Buffer(&mesh.indices)),
            ("Radiance", Bind::Buffer(radiance)),
        ];
        binds.extend([views.bind()]);
        let threads = (views.width * views.height, 1, 1);
        g.pass(
            "source irradiance",
            &self.pipeline,
            binds,
            bytes_of(&push),
            threads,
        )
    }

    /// One tiny dispatch so that the driver compiles the shader (lavapipe compiles at first
    /// use), keeping compilation out of timings.
    pub fn record_warm(
        &self,
        gpu: &Arc<Gpu>,
        mesh: &RayScene,
        radiance: &Buffer,
        views: &GpuViews,
        out: &Buffer,
    ) -> Result<()> {
        let mut res = Ok(());
        gpu.submit(|cmd| {
            let mut g = Graph::new(gpu, cmd, None);
            res = self.record(&mut g, mesh, radiance, views, 0, 1, 0, out)
        })?;
        res
    }

    /// Runs one view and reads the result back.
    pub fn run(
        &self,
        mesh: &RayScene,
        radiance: &Buffer,
        views: &GpuViews,
        view: u32,
        samples: u32,
        seed: u32,
    ) -> Result<Vec<[f32; 4]>> {
        let gpu = &self.pipeline.gpu;
        super::views::run_pixels(gpu, views, |cmd, out| {
            let mut g = Graph::new(gpu, cmd, None);
            self.record(&mut g, mesh, radiance, views, view, samples, seed, out)
        })
    }

    /// Runs the `parts` of the estimator for one view and reads the result back.
    pub fn run_parts(
        &self,
        mesh: &RayScene,
        radiance: &Buffer,
        views: &GpuViews,
        (view, samples, seed): (u32, u32, u32),
        parts: u32,
    ) -> Result<Vec<[f32; 4]>> {
        let gpu = &self.pipeline.gpu;
        super::views::run_pixels(gpu, views, |cmd, out| {
            let r = (view, samples, seed, parts);
            self.record_parts(
                &mut Graph::new(gpu, cmd, None),
                mesh,
                radiance,
                views,
                r,
                out,
            )
        })
    }

    /// The declared original lights as the shader reads them, and their count.
    pub(super) fn lights(&self) -> (&Buffer, u32) {
        (&self.lights, self.nlights)
    }

    /// The `parts` of E_src at points `first..first + count` of `positions` (vec3 each: the
    /// mesh's vertices, or the source cache's texels; normals: one unit vec4 per point, zero to
    /// skip), no view excluded; one vec4 per point as the per-pixel pass.
    #[allow(clippy::too_many_arguments)]
    pub fn run_vertices(
        &self,
        mesh: &RayScene,
        radiance: &Buffer,
        views: &GpuViews,
        positions: &Buffer,
        normals: &Buffer,
        (first, count): (u32, u32),
        samples: u32,
        seed: u32,
        parts: u32,
    ) -> Result<Vec<[f32; 4]>> {
        let push = Push {
            view: first,
            width: views.width,
            height: views.height,
            nviews: views.count,
            samples,
            seed,
            nlights: self.nlights,
            count,
            parts,
        };
        let gpu = &self.pipeline.gpu;
        super::views::run_vertices(gpu, count, |cmd, out| {
            let mut binds = vec![
                ("tlas", Bind::Accel(mesh.tlas.raw)),
                ("Out", Bind::Buffer(out)),
                ("Lights", Bind::Buffer(&self.lights)),
                ("Indices", Bind::Buffer(&mesh.indices)),
                ("Radiance", Bind::Buffer(radiance)),
                ("Verts", Bind::Buffer(positions)),
                ("Normals", Bind::Buffer(normals)),
            ];
            binds.extend([views.bind()]);
            let g = &mut Graph::new(gpu, cmd, None);
            g.pass(
                "source irradiance (vertices)",
                &self.vertices,
                binds,
                bytes_of(&push),
                (count, 1, 1),
            )
        })
    }
}

/// Whether the ray (o, d), whose proxy hit is `hit` (distance, point), meets a declared light
/// first (`meets_light` in the shader).
fn meets_light(lights: &[GpuLight], o: Vec3, d: Vec3, hit: Option<(f32, Vec3)>) -> bool {
    lights.iter().any(|l| {
        let Some(tl) = l.hit(o, d) else {
            return false;
        };
        match hit {
            None => true,
            Some((t, y)) => {
                tl <= t || (y - Vec3::from_slice(&l.p0[..3])).dot(l.normal()).abs() < LIGHT_SKIN
            }
        }
    })
}

/// The radiance mesh at barycentrics `bary` of triangle `tri`; w = 1 when all three corners
/// have a radiance (`mesh_radiance` in the shader).
fn mesh_radiance(mesh: &Mesh, radiance: &[[f32; 4]], tri: u32, bary: [f32; 2]) -> [f32; 4] {
    let b = [1.0 - bary[0] - bary[1], bary[0], bary[1]];
    let mut r = [0.0, 0.0, 0.0, 1.0f32];
    for (k, &v) in mesh.triangles[tri as usize].iter().enumerate() {
        let c = radiance[v as usize];
        for i in 0..3 {
            r[i] += b[k] * c[i];
        }
        if c[3] <= 0.0 {
            r[3] = 0.0;
        }
    }
    r
}

/// What the CPU references share: the scene, its views, declared lights and radiance mesh.
pub struct RefScene<'a> {
    pub mesh: &'a Mesh,
    pub radiance: &'a [[f32; 4]],
    pub views: &'a ViewData,
    pub lights: &'a [GpuLight],
}

/// The estimator's `parts` at x (normal n), views other than `exclude`, random stream `key`
/// (`source_irradiance` in the shader).
#[allow(clippy::too_many_arguments)]
pub(super) fn estimate(
    r: &RefScene,
    x: Vec3,
    n: Vec3,
    exclude: usize,
    key: u32,
    samples: u32,
    seed: u32,
    parts: u32,
) -> [f32; 4] {
    let (d, lights) = (r.views, r.lights);
    let nl = lights.len() as u32;
    let (mut sum, mut direct, mut valid, mut on_light) = (Vec3::ZERO, Vec3::ZERO, 0u32, 0u32);
    for s in 0..samples {
        if nl > 0 && parts & PART_DIRECT != 0 {
            let l = s % nl;
            let per_light = (samples - l).div_ceil(nl) as f32;
            let u = rand2([key, s, !seed]);
            direct += lights[l as usize].direct(r.mesh, x, n, u, LIGHT_SKIN) / per_light;
        }
        if parts & PART_INDIRECT == 0 {
            continue;
        }
        let dir = cosine_dir(n, rand2([key, s, seed]));
        let o = x + n * 1e-3;
        let h = crate::cpu::closest_hit(r.mesh, o, dir, 1e-3, 1e4);
        let hit = h.map(|h| (h.t, o + dir * h.t));
        if meets_light(lights, o, dir, hit) {
            on_light += 1;
            continue;
        }
        let (Some(h), Some((_, y))) = (h, hit) else {
            continue;
        };
        let l = match d
            .best_view(y, dir, exclude)
            .filter(|&q| !d.clipped(q) && !near_light(d, lights, q))
        {
            Some(q) => [d.img[q][0], d.img[q][1], d.img[q][2], 1.0],
            None => mesh_radiance(r.mesh, r.radiance, h.tri, h.bary),
        };
        if l[3] > 0.0 {
            sum += Vec3::from_slice(&l[..3]);
            valid += 1;
        }
    }
    let mut e = if valid > 0 {
        let n_s = samples as f32;
        sum * std::f32::consts::PI / valid as f32 * (n_s - on_light as f32) / n_s
    } else {
        Vec3::ZERO
    };
    e += direct;
    [e.x, e.y, e.z, (valid + on_light) as f32]
}

/// CPU reference of the per-pixel pass (same random numbers, brute-force ray casting).
pub fn reference(r: &RefScene, view: usize, samples: u32, seed: u32) -> Vec<[f32; 4]> {
    let d = r.views;
    let npix = d.pixels();
    (0..npix)
        .map(|p| {
            let gi = view * npix + p;
            if d.pos[gi][3] <= 0.0 {
                return [0.0; 4];
            }
            let x = Vec3::from_slice(&d.pos[gi][..3]);
            let n = facing_normal(d, gi, view);
            estimate(r, x, n, view, gi as u32, samples, seed, PART_ALL)
        })
        .collect()
}

/// CPU reference of the per-vertex pass at `positions` (the mesh's vertices or the texels).
pub fn reference_vertices(
    r: &RefScene,
    positions: &[[f32; 3]],
    normals: &[Vec3],
    samples: u32,
    seed: u32,
    parts: u32,
) -> Vec<[f32; 4]> {
    positions
        .iter()
        .zip(normals)
        .enumerate()
        .map(|(v, (p, n))| {
            if n.length_squared() < 0.5 {
                return [0.0; 4];
            }
            let key = VERTEX_KEY.wrapping_add(v as u32);
            estimate(r, Vec3::from(*p), *n, usize::MAX, key, samples, seed, parts)
        })
        .collect()
}
