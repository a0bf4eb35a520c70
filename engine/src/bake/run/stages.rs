//! `bake` and stages 1–3 (E_src, the albedo mesh, M_src) as methods over what one bake shares.

use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;

use super::lights::{added_stage, wanted_lights};
use super::{filter_rounds, uses_source_cache, BakeParams, BakeReport, Progress, Setup};
use crate::bake::{
    AlbedoMesh, BakeCache, CacheLayout, Denoise, GpuCacheLayout, Mirror, SourceCache,
    SourceIrradiance,
};
use crate::error::{Error, Result};
use crate::gpu::{vk, Buffer, Gpu, Graph, MemoryLocation};
use crate::scene::image::load_rgb;
use crate::scene::Scene;

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
        let r = crate::bake::radiance_mesh::build(
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
            let v = crate::bake::source_cache::trace(
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
            crate::bake::albedo_mesh::fill_unseen(&s.geom.triangles, &mut a);
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
