//! Albedo mesh `a(v)` (§4.1.2): `shaders_glsl/bake/albedo_mesh.comp`. `a = π·I/E_src`: the
//! paper's `I/E` with E as irradiance in W/m² (a Lambertian surface has I = ρ/π·E).

use std::sync::Arc;

use glam::Vec3;

use super::views::{GpuViews, ViewData};
use crate::error::Result;
use crate::gpu::{bytes_of, Bind, Buffer, Gpu, Pipeline, RayScene};

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
        let push = Push {
            nverts,
            width: views.width,
            height: views.height,
            nviews: views.count,
        };
        super::views::run_vertices(&self.pipeline.gpu, nverts, |cmd, out| {
            let mut binds = vec![
                (4, Bind::Buffer(&mesh.positions)),
                (5, Bind::Buffer(e_src)),
                (6, Bind::Buffer(out)),
            ];
            binds.extend(views.binds(0));
            self.pipeline
                .dispatch(cmd, &binds, bytes_of(&push), (nverts, 1, 1))
        })
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

/// Makes the proxy black where a declared original light sits. Its pixels are the emitter's
/// radiance, not reflected light, so π·I/E_src there means nothing (it clamps to 1), and a lamp
/// that is off reflects little: the ground truth models lights as black shapes. A white window
/// or ceiling panel in the albedo mesh sent the added lights' indirect light back into the room
/// (E_add 1.08× the truth on a scene with a 1 m² window).
pub fn darken_lights(positions: &[[f32; 3]], lights: &[super::GpuLight], albedo: &mut [[f32; 4]]) {
    use super::source_irradiance::LIGHT_SKIN;
    for (p, a) in positions.iter().zip(albedo.iter_mut()) {
        let p = Vec3::from(*p);
        if lights.iter().any(|l| l.near(p, LIGHT_SKIN, 0.0)) {
            a[0] = 0.0;
            a[1] = 0.0;
            a[2] = 0.0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{darken_lights, fill_unseen};
    use crate::bake::GpuLight;
    use crate::scene::{Light, LightShape};
    use glam::Vec3;

    #[test]
    fn vertices_on_a_declared_light_are_black() {
        let light = GpuLight::new(&Light {
            name: "panel".into(),
            // Faces down (X × Z = −Y), 1 m above the origin.
            shape: LightShape::Quad {
                corner: Vec3::new(0.0, 1.0, 0.0),
                edge_u: Vec3::X,
                edge_v: Vec3::Z,
            },
            radiance: [5.0; 3],
            original: true,
        });
        let pos = [
            [0.5, 1.01, 0.5],
            [0.5, 0.9, 0.5],
            [1.5, 1.0, 0.5],
            [0.2, 0.995, 0.9],
        ];
        let mut a = vec![[0.7f32, 0.7, 0.7, 1.0]; 4];
        darken_lights(&pos, &[light], &mut a);
        let black: Vec<bool> = a.iter().map(|x| x[0] == 0.0).collect();
        assert_eq!(black, [true, false, false, true]);
        assert!(a.iter().all(|x| x[3] == 1.0), "weights are kept");
    }

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
