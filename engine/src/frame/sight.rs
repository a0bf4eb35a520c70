//! Shadow rays shared between neighbouring pixels: the CPU twin of `shaders_glsl/frame/sight.glsl`
//! (the glossy layer's). Pixel i of a workgroup of [`SIGHT_GROUP`] consecutive pixels traces
//! slot r·m + i mod m in round r (m = min(slots, GLOSSY_SIGHT_SPAN)); a pixel takes a slot's
//! answer from the nearest pixel that traced it, where that pixel lies on the same surface
//! (within GLOSSY_SIGHT_DIST, normals within ~25°), else traces its own ray. A ray query costs
//! a whole SIMD vector on a CPU device (a warp on a GPU) however few lanes trace.

use glam::Vec3;

use super::glossy::{light_frame, sees_light};
use super::RefInputs;
use crate::bake::GpuLight;
use crate::constants::{GLOSSY_SIGHT_DIST, GLOSSY_SIGHT_SPAN};
use crate::scene::Mesh;

/// Slots: lights whose answers are shared (bits of a u32).
pub const SIGHT_MAX: usize = 32;
/// Invocations of the layer's workgroup, over consecutive pixels.
pub const SIGHT_GROUP: usize = 64;

/// The slots' lights: the original lights (at most `max_orig`), then the lit added lights in
/// order, at most [`SIGHT_MAX`] in all.
pub fn sight_lights<'a>(r: &'a RefInputs, max_orig: usize) -> Vec<&'a GpuLight> {
    let lit = |l: &usize| r.intensities.get(*l).copied().unwrap_or(0.0) > 0.0;
    (r.originals.iter().take(max_orig).map(|o| &o.light))
        .chain(
            (r.emitters.iter().enumerate())
                .filter(|(l, _)| lit(l))
                .map(|(_, e)| e),
        )
        .take(SIGHT_MAX)
        .collect()
}

/// Whether x (normal n) faces light l near enough to trace (`sees_light`'s own tests).
fn faces_light(x: Vec3, n: Vec3, l: &GpuLight) -> bool {
    let d = light_frame(l).0 - x;
    d.dot(n) > 0.0 && d.length() >= 0.06
}

/// Per pixel, bit k: whether its point (x, normal n; None: it needs no answers) sees slot k's
/// light, as the GPU's workgroups share the rays.
pub fn shared_sight(mesh: &Mesh, lights: &[&GpuLight], pts: &[Option<(Vec3, Vec3)>]) -> Vec<u32> {
    let nk = lights.len();
    let m = nk.clamp(1, GLOSSY_SIGHT_SPAN as usize);
    // Round r's answer in bits 2r (traced) and 2r + 1 (seen).
    let traced: Vec<u32> = (pts.iter().enumerate())
        .map(|(p, pt)| {
            let Some((x, n)) = *pt else { return 0 };
            let li = p % SIGHT_GROUP;
            (0..nk.div_ceil(m)).fold(0, |bits, r| {
                let k = r * m + li % m;
                if k >= nk || !faces_light(x, n, lights[k]) {
                    return bits;
                }
                let b = if sees_light(mesh, x, n, lights[k]) {
                    3
                } else {
                    1
                };
                bits | b << (2 * r)
            })
        })
        .collect();
    let slot_seen = |p: usize, (x, n): (Vec3, Vec3), k: usize| {
        if !faces_light(x, n, lights[k]) {
            return false;
        }
        let li = p % SIGHT_GROUP;
        let mut j = li - li % m + k % m;
        if j >= SIGHT_GROUP {
            j -= m;
        }
        let q = p - li + j;
        let b = traced.get(q).map_or(0, |t| t >> (2 * (k / m)) & 3);
        let near =
            j == li
                || pts.get(q).copied().flatten().is_some_and(|(xq, nq)| {
                    xq.distance(x) <= GLOSSY_SIGHT_DIST && nq.dot(n) >= 0.9
                });
        match near && b & 1 != 0 {
            true => b & 2 != 0,
            false => sees_light(mesh, x, n, lights[k]),
        }
    };
    (pts.iter().enumerate())
        .map(|(p, pt)| match *pt {
            Some(xn) => (0..nk)
                .filter(|&k| slot_seen(p, xn, k))
                .fold(0, |s, k| s | 1 << k),
            None => 0,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Light, LightShape};

    fn disk(x: f32) -> GpuLight {
        GpuLight::new(&Light {
            name: format!("disk at {x}"),
            shape: LightShape::Disk {
                center: Vec3::new(x, 2.0, 0.0),
                normal: Vec3::NEG_Y,
                radius: 0.1,
            },
            radiance: [1.0; 3],
            original: true,
            estimated: false,
        })
    }

    /// A floor and, above it, a small square that shadows it; 128 points along a line of the
    /// floor 2.3 cm apart, a hole, and one point on the square's top among them.
    fn scene() -> (Mesh, Vec<Option<(Vec3, Vec3)>>) {
        let quad = |y: f32, h: f32| [[-h, y, -h], [h, y, -h], [h, y, h], [-h, y, h]];
        let mut positions = quad(0.0, 2.0).to_vec();
        positions.extend(quad(1.0, 0.2));
        let triangles = vec![[0, 2, 1], [0, 3, 2], [4, 6, 5], [4, 7, 6]];
        let mesh = Mesh {
            positions,
            colors: None,
            triangles,
        };
        let mut pts: Vec<_> = (0..128)
            .map(|i| Some((Vec3::new(-1.5 + 3.0 * i as f32 / 128.0, 0.0, 0.0), Vec3::Y)))
            .collect();
        pts[20] = None;
        pts[65] = Some((Vec3::new(0.0, 1.0, 0.1), Vec3::Y));
        (mesh, pts)
    }

    /// Shared answers equal each pixel's own rays except within the span of a shadow's edge;
    /// a point on another surface and the hole's neighbours answer exactly, the hole nothing.
    #[test]
    fn neighbours_share_shadow_rays_within_a_surface_only() {
        let (mesh, pts) = scene();
        let lights = [disk(-1.0), disk(0.0), disk(1.0)];
        let lights: Vec<&GpuLight> = lights.iter().collect();
        let shared = shared_sight(&mesh, &lights, &pts);
        let own: Vec<u32> = (pts.iter())
            .map(|pt| match pt {
                Some((x, n)) => (0..lights.len())
                    .filter(|&k| sees_light(&mesh, *x, *n, lights[k]))
                    .fold(0, |s, k| s | 1 << k),
                None => 0,
            })
            .collect();
        assert_eq!(shared[20], 0);
        assert_eq!(shared[65], own[65]);
        let span = GLOSSY_SIGHT_SPAN as usize;
        // Each light's shadow of the square has edges on the line; away from them, exact.
        let edge = |p: usize, k: usize| {
            let lo = p.saturating_sub(span);
            let hi = (p + span).min(own.len() - 1);
            (lo..=hi).any(|q| own[q] >> k & 1 != own[p] >> k & 1 && q != 65)
        };
        let mut shadowed = 0;
        for p in (0..pts.len()).filter(|&p| p != 65) {
            for k in 0..lights.len() {
                shadowed += (own[p] >> k & 1 == 0 && pts[p].is_some()) as u32;
                if !edge(p, k) {
                    let (s, o) = (shared[p] >> k & 1, own[p] >> k & 1);
                    assert_eq!(s, o, "pixel {p}, light {k}: shared {s}, own {o}");
                }
            }
        }
        assert!(shadowed >= 10, "the square shadows the line ({shadowed})");
        // The neighbours' answers are taken: at some shadow edge a pixel reads one.
        let differ = (0..pts.len()).filter(|&p| shared[p] != own[p]).count();
        assert!(
            differ > 0 && differ <= 4 * span * lights.len(),
            "{differ} pixels differ"
        );
    }
}
