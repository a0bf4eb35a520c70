//! `relit bake`: runs the bake passes over a scene and keeps their results in a cache under the
//! scene directory, `.relit/bake-<key>/`, keyed by a hash of the inputs and parameters.
//!
//! Stages: (1) E_src per view, (2) the albedo mesh (needs every view's E_src), (3) M_src and one
//! E_add per added light, per view. Each view's maps are written to a temp file and renamed, so
//! an interrupted bake (Ctrl-C, kill -9) resumes where it stopped and never reads a partial
//! entry. `views` bakes a slice, so a capture can be split across jobs: stage 2 and 3 run once
//! every view's E_src is present.

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use super::{
    AddedIrradiance, AddedParams, AlbedoMesh, CacheLayout, Denoise, DenoiseParams, GpuCacheLayout,
    GpuLight, GpuViews, Mirror, SourceCache, SourceIrradiance, SurfaceCache, ViewData,
};
use crate::error::{Error, Result};
use crate::gpu::{vk, Buffer, Gpu, MemoryLocation, RayScene};
use crate::scene::image::{load_rgb, write_exr, RgbImage};
use crate::scene::{write_atomic, Light, Scene};

/// Bump when a pass changes what it computes: old caches are then not reused.
pub const BAKE_VERSION: u32 = 8;

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

/// FNV-1a 64: a stable hash (std's hasher may change between Rust versions).
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 = (self.0 ^ x as u64).wrapping_mul(0x0000_0100_0000_01B3);
        }
    }
    fn file(&mut self, p: &Path) -> Result<()> {
        let b = std::fs::read(p).map_err(|e| Error::io(p, e))?;
        self.bytes(&(b.len() as u64).to_le_bytes());
        self.bytes(&b);
        Ok(())
    }
}

/// The cache directory for `scene` and `p` (the view slice does not change the key).
pub fn cache_dir(scene: &Scene, p: &BakeParams) -> Result<PathBuf> {
    let mut h = Fnv::new();
    h.bytes(&BAKE_VERSION.to_le_bytes());
    // E_add's sample counts and bounces key the light entries (`light_dir`), not the bake.
    for v in [p.irradiance_samples, p.source_cache_samples, p.seed] {
        h.bytes(&v.to_le_bytes());
    }
    h.bytes(&p.texel_size.to_le_bytes());
    h.bytes(&[p.mesh_process as u8]);
    let d = p.denoise;
    for v in [d.radius as f32, d.sigma_px, d.sigma_depth, d.normal_power] {
        h.bytes(&v.to_le_bytes());
    }
    h.file(&scene.mesh_path)?;
    for v in &scene.views {
        h.bytes(v.name.as_bytes());
        h.bytes(bytemuck::bytes_of(&v.camera.to_gpu(0.0, 0.0)));
        h.file(&v.image)?;
    }
    // Original lights shape E_src and the albedo; added lights have entries of their own.
    for l in scene.lights.iter().filter(|l| l.original) {
        h.bytes(l.name.as_bytes());
        h.bytes(bytemuck::bytes_of(&GpuLight::new(l)));
    }
    Ok(scene.root.join(".relit").join(format!("bake-{:016x}", h.0)))
}

fn to_image(w: u32, h: u32, px: &[[f32; 4]]) -> RgbImage {
    RgbImage {
        width: w,
        height: h,
        pixels: px.iter().map(|p| [p[0], p[1], p[2]]).collect(),
    }
}

fn from_image(img: &RgbImage) -> Vec<[f32; 4]> {
    img.pixels.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect()
}

/// `params.json` in a cache: the parameters that made it, so readers can find every bake of
/// a scene (the key alone cannot be inverted).
fn write_params(cache: &Path, p: &BakeParams) -> Result<()> {
    let d = p.denoise;
    let doc = serde_json::json!({
        "irradiance_samples": p.irradiance_samples, "source_cache_samples": p.source_cache_samples,
        "added_samples": p.added_samples,
        "cache_samples": p.cache_samples, "texel_size": p.texel_size, "bounces": p.bounces, "seed": p.seed, "mesh_process": p.mesh_process,
        "denoise": { "radius": d.radius, "sigma_px": d.sigma_px, "sigma_depth": d.sigma_depth,
                     "normal_power": d.normal_power },
    });
    write_atomic(&cache.join("params.json"), doc.to_string().as_bytes())
}

fn read_params(path: &Path) -> Option<BakeParams> {
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(path).ok()?).ok()?;
    let u = |k: &str| v.get(k)?.as_u64().map(|x| x as u32);
    let d = v.get("denoise")?;
    let f = |k: &str| d.get(k)?.as_f64().map(|x| x as f32);
    Some(BakeParams {
        irradiance_samples: u("irradiance_samples")?,
        source_cache_samples: u("source_cache_samples")?,
        added_samples: u("added_samples")?,
        cache_samples: u("cache_samples")?,
        bounces: u("bounces")?,
        texel_size: v.get("texel_size")?.as_f64()? as f32,
        seed: u("seed")?,
        views: None,
        lights: None,
        denoise: DenoiseParams {
            radius: d.get("radius")?.as_i64()? as i32,
            sigma_px: f("sigma_px")?,
            sigma_depth: f("sigma_depth")?,
            normal_power: f("normal_power")?,
        },
        compress: true,
        mesh_process: v.get("mesh_process")?.as_bool()?,
    })
}

/// Whether every map the frame reads is in the cache for `p`.
/// Added lights' entries are not needed: `bake_lights` bakes a missing one when it is used.
pub fn is_complete(scene: &Scene, p: &BakeParams) -> Result<bool> {
    let dir = cache_dir(scene, p)?;
    Ok(albedo_file(&dir).exists()
        && scene
            .views
            .iter()
            .all(|v| esrc_file(&dir, &v.name).exists() && msrc_file(&dir, &v.name).exists()))
}

/// The added lights of `p` whose entry in the bake lacks a view's map.
pub fn missing_lights<'a>(scene: &'a Scene, p: &BakeParams) -> Result<Vec<&'a Light>> {
    let dir = cache_dir(scene, p)?;
    Ok(scene
        .lights
        .iter()
        .filter(|l| p.wants(l))
        .filter(|l| {
            scene
                .views
                .iter()
                .any(|v| !eadd_file(&dir, &v.name, l, p).exists())
        })
        .collect())
}

/// Bakes the entries of the added lights of `p` that have none yet (a light added or moved since
/// the bake, or first used), on a complete bake; the frame calls this before it loads the maps.
pub fn bake_lights(
    gpu: &Arc<Gpu>,
    scene: &Scene,
    p: &BakeParams,
    progress: &mut dyn Progress,
) -> Result<BakeReport> {
    let cache = cache_dir(scene, p)?;
    let mut report = BakeReport {
        cache: cache.clone(),
        ..Default::default()
    };
    let lights = missing_lights(scene, p)?;
    if lights.is_empty() {
        return Ok(report);
    }
    let s = Setup::new(gpu, scene, p)?;
    let albedo = read_albedo(&albedo_file(&cache), s.geom.positions.len())?;
    let ab = Buffer::from_slice(gpu, "albedo", vk::BufferUsageFlags::STORAGE_BUFFER, &albedo)?;
    let p = BakeParams {
        views: None,
        lights: None,
        ..p.clone()
    };
    added_stage(
        gpu,
        &s.mesh,
        &s.geom,
        &s.views,
        &ab,
        &cache,
        &lights,
        scene,
        &p,
        progress,
        &mut report,
    )?;
    if p.compress {
        compress_missing(&cache)?;
    }
    Ok(report)
}

/// What every bake stage reads: the bake mesh, traceable, and the views with their G-buffers.
struct Setup {
    geom: crate::scene::Mesh,
    mesh: RayScene,
    data: ViewData,
    views: GpuViews,
}

impl Setup {
    fn new(gpu: &Arc<Gpu>, scene: &Scene, p: &BakeParams) -> Result<Setup> {
        let images = scene
            .views
            .iter()
            .map(|v| load_rgb(&v.image))
            .collect::<Result<Vec<_>>>()?;
        let cams: Vec<_> = scene.views.iter().map(|v| v.camera.clone()).collect();
        let geom = bake_mesh(scene, p);
        let mesh = RayScene::new(gpu, &geom.positions, &geom.triangles)?;
        let data = ViewData::build(gpu, &mesh, &cams, &images)?;
        let views = GpuViews::upload(gpu, &data)?;
        Ok(Setup {
            geom,
            mesh,
            data,
            views,
        })
    }
}

/// The complete, current bakes of `scene` (their key matches the scene's files as they are
/// now), best first (most E_src rays, then most E_add paths).
pub fn complete_bakes(scene: &Scene) -> Result<Vec<BakeParams>> {
    let mut cands = vec![BakeParams::final_quality(), BakeParams::preview()];
    if let Ok(rd) = std::fs::read_dir(scene.root.join(".relit")) {
        let mut dirs: Vec<_> = rd.flatten().map(|e| e.path()).collect();
        dirs.sort();
        cands.extend(
            dirs.iter()
                .filter_map(|d| read_params(&d.join("params.json"))),
        );
    }
    let mut out: Vec<(PathBuf, BakeParams)> = Vec::new();
    for p in cands {
        let dir = cache_dir(scene, &p)?;
        if out.iter().all(|(d, _)| *d != dir) && is_complete(scene, &p)? {
            out.push((dir, p));
        }
    }
    out.sort_by_key(|(_, p)| std::cmp::Reverse((p.irradiance_samples, p.added_samples)));
    Ok(out.into_iter().map(|(_, p)| p).collect())
}

/// File names of a view's cached maps.
pub fn esrc_file(cache: &Path, view: &str) -> PathBuf {
    cache.join(format!("{view}.esrc.exr"))
}
pub fn msrc_file(cache: &Path, view: &str) -> PathBuf {
    cache.join(format!("{view}.msrc.exr"))
}
/// An added light's entry in a bake: its surface cache and E_add maps, keyed by what the light
/// is (shape, place, size, radiance; not its name) and E_add's parameters, so moving one light
/// or changing E_add's sample counts re-bakes the light entries alone.
pub fn light_dir(cache: &Path, light: &Light, p: &BakeParams) -> PathBuf {
    let mut h = Fnv::new();
    h.bytes(bytemuck::bytes_of(&GpuLight::new(light)));
    for v in [p.added_samples, p.cache_samples, p.bounces] {
        h.bytes(&v.to_le_bytes());
    }
    cache.join(format!("light-{:016x}", h.0))
}
pub fn eadd_file(cache: &Path, view: &str, light: &Light, p: &BakeParams) -> PathBuf {
    light_dir(cache, light, p).join(format!("{view}.eadd.exr"))
}
pub fn cache_file(cache: &Path, light: &Light, p: &BakeParams) -> PathBuf {
    light_dir(cache, light, p).join("surface_cache.bin")
}
pub fn albedo_file(cache: &Path) -> PathBuf {
    cache.join("albedo_mesh.bin")
}

/// Per-vertex albedo (rgb, weight), tagged "RALB".
fn write_albedo(path: &Path, a: &[[f32; 4]]) -> Result<()> {
    super::storage::write_vec4s(path, b"RALB", a)
}

pub fn read_albedo(path: &Path, expected: usize) -> Result<Vec<[f32; 4]>> {
    super::storage::read_vec4s(path, b"RALB", expected, "albedo-mesh cache", "vertices")
}

/// Bakes `scene` (or the slice `p.views`) into its cache.
pub fn bake(
    gpu: &Arc<Gpu>,
    scene: &Scene,
    p: &BakeParams,
    progress: &mut dyn Progress,
) -> Result<BakeReport> {
    let cache = cache_dir(scene, p)?;
    std::fs::create_dir_all(&cache).map_err(|e| Error::io(&cache, e))?;
    write_params(&cache, p)?;
    // Temp files of an interrupted run are never read; remove them.
    for path in entry_files(&cache) {
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        if name.ends_with(".tmp") || name.contains(".tmp.") {
            let _ = std::fs::remove_file(&path);
        }
    }
    let nv = scene.views.len();
    let slice = p.views.clone().unwrap_or(0..nv);
    if slice.start >= slice.end || slice.end > nv {
        return Err(Error::Other(format!(
            "--views {}..{}: the scene has views 0..{nv}",
            slice.start, slice.end
        )));
    }
    let mut report = BakeReport {
        cache: cache.clone(),
        ..Default::default()
    };
    let Setup {
        geom,
        mesh,
        data,
        views,
    } = Setup::new(gpu, scene, p)?;
    let (w, h) = (data.width, data.height);
    let npix = (w * h) as u64;
    // One vec4 per pixel of a view, on the device.
    let map_buffer = |name: &str| {
        Buffer::new(
            gpu,
            name,
            npix * 16,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::GpuOnly,
        )
    };
    let out = map_buffer("bake out")?;
    let read_out = |out: &Buffer| -> Result<Vec<[f32; 4]>> {
        let mut v: Vec<[f32; 4]> = out.download_vec()?;
        v.truncate(npix as usize);
        Ok(v)
    };

    // Stage 1: source irradiance, denoised.
    let si = SourceIrradiance::new(gpu, &scene.lights)?;
    let dn = Denoise::new(gpu)?;
    let noisy = map_buffer("noisy map")?;
    let todo: Vec<usize> = slice
        .clone()
        .filter(|&i| !esrc_file(&cache, &scene.views[i].name).exists())
        .collect();
    // Declared original lights add one shadow ray per sample.
    let per_sample = 1 + scene.lights.iter().any(|l| l.original) as u64;
    let radiance = if todo.is_empty() {
        None
    } else {
        let t0 = Instant::now();
        let r = super::radiance_mesh::build(
            gpu,
            &si,
            &scene.lights,
            &geom,
            &mesh,
            &views,
            p.irradiance_samples,
            p.seed,
        )?;
        let nv = geom.positions.len();
        let rays = nv as u64 * p.irradiance_samples as u64 * per_sample;
        report
            .stages
            .push(("radiance mesh".into(), t0.elapsed().as_secs_f64(), rays, nv));
        progress.update("radiance mesh", 1, 1, rays);
        Some(r)
    };
    let source_cache = match radiance.as_ref() {
        Some(r) if uses_source_cache(scene, p) => Some(source_cache(
            gpu,
            &si,
            &mesh,
            r,
            &views,
            &geom,
            &cache,
            p,
            progress,
            &mut report,
        )?),
        _ => None,
    };
    let sc = SourceCache::new(gpu)?;
    let (t0, mut rays) = (Instant::now(), 0u64);
    for (k, &i) in todo.iter().enumerate() {
        let Some(radiance) = radiance.as_ref() else {
            break;
        };
        let mut res = Ok(());
        let (v, n) = (i as u32, p.irradiance_samples);
        let estimate = |cmd, out: &Buffer| match &source_cache {
            Some((layout, values)) => sc.record(
                cmd,
                &si,
                &mesh,
                radiance,
                &views,
                (layout, values),
                v,
                n,
                p.seed,
                out,
            ),
            None => si.record(cmd, &mesh, radiance, &views, v, n, p.seed, out),
        };
        gpu.submit(|cmd| {
            res = if p.denoise.radius > 0 {
                estimate(cmd, &noisy).and_then(|_| {
                    crate::gpu::full_barrier(gpu, cmd);
                    dn.record(cmd, &views, v, p.denoise, &noisy, None, &out)
                })
            } else {
                estimate(cmd, &out)
            }
        })?;
        res?;
        let e = read_out(&out)?;
        write_exr(
            &esrc_file(&cache, &scene.views[i].name),
            &to_image(w, h, &e),
        )?;
        // With the source cache, a pixel traces only its shadow rays.
        rays += npix
            * p.irradiance_samples as u64
            * if source_cache.is_some() {
                1
            } else {
                per_sample
            };
        progress.update("source irradiance", k + 1, todo.len(), rays);
    }
    report.stages.push((
        "source irradiance".into(),
        t0.elapsed().as_secs_f64(),
        rays,
        todo.len(),
    ));

    // Stage 2: albedo mesh, once every view has E_src.
    let have_all = scene
        .views
        .iter()
        .all(|v| esrc_file(&cache, &v.name).exists());
    let nverts = geom.positions.len();
    if !have_all {
        if p.compress {
            compress_missing(&cache)?;
        }
        return Ok(report);
    }
    let albedo = if albedo_file(&cache).exists() {
        read_albedo(&albedo_file(&cache), nverts)?
    } else {
        let t0 = Instant::now();
        let mut e_all = Vec::with_capacity(nv * npix as usize);
        for v in &scene.views {
            let img = load_rgb(&esrc_file(&cache, &v.name))?;
            // Rays-used counts are not cached: a stored zero means no estimate.
            e_all.extend(img.pixels.iter().map(|p| {
                [
                    p[0],
                    p[1],
                    p[2],
                    if p.iter().any(|c| *c > 0.0) { 1.0 } else { 0.0 },
                ]
            }));
        }
        let eb = Buffer::from_slice(
            gpu,
            "e_src all",
            vk::BufferUsageFlags::STORAGE_BUFFER,
            &e_all,
        )?;
        let mut a = AlbedoMesh::new(gpu, &scene.lights)?.run(&mesh, nverts as u32, &views, &eb)?;
        // Vertices on a declared light have no samples: they take their neighbours' albedo.
        super::albedo_mesh::fill_unseen(&geom.triangles, &mut a);
        write_albedo(&albedo_file(&cache), &a)?;
        report
            .stages
            .push(("albedo mesh".into(), t0.elapsed().as_secs_f64(), 0, nverts));
        progress.update("albedo mesh", 1, 1, 0);
        a
    };
    report.albedo_mesh = true;
    let albedo_buf =
        Buffer::from_slice(gpu, "albedo", vk::BufferUsageFlags::STORAGE_BUFFER, &albedo)?;

    // Stage 3: source mirror images.
    let mirror = Mirror::new(gpu)?;
    let (t0, mut done) = (Instant::now(), 0);
    for (k, i) in slice.clone().enumerate() {
        let name = &scene.views[i].name;
        if !msrc_file(&cache, name).exists() {
            let mut res = Ok(());
            gpu.submit(|cmd| res = mirror.record(cmd, &mesh, &views, i as u32, &out))?;
            res?;
            write_exr(&msrc_file(&cache, name), &to_image(w, h, &read_out(&out)?))?;
            done += 1;
        }
        progress.update("mirror", k + 1, slice.len(), npix * (k as u64 + 1));
    }
    report.stages.push((
        "mirror".into(),
        t0.elapsed().as_secs_f64(),
        npix * done as u64,
        done,
    ));

    // Stage 4: per added light, its surface cache, then its E_add map per view.
    let lights: Vec<&Light> = scene.lights.iter().filter(|l| p.wants(l)).collect();
    added_stage(
        gpu,
        &mesh,
        &geom,
        &views,
        &albedo_buf,
        &cache,
        &lights,
        scene,
        p,
        progress,
        &mut report,
    )?;
    report.complete_views = slice.len();
    if p.compress {
        compress_missing(&cache)?;
    }
    Ok(report)
}

/// Whether E_src's indirect part comes from the source cache: when asked for and the scene
/// declares original lights (without them their light reaches E_src through the views' pixels,
/// whose shadows texels would blur).
pub fn uses_source_cache(scene: &Scene, p: &BakeParams) -> bool {
    p.source_cache_samples > 0 && scene.lights.iter().any(|l| l.original)
}

pub fn source_cache_file(cache: &Path) -> PathBuf {
    cache.join("source_cache.bin")
}

/// The source cache of this bake on the device: read from the cache directory, or traced,
/// filtered and written there (a resumed bake, or another slice's job, reuses it).
#[allow(clippy::too_many_arguments)]
fn source_cache(
    gpu: &Arc<Gpu>,
    si: &SourceIrradiance,
    mesh: &RayScene,
    radiance: &Buffer,
    views: &GpuViews,
    geom: &crate::scene::Mesh,
    cache: &Path,
    p: &BakeParams,
    progress: &mut dyn Progress,
    report: &mut BakeReport,
) -> Result<(GpuCacheLayout, Buffer)> {
    let layout = CacheLayout::new(geom);
    let file = source_cache_file(cache);
    let values = if file.exists() {
        super::surface_cache::read(&file, layout.texels())?
    } else {
        let t0 = Instant::now();
        let rounds = if p.denoise.radius > 0 {
            CACHE_FILTER_ROUNDS
        } else {
            0
        };
        let n = p.source_cache_samples;
        let v = super::source_cache::trace(
            gpu,
            si,
            mesh,
            radiance,
            views,
            &layout,
            (n, p.seed, rounds),
            &mut |d, total| progress.update("source cache", d as usize, total as usize, 0),
        )?;
        super::surface_cache::write(&file, &v)?;
        let rays = layout.texels() as u64 * n as u64;
        report.stages.push((
            "source cache".into(),
            t0.elapsed().as_secs_f64(),
            rays,
            layout.texels(),
        ));
        v
    };
    let one = [[0.0f32; 4]];
    let values = if values.is_empty() {
        &one[..]
    } else {
        &values[..]
    };
    let vb = Buffer::from_slice(
        gpu,
        "source cache",
        vk::BufferUsageFlags::STORAGE_BUFFER,
        values,
    )?;
    Ok((GpuCacheLayout::upload(gpu, &layout)?, vb))
}

/// Rounds of the surface cache's filter along the mesh (off with the denoiser).
const CACHE_FILTER_ROUNDS: u32 = 2;

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
    let rounds = if p.denoise.radius > 0 {
        CACHE_FILTER_ROUNDS
    } else {
        0
    };
    Ok(layout.filter(&raw, rounds))
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
    let cache = cache_dir(scene, p)?;
    let geom = bake_mesh(scene, p);
    let layout = CacheLayout::new(&geom);
    let missing = lights
        .iter()
        .filter(|l| !cache_file(&cache, l, p).exists())
        .count();
    if missing > 0 {
        let mesh = RayScene::new(gpu, &geom.positions, &geom.triangles)?;
        let albedo = read_albedo(&albedo_file(&cache), geom.positions.len())?;
        let ab = Buffer::from_slice(gpu, "albedo", vk::BufferUsageFlags::STORAGE_BUFFER, &albedo)?;
        let glayout = GpuCacheLayout::upload(gpu, &layout)?;
        let sc = SurfaceCache::new(gpu)?;
        let mut k = 0;
        for l in lights {
            let cf = cache_file(&cache, l, p);
            if cf.exists() {
                continue;
            }
            k += 1;
            let stage = format!("surface cache {k}/{missing}");
            let v = trace_cache(
                &sc,
                &mesh,
                &glayout,
                &layout,
                &ab,
                &GpuLight::new(l),
                p,
                &mut |d, n| progress.update(&stage, d as usize, n as usize, 0),
            )?;
            let dir = light_dir(&cache, l, p);
            std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
            super::surface_cache::write(&cf, &v)?;
        }
    }
    lights
        .iter()
        .map(|l| super::surface_cache::read(&cache_file(&cache, l, p), layout.texels()))
        .collect()
}

/// Bakes the lights' entries that are missing: the surface cache (traced once per light, kept
/// as `light-<key>/surface_cache.bin`) and the E_add map of every view in the slice.
#[allow(clippy::too_many_arguments)]
fn added_stage(
    gpu: &Arc<Gpu>,
    mesh: &RayScene,
    geom: &crate::scene::Mesh,
    views: &GpuViews,
    albedo: &Buffer,
    cache: &Path,
    lights: &[&Light],
    scene: &Scene,
    p: &BakeParams,
    progress: &mut dyn Progress,
    report: &mut BakeReport,
) -> Result<()> {
    let slice = p.views.clone().unwrap_or(0..scene.views.len());
    let ap = p.added();
    let layout = CacheLayout::new(geom);
    let glayout = GpuCacheLayout::upload(gpu, &layout)?;
    let (sc, added) = (SurfaceCache::new(gpu)?, AddedIrradiance::new(gpu)?);
    let (mut cache_s, mut cache_rays, mut caches) = (0.0, 0u64, 0);
    let (mut added_s, mut added_rays, mut maps) = (0.0, 0u64, 0);
    let npix = (views.width * views.height) as u64;
    for (li, l) in lights.iter().enumerate() {
        let todo: Vec<usize> = slice
            .clone()
            .filter(|&i| !eadd_file(cache, &scene.views[i].name, l, p).exists())
            .collect();
        if todo.is_empty() {
            continue;
        }
        let gl = GpuLight::new(l);
        let dir = light_dir(cache, l, p);
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        let cf = cache_file(cache, l, p);
        let values = if cf.exists() {
            super::surface_cache::read(&cf, layout.texels())?
        } else {
            let t = Instant::now();
            let stage = format!("surface cache {}/{}", li + 1, lights.len());
            let v = trace_cache(&sc, mesh, &glayout, &layout, albedo, &gl, p, &mut |d, n| {
                progress.update(&stage, d as usize, n as usize, 0)
            })?;
            super::surface_cache::write(&cf, &v)?;
            cache_s += t.elapsed().as_secs_f64();
            cache_rays += super::surface_cache::max_rays(layout.texels(), ap);
            caches += 1;
            v
        };
        let cb = Buffer::from_slice(
            gpu,
            "surface cache",
            vk::BufferUsageFlags::STORAGE_BUFFER,
            &values,
        )?;
        let t = Instant::now();
        for (k, &i) in todo.iter().enumerate() {
            let m = added.run(mesh, views, &glayout, &cb, i as u32, &gl, ap)?;
            write_exr(
                &eadd_file(cache, &scene.views[i].name, l, p),
                &to_image(views.width, views.height, &m),
            )?;
            maps += 1;
            added_rays += npix * ap.samples as u64;
            progress.update(
                &format!("added irradiance {}/{}", li + 1, lights.len()),
                k + 1,
                todo.len(),
                added_rays,
            );
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

/// The files of a bake cache: its own and those of its lights' entries (`light-*/`).
fn entry_files(cache: &Path) -> Vec<PathBuf> {
    let list = |d: &Path| -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(d)
            .map(|rd| rd.flatten().map(|e| e.path()).collect())
            .unwrap_or_default();
        v.sort();
        v
    };
    let mut out = Vec::new();
    for p in list(cache) {
        if p.is_dir() {
            out.extend(list(&p).into_iter().filter(|f| f.is_file()));
        } else {
            out.push(p);
        }
    }
    out
}

/// BC6H copy of a cached map: `v000.esrc.exr` → `v000.esrc.bc6h`.
pub fn bc6h_file(exr: &Path) -> PathBuf {
    exr.with_extension("bc6h")
}

/// Encodes every cached EXR map that has no BC6H copy yet (the EXR is the finished entry; its
/// BC6H copy is derived, so a kill between the two only costs a re-encode).
fn compress_missing(cache: &Path) -> Result<()> {
    for path in entry_files(cache) {
        if path.extension().is_none_or(|x| x != "exr") || bc6h_file(&path).exists() {
            continue;
        }
        let img = load_rgb(&path)?;
        let px: Vec<[f32; 4]> = from_image(&img);
        let blocks = super::storage::encode_bc6h(
            img.width,
            img.height,
            &px,
            super::storage::Bc6hQuality::Basic,
        );
        super::storage::write_bc6h(&bc6h_file(&path), img.width, img.height, &blocks)?;
    }
    Ok(())
}

/// The cached maps of one view, for the frame passes and the tests.
pub fn load_view_map(path: &Path) -> Result<Vec<[f32; 4]>> {
    Ok(from_image(&load_rgb(path)?))
}
