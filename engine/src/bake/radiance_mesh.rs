//! Radiance mesh (§4.1.1's gathering, where no view sees the hit):
//! `shaders_glsl/bake/radiance_mesh.comp`. The views' radiance averaged at each vertex of the
//! bake mesh, pixels on or beside a declared light left out; the vertices no view sees get
//! albedo × irradiance / π (`complete`). Source irradiance reads it for rays whose hit no view
//! sees: before, such rays took the mean of the rays that found a view, which over-estimated
//! E_src by 2.5% (more where more rays went unseen: ceilings, table undersides are darker than
//! the average ray).

use crate::gpu::shaders;
use std::sync::Arc;

use glam::Vec3;

use super::source_irradiance::{lights_buffer, near_light, SourceIrradiance};
use super::views::{GpuViews, ViewData};
use super::GpuLight;
use crate::error::Result;
use crate::gpu::{bytes_of, vk, Bind, Buffer, Gpu, Graph, Pipeline, RayScene};
use crate::scene::meshproc::vertex_normals;
use crate::scene::{Light, Mesh};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    nverts: u32,
    width: u32,
    height: u32,
    nviews: u32,
    nlights: u32,
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    Push,
    [shaders::BAKE_RADIANCE_MESH],
    [nverts, width, height, nviews, nlights]
);

pub struct RadianceMesh {
    pipeline: Pipeline,
    lights: Buffer,
    nlights: u32,
}

impl RadianceMesh {
    /// `lights`: the scene's lights; pixels near the original ones are no radiance samples.
    pub fn new(gpu: &Arc<Gpu>, lights: &[Light]) -> Result<RadianceMesh> {
        let (lights, nlights) = lights_buffer(gpu, lights)?;
        Ok(RadianceMesh {
            pipeline: Pipeline::compute(gpu, shaders::BAKE_RADIANCE_MESH)?,
            lights,
            nlights,
        })
    }

    /// Per-vertex radiance as gathered (rgb, w = weight sum; 0 where no view sees the vertex).
    pub fn run(&self, mesh: &RayScene, nverts: u32, views: &GpuViews) -> Result<Vec<[f32; 4]>> {
        let push = Push {
            nverts,
            width: views.width,
            height: views.height,
            nviews: views.count,
            nlights: self.nlights,
        };
        let gpu = &self.pipeline.gpu;
        super::views::run_vertices(gpu, nverts, |cmd, out| {
            let mut binds = vec![
                ("Verts", Bind::Buffer(&mesh.positions)),
                ("Lights", Bind::Buffer(&self.lights)),
                ("Out", Bind::Buffer(out)),
            ];
            binds.extend([views.bind()]);
            let g = &mut Graph::new(gpu, cmd, None);
            g.pass(
                "radiance mesh",
                &self.pipeline,
                binds,
                bytes_of(&push),
                (nverts, 1, 1),
            )
        })
    }
}

/// CPU reference of the gather.
pub fn reference(positions: &[[f32; 3]], d: &ViewData, lights: &[GpuLight]) -> Vec<[f32; 4]> {
    positions
        .iter()
        .map(|p| {
            let p = Vec3::from(*p);
            let (mut sum, mut wsum) = (Vec3::ZERO, 0.0f32);
            for j in 0..d.cameras.len() {
                let Some(q) =
                    (d.visible_pixel(j, p)).filter(|&q| !d.clipped(q) && !near_light(d, lights, q))
                else {
                    continue;
                };
                let w = 1.0 / (d.cameras[j].center() - p).length().max(1e-3);
                sum += w * Vec3::from_slice(&d.img[q][..3]);
                wsum += w;
            }
            let l = if wsum > 0.0 { sum / wsum } else { Vec3::ZERO };
            [l.x, l.y, l.z, wsum]
        })
        .collect()
}

/// Vertices per dispatch of the per-vertex irradiance.
const CHUNK: u32 = 16384;

/// Completes the gathered radiance (`gathered`: w > 0 where seen) with the per-vertex irradiance
/// `e`: a point no view sees reflects its irradiance times an albedo, and albedo, unlike
/// radiance, varies little across a surface whatever the lighting. So the albedo π·L/E of the
/// seen vertices is filled in across the mesh (as the albedo mesh's is) and an unseen vertex
/// takes ρ·E/π. Filling radiance itself gave a ceiling no view sees the brightness of the walls
/// around it. w = 1 marks every vertex with a radiance.
pub fn complete(triangles: &[[u32; 3]], gathered: &[[f32; 4]], e: &[[f32; 4]]) -> Vec<[f32; 4]> {
    let pi = std::f32::consts::PI;
    let has_e = |e: &[f32; 4]| e[3] > 0.0 && e[0].max(e[1]).max(e[2]) > 1e-6;
    let mut albedo: Vec<[f32; 4]> = gathered
        .iter()
        .zip(e)
        .map(|(l, e)| {
            if l[3] > 0.0 && has_e(e) {
                let a = |k: usize| (pi * l[k] / e[k].max(1e-6)).clamp(0.0, 1.0);
                [a(0), a(1), a(2), 1.0]
            } else {
                [0.0; 4]
            }
        })
        .collect();
    super::albedo_mesh::fill_unseen(triangles, &mut albedo);
    let any_albedo = albedo.iter().any(|a| a[3] > 0.0);
    gathered
        .iter()
        .zip(&albedo)
        .zip(e)
        .map(|((l, a), e)| {
            if l[3] > 0.0 {
                [l[0], l[1], l[2], 1.0]
            } else if any_albedo && has_e(e) {
                [a[0] * e[0] / pi, a[1] * e[1] / pi, a[2] * e[2] / pi, 1.0]
            } else {
                [0.0; 4]
            }
        })
        .collect()
}

/// The completed radiance mesh of `geom` (uploaded as `mesh`), on the device, as source
/// irradiance reads it: gathered from the views, then completed with the per-vertex E_src
/// (`samples` rays, `seed`) of `si`.
#[allow(clippy::too_many_arguments)]
pub fn build(
    gpu: &Arc<Gpu>,
    si: &SourceIrradiance,
    lights: &[Light],
    geom: &Mesh,
    mesh: &RayScene,
    views: &GpuViews,
    samples: u32,
    seed: u32,
) -> Result<Buffer> {
    let nverts = geom.positions.len() as u32;
    let storage = |name: &str, data: &[[f32; 4]]| {
        let one = [[0.0f32; 4]];
        let data = if data.is_empty() { &one[..] } else { data };
        Buffer::from_slice(gpu, name, vk::BufferUsageFlags::STORAGE_BUFFER, data)
    };
    let gathered = RadianceMesh::new(gpu, lights)?.run(mesh, nverts, views)?;
    let gb = storage("radiance gathered", &gathered)?;
    let normals: Vec<[f32; 4]> = vertex_normals(geom)
        .iter()
        .map(|n| [n.x, n.y, n.z, 0.0])
        .collect();
    let nb = storage("vertex normals", &normals)?;
    let mut e = Vec::with_capacity(nverts as usize);
    let mut first = 0;
    while first < nverts {
        let count = CHUNK.min(nverts - first);
        e.extend(si.run_vertices(
            mesh,
            &gb,
            views,
            &mesh.positions,
            &nb,
            (first, count),
            samples,
            seed,
            super::source_irradiance::PART_ALL,
        )?);
        first += count;
    }
    storage("radiance mesh", &complete(&geom.triangles, &gathered, &e))
}

#[cfg(test)]
mod tests {
    use super::complete;

    #[test]
    fn unseen_vertices_reflect_their_irradiance_with_the_seen_ones_albedo() {
        // A strip of two triangles: vertices 0, 1 seen (L = 0.25 under E = 1, so ρ = π/4),
        // 2 and 3 unseen under E = 2 and 0 (no estimate).
        let tris = [[0, 1, 2], [1, 3, 2]];
        let gathered = [
            [0.25, 0.25, 0.25, 1.0],
            [0.25, 0.25, 0.25, 2.0],
            [0.0; 4],
            [0.0; 4],
        ];
        let e = [
            [1.0, 1.0, 1.0, 16.0],
            [1.0, 1.0, 1.0, 16.0],
            [2.0, 2.0, 2.0, 16.0],
            [0.0, 0.0, 0.0, 0.0],
        ];
        let r = complete(&tris, &gathered, &e);
        assert_eq!(r[0], [0.25, 0.25, 0.25, 1.0]);
        assert_eq!(r[1], [0.25, 0.25, 0.25, 1.0]);
        assert!((r[2][0] - 0.5).abs() < 1e-6 && r[2][3] == 1.0, "{:?}", r[2]);
        assert_eq!(r[3], [0.0; 4], "no irradiance, no radiance");
    }
}
