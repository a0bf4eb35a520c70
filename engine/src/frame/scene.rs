//! The baked scene on the device as the frame reads it ([`FrameScene`]), and the loading of the
//! bake cache's maps into it.

use std::path::Path;
use std::sync::Arc;

use super::{emitters, HostMaps, LightingMap, MapFormat, ViewMaps};
use crate::bake::{run as bakerun, BakeCache, BakeParams, GpuLight, GpuViews, ViewData};
use crate::error::{Error, Result};
use crate::gpu::{vk, Buffer, Gpu, RayScene, Sampler};
use crate::scene::{Camera, Light, Scene};

/// Everything the frame reads from a baked scene, on the device.
pub struct FrameScene {
    pub mesh: RayScene,
    /// The bake mesh on the host, and its albedo when the scene comes from a bake (live lights
    /// trace it).
    pub geom: crate::scene::Mesh,
    pub albedo: Option<Vec<[f32; 4]>>,
    pub data: ViewData,
    pub views: GpuViews,
    pub maps: ViewMaps,
    /// The added lights' names, in E_add layer order, and their shapes (drawn where seen).
    pub lights: Vec<String>,
    /// Added lights without baked maps (zero layers): a lighting may not light them unless
    /// they are live.
    pub unbaked: Vec<String>,
    pub emitters: Vec<GpuLight>,
    pub(crate) emitter_buf: Buffer,
    /// The declared original lights (drawn where seen, dimmed by α_dim and their factors).
    pub originals: Vec<emitters::GpuOriginal>,
    pub(crate) original_buf: Buffer,
    /// The original lights with E_add layers of their own (0 or all of them: E_src split among
    /// them, frame/lighting.rs), from E_add layer `split_layer` on (light-major).
    pub split: u32,
    pub split_layer: u32,
    pub sampler: Sampler,
}

/// `items` in a storage buffer (one zeroed item when there is none: Vulkan has no empty
/// buffers, and the shaders read none then).
fn light_buffer<T: bytemuck::Pod>(gpu: &Arc<Gpu>, name: &str, items: &[T]) -> Result<Buffer> {
    let zero = [T::zeroed()];
    let data = if items.is_empty() { &zero[..] } else { items };
    Buffer::from_slice(gpu, name, vk::BufferUsageFlags::STORAGE_BUFFER, data)
}

/// The declared original lights of `lights`, each with its surface's albedo from the albedo
/// mesh when there is one ([`emitters::GpuOriginal::new`]).
fn original_lights(
    lights: &[Light],
    albedo: Option<(&crate::scene::Mesh, &[[f32; 4]])>,
) -> Vec<emitters::GpuOriginal> {
    let declared = lights.iter().filter(|l| l.original);
    declared
        .map(|l| emitters::GpuOriginal::new(l, albedo))
        .collect()
}

impl FrameScene {
    /// From host data (tests, tools): `mesh` is the proxy the maps were baked on; `lights` the
    /// added lights (in E_add layer order) and the declared original ones. The views' per-pixel
    /// host copies stay (the CPU references read them).
    pub fn from_parts(
        gpu: &Arc<Gpu>,
        mesh: &crate::scene::Mesh,
        cameras: &[Camera],
        host: &HostMaps,
        lights: &[Light],
        format: MapFormat,
    ) -> Result<FrameScene> {
        let maps = |h: HostMaps| ViewMaps::upload(gpu, &h, format);
        FrameScene::build(gpu, mesh, cameras, host.clone(), lights, true, maps)
    }

    /// The views from `host`'s images first, then `maps(host)`: so that a loader can read the
    /// lighting maps only once the views are on the device. Without `keep_pixels` the views go
    /// to the device one at a time and no host copy of them is kept.
    fn build(
        gpu: &Arc<Gpu>,
        mesh: &crate::scene::Mesh,
        cameras: &[Camera],
        host: HostMaps,
        lights: &[Light],
        keep_pixels: bool,
        maps: impl FnOnce(HostMaps) -> Result<ViewMaps>,
    ) -> Result<FrameScene> {
        let rs = RayScene::new(gpu, &mesh.positions, &mesh.triangles)?;
        let rgba = |j: usize| host.img[j].iter().map(|p| [p[0], p[1], p[2], 1.0]);
        let (data, views) = if keep_pixels {
            let data = ViewData::build_with(gpu, &rs, cameras, |j, img| img.extend(rgba(j)))?;
            let views = GpuViews::upload(gpu, &data)?;
            (data, views)
        } else {
            GpuViews::build_streamed(gpu, &rs, cameras, |j| Ok(rgba(j).collect()))?
        };
        let (split, nviews) = (host.split as u32, cameras.len() as u32);
        let maps = maps(host)?;
        let added: Vec<&Light> = lights.iter().filter(|l| !l.original).collect();
        let emitters: Vec<GpuLight> = added.iter().map(|l| GpuLight::new(l)).collect();
        let originals = original_lights(lights, None);
        Ok(FrameScene {
            mesh: rs,
            geom: mesh.clone(),
            albedo: None,
            data,
            views,
            maps,
            lights: added.iter().map(|l| l.name.clone()).collect(),
            unbaked: Vec::new(),
            emitter_buf: light_buffer(gpu, "frame emitters", &emitters)?,
            emitters,
            original_buf: light_buffer(gpu, "frame original lights", &originals)?,
            originals,
            split,
            split_layer: added.len() as u32 * nviews,
            sampler: Sampler::linear(gpu)?,
        })
    }

    /// A baked scene: the maps of the bake cache for `params` (which must be complete).
    pub fn load(
        gpu: &Arc<Gpu>,
        scene: &Scene,
        params: &BakeParams,
        format: MapFormat,
    ) -> Result<FrameScene> {
        let mesh = bakerun::bake_mesh(scene, params);
        let cams: Vec<Camera> = scene.views.iter().map(|v| v.camera.clone()).collect();
        // The images, the views from them, and only then the lighting maps, each type freed
        // once on the device: at the paper's scale (300 views at 512×384) these are GBs.
        let mut host = HostMaps::default();
        load_view_images(scene, &mut host)?;
        let mut unbaked = Vec::new();
        let mut load = |kind, m: &mut HostMaps| {
            load_lighting_map(scene, params, kind, m)?;
            unbaked.clone_from(&m.unbaked);
            Ok(())
        };
        let maps = |h: HostMaps| ViewMaps::upload_cached(gpu, scene, params, h, &mut load, format);
        let mut fs = FrameScene::build(gpu, &mesh, &cams, host, &scene.lights, false, maps)?;
        fs.unbaked = unbaked;
        let cache = BakeCache::of(scene, params)?;
        let layers = layer_lights(scene, &cache, params);
        fs.split = layers.iter().filter(|l| l.original).count() as u32;
        let albedo = cache.read_albedo(mesh.positions.len())?;
        fs.originals = original_lights(&scene.lights, Some((&mesh, &albedo)));
        fs.original_buf = light_buffer(gpu, "frame original lights", &fs.originals)?;
        fs.albedo = Some(albedo);
        Ok(fs)
    }

    /// Sets added light `layer`'s shape (a new light when `layer` is the count): it is drawn
    /// there from the next frame on.
    pub fn set_emitter(&mut self, layer: usize, light: &Light) -> Result<()> {
        match layer.cmp(&self.emitters.len()) {
            std::cmp::Ordering::Less => self.emitters[layer] = GpuLight::new(light),
            std::cmp::Ordering::Equal => {
                self.emitters.push(GpuLight::new(light));
                self.lights.push(light.name.clone());
            }
            std::cmp::Ordering::Greater => {
                return Err(Error::Other(format!(
                    "added light {layer}: the scene has {}",
                    self.emitters.len()
                )))
            }
        }
        self.emitter_buf =
            light_buffer(&self.mesh.positions.gpu, "frame emitters", &self.emitters)?;
        Ok(())
    }
}

/// The lights with E_add layers in a frame of `scene`, in layer order: every added light (zero
/// layers where it has no entry yet), then the declared original lights when E_src is split
/// among them and each of them has its entry (else none: per-light factors are refused until
/// they are baked).
pub(crate) fn layer_lights<'a>(
    scene: &'a Scene,
    cache: &BakeCache,
    params: &BakeParams,
) -> Vec<&'a Light> {
    let baked = |l: &Light| {
        !l.original || (scene.views.iter()).all(|v| cache.eadd(&v.name, l, params).exists())
    };
    let all = bakerun::entry_lights(scene);
    let originals = all.clone().filter(|l| l.original).all(baked);
    all.filter(|l| !l.original || originals).collect()
}

/// Reads a scene's images and its complete bake cache into host maps.
pub fn load_host_maps(scene: &Scene, params: &BakeParams) -> Result<HostMaps> {
    let mut m = HostMaps::default();
    load_view_images(scene, &mut m)?;
    for kind in [LightingMap::Msrc, LightingMap::Esrc, LightingMap::Eadd] {
        load_lighting_map(scene, params, kind, &mut m)?;
    }
    Ok(m)
}

/// The views' photos into `m.img` (RGBA, w = 1), and the maps' size.
fn load_view_images(scene: &Scene, m: &mut HostMaps) -> Result<()> {
    for img in scene.view_images()? {
        m.width = img.width;
        m.height = img.height;
        m.img
            .push(img.pixels.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect());
    }
    Ok(())
}

/// One type of the bake's maps (M_src, E_src, or every added light's E_add) from the bake
/// cache into `m` (size from `load_view_images`); added lights without baked maps get zero
/// layers and are listed in `m.unbaked`.
fn load_lighting_map(
    scene: &Scene,
    params: &BakeParams,
    kind: LightingMap,
    m: &mut HostMaps,
) -> Result<()> {
    let cache = BakeCache::of(scene, params)?;
    let load = |path: &Path| -> Result<Vec<[f32; 4]>> {
        if !path.exists() {
            return Err(Error::input(
                path,
                format!(
                    "missing from the bake cache: run `relit bake {}` with the same quality first",
                    scene.root.display()
                ),
            ));
        }
        BakeCache::load_map(path)
    };
    let views = || scene.views.iter();
    match kind {
        LightingMap::Msrc => {
            m.msrc = views()
                .map(|v| load(&cache.msrc(&v.name)))
                .collect::<Result<_>>()?
        }
        LightingMap::Esrc => {
            m.esrc = views()
                .map(|v| load(&cache.esrc(&v.name)))
                .collect::<Result<_>>()?
        }
        LightingMap::Eadd => {
            let npix = (m.width * m.height) as usize;
            for l in layer_lights(scene, &cache, params) {
                let files: Vec<_> = views().map(|v| cache.eadd(&v.name, l, params)).collect();
                m.split += l.original as usize;
                // A light no map was baked for has not been used yet: zero layers, refused if lit.
                if !l.original && files.iter().all(|f| !f.exists()) {
                    m.unbaked.push(l.name.clone());
                    m.eadd.extend(files.iter().map(|_| vec![[0.0; 4]; npix]));
                    continue;
                }
                for f in &files {
                    m.eadd.push(load(f)?);
                }
            }
        }
    }
    Ok(())
}
