//! Live lights (`shaders_glsl/frame/live.glsl`): added lights being placed or moved in the
//! viewer. Their E_add is evaluated at the frame's surface points (direct light by next-event
//! estimation + the light's surface cache), so a light shows where it is at the next frame; the
//! cache is refined a few paths per texel per call while the light stays put, converging to
//! what the bake would store. Moving the light again starts its cache over. The texels the last
//! frame shows are refined first (the focus), the rest of the mesh after them: what the user
//! looks at converges in a fraction of the time the whole cache takes.

use std::sync::Arc;

use glam::Vec3;

use crate::bake::surface_cache::{CacheLayout, GpuCacheLayout, SurfaceCache, Texels};
use crate::bake::{AddedParams, GpuLight};
use crate::error::{Error, Result};
use crate::gpu::{vk, Buffer, Gpu, Graph, MemoryLocation, RayScene};
use crate::scene::Mesh;

/// At most this many lights are live at once (each costs shadow rays at every pixel).
pub const MAX_LIVE: usize = 4;

/// As `LiveLight` in live.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuLive {
    pub light: GpuLight,
    pub layer: u32,
    pub samples: u32,
    pub texels: u32,
    pub pad: u32,
}

/// The live lights' parameters: shadow rays per point each frame, paths per texel per
/// refinement, and the paths per texel at which a cache counts as converged (the preview bake's).
#[derive(Clone, Copy, Debug)]
pub struct LiveParams {
    pub samples: u32,
    pub paths_per_step: u32,
    pub paths: u32,
    pub bounces: u32,
}

impl Default for LiveParams {
    fn default() -> LiveParams {
        LiveParams {
            samples: 8,
            paths_per_step: 2,
            paths: 32,
            bounces: 6,
        }
    }
}

struct Entry {
    layer: u32,
    light: GpuLight,
    /// Sum of the cache estimates so far, and the paths each texel holds.
    sum: Vec<[f32; 4]>,
    count: Vec<u32>,
    /// Refinement steps so far: each step's seed, so that no texel draws the same paths twice.
    steps: u32,
    /// The filtered cache on the device. After a move it stays the old place's until the new
    /// estimate has `SHOW_AFTER` paths: a lamp moved a few centimetres changes its indirect
    /// light little, so the stale cache looks closer than none (direct light is exact at once).
    shown: Vec<[f32; 4]>,
}

/// Paths per texel before a moved light's new cache replaces the old one on screen.
const SHOW_AFTER: u32 = 4;

pub struct LiveLights {
    pub params: LiveParams,
    gpu: Arc<Gpu>,
    layout: CacheLayout,
    glayout: GpuCacheLayout,
    albedo: Option<Buffer>,
    tracer: SurfaceCache,
    entries: Vec<Entry>,
    /// MAX_LIVE caches (filtered means), the lights, one pass's output, the texels it traces.
    caches: Buffer,
    lives: Buffer,
    step: Buffer,
    list: Buffer,
}

impl LiveLights {
    /// For the bake mesh `mesh` (the frame's proxy); `albedo` per vertex from the bake, without
    /// which no light can be live.
    pub fn new(gpu: &Arc<Gpu>, mesh: &Mesh, albedo: Option<&[[f32; 4]]>) -> Result<LiveLights> {
        let layout = CacheLayout::new(mesh);
        let n = layout.texels().max(1) as u64;
        let buf = |name: &str, size: u64| {
            Buffer::new(
                gpu,
                name,
                size,
                vk::BufferUsageFlags::STORAGE_BUFFER,
                MemoryLocation::GpuOnly,
            )
        };
        let albedo = match albedo {
            Some(a) if a.len() == mesh.positions.len() => Some(Buffer::from_slice(
                gpu,
                "live albedo",
                vk::BufferUsageFlags::STORAGE_BUFFER,
                a,
            )?),
            Some(a) => {
                return Err(Error::Other(format!(
                    "albedo mesh has {} vertices; the bake mesh has {}",
                    a.len(),
                    mesh.positions.len()
                )))
            }
            None => None,
        };
        let caches = buf("live caches", MAX_LIVE as u64 * n * 16)?;
        caches.upload(&vec![0u8; (MAX_LIVE as u64 * n * 16) as usize])?;
        Ok(LiveLights {
            params: LiveParams::default(),
            gpu: gpu.clone(),
            glayout: GpuCacheLayout::upload(gpu, &layout)?,
            layout,
            albedo,
            tracer: SurfaceCache::new(gpu)?,
            entries: Vec::new(),
            caches,
            lives: buf(
                "live lights",
                (MAX_LIVE * std::mem::size_of::<GpuLive>()) as u64,
            )?,
            step: buf("live cache step", n * 16)?,
            list: Buffer::new(
                gpu,
                "live cache texels",
                n * 4,
                vk::BufferUsageFlags::STORAGE_BUFFER,
                MemoryLocation::CpuToGpu,
            )?,
        })
    }

    pub fn count(&self) -> u32 {
        self.entries.len() as u32
    }

    /// Bit l set: added light l is live (live.glsl's `is_live`).
    pub fn mask(&self) -> u32 {
        self.entries.iter().fold(0, |m, e| m | (1 << e.layer))
    }

    pub fn is_live(&self, layer: usize) -> bool {
        self.entries.iter().any(|e| e.layer as usize == layer)
    }

    /// Paths per texel in each live light's cache so far, by layer.
    pub fn progress(&self) -> Vec<(u32, u32)> {
        self.entries
            .iter()
            .map(|e| (e.layer, e.count.iter().copied().min().unwrap_or(0)))
            .collect()
    }

    /// Whether live light `layer`'s cache holds the converged count of paths at every texel
    /// (the viewer has refined it, or a path placed it with a finished cache).
    pub fn converged(&self, layer: usize) -> bool {
        (self.entries.iter())
            .any(|e| e.layer as usize == layer && e.count.iter().all(|&c| c >= self.params.paths))
    }

    /// Paths per texel so far of live light `layer`'s cache (None: not live).
    pub fn texel_paths(&self, layer: usize) -> Option<&[u32]> {
        self.entries
            .iter()
            .find(|e| e.layer as usize == layer)
            .map(|e| &e.count[..])
    }

    /// The cache texels of the triangles a frame shows (`tri`: the G-buffer's triangle id + 1
    /// per pixel, 0 for none), each once.
    pub fn texels_shown(&self, tri: &[u32]) -> Vec<u32> {
        let mut seen = vec![false; self.layout.texels()];
        for &t in tri.iter().filter(|&&t| t > 0) {
            for k in 0..3 {
                if let Some(&c) = self.layout.corners.get(3 * (t as usize - 1) + k) {
                    seen[c as usize] = true;
                }
            }
        }
        (0..seen.len() as u32)
            .filter(|&i| seen[i as usize])
            .collect()
    }

    /// Makes added light `layer` live at `light` (or moves it): its cache starts over.
    pub fn set(&mut self, layer: usize, light: &GpuLight) -> Result<()> {
        if self.albedo.is_none() {
            return Err(Error::Other(
                "lights can only be moved on a baked scene (its albedo mesh is needed)".into(),
            ));
        }
        if layer >= 32 {
            return Err(Error::Other(format!(
                "added light {layer}: only the first 32 added lights can be moved live"
            )));
        }
        let n = self.layout.texels();
        match self.entries.iter().position(|e| e.layer as usize == layer) {
            Some(i) => {
                let e = &mut self.entries[i];
                e.light = *light;
                e.sum = vec![[0.0; 4]; n];
                e.count = vec![0; n];
                e.steps = 0;
            }
            None if self.entries.len() == MAX_LIVE => {
                return Err(Error::Other(format!(
                    "at most {MAX_LIVE} lights can be moved at once: bake the scene's lights \
                     (save them, then `relit bake`) to move more"
                )))
            }
            None => self.entries.push(Entry {
                layer: layer as u32,
                light: *light,
                sum: vec![[0.0; 4]; n],
                count: vec![0; n],
                steps: 0,
                shown: vec![[0.0; 4]; n],
            }),
        }
        self.upload()
    }

    /// Makes added light `layer` live at `light` with a finished cache (no refinement).
    pub fn set_converged(
        &mut self,
        layer: usize,
        light: &GpuLight,
        cache: Vec<[f32; 4]>,
    ) -> Result<()> {
        self.set(layer, light)?;
        let paths = self.params.paths;
        let e = self
            .entries
            .iter_mut()
            .find(|e| e.layer as usize == layer)
            .expect("just set");
        e.sum = cache
            .iter()
            .map(|v| {
                [
                    v[0] * paths as f32,
                    v[1] * paths as f32,
                    v[2] * paths as f32,
                    0.0,
                ]
            })
            .collect();
        e.count = vec![paths; e.sum.len()];
        e.shown = cache;
        self.upload()
    }

    /// Added light `layer` is no longer live (its baked maps are read again).
    pub fn unset(&mut self, layer: usize) -> Result<()> {
        self.entries.retain(|e| e.layer as usize != layer);
        self.upload()
    }

    /// One refinement step: `paths_per_step` more paths per texel for every live light whose
    /// cache is not converged, on the `focus` texels (those the frame shows, see
    /// [`LiveLights::texels_shown`]) while any of them is short of paths, then on the rest.
    /// Returns whether anything changed.
    pub fn refine(&mut self, mesh: &RayScene, focus: Option<&[u32]>) -> Result<bool> {
        let Some(albedo) = &self.albedo else {
            return Ok(false);
        };
        let p = self.params;
        let mut changed = false;
        for e in &mut self.entries {
            let short = |t: &u32| e.count[*t as usize] < p.paths;
            let mut todo: Vec<u32> = focus.unwrap_or(&[]).iter().copied().filter(short).collect();
            if todo.is_empty() {
                todo = (0..e.count.len() as u32).filter(short).collect();
            }
            if todo.is_empty() {
                continue;
            }
            let fewest = todo.iter().map(|&t| e.count[t as usize]).min().unwrap_or(0);
            let ap = AddedParams {
                samples: p.samples,
                cache_samples: p.paths_per_step,
                bounces: p.bounces,
                // A new seed per step: the steps are independent estimates.
                seed: 0x5EED_0000 + e.steps,
            };
            e.steps += 1;
            self.list.upload(bytemuck::cast_slice(&todo))?;
            let mut res = Ok(());
            self.gpu.submit(|cmd| {
                res = self.tracer.record(
                    &mut Graph::new(&self.gpu, cmd, None),
                    mesh,
                    &self.glayout,
                    albedo,
                    &e.light,
                    ap,
                    Texels::List {
                        list: &self.list,
                        count: todo.len() as u32,
                    },
                    &self.step,
                )
            })?;
            res?;
            let step: Vec<[f32; 4]> = self.step.download_vec()?;
            let w = p.paths_per_step as f32;
            for &t in &todo {
                let (s, v) = (&mut e.sum[t as usize], step[t as usize]);
                for k in 0..3 {
                    s[k] += w * v[k];
                }
                e.count[t as usize] += p.paths_per_step;
            }
            let fewest = fewest + p.paths_per_step;
            if fewest >= SHOW_AFTER.min(p.paths) || e.shown.iter().all(|v| v[3] == 0.0) {
                // Fewer paths, more smoothing: the first estimates are noisy, and a blurred
                // indirect light is closer to the truth than a grainy one. Texels with too few
                // paths of their own (outside the focus) keep what they showed.
                // Texels this step did not trace keep what they showed (a converged texel is
                // not smoothed again when new texels come into view).
                let rounds = (16 / fewest).max(2);
                let fresh = self.layout.filter(&mean(&e.sum, &e.count), rounds);
                let show = SHOW_AFTER.min(p.paths);
                let mut traced = vec![false; fresh.len()];
                for &t in &todo {
                    traced[t as usize] = true;
                }
                for (t, f) in fresh.into_iter().enumerate() {
                    if (traced[t] && e.count[t] >= show) || e.shown[t][3] == 0.0 {
                        e.shown[t] = f;
                    }
                }
            }
            changed = true;
        }
        if changed {
            self.upload()?;
        }
        Ok(changed)
    }

    /// The filtered mean cache of each live light, and the lights, to the device.
    fn upload(&self) -> Result<()> {
        let n = self.layout.texels();
        let mut all = vec![[0f32; 4]; MAX_LIVE * n.max(1)];
        let mut lives = vec![GpuLive::zeroed(); MAX_LIVE];
        for (i, e) in self.entries.iter().enumerate() {
            all[i * n..(i + 1) * n].copy_from_slice(&e.shown);
            lives[i] = GpuLive {
                light: e.light,
                layer: e.layer,
                samples: self.params.samples,
                texels: n as u32,
                pad: 0,
            };
        }
        self.caches.upload(bytemuck::cast_slice(&all))?;
        self.lives.upload(bytemuck::cast_slice(&lives))
    }

    /// The current filtered caches, live light by live light (for the CPU references).
    pub fn caches(&self) -> Result<Vec<Vec<[f32; 4]>>> {
        let all: Vec<[f32; 4]> = self.caches.download_vec()?;
        let n = self.layout.texels();
        Ok((0..self.entries.len())
            .map(|i| all[i * n..(i + 1) * n].to_vec())
            .collect())
    }

    pub fn lights(&self) -> Vec<GpuLive> {
        self.entries
            .iter()
            .map(|e| GpuLive {
                light: e.light,
                layer: e.layer,
                samples: self.params.samples,
                texels: self.layout.texels() as u32,
                pad: 0,
            })
            .collect()
    }

    pub fn layout(&self) -> &CacheLayout {
        &self.layout
    }

    /// The buffers live.glsl binds (23: caches, 24: corners, 25: lights).
    pub fn buffers(&self) -> (&Buffer, &Buffer, &Buffer) {
        (&self.caches, &self.glayout.corners, &self.lives)
    }
}

use bytemuck::Zeroable;

/// Each texel's mean of its `count` estimates (w = 1: an estimate is present, 0: none yet).
fn mean(sum: &[[f32; 4]], count: &[u32]) -> Vec<[f32; 4]> {
    sum.iter()
        .zip(count)
        .map(|(s, &c)| match c {
            0 => [0.0; 4],
            c => (Vec3::from_slice(&s[..3]) / c as f32).extend(1.0).into(),
        })
        .collect()
}

/// CPU mirror of `live_eadd`: live light `i` at x (normal n) on triangle `tri`.
#[allow(clippy::too_many_arguments)]
pub fn reference_eadd(
    mesh: &Mesh,
    layout: &CacheLayout,
    live: &GpuLive,
    cache: &[[f32; 4]],
    i: u32,
    x: Vec3,
    n: Vec3,
    tri: usize,
    key: u32,
) -> Vec3 {
    let dir: Vec3 = (0..live.samples)
        .map(|s| {
            live.light
                .direct(mesh, x, n, crate::bake::random::rand2([key, s, i]), 0.0)
        })
        .sum();
    dir / live.samples.max(1) as f32 + layout.lookup(mesh, cache, tri, x)
}

/// The lights a camera path moves (`moves` in its lighting keyframes): their surface caches at
/// each keyframe's place, traced once (kept in the bake's light entries); at any time the
/// light is live at its interpolated place, with exact direct light and the two neighbouring
/// keyframes' caches blended by the same weight (indirect light varies slowly with the place).
pub struct PathMoves {
    lights: Vec<MovedLight>,
}

/// A light a path moves: its layer, its place in the scene, its cache at each keyframe.
struct MovedLight {
    layer: usize,
    base: crate::scene::Light,
    caches: Vec<Vec<[f32; 4]>>,
}

impl PathMoves {
    pub fn new(
        gpu: &Arc<Gpu>,
        scene: &crate::scene::Scene,
        params: &crate::bake::BakeParams,
        path: &crate::scene::path::CameraPath,
        progress: &mut dyn crate::bake::Progress,
    ) -> Result<PathMoves> {
        let added: Vec<&crate::scene::Light> =
            scene.lights.iter().filter(|l| !l.original).collect();
        let mut lights = Vec::new();
        for name in path.moved_lights() {
            let Some(layer) = added.iter().position(|l| l.name == name) else {
                return Err(Error::Other(format!(
                    "the path moves \"{name}\", which is not an added light of the scene"
                )));
            };
            let base = added[layer].clone();
            let placed: Vec<crate::scene::Light> = path
                .moves_at_keys(&name)
                .iter()
                .map(|d| base.translated(*d))
                .collect();
            let caches = crate::bake::run::light_caches(gpu, scene, params, &placed, progress)?;
            lights.push(MovedLight {
                layer,
                base,
                caches,
            });
        }
        Ok(PathMoves { lights })
    }

    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Places the moved lights as the path has them at time t.
    pub fn apply(
        &self,
        r: &mut super::Renderer,
        path: &crate::scene::path::CameraPath,
        t: f32,
    ) -> Result<()> {
        let (Some((i, j, u)), Some(l)) = (path.lighting_segment(t), path.lighting_at(t)) else {
            return Ok(());
        };
        for MovedLight {
            layer,
            base,
            caches,
        } in &self.lights
        {
            let d = l.moves.get(&base.name).copied().unwrap_or(Vec3::ZERO);
            if d == Vec3::ZERO {
                r.unset_live_light(*layer, base)?;
                continue;
            }
            let blend: Vec<[f32; 4]> = caches[i]
                .iter()
                .zip(&caches[j])
                .map(|(a, b)| {
                    let m = Vec3::from_slice(&a[..3]) * (1.0 - u) + Vec3::from_slice(&b[..3]) * u;
                    m.extend(1.0).into()
                })
                .collect();
            r.set_live_light_cached(*layer, &base.translated(d), blend)?;
        }
        Ok(())
    }
}
