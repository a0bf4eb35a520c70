//! Which lights have entries of their own, and stage 4: their surface caches and E_add maps.

use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;

use super::{bake_mesh, filter_rounds, BakeParams, BakeReport, Progress, Setup};
use crate::bake::{
    AddedIrradiance, BakeCache, CacheLayout, GpuCacheLayout, GpuLight, SurfaceCache,
};
use crate::error::Result;
use crate::gpu::{vk, Buffer, Gpu, RayScene};
use crate::scene::{Light, Scene};

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
pub(super) fn added_stage(
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
            cache_rays += crate::bake::surface_cache::max_rays(layout.texels(), ap);
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
