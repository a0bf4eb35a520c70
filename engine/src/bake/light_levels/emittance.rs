//! Step 3: the found lights' emittance from pairs of pixels taken to share their albedo.

use std::sync::Arc;

use glam::Vec3;

use super::{FindParams, FoundLight};
use crate::bake::radiance_mesh;
use crate::bake::run::Progress;
use crate::bake::source_irradiance::{near_light, original_lights, SourceIrradiance};
use crate::bake::source_irradiance::{PART_ALL, PART_DIRECT};
use crate::bake::views::{GpuViews, ViewData};
use crate::error::Result;
use crate::gpu::{Gpu, RayScene};
use crate::scene::{Light, Mesh};

/// What the emittance passes trace.
pub(super) struct Setting<'a> {
    pub(super) gpu: &'a Arc<Gpu>,
    pub(super) geom: &'a Mesh,
    pub(super) mesh: &'a RayScene,
    pub(super) data: &'a ViewData,
    pub(super) views: &'a GpuViews,
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
pub(super) fn emittance(
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
    dark: &[crate::bake::GpuLight],
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
}
