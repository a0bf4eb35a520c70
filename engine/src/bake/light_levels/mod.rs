//! Light levels of overexposed captures (Appendix A): the original lights a capture's photos
//! clip are found in 3D, and their emittance is estimated from the unclipped pixels they light.
//!
//! 1. **Voxels.** Every view pixel with a proxy surface lands in one voxel (2 cm, or a pixel's
//!    footprint where the photos are coarser). A voxel where at least half of its pixels
//!    clipped is overexposed.
//! 2. **Regions.** Touching overexposed voxels form clusters, merged while their bounding
//!    spheres meet (the paper's clustering). Each becomes a quad fitted to its clipped pixels
//!    (principal axes), facing the views that saw it, `SKIN` off the surface.
//! 3. **Emittance.** E_src = E_nc + Σ_l α_l E_l (eq. 13): E_nc is the estimate with every found
//!    light dark (clipped pixels never enter it), E_l light l's direct light at unit radiance.
//!    The paper asks the user to click points of one albedo (eq. 14); here pairs of nearby
//!    pixels on one surface and of one colour are taken to share it: E_p/I_p = E_q/I_q, which is
//!    linear in α. Least squares per colour channel, reweighted towards L1 so that pairs across
//!    a texture edge lose their say; α ≥ 0.
//!
//! Steps 1–2 are in `regions`, step 3 in `emittance`.

mod emittance;
mod regions;

use std::sync::Arc;

use super::run::Progress;
use super::source_irradiance::{near_light, original_lights};
use super::views::{GpuViews, ViewData};
use crate::error::Result;
use crate::gpu::{Gpu, RayScene};
use crate::scene::{Light, Photo, Scene};

use emittance::{emittance, Setting};
use regions::{fit_quad, regions, voxel_size};

/// Metres between a found light and the surface its pixels lie on (towards the views): its
/// shadow rays then end in front of the proxy, as a declared panel's do.
pub const SKIN: f32 = 0.01;

#[derive(Clone, Debug)]
pub struct FindParams {
    /// Voxel edge (m); the pixels' footprint where that is larger.
    pub voxel: f32,
    /// A voxel is overexposed when at least this fraction of its pixels clipped.
    pub min_clipped: f32,
    /// Regions of fewer voxels are left out (a clipped highlight, a bright speck).
    pub min_voxels: usize,
    /// Rays per pixel of E_nc and E_l.
    pub samples: u32,
    /// Views the emittance is estimated from (evenly spread over the capture).
    pub max_views: usize,
    pub seed: u32,
}

impl Default for FindParams {
    fn default() -> Self {
        FindParams {
            voxel: 0.02,
            min_clipped: 0.5,
            min_voxels: 3,
            samples: 64,
            max_views: 8,
            seed: 11,
        }
    }
}

/// One light found from clipped pixels.
#[derive(Clone, Debug)]
pub struct FoundLight {
    /// An original quad light, `estimated`, its radiance α per channel.
    pub light: Light,
    /// Clipped pixels and views it was fitted to; pixel pairs its emittance was solved from.
    pub pixels: usize,
    pub views: usize,
    pub pairs: usize,
}

impl FoundLight {
    /// Emitted power per channel (W for radiance in W/sr/m²): π L A for a one-sided
    /// Lambertian emitter.
    pub fn power(&self) -> [f32; 3] {
        let a = std::f32::consts::PI * self.light.shape.area();
        self.light.radiance.map(|l| l * a)
    }
}

#[derive(Debug)]
pub struct Finding {
    pub lights: Vec<FoundLight>,
    pub clipped_pixels: usize,
    /// Clipped pixels on no surface of the proxy mesh: they cannot be placed in 3D (a lamp on
    /// a ceiling that a surface over sparse SfM points does not reach).
    pub off_mesh: usize,
    /// The voxel edge used (m).
    pub voxel: f32,
}

impl Finding {
    /// Why nothing was found although photos clip (`None` when a light was found or nothing
    /// clipped): most clipped pixels off the proxy, or no region that meets `p`'s thresholds.
    pub fn why_none(&self, p: &FindParams) -> Option<String> {
        if !self.lights.is_empty() || self.clipped_pixels == 0 {
            return None;
        }
        let (off, all) = (self.off_mesh, self.clipped_pixels);
        Some(if 2 * off >= all {
            format!(
                "no light found: {off} of the {all} clipped pixels see no surface of the proxy \
                 mesh, so they cannot be placed in 3D (a lamp on a ceiling or wall the mesh does \
                 not reach: a surface over sparse SfM points often lacks the ceiling). Give a mesh \
                 that covers it (--mesh FILE) or declare the light by hand (docs/formats.md)"
            )
        } else {
            format!(
                "no light found: no region of at least {} voxels where {:.0} % of the pixels clip \
                 (a clipped highlight on a glossy surface clips in one view, not in the others)",
                p.min_voxels,
                100.0 * p.min_clipped
            )
        })
    }
}

/// Finds the lights `scene`'s photos clip (none when nothing clipped). Lights the scene already
/// declares (not `estimated`) count as known: their pixels and light are not searched again.
pub fn find(
    gpu: &Arc<Gpu>,
    scene: &Scene,
    p: &FindParams,
    progress: &mut dyn Progress,
) -> Result<Finding> {
    let photos = scene.view_photos()?;
    let clipped_pixels = photos.iter().map(Photo::clipped_count).sum();
    let known: Vec<Light> = (scene.lights.iter())
        .filter(|l| !l.estimated)
        .cloned()
        .collect();
    let geom = &scene.mesh;
    let mesh = RayScene::new(gpu, &geom.positions, &geom.triangles)?;
    let cams: Vec<_> = scene.views.iter().map(|v| v.camera.clone()).collect();
    let data = ViewData::from_photos(gpu, &mesh, &cams, &photos)?;
    let voxel = voxel_size(&data, p.voxel);
    let off_mesh = (0..data.pos.len())
        .filter(|&q| data.clipped(q) && data.pos[q][3] <= 0.0)
        .count();
    let known_gpu = original_lights(&known);
    let regions: Vec<Vec<usize>> = regions(&data, voxel, p)
        .into_iter()
        .map(|r| r.into_iter().filter(|&q| !near_light(&data, &known_gpu, q)))
        .map(|r| r.collect::<Vec<_>>())
        .filter(|r| !r.is_empty())
        .collect();
    let mut lights: Vec<FoundLight> = (regions.iter().enumerate())
        .map(|(i, r)| fit_quad(&data, r, i))
        .collect();
    if !lights.is_empty() {
        let views = GpuViews::upload(gpu, &data)?;
        let s = Setting {
            gpu,
            geom,
            mesh: &mesh,
            data: &data,
            views: &views,
        };
        emittance(&s, &known, &mut lights, p, progress)?;
    }
    Ok(Finding {
        lights,
        clipped_pixels,
        off_mesh,
        voxel,
    })
}

/// The scene's lights with `found` in place of any earlier estimated ones.
pub fn replace_estimated(scene: &Scene, found: &[FoundLight]) -> Vec<Light> {
    let mut lights: Vec<Light> = (scene.lights.iter())
        .filter(|l| !l.estimated)
        .cloned()
        .collect();
    lights.extend(found.iter().map(|f| f.light.clone()));
    lights
}
