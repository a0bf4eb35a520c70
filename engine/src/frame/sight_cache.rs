//! The sight cache: how much of each still light every surface point sees, traced once per light
//! instead of once per pixel of every frame. On lavapipe the glossy layer's shadow rays
//! (frame/sight.glsl) were two thirds of its cost, and a light that does not move — an original
//! light, an added light at its baked place, a lamp dropped in the viewer once its live cache has
//! converged — answers the same every frame. A light gets its column when it is first lit or
//! settles; when the columns run out the cache starts over. Lights being moved have none and
//! keep their rays per pixel.
//!
//! Points: the bake mesh's texels (each vertex once per side of a crease, [`CacheLayout`]) for a
//! triangle no longer than [`SPACING`], and a grid [`SPACING`] apart on a larger one (the hand-made
//! rooms' walls are two triangles each). A point holds, per column (light), how many of
//! SIGHT_CACHE_SAMPLES rays to points of the light's area reach it, 8 bits each, four columns a
//! word. A pixel asks the three points of the grid cell around it
//! (`shaders_glsl/frame/sight_cache.glsl`) and sees the light where their counts, interpolated,
//! reach half. For a light of at most SIGHT_SHARP_AREA, where they straddle half and differ by
//! half of the rays or more — a hard shadow's edge crosses the cell — it traces its own ray, as
//! before: a small lamp's shadows keep their edges and the ones narrower than the points'
//! spacing (a table leg's). A large light's penumbrae are wide enough to interpolate.

use std::sync::Arc;

use glam::Vec3;

use crate::bake::random::rand2;
use crate::bake::surface_cache::{barycentrics, CacheLayout};
use crate::bake::GpuLight;
use crate::constants::{SIGHT_CACHE_SAMPLES, SIGHT_LIFT, SIGHT_SHARP_AREA};
use crate::cpu::MeshBvh;
use crate::error::{Error, Result};
use crate::gpu::{bytes_of, shaders, vk, Bind, Buffer, Gpu, Graph, Pipeline, RayScene};
use crate::scene::Mesh;

use super::Lighting;

pub const SHADER: crate::gpu::Shader = shaders::FRAME_SIGHT_CACHE;

/// Metres between a large triangle's grid points. Proxies from photos (and scenegen's) have
/// vertices 5 cm apart, triangles 7 cm long: they keep their texels (a 3 cm grid on them made
/// 16× the points and took 18 s on the demo room's 4 lights on lavapipe, against ~1 s).
pub const SPACING: f32 = 0.08;
/// Grid points along a triangle's edge at most (a 2 m triangle keeps SPACING).
const MAX_RES: u32 = 64;
/// Columns (lights) a point holds: the glossy layer's slots.
pub const COLUMNS: usize = super::sight::SIGHT_MAX;
/// Words per point: four 8-bit counts each.
pub const WORDS: usize = COLUMNS / 4;
/// The column map's entry for a slot whose light has no column.
pub const NO_COLUMN: u32 = u32::MAX;
/// Added to a column map's entry: the light is at most SIGHT_SHARP_AREA (hard shadows).
pub const SHARP: u32 = 0x100;
/// Points per dispatch: a chunk takes about a second on lavapipe.
const CHUNK: u32 = 16384;

/// Where the points are. Triangle t's entry: its three corners' texels and 1 where it takes them,
/// else (its grid's first point, 0, 0, resolution r), (r + 1)(r + 2)/2 points in rows of
/// constant j (i along the edge a→b, j along a→c).
pub struct SightLayout {
    pub tris: Vec<[u32; 4]>,
    pub pos: Vec<[f32; 4]>,
    pub nrm: Vec<[f32; 4]>,
}

/// Grid point (i, j)'s offset in a triangle of resolution r: row j holds r + 1 − j points.
fn grid_index(r: u32, i: u32, j: u32) -> u32 {
    j * (2 * r + 3 - j) / 2 + i
}

impl SightLayout {
    pub fn new(mesh: &Mesh) -> SightLayout {
        let texels = CacheLayout::new(mesh);
        let mut l = SightLayout {
            tris: Vec::with_capacity(mesh.triangles.len()),
            pos: texels.pos,
            nrm: texels.nrm,
        };
        for t in 0..mesh.triangles.len() {
            let [a, b, c] = mesh.corners(t);
            let edge = (b - a).length().max((c - a).length()).max((c - b).length());
            let r = ((edge / SPACING).ceil() as u32).clamp(1, MAX_RES);
            if r == 1 {
                let k = &texels.corners[3 * t..3 * t + 3];
                l.tris.push([k[0], k[1], k[2], 1]);
                continue;
            }
            l.tris.push([l.pos.len() as u32, 0, 0, r]);
            let n = (b - a).cross(c - a).normalize_or_zero().extend(0.0).into();
            for j in 0..=r {
                for i in 0..=r - j {
                    let (u, v) = (i as f32 / r as f32, j as f32 / r as f32);
                    l.pos
                        .push((a + u * (b - a) + v * (c - a)).extend(1.0).into());
                    l.nrm.push(n);
                }
            }
        }
        l
    }

    pub fn points(&self) -> usize {
        self.pos.len()
    }

    /// The point of triangle t's grid point (i, j).
    fn point(&self, t: usize, i: u32, j: u32) -> u32 {
        let e = self.tris[t];
        match e[3] {
            1 if i == 1 => e[1],
            1 if j == 1 => e[2],
            1 => e[0],
            r => e[0] + grid_index(r, i, j),
        }
    }

    /// The points around x on triangle t and their weights (`sight_cache.glsl`'s twin): the
    /// grid's cell that holds x's barycentrics, split into its two triangles.
    pub fn weights(&self, mesh: &Mesh, t: usize, x: Vec3) -> [(u32, f32); 3] {
        let [a, b, c] = mesh.corners(t);
        let l = barycentrics(x, a, b, c);
        let r = self.tris[t][3];
        let (fi, fj) = (l.y * r as f32, l.z * r as f32);
        let i0 = (fi as u32).min(r);
        let j0 = (fj as u32).min(r - i0);
        let (u, v) = (fi - i0 as f32, fj - j0 as f32);
        let p = |i, j| self.point(t, i, j);
        if i0 + j0 == r {
            [(p(i0, j0), 1.0), (p(i0, j0), 0.0), (p(i0, j0), 0.0)]
        } else if u + v <= 1.0 || i0 + j0 + 2 > r {
            let w = Vec3::new(1.0 - u - v, u, v).max(Vec3::ZERO);
            let w = w / (w.x + w.y + w.z).max(1e-20);
            [(p(i0, j0), w.x), (p(i0 + 1, j0), w.y), (p(i0, j0 + 1), w.z)]
        } else {
            [
                (p(i0 + 1, j0 + 1), u + v - 1.0),
                (p(i0, j0 + 1), 1.0 - u),
                (p(i0 + 1, j0), 1.0 - v),
            ]
        }
    }
}

/// Point p's count of the rays that reach column `col`'s light (counts `vis`).
pub fn count(vis: &[u32], p: u32, col: u32) -> f32 {
    let w = vis[p as usize * WORDS + col as usize / 4];
    (w >> (8 * (col % 4)) & 255) as f32
}

/// Whether the ray from x (normal n) to point q of a light arrives: it starts SIGHT_LIFT off the
/// surface on q's side (a point's normal may face either way) and ends 5 cm short of q, as
/// `sees_light` does.
fn reaches(bvh: &MeshBvh, x: Vec3, n: Vec3, q: Vec3) -> bool {
    let d = q - x;
    let dist = d.length();
    if dist < 0.06 {
        return false;
    }
    let lift = if d.dot(n) >= 0.0 { n } else { -n } * SIGHT_LIFT;
    !bvh.occluded(x + lift, d / dist, 1e-3, dist - 0.05)
}

/// CPU reference of the cache pass: WORDS words per point, column c holding light c's count.
pub fn reference(mesh: &Mesh, layout: &SightLayout, lights: &[GpuLight]) -> Vec<u32> {
    let bvh = MeshBvh::new(mesh);
    let mut vis = vec![0u32; layout.points() * WORDS];
    for p in 0..layout.points() {
        let x = Vec3::from_slice(&layout.pos[p][..3]);
        let n = Vec3::from_slice(&layout.nrm[p][..3]);
        for (c, l) in lights.iter().enumerate().take(COLUMNS) {
            let count = (0..SIGHT_CACHE_SAMPLES)
                .filter(|&s| reaches(&bvh, x, n, l.sample(rand2([p as u32, s, c as u32])).0))
                .count() as u32;
            vis[p * WORDS + c / 4] |= count << (8 * (c % 4));
        }
    }
    vis
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    first: u32,
    count: u32,
    col0: u32,
    ncols: u32,
}

/// Push as its shader's push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout =
    crate::push_layout!(Push, [SHADER], [first, count, col0, ncols]);

/// The layout on the device (made once per scene) and the pass that fills a cache.
pub struct SightPass {
    pipeline: Pipeline,
    pub layout: SightLayout,
    pos: Buffer,
    nrm: Buffer,
    /// Per triangle, [`SightLayout::tris`] (the glossy layer's `SightTris`).
    pub tris: Buffer,
}

/// One cache: its columns' lights and the points' counts (`SightVis`).
pub struct SightCache {
    pub lights: Vec<GpuLight>,
    pub vis: Buffer,
}

impl SightCache {
    /// The column that holds `l` as it is now (None: it moved since, or it has none).
    pub fn column(&self, l: &GpuLight) -> Option<u32> {
        let b = bytemuck::bytes_of(l);
        (self.lights.iter())
            .position(|c| bytemuck::bytes_of(c) == b)
            .map(|c| c as u32)
    }
}

impl SightPass {
    pub fn new(gpu: &Arc<Gpu>, mesh: &Mesh) -> Result<SightPass> {
        let layout = SightLayout::new(mesh);
        let u = vk::BufferUsageFlags::STORAGE_BUFFER;
        // A buffer holds something even for a mesh without triangles.
        fn held<T: bytemuck::Pod + bytemuck::Zeroable>(v: &[T]) -> Vec<T> {
            match v.is_empty() {
                true => vec![T::zeroed()],
                false => v.to_vec(),
            }
        }
        Ok(SightPass {
            pipeline: Pipeline::compute(gpu, SHADER)?,
            pos: Buffer::from_slice(gpu, "sight points", u, &held(&layout.pos))?,
            nrm: Buffer::from_slice(gpu, "sight normals", u, &held(&layout.nrm))?,
            tris: Buffer::from_slice(gpu, "sight triangles", u, &held(&layout.tris))?,
            layout,
        })
    }

    /// A cache with a column for each of `lights` over `scene`: `old`'s columns and, after
    /// them, the lights it lacks (a new cache where they would not fit), traced chunk by chunk.
    pub fn extend(
        &self,
        scene: &RayScene,
        old: Option<SightCache>,
        lights: &[GpuLight],
    ) -> Result<SightCache> {
        if lights.len() > COLUMNS {
            return Err(Error::Other(format!(
                "the sight cache holds {COLUMNS} lights; {} asked",
                lights.len()
            )));
        }
        let mut cache = match old {
            Some(c) => c,
            None => self.empty()?,
        };
        let new: Vec<GpuLight> = (lights.iter())
            .filter(|l| cache.column(l).is_none())
            .copied()
            .collect();
        if cache.lights.len() + new.len() > COLUMNS {
            return self.extend(scene, None, lights);
        }
        if !new.is_empty() {
            self.trace(scene, &cache.vis, cache.lights.len() as u32, &new)?;
            cache.lights.extend(new);
        }
        Ok(cache)
    }

    /// A cache without columns (its counts are written with its first).
    fn empty(&self) -> Result<SightCache> {
        let n = self.layout.points().max(1);
        let vis = Buffer::new(
            &self.pipeline.gpu,
            "sight cache",
            (n * WORDS * 4) as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            crate::gpu::MemoryLocation::GpuOnly,
        )?;
        Ok(SightCache {
            lights: Vec::new(),
            vis,
        })
    }

    /// Traces `lights` into columns col0.. of `vis`, chunk by chunk.
    fn trace(&self, scene: &RayScene, vis: &Buffer, col0: u32, lights: &[GpuLight]) -> Result<()> {
        let gpu = &self.pipeline.gpu;
        let n = self.layout.points() as u32;
        let u = vk::BufferUsageFlags::STORAGE_BUFFER;
        let lbuf = Buffer::from_slice(gpu, "sight lights", u, lights)?;
        let mut first = 0;
        while first < n {
            let push = Push {
                first,
                count: CHUNK.min(n - first),
                col0,
                ncols: lights.len() as u32,
            };
            let binds = [
                ("tlas", Bind::Accel(scene.tlas.raw)),
                ("SightPoints", Bind::Buffer(&self.pos)),
                ("SightNormals", Bind::Buffer(&self.nrm)),
                ("SightLights", Bind::Buffer(&lbuf)),
                ("SightOut", Bind::Buffer(vis)),
            ];
            let mut res = Ok(());
            gpu.submit(|cmd| {
                res = (Graph::new(gpu, cmd, None)).pass(
                    "sight cache",
                    &self.pipeline,
                    binds,
                    bytes_of(&push),
                    (push.count, 1, 1),
                )
            })?;
            res?;
            first += push.count;
        }
        Ok(())
    }
}

impl super::Renderer {
    /// The glossy layer's slots under `lighting` in sight.glsl's order (the original lights, at
    /// most MAX_ORIG, then the lit added lights) and whether each should have a column: a light
    /// not being moved, or a live one that has settled (its cache converged, where it was in
    /// the last frame: a dropped lamp, not one a path moves every frame).
    fn sight_slots(&self, lighting: &Lighting) -> Vec<(GpuLight, bool)> {
        let s = &self.scene;
        let lit = |l: &usize| lighting.intensities.get(*l).copied().unwrap_or(0.0) > 0.0;
        let settled = |l: usize| {
            let here = bytemuck::bytes_of(&s.emitters[l]);
            self.live.converged(l)
                && (self.sight_prev.iter()).any(|(k, p)| *k == l && bytemuck::bytes_of(p) == here)
        };
        let originals = (s.originals.iter().take(super::glossy::MAX_ORIG)).map(|o| (o.light, true));
        let lamps = (0..s.emitters.len())
            .filter(lit)
            .map(|l| (s.emitters[l], !self.live.is_live(l) || settled(l)));
        originals.chain(lamps).take(COLUMNS).collect()
    }

    /// Adds the columns the lights of `lighting` that should have one lack (a new cache when the
    /// columns run out), and notes where the live lights are.
    pub(super) fn ensure_sight_cache(&mut self, lighting: &Lighting) -> Result<()> {
        if !self.use_sight_cache || self.fitting {
            return Ok(());
        }
        let wanted: Vec<GpuLight> = (self.sight_slots(lighting).into_iter())
            .filter_map(|(l, want)| want.then_some(l))
            .collect();
        self.sight_prev = (0..self.scene.emitters.len())
            .filter(|&l| self.live.is_live(l))
            .map(|l| (l, self.scene.emitters[l]))
            .collect();
        let have =
            (self.sight.as_ref()).is_some_and(|c| wanted.iter().all(|l| c.column(l).is_some()));
        if !have {
            self.extend_sight_cache(wanted)?;
        }
        Ok(())
    }

    fn extend_sight_cache(&mut self, lights: Vec<GpuLight>) -> Result<()> {
        if self.sight_pass.is_none() {
            self.sight_pass = Some(SightPass::new(&self.gpu, &self.scene.geom)?);
        }
        let old = self.sight.take();
        let pass = self.sight_pass.as_ref().unwrap();
        self.sight = Some(pass.extend(&self.scene.mesh, old, &lights)?);
        Ok(())
    }

    /// Traces the sight cache anew for the lights of `lighting` that should have a column and
    /// returns how long it took: what a scene's first glossy frame adds (`relit bench` reports
    /// it); a light lit later, or a lamp dropped in the viewer, adds its own column (a quarter
    /// of that for the demo room's four lights).
    pub fn rebuild_sight_cache(&mut self, lighting: &Lighting) -> Result<std::time::Duration> {
        let t0 = std::time::Instant::now();
        self.sight = None;
        let wanted: Vec<GpuLight> = (self.sight_slots(lighting).into_iter())
            .filter_map(|(l, want)| want.then_some(l))
            .collect();
        self.extend_sight_cache(wanted)?;
        Ok(t0.elapsed())
    }

    /// Each slot's column under `lighting` (`SightCols`, with [`SHARP`] for a small light):
    /// [`NO_COLUMN`] where the light as it is now has none (being moved, moved since) and for all
    /// of them with the cache off.
    pub(super) fn sight_columns(&self, lighting: &Lighting) -> Vec<u32> {
        let mut cols = vec![NO_COLUMN; COLUMNS];
        if let (true, Some(c)) = (self.use_sight_cache, &self.sight) {
            for (k, (l, _)) in self.sight_slots(lighting).iter().enumerate() {
                let sharp = super::glossy::light_frame(l).2 <= SIGHT_SHARP_AREA;
                if let Some(col) = c.column(l) {
                    cols[k] = col | if sharp { SHARP } else { 0 };
                }
            }
        }
        cols
    }

    /// The sight cache's points and lights (columns); zeros before one.
    pub fn sight_cache_size(&self) -> (usize, usize) {
        let points = self.sight_pass.as_ref().map_or(0, |p| p.layout.points());
        (points, self.sight.as_ref().map_or(0, |c| c.lights.len()))
    }

    /// The sight cache a glossy frame under `lighting` reads; None before one or with the cache
    /// off (the CPU references' input).
    pub fn sight_cache_data(&self, lighting: &Lighting) -> Result<Option<SightData<'_>>> {
        match (&self.sight_pass, &self.sight, self.use_sight_cache) {
            (Some(p), Some(c), true) => Ok(Some(SightData {
                layout: &p.layout,
                vis: bytemuck::pod_collect_to_vec(&c.vis.download()?),
                cols: self.sight_columns(lighting),
                lights: c.lights.clone(),
            })),
            _ => Ok(None),
        }
    }
}

/// A sight cache read back: its layout, its points' counts ([`WORDS`] words each), each slot's
/// column and each column's light.
pub struct SightData<'a> {
    pub layout: &'a SightLayout,
    pub vis: Vec<u32>,
    pub cols: Vec<u32>,
    pub lights: Vec<GpuLight>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles of a 1 m square and one small one: the big ones take grids, the small one
    /// its corners' texels; every point's weights sum to one and reproduce a linear field.
    #[test]
    fn weights_interpolate_the_grid_linearly() {
        let mut positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
        ];
        positions.extend([[3.0, 0.0, 0.0], [3.02, 0.0, 0.0], [3.0, 0.0, 0.02]]);
        let mesh = Mesh {
            positions,
            colors: None,
            triangles: vec![[0, 2, 1], [0, 3, 2], [4, 6, 5]],
        };
        let l = SightLayout::new(&mesh);
        let r = (2f32.sqrt() / SPACING).ceil() as u32;
        assert_eq!(l.tris[0][3], r);
        assert_eq!(l.tris[2][3], 1);
        let field = |p: Vec3| 2.0 * p.x - p.z + 0.5;
        for t in 0..3 {
            for k in 0..50 {
                let [a, b, c] = mesh.corners(t);
                let (s, q) = ((k % 7) as f32 / 7.0, (k / 7) as f32 / 8.0);
                let x = a + s * (1.0 - q) * (b - a) + q * (1.0 - s) * (c - a);
                let w = l.weights(&mesh, t, x);
                let sum: f32 = w.iter().map(|p| p.1).sum();
                assert!(
                    (sum - 1.0).abs() < 1e-4,
                    "triangle {t}: weights sum to {sum}"
                );
                let got: f32 = (w.iter())
                    .map(|&(p, f)| f * field(Vec3::from_slice(&l.pos[p as usize][..3])))
                    .sum();
                assert!((got - field(x)).abs() < 1e-3, "triangle {t} at {x}: {got}");
            }
        }
    }
}
