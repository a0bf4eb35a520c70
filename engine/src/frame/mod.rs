//! The novel-view frame (§4.2.2, §4.3, §4.4, §5): G-buffer of the proxy in the novel camera,
//! reprojected composites, irradiance composites, target mirror, the view-dependent layer (glossy
//! mode), the 66-channel features, the network (or the ULR composite) and the output transform. One Rust file and one shader per
//! pass, each with a CPU reference on small inputs (tests/frame.rs).

pub mod emitters;
pub mod features;
pub mod glossy;
pub mod irradiance;
pub mod lighting;
pub mod live;
pub mod maps;
pub mod output;
pub mod reproject;
pub mod target_mirror;
pub mod view_cull;

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;

pub use lighting::{added_lights, Lighting};
pub use maps::{HostMaps, LightingMap, MapFormat, ViewMaps};

use crate::bake::{run as bakerun, BakeCache, BakeParams, GpuLight, GpuViews, ViewData};
use crate::error::{Error, Result};
use crate::gpu::{
    bytes_of, vk, Bind, Buffer, Gpu, Graph, MemoryLocation, Pipeline, RayScene, Sampler, Timer,
};
use crate::net::{Network, Storage, Tensor, INPUT_CHANNELS};
use crate::raster::{Gbuffer, GbufferPass};
use crate::scene::{Camera, Light, Scene};

/// At most this many input views take part in one frame (`constants.table`; which ones:
/// [`view_cull`]).
pub const MAX_ACTIVE: usize = crate::constants::MAX_ACTIVE as usize;

/// What the CPU references read: the views, the host maps, the novel G-buffer and the frame's
/// parameters.
pub struct RefInputs<'a> {
    pub data: &'a ViewData,
    pub maps: &'a HostMaps,
    pub gpos: &'a [[f32; 4]],
    pub gnrm: &'a [[f32; 4]],
    pub width: u32,
    pub height: u32,
    pub eye: Vec3,
    pub active: &'a [u32],
    pub intensities: &'a [f32],
    pub alpha_dim: f32,
    /// The view left out of the frame (also by the target mirror).
    pub exclude: Option<u32>,
    /// The added lights' shapes (drawn where seen, in the mirror too).
    pub emitters: &'a [GpuLight],
    /// The declared original lights (drawn where seen, dimmed).
    pub originals: &'a [emitters::GpuOriginal],
    /// Their factors ([`Lighting::originals`]; 1 where missing). `maps.split` of them have E_add
    /// layers, the last ones of `maps.eadd`.
    pub keep: &'a [[f32; 3]],
    /// Live lights, when some are (frame/live.rs).
    pub live: Option<LiveRef<'a>>,
}

/// What the CPU references read of the live lights: the bake mesh, the novel view's triangle
/// ids (+1, 0: none), and per live light its parameters and filtered cache.
pub struct LiveRef<'a> {
    pub mesh: &'a crate::scene::Mesh,
    pub layout: &'a crate::bake::CacheLayout,
    pub gtri: &'a [u32],
    pub lights: &'a [live::GpuLive],
    pub caches: &'a [Vec<[f32; 4]>],
}

impl LiveRef<'_> {
    /// Whether added light l is live.
    pub fn is_live(&self, l: usize) -> bool {
        self.lights.iter().any(|x| x.layer as usize == l)
    }

    /// Σ intensity × E_add of the live lights at x (normal n) on triangle `tri`.
    pub fn eadd(&self, intensities: &[f32], x: Vec3, n: Vec3, tri: usize, key: u32) -> Vec3 {
        let mut e = Vec3::ZERO;
        for (i, l) in self.lights.iter().enumerate() {
            let s = intensities[l.layer as usize];
            if s != 0.0 {
                let c = &self.caches[i];
                e += s * live::reference_eadd(
                    self.mesh,
                    self.layout,
                    l,
                    c,
                    i as u32,
                    x,
                    n,
                    tri,
                    key,
                );
            }
        }
        e
    }
}

impl RefInputs<'_> {
    /// α_dim and the original lights' factors.
    pub fn dim(&self) -> (f32, &[[f32; 3]]) {
        (self.alpha_dim, self.keep)
    }

    /// Whether some original light has a factor of its own ([`Lighting::per_light`]).
    pub fn per_light(&self) -> bool {
        self.keep.iter().any(|c| *c != lighting::AS_CAPTURED)
    }

    /// CPU mirror of `removed_share` (originals.glsl) at view j's pixel px.
    pub fn removed_share(&self, j: usize, px: glam::Vec2) -> Vec3 {
        let (m, nviews) = (self.maps, self.data.cameras.len());
        let first = m.eadd.len() / nviews - m.split;
        let sims: Vec<Vec3> = (0..m.split)
            .map(|l| {
                maps::sample_bilinear(&m.eadd[(first + l) * nviews + j], m.width, m.height, px)
            })
            .collect();
        lighting::removed_share(&sims, self.keep, self.originals.len())
    }

    /// The surface point at pixel p and its normal facing the novel camera.
    pub fn surface(&self, p: usize) -> Option<(Vec3, Vec3)> {
        let g = self.gpos[p];
        if g[3] <= 0.0 {
            return None;
        }
        let x = Vec3::new(g[0], g[1], g[2]);
        let mut n = Vec3::from_slice(&self.gnrm[p][..3]);
        if n.dot(self.eye - x) < 0.0 {
            n = -n;
        }
        Some((x, n))
    }
}

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
    emitter_buf: Buffer,
    /// The declared original lights (drawn where seen, dimmed by α_dim and their factors).
    pub originals: Vec<emitters::GpuOriginal>,
    original_buf: Buffer,
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
        // The loaders read every original light's layers or fail (relit render bakes them first).
        if bakerun::splits_originals(scene) {
            fs.split = scene.lights.iter().filter(|l| l.original).count() as u32;
        }
        let cache = BakeCache::of(scene, params)?;
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
            for l in crate::bake::run::entry_lights(scene) {
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

/// The mode commands render in when the user names neither a mode nor weights: the one that
/// scores best on the validation rooms and holds on the held-out ones (`tools/train/evaluate.py`,
/// README "Evaluation"). Network: since 2026-12-06 the shipped network (ratio base, gated,
/// its diffuse correction a gain, scaled by the input views' disagreement) meets the floor, at
/// or above ratio on covered pixels in every validation and held-out room and lighting, and
/// above it by 0.4 dB on the held-out means. Before it, ratio-filled (ratio's image, the
/// network only in the holes) was the default, as it must be again whenever the shipped
/// network does not meet the floor.
pub const DEFAULT_MODE: Mode = Mode::Network;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// The network's output (needs weights).
    Network,
    /// The `I_1` composite alone: unstructured-lumigraph-style blending, the baseline.
    Ulr,
    /// `I_1 / E_src · (E_add + E_src − E_rem)`: the composite relit by eq. 5's pseudo-albedo
    /// rule, a diffuse relighting baseline without the network (no view-dependent effects).
    Ratio,
    /// Ratio where some input view sees the surface (`I_1` not black), the network's image in
    /// the holes no view sees, which ratio leaves black (needs weights).
    RatioFilled,
    /// §3's L = a·E + S without the network: the photos' diffuse part relit by eq. 5 plus the
    /// view-dependent layer fitted from the photos and their mirror images ([`glossy`]), so
    /// highlights move with the view and a lamp shows its own; ratio's image where no fit holds.
    Glossy,
}

impl Mode {
    /// Whether the frame runs the network in this mode.
    pub fn needs_network(self) -> bool {
        matches!(self, Mode::Network | Mode::RatioFilled)
    }

    /// Whether the frame runs the view-dependent layer ([`glossy`]) in this mode.
    pub fn needs_glossy(self) -> bool {
        matches!(self, Mode::Glossy)
    }
}

/// Per-resolution buffers of a frame.
pub struct FrameBuffers {
    pub width: u32,
    pub height: u32,
    pub gbuf: Gbuffer,
    pub comp: Buffer,
    pub irr: Buffer,
    pub mirror: Buffer,
    /// The view-dependent layer: (D, s), (S, lobe + 1) per pixel ([`glossy`]).
    pub glossy: Buffer,
    /// The layer's per-pixel sums over the views, which its pass pools ([`glossy`]).
    pub glossy_sums: Buffer,
    pub active: Buffer,
    /// The view culling's visibility bits and grid points (host-readable).
    pub cull_seen: Buffer,
    pub cull_points: Buffer,
    pub intensity: Buffer,
    /// The original lights' factors (`Keep`, [`Lighting::keep_buffer`]).
    pub keep: Buffer,
    pub input: Tensor,
    pub hdr: Buffer,
    pub ldr: Buffer,
    net: Option<crate::net::NetBuffers>,
    dummy_net_out: Tensor,
}

impl FrameBuffers {
    /// The 16 composite planes (I_1..8, M_src_1..8; stored as half floats) as f32.
    pub fn composites(&self) -> Result<Vec<[f32; 4]>> {
        let n = reproject::PLANES * (self.width * self.height) as usize;
        let h: Vec<half::f16> =
            bytemuck::pod_collect_to_vec(&self.comp.download_range(0, n as u64 * 8)?);
        Ok(h.chunks_exact(4)
            .map(|c| [c[0].to_f32(), c[1].to_f32(), c[2].to_f32(), c[3].to_f32()])
            .collect())
    }
}

/// The frame pipelines and, optionally, the network.
pub struct Renderer {
    pub gpu: Arc<Gpu>,
    pub scene: FrameScene,
    pub net: Option<Network>,
    pub storage: Storage,
    gbuffer: GbufferPass,
    reproject: Pipeline,
    irradiance: Pipeline,
    target_mirror: Pipeline,
    glossy_sums: Pipeline,
    glossy: Pipeline,
    features: Pipeline,
    output: Pipeline,
    view_cull: Pipeline,
    /// The active views of the last frame, ascending.
    active: Vec<u32>,
    /// When frames choose their active views ([`view_cull`]) and how many.
    pub culling: view_cull::Culling,
    /// Buffers per resolution, the last frame's first: the viewer alternates a reduced
    /// resolution while moving with the full one when still, so two stay allocated.
    bufs: Vec<FrameBuffers>,
    /// An input view left out of every pass (leave-one-out inputs for training on input
    /// views: `relit dump` of an input camera).
    pub exclude: Option<u32>,
    /// Lights being placed or moved (the viewer).
    pub live: live::LiveLights,
    /// Skip the passes that only feed the network (target mirror, features) in the modes that
    /// do not run it: ratio and ULR frames for the screen cost half as much. Off by default,
    /// since `relit dump` and the tests read those passes' buffers after a ULR frame.
    pub display_only: bool,
    /// Fill the holes no input view sees (ratio, glossy and ULR modes) from the nearest covered
    /// pixels (`output.glsl`'s `hole_fill`): the viewer's moving frame, which would show them
    /// black. Off by default: renders and evaluations score holes as the mode leaves them.
    pub fill_holes: bool,
}

/// The push constants of one frame's passes.
struct Pushes {
    reproject: reproject::Push,
    irradiance: irradiance::Push,
    target_mirror: target_mirror::Push,
    glossy: glossy::Push,
    features: features::Push,
    output: output::Push,
}

/// The novel view's G-buffer, as the frame's passes name it.
const GBUFFER: [&str; 3] = ["g_pos", "g_nrm", "g_tri"];

/// Near and far planes of the novel view's G-buffer (m): the input views'.
pub use crate::bake::views::{FAR, NEAR};

impl Renderer {
    pub fn new(
        gpu: &Arc<Gpu>,
        scene: FrameScene,
        net: Option<Network>,
        storage: Storage,
    ) -> Result<Renderer> {
        if let Some(n) = &net {
            if n.kernels.storage != storage {
                return Err(Error::Other(
                    "the network's storage type differs from the renderer's".into(),
                ));
            }
            if n.config.in_channels != INPUT_CHANNELS || n.config.out_channels != 6 {
                return Err(Error::Other(format!(
                    "the network takes {} channels and returns {}; the frame needs {} in, 6 out",
                    n.config.in_channels, n.config.out_channels, INPUT_CHANNELS
                )));
            }
        }
        let (feat, out) = match storage {
            Storage::F16 => (features::SHADER_F16, output::SHADER_F16),
            Storage::F32 => (features::SHADER_F32, output::SHADER_F32),
        };
        let live = live::LiveLights::new(gpu, &scene.geom, scene.albedo.as_deref())?;
        Ok(Renderer {
            live,
            gbuffer: GbufferPass::new(gpu)?,
            reproject: Pipeline::compute(gpu, reproject::SHADER)?,
            irradiance: Pipeline::compute(gpu, irradiance::SHADER)?,
            target_mirror: Pipeline::compute(gpu, target_mirror::SHADER)?,
            glossy_sums: Pipeline::compute(gpu, glossy::SUMS_SHADER)?,
            glossy: Pipeline::compute(gpu, glossy::SHADER)?,
            features: Pipeline::compute(gpu, feat)?,
            output: Pipeline::compute(gpu, out)?,
            view_cull: Pipeline::compute(gpu, view_cull::SHADER)?,
            active: Vec::new(),
            culling: view_cull::Culling::default(),
            gpu: gpu.clone(),
            scene,
            net,
            storage,
            bufs: Vec::new(),
            exclude: None,
            display_only: false,
            fill_holes: false,
        })
    }

    /// At most this many resolutions keep their buffers.
    const RESOLUTIONS: usize = 2;

    fn buffers(&mut self, width: u32, height: u32) -> Result<&FrameBuffers> {
        match (self.bufs.iter()).position(|b| (b.width, b.height) == (width, height)) {
            Some(i) => {
                let b = self.bufs.remove(i);
                self.bufs.insert(0, b);
            }
            None => {
                self.bufs.truncate(Self::RESOLUTIONS - 1);
                let b = self.new_buffers(width, height)?;
                self.bufs.insert(0, b);
            }
        }
        Ok(&self.bufs[0])
    }

    fn new_buffers(&self, width: u32, height: u32) -> Result<FrameBuffers> {
        let gpu = &self.gpu;
        let n = (width * height) as u64;
        let storage = |name: &str, size: u64, at: MemoryLocation| {
            let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
            Buffer::new(gpu, name, size.max(16), usage, at)
        };
        let buf = |name: &str, size: u64| storage(name, size, MemoryLocation::GpuOnly);
        // The view culling's bits are read back by the host.
        let readable = |name: &str, size: u64| storage(name, size, MemoryLocation::GpuToCpu);
        let grid = view_cull::grid(width, height);
        let nl = self.scene.lights.len().max(1) as u64;
        Ok(FrameBuffers {
            width,
            height,
            gbuf: Gbuffer::new(gpu, width, height)?,
            comp: buf("frame composites", reproject::PLANES as u64 * n * 8)?,
            irr: buf("frame irradiance", irradiance::PLANES as u64 * n * 16)?,
            mirror: buf("frame target mirror", n * 16)?,
            glossy: buf("frame glossy layer", glossy::PLANES as u64 * n * 16)?,
            glossy_sums: buf("frame glossy sums", glossy::SUM_PLANES as u64 * n * 16)?,
            active: buf("frame active views", MAX_ACTIVE as u64 * 4)?,
            cull_seen: readable(
                "view culling bits",
                (view_cull::words(grid) * self.scene.views.count as usize * 4) as u64,
            )?,
            cull_points: readable("view culling points", (grid.0 * grid.1 * 16) as u64)?,
            intensity: buf("frame intensities", nl * 4)?,
            keep: buf(
                "frame original factors",
                self.scene.originals.len().max(1) as u64 * 16,
            )?,
            input: Tensor::new(
                gpu,
                "frame input",
                INPUT_CHANNELS,
                height,
                width,
                self.storage,
            )?,
            hdr: buf("frame hdr", n * 16)?,
            ldr: buf("frame ldr", n * 4)?,
            net: match &self.net {
                Some(net) => Some(net.buffers(height, width)?),
                None => None,
            },
            dummy_net_out: Tensor::new(gpu, "no network", 6, 1, 1, self.storage)?,
        })
    }

    /// Places added light `layer` (a new one when `layer` is the count of added lights) at
    /// `light` and makes it live: drawn there and lit from the next frame, its surface cache
    /// refined by [`Renderer::refine_live`]. A new light needs one more intensity in the
    /// `Lighting` passed to `render`.
    pub fn set_live_light(&mut self, layer: usize, light: &Light) -> Result<()> {
        let before = self.scene.lights.len();
        self.live.set(layer, &GpuLight::new(light))?;
        self.scene.set_emitter(layer, light)?;
        if self.scene.lights.len() != before {
            // The intensity buffer holds one float per added light.
            self.bufs.clear();
        }
        Ok(())
    }

    /// As [`Renderer::set_live_light`] with a finished surface cache (no refinement).
    pub fn set_live_light_cached(
        &mut self,
        layer: usize,
        light: &Light,
        cache: Vec<[f32; 4]>,
    ) -> Result<()> {
        self.live
            .set_converged(layer, &GpuLight::new(light), cache)?;
        self.scene.set_emitter(layer, light)
    }

    /// Added light `layer` reads its baked maps again, drawn at `light` (its baked place).
    pub fn unset_live_light(&mut self, layer: usize, light: &Light) -> Result<()> {
        if self.live.is_live(layer) {
            self.live.unset(layer)?;
            self.scene.set_emitter(layer, light)?;
        }
        Ok(())
    }

    /// One refinement step of the live lights' caches; whether anything changed.
    pub fn refine_live(&mut self) -> Result<bool> {
        // The texels the last frame shows converge first: what the user looks at.
        let focus = match self.bufs.first() {
            Some(b) if self.live.count() > 0 => {
                let tri: Vec<u32> =
                    bytemuck::pod_collect_to_vec(&b.gbuf.tri.download(vk::ImageLayout::GENERAL)?);
                Some(self.live.texels_shown(&tri))
            }
            _ => None,
        };
        self.live.refine(&self.scene.mesh, focus.as_deref())
    }

    /// Renders `cam` under `lighting` and waits; read the results with [`Renderer::buffers_ref`].
    /// With a timer: one span per pass.
    pub fn render(
        &mut self,
        cam: &Camera,
        lighting: &Lighting,
        mode: Mode,
        exposure: f32,
        mut timer: Option<&mut Timer>,
    ) -> Result<()> {
        self.check_frame(lighting, mode)?;
        self.buffers(cam.width, cam.height)?;
        let culled = self.cull_views(cam, timer.as_deref_mut())?;
        let b = &self.bufs[0];
        b.active.upload(bytemuck::cast_slice(&self.active))?;
        let mut ints = lighting.intensities.clone();
        ints.resize(self.scene.lights.len().max(1), 0.0);
        b.intensity.upload(bytemuck::cast_slice(&ints))?;
        let keep = lighting.keep_buffer(self.scene.originals.len());
        b.keep.upload(bytemuck::cast_slice(&keep))?;
        let push = self.pushes(cam, lighting, mode, exposure);
        let threads = (cam.width * cam.height, 1, 1);
        // The passes that only feed the network (see `display_only`).
        let inputs = mode.needs_network() || !self.display_only;
        let gpu = self.gpu.clone();
        let res = gpu.submit(|cmd| -> Result<()> {
            let mut g = Graph::new(&gpu, cmd, timer);
            self.resources(&mut g, b);
            if culled {
                g.written_before(&GBUFFER)?;
            } else {
                self.record_gbuffer(&mut g, b, cam)?;
            }
            g.dispatch(
                "reproject",
                &self.reproject,
                bytes_of(&push.reproject),
                threads,
            )?;
            g.dispatch(
                "irradiance",
                &self.irradiance,
                bytes_of(&push.irradiance),
                threads,
            )?;
            if inputs {
                let mirror = bytes_of(&push.target_mirror);
                g.dispatch("target mirror", &self.target_mirror, mirror, threads)?;
            }
            if self.runs_glossy(mode) {
                let gl = bytes_of(&push.glossy);
                g.dispatch("glossy sums", &self.glossy_sums, gl, threads)?;
                g.dispatch("glossy layer", &self.glossy, gl, threads)?;
            }
            if inputs {
                g.dispatch(
                    "features",
                    &self.features,
                    bytes_of(&push.features),
                    threads,
                )?;
            }
            if mode.needs_network() {
                let (net, nb) = (self.net.as_ref().unwrap(), b.net.as_ref().unwrap());
                g.external(None, &["NetIn"], &["NetOut"], |cmd, timer| {
                    net.record(cmd, nb, &b.input, timer)
                })?;
            }
            g.dispatch("output", &self.output, bytes_of(&push.output), threads)
        })?;
        res
    }

    /// Whether a frame in `mode` runs the view-dependent layer: glossy mode, and the network
    /// modes of a network whose base is glossy mode's image.
    pub fn runs_glossy(&self, mode: Mode) -> bool {
        let base = self.net.as_ref().map(|n| n.config.base);
        mode.needs_glossy() || (mode.needs_network() && base == Some(crate::net::NetBase::Glossy))
    }

    /// The viewer's cheap frame while anything moves, for the chosen `mode`: ULR and ratio as
    /// they are; glossy mode for glossy mode and for a network whose base is glossy mode's
    /// image (its highlights then move with the walk and a dragged lamp); ratio otherwise, as
    /// the image the network corrects.
    pub fn moving_mode(&self, mode: Mode) -> Mode {
        match mode {
            Mode::Ulr | Mode::Ratio | Mode::Glossy => mode,
            _ if self.runs_glossy(mode) => Mode::Glossy,
            _ => Mode::Ratio,
        }
    }

    /// What a frame needs before anything is recorded: weights for a network mode, one
    /// intensity per added light, and every lit light baked (or live).
    fn check_frame(&self, lighting: &Lighting, mode: Mode) -> Result<()> {
        if mode.needs_network() && self.net.is_none() {
            return Err(Error::Other(format!(
                "{mode:?} mode needs weights (--weights FILE.safetensors); use --mode ratio or ulr"
            )));
        }
        if lighting.intensities.len() != self.scene.lights.len() {
            return Err(Error::Other(format!(
                "lighting has {} intensities; the scene has {} added lights",
                lighting.intensities.len(),
                self.scene.lights.len()
            )));
        }
        if let Some(name) = (self.scene.lights.iter().enumerate()).find_map(|(i, n)| {
            let lit = lighting.intensities[i] != 0.0 && !self.live.is_live(i);
            (lit && self.scene.unbaked.contains(n)).then_some(n)
        }) {
            return Err(Error::Other(format!(
                "added light \"{name}\" is lit but not baked: bake it first (`relit bake SCENE --lights {name}`)"
            )));
        }
        let norig = self.scene.originals.len();
        if lighting.originals.len() > norig {
            return Err(Error::Other(format!(
                "lighting has {} original-light factors; the scene declares {norig} original lights",
                lighting.originals.len()
            )));
        }
        if lighting.per_light() && norig >= 2 && self.scene.split == 0 {
            return Err(Error::Other(
                "a factor for one original light needs their entries in the bake: run `relit bake` again".into(),
            ));
        }
        Ok(())
    }

    /// The push constants of the frame's passes for `cam` (after `cull_views` chose the views).
    fn pushes(&self, cam: &Camera, lighting: &Lighting, mode: Mode, exposure: f32) -> Pushes {
        let s = &self.scene;
        let c = cam.center();
        let eye = [c.x, c.y, c.z, 1.0];
        let (width, height) = (cam.width, cam.height);
        let (view_w, view_h, nviews) = (s.views.width, s.views.height, s.views.count);
        let (nlights, norig) = (s.lights.len() as u32, s.originals.len() as u32);
        let (nlive, live_mask) = (self.live.count(), self.live.mask());
        let (alpha_dim, nactive) = (lighting.alpha_dim, self.active.len() as u32);
        let (nsplit, split_layer) = (s.split, s.split_layer);
        let per_light = lighting.per_light() as u32;
        Pushes {
            reproject: reproject::Push {
                eye,
                width,
                height,
                nactive,
                view_w,
                view_h,
            },
            irradiance: irradiance::Push {
                eye,
                width,
                height,
                nactive,
                view_w,
                view_h,
                nviews,
                nlights,
                alpha_dim,
                nlive,
                live_mask,
                norig,
                nsplit,
                split_layer,
                per_light,
            },
            target_mirror: target_mirror::Push {
                eye,
                width,
                height,
                view_w,
                view_h,
                nviews,
                nlights,
                alpha_dim,
                exclude: self.exclude.unwrap_or(u32::MAX),
                nlive,
                live_mask,
                norig,
                nsplit,
                split_layer,
                per_light,
            },
            glossy: glossy::Push {
                eye,
                width,
                height,
                nactive,
                view_w,
                view_h,
                nlights,
                norig,
                alpha_dim,
                per_light,
            },
            features: features::Push { eye, width, height },
            output: output::Push {
                width,
                height,
                mode: match mode {
                    Mode::Network => 0,
                    Mode::Ulr => 1,
                    Mode::Ratio => 2,
                    Mode::RatioFilled => 3,
                    Mode::Glossy => 4,
                },
                exposure,
                cam: cam.to_gpu(NEAR, FAR),
                nlights,
                base: match self.net.as_ref().map(|n| n.config.base) {
                    Some(crate::net::NetBase::Ratio) => 1,
                    Some(crate::net::NetBase::Glossy) => 2,
                    _ => 0,
                },
                shrink: self.net.as_ref().map_or(0.0, |n| n.config.shrink),
                gate: self.net.as_ref().map_or(0.0, |n| n.config.gate),
                gain: self.net.as_ref().is_some_and(|n| n.config.gain) as u32,
                agree: self.net.as_ref().map_or(0.0, |n| n.config.agree),
                norig,
                alpha_dim,
                fill: self.fill_holes as u32,
            },
        }
    }

    /// Chooses the frame's active views (`self.active`). With more views than `culling.above`
    /// this renders the G-buffer and the view culling pass in a submission of their own and
    /// reads the pass back (returns true: the G-buffer is done).
    fn cull_views(&mut self, cam: &Camera, timer: Option<&mut Timer>) -> Result<bool> {
        let n = self.scene.data.cameras.len();
        if !self.culling.needed(n, self.exclude) {
            self.active = (0..n as u32).filter(|&i| Some(i) != self.exclude).collect();
            return Ok(false);
        }
        let (seen, points) = self.view_visibility(cam, timer)?;
        let cameras = &self.scene.data.cameras;
        self.active = view_cull::choose(
            &self.culling,
            &seen,
            &points,
            cameras,
            cam.center(),
            self.exclude,
        );
        Ok(true)
    }

    /// Renders `cam`'s G-buffer and the view culling pass; returns its visibility bits and grid
    /// points (as [`view_cull::reference`]). Call after `buffers` for `cam`'s size.
    pub fn view_visibility(
        &self,
        cam: &Camera,
        timer: Option<&mut Timer>,
    ) -> Result<(Vec<u32>, Vec<[f32; 4]>)> {
        let b = self.last()?;
        let n = self.scene.data.cameras.len();
        let grid = view_cull::grid(cam.width, cam.height);
        let nw = view_cull::words(grid) as u32;
        let push = view_cull::Push {
            eye: cam.center().extend(1.0).into(),
            width: cam.width,
            height: cam.height,
            grid_w: grid.0,
            grid_h: grid.1,
            nviews: n as u32,
            view_w: self.scene.views.width,
            view_h: self.scene.views.height,
            words: nw,
        };
        let gpu = self.gpu.clone();
        gpu.submit(|cmd| -> Result<()> {
            let mut g = Graph::new(&gpu, cmd, timer);
            self.resources(&mut g, b);
            self.record_gbuffer(&mut g, b, cam)?;
            let threads = (nw * n as u32, 1, 1);
            g.dispatch("view culling", &self.view_cull, bytes_of(&push), threads)
        })??;
        let mut seen: Vec<u32> = bytemuck::pod_collect_to_vec(&b.cull_seen.download()?);
        let mut points: Vec<[f32; 4]> = b.cull_points.download_vec()?;
        seen.truncate(nw as usize * n);
        points.truncate((grid.0 * grid.1) as usize);
        Ok((seen, points))
    }

    fn record_gbuffer<'a>(
        &'a self,
        g: &mut Graph<'a, '_>,
        b: &'a FrameBuffers,
        cam: &Camera,
    ) -> Result<()> {
        let mesh = &self.scene.mesh;
        g.external(Some("g-buffer"), &[], &GBUFFER, |cmd, _| {
            self.gbuffer.record(cmd, mesh, cam, NEAR, FAR, &b.gbuf)
        })
    }

    /// The active views of the last frame, ascending (what its composites read).
    pub fn active_views(&self) -> &[u32] {
        &self.active
    }

    /// The frame's resources by the names its shaders give them.
    fn resources<'a>(&'a self, g: &mut Graph<'a, '_>, b: &'a FrameBuffers) {
        let s = &self.scene;
        let sm = s.sampler.raw;
        let net_out = b.net.as_ref().map(|n| &n.out).unwrap_or(&b.dummy_net_out);
        let (live_caches, live_corners, live_lights) = self.live.buffers();
        let (name, views) = s.views.bind();
        g.set(name, views)
            .set("g_pos", Bind::StorageImage(b.gbuf.pos_depth.view))
            .set("g_nrm", Bind::StorageImage(b.gbuf.normal.view))
            .set("g_tri", Bind::StorageImage(b.gbuf.tri.view))
            .set("Active", Bind::Buffer(&b.active))
            .set("CullSeen", Bind::Buffer(&b.cull_seen))
            .set("CullPoints", Bind::Buffer(&b.cull_points))
            .set("tex_img", Bind::Sampled(s.maps.img.view, sm))
            .set("tex_msrc", Bind::Sampled(s.maps.msrc.view, sm))
            .set("tex_esrc", Bind::Sampled(s.maps.esrc.view, sm))
            .set("tex_eadd", Bind::Sampled(s.maps.eadd.view, sm))
            .set("Intensity", Bind::Buffer(&b.intensity))
            .set("Keep", Bind::Buffer(&b.keep))
            .set("tlas", Bind::Accel(s.mesh.tlas.raw))
            .set("Comp", Bind::Buffer(&b.comp))
            .set("Irr", Bind::Buffer(&b.irr))
            .set("Mirror", Bind::Buffer(&b.mirror))
            .set("Glossy", Bind::Buffer(&b.glossy))
            .set("GlossySums", Bind::Buffer(&b.glossy_sums))
            .set("NetIn", Bind::Buffer(&b.input.buf))
            .set("NetOut", Bind::Buffer(&net_out.buf))
            .set("Hdr", Bind::Buffer(&b.hdr))
            .set("Ldr", Bind::Buffer(&b.ldr))
            .set("Emitters", Bind::Buffer(&s.emitter_buf))
            .set("Originals", Bind::Buffer(&s.original_buf))
            .set("LiveVerts", Bind::Buffer(&s.mesh.positions))
            .set("LiveIndices", Bind::Buffer(&s.mesh.indices))
            .set("LiveCaches", Bind::Buffer(live_caches))
            .set("LiveCorners", Bind::Buffer(live_corners))
            .set("Lives", Bind::Buffer(live_lights));
    }

    /// The buffers of the last [`Renderer::render`] (composites: [`FrameBuffers::composites`]).
    pub fn buffers_ref(&self) -> Option<&FrameBuffers> {
        self.bufs.first()
    }

    /// Linear RGB of the last frame.
    pub fn hdr(&self) -> Result<Vec<[f32; 4]>> {
        let b = self.last()?;
        let mut v: Vec<[f32; 4]> = b.hdr.download_vec()?;
        v.truncate((b.width * b.height) as usize);
        Ok(v)
    }

    /// Display RGBA8 of the last frame.
    pub fn ldr(&self) -> Result<Vec<u8>> {
        let b = self.last()?;
        let n = (b.width * b.height * 4) as u64;
        b.ldr.download_range(0, n)
    }

    fn last(&self) -> Result<&FrameBuffers> {
        self.bufs
            .first()
            .ok_or_else(|| Error::Other("no frame rendered yet".into()))
    }
}
