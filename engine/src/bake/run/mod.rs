//! `relit bake`: runs the bake passes over a scene and keeps their results in its
//! [`BakeCache`] (`.relit/bake-<key>/`).
//!
//! Stages, each a short function over the cache: (1) E_src per view, (2) the albedo mesh (needs
//! every view's E_src), (3) M_src per view, (4) per added light its surface cache and E_add per
//! view. A stage skips what the cache already holds, so an interrupted bake (Ctrl-C, kill -9)
//! resumes where it stopped. `views` bakes a slice, so a capture can be split across jobs:
//! stages 2–4 run once every view's E_src is present.
//!
//! Here: the parameters, the report and what every stage reads; stages 1–3 are in `stages`,
//! the lights' entries (stage 4) in `lights`.

mod lights;
mod stages;

use std::ops::Range;
use std::path::PathBuf;
use std::sync::Arc;

use crate::bake::views::photo_rgba;
use crate::bake::{AddedParams, BakeCache, DenoiseParams, GpuViews, ViewData};
use crate::error::Result;
use crate::gpu::{vk, Buffer, Gpu, RayScene};
use crate::scene::{Light, Scene};

use lights::added_stage;
pub use lights::{entry_lights, light_caches, splits_originals, wanted_lights};
pub use stages::bake;

pub use crate::bake::cache::BAKE_VERSION;

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
