//! Target mirror image `M_tgt` (§4.2.2, eq. 5): `shaders_glsl/frame/target_mirror.comp`.
//! Its push constants are the frame's ([`super::FrameConstants`]).

use crate::gpu::shaders;
use glam::Vec3;

use super::RefInputs;
use crate::scene::Mesh;

pub const SHADER: crate::gpu::Shader = shaders::FRAME_TARGET_MIRROR;

/// CPU reference: vec4 per pixel (rgb, reflected distance; a lit added light met first gives
/// its radiance, a declared original light at the hit its dimmed glow).
pub fn reference(r: &RefInputs, mesh: &Mesh) -> Vec<[f32; 4]> {
    let npix = (r.width * r.height) as usize;
    let nviews = r.data.cameras.len();
    let vpix = r.data.pixels();
    let v3 = |p: [f32; 4]| Vec3::new(p[0], p[1], p[2]);
    (0..npix)
        .map(|p| {
            let Some((x, n)) = r.surface(p) else {
                return [0.0; 4];
            };
            let v = (x - r.eye).normalize();
            let rd = v - 2.0 * n.dot(v) * n;
            let o = x + n * 1e-3;
            let hit = crate::cpu::closest_hit(mesh, o, rd, 1e-3, 1e4);
            let t = hit.as_ref().map_or(1e30, |h| h.t);
            if let Some((le, tl)) =
                super::emitters::nearest_emitter(r.emitters, r.intensities, o, rd, t)
            {
                return [le.x, le.y, le.z, tl];
            }
            let Some(h) = hit else {
                return [0.0; 4];
            };
            let y = o + rd * h.t;
            let skip = r.exclude.map_or(usize::MAX, |e| e as usize);
            let q = r.data.best_view(y, rd, skip);
            let (j, qp) = q.map_or((0, 0), |q| (q / vpix, q % vpix));
            let mut ea = Vec3::ZERO;
            for (l, &s) in r.intensities.iter().enumerate() {
                let live = r.live.as_ref().is_some_and(|v| v.is_live(l));
                if q.is_some() && s != 0.0 && !live {
                    ea += s * v3(r.maps.eadd[l * nviews + j][qp]);
                }
            }
            if let Some(v) = &r.live {
                let mut ny = mesh.face_normal(h.tri as usize);
                if ny.dot(rd) > 0.0 {
                    ny = -ny;
                }
                ea += v.eadd(r.intensities, y, ny, h.tri as usize, p as u32);
            }
            let col = q.map_or(Vec3::ZERO, |_| v3(r.maps.img[j][qp]));
            let glow = super::emitters::original_light(r.originals, r.dim(), (y, rd), col, ea, 0.0);
            if let Some(le) = glow {
                return [le.x, le.y, le.z, y.distance(x)];
            }
            if q.is_none() {
                return [0.0; 4];
            }
            let es = v3(r.maps.esrc[j][qp]);
            let mut rem = r.alpha_dim * es;
            if r.per_light() {
                let px = glam::Vec2::new(
                    (qp % r.maps.width as usize) as f32 + 0.5,
                    (qp / r.maps.width as usize) as f32 + 0.5,
                );
                rem += (1.0 - r.alpha_dim) * es * r.removed_share(j, px);
            }
            let m = col / es.max(Vec3::splat(crate::constants::E_FLOOR)) * (ea + es - rem);
            [m.x, m.y, m.z, y.distance(x)]
        })
        .collect()
}
