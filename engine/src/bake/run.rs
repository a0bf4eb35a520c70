//! `relit bake`: runs the bake passes over a scene and keeps their results in its
//! [`BakeCache`] (`.relit/bake-<key>/`).
//!
//! Stages, each a short function over the cache: (1) E_src per view, (2) the albedo mesh (needs
//! every view's E_src), (3) M_src per view, (4) per added light its surface cache and E_add per
//! view. A stage skips what the cache already holds, so an interrupted bake (Ctrl-C, kill -9)
//! resumes where it stopped. `views` bakes a slice, so a capture can be split across jobs:
//! stages 2–4 run once every view's E_src is present.

use std::ops::Range;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use super::{
    AddedIrradiance, AddedParams, AlbedoMesh, BakeCache, CacheLayout, Denoise, DenoiseParams,
    GpuCacheLayout, GpuLight, GpuViews, Mirror, SourceCache, SourceIrradiance, SurfaceCache,
    ViewData,
};
use crate::bake::views::photo_rgba;
use crate::error::{Error, Result};
use crate::gpu::{vk, Buffer, Gpu, Graph, MemoryLocation, RayScene};
use crate::scene::image::load_rgb;
use crate::scene::{Light, Scene};

pub use super::cache::BAKE_VERSION;

#[derive(Clone, Debug)]
pub struct BakeParams {
    /// Rays per pixel for E_src (§4.1.1: 128). With the source cache, the shadow rays per pixel
    /// towards the declared original lights.
    pub irradiance_samples: u32,
    /// Rays per texel for E_src's indirect part in the source cache (`source_cache.rs`), used
    /// when the scene declares its original lights; 0: every ray per pixel, as §4.1.1.
    pub source_cache_samples: u32,
    /// Shadow rays per pixel for E_add's direct part.
    pub added_samples: u32,
    /// Paths per texel of the surface cache (E_add's indirect part), and the most bounces.
    /// 32 (preview) is enough: on a scenegen room, 32, 64 and 128 paths gave the same E_add
    /// error against Mitsuba (0.129, 0.129, 0.128), the filter taking the rest of the noise.
    /// Indoors, walls of albedo ~0.6 pass on most of the light: a direct + 1-bounce estimate
    /// reaches about 60% of the true irradiance (measured on the demo room), and 3 bounces left
    /// E_add 0.85–0.88× the truth on plain walls. The presets allow 6, the depth of the ground
    /// truth's path tracer; Russian roulette past 2 bounces keeps the mean path short.
    pub cache_samples: u32,
    pub bounces: u32,
    /// The bake mesh's longest edge (m): longer edges are split, so the surface cache (one
    /// texel per vertex) and the albedo mesh are at least this dense.
    pub texel_size: f32,
    pub seed: u32,
    /// Slice of views to bake (all by default).
    pub views: Option<Range<usize>>,
    /// The added lights to bake, by name (None: every one). Not in the cache key: each light
    /// has an entry of its own, and the frame bakes a missing one when it is first used.
    pub lights: Option<Vec<String>>,
    /// The E_src denoiser (radius 0: off, and the surface cache's filter off too).
    pub denoise: DenoiseParams,
    /// Also store every map as BC6H (`<map>.bc6h`); off = the uncompressed switch (EXR only).
    pub compress: bool,
    /// §4.4 geometry processing of the proxy before baking: Taubin smoothing and RANSAC plane
    /// snapping (off by default).
    pub mesh_process: bool,
}

/// The proxy mesh the bake traces: the scene's, processed when `p.mesh_process` (§4.4).
pub fn bake_mesh(scene: &Scene, p: &BakeParams) -> crate::scene::Mesh {
    let mut m = scene.mesh.clone();
    if p.mesh_process {
        crate::scene::meshproc::smooth(&mut m, 2);
        crate::scene::meshproc::snap_planes(&mut m, &Default::default());
    }
    crate::scene::meshproc::refine(&mut m, p.texel_size);
    m
}

/// The presets' texel size: MVS meshes of a room are about this dense already (the demo's
/// median edge is 5 cm), and the indirect light varies slowly at this scale.
pub const TEXEL_SIZE: f32 = 0.1;

impl BakeParams {
    /// Whether `l` is an added light this bake covers.
    pub fn wants(&self, l: &Light) -> bool {
        !l.original && self.lights.as_ref().is_none_or(|n| n.contains(&l.name))
    }

    /// E_add's parameters.
    pub fn added(&self) -> AddedParams {
        AddedParams {
            samples: self.added_samples,
            cache_samples: self.cache_samples,
            bounces: self.bounces,
            seed: self.seed,
        }
    }

    pub fn final_quality() -> BakeParams {
        BakeParams {
            irradiance_samples: 128,
            source_cache_samples: 512,
            added_samples: 32,
            cache_samples: 128,
            bounces: 6,
            texel_size: TEXEL_SIZE,
            seed: 1,
            views: None,
            lights: None,
            denoise: DenoiseParams::default(),
            mesh_process: false,
            compress: true,
        }
    }
    pub fn preview() -> BakeParams {
        BakeParams {
            irradiance_samples: 32,
            source_cache_samples: 128,
            added_samples: 8,
            cache_samples: 32,
            bounces: 6,
            texel_size: TEXEL_SIZE,
            seed: 1,
            views: None,
            lights: None,
            denoise: DenoiseParams::default(),
            mesh_process: false,
            compress: true,
        }
    }
}

/// What a stage reports as it goes: (stage name, items done, items total, rays traced so far).
pub trait Progress {
    fn update(&mut self, stage: &str, done: usize, total: usize, rays: u64);
}

impl<F: FnMut(&str, usize, usize, u64)> Progress for F {
    fn update(&mut self, stage: &str, done: usize, total: usize, rays: u64) {
        self(stage, done, total, rays)
    }
}

#[derive(Debug, Default)]
pub struct BakeReport {
    pub cache: PathBuf,
    /// (stage, seconds, rays traced, items computed) for the work done in this run.
    pub stages: Vec<(String, f64, u64, usize)>,
    /// Views of the slice whose every map is now in the cache.
    pub complete_views: usize,
    pub albedo_mesh: bool,
}

/// Bakes the entries of the added lights of `p` that have none yet (a light added or moved since
/// the bake, or first used), on a complete bake; the frame calls this before it loads the maps.
pub fn bake_lights(
    gpu: &Arc<Gpu>,
    scene: &Scene,
    p: &BakeParams,
    progress: &mut dyn Progress,
) -> Result<BakeReport> {
    let cache = BakeCache::of(scene, p)?;
    let mut report = BakeReport {
        cache: cache.dir().to_path_buf(),
        ..Default::default()
    };
    let lights = cache.missing_lights(scene, p);
    if lights.is_empty() {
        return Ok(report);
    }
    let s = Setup::new(gpu, scene, p)?;
    let albedo = cache.read_albedo(s.geom.positions.len())?;
    let ab = Buffer::from_slice(gpu, "albedo", vk::BufferUsageFlags::STORAGE_BUFFER, &albedo)?;
    let p = BakeParams {
        views: None,
        lights: None,
        ..p.clone()
    };
    let slice = 0..scene.views.len();
    added_stage(
        gpu,
        &s,
        &ab,
        &cache,
        &lights,
        scene,
        &p,
        &slice,
        progress,
        &mut report,
    )?;
    if p.compress {
        cache.compress_missing()?;
    }
    Ok(report)
}

/// What every bake stage reads: the bake mesh, traceable, and the views with their G-buffers.
struct Setup {
    geom: crate::scene::Mesh,
    mesh: RayScene,
    /// The views' cameras and size (no pixels: those are in `views`).
    data: ViewData,
    views: GpuViews,
}

impl Setup {
    fn new(gpu: &Arc<Gpu>, scene: &Scene, p: &BakeParams) -> Result<Setup> {
        let scales = scene.photo_scales()?;
        let cams: Vec<_> = scene.views.iter().map(|v| v.camera.clone()).collect();
        let geom = bake_mesh(scene, p);
        let mesh = RayScene::new(gpu, &geom.positions, &geom.triangles)?;
        // Straight to the device, view by view: the stages read the views there, and a host
        // copy of every view's G-buffer and image (52 B a pixel) would double the bake's memory.
        let (data, views) = GpuViews::build_streamed(gpu, &mesh, &cams, |j| {
            Ok(photo_rgba(&scene.view_photo(j, scales[j])?).collect())
        })?;
        Ok(Setup {
            geom,
            mesh,
            data,
            views,
        })
    }
}

/// The complete, current bakes of `scene`, best first ([`BakeCache::complete`]).
pub fn complete_bakes(scene: &Scene) -> Result<Vec<BakeParams>> {
    BakeCache::complete(scene)
}

/// The views `p` asks for, checked against the scene.
fn view_slice(scene: &Scene, p: &BakeParams) -> Result<Range<usize>> {
    let nv = scene.views.len();
    let slice = p.views.clone().unwrap_or(0..nv);
    if slice.start >= slice.end || slice.end > nv {
        return Err(Error::Other(format!(
            "--views {}..{}: the scene has views 0..{nv}",
            slice.start, slice.end
        )));
    }
    Ok(slice)
}

/// Bakes `scene` (or the slice `p.views`) into its cache.
pub fn bake(
    gpu: &Arc<Gpu>,
    scene: &Scene,
    p: &BakeParams,
    progress: &mut dyn Progress,
) -> Result<BakeReport> {
    let cache = BakeCache::of(scene, p)?;
    cache.prepare(p)?;
    let slice = view_slice(scene, p)?;
    let s = Setup::new(gpu, scene, p)?;
    let npix = (s.data.width * s.data.height) as u64;
    let out = Buffer::new(
        gpu,
        "bake out",
        npix * 16,
        vk::BufferUsageFlags::STORAGE_BUFFER,
        MemoryLocation::GpuOnly,
    )?;
    let report = BakeReport {
        cache: cache.dir().to_path_buf(),
        ..Default::default()
    };
    let mut st = Stages {
        gpu,
        scene,
        p,
        cache: &cache,
        s,
        out,
        progress,
        report,
    };
    st.source_irradiance(&slice)?;
    if scene.views.iter().all(|v| cache.esrc(&v.name).exists()) {
        let albedo = st.albedo_mesh()?;
        st.mirror(&slice)?;
        let lights = wanted_lights(scene, p);
        let Stages {
            s,
            progress,
            report,
            ..
        } = &mut st;
        added_stage(
            gpu,
            s,
            &albedo,
            &cache,
            &lights,
            scene,
            p,
            &slice,
            &mut **progress,
            report,
        )?;
        st.report.complete_views = slice.len();
    }
    if p.compress {
        cache.compress_missing()?;
    }
    Ok(st.report)
}

/// What the stages of one bake share.
struct Stages<'a> {
    gpu: &'a Arc<Gpu>,
    scene: &'a Scene,
    p: &'a BakeParams,
    cache: &'a BakeCache,
    s: Setup,
    /// One vec4 per pixel of a view, on the device: what a stage's pass writes.
    out: Buffer,
    progress: &'a mut dyn Progress,
    report: BakeReport,
}

impl Stages<'_> {
    fn size(&self) -> (u32, u32, u64) {
        let (w, h) = (self.s.data.width, self.s.data.height);
        (w, h, (w * h) as u64)
    }

    /// `out` as a view's map.
    fn read_out(&self) -> Result<Vec<[f32; 4]>> {
        let mut v: Vec<[f32; 4]> = self.out.download_vec()?;
        v.truncate(self.size().2 as usize);
        Ok(v)
    }

    fn stage(&mut self, name: &str, t0: Instant, rays: u64, items: usize) {
        let secs = t0.elapsed().as_secs_f64();
        self.report.stages.push((name.into(), secs, rays, items));
    }

    /// Stage 1 (§4.1.1): E_src of every view of the slice that lacks it, denoised.
    fn source_irradiance(&mut self, slice: &Range<usize>) -> Result<()> {
        let (scene, p, gpu) = (self.scene, self.p, self.gpu);
        let todo: Vec<usize> = slice
            .clone()
            .filter(|&i| !self.cache.esrc(&scene.views[i].name).exists())
            .collect();
        if todo.is_empty() {
            self.stage("source irradiance", Instant::now(), 0, 0);
            return Ok(());
        }
        let si = SourceIrradiance::new(gpu, &scene.lights)?;
        let radiance = self.radiance_mesh(&si)?;
        let source_cache = match uses_source_cache(scene, p) {
            true => Some(self.source_cache(&si, &radiance)?),
            false => None,
        };
        let (sc, dn) = (SourceCache::new(gpu)?, Denoise::new(gpu)?);
        let (w, h, npix) = self.size();
        let noisy = Buffer::new(
            gpu,
            "noisy map",
            npix * 16,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        // A pixel traces one shadow ray per declared original light and sample; without the
        // source cache, one ray more for the light arriving through the views' pixels.
        let originals = scene.lights.iter().any(|l| l.original) as u64;
        let per_pixel =
            p.irradiance_samples as u64 * (1 + originals * source_cache.is_none() as u64);
        let (t0, mut rays) = (Instant::now(), 0u64);
        for (k, &i) in todo.iter().enumerate() {
            let (v, n, (mesh, views)) = (
                i as u32,
                p.irradiance_samples,
                (&self.s.mesh, &self.s.views),
            );
            // E_src, then (with the denoiser) filtered into the stage's output: the graph puts
            // the barrier between them.
            let denoise = p.denoise.radius > 0;
            let target = if denoise { &noisy } else { &self.out };
            let mut res = Ok(());
            gpu.submit(|cmd| {
                let mut g = Graph::new(gpu, cmd, None);
                res = match &source_cache {
                    Some(c) => {
                        let cache = (&c.0, &c.1);
                        sc.record(
                            &mut g, &si, mesh, &radiance, views, cache, v, n, p.seed, target,
                        )
                    }
                    None => si.record(&mut g, mesh, &radiance, views, v, n, p.seed, target),
                };
                if denoise && res.is_ok() {
                    res = dn.record(&mut g, views, v, p.denoise, &noisy, None, &self.out);
                }
            })?;
            res?;
            let e = self.read_out()?;
            BakeCache::write_map(&self.cache.esrc(&scene.views[i].name), w, h, &e)?;
            rays += npix * per_pixel;
            self.progress
                .update("source irradiance", k + 1, todo.len(), rays);
        }
        self.stage("source irradiance", t0, rays, todo.len());
        Ok(())
    }

    /// The radiance mesh: the views' radiance on the bake mesh, what E_src's rays read.
    fn radiance_mesh(&mut self, si: &SourceIrradiance) -> Result<Buffer> {
        let (s, p, t0) = (&self.s, self.p, Instant::now());
        let lights = &self.scene.lights;
        let r = super::radiance_mesh::build(
            self.gpu,
            si,
            lights,
            &s.geom,
            &s.mesh,
            &s.views,
            p.irradiance_samples,
            p.seed,
        )?;
        let nv = s.geom.positions.len();
        // Declared original lights add one shadow ray per sample.
        let per_sample = 1 + lights.iter().any(|l| l.original) as u64;
        let rays = nv as u64 * p.irradiance_samples as u64 * per_sample;
        self.stage("radiance mesh", t0, rays, nv);
        self.progress.update("radiance mesh", 1, 1, rays);
        Ok(r)
    }

    /// The source cache on the device: read from the bake, or traced, filtered and written
    /// there (a resumed bake, or another slice's job, reuses it).
    fn source_cache(
        &mut self,
        si: &SourceIrradiance,
        radiance: &Buffer,
    ) -> Result<(GpuCacheLayout, Buffer)> {
        let (gpu, p, s) = (self.gpu, self.p, &self.s);
        let layout = CacheLayout::new(&s.geom);
        let file = self.cache.source_cache();
        let values = if file.exists() {
            BakeCache::read_texels(&file, layout.texels())?
        } else {
            let t0 = Instant::now();
            let rounds = filter_rounds(p);
            let n = p.source_cache_samples;
            let progress = &mut *self.progress;
            let v = super::source_cache::trace(
                gpu,
                si,
                &s.mesh,
                radiance,
                &s.views,
                &layout,
                (n, p.seed, rounds),
                &mut |d, total| progress.update("source cache", d as usize, total as usize, 0),
            )?;
            BakeCache::write_texels(&file, &v)?;
            self.stage(
                "source cache",
                t0,
                layout.texels() as u64 * n as u64,
                layout.texels(),
            );
            v
        };
        // A buffer is never empty (a mesh without texels binds one zero).
        let one = [[0.0f32; 4]];
        let values = if values.is_empty() {
            &one[..]
        } else {
            &values[..]
        };
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let vb = Buffer::from_slice(gpu, "source cache", usage, values)?;
        Ok((GpuCacheLayout::upload(gpu, &layout)?, vb))
    }

    /// Stage 2 (§4.1.2): the albedo mesh from every view's E_src, read from the bake when there.
    fn albedo_mesh(&mut self) -> Result<Buffer> {
        let (gpu, scene, s) = (self.gpu, self.scene, &self.s);
        let nverts = s.geom.positions.len();
        let albedo = if self.cache.albedo().exists() {
            self.cache.read_albedo(nverts)?
        } else {
            let t0 = Instant::now();
            let mut e_all = Vec::with_capacity(scene.views.len() * self.size().2 as usize);
            for v in &scene.views {
                let img = load_rgb(&self.cache.esrc(&v.name))?;
                // Rays-used counts are not cached: a stored zero means no estimate.
                let used = |p: &[f32; 3]| if p.iter().any(|c| *c > 0.0) { 1.0 } else { 0.0 };
                e_all.extend(img.pixels.iter().map(|p| [p[0], p[1], p[2], used(p)]));
            }
            // Read by address: all views' maps may pass maxStorageBufferRange.
            let usage = vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
            let eb = Buffer::from_slice(gpu, "e_src all", usage, &e_all)?;
            let am = AlbedoMesh::new(gpu, &scene.lights)?;
            let mut a = am.run(&s.mesh, nverts as u32, &s.views, &eb)?;
            // Vertices on a declared light have no samples: they take their neighbours' albedo.
            super::albedo_mesh::fill_unseen(&s.geom.triangles, &mut a);
            self.cache.write_albedo(&a)?;
            self.stage("albedo mesh", t0, 0, nverts);
            self.progress.update("albedo mesh", 1, 1, 0);
            a
        };
        self.report.albedo_mesh = true;
        Buffer::from_slice(gpu, "albedo", vk::BufferUsageFlags::STORAGE_BUFFER, &albedo)
    }

    /// Stage 3 (§4.2.1): the mirror image M_src of every view of the slice that lacks it.
    fn mirror(&mut self, slice: &Range<usize>) -> Result<()> {
        let mirror = Mirror::new(self.gpu)?;
        let (w, h, npix) = self.size();
        let (t0, mut done) = (Instant::now(), 0);
        for (k, i) in slice.clone().enumerate() {
            let file = self.cache.msrc(&self.scene.views[i].name);
            if !file.exists() {
                let mut res = Ok(());
                let (s, out) = (&self.s, &self.out);
                self.gpu.submit(|cmd| {
                    let g = &mut Graph::new(self.gpu, cmd, None);
                    res = mirror.record(g, &s.mesh, &s.views, i as u32, out)
                })?;
                res?;
                BakeCache::write_map(&file, w, h, &self.read_out()?)?;
                done += 1;
            }
            self.progress
                .update("mirror", k + 1, slice.len(), npix * (k as u64 + 1));
        }
        self.stage("mirror", t0, npix * done as u64, done);
        Ok(())
    }
}

/// Whether the bake splits E_src among the declared original lights (per-light control,
/// `frame/lighting.rs`): with two or more, each has an entry as an added light has (its surface
/// cache and E_add maps from its declared radiance), its simulated share of E_src. One original
/// light needs none: E_src is all its own.
pub fn splits_originals(scene: &Scene) -> bool {
    scene.lights.iter().filter(|l| l.original).count() >= 2
}

/// The lights with entries of their own, in the frame's E_add layer order: the added lights,
/// then the declared original ones when the bake splits E_src among them.
pub fn entry_lights(scene: &Scene) -> impl Iterator<Item = &Light> + Clone {
    let split = splits_originals(scene);
    let added = scene.lights.iter().filter(|l| !l.original);
    added.chain(scene.lights.iter().filter(move |l| split && l.original))
}

/// The entry lights `p` asks for: the added lights it wants, and every original light (their
/// shares need all of them) when it names one of them. Like an added light's, they are baked
/// when first used (a lighting with a factor for one original light) or asked for (`relit bake
/// --lights all` names every light, a preset with `originals`); `lights: None` (every added
/// light: datasets, `dump --parts`) asks for none.
pub fn wanted_lights<'a>(scene: &'a Scene, p: &BakeParams) -> Vec<&'a Light> {
    let named = |l: &Light| p.lights.as_ref().is_some_and(|n| n.contains(&l.name));
    let originals = scene.lights.iter().any(|l| l.original && named(l));
    let wants = |l: &Light| if l.original { originals } else { p.wants(l) };
    entry_lights(scene).filter(|l| wants(l)).collect()
}

/// Whether E_src's indirect part comes from the source cache: when asked for and the scene
/// declares original lights (without them their light reaches E_src through the views' pixels,
/// whose shadows texels would blur).
pub fn uses_source_cache(scene: &Scene, p: &BakeParams) -> bool {
    p.source_cache_samples > 0 && scene.lights.iter().any(|l| l.original)
}

/// Rounds of the surface caches' filter along the mesh (off with the denoiser).
const CACHE_FILTER_ROUNDS: u32 = 2;

fn filter_rounds(p: &BakeParams) -> u32 {
    if p.denoise.radius > 0 {
        CACHE_FILTER_ROUNDS
    } else {
        0
    }
}

/// Traces and filters one light's surface cache.
#[allow(clippy::too_many_arguments)]
fn trace_cache(
    sc: &SurfaceCache,
    mesh: &RayScene,
    glayout: &GpuCacheLayout,
    layout: &CacheLayout,
    albedo: &Buffer,
    light: &GpuLight,
    p: &BakeParams,
    progress: &mut dyn FnMut(u32, u32),
) -> Result<Vec<[f32; 4]>> {
    let raw = sc.run(mesh, glayout, albedo, light, p.added(), progress)?;
    Ok(layout.filter(&raw, filter_rounds(p)))
}

/// The surface caches of `lights` (the scene's added lights, possibly moved) in the bake for
/// `p`, traced where their entry has none yet: what `fly` blends for a light a path moves.
pub fn light_caches(
    gpu: &Arc<Gpu>,
    scene: &Scene,
    p: &BakeParams,
    lights: &[Light],
    progress: &mut dyn Progress,
) -> Result<Vec<Vec<[f32; 4]>>> {
    let cache = BakeCache::of(scene, p)?;
    let geom = bake_mesh(scene, p);
    let layout = CacheLayout::new(&geom);
    let missing: Vec<&Light> = lights
        .iter()
        .filter(|l| !cache.surface_cache(l, p).exists())
        .collect();
    if !missing.is_empty() {
        let mesh = RayScene::new(gpu, &geom.positions, &geom.triangles)?;
        let albedo = cache.read_albedo(geom.positions.len())?;
        let ab = Buffer::from_slice(gpu, "albedo", vk::BufferUsageFlags::STORAGE_BUFFER, &albedo)?;
        let glayout = GpuCacheLayout::upload(gpu, &layout)?;
        let sc = SurfaceCache::new(gpu)?;
        for (k, l) in missing.iter().enumerate() {
            let stage = format!("surface cache {}/{}", k + 1, missing.len());
            let v = trace_cache(
                &sc,
                &mesh,
                &glayout,
                &layout,
                &ab,
                &GpuLight::traced(l),
                p,
                &mut |d, n| progress.update(&stage, d as usize, n as usize, 0),
            )?;
            BakeCache::write_texels(&cache.surface_cache(l, p), &v)?;
        }
    }
    lights
        .iter()
        .map(|l| BakeCache::read_texels(&cache.surface_cache(l, p), layout.texels()))
        .collect()
}

/// Stage 4 (§4.1.3): the lights' entries that are missing: the surface cache (traced once per
/// light, kept as `light-<key>/surface_cache.bin`) and the E_add map of every view in `slice`.
#[allow(clippy::too_many_arguments)]
fn added_stage(
    gpu: &Arc<Gpu>,
    s: &Setup,
    albedo: &Buffer,
    cache: &BakeCache,
    lights: &[&Light],
    scene: &Scene,
    p: &BakeParams,
    slice: &Range<usize>,
    progress: &mut dyn Progress,
    report: &mut BakeReport,
) -> Result<()> {
    let ap = p.added();
    let layout = CacheLayout::new(&s.geom);
    let glayout = GpuCacheLayout::upload(gpu, &layout)?;
    let (sc, added) = (SurfaceCache::new(gpu)?, AddedIrradiance::new(gpu)?);
    let (mut cache_s, mut cache_rays, mut caches) = (0.0, 0u64, 0);
    let (mut added_s, mut added_rays, mut maps) = (0.0, 0u64, 0);
    let (w, h) = (s.views.width, s.views.height);
    let npix = (w * h) as u64;
    for (li, l) in lights.iter().enumerate() {
        let todo: Vec<usize> = slice
            .clone()
            .filter(|&i| !cache.eadd(&scene.views[i].name, l, p).exists())
            .collect();
        if todo.is_empty() {
            continue;
        }
        let gl = GpuLight::traced(l);
        let cf = cache.surface_cache(l, p);
        let values = if cf.exists() {
            BakeCache::read_texels(&cf, layout.texels())?
        } else {
            let t = Instant::now();
            let stage = format!("surface cache {}/{}", li + 1, lights.len());
            let v = trace_cache(
                &sc,
                &s.mesh,
                &glayout,
                &layout,
                albedo,
                &gl,
                p,
                &mut |d, n| progress.update(&stage, d as usize, n as usize, 0),
            )?;
            BakeCache::write_texels(&cf, &v)?;
            cache_s += t.elapsed().as_secs_f64();
            cache_rays += super::surface_cache::max_rays(layout.texels(), ap);
            caches += 1;
            v
        };
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let cb = Buffer::from_slice(gpu, "surface cache", usage, &values)?;
        let t = Instant::now();
        for (k, &i) in todo.iter().enumerate() {
            let m = added.run(&s.mesh, &s.views, &glayout, &cb, i as u32, &gl, ap)?;
            BakeCache::write_map(&cache.eadd(&scene.views[i].name, l, p), w, h, &m)?;
            maps += 1;
            added_rays += npix * ap.samples as u64;
            let stage = format!("added irradiance {}/{}", li + 1, lights.len());
            progress.update(&stage, k + 1, todo.len(), added_rays);
        }
        added_s += t.elapsed().as_secs_f64();
    }
    report
        .stages
        .push(("surface cache".into(), cache_s, cache_rays, caches));
    report
        .stages
        .push(("added irradiance".into(), added_s, added_rays, maps));
    Ok(())
}
