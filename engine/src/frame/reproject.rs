//! Reprojected composites `I_1..8`, `M_src_1..8` (§4.3.1–4.3.2): `shaders_glsl/frame/reproject.comp`.
//! Its push constants are the frame's ([`super::FrameConstants`]).

use crate::gpu::shaders;
use glam::Vec3;

use super::maps::sample_bilinear;
use super::RefInputs;
use crate::bake::ViewData;

pub const SHADER: crate::gpu::Shader = shaders::FRAME_REPROJECT;
/// Planes of the output: I_1..8 then M_src_1..8.
pub const PLANES: usize = 16;

pub(crate) fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

pub(crate) fn project_px(d: &ViewData, j: usize, p: Vec3) -> glam::Vec2 {
    let c = &d.cameras[j];
    let q = c.to_camera(p);
    glam::Vec2::new(c.fx * q.x / q.z + c.cx, c.fy * q.y / q.z + c.cy)
}

/// CPU reference of the pass's views-seen bits: per pixel, bit a (of two words) where active
/// view a sees its surface point, as the glossy layer reads them.
pub fn views_seen_reference(r: &RefInputs) -> Vec<[u32; 2]> {
    let npix = (r.width * r.height) as usize;
    (0..npix)
        .map(|p| {
            let Some((x, _)) = r.surface(p) else {
                return [0; 2];
            };
            let mut bits = [0u32; 2];
            for (a, &j) in r.active.iter().enumerate() {
                if r.data.visible_pixel(j as usize, x).is_some() {
                    bits[a / 32] |= 1 << (a % 32);
                }
            }
            bits
        })
        .collect()
}

/// CPU reference: 16 planes of `width × height` vec4 (w = 1 where defined).
pub fn reference(r: &RefInputs) -> Vec<[f32; 4]> {
    let npix = (r.width * r.height) as usize;
    let mut out = vec![[0f32; 4]; PLANES * npix];
    let (vw, vh) = (r.maps.width, r.maps.height);
    for p in 0..npix {
        let Some((x, n)) = r.surface(p) else { continue };
        let dn = (r.eye - x).normalize();
        let (mut si, mut sm, mut sw) = ([Vec3::ZERO; 4], [Vec3::ZERO; 4], [0f32; 4]);
        let mut seen: Vec<(f32, u32)> = Vec::new();
        for &j in r.active {
            let ju = j as usize;
            if r.data.visible_pixel(ju, x).is_none() {
                continue;
            }
            let px = project_px(r.data, ju, x);
            let col = sample_bilinear(&r.maps.img[ju], vw, vh, px);
            let mir = sample_bilinear(&r.maps.msrc[ju], vw, vh, px);
            let ci = r.data.cameras[ju].center();
            let d = ci - x;
            let dl = d.length();
            let e = r.eye - ci;
            let cw = dn.dot(d / dl);
            let w = [
                1.0 / e.dot(e).max(1e-8),
                cw * cw,
                1.0 / (dl * dl).max(1e-8),
                (d.dot(n) / (0.1 * dl)).exp() - 1.0,
            ];
            for k in 0..4 {
                si[k] += w[k] * col;
                sm[k] += w[k] * mir;
                sw[k] += w[k];
            }
            seen.push((luminance(col), j));
        }
        for k in 0..4 {
            if sw[k] > 0.0 {
                let a = si[k] / sw[k];
                let b = sm[k] / sw[k];
                out[k * npix + p] = [a.x, a.y, a.z, 1.0];
                out[(8 + k) * npix + p] = [b.x, b.y, b.z, 1.0];
            }
        }
        if seen.is_empty() {
            continue;
        }
        seen.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let c = seen.len();
        let pick = [c - 1, c.saturating_sub(2), (c - 1) / 2, 0];
        for (k, &i) in pick.iter().enumerate() {
            let j = seen[i].1 as usize;
            let px = project_px(r.data, j, x);
            let a = sample_bilinear(&r.maps.img[j], vw, vh, px);
            let b = sample_bilinear(&r.maps.msrc[j], vw, vh, px);
            out[(4 + k) * npix + p] = [a.x, a.y, a.z, 1.0];
            out[(12 + k) * npix + p] = [b.x, b.y, b.z, 1.0];
        }
    }
    out
}
