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
    AddedIrradiance, AddedParams, AlbedoMesh, Denoise, DenoiseParams, GpuLight, GpuViews, Mirror,
    SourceIrradiance, ViewData,
};
use crate::error::{Error, Result};
use crate::gpu::{vk, Buffer, Gpu, MemoryLocation, RayScene};
use crate::scene::image::{load_rgb, write_exr, RgbImage};
use crate::scene::{write_atomic, Scene};

/// Bump when a pass changes what it computes: old caches are then not reused.
pub const BAKE_VERSION: u32 = 4;

#[derive(Clone, Debug)]
pub struct BakeParams {
    /// Rays per pixel for E_src (§4.1.1: 128).
    pub irradiance_samples: u32,
    /// Paths per pixel and the most bounces for E_add. Indoors, walls of albedo ~0.6 pass on
    /// most of the light: a direct + 1-bounce estimate reaches about 60% of the true irradiance
    /// (measured on the demo room), and 3 bounces left E_add 0.85–0.88× the truth on plain
    /// walls. The presets allow 6, the depth of the ground truth's path tracer; Russian
    /// roulette past 2 bounces keeps the mean path short.
    pub added_samples: u32,
    pub bounces: u32,
    pub seed: u32,
    /// Slice of views to bake (all by default).
    pub views: Option<Range<usize>>,
    /// The E_src denoiser (radius 0: off).
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
    m
}

impl BakeParams {
    pub fn final_quality() -> BakeParams {
        BakeParams {
            irradiance_samples: 128,
            added_samples: 32,
            bounces: 6,
            seed: 1,
            views: None,
            denoise: DenoiseParams::default(),
            mesh_process: false,
            compress: true,
        }
    }
    pub fn preview() -> BakeParams {
        BakeParams {
            irradiance_samples: 32,
            added_samples: 8,
            bounces: 6,
            seed: 1,
            views: None,
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
    for v in [p.irradiance_samples, p.added_samples, p.bounces, p.seed] {
        h.bytes(&v.to_le_bytes());
    }
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
    for l in &scene.lights {
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
        "irradiance_samples": p.irradiance_samples, "added_samples": p.added_samples,
        "bounces": p.bounces, "seed": p.seed, "mesh_process": p.mesh_process,
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
        added_samples: u("added_samples")?,
        bounces: u("bounces")?,
        seed: u("seed")?,
        views: None,
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
pub fn is_complete(scene: &Scene, p: &BakeParams) -> Result<bool> {
    let dir = cache_dir(scene, p)?;
    let added: Vec<&str> = scene
        .lights
        .iter()
        .filter(|l| !l.original)
        .map(|l| l.name.as_str())
        .collect();
    Ok(scene.views.iter().all(|v| {
        esrc_file(&dir, &v.name).exists()
            && msrc_file(&dir, &v.name).exists()
            && added.iter().all(|l| eadd_file(&dir, &v.name, l).exists())
    }))
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
pub fn eadd_file(cache: &Path, view: &str, light: &str) -> PathBuf {
    cache.join(format!("{view}.eadd.{light}.exr"))
}
pub fn albedo_file(cache: &Path) -> PathBuf {
    cache.join("albedo_mesh.bin")
}

/// Per-vertex albedo (rgb, weight) as little-endian f32 after a "RALB" + count header.
fn write_albedo(path: &Path, a: &[[f32; 4]]) -> Result<()> {
    let mut out = b"RALB".to_vec();
    out.extend_from_slice(&(a.len() as u32).to_le_bytes());
    out.extend_from_slice(bytemuck::cast_slice(a));
    write_atomic(path, &out)
}

pub fn read_albedo(path: &Path, expected: usize) -> Result<Vec<[f32; 4]>> {
    let b = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if b.len() < 8 || &b[..4] != b"RALB" {
        return Err(Error::input(path, "not an albedo-mesh cache file"));
    }
    let n = u32::from_le_bytes(b[4..8].try_into().unwrap()) as usize;
    if n != expected || b.len() != 8 + 16 * n {
        return Err(Error::input(
            path,
            format!("holds {n} vertices; the mesh has {expected}"),
        ));
    }
    Ok(bytemuck::pod_collect_to_vec(&b[8..]))
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
    if let Ok(rd) = std::fs::read_dir(&cache) {
        for e in rd.flatten() {
            if e.file_name().to_string_lossy().ends_with(".tmp")
                || e.file_name().to_string_lossy().contains(".tmp.")
            {
                let _ = std::fs::remove_file(e.path());
            }
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
    let (t0, mut rays) = (Instant::now(), 0u64);
    for (k, &i) in todo.iter().enumerate() {
        let mut res = Ok(());
        let (v, n) = (i as u32, p.irradiance_samples);
        gpu.submit(|cmd| {
            res = if p.denoise.radius > 0 {
                si.record(cmd, &mesh, &views, v, n, p.seed, &noisy)
                    .and_then(|_| {
                        crate::gpu::full_barrier(gpu, cmd);
                        dn.record(cmd, &views, v, p.denoise, &noisy, None, &out)
                    })
            } else {
                si.record(cmd, &mesh, &views, v, n, p.seed, &out)
            }
        })?;
        res?;
        let e = read_out(&out)?;
        write_exr(
            &esrc_file(&cache, &scene.views[i].name),
            &to_image(w, h, &e),
        )?;
        // Declared original lights add one shadow ray per sample.
        let per_sample = 1 + scene.lights.iter().any(|l| l.original) as u64;
        rays += npix * p.irradiance_samples as u64 * per_sample;
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
    let nverts = scene.mesh.positions.len();
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
        let mut a = AlbedoMesh::new(gpu)?.run(&mesh, nverts as u32, &views, &eb)?;
        super::albedo_mesh::fill_unseen(&geom.triangles, &mut a);
        let lights = super::source_irradiance::original_lights(&scene.lights);
        super::albedo_mesh::darken_lights(&geom.positions, &lights, &mut a);
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

    // Stage 3: source mirror images and added irradiance per user light.
    let ind = map_buffer("e_add indirect")?;
    let mirror = Mirror::new(gpu)?;
    let added = AddedIrradiance::new(gpu)?;
    let user_lights: Vec<_> = scene.lights.iter().filter(|l| !l.original).collect();
    let ap = AddedParams {
        samples: p.added_samples,
        bounces: p.bounces,
        seed: p.seed,
    };
    let (mut mirror_s, mut added_s, mut added_rays, mut done, mut added_done) =
        (0.0, 0.0, 0u64, 0, 0);
    for (k, i) in slice.clone().enumerate() {
        let name = &scene.views[i].name;
        let t = Instant::now();
        if !msrc_file(&cache, name).exists() {
            let mut res = Ok(());
            gpu.submit(|cmd| res = mirror.record(cmd, &mesh, &views, i as u32, &out))?;
            res?;
            write_exr(&msrc_file(&cache, name), &to_image(w, h, &read_out(&out)?))?;
            done += 1;
        }
        mirror_s += t.elapsed().as_secs_f64();
        for l in &user_lights {
            let f = eadd_file(&cache, name, &l.name);
            if f.exists() {
                continue;
            }
            let t = Instant::now();
            let gl = GpuLight::new(l);
            let mut res = Ok(());
            // The indirect part is filtered like E_src; the direct part keeps its sharp shadows.
            let filter = p.denoise.radius > 0;
            let total = if filter { &noisy } else { &out };
            gpu.submit(|cmd| {
                res = added
                    .record(
                        cmd,
                        &mesh,
                        &views,
                        &albedo_buf,
                        i as u32,
                        &gl,
                        ap,
                        total,
                        &ind,
                    )
                    .and_then(|_| {
                        if !filter {
                            return Ok(());
                        }
                        crate::gpu::full_barrier(gpu, cmd);
                        dn.record(cmd, &views, i as u32, p.denoise, &ind, Some(&noisy), &out)
                    })
            })?;
            res?;
            write_exr(&f, &to_image(w, h, &read_out(&out)?))?;
            added_s += t.elapsed().as_secs_f64();
            added_done += 1;
            // Per path: (bounces + 1) shadow rays and `bounces` continuation rays at most;
            // Russian roulette ends most paths sooner, so this rate is an upper bound.
            added_rays += npix * p.added_samples as u64 * (2 * p.bounces as u64 + 1);
        }
        progress.update(
            "mirror + added irradiance",
            k + 1,
            slice.len(),
            added_rays + npix * (k as u64 + 1),
        );
    }
    report
        .stages
        .push(("mirror".into(), mirror_s, npix * done as u64, done));
    report
        .stages
        .push(("added irradiance".into(), added_s, added_rays, added_done));
    report.complete_views = slice.len();
    if p.compress {
        compress_missing(&cache)?;
    }
    Ok(report)
}

/// BC6H copy of a cached map: `v000.esrc.exr` → `v000.esrc.bc6h`.
pub fn bc6h_file(exr: &Path) -> PathBuf {
    exr.with_extension("bc6h")
}

/// Encodes every cached EXR map that has no BC6H copy yet (the EXR is the finished entry; its
/// BC6H copy is derived, so a kill between the two only costs a re-encode).
fn compress_missing(cache: &Path) -> Result<()> {
    let rd = std::fs::read_dir(cache).map_err(|e| Error::io(cache, e))?;
    for e in rd.flatten() {
        let path = e.path();
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
