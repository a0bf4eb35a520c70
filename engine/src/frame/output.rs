//! The frame's output (§5.2): `shaders_glsl/frame/output.glsl`. Network mode sums the diffuse
//! and view-dependent outputs in tonemapped space and inverts the tonemap; ULR mode shows the
//! `I_1` composite; ratio mode relights it with eq. 5's pseudo-albedo rule. Linear HDR for EXR, exposure + sRGB in 8 bits for screens and PNG.
//! In every mode, lit added lights in front of the surface are drawn, and declared original
//! lights on it, dimmed by α_dim (`frame/emitters.glsl`, [`super::emitters`]). Its push
//! constants are the frame's ([`super::FrameConstants`]: the mode, exposure, hole fill and the
//! network's configuration among them); the novel camera it casts rays from comes in the
//! `NovelCamera` buffer ([`super::FrameBuffers::camera`]), too large for them.

use crate::constants::{E_FLOOR, GAIN_EPS};
use crate::gpu::shaders;

pub const SHADER_F16: crate::gpu::Shader = shaders::FRAME_OUTPUT;
pub const SHADER_F32: crate::gpu::Shader = shaders::FRAME_OUTPUT_F32;

/// sRGB transfer function of a linear value, clamped to [0, 1].
pub fn srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.0031308 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// What a base-"ratio" network's configuration does to its corrections on covered pixels
/// ([`crate::net::NetConfig`]'s `shrink`, `gate`, `gain` and `agree`; `model.py`'s output keys).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Corrections {
    pub shrink: f32,
    pub gate: f32,
    pub gain: bool,
    pub agree: f32,
}

/// CPU reference of network mode: linear RGB per pixel from the 6 output channels (planar CHW,
/// `width` pixels a row), black where `has_surface` is false. With `ratio_input` (the
/// network's 66-channel input, planar CHW), the diffuse channels correct [`ratio_base`] (a
/// network with base "ratio"), each correction soft-thresholded by `shrink`, then scaled by
/// [`gate_weight`] with `gate` and by [`agreement_weights`] with `agree`, where I_1 is not
/// black; with `gain` the diffuse correction there becomes a gain on the base ([`gained`]).
/// (Where the scale is 0 the GPU pass takes ratio mode's own arithmetic, [`reference_ratio`];
/// this reference's ratio base from the input tensor equals it up to the tensor's storage
/// precision.)
pub fn reference_network(
    net_out: &[f32],
    ratio_input: Option<&[f32]>,
    c: Corrections,
    width: usize,
    has_surface: &[bool],
) -> Vec<[f32; 3]> {
    reference_network_on(net_out, ratio_input, None, c, width, has_surface)
}

/// [`reference_network`] with the base given: with `base_image` (linear, per pixel: glossy
/// mode's image, a network with base "glossy") the diffuse channels correct tm of it instead of
/// the ratio base; the keys read `input` as for base "ratio".
pub fn reference_network_on(
    net_out: &[f32],
    ratio_input: Option<&[f32]>,
    base_image: Option<&[[f32; 3]]>,
    c: Corrections,
    width: usize,
    has_surface: &[bool],
) -> Vec<[f32; 3]> {
    use super::features::{tonemap, untonemap};
    let npix = has_surface.len();
    let agreement = match ratio_input {
        Some(x) if c.agree > 0.0 => agreement_weights(x, width, npix / width, c.agree),
        _ => vec![1.0; npix],
    };
    (0..npix)
        .map(|p| {
            if !has_surface[p] {
                return [0.0; 3];
            }
            let base = match (base_image, ratio_input) {
                (Some(g), _) => g[p].map(tonemap),
                (None, Some(x)) => ratio_base(x, npix, p),
                (None, None) => [0.0; 3],
            };
            let covered = ratio_input.is_some_and(|x| (0..3).any(|k| x[k * npix + p] != 0.0));
            let (t, w) = match ratio_input {
                Some(x) if covered => (c.shrink, gate_weight(x, npix, p, c.gate) * agreement[p]),
                _ => (0.0, 1.0),
            };
            let d = [0, 1, 2].map(|k| soft_threshold(net_out[k * npix + p], t));
            let v = [0, 1, 2].map(|k| w * soft_threshold(net_out[(k + 3) * npix + p], t));
            let diffuse = match c.gain && covered {
                true => gained(base, d, w),
                false => [0, 1, 2].map(|k| base[k] + w * d[k]),
            };
            [0, 1, 2].map(|k| untonemap(diffuse[k] + v[k]))
        })
        .collect()
}

/// `gain`'s diffuse image (tonemapped): tm(untm(B)·exp(w·g)), g the log ratio of the RGB means
/// of untm(B + d) and untm(B), each plus GAIN_EPS; the ratio base B's colour is kept.
pub fn gained(base: [f32; 3], d: [f32; 3], w: f32) -> [f32; 3] {
    use super::features::{tonemap, untonemap};
    let mean = |c: [f32; 3]| c.iter().map(|&v| untonemap(v)).sum::<f32>() / 3.0;
    let lit = mean([0, 1, 2].map(|k| base[k] + d[k]));
    let g = (lit + GAIN_EPS).ln() - (mean(base) + GAIN_EPS).ln();
    base.map(|b| tonemap(untonemap(b) * (w * g).exp()))
}

/// f at pixel `p` from the network input (planar CHW): max over RGB of
/// E_add / (E_src − E_rem + E_add), the new light's share of the pixel's light, the denominator
/// floored as [`ratio_base`] floors E_src; 0 where no lamp reaches the pixel (`model.py`'s
/// `new_light_share`, `output.glsl`'s).
pub fn new_light_share(x: &[f32], npix: usize, p: usize) -> f32 {
    (0..3)
        .map(|k| {
            let (es, ea, er) = input_irradiance(x, npix, p, k);
            ea / (es - er + ea).max(ES_FLOOR)
        })
        .fold(0.0, f32::max)
}

/// E_src, E_add, E_rem (/π, untonemapped) of colour channel `k` at pixel `p` from the network
/// input (channels 51–59), as the ratio base and the gate read them.
fn input_irradiance(x: &[f32], npix: usize, p: usize, k: usize) -> (f32, f32, f32) {
    let ch = |c: usize| super::features::untonemap(x[c * npix + p]);
    (ch(51 + k), ch(54 + k), ch(57 + k))
}

/// E_src/π's floor in the input tensor's terms: ratio mode floors E_src at E_FLOOR.
const ES_FLOOR: f32 = E_FLOOR / std::f32::consts::PI;

/// The scale of a covered pixel's corrections under `gate` G: min(1, f / G); 1 when G is 0.
pub fn gate_weight(x: &[f32], npix: usize, p: usize, gate: f32) -> f32 {
    if gate > 0.0 {
        (new_light_share(x, npix, p) / gate).min(1.0)
    } else {
        1.0
    }
}

/// D of `agree` at every pixel of the network input (planar CHW, `width`×`height`): at each
/// pixel the mean over the layers I_2..I_8 that cover it together with I_1 of the RGB mean of
/// |I_k − I_1| (channels 0–23, tonemapped), 0 where none does; then the 5-tap binomial filter
/// [1 4 6 4 1]/16 across rows and columns, edge pixels repeated (`model.py`'s `disagreement`).
pub fn disagreement(x: &[f32], width: usize, height: usize) -> Vec<f32> {
    let npix = width * height;
    let layer = |k: usize, p: usize| [0, 1, 2].map(|c| x[(3 * k + c) * npix + p]);
    let per_pixel: Vec<f32> = (0..npix)
        .map(|p| {
            let i1 = layer(0, p);
            let (mut sum, mut n) = (0.0, 0.0);
            for k in 1..8 {
                let ik = layer(k, p);
                if i1.iter().any(|&v| v != 0.0) && ik.iter().any(|&v| v != 0.0) {
                    sum += (0..3).map(|c| (ik[c] - i1[c]).abs()).sum::<f32>() / 3.0;
                    n += 1.0;
                }
            }
            if n > 0.0 {
                sum / n
            } else {
                0.0
            }
        })
        .collect();
    let rows = binomial5(&per_pixel, width, height, 1, 0);
    binomial5(&rows, width, height, 0, 1)
}

/// The 5-tap binomial filter along (dx, dy), clamped at the edges.
fn binomial5(v: &[f32], width: usize, height: usize, dx: i64, dy: i64) -> Vec<f32> {
    const W: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
    let at = |x: i64, y: i64| {
        let (x, y) = (x.clamp(0, width as i64 - 1), y.clamp(0, height as i64 - 1));
        v[y as usize * width + x as usize]
    };
    (0..width * height)
        .map(|p| {
            let (x, y) = ((p % width) as i64, (p / width) as i64);
            (0..5i64)
                .map(|t| W[t as usize] * at(x + (t - 2) * dx, y + (t - 2) * dy))
                .sum()
        })
        .collect()
}

/// `agree`'s scale of each pixel's corrections: min(1, D / A), D from [`disagreement`].
pub fn agreement_weights(x: &[f32], width: usize, height: usize, agree: f32) -> Vec<f32> {
    disagreement(x, width, height)
        .into_iter()
        .map(|d| (d / agree).min(1.0))
        .collect()
}

/// sign(c)·max(|c| − τ, 0): a network's correction under `shrink` (`model.py`).
pub fn soft_threshold(c: f32, tau: f32) -> f32 {
    c.signum() * (c.abs() - tau).max(0.0)
}

/// tm of eq. 5's ratio image at pixel `p` from the network input (planar CHW): I_1 (channels
/// 0–2) / E_src · (E_add + E_src − E_rem) (51–59, stored /π), E_src/π floored at E_FLOOR/π —
/// `model.py`'s `ratio_base` and `output.glsl`'s.
pub fn ratio_base(x: &[f32], npix: usize, p: usize) -> [f32; 3] {
    use super::features::{tonemap, untonemap};
    [0, 1, 2].map(|k| {
        let (es, ea, er) = input_irradiance(x, npix, p, k);
        tonemap(untonemap(x[k * npix + p]) / es.max(ES_FLOOR) * (ea + es - er))
    })
}

/// CPU reference of ratio mode from the composites and irradiance planes (as the passes wrote
/// them): `I_1 / max(E_src, E_FLOOR) · (E_add + E_src − E_rem)`.
pub fn reference_ratio(comp: &[[f32; 4]], irr: &[[f32; 4]], npix: usize) -> Vec<[f32; 3]> {
    (0..npix)
        .map(|p| {
            let (i, es, ea, er) = (comp[p], irr[p], irr[npix + p], irr[2 * npix + p]);
            [0, 1, 2].map(|k| i[k] / es[k].max(E_FLOOR) * (ea[k] + es[k] - er[k]))
        })
        .collect()
}

/// CPU reference of ratio-filled mode: `ratio` where the composite `I_1` is not black, else
/// `network` (both as [`reference_ratio`] and [`reference_network`] give them).
pub fn reference_ratio_filled(
    comp: &[[f32; 4]],
    ratio: &[[f32; 3]],
    network: &[[f32; 3]],
) -> Vec<[f32; 3]> {
    (0..ratio.len())
        .map(|p| {
            let hole = comp[p][..3].iter().all(|&c| c == 0.0);
            if hole {
                network[p]
            } else {
                ratio[p]
            }
        })
        .collect()
}

/// Pixels a hole fill searches along each of its 8 directions (`output.glsl`'s `hole_fill`).
pub const FILL_RADIUS: i64 = 12;

/// CPU reference of the hole fill: each pixel with a surface that no input view covers takes
/// the mean of `image` at the first covered pixel along each of the 8 directions (rows,
/// columns, diagonals) within FILL_RADIUS; it keeps its value where none is found.
pub fn fill_holes(
    image: &[[f32; 3]],
    covered: &[bool],
    surface: &[bool],
    width: usize,
) -> Vec<[f32; 3]> {
    let height = (image.len() / width) as i64;
    let w = width as i64;
    (0..image.len())
        .map(|p| {
            if !surface[p] || covered[p] {
                return image[p];
            }
            let (x, y) = (p as i64 % w, p as i64 / w);
            let (mut sum, mut n) = ([0f32; 3], 0.0);
            for (dx, dy) in [
                (1, 0),
                (-1, 0),
                (0, 1),
                (0, -1),
                (1, 1),
                (-1, 1),
                (1, -1),
                (-1, -1),
            ] {
                let found = (1..=FILL_RADIUS)
                    .map(|k| (x + k * dx, y + k * dy))
                    .take_while(|&(qx, qy)| qx >= 0 && qy >= 0 && qx < w && qy < height)
                    .map(|(qx, qy)| (qy * w + qx) as usize)
                    .find(|&q| covered[q]);
                if let Some(q) = found {
                    (0..3).for_each(|c| sum[c] += image[q][c]);
                    n += 1.0;
                }
            }
            if n > 0.0 {
                sum.map(|v| v / n)
            } else {
                image[p]
            }
        })
        .collect()
}

/// The display value (8-bit sRGB) of a linear colour at `exposure`.
pub fn display(c: [f32; 3], exposure: f32) -> [u8; 3] {
    c.map(|v| (srgb(v * exposure) * 255.0).round() as u8)
}
