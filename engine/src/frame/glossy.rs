//! The view-dependent layer (§3: L = a·E + S): `shaders_glsl/frame/glossy_sums.comp` and
//! `glossy.comp`. The photos that see a surface point are fitted as `I_j ≈ D + Σ_c w_c·X_j,c`
//! (RGB D, grey w_c), X_j,c the declared original lights through a GGX microfacet lobe of
//! roughness GLOSSY_LOBE_1..3 seen from view j, with Schlick's Fresnel and Smith's masking
//! (`lobe.glsl`; w_c then reads as the surface's F0). The sums pass gathers each pixel's centred
//! sums over the views; the fit per surface (`glossy_fit/`) renders it from the input cameras
//! once per scene and pools it over every photo of a surface. The layer takes the strengths of
//! the pixel's surface (none: ratio's image); it gives the diffuse part D, which eq. 5 relights,
//! and the view-dependent part S: the photos' own (I_1 − D) moved to the novel view (plus what
//! the lobes give there, less what they gave the photos), dimmed with their lights, plus each
//! lit lamp through the lobes seen from the novel view. Glossy mode shows
//! `D · (E_add + E_src − E_rem) / E_src + S` (`output.glsl`): ratio's image where no fit holds.
//! Both passes' push constants are the frame's ([`super::FrameConstants`]).

use glam::Vec3;

use super::sight::{shared_sight, sight_lights, SIGHT_MAX};
use super::sight_cache::SHARP;
use super::RefInputs;
use crate::bake::GpuLight;
use crate::constants::{
    GLOSSY_COS_MIN, GLOSSY_F0, GLOSSY_LOBE_1, GLOSSY_LOBE_2, GLOSSY_LOBE_3, GLOSSY_MIN_VIEWS,
    GLOSSY_SHARE, GLOSSY_S_MAX, GLOSSY_WIDE_S, SIGHT_CACHE_SAMPLES,
};
use crate::gpu::shaders;
use crate::scene::Mesh;

pub const SHADER: crate::gpu::Shader = shaders::FRAME_GLOSSY;
pub const SUMS_SHADER: crate::gpu::Shader = shaders::FRAME_GLOSSY_SUMS;
/// Planes of the output: (D, Σ w_c), (S, the leading lobe + 1).
pub const PLANES: usize = 2;
/// Regressors: the original lights through the three lobe widths.
const LOBES: usize = 3;
/// Original lights that take part in the fit (one shadow ray each per pixel).
pub(super) const MAX_ORIG: usize = 8;

fn lobe_width(c: usize) -> f32 {
    [GLOSSY_LOBE_1, GLOSSY_LOBE_2, GLOSSY_LOBE_3][c]
}

/// The largest strength lobe c may take in the fit per surface (`glossy_fit/`):
/// GLOSSY_S_MAX for the narrowest, less for wider ones in proportion to their roughness (a rough
/// surface that reflects as much as a mirror is a rough metal, rare indoors; a near-mirror
/// blurred by its proxy would otherwise take a wide lobe and glow around every lamp), and at
/// most GLOSSY_WIDE_S, a dielectric's F0, for the wider ones: a glossy plastic reflecting a large
/// window (a lobe evaluated at the light's centre) otherwise takes the widest lobe and spreads
/// the window into a sheen the surface does not have (sg800003, session 36).
pub fn lobe_s_max(c: usize) -> f32 {
    let s = GLOSSY_S_MAX * GLOSSY_LOBE_1 / lobe_width(c);
    if c > 0 {
        s.min(GLOSSY_WIDE_S)
    } else {
        s
    }
}

/// Centre, unit emitting normal and area of a light.
pub(crate) fn light_frame(l: &GpuLight) -> (Vec3, Vec3, f32) {
    let v = |a: [f32; 4]| Vec3::from_slice(&a[..3]);
    if l.p0[3] < 0.5 {
        let cr = v(l.p1).cross(v(l.p2));
        (
            v(l.p0) + 0.5 * (v(l.p1) + v(l.p2)),
            cr.normalize(),
            cr.length(),
        )
    } else {
        let r = l.p2[0];
        (v(l.p0), v(l.p1).normalize(), std::f32::consts::PI * r * r)
    }
}

/// Whether x (normal n) sees light l's centre (one ray from 1 cm off the surface, stopped 5 cm
/// short of the light: `lobe.glsl`'s `sees_light`).
pub fn sees_light(mesh: &Mesh, x: Vec3, n: Vec3, l: &GpuLight) -> bool {
    let d = light_frame(l).0 - x;
    let dist = d.length();
    if d.dot(n) <= 0.0 || dist < 0.06 {
        return false;
    }
    !crate::cpu::occluded(
        mesh,
        x + n * crate::constants::SIGHT_LIFT,
        d / dist,
        1e-3,
        dist - 0.05,
    )
}

/// The GGX lobe of roughness α that light l (solid angle Ω, unit direction w from x) gives
/// towards unit v over normal n (`lobe.glsl`'s `lobe_weight`):
/// Ω·D(n·h)·F(v·h)·G1(n·v)·G1(n·w)/(4·n·v·F0), α widened to α'² = α² + Ω/8π in D, F Schlick's
/// with F0 = GLOSSY_F0, G1 Smith's masking; zero below GLOSSY_COS_MIN.
pub fn lobe_weight(alpha: f32, omega: f32, w: Vec3, v: Vec3, n: Vec3) -> f32 {
    use std::f32::consts::PI;
    let cv = n.dot(v);
    if cv < GLOSSY_COS_MIN || n.dot(w) <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha + omega / (8.0 * PI);
    let h = (w + v).normalize();
    let ch = n.dot(h).max(0.0);
    let t = ch * ch * (a2 - 1.0) + 1.0;
    let f = 1.0 + (1.0 / GLOSSY_F0 - 1.0) * (1.0 - v.dot(h).clamp(0.0, 1.0)).powi(5);
    omega * a2 / (PI * t * t) * f * smith_g1(alpha, cv) * smith_g1(alpha, n.dot(w)) / (4.0 * cv)
}

/// Smith's GGX masking of one direction at cosine `c` to the normal.
fn smith_g1(alpha: f32, c: f32) -> f32 {
    let a2 = alpha * alpha;
    2.0 * c / (c + (a2 + (1.0 - a2) * c * c).sqrt())
}

/// Light l's solid angle from x (0 from behind) and the unit direction to its centre.
fn light_seen(x: Vec3, l: &GpuLight) -> (f32, Vec3) {
    use std::f32::consts::PI;
    let (c, nl, area) = light_frame(l);
    let d = c - x;
    let d2 = d.length_squared().max(1e-6);
    let w = d / d2.sqrt();
    let cosl = -nl.dot(w);
    let omega = if cosl > 0.0 {
        (area * cosl / d2).min(2.0 * PI)
    } else {
        0.0
    };
    (omega, w)
}

/// Light l's radiance seen from x (normal n) from unit direction v through the lobe of GGX
/// roughness α.
pub fn lobe_light(x: Vec3, v: Vec3, n: Vec3, alpha: f32, l: &GpuLight) -> Vec3 {
    let (omega, w) = light_seen(x, l);
    if omega <= 0.0 {
        return Vec3::ZERO;
    }
    Vec3::from_slice(&l.radiance[..3]) * lobe_weight(alpha, omega, w, v, n)
}

/// Planes of the sums pass: Σ|X' − X̄'|² and Σ(X' − X̄')·(I − Ī) per lobe, (Σ|I − Ī|², views,
/// original lights seen, 0); X'_j = X_j − (1/GLOSSY_F0 − 1)·Ī·(1 − n·v_j)⁵, a coated
/// surface's regressor (`glossy_sums.comp`).
pub const SUM_PLANES: usize = 3;

/// The sums pass's running sums over the views that see a point.
/// g: a view's grazing term (1 − n·v)⁵.
#[derive(Default)]
struct Sums {
    x: [Vec3; LOBES],
    xx: [f32; LOBES],
    xi: [f32; LOBES],
    gx: [Vec3; LOBES],
    i: Vec3,
    ii: f32,
    gi: Vec3,
    g: f32,
    gg: f32,
    n: f32,
}

impl Sums {
    fn add(&mut self, col: Vec3, xs: [Vec3; LOBES], cos_v: f32) {
        let g = (1.0 - cos_v).powi(5);
        for (c, xc) in xs.into_iter().enumerate() {
            self.x[c] += xc;
            self.xx[c] += xc.dot(xc);
            self.xi[c] += xc.dot(col);
            self.gx[c] += g * xc;
        }
        self.i += col;
        self.ii += col.dot(col);
        self.gi += g * col;
        self.g += g;
        self.gg += g * g;
        self.n += 1.0;
    }

    /// The pixel's planes (`SUM_PLANES` vec4), None with fewer than GLOSSY_MIN_VIEWS views.
    #[allow(clippy::needless_range_loop)]
    fn planes(&self, seen: u32) -> Option<[[f32; 4]; SUM_PLANES]> {
        if self.n < GLOSSY_MIN_VIEWS as f32 {
            return None;
        }
        let k = 1.0 / GLOSSY_F0 - 1.0;
        let (im, gm) = (self.i / self.n, self.g / self.n);
        let zz = im.dot(im) * (self.gg - self.n * gm * gm);
        let zi = im.dot(self.gi - self.n * gm * im);
        let mut out = [[0f32; 4]; SUM_PLANES];
        for c in 0..LOBES {
            let xm = self.x[c] / self.n;
            let zx = im.dot(self.gx[c] - self.n * gm * xm);
            out[0][c] = (self.xx[c] - self.n * xm.dot(xm) - 2.0 * k * zx + k * k * zz).max(0.0);
            out[1][c] = self.xi[c] - self.n * xm.dot(im) - k * zi;
        }
        out[2] = [self.ii - self.n * im.dot(im), self.n, seen as f32, 0.0];
        Some(out)
    }
}

/// The pixels within `radius` of p (a square) on p's surface: a surface there, depth within
/// 5 % of p's, normals within ~25° (|cos| ≥ 0.9), as the shaders' windows test them.
fn same_surface<'a>(
    r: &'a RefInputs<'a>,
    p: usize,
    radius: i64,
) -> impl Iterator<Item = usize> + 'a {
    let (w, h) = (r.width as i64, r.height as i64);
    let (px, py, depth) = (p as i64 % w, p as i64 / w, r.gpos[p][3]);
    let n = Vec3::from_slice(&r.gnrm[p][..3]);
    (-radius..=radius)
        .flat_map(move |dy| (-radius..=radius).map(move |dx| (px + dx, py + dy)))
        .filter(move |&(qx, qy)| qx >= 0 && qy >= 0 && qx < w && qy < h)
        .map(move |(qx, qy)| (qy * w + qx) as usize)
        .filter(move |&q| {
            let d = r.gpos[q][3];
            let c = Vec3::from_slice(&r.gnrm[q][..3]).dot(n);
            d > 0.0 && (d - depth).abs() <= 0.05 * depth && c.abs() >= 0.9
        })
}

/// The normal mirror directions take at pixel p: the mean of the G-buffer normals (facing n)
/// over the 7×7 pixels on the same surface (`lobe.glsl`'s `smooth_normal`): a proxy's noisy
/// normals would scatter the highlights.
pub fn smooth_normal(r: &RefInputs, p: usize, n: Vec3) -> Vec3 {
    same_surface(r, p, 3)
        .map(|q| {
            let nq = Vec3::from_slice(&r.gnrm[q][..3]);
            if nq.dot(n) < 0.0 {
                -nq
            } else {
                nq
            }
        })
        .sum::<Vec3>()
        .normalize()
}

/// The original lights (at most MAX_ORIG) that x sees, as bits.
fn seen_originals(r: &RefInputs, mesh: &Mesh, x: Vec3, n: Vec3) -> u32 {
    (r.originals.iter().take(MAX_ORIG).enumerate())
        .filter(|(_, o)| sees_light(mesh, x, n, &o.light))
        .fold(0, |m, (l, _)| m | 1 << l)
}

/// The seen original lights through lobe c, seen from unit v over normal n.
fn lobe_originals(r: &RefInputs, seen: u32, (x, n): (Vec3, Vec3), v: Vec3, c: usize) -> Vec3 {
    (r.originals.iter().take(MAX_ORIG).enumerate())
        .filter(|(l, _)| seen & (1 << l) != 0)
        .map(|(_, o)| lobe_light(x, v, n, lobe_width(c), &o.light))
        .sum()
}

/// The active input views that see x and are not grazing (normal n within GLOSSY_COS_MIN of the
/// view): (view, unit direction to it, I_1's view weight 1/|eye − c_j|²).
fn views_seeing<'a>(
    r: &'a RefInputs<'a>,
    x: Vec3,
    n: Vec3,
) -> impl Iterator<Item = (usize, Vec3, f32)> + 'a {
    r.active.iter().filter_map(move |&j| {
        let j = j as usize;
        r.data.visible_pixel(j, x)?;
        let ci = r.data.cameras[j].center();
        let v = (ci - x).normalize();
        let e = r.eye - ci;
        (n.dot(v) >= GLOSSY_COS_MIN).then(|| (j, v, 1.0 / e.dot(e).max(1e-8)))
    })
}

/// Σ_c w_c·X̄_c at x (`glossy.comp`'s `photos_part`): the original lights seen (bits `seen`) through the
/// fitted lobes from each view that sees x, under I_1's view weights; zero under
/// GLOSSY_MIN_VIEWS views.
fn photos_part(r: &RefInputs, seen: u32, (x, n): (Vec3, Vec3), w: [f32; LOBES]) -> Vec3 {
    if seen == 0 {
        return Vec3::ZERO;
    }
    let (mut sx, mut sw, mut cnt) = (Vec3::ZERO, 0.0, 0);
    for (_, v, w1) in views_seeing(r, x, n) {
        let xs: Vec3 = (0..LOBES)
            .filter(|&c| w[c] > 0.0)
            .map(|c| w[c] * lobe_originals(r, seen, (x, n), v, c))
            .sum();
        sx += w1 * xs;
        sw += w1;
        cnt += 1;
    }
    if cnt < GLOSSY_MIN_VIEWS as usize {
        Vec3::ZERO
    } else {
        sx / sw
    }
}

/// CPU reference of the sums pass: `SUM_PLANES` planes of `width × height` vec4.
pub fn sums_reference(r: &RefInputs, mesh: &Mesh, comp: &[[f32; 4]]) -> Vec<[f32; 4]> {
    let npix = (r.width * r.height) as usize;
    let mut out = vec![[0f32; 4]; SUM_PLANES * npix];
    let (vw, vh) = (r.maps.width, r.maps.height);
    for p in 0..npix {
        let Some((x, n)) = r.surface(p).filter(|_| comp[p][..3] != [0.0; 3]) else {
            continue;
        };
        let n = smooth_normal(r, p, n);
        let seen = seen_originals(r, mesh, x, n);
        if seen == 0 {
            continue;
        }
        let mut sums = Sums::default();
        for (j, v, _) in views_seeing(r, x, n) {
            let px = super::reproject::project_px(r.data, j, x);
            let col = super::maps::sample_bilinear(&r.maps.img[j], vw, vh, px);
            let xs = [0, 1, 2].map(|c| lobe_originals(r, seen, (x, n), v, c));
            sums.add(col, xs, n.dot(v));
        }
        if let Some(planes) = sums.planes(seen) {
            for (k, v) in planes.into_iter().enumerate() {
                out[k * npix + p] = v;
            }
        }
    }
    out
}

/// What remains of the photos' own highlights at pixel p: 1 − α_dim, or with per-light factors
/// what remains of E_src there, 1 − E_rem / E_src (`glossy.comp`).
fn kept(r: &RefInputs, irr: &[[f32; 4]], p: usize) -> Vec3 {
    if !r.per_light() {
        return Vec3::splat(1.0 - r.alpha_dim);
    }
    let npix = (r.width * r.height) as usize;
    let es = Vec3::from_slice(&irr[p][..3]).max(Vec3::splat(crate::constants::E_FLOOR));
    (Vec3::ONE - Vec3::from_slice(&irr[2 * npix + p][..3]) / es).max(Vec3::ZERO)
}

/// The surface fit a pixel falls back on: the fit per triangle ([`super::glossy_fit`]: the
/// fits, then the surface normals) and the novel view's triangle ids (+1, 0: none).
pub struct SurfaceFit<'a> {
    pub per_tri: &'a [[f32; 4]],
    pub gtri: &'a [u32],
    /// The sight cache the frame read (None: every slot traces).
    pub sight: Option<CachedSight<'a>>,
}

/// The sight cache as a frame read it ([`super::sight_cache`]): its layout, its points' counts
/// and each slot's column ([`super::sight_cache::NO_COLUMN`]: none).
pub struct CachedSight<'a> {
    pub layout: &'a super::sight_cache::SightLayout,
    pub vis: &'a [u32],
    pub cols: &'a [u32],
}

impl CachedSight<'_> {
    /// The slots (of `nk`) that read the cache.
    fn cached(&self, nk: usize) -> u32 {
        (0..nk.min(self.cols.len()))
            .filter(|&k| self.cols[k] != super::sight_cache::NO_COLUMN)
            .fold(0, |m, k| m | 1 << k)
    }

    /// Bit k of `cached`: x (normal n) on triangle t faces slot k's light and sees half of it
    /// (`sight_cache.glsl`'s `cache_sight`); where the points around x disagree, x's own ray.
    fn bits(
        &self,
        mesh: &Mesh,
        lights: &[&GpuLight],
        cached: u32,
        t: usize,
        (x, n): (Vec3, Vec3),
    ) -> u32 {
        let w = self.layout.weights(mesh, t, x);
        let half = 0.5 * SIGHT_CACHE_SAMPLES as f32;
        (0..lights.len())
            .filter(|&k| cached >> k & 1 == 1 && super::sight::faces_light(x, n, lights[k]))
            .filter(|&k| {
                let (col, sharp) = (self.cols[k] & 0xFF, self.cols[k] & SHARP != 0);
                let count = |p: u32| super::sight_cache::count(self.vis, p, col);
                let said: Vec<f32> = (w.iter().filter(|p| p.1 > 0.0))
                    .map(|p| count(p.0))
                    .collect();
                let top = said.iter().fold(-1f32, |m, &c| m.max(c));
                let bottom = said.iter().fold(1e9f32, |m, &c| m.min(c));
                match sharp && top >= half && bottom < half && top - bottom >= half {
                    true => sees_light(mesh, x, n, lights[k]),
                    false => w.iter().map(|p| p.1 * count(p.0)).sum::<f32>() >= half,
                }
            })
            .fold(0, |m, k| m | 1 << k)
    }
}

impl SurfaceFit<'_> {
    /// Pixel p's surface: its strengths and its surface normal (zero: none).
    fn at(&self, p: usize) -> Option<([f32; LOBES], Vec3)> {
        let t = (*self.gtri.get(p)? as usize).checked_sub(1)?;
        let f = self.per_tri.get(t)?;
        let n = self.per_tri.get(self.per_tri.len() / 2 + t)?;
        Some(([f[0], f[1], f[2]], Vec3::new(n[0], n[1], n[2])))
    }
}

/// CPU reference of the layer pass: 2 planes of `width × height` vec4, from the frame's
/// composites (I_1, I_8) and irradiance planes (E_src, E_add, E_rem) as the passes wrote them,
/// and the surface fit.
pub fn reference(
    r: &RefInputs,
    mesh: &Mesh,
    comp: &[[f32; 4]],
    irr: &[[f32; 4]],
    fit: &SurfaceFit,
) -> Vec<[f32; 4]> {
    let npix = (r.width * r.height) as usize;
    let mut out = vec![[0f32; 4]; PLANES * npix];
    // The fitted pixels: (x, smoothed n) and the surface's strengths.
    let fitted: Vec<Option<(Vec3, Vec3, [f32; LOBES])>> = (0..npix)
        .map(|p| {
            let i1 = Vec3::from_slice(&comp[p][..3]);
            let (x, n) = r.surface(p).filter(|_| i1 != Vec3::ZERO)?;
            out[p] = [i1.x, i1.y, i1.z, 0.0];
            let (w, ns) = fit.at(p).filter(|(w, _)| w.iter().any(|&v| v > 0.0))?;
            let n = match ns == Vec3::ZERO {
                true => smooth_normal(r, p, n),
                false => ns * ns.dot(n).signum(),
            };
            Some((x, n, w))
        })
        .collect();
    let pts: Vec<_> = fitted.iter().map(|f| f.map(|(x, n, _)| (x, n))).collect();
    let lights = sight_lights(r, MAX_ORIG);
    let cached = fit.sight.as_ref().map_or(0, |c| c.cached(lights.len()));
    let mut seen = shared_sight(mesh, &lights, &pts, r.width as usize, cached);
    if let Some(c) = &fit.sight {
        for (p, pt) in pts.iter().enumerate() {
            if let (Some(xn), Some(t)) = (*pt, fit.gtri[p].checked_sub(1)) {
                seen[p] |= c.bits(mesh, &lights, cached, t as usize, xn);
            }
        }
    }
    let no = r.originals.len().min(MAX_ORIG);
    for (p, f) in fitted.iter().enumerate() {
        let Some((x, n, mut w)) = *f else {
            continue;
        };
        let i1 = Vec3::from_slice(&comp[p][..3]);
        // At most GLOSSY_SHARE of I_1's luminance is called view-dependent, and D stays at or
        // above the darkest photo (I_8).
        let xm = photos_part(r, seen[p] & ((1 << no) - 1), (x, n), w);
        let lum = super::reproject::luminance;
        let cap = (GLOSSY_SHARE * lum(i1) / lum(xm).max(1e-8)).min(1.0);
        w = w.map(|v| v * cap);
        let i8 = Vec3::from_slice(&comp[7 * npix + p][..3]);
        let d = (i1 - cap * xm).max(i8.min(i1)).max(Vec3::ZERO);
        let so = seen[p] & ((1 << no) - 1);
        let v = (r.eye - x).normalize();
        let here: Vec3 = (0..LOBES)
            .filter(|&c| w[c] > 0.0)
            .map(|c| w[c] * lobe_originals(r, so, (x, n), v, c))
            .sum();
        let own = (i1 - d + here - cap * xm).max(Vec3::ZERO);
        let st = kept(r, irr, p) * own + lamps(r, mesh, (x, n), w, seen[p]);
        let lead = (0..LOBES).fold(0, |b, c| if w[c] > w[b] { c } else { b });
        out[p] = [d.x, d.y, d.z, w.iter().sum()];
        out[npix + p] = [st.x, st.y, st.z, (lead + 1) as f32];
    }
    out
}

/// Σ_L i_L Σ_c w_c·X_L,c: the lit lamps x sees (slot bits `seen`, [`super::sight`]; lamps past
/// its slots trace their own ray) through the lobes around the novel view's mirror direction.
fn lamps(r: &RefInputs, mesh: &Mesh, (x, n): (Vec3, Vec3), w: [f32; LOBES], seen: u32) -> Vec3 {
    let v = (r.eye - x).normalize();
    let mut s = Vec3::ZERO;
    let mut k = r.originals.len().min(MAX_ORIG);
    for (l, e) in r.emitters.iter().enumerate() {
        let i = r.intensities.get(l).copied().unwrap_or(0.0);
        if i <= 0.0 {
            continue;
        }
        let sees = match k < SIGHT_MAX {
            true => seen & 1 << k != 0,
            false => sees_light(mesh, x, n, e),
        };
        k += 1;
        if sees {
            for c in (0..LOBES).filter(|&c| w[c] > 0.0) {
                s += w[c] * i * lobe_light(x, v, n, lobe_width(c), e);
            }
        }
    }
    s
}

/// CPU reference of glossy mode from the glossy planes and the irradiance planes:
/// `D / max(E_src, E_FLOOR) · (E_add + E_src − E_rem) + S`.
pub fn reference_image(glossy: &[[f32; 4]], irr: &[[f32; 4]], npix: usize) -> Vec<[f32; 3]> {
    (0..npix)
        .map(|p| {
            let (d, s) = (glossy[p], glossy[npix + p]);
            let (es, ea, er) = (irr[p], irr[npix + p], irr[2 * npix + p]);
            [0, 1, 2].map(|k| {
                d[k] / es[k].max(crate::constants::E_FLOOR) * (ea[k] + es[k] - er[k]) + s[k]
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Smith's masking is GGX's own: the microfacets' projected area towards any view equals
    /// the surface's, ∫ G1(v)·D(h)·max(v·h, 0) dω_h = n·v (Heitz 2014, eq. 2 with 17).
    #[test]
    fn smith_masking_matches_the_ggx_distribution() {
        use std::f32::consts::PI;
        let (nt, np) = (2000, 200);
        for alpha in [0.04f32, 0.12, 0.25, 0.5] {
            for cv in [0.95f32, 0.6, 0.3, 0.1] {
                let v = Vec3::new((1.0 - cv * cv).sqrt(), cv, 0.0);
                let a2 = alpha * alpha;
                let mut sum = 0.0f64;
                for i in 0..nt {
                    // θ_h over [0, π/2) in tan-space steps that follow the lobe's width.
                    let (u0, u1) = (i as f32 / nt as f32, (i + 1) as f32 / nt as f32);
                    let th = |u: f32| match u < 1.0 {
                        true => (alpha * (u * 0.5 * PI).tan()).atan(),
                        false => 0.5 * PI,
                    };
                    let (t0, t1) = (th(u0), th(u1));
                    let t = 0.5 * (t0 + t1);
                    let ch = t.cos();
                    let d = a2 / (PI * (ch * ch * (a2 - 1.0) + 1.0).powi(2));
                    for j in 0..np {
                        let ph = (j as f32 + 0.5) / np as f32 * 2.0 * PI;
                        let h = Vec3::new(t.sin() * ph.cos(), ch, t.sin() * ph.sin());
                        let dw = t.sin() * (t1 - t0) * 2.0 * PI / np as f32;
                        sum += (d * v.dot(h).max(0.0) * dw) as f64;
                    }
                }
                let got = smith_g1(alpha, cv) as f64 * sum;
                assert!(
                    (got - cv as f64).abs() < 0.01 * cv as f64,
                    "α {alpha}, n·v {cv}: {got}"
                );
            }
        }
    }

    /// A coated surface (F0 0.04) photographed from views 0.3–0.95 off grazing, its views nearer
    /// the light's mirror direction the steeper ones: its diffuse part darkens towards grazing
    /// views by (1 − F). The sums' slope reads its F0 whether the photos show the light's
    /// highlight or hardly (X alone read 0.10 and 5.9 there), and a matte surface's as none.
    #[test]
    fn the_sums_read_a_coated_surfaces_f0_from_its_darkening_and_its_highlights() {
        let f0 = 0.04;
        let slope = |x_scale: f32, coat: f32| {
            let (mut sums, mut plain) = (Sums::default(), [0.0f32; 4]);
            for j in 0..10 {
                let c = 0.3 + 0.65 * j as f32 / 9.0;
                let x = x_scale * c.powi(4);
                let fresnel = f0 + (1.0 - f0) * (1.0 - c).powi(5);
                let i = 0.1 * (1.0 - coat * fresnel) + coat * f0 * x;
                sums.add(Vec3::splat(i), [Vec3::ZERO, Vec3::splat(x), Vec3::ZERO], c);
                plain = [
                    plain[0] + x,
                    plain[1] + i,
                    plain[2] + x * x,
                    plain[3] + x * i,
                ];
            }
            let p = sums.planes(0).unwrap();
            let [sx, si, sxx, sxi] = plain;
            (
                p[1][1] / p[0][1],
                (sxi - sx * si / 10.0) / (sxx - sx * sx / 10.0),
            )
        };
        for x_scale in [0.2, 0.002] {
            let (s, plain) = slope(x_scale, 1.0);
            assert!(
                (s - f0).abs() < 0.15 * f0,
                "X × {x_scale}: {s} (X alone {plain})"
            );
            assert!(plain > 1.5 * f0, "{plain}");
        }
        let (s, _) = slope(0.2, 0.0);
        assert!(s.abs() < 1e-4, "matte: {s}");
    }
}
