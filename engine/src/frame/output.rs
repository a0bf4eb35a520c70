//! The frame's output (§5.2): `shaders_glsl/frame/output.glsl`. Network mode sums the diffuse
//! and view-dependent outputs in tonemapped space and inverts the tonemap; ULR mode shows the
//! `I_1` composite; ratio mode relights it with eq. 5's pseudo-albedo rule. Linear HDR for EXR, exposure + sRGB in 8 bits for screens and PNG.
//! In every mode, lit added lights in front of the surface are drawn, and declared original
//! lights on it, dimmed by α_dim (`frame/emitters.glsl`).

use crate::gpu::shaders;
use glam::Vec3;

use crate::bake::GpuLight;
use crate::constants::{E_FLOOR, LEAK_PX, LIGHT_SKIN};
use crate::scene::{Camera, GpuCamera, Light, Mesh};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Push {
    pub width: u32,
    pub height: u32,
    pub mode: u32,
    pub exposure: f32,
    pub cam: GpuCamera,
    pub nlights: u32,
    /// [`crate::net::NetBase`]: 0 none, 1 ratio.
    pub base: u32,
    /// [`crate::net::NetConfig::shrink`].
    pub shrink: f32,
    /// [`crate::net::NetConfig::gate`].
    pub gate: f32,
    /// Declared original lights (drawn where seen, dimmed).
    pub norig: u32,
    pub alpha_dim: f32,
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    Push,
    [shaders::FRAME_OUTPUT, shaders::FRAME_OUTPUT_F32],
    [
        width,
        height,
        mode,
        exposure,
        cam.r0,
        cam.r1,
        cam.r2,
        cam.intrinsics,
        cam.size_clip,
        nlights,
        base,
        shrink,
        gate,
        norig,
        alpha_dim
    ]
);

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

/// CPU reference of network mode: linear RGB per pixel from the 6 output channels (planar CHW),
/// black where `has_surface` is false. With `ratio_input` (the network's 66-channel input,
/// planar CHW), the diffuse channels correct [`ratio_base`] (a network with base "ratio"),
/// each correction soft-thresholded by `shrink`, then scaled by [`gate_weight`] with `gate`,
/// where I_1 is not black. (Where the gate is closed the GPU pass takes ratio mode's own
/// arithmetic, [`reference_ratio`]; this reference's ratio base from the input tensor equals it
/// up to the tensor's storage precision.)
pub fn reference_network(
    net_out: &[f32],
    ratio_input: Option<&[f32]>,
    (shrink, gate): (f32, f32),
    npix: usize,
    has_surface: &[bool],
) -> Vec<[f32; 3]> {
    (0..npix)
        .map(|p| {
            if !has_surface[p] {
                return [0.0; 3];
            }
            let base = ratio_input.map_or([0.0; 3], |x| ratio_base(x, npix, p));
            let covered = ratio_input.is_some_and(|x| (0..3).any(|k| x[k * npix + p] != 0.0));
            let (t, w) = match ratio_input {
                Some(x) if covered => (shrink, gate_weight(x, npix, p, gate)),
                _ => (0.0, 1.0),
            };
            let c = |k: usize| {
                let (d, v) = (net_out[k * npix + p], net_out[(k + 3) * npix + p]);
                let o = base[k] + w * (soft_threshold(d, t) + soft_threshold(v, t));
                super::features::untonemap(o)
            };
            [c(0), c(1), c(2)]
        })
        .collect()
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

/// The display value (8-bit sRGB) of a linear colour at `exposure`.
pub fn display(c: [f32; 3], exposure: f32) -> [u8; 3] {
    c.map(|v| (srgb(v * exposure) * 255.0).round() as u8)
}

/// CPU mirror of `nearest_emitter`: the radiance of the nearest lit added light along (o, d)
/// closer than `t`, with its distance.
pub fn nearest_emitter(
    emitters: &[GpuLight],
    intensities: &[f32],
    o: Vec3,
    d: Vec3,
    mut t: f32,
) -> Option<(Vec3, f32)> {
    let mut found = None;
    for (l, e) in emitters.iter().enumerate() {
        let s = intensities.get(l).copied().unwrap_or(0.0);
        if s <= 0.0 {
            continue;
        }
        if let Some(tl) = e.hit(o, d).filter(|&tl| tl < t) {
            t = tl;
            found = Some((s * Vec3::from_slice(&e.radiance[..3]), tl));
        }
    }
    found
}

/// The albedo of a declared original light's surface where the albedo mesh has no vertex on it
/// (tests, scenes without a bake): a diffuser is near white.
pub const EMITTER_ALBEDO: f32 = 0.8;

/// Metres outside a declared original light's outline between which the albedo mesh gives the
/// light's surface its albedo ([`GpuOriginal::new`]): past the glow that bleeds into the
/// vertices beside it, within the ceiling or wall it sits on.
pub const RING: (f32, f32) = (0.1, 0.4);

/// A declared original light as `frame/emitters.glsl` reads it: its shape and radiance, and
/// the diffuse albedo of its own surface, which the frame relights once the light is dimmed.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuOriginal {
    pub light: GpuLight,
    pub albedo: [f32; 4],
}

impl GpuOriginal {
    /// `light` with its surface's albedo taken from the albedo mesh (`albedo` per vertex of
    /// `mesh`, from the bake): the mean over the vertices around the light, in its plane,
    /// `RING` outside its outline, each channel at most 1. Photos show a light's glow, not its
    /// surface, and the vertices on it and just beside it take some glow into their albedo; the
    /// ground truth shows the ceiling or wall around it where the light is off. `EMITTER_ALBEDO`
    /// grey without an albedo mesh or a vertex around the light.
    pub fn new(light: &Light, mesh: Option<(&Mesh, &[[f32; 4]])>) -> GpuOriginal {
        let light = GpuLight::new(light);
        let around = |p: &[f32; 3]| {
            let p = Vec3::from(*p);
            light.near(p, LIGHT_SKIN, RING.1) && !light.near(p, LIGHT_SKIN, RING.0)
        };
        let (mut sum, mut n) = (Vec3::ZERO, 0.0);
        if let Some((m, a)) = mesh {
            for (_, a) in m.positions.iter().zip(a).filter(|(p, _)| around(p)) {
                sum += Vec3::from_slice(&a[..3]).clamp(Vec3::ZERO, Vec3::ONE);
                n += 1.0;
            }
        }
        let albedo = if n > 0.0 {
            sum / n
        } else {
            Vec3::splat(EMITTER_ALBEDO)
        };
        GpuOriginal {
            light,
            albedo: albedo.extend(0.0).into(),
        }
    }
}

/// The glow of the declared original light that the proxy point `y`, seen along unit `d`, lies
/// on (its emitting side, within `LIGHT_SKIN` of its plane, inside its outline grown by
/// `margin` metres, where the pixel filter spreads its glow), and that light: `seen` (the
/// photos' radiance at `y`), or where `seen` is black (no view sees `y`) its declared radiance
/// on the light itself and nothing beside it.
pub fn original_glow(
    originals: &[GpuOriginal],
    y: Vec3,
    d: Vec3,
    seen: Vec3,
    margin: f32,
) -> Option<(Vec3, &GpuOriginal)> {
    let hole = seen == Vec3::ZERO;
    let o = originals.iter().find(|o| {
        let l = &o.light;
        let near = d.dot(l.normal()) < 0.0 && l.near(y, LIGHT_SKIN + margin, margin);
        near && (!hole || l.near(y, LIGHT_SKIN, 0.0))
    })?;
    let glow = if hole {
        Vec3::from_slice(&o.light.radiance[..3])
    } else {
        seen
    };
    Some((glow, o))
}

/// CPU mirror of `original_light`: what the proxy point `y`, seen along unit `d`, shows when it
/// lies on a declared original light: (1 − α_dim) · glow + ρ · E_add / π, the ratio rule with
/// the light's albedo ρ taken from its surroundings ([`original_glow`], [`GpuOriginal::new`];
/// `ea`: E_add at `y`).
pub fn original_light(
    originals: &[GpuOriginal],
    alpha_dim: f32,
    (y, d): (Vec3, Vec3),
    seen: Vec3,
    ea: Vec3,
    margin: f32,
) -> Option<Vec3> {
    let (glow, o) = original_glow(originals, y, d, seen, margin)?;
    let rho = Vec3::from_slice(&o.albedo[..3]);
    Some((1.0 - alpha_dim) * glow + rho / std::f32::consts::PI * ea)
}

/// Metres around a point at camera depth `z` that `LEAK_PX` pixels of `cam` span: how far the
/// photos' pixel filter spreads a light's glow.
pub fn leak_margin(cam: &Camera, z: f32) -> f32 {
    LEAK_PX * z / cam.fx
}

/// The unit camera ray through the centre of pixel `p` (row-major).
pub fn pixel_ray(cam: &Camera, p: usize) -> Vec3 {
    let (x, y) = ((p as u32 % cam.width) as f32, (p as u32 / cam.width) as f32);
    cam.ray_dir(glam::Vec2::new(x + 0.5, y + 0.5)).normalize()
}

/// Per pixel of `cam`, the glow of the declared original light it shows and that light's
/// albedo ([`original_glow`]; `gpos`: the G-buffer, `comp`: the composites, `I_1` first), zero
/// off the lights: the frame draws (1 − α_dim) · glow + albedo · E_add / π there (`relit dump
/// --parts` writes both for the trainer).
pub fn original_glow_image(
    cam: &Camera,
    gpos: &[[f32; 4]],
    comp: &[[f32; 4]],
    originals: &[GpuOriginal],
) -> Vec<([f32; 3], [f32; 3])> {
    (0..(cam.width * cam.height) as usize)
        .map(|p| {
            let (g, c) = (gpos[p], comp[p]);
            let (y, seen) = (Vec3::from_slice(&g[..3]), Vec3::from_slice(&c[..3]));
            let margin = leak_margin(cam, g[3]);
            let on =
                (g[3] > 0.0).then(|| original_glow(originals, y, pixel_ray(cam, p), seen, margin));
            match on.flatten() {
                Some((glow, o)) => (glow.into(), [o.albedo[0], o.albedo[1], o.albedo[2]]),
                None => ([0.0; 3], [0.0; 3]),
            }
        })
        .collect()
}

/// The lights a frame draws where they are seen (`frame/emitters.glsl`): the added lights at
/// this frame's intensities, the declared original lights dimmed by α_dim.
#[derive(Clone, Copy)]
pub struct Drawn<'a> {
    pub added: &'a [GpuLight],
    pub intensities: &'a [f32],
    pub originals: &'a [GpuOriginal],
    pub alpha_dim: f32,
}

/// CPU reference of the lights drawn over a mode's output `base` (linear RGB per pixel;
/// `gpos`: the G-buffer's world position + depth; `comp`: the composites (`I_1` first);
/// `eadd`: the frame's E_add per pixel).
pub fn reference_emitters(
    cam: &Camera,
    gpos: &[[f32; 4]],
    (comp, eadd): (&[[f32; 4]], &[[f32; 4]]),
    drawn: &Drawn,
    base: &[[f32; 3]],
) -> Vec<[f32; 3]> {
    let eye = cam.center();
    let v3 = |a: &[f32; 4]| Vec3::from_slice(&a[..3]);
    (0..base.len())
        .map(|p| {
            let d = pixel_ray(cam, p);
            let (g, pos) = (gpos[p], v3(&gpos[p]));
            let t = if g[3] > 0.0 { pos.distance(eye) } else { 1e30 };
            let (o, a) = (drawn.originals, drawn.alpha_dim);
            let margin = leak_margin(cam, g[3]);
            let seen = (g[3] > 0.0)
                .then(|| original_light(o, a, (pos, d), v3(&comp[p]), v3(&eadd[p]), margin))
                .flatten();
            match nearest_emitter(drawn.added, drawn.intensities, eye, d, t) {
                Some((le, _)) => le.into(),
                None => seen.map_or(base[p], Into::into),
            }
        })
        .collect()
}
