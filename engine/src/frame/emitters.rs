//! The lights a frame draws where they are seen (`shaders_glsl/frame/emitters.glsl`, used by
//! the output pass and the target mirror): lit added lights in front of the surface, at their
//! radiance × intensity, and declared original lights on it, relit by the ratio rule with their
//! own surface's albedo. CPU references of both, and the original lights' GPU layout.

use glam::Vec3;

use crate::bake::GpuLight;
use crate::constants::{LEAK_PX, LIGHT_SKIN};
use crate::scene::{Camera, Light, Mesh};

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
) -> Option<(Vec3, usize)> {
    let hole = seen == Vec3::ZERO;
    let i = originals.iter().position(|o| {
        let l = &o.light;
        let near = d.dot(l.normal()) < 0.0 && l.near(y, LIGHT_SKIN + margin, margin);
        near && (!hole || l.near(y, LIGHT_SKIN, 0.0))
    })?;
    let glow = if hole {
        Vec3::from_slice(&originals[i].light.radiance[..3])
    } else {
        seen
    };
    Some((glow, i))
}

/// CPU mirror of `original_light`: what the proxy point `y`, seen along unit `d`, shows when it
/// lies on a declared original light l: (1 − α_dim) · c_l · glow + ρ · E_add / π, the ratio
/// rule with the light's albedo ρ taken from its surroundings ([`original_glow`],
/// [`GpuOriginal::new`]; `ea`: E_add at `y`; c_l: `keep[l]`, 1 where missing).
pub fn original_light(
    originals: &[GpuOriginal],
    (alpha_dim, keep): (f32, &[[f32; 3]]),
    (y, d): (Vec3, Vec3),
    seen: Vec3,
    ea: Vec3,
    margin: f32,
) -> Option<Vec3> {
    let (glow, l) = original_glow(originals, y, d, seen, margin)?;
    let rho = Vec3::from_slice(&originals[l].albedo[..3]);
    let c = Vec3::from(keep.get(l).copied().unwrap_or([1.0; 3]));
    Some((1.0 - alpha_dim) * c * glow + rho / std::f32::consts::PI * ea)
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
                Some((glow, l)) => {
                    let a = originals[l].albedo;
                    (glow.into(), [a[0], a[1], a[2]])
                }
                None => ([0.0; 3], [0.0; 3]),
            }
        })
        .collect()
}

/// The lights a frame draws where they are seen (`frame/emitters.glsl`): the added lights at
/// this frame's intensities, the declared original lights dimmed by α_dim and their factors
/// (`keep`, [`super::Lighting::originals`]: 1 where missing).
#[derive(Clone, Copy)]
pub struct Drawn<'a> {
    pub added: &'a [GpuLight],
    pub intensities: &'a [f32],
    pub originals: &'a [GpuOriginal],
    pub alpha_dim: f32,
    pub keep: &'a [[f32; 3]],
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
            let (o, a) = (drawn.originals, (drawn.alpha_dim, drawn.keep));
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
