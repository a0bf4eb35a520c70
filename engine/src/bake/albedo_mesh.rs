//! Albedo mesh `a(v)` (§4.1.2): `shaders_glsl/bake/albedo_mesh.comp`. `a = π·I/E_src`: the
//! paper's `I/E` with E as irradiance in W/m² (a Lambertian surface has I = ρ/π·E).

use crate::gpu::shaders;
use std::sync::Arc;

use glam::Vec3;

use super::views::{GpuViews, ViewData};
use crate::error::Result;
use crate::gpu::{bytes_of, Bind, Buffer, Gpu, Graph, Pipeline, RayScene};
use crate::scene::Light;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    nverts: u32,
    width: u32,
    height: u32,
    nviews: u32,
    nlights: u32,
    pad: u32,
    /// Device address of E_src of all views.
    e_src: [u32; 2],
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    Push,
    [shaders::BAKE_ALBEDO_MESH],
    [nverts, width, height, nviews, nlights, pad, e_src]
);

pub struct AlbedoMesh {
    pipeline: Pipeline,
    lights: Buffer,
    nlights: u32,
}

impl AlbedoMesh {
    /// `lights`: the scene's lights; pixels on or beside the original ones are no samples.
    pub fn new(gpu: &Arc<Gpu>, lights: &[Light]) -> Result<AlbedoMesh> {
        let (lights, nlights) = super::source_irradiance::lights_buffer(gpu, lights)?;
        Ok(AlbedoMesh {
            pipeline: Pipeline::compute(gpu, shaders::BAKE_ALBEDO_MESH)?,
            lights,
            nlights,
        })
    }

    /// Per-vertex albedo (rgb, w = weight sum; 0 where no view sees the vertex) from the E_src of
    /// all views (`e_src`: view-major vec4 per pixel, made with SHADER_DEVICE_ADDRESS usage).
    pub fn run(
        &self,
        mesh: &RayScene,
        nverts: u32,
        views: &GpuViews,
        e_src: &Buffer,
    ) -> Result<Vec<[f32; 4]>> {
        if e_src.address == 0 {
            return Err(crate::error::Error::Other(
                "albedo mesh: E_src is read by address; its buffer needs SHADER_DEVICE_ADDRESS usage".into(),
            ));
        }
        let push = Push {
            nverts,
            width: views.width,
            height: views.height,
            nviews: views.count,
            nlights: self.nlights,
            pad: 0,
            e_src: [e_src.address as u32, (e_src.address >> 32) as u32],
        };
        let gpu = &self.pipeline.gpu;
        super::views::run_vertices(gpu, nverts, |cmd, out| {
            let mut binds = vec![
                ("Verts", Bind::Buffer(&mesh.positions)),
                ("Out", Bind::Buffer(out)),
                ("Lights", Bind::Buffer(&self.lights)),
            ];
            binds.extend([views.bind()]);
            let g = &mut Graph::new(gpu, cmd, None);
            g.pass(
                "albedo mesh",
                &self.pipeline,
                binds,
                bytes_of(&push),
                (nverts, 1, 1),
            )
        })
    }
}

/// CPU reference (`lights`: the declared original lights).
pub fn reference(
    positions: &[[f32; 3]],
    d: &ViewData,
    e_src: &[[f32; 4]],
    lights: &[super::GpuLight],
) -> Vec<[f32; 4]> {
    positions
        .iter()
        .map(|p| {
            let p = Vec3::from(*p);
            let (mut sum, mut wsum) = (Vec3::ZERO, 0.0f32);
            for j in 0..d.cameras.len() {
                let Some(q) = d.visible_pixel(j, p).filter(|&q| {
                    !d.clipped(q) && !super::source_irradiance::near_light(d, lights, q)
                }) else {
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

/// Gives the vertices no view sees (w = 0) an albedo, keeping w = 0: the added-irradiance path
/// tracer bounces off them too, and a black vertex there (the floor under a table, the back of
/// a box) would absorb the light that reaches it (E_add was 0.8× the truth with 29% of the
/// proxy's vertices unseen). Rings of unseen vertices take the mean of their seen or filled
/// neighbours, outwards from the seen ones; parts of the mesh with no seen vertex at all take
/// the mean albedo of the seen vertices.
pub fn fill_unseen(triangles: &[[u32; 3]], albedo: &mut [[f32; 4]]) {
    let n = albedo.len();
    let mut nbrs: Vec<Vec<u32>> = vec![Vec::new(); n];
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            if a < n && b < n {
                nbrs[a].push(b as u32);
                nbrs[b].push(a as u32);
            }
        }
    }
    let mut known: Vec<bool> = albedo.iter().map(|a| a[3] > 0.0).collect();
    let seen = known.iter().filter(|k| **k).count();
    if seen == 0 {
        return;
    }
    let mean = albedo
        .iter()
        .filter(|a| a[3] > 0.0)
        .fold(Vec3::ZERO, |s, a| s + Vec3::from_slice(&a[..3]))
        / seen as f32;
    let mut frontier: Vec<usize> = (0..n).filter(|&v| !known[v]).collect();
    while !frontier.is_empty() {
        // One ring at a time, from the values known before the ring (order-independent).
        let ring: Vec<(usize, Vec3)> = frontier
            .iter()
            .filter_map(|&v| {
                let (s, c) = nbrs[v]
                    .iter()
                    .filter(|&&u| known[u as usize])
                    .fold((Vec3::ZERO, 0u32), |(s, c), &u| {
                        (s + Vec3::from_slice(&albedo[u as usize][..3]), c + 1)
                    });
                (c > 0).then(|| (v, s / c as f32))
            })
            .collect();
        if ring.is_empty() {
            break;
        }
        for &(v, a) in &ring {
            albedo[v] = [a.x, a.y, a.z, 0.0];
            known[v] = true;
        }
        frontier.retain(|&v| !known[v]);
    }
    for v in frontier {
        albedo[v] = [mean.x, mean.y, mean.z, 0.0];
    }
}

#[cfg(test)]
mod tests {
    use super::fill_unseen;

    #[test]
    fn unseen_vertices_take_their_neighbours_albedo() {
        // A strip 0-1-2-3 (two triangles) and a separate triangle 4-5-6; only vertex 0 and 4
        // are seen.
        let tris = [[0, 1, 2], [1, 3, 2], [4, 5, 6]];
        let mut a = vec![[0.0f32; 4]; 7];
        a[0] = [0.2, 0.4, 0.6, 1.0];
        a[4] = [0.6, 0.4, 0.2, 2.0];
        fill_unseen(&tris, &mut a);
        for v in [1, 2, 3] {
            assert_eq!(&a[v][..3], &[0.2, 0.4, 0.6], "vertex {v}");
            assert_eq!(a[v][3], 0.0, "filled vertices stay unseen");
        }
        assert_eq!(&a[5][..3], &[0.6, 0.4, 0.2]);
        // An island with no seen vertex takes the mean of the seen ones.
        let mut b = vec![[0.0f32; 4]; 6];
        b[0] = [0.2, 0.2, 0.2, 1.0];
        b[1] = [0.4, 0.4, 0.4, 1.0];
        fill_unseen(&[[0, 1, 2], [3, 4, 5]], &mut b);
        assert!((b[4][0] - 0.3).abs() < 1e-6 && (b[2][0] - 0.3).abs() < 1e-6);
    }
}
