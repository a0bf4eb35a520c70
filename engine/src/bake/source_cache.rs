//! The source cache: E_src (§4.1.1) from its two parts, each computed where it is cheapest
//! (`shaders_glsl/bake/source_cache.comp`). The views' indirect part — cosine rays gathering the
//! views' radiance — varies slowly across a surface and does not depend on the view, so it is
//! traced once per texel of the bake mesh (the surface cache's layout; `source_irradiance_vertices
//! .comp`) and filtered along the mesh. The declared original lights' direct part, which casts
//! the sharp shadows, stays per pixel (next-event estimation). On the demo room this replaces 32
//! gathering rays at each of 1.57 M view pixels by a few hundred at each of ~90 k texels.
//!
//! Only for scenes that declare their original lights: without them the direct light arrives
//! through the views' pixels as well, and texels would blur its shadows.

use crate::gpu::shaders;
use std::sync::Arc;

use glam::Vec3;

use super::source_irradiance::{
    estimate, Push, RefScene, SourceIrradiance, PART_DIRECT, PART_INDIRECT,
};
use super::surface_cache::{barycentrics, CacheLayout, GpuCacheLayout};
use super::views::{facing_normal, GpuViews};
use crate::error::Result;
use crate::gpu::{bytes_of, vk, Bind, Buffer, Gpu, Graph, Pipeline, RayScene};

/// Texels per dispatch: a few seconds each on lavapipe, so progress shows as it goes.
const CHUNK: u32 = 8192;

/// Traces the indirect part of E_src at every texel of `layout` (`samples` cosine rays each),
/// reporting texels done, and filters it along the mesh (`rounds`, see [`finish`]).
#[allow(clippy::too_many_arguments)]
pub fn trace(
    gpu: &Arc<Gpu>,
    si: &SourceIrradiance,
    mesh: &RayScene,
    radiance: &Buffer,
    views: &GpuViews,
    layout: &CacheLayout,
    (samples, seed, rounds): (u32, u32, u32),
    progress: &mut dyn FnMut(u32, u32),
) -> Result<Vec<[f32; 4]>> {
    let n = layout.texels() as u32;
    if n == 0 {
        return Ok(Vec::new());
    }
    let pos: Vec<[f32; 3]> = layout.pos.iter().map(|p| [p[0], p[1], p[2]]).collect();
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let pb = Buffer::from_slice(gpu, "source cache texels", storage, &pos)?;
    let nb = Buffer::from_slice(gpu, "source cache normals", storage, &layout.nrm)?;
    let mut raw = Vec::with_capacity(n as usize);
    let mut first = 0;
    while first < n {
        let count = CHUNK.min(n - first);
        raw.extend(si.run_vertices(
            mesh,
            radiance,
            views,
            &pb,
            &nb,
            (first, count),
            samples,
            seed,
            PART_INDIRECT,
        )?);
        first += count;
        progress(first, n);
    }
    Ok(finish(layout, &raw, rounds))
}

/// The traced values as the cache keeps them: w = 1 where a texel's rays found radiance (the
/// estimator's w counts them), then `rounds` of the surface cache's filter along the mesh, which
/// also fills texels without an estimate from their neighbours.
pub fn finish(layout: &CacheLayout, raw: &[[f32; 4]], rounds: u32) -> Vec<[f32; 4]> {
    let marked: Vec<[f32; 4]> = raw
        .iter()
        .map(|v| {
            if v[3] > 0.0 {
                [v[0], v[1], v[2], 1.0]
            } else {
                [0.0; 4]
            }
        })
        .collect();
    layout.filter(&marked, rounds)
}

/// CPU reference of the texels' tracing, before [`finish`].
pub fn reference_texels(
    r: &RefScene,
    layout: &CacheLayout,
    samples: u32,
    seed: u32,
) -> Vec<[f32; 4]> {
    let pos: Vec<[f32; 3]> = layout.pos.iter().map(|p| [p[0], p[1], p[2]]).collect();
    let nrm: Vec<Vec3> = layout
        .nrm
        .iter()
        .map(|n| Vec3::from_slice(&n[..3]))
        .collect();
    super::source_irradiance::reference_vertices(r, &pos, &nrm, samples, seed, PART_INDIRECT)
}

/// The per-pixel pass: direct part + the cache's indirect part.
pub struct SourceCache {
    pipeline: Pipeline,
}

impl SourceCache {
    pub fn new(gpu: &Arc<Gpu>) -> Result<SourceCache> {
        Ok(SourceCache {
            pipeline: Pipeline::compute(gpu, shaders::BAKE_SOURCE_CACHE)?,
        })
    }

    /// Records E_src of `view` into `out` (one vec4 per pixel: rgb, w = 1 where the cache has
    /// an estimate): `samples` shadow rays per pixel over the declared lights of `si`, plus the
    /// indirect part from `cache` (one vec4 per texel of `layout`).
    #[allow(clippy::too_many_arguments)]
    pub fn record<'a>(
        &'a self,
        g: &mut Graph<'a, '_>,
        si: &'a SourceIrradiance,
        mesh: &'a RayScene,
        radiance: &'a Buffer,
        views: &'a GpuViews,
        (layout, cache): (&'a GpuCacheLayout, &'a Buffer),
        view: u32,
        samples: u32,
        seed: u32,
        out: &'a Buffer,
    ) -> Result<()> {
        let (lights, nlights) = si.lights();
        let push = Push {
            view,
            width: views.width,
            height: views.height,
            nviews: views.count,
            samples,
            seed,
            nlights,
            count: 0,
            parts: PART_DIRECT,
        };
        let mut binds = vec![
            ("tlas", Bind::Accel(mesh.tlas.raw)),
            ("Out", Bind::Buffer(out)),
            ("Lights", Bind::Buffer(lights)),
            ("Indices", Bind::Buffer(&mesh.indices)),
            ("Radiance", Bind::Buffer(radiance)),
            ("Verts", Bind::Buffer(&mesh.positions)),
            ("Cache", Bind::Buffer(cache)),
            ("Corners", Bind::Buffer(&layout.corners)),
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

    /// Runs one view and reads the result back.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        &self,
        si: &SourceIrradiance,
        mesh: &RayScene,
        radiance: &Buffer,
        views: &GpuViews,
        cache: (&GpuCacheLayout, &Buffer),
        view: u32,
        samples: u32,
        seed: u32,
    ) -> Result<Vec<[f32; 4]>> {
        let gpu = &self.pipeline.gpu;
        super::views::run_pixels(gpu, views, |cmd, out| {
            let g = &mut Graph::new(gpu, cmd, None);
            self.record(
                g, si, mesh, radiance, views, cache, view, samples, seed, out,
            )
        })
    }
}

/// CPU reference of the per-pixel pass (same random numbers as the shader).
pub fn reference(
    r: &RefScene,
    layout: &CacheLayout,
    cache: &[[f32; 4]],
    view: usize,
    samples: u32,
    seed: u32,
) -> Vec<[f32; 4]> {
    let d = r.views;
    let npix = d.pixels();
    (0..npix)
        .map(|p| {
            let gi = view * npix + p;
            if d.pos[gi][3] <= 0.0 || d.tri[gi] == 0 {
                return [0.0; 4];
            }
            let x = Vec3::from_slice(&d.pos[gi][..3]);
            let n = facing_normal(d, gi, view);
            let e = estimate(r, x, n, view, gi as u32, samples, seed, PART_DIRECT);
            let tri = d.tri[gi] as usize - 1;
            let [a, b, c] = r.mesh.corners(tri);
            let l = barycentrics(x, a, b, c);
            let (mut ind, mut w) = (Vec3::ZERO, 0.0);
            for k in 0..3 {
                let v = cache[layout.corners[3 * tri + k] as usize];
                ind += l[k] * Vec3::from_slice(&v[..3]);
                w += l[k] * v[3];
            }
            let dir = Vec3::from_slice(&e[..3]);
            if w > 0.0 {
                (dir + ind / w).extend(1.0).into()
            } else {
                dir.extend(0.0).into()
            }
        })
        .collect()
}
