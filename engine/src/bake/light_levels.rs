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

use std::collections::{HashMap, HashSet};
use std::sync::Arc;

use glam::Vec3;

use super::radiance_mesh;
use super::run::Progress;
use super::source_irradiance::{near_light, original_lights, SourceIrradiance};
use super::source_irradiance::{PART_ALL, PART_DIRECT};
use super::views::{GpuViews, ViewData};
use crate::error::Result;
use crate::gpu::{Gpu, RayScene};
use crate::scene::{Light, LightShape, Mesh, Photo, Scene};

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

/// `voxel`, or the median footprint of a clipped pixel on its surface where that is larger
/// (coarse photos put one pixel in a voxel of 2 cm only now and then).
fn voxel_size(d: &ViewData, voxel: f32) -> f32 {
    let mut fp: Vec<f32> = (0..d.pos.len())
        .filter(|&q| d.clipped(q) && d.pos[q][3] > 0.0)
        .map(|q| d.pos[q][3] / d.cameras[q / d.pixels()].fx)
        .collect();
    if fp.is_empty() {
        return voxel;
    }
    let mid = fp.len() / 2;
    fp.select_nth_unstable_by(mid, f32::total_cmp);
    voxel.max(fp[mid])
}

type Key = [i32; 3];

fn key(p: [f32; 4], voxel: f32) -> Key {
    [0, 1, 2].map(|i| (p[i] / voxel).floor() as i32)
}

/// The clipped pixels of each overexposed region (global pixel indices).
fn regions(d: &ViewData, voxel: f32, p: &FindParams) -> Vec<Vec<usize>> {
    let mut count: HashMap<Key, (u32, u32)> = HashMap::new();
    for (q, g) in d.pos.iter().enumerate().filter(|(_, g)| g[3] > 0.0) {
        let c = count.entry(key(*g, voxel)).or_default();
        c.0 += 1;
        c.1 += d.clipped(q) as u32;
    }
    let over: HashSet<Key> = (count.iter())
        .filter(|(_, &(n, c))| c > 0 && c as f32 >= p.min_clipped * n as f32)
        .map(|(k, _)| *k)
        .collect();
    let clusters = merge_spheres(components(&over), voxel);
    let of: HashMap<Key, usize> = (clusters.iter().enumerate())
        .filter(|(_, c)| c.len() >= p.min_voxels)
        .flat_map(|(i, c)| c.iter().map(move |k| (*k, i)))
        .collect();
    let mut pixels = vec![Vec::new(); clusters.len()];
    for q in (0..d.pos.len()).filter(|&q| d.clipped(q) && d.pos[q][3] > 0.0) {
        if let Some(&i) = of.get(&key(d.pos[q], voxel)) {
            pixels[i].push(q);
        }
    }
    pixels.retain(|r| !r.is_empty());
    pixels
}

/// Sets of overexposed voxels that touch (26-neighbourhood).
fn components(over: &HashSet<Key>) -> Vec<Vec<Key>> {
    let mut seen: HashSet<Key> = HashSet::new();
    let mut out = Vec::new();
    let mut sorted: Vec<Key> = over.iter().copied().collect();
    sorted.sort();
    for start in sorted {
        if !seen.insert(start) {
            continue;
        }
        let (mut comp, mut stack) = (vec![], vec![start]);
        while let Some(k) = stack.pop() {
            comp.push(k);
            for d in (0..27).map(|i| [i % 3 - 1, i / 3 % 3 - 1, i / 9 - 1]) {
                let n = [k[0] + d[0], k[1] + d[1], k[2] + d[2]];
                if over.contains(&n) && seen.insert(n) {
                    stack.push(n);
                }
            }
        }
        out.push(comp);
    }
    out
}

/// Centre and radius of the sphere around a cluster's voxels.
fn bounding_sphere(c: &[Key], voxel: f32) -> (Vec3, f32) {
    let at = |k: &Key| (Vec3::new(k[0] as f32, k[1] as f32, k[2] as f32) + 0.5) * voxel;
    let centre = c.iter().map(at).sum::<Vec3>() / c.len() as f32;
    let r = c.iter().map(|k| at(k).distance(centre)).fold(0.0, f32::max);
    (centre, r + 0.87 * voxel)
}

/// Merges clusters while the bounding spheres of two of them intersect: each pass joins every
/// intersecting pair at once (union-find), then the merged clusters' spheres are measured again.
/// One pair a pass took O(n³) on a dense proxy, where a capture's clipped pixels make thousands
/// of small clusters (AliceVision's buddha: > 45 min).
fn merge_spheres(mut clusters: Vec<Vec<Key>>, voxel: f32) -> Vec<Vec<Key>> {
    loop {
        let spheres: Vec<_> = clusters.iter().map(|c| bounding_sphere(c, voxel)).collect();
        let n = clusters.len();
        let mut parent: Vec<usize> = (0..n).collect();
        let mut merged = false;
        for i in 0..n {
            for j in i + 1..n {
                if spheres[i].0.distance(spheres[j].0) <= spheres[i].1 + spheres[j].1 {
                    let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                    if a != b {
                        parent[a.max(b)] = a.min(b);
                        merged = true;
                    }
                }
            }
        }
        if !merged {
            return clusters;
        }
        let mut joined: Vec<Vec<Key>> = vec![Vec::new(); n];
        for (i, c) in clusters.into_iter().enumerate() {
            joined[root(&mut parent, i)].extend(c);
        }
        clusters = joined.into_iter().filter(|c| !c.is_empty()).collect();
    }
}

/// The representative of `i`'s set (path halving).
fn root(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// A quad over a region's clipped pixels: principal axes of their surface points, the normal
/// towards the views that saw them, the extent of the points along the two larger axes.
fn fit_quad(d: &ViewData, pixels: &[usize], index: usize) -> FoundLight {
    let pts: Vec<Vec3> = pixels
        .iter()
        .map(|&q| Vec3::from_slice(&d.pos[q][..3]))
        .collect();
    let mean = pts.iter().sum::<Vec3>() / pts.len() as f32;
    let mut cov = [[0.0f32; 3]; 3];
    for p in &pts {
        let x = *p - mean;
        for (i, row) in cov.iter_mut().enumerate() {
            for (j, c) in row.iter_mut().enumerate() {
                *c += x[i] * x[j];
            }
        }
    }
    let axes = principal_axes(cov);
    let mut n = axes[2];
    let towards: Vec3 = (pixels.iter().zip(&pts))
        .map(|(&q, p)| (d.cameras[q / d.pixels()].center() - *p).normalize_or_zero())
        .sum();
    if n.dot(towards) < 0.0 {
        n = -n;
    }
    let u = axes[0];
    let v = if u.cross(axes[1]).dot(n) < 0.0 {
        -axes[1]
    } else {
        axes[1]
    };
    let range = |a: Vec3| {
        let s = pts.iter().map(|p| (*p - mean).dot(a));
        let lo = s.clone().fold(f32::INFINITY, f32::min);
        (lo, s.fold(f32::NEG_INFINITY, f32::max) - lo)
    };
    let ((u0, du), (v0, dv)) = (range(u), range(v));
    let views: HashSet<usize> = pixels.iter().map(|&q| q / d.pixels()).collect();
    FoundLight {
        light: Light {
            name: format!("estimated{index}"),
            shape: LightShape::Quad {
                corner: mean + u0 * u + v0 * v + SKIN * n,
                edge_u: du.max(1e-3) * u,
                edge_v: dv.max(1e-3) * v,
            },
            radiance: [1.0; 3],
            original: true,
            estimated: true,
        },
        pixels: pixels.len(),
        views: views.len(),
        pairs: 0,
    }
}

/// Eigenvectors of a symmetric 3×3 matrix, largest eigenvalue first (Jacobi rotations).
fn principal_axes(m: [[f32; 3]; 3]) -> [Vec3; 3] {
    let mut a = m.map(|r| r.map(f64::from));
    let mut v = [[1.0f64, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..50 {
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q].abs() < 1e-30 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let (c, s) = (1.0 / (t * t + 1.0).sqrt(), t / (t * t + 1.0).sqrt());
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (rp, rq) = (a[p], a[q]);
            a[p] = [0, 1, 2].map(|k| c * rp[k] - s * rq[k]);
            a[q] = [0, 1, 2].map(|k| s * rp[k] + c * rq[k]);
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| a[j][j].total_cmp(&a[i][i]));
    order.map(|i| Vec3::new(v[0][i] as f32, v[1][i] as f32, v[2][i] as f32).normalize())
}

/// What the emittance passes trace.
struct Setting<'a> {
    gpu: &'a Arc<Gpu>,
    geom: &'a Mesh,
    mesh: &'a RayScene,
    data: &'a ViewData,
    views: &'a GpuViews,
}

/// Two pixels taken to share their albedo (eq. 14): log I_p − log I_q = log E_p − log E_q, with
/// E = E_nc + Σ_l α_l E_l. In logarithms an albedo that differs after all (a texture) only
/// shifts the residual; divided by I, as in eq. 15, it would scale both sides together and drag
/// α below zero (measured on a textured scenegen room).
struct Row {
    /// log I_p − log I_q per channel.
    d: [f32; 3],
    /// E_nc at p and q per channel.
    nc: [[f32; 3]; 2],
    /// Per light: E_l (unit radiance) at p and q per channel.
    l: Vec<[[f32; 3]; 2]>,
}

impl Row {
    /// |residual| of channel `c` under `alpha`.
    fn residual(&self, c: usize, alpha: &[f64]) -> f64 {
        let e = |k: usize| {
            let lit: f64 = (self.l.iter().zip(alpha))
                .map(|(l, a)| l[k][c] as f64 * a)
                .sum();
            (self.nc[k][c] as f64 + lit).max(1e-12).ln()
        };
        (self.d[c] as f64 - e(0) + e(1)).abs()
    }
}

/// Solves the found lights' radiance (eq. 13–15) and writes it into `lights`.
fn emittance(
    s: &Setting,
    known: &[Light],
    lights: &mut [FoundLight],
    p: &FindParams,
    progress: &mut dyn Progress,
) -> Result<()> {
    let dark: Vec<Light> = (known.iter().cloned())
        .chain(lights.iter().map(|f| Light {
            radiance: [0.0; 3],
            ..f.light.clone()
        }))
        .collect();
    let nc = SourceIrradiance::new(s.gpu, &dark)?;
    let radiance = radiance_mesh::build(
        s.gpu, &nc, &dark, s.geom, s.mesh, s.views, p.samples, p.seed,
    )?;
    let unit: Vec<SourceIrradiance> = (lights.iter())
        .map(|f| SourceIrradiance::new(s.gpu, std::slice::from_ref(&f.light)))
        .collect::<Result<_>>()?;
    let dark_gpu = original_lights(&dark);
    let nv = s.data.cameras.len();
    let step = nv.div_ceil(p.max_views.max(1));
    let mut rows = Vec::new();
    let chosen: Vec<usize> = (0..nv).step_by(step).collect();
    for (k, &j) in chosen.iter().enumerate() {
        progress.update("emittance", k, chosen.len(), 0);
        let r = (j as u32, p.samples, p.seed);
        let e_nc = nc.run_parts(s.mesh, &radiance, s.views, r, PART_ALL)?;
        // E_l sits inside a logarithm: more rays than E_nc keep its noise from biasing α.
        let r_l = (r.0, 2 * r.1, r.2);
        let e_l: Vec<Vec<[f32; 4]>> = (unit.iter())
            .map(|u| u.run_parts(s.mesh, &radiance, s.views, r_l, PART_DIRECT))
            .collect::<Result<_>>()?;
        pair_rows(s.data, j, &e_nc, &e_l, &dark_gpu, &mut rows);
    }
    progress.update("emittance", chosen.len(), chosen.len(), 0);
    let per_channel: Vec<Vec<f64>> = (0..3).map(|c| solve(&rows, c, lights.len())).collect();
    for (l, f) in lights.iter_mut().enumerate() {
        f.light.radiance = [0, 1, 2].map(|c| per_channel[c][l] as f32);
        f.pairs = (rows.iter())
            .filter(|r| r.l[l].iter().flatten().any(|&e| e > 0.0))
            .count();
    }
    Ok(())
}

/// Pixel offsets of the pairs: a fifth and a third of the view's width. Near pairs see too
/// little of the light's falloff against the noise of I (JPEG) and the pixel filter's blur of
/// shadow edges, which pull α low (measured on hand_room at 64×48: pairs 2 and 6 px apart gave
/// 0.79 of the truth's power, 6 and 12 px 0.93, 12 and 21 px 0.97).
fn offsets(width: u32) -> [(i32, i32); 4] {
    let (a, b) = ((width / 5).max(1) as i32, (width / 3).max(2) as i32);
    [(a, 0), (0, a), (b, 0), (0, b)]
}

/// The equations of view `j`'s pixel pairs that lie on one surface with one colour.
fn pair_rows(
    d: &ViewData,
    j: usize,
    e_nc: &[[f32; 4]],
    e_l: &[Vec<[f32; 4]>],
    dark: &[super::GpuLight],
    rows: &mut Vec<Row>,
) {
    let (w, h, npix) = (d.width as i32, d.height as i32, d.pixels());
    let usable = |i: usize| {
        let g = j * npix + i;
        let lum = d.img[g][0] + d.img[g][1] + d.img[g][2];
        d.pos[g][3] > 0.0
            && !d.clipped(g)
            && e_nc[i][3] > 0.0
            && lum > 1e-4
            && !near_light(d, dark, g)
    };
    let chroma = |g: usize| {
        let c = Vec3::from_slice(&d.img[g][..3]);
        c / c.element_sum().max(1e-6)
    };
    for y in 0..h {
        for x in 0..w {
            let ip = (y * w + x) as usize;
            if !usable(ip) {
                continue;
            }
            for (dx, dy) in offsets(d.width) {
                let (xq, yq) = (x + dx, y + dy);
                if xq >= w || yq >= h {
                    continue;
                }
                let iq = (yq * w + xq) as usize;
                let (gp, gq) = (j * npix + ip, j * npix + iq);
                if !usable(iq) || !one_surface(d, gp, gq) || chroma(gp).distance(chroma(gq)) > 0.05
                {
                    continue;
                }
                let rgb = |e: [f32; 4]| [e[0], e[1], e[2]];
                let (ip_rgb, iq_rgb) = (d.img[gp], d.img[gq]);
                rows.push(Row {
                    d: [0, 1, 2].map(|c| (ip_rgb[c].max(1e-6) / iq_rgb[c].max(1e-6)).ln()),
                    nc: [rgb(e_nc[ip]), rgb(e_nc[iq])],
                    l: e_l.iter().map(|e| [rgb(e[ip]), rgb(e[iq])]).collect(),
                });
            }
        }
    }
}

/// Whether global pixels `p` and `q` lie on one plane (normals agree, each on the other's
/// plane within 2 cm).
fn one_surface(d: &ViewData, p: usize, q: usize) -> bool {
    let (np, nq) = (
        Vec3::from_slice(&d.nrm[p][..3]),
        Vec3::from_slice(&d.nrm[q][..3]),
    );
    let (xp, xq) = (
        Vec3::from_slice(&d.pos[p][..3]),
        Vec3::from_slice(&d.pos[q][..3]),
    );
    np.dot(nq).abs() > 0.95 && (xq - xp).dot(np).abs() < 0.02
}

/// α ≥ 0 of channel `c`: the least sum of |residual| (L1: pairs across a texture edge or a
/// shadow the proxy lacks do not pull it), light by light over a log-spaced grid and then
/// finer around the best, two sweeps.
fn solve(rows: &[Row], c: usize, n: usize) -> Vec<f64> {
    let mut alpha = vec![0.0f64; n];
    let cost = |a: &[f64]| rows.iter().map(|r| r.residual(c, a)).sum::<f64>();
    // α_l from 1e-4 to 1e6, 20 steps a decade; then ±1 step in 40.
    let at = |k: f64| 10f64.powf(-4.0 + k / 20.0);
    for _ in 0..2 {
        for l in 0..n {
            let mut trial = alpha.clone();
            let mut best = (cost(&alpha), alpha[l]);
            let mut probe = |k: f64, best: &mut (f64, f64)| {
                trial[l] = at(k);
                let e = cost(&trial);
                if e < best.0 {
                    *best = (e, trial[l]);
                }
            };
            (0..=200).for_each(|k| probe(k as f64, &mut best));
            let k0 = 20.0 * (best.1.max(1e-4).log10() + 4.0);
            (-20..=20).for_each(|k| probe(k0 + k as f64 / 20.0, &mut best));
            alpha[l] = best.1;
        }
    }
    alpha
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn principal_axes_of_a_flat_cloud_put_its_normal_last() {
        // Points spread 1 m along x, 0.5 m along z, flat in y.
        let mut cov = [[0.0f32; 3]; 3];
        cov[0][0] = 1.0;
        cov[2][2] = 0.25;
        cov[0][2] = 0.01;
        cov[2][0] = 0.01;
        let a = principal_axes(cov);
        assert!(
            a[0].x.abs() > 0.99 && a[1].z.abs() > 0.99 && a[2].y.abs() > 0.99,
            "{a:?}"
        );
    }

    #[test]
    fn pairs_of_one_albedo_give_the_lights_emittance() {
        // Pixels of albedo 0.5 (I = 0.5/π E) under E = E_nc + 3 E_l: the pairs recover α = 3,
        // also with a quarter of them across an albedo edge (L1), one of the two dark.
        let mut rows = Vec::new();
        for i in 0..40 {
            let (enc_p, enc_q) = (0.2 + 0.01 * i as f32, 0.25);
            let (el_p, el_q) = (0.1 * (i % 7) as f32, 0.05);
            let edge = if i % 4 == 0 { 0.2 } else { 1.0 };
            let ip = 0.5 / std::f32::consts::PI * (enc_p + 3.0 * el_p) * edge;
            let iq = 0.5 / std::f32::consts::PI * (enc_q + 3.0 * el_q);
            rows.push(Row {
                d: [(ip / iq).ln(); 3],
                nc: [[enc_p; 3], [enc_q; 3]],
                l: vec![[[el_p; 3], [el_q; 3]]],
            });
        }
        let a = solve(&rows, 0, 1);
        assert!((a[0] - 3.0).abs() < 0.05, "{a:?}");
    }

    #[test]
    fn touching_voxels_and_meeting_spheres_make_one_region() {
        let over: HashSet<Key> = [[0, 0, 0], [1, 0, 0], [2, 1, 0], [9, 0, 0], [30, 0, 0]]
            .into_iter()
            .collect();
        let c = components(&over);
        assert_eq!(c.len(), 3);
        // [9,0,0]'s sphere (r 0.87) misses the first cluster's (centre x ≈ 1.5, r ≈ 2.2).
        let m = merge_spheres(c, 1.0);
        assert_eq!(m.len(), 3, "{m:?}");
        // A 4 × 4 patch and a voxel one gap away: two components, one sphere each, meeting.
        let mut over2: HashSet<Key> = (0..16).map(|i| [i % 4, i / 4, 0]).collect();
        over2.insert([5, 1, 0]);
        assert_eq!(components(&over2).len(), 2);
        assert_eq!(merge_spheres(components(&over2), 1.0).len(), 1);
    }

    #[test]
    fn thousands_of_clusters_merge_by_their_spheres() {
        // 3000 single voxels 3 apart (spheres of r 0.87 miss) and, far off, a chain of 2 × 2
        // patches one gap apart (spheres of r 1.58 meet across the gap: one region).
        let mut over: HashSet<Key> = (0..3000).map(|i| [3 * i, 0, 0]).collect();
        for i in 0..20 {
            over.extend([
                [3 * i, 100, 0],
                [3 * i + 1, 100, 0],
                [3 * i, 101, 0],
                [3 * i + 1, 101, 0],
            ]);
        }
        let m = merge_spheres(components(&over), 1.0);
        assert_eq!(m.len(), 3001, "3000 apart, the chain one");
        assert!(m.iter().any(|c| c.len() == 80));
    }
}
