//! Irradiance composites `E_src`, `E_add`, `E_rem` (§4.3.3): `shaders_glsl/frame/irradiance.comp`.
//! Its push constants are the frame's ([`super::FrameConstants`]).

use crate::gpu::shaders;
use glam::Vec3;

use super::maps::sample_bilinear;
use super::reproject::project_px;
use super::RefInputs;

pub const SHADER: crate::gpu::Shader = shaders::FRAME_IRRADIANCE;
pub const PLANES: usize = 3;

/// CPU reference: 3 planes (E_src, E_add, E_rem) of `width × height` vec4.
pub fn reference(r: &RefInputs) -> Vec<[f32; 4]> {
    let npix = (r.width * r.height) as usize;
    let mut out = vec![[0f32; 4]; PLANES * npix];
    let (vw, vh) = (r.maps.width, r.maps.height);
    let nviews = r.data.cameras.len();
    for p in 0..npix {
        let Some((x, n)) = r.surface(p) else { continue };
        let (mut es, mut ea, mut er, mut sw) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, 0f32);
        for &j in r.active {
            let j = j as usize;
            if r.data.visible_pixel(j, x).is_none() {
                continue;
            }
            let px = project_px(r.data, j, x);
            let w = 1.0 / r.data.cameras[j].center().distance(r.eye).max(1e-3);
            let esj = sample_bilinear(&r.maps.esrc[j], vw, vh, px);
            es += w * esj;
            if r.per_light() {
                er += w * esj * r.removed_share(j, px);
            }
            let mut add = Vec3::ZERO;
            for (l, &s) in r.intensities.iter().enumerate() {
                if s != 0.0 && !r.live.as_ref().is_some_and(|v| v.is_live(l)) {
                    add += s * sample_bilinear(&r.maps.eadd[l * nviews + j], vw, vh, px);
                }
            }
            ea += w * add;
            sw += w;
        }
        if sw > 0.0 {
            let live = match &r.live {
                Some(v) if v.gtri[p] > 0 => {
                    v.eadd(r.intensities, x, n, v.gtri[p] as usize - 1, p as u32)
                }
                _ => Vec3::ZERO,
            };
            let mut c = r.alpha_dim * es / sw;
            if r.per_light() {
                c += (1.0 - r.alpha_dim) * er / sw;
            }
            let (a, b) = (es / sw, ea / sw + live);
            out[p] = [a.x, a.y, a.z, 1.0];
            out[npix + p] = [b.x, b.y, b.z, 1.0];
            out[2 * npix + p] = [c.x, c.y, c.z, 1.0];
        }
    }
    out
}
