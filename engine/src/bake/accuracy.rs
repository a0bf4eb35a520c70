//! Accuracy of the bake against a synthetic scene's ground truth (tools/groundtruth):
//! - E_src vs the true irradiance π·O*_diffuse/ρ under the original lighting,
//! - the albedo mesh (interpolated at each pixel) vs the true diffuse albedo ρ,
//! - E_add of each added light vs π·O*_diffuse/ρ rendered with that light alone,
//! - M_src vs the true mirror image (radiance from the mirror direction, path traced), where
//!   M_src found a view.
//!
//! Compared per pixel, luminance, where the proxy and true surfaces agree (camera depth within
//! 2%), ρ > 0.05 and the pixel is not a light (O*_diffuse luminance < 5). Reported as median
//! relative errors |estimate − truth| / truth, and as the median ratio estimate / truth: the
//! error bounds its size, the ratio its sign (a bias that a symmetric error hides).

use std::sync::Arc;

use glam::Vec3;

use super::BakeCache;
use super::ViewData;
use crate::error::{Error, Result};
use crate::gpu::{Gpu, RayScene};
use crate::scene::image::load_rgb;
use crate::scene::Scene;

/// One quantity compared per pixel.
#[derive(Debug, Default, Clone, Copy)]
pub struct Stat {
    /// Median of |estimate − truth| / truth.
    pub error: f64,
    /// Median of estimate / truth (1 = unbiased).
    pub ratio: f64,
    pub pixels: usize,
}

impl Stat {
    /// From (estimate, truth) pairs.
    fn of(pairs: &[(f64, f64)]) -> Stat {
        Stat {
            error: median(pairs.iter().map(|(e, t)| (e - t).abs() / t).collect()),
            ratio: median(pairs.iter().map(|(e, t)| e / t).collect()),
            pixels: pairs.len(),
        }
    }
}

impl std::fmt::Display for Stat {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "error {:.3}, ratio {:.3} ({} px)",
            self.error, self.ratio, self.pixels
        )
    }
}

#[derive(Debug, Default, Clone)]
pub struct Accuracy {
    pub e_src: Stat,
    pub albedo: Stat,
    /// Per added light with ground truth.
    pub e_add: Vec<(String, Stat)>,
    pub m_src: Stat,
    pub views: usize,
}

fn lum(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// The bake of `scene` with `p` (the parameters also decide the traced mesh) against its
/// ground truth.
pub fn evaluate(gpu: &Arc<Gpu>, scene: &Scene, p: &super::BakeParams) -> Result<Accuracy> {
    let cache = &BakeCache::of(scene, p)?;
    let geom = super::run::bake_mesh(scene, p);
    let syn = scene.synthetic.as_ref().ok_or_else(|| {
        Error::Other(format!(
            "{}: no ground truth (not a synthetic scene)",
            scene.root.display()
        ))
    })?;
    let gt = scene.root.join(&syn.ground_truth);
    let mesh = RayScene::new(gpu, &geom.positions, &geom.triangles)?;
    let cams: Vec<_> = scene.views.iter().map(|v| v.camera.clone()).collect();
    let imgs = scene.view_images()?;
    let d = ViewData::build(gpu, &mesh, &cams, &imgs)?;
    let albedo = cache.read_albedo(geom.positions.len())?;
    let npix = d.pixels();
    let mut acc = Accuracy::default();
    let (mut es, mut al, mut ms) = (Vec::new(), Vec::new(), Vec::new());
    let mut ea: Vec<(String, Vec<(f64, f64)>)> = scene
        .lights
        .iter()
        .filter(|l| !l.original)
        .map(|l| (l.name.clone(), Vec::new()))
        .collect();
    for (i, v) in scene.views.iter().enumerate() {
        let f = |k: &str| gt.join("aov").join(format!("{}.{k}.exr", v.name));
        let diff = gt.join("original").join(format!("{}.diffuse.exr", v.name));
        if !f("albedo").exists() || !diff.exists() {
            continue;
        }
        acc.views += 1;
        let (rho, depth, od) = (
            load_rgb(&f("albedo"))?,
            load_rgb(&f("depth"))?,
            load_rgb(&diff)?,
        );
        let esrc = BakeCache::load_map(&cache.esrc(&v.name))?;
        let mirror_gt = gt.join("original").join(format!("{}.mirror.exr", v.name));
        let mirror = if mirror_gt.exists() {
            Some((
                BakeCache::load_map(&cache.msrc(&v.name))?,
                load_rgb(&mirror_gt)?,
            ))
        } else {
            None
        };
        let names: Vec<&str> = ea.iter().map(|(l, _)| l.as_str()).collect();
        let eadd = load_eadd(scene, cache, p, &gt, &v.name, &names)?;
        for p in 0..npix {
            let gi = i * npix + p;
            let (zp, zt) = (d.pos[gi][3], depth.pixels[p][0]);
            let r = lum(rho.pixels[p]);
            if zp <= 0.0
                || zt <= 0.0
                || (zp - zt).abs() > crate::constants::DEPTH_EPS * zt
                || r <= 0.05
                || lum(od.pixels[p]) >= 5.0
            {
                continue;
            }
            let e_true = std::f32::consts::PI * lum(od.pixels[p]) / r;
            if let Some((ours, t)) = &mirror {
                let (o, t) = (lum([ours[p][0], ours[p][1], ours[p][2]]), lum(t.pixels[p]));
                if o > 0.0 && t > 1e-3 {
                    ms.push((o as f64, t as f64));
                }
            }
            if e_true > 1e-4 {
                es.push((
                    lum([esrc[p][0], esrc[p][1], esrc[p][2]]) as f64,
                    e_true as f64,
                ));
            }
            if let Some(est) = albedo_at(&geom, &albedo, &d, gi) {
                al.push((lum(est) as f64, r as f64));
            }
            for (k, e) in eadd.iter().enumerate() {
                if let Some((ours, g)) = e {
                    let t = std::f32::consts::PI * lum(g.pixels[p]) / r;
                    if t > 1e-3 {
                        ea[k]
                            .1
                            .push((lum([ours[p][0], ours[p][1], ours[p][2]]) as f64, t as f64));
                    }
                }
            }
        }
    }
    acc.e_src = Stat::of(&es);
    acc.albedo = Stat::of(&al);
    acc.m_src = Stat::of(&ms);
    acc.e_add = ea
        .into_iter()
        .filter(|(_, v)| !v.is_empty())
        .map(|(n, v)| (n, Stat::of(&v)))
        .collect();
    Ok(acc)
}

/// An added light's E_add map of one view and its ground truth (the light alone).
type EaddPair = (Vec<[f32; 4]>, crate::scene::RgbImage);

/// Each added light's E_add map of view `view` with its ground truth, where both exist.
fn load_eadd(
    scene: &Scene,
    cache: &BakeCache,
    p: &super::BakeParams,
    gt: &std::path::Path,
    view: &str,
    lights: &[&str],
) -> Result<Vec<Option<EaddPair>>> {
    lights
        .iter()
        .map(|l| {
            let g = gt.join(l).join(format!("{view}.diffuse.exr"));
            let light = scene.lights.iter().find(|x| x.name == *l);
            let c = light.map(|x| cache.eadd(view, x, p)).unwrap_or_default();
            (g.exists() && c.exists())
                .then(|| Ok::<_, Error>((BakeCache::load_map(&c)?, load_rgb(&g)?)))
                .transpose()
        })
        .collect()
}

/// The albedo mesh interpolated at pixel `gi`'s surface point: `None` off the mesh, in a
/// degenerate triangle, or where a corner's albedo was never seen.
fn albedo_at(
    geom: &crate::scene::Mesh,
    albedo: &[[f32; 4]],
    d: &ViewData,
    gi: usize,
) -> Option<[f32; 3]> {
    if d.tri[gi] == 0 {
        return None;
    }
    let t = geom.triangles[(d.tri[gi] - 1) as usize];
    let [a, b, c] = t.map(|k| Vec3::from(geom.positions[k as usize]));
    let x = Vec3::from_slice(&d.pos[gi][..3]);
    // Barycentrics of x in the triangle.
    let (v0, v1, v2) = (b - a, c - a, x - a);
    let (d00, d01, d11, d20, d21) = (v0.dot(v0), v0.dot(v1), v1.dot(v1), v2.dot(v0), v2.dot(v1));
    let den = d00 * d11 - d01 * d01;
    if den.abs() > 1e-12 {
        let (bv, bw) = ((d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den);
        let w = [1.0 - bv - bw, bv, bw];
        let mut est = [0.0f32; 3];
        let mut seen = true;
        for (k, &vi) in t.iter().enumerate() {
            let av = albedo[vi as usize];
            seen &= av[3] > 0.0;
            for ch in 0..3 {
                est[ch] += w[k] * av[ch];
            }
        }
        if seen {
            return Some(est);
        }
    }
    None
}
