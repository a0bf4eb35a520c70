//! The surface cache (§4.1.3 computed per surface point): the indirect part of one added
//! light's E_add stored at the texels of the bake mesh — each vertex, once per side of a crease
//! — path traced once (`shaders_glsl/bake/surface_cache.comp`), filtered along the mesh, and
//! looked up by every view's E_add map (`added_irradiance.comp`). Irradiance does not depend on
//! the view, so this replaces tracing the same surface once per pixel of every view that sees it.

use crate::gpu::shaders;
use std::sync::Arc;

use glam::Vec3;

use super::added_light::{AddedParams, GpuLight, RR_START};
use super::random::{cosine_dir, rand2};
use crate::error::Result;
use crate::gpu::{bytes_of, vk, Bind, Buffer, Gpu, Graph, Pipeline, RayScene};
use crate::scene::Mesh;

/// Faces meeting at a vertex at more than this angle (cos 45°) get texels of their own: a room's
/// corner holds a wall's irradiance and the floor's, which differ.
const CREASE_COS: f32 = std::f32::consts::FRAC_1_SQRT_2;

/// Where the texels are: positions and normals, and the texel at each triangle corner.
pub struct CacheLayout {
    pub pos: Vec<[f32; 4]>,
    pub nrm: Vec<[f32; 4]>,
    /// Three per triangle, in the mesh's corner order.
    pub corners: Vec<u32>,
}

impl CacheLayout {
    pub fn new(mesh: &Mesh) -> CacheLayout {
        let mut around = vec![Vec::new(); mesh.positions.len()];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for (k, &v) in tri.iter().enumerate() {
                around[v as usize].push((t, k));
            }
        }
        let mut l = CacheLayout {
            pos: vec![],
            nrm: vec![],
            corners: vec![0; 3 * mesh.triangles.len()],
        };
        for (v, faces) in around.iter().enumerate() {
            // Greedy clusters of the faces around v by normal; area-weighted sums.
            let mut clusters: Vec<(Vec3, u32)> = Vec::new();
            for &(t, k) in faces {
                let [a, b, c] = mesh.corners(t);
                let f = (b - a).cross(c - a);
                let i = match clusters.iter().position(|(s, _)| {
                    s.normalize_or_zero().dot(f.normalize_or_zero()) > CREASE_COS
                }) {
                    Some(i) => i,
                    None => {
                        clusters.push((Vec3::ZERO, (l.pos.len() + clusters.len()) as u32));
                        clusters.len() - 1
                    }
                };
                clusters[i].0 += f;
                l.corners[3 * t + k] = clusters[i].1;
            }
            for (s, _) in clusters {
                l.pos.push(Vec3::from(mesh.positions[v]).extend(1.0).into());
                l.nrm.push(s.normalize_or_zero().extend(0.0).into());
            }
        }
        l
    }

    pub fn texels(&self) -> usize {
        self.pos.len()
    }

    /// Texels that share a triangle, with a weight for normal agreement (the filter's graph).
    fn neighbours(&self) -> Vec<Vec<(u32, f32)>> {
        let mut nb: Vec<Vec<(u32, f32)>> = vec![Vec::new(); self.texels()];
        for c in self.corners.chunks_exact(3) {
            for (i, j) in [(c[0], c[1]), (c[1], c[2]), (c[2], c[0])] {
                let n = |t: u32| Vec3::from_slice(&self.nrm[t as usize][..3]);
                let w = n(i).dot(n(j)).max(0.0).powi(8);
                for (a, b) in [(i, j), (j, i)] {
                    if a != b && !nb[a as usize].iter().any(|x| x.0 == b) {
                        nb[a as usize].push((b, w));
                    }
                }
            }
        }
        nb
    }

    /// Smooths cached values along the mesh: `iterations` rounds of averaging each texel with
    /// its neighbours (weighted by normal agreement). The mesh's connectivity keeps the filter
    /// from mixing surfaces that only lie close, like a table top and the floor under it. A
    /// value's w is its own weight: 1 for an estimate, 0 for a texel not traced yet, which takes
    /// its traced neighbours' mean (and stays 0, w = 0, with none).
    pub fn filter(&self, values: &[[f32; 4]], iterations: u32) -> Vec<[f32; 4]> {
        let nb = self.neighbours();
        let mut cur = values.to_vec();
        for _ in 0..iterations {
            cur = (0..cur.len())
                .map(|i| {
                    let wi = cur[i][3];
                    let (mut s, mut w) = (wi * Vec3::from_slice(&cur[i][..3]), wi);
                    for &(j, wj) in &nb[i] {
                        let v = cur[j as usize];
                        s += wj * v[3] * Vec3::from_slice(&v[..3]);
                        w += wj * v[3];
                    }
                    if w > 0.0 {
                        (s / w).extend(1.0).into()
                    } else {
                        [0.0; 4]
                    }
                })
                .collect();
        }
        cur
    }

    /// The indirect irradiance at `p` on triangle `tri` (CPU mirror of the lookup in
    /// added_irradiance.comp).
    pub fn lookup(&self, mesh: &Mesh, cache: &[[f32; 4]], tri: usize, p: Vec3) -> Vec3 {
        let [a, b, c] = mesh.corners(tri);
        let l = barycentrics(p, a, b, c);
        (0..3)
            .map(|k| l[k] * Vec3::from_slice(&cache[self.corners[3 * tri + k] as usize][..3]))
            .sum()
    }
}

/// CPU mirror of `barycentrics` in added_irradiance.comp.
pub fn barycentrics(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (e0, e1, q) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
    let (d20, d21) = (q.dot(e0), q.dot(e1));
    let den = (d00 * d11 - d01 * d01).max(1e-20);
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    let l = Vec3::new(1.0 - v - w, v, w).max(Vec3::ZERO);
    l / (l.x + l.y + l.z).max(1e-20)
}

/// The layout on the device.
pub struct GpuCacheLayout {
    pub pos: Buffer,
    pub nrm: Buffer,
    pub corners: Buffer,
    pub texels: u32,
}

impl GpuCacheLayout {
    pub fn upload(gpu: &Arc<Gpu>, l: &CacheLayout) -> Result<GpuCacheLayout> {
        let u = vk::BufferUsageFlags::STORAGE_BUFFER;
        Ok(GpuCacheLayout {
            pos: Buffer::from_slice(gpu, "cache texels", u, &l.pos)?,
            nrm: Buffer::from_slice(gpu, "cache normals", u, &l.nrm)?,
            corners: Buffer::from_slice(gpu, "cache corners", u, &l.corners)?,
            texels: l.texels() as u32,
        })
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    first: u32,
    count: u32,
    samples: u32,
    seed: u32,
    bounces: u32,
    use_list: u32,
    pad: [u32; 2],
    light: GpuLight,
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    Push,
    [shaders::BAKE_SURFACE_CACHE],
    [
        first,
        count,
        samples,
        seed,
        bounces,
        use_list,
        pad,
        light.p0,
        light.p1,
        light.p2,
        light.radiance
    ]
);

/// Texels per dispatch: a chunk is a few seconds on lavapipe, so progress shows as it goes.
pub const CHUNK: u32 = 8192;

pub struct SurfaceCache {
    pipeline: Pipeline,
}

/// Which texels a [`SurfaceCache::record`] traces.
#[derive(Clone, Copy)]
pub enum Texels<'a> {
    /// `first..first + count`.
    Range { first: u32, count: u32 },
    /// The texel indices `list[..count]` (the live lights' focus); the rest of `out` is left as
    /// it was.
    List { list: &'a Buffer, count: u32 },
}

impl SurfaceCache {
    pub fn new(gpu: &Arc<Gpu>) -> Result<SurfaceCache> {
        Ok(SurfaceCache {
            pipeline: Pipeline::compute(gpu, shaders::BAKE_SURFACE_CACHE)?,
        })
    }

    /// Records the tracing of `texels` into `out`, each texel's result at its own index.
    #[allow(clippy::too_many_arguments)]
    pub fn record<'a>(
        &self,
        g: &mut Graph<'a, '_>,
        mesh: &'a RayScene,
        layout: &'a GpuCacheLayout,
        albedo: &'a Buffer,
        light: &GpuLight,
        p: AddedParams,
        texels: Texels<'a>,
        out: &'a Buffer,
    ) -> Result<()> {
        let (first, count, list) = match texels {
            Texels::Range { first, count } => (first, count, None),
            Texels::List { list, count } => (0, count, Some(list)),
        };
        let push = Push {
            first,
            count,
            samples: p.cache_samples,
            seed: p.seed,
            bounces: p.bounces,
            use_list: u32::from(list.is_some()),
            pad: [0; 2],
            light: *light,
        };
        let binds = [
            ("tlas", Bind::Accel(mesh.tlas.raw)),
            ("Verts", Bind::Buffer(&mesh.positions)),
            ("Indices", Bind::Buffer(&mesh.indices)),
            ("Albedo", Bind::Buffer(albedo)),
            ("Texels", Bind::Buffer(&layout.pos)),
            ("Normals", Bind::Buffer(&layout.nrm)),
            ("Out", Bind::Buffer(out)),
            // Unread without a list; any storage buffer fills the binding.
            ("List", Bind::Buffer(list.unwrap_or(&layout.pos))),
        ];
        g.pass(
            "surface cache",
            &self.pipeline,
            binds,
            bytes_of(&push),
            (count, 1, 1),
        )
    }

    /// Traces the whole cache of `light` (unfiltered), chunk by chunk, reporting texels done.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        &self,
        mesh: &RayScene,
        layout: &GpuCacheLayout,
        albedo: &Buffer,
        light: &GpuLight,
        p: AddedParams,
        progress: &mut dyn FnMut(u32, u32),
    ) -> Result<Vec<[f32; 4]>> {
        let gpu = &self.pipeline.gpu;
        let out = Buffer::new(
            gpu,
            "surface cache",
            layout.texels.max(1) as u64 * 16,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            crate::gpu::MemoryLocation::GpuOnly,
        )?;
        let mut first = 0;
        while first < layout.texels {
            let count = CHUNK.min(layout.texels - first);
            let mut res = Ok(());
            gpu.submit(|cmd| {
                res = self.record(
                    &mut Graph::new(gpu, cmd, None),
                    mesh,
                    layout,
                    albedo,
                    light,
                    p,
                    Texels::Range { first, count },
                    &out,
                )
            })?;
            res?;
            first += count;
            progress(first, layout.texels);
        }
        let mut v: Vec<[f32; 4]> = out.download_vec()?;
        v.truncate(layout.texels as usize);
        Ok(v)
    }
}

/// Rays traced for a cache at most: per path `bounces` continuation rays and as many shadow
/// rays (Russian roulette ends most paths sooner, so rates from this are upper bounds).
pub fn max_rays(texels: usize, p: AddedParams) -> u64 {
    texels as u64 * p.cache_samples as u64 * 2 * p.bounces as u64
}

/// CPU reference of surface_cache.comp (same random numbers).
pub fn reference(
    mesh: &Mesh,
    layout: &CacheLayout,
    albedo: &[[f32; 4]],
    light: &GpuLight,
    p: AddedParams,
) -> Vec<[f32; 4]> {
    (0..layout.texels())
        .map(|t| {
            let tk = t as u32;
            let mut sum = Vec3::ZERO;
            for s in 0..p.cache_samples {
                let mut x = Vec3::from_slice(&layout.pos[t][..3]);
                let mut n = Vec3::from_slice(&layout.nrm[t][..3]);
                let mut thr = Vec3::ONE;
                for b in 1..=p.bounces {
                    let k = s * 64 + 2 * b;
                    let o = x + n * 1e-3;
                    let hit = (0..4u32).find_map(|r| {
                        let seed = p.seed.wrapping_add(r.wrapping_mul(0x9E37_79B9));
                        let d = cosine_dir(n, rand2([tk, k + 1, seed]));
                        crate::cpu::closest_hit(mesh, o, d, 1e-3, 1e4).map(|h| (d, h))
                    });
                    let Some((d, h)) = hit else { break };
                    let tri = mesh.triangles[h.tri as usize];
                    x = o + d * h.t;
                    n = mesh.face_normal(h.tri as usize);
                    if n.dot(d) > 0.0 {
                        n = -n;
                    }
                    let a = |i: u32| Vec3::from_slice(&albedo[i as usize][..3]);
                    let rho = (1.0 - h.bary[0] - h.bary[1]) * a(tri[0])
                        + h.bary[0] * a(tri[1])
                        + h.bary[1] * a(tri[2]);
                    thr *= rho.clamp(Vec3::ZERO, Vec3::ONE);
                    if b >= RR_START {
                        let q = thr.max_element().min(0.95);
                        if rand2([tk, k + 1, !p.seed])[0] >= q {
                            break;
                        }
                        thr /= q;
                    }
                    sum += thr * light.direct(mesh, x, n, rand2([tk, k, p.seed]), light.lift());
                }
            }
            (sum / p.cache_samples as f32).extend(1.0).into()
        })
        .collect()
}
