//! Shadow rays shared between neighbouring pixels: the CPU twin of `shaders_glsl/frame/sight.glsl`
//! (the glossy layer's). Pixel i of a workgroup of [`SIGHT_GROUP`] consecutive pixels traces
//! slot r·m + i mod m in round r (m = min(slots, GLOSSY_SIGHT_SPAN)); a pixel takes a slot's
//! answer from the two nearest pixels that traced it, one on each side, that lie on its surface
//! (within GLOSSY_SIGHT_DIST, normals within ~25°); where they disagree (a shadow's edge) or
//! none may answer it traces its own ray, so a shadow's edge stays where the rays put it. A
//! ray query costs a whole SIMD vector on a CPU device (a warp on a GPU) however few lanes
//! trace: rays only at edges keep most vectors free of them.

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
    sight(mesh, lights, pts, &std::cell::Cell::new(0))
}

/// [`shared_sight`], counting the rays traced in `rays`.
fn sight(
    mesh: &Mesh,
    lights: &[&GpuLight],
    pts: &[Option<(Vec3, Vec3)>],
    rays: &std::cell::Cell<usize>,
) -> Vec<u32> {
    let trace = |x: Vec3, n: Vec3, l: &GpuLight| {
        rays.set(rays.get() + 1);
        sees_light(mesh, x, n, l)
    };
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
    // Round r's answer of pixel q (group index j) for a pixel at x, normal n: Some(seen), or
    // None where it may not take it (outside the group, another surface, q did not trace).
    let answer = |q: isize, j: isize, r: usize, (x, n): (Vec3, Vec3)| {
        if !(0..SIGHT_GROUP as isize).contains(&j) {
            return None;
        }
        let b = traced.get(q as usize).map_or(0, |t| t >> (2 * r) & 3);
        let (xq, nq) = pts.get(q as usize).copied().flatten()?;
        let near = xq.distance(x) <= GLOSSY_SIGHT_DIST && nq.dot(n) >= 0.9;
        (b & 1 != 0 && near).then_some(b & 2 != 0)
    };
    let slot_seen = |p: usize, xn: (Vec3, Vec3), k: usize| {
        if !faces_light(xn.0, xn.1, lights[k]) {
            return false;
        }
        let (r, c, li) = (k / m, k % m, p % SIGHT_GROUP);
        let j0 = li as isize - ((li + m - c) % m) as isize;
        let q0 = p as isize - li as isize + j0;
        let a0 = answer(q0, j0, r, xn);
        if j0 == li as isize && a0.is_some() {
            return a0 == Some(true);
        }
        let a1 = match j0 == li as isize {
            true => None,
            false => answer(q0 + m as isize, j0 + m as isize, r, xn),
        };
        match (a0, a1) {
            (Some(a), Some(b)) if a == b => a,
            (Some(a), None) | (None, Some(a)) => a,
            _ => trace(xn.0, xn.1, lights[k]),
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

    /// Shared answers equal each pixel's own rays except where one side may not answer (a
    /// workgroup's edge, a hole, another surface); a point on another surface answers exactly,
    /// the hole nothing; far fewer rays than one per light and point.
    #[test]
    fn neighbours_share_shadow_rays_within_a_surface_only() {
        let (mesh, pts) = scene();
        let lights = [disk(-1.0), disk(0.0), disk(1.0)];
        let lights: Vec<&GpuLight> = lights.iter().collect();
        let rays = std::cell::Cell::new(0);
        let shared = sight(&mesh, &lights, &pts, &rays);
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
        let m = lights.len();
        let shadowed = (0..pts.len())
            .filter(|&p| pts[p].is_some())
            .map(|p| (0..m).filter(|k| own[p] >> k & 1 == 0).count())
            .sum::<usize>();
        assert!(shadowed >= 10, "the square shadows the line ({shadowed})");
        for p in (0..pts.len()).filter(|&p| shared[p] != own[p]) {
            let g = p % SIGHT_GROUP;
            let one_side = g < m
                || g >= SIGHT_GROUP - m
                || (p.saturating_sub(m)..=p + m).any(|q| q == 65 || pts.get(q) == Some(&None));
            assert!(
                one_side,
                "pixel {p}: shared {:b}, own {:b}",
                shared[p], own[p]
            );
        }
        let all = pts.iter().flatten().count() * m;
        assert!(
            rays.get() * 2 < all,
            "{} rays for {all} answers",
            rays.get()
        );
    }
}
