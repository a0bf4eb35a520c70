//! Shadow rays shared between neighbouring pixels: the CPU twin of `shaders_glsl/frame/sight.glsl`
//! (the glossy layer's). The layer's workgroups are tiles of [`SIGHT_TILE`]² pixels; in each,
//! only every GLOSSY_SIGHT_ROWS-th row traces, pixel (tx, ty) slot r·m + c in round r, c =
//! tx mod m mirrored every other tracing row (m = min(slots, GLOSSY_SIGHT_SPAN)). A pixel takes
//! a slot's answer from the nearest pixels that traced it — the columns with that slot on
//! either side, in its own row and the tracing rows before and after where it traces, else in
//! the tracing rows above and below — that lie on its plane (within GLOSSY_SIGHT_DIST of it and
//! GLOSSY_SIGHT_REACH away, normals within ~25°), where all of them agree; where they disagree
//! (a shadow's edge) or none may answer it traces its own ray, so a shadow's edge stays where
//! the rays put it. A ray query costs a whole SIMD vector on a CPU device (a warp on a GPU)
//! however few lanes trace: a tile's row is one vector on llvmpipe, so rows that do not trace
//! cost no ray unless an edge crosses them. Still lights are read from the sight cache
//! ([`super::sight_cache`]) instead; only the others go through here.

use glam::Vec3;

use super::glossy::{light_frame, sees_light};
use super::RefInputs;
use crate::bake::GpuLight;
use crate::constants::{
    GLOSSY_SIGHT_DIST, GLOSSY_SIGHT_REACH, GLOSSY_SIGHT_ROWS, GLOSSY_SIGHT_SPAN,
};
use crate::scene::Mesh;

/// Slots: lights whose answers are shared (bits of a u32).
pub const SIGHT_MAX: usize = 32;
/// Pixels per side of the layer's square workgroup.
pub const SIGHT_TILE: usize = 8;

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

/// The layer's workgroups for a `width × height` frame: one per tile, in rows.
pub fn tiles(width: u32, height: u32) -> u32 {
    let t = SIGHT_TILE as u32;
    width.div_ceil(t) * height.div_ceil(t)
}

/// Whether x (normal n) faces light l near enough to trace (`sees_light`'s own tests).
pub fn faces_light(x: Vec3, n: Vec3, l: &GpuLight) -> bool {
    let d = light_frame(l).0 - x;
    d.dot(n) > 0.0 && d.length() >= 0.06
}

const ROWS: isize = GLOSSY_SIGHT_ROWS as isize;
const TILE: isize = SIGHT_TILE as isize;
/// Whether the tile's last row traces too: where the rows after the last GLOSSY_SIGHT_ROWS-th
/// would be more than one (so that the rows between have a tracing row above and below).
const LAST_ROW: bool = (TILE - 1) % ROWS > 1;

/// Whether a tile's row traces in the shared rounds.
fn traces(ty: isize) -> bool {
    ty % ROWS == 0 || (LAST_ROW && ty == TILE - 1)
}

/// The tracing rows before and after tracing row y (either may lie outside the tile).
fn row_before(y: isize) -> isize {
    match LAST_ROW && y == TILE - 1 {
        true => y - y % ROWS,
        false => y - ROWS,
    }
}

fn row_after(y: isize) -> isize {
    match LAST_ROW && y < TILE - 1 {
        true => (y + ROWS).min(TILE - 1),
        false => y + ROWS,
    }
}

/// The column (mod m) where tracing row y traces slot column c: mirrored every other tracing
/// row, so that a pixel near a tile's side finds the slot on its far side in a row nearby.
fn slot_column(c: usize, m: usize, y: isize) -> usize {
    match ((y + ROWS - 1) / ROWS) % 2 {
        0 => c,
        _ => m - 1 - c,
    }
}

/// The places in the tile (possibly outside it) of the pixels whose answers to slot column c
/// pixel (tx, ty) may take when it did not trace it: in the tracing rows around it (before,
/// its own and after where it traces, else the nearest above and below), the columns with c
/// on either side.
fn candidates(tx: usize, ty: usize, c: usize, m: usize) -> Vec<(isize, isize)> {
    let (txi, tyi) = (tx as isize, ty as isize);
    let ys = match traces(tyi) {
        true => vec![row_before(tyi), tyi, row_after(tyi)],
        false => {
            let y0 = tyi - tyi % ROWS;
            vec![y0, row_after(y0)]
        }
    };
    ys.into_iter()
        .filter(|y| (0..TILE).contains(y))
        .flat_map(|y| {
            let x0 = txi - ((tx + m - slot_column(c, m, y)) % m) as isize;
            let cols = if x0 == txi { 1 } else { 2 };
            (0..cols).map(move |i| (x0 + i * m as isize, y))
        })
        .collect()
}

/// Whether a pixel at xq (normal nq) may answer for one at x (normal n): on its plane (within
/// GLOSSY_SIGHT_DIST of it, normals within ~25°) and within GLOSSY_SIGHT_REACH.
fn near(x: Vec3, n: Vec3, xq: Vec3, nq: Vec3) -> bool {
    let d = xq - x;
    d.dot(n).abs() <= GLOSSY_SIGHT_DIST
        && d.length_squared() <= GLOSSY_SIGHT_REACH * GLOSSY_SIGHT_REACH
        && nq.dot(n) >= 0.9
}

/// Per pixel (an image `width` wide, in rows), bit k: whether its point (x, normal n; None: it
/// needs no answers) sees slot k's light, as the GPU's workgroups share the rays. Slots in
/// `cached` (their lights read the sight cache, [`super::sight_cache`]) are left out: the others
/// are dealt out in their order, as if they were all the slots.
pub fn shared_sight(
    mesh: &Mesh,
    lights: &[&GpuLight],
    pts: &[Option<(Vec3, Vec3)>],
    width: usize,
    cached: u32,
) -> Vec<u32> {
    let slots: Vec<usize> = (0..lights.len()).filter(|k| cached >> k & 1 == 0).collect();
    let traced: Vec<&GpuLight> = slots.iter().map(|&k| lights[k]).collect();
    let bits = sight(mesh, &traced, pts, width, &std::cell::Cell::new(0));
    (bits.into_iter())
        .map(|b| (slots.iter().enumerate()).fold(0, |s, (j, &k)| s | (b >> j & 1) << k))
        .collect()
}

/// [`shared_sight`], counting the rays traced in `rays`.
fn sight(
    mesh: &Mesh,
    lights: &[&GpuLight],
    pts: &[Option<(Vec3, Vec3)>],
    width: usize,
    rays: &std::cell::Cell<usize>,
) -> Vec<u32> {
    let trace = |x: Vec3, n: Vec3, l: &GpuLight| {
        rays.set(rays.get() + 1);
        sees_light(mesh, x, n, l)
    };
    let nk = lights.len();
    let m = nk.clamp(1, GLOSSY_SIGHT_SPAN as usize);
    let place = |p: usize| ((p % width) % SIGHT_TILE, (p / width) % SIGHT_TILE);
    // Round r's answer in bits 2r (traced) and 2r + 1 (seen).
    let traced: Vec<u32> = (pts.iter().enumerate())
        .map(|(p, pt)| {
            let (Some((x, n)), (tx, ty)) = (*pt, place(p)) else {
                return 0;
            };
            if !traces(ty as isize) {
                return 0;
            }
            (0..nk.div_ceil(m)).fold(0, |bits, r| {
                let k = r * m + slot_column(tx % m, m, ty as isize);
                if k >= nk || !faces_light(x, n, lights[k]) {
                    return bits;
                }
                bits | (1 + 2 * trace(x, n, lights[k]) as u32) << (2 * r)
            })
        })
        .collect();
    // Round r's answer of the pixel at (tx, ty) of p's tile for a pixel at x, normal n:
    // Some(seen), or None where it may not take it (outside the tile or the image, another
    // surface, it did not trace).
    let answer = |p: usize, (tx, ty): (isize, isize), r: usize, (x, n): (Vec3, Vec3)| {
        let t = 0..SIGHT_TILE as isize;
        if !t.contains(&tx) || !t.contains(&ty) {
            return None;
        }
        let (px, py) = (p % width, p / width);
        let qx = px - px % SIGHT_TILE + tx as usize;
        let q = (py - py % SIGHT_TILE + ty as usize) * width + qx;
        let (xq, nq) = pts.get(q).copied().flatten().filter(|_| qx < width)?;
        let b = traced[q] >> (2 * r) & 3;
        (b & 1 != 0 && near(x, n, xq, nq)).then_some(b & 2 != 0)
    };
    let slot_seen = |p: usize, xn: (Vec3, Vec3), k: usize| {
        if !faces_light(xn.0, xn.1, lights[k]) {
            return false;
        }
        let ((tx, ty), r, c) = (place(p), k / m, k % m);
        let at = |place: (isize, isize)| answer(p, place, r, xn);
        if traces(ty as isize) && tx % m == slot_column(c, m, ty as isize) {
            if let Some(a) = at((tx as isize, ty as isize)) {
                return a;
            }
        }
        let said: Vec<bool> = (candidates(tx, ty, c, m).into_iter())
            .filter_map(at)
            .collect();
        match (said.contains(&true), said.contains(&false)) {
            (true, false) => true,
            (false, true) => false,
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

    /// A floor and, above it, a small square that shadows it; a grid of floor points 2 cm
    /// apart, [`WIDTH`] wide (tiles cut at the image's right edge), a hole, and one point on the
    /// square's top among them.
    const WIDTH: usize = 60;
    fn scene() -> (Mesh, Vec<Option<(Vec3, Vec3)>>) {
        let quad = |y: f32, c: Vec3, h: f32| {
            [[-h, y, -h], [h, y, -h], [h, y, h], [-h, y, h]].map(|p| (c + Vec3::from(p)).to_array())
        };
        let mut positions = quad(0.0, Vec3::ZERO, 2.0).to_vec();
        positions.extend(quad(1.0, Vec3::new(0.0, 0.0, 0.15), 0.2));
        let triangles = vec![[0, 2, 1], [0, 3, 2], [4, 6, 5], [4, 7, 6]];
        let mesh = Mesh {
            positions,
            colors: None,
            triangles,
        };
        let mut pts: Vec<_> = (0..WIDTH * 20)
            .map(|p| {
                let (i, j) = ((p % WIDTH) as f32, (p / WIDTH) as f32);
                Some((Vec3::new(-0.6 + 0.02 * i, 0.0, -0.2 + 0.02 * j), Vec3::Y))
            })
            .collect();
        pts[3 * WIDTH + 20] = None;
        pts[9 * WIDTH + 5] = Some((Vec3::new(0.0, 1.0, 0.1), Vec3::Y));
        (mesh, pts)
    }

    /// Shared answers equal each pixel's own rays except at under 1 % of the pixels, where one of
    /// the pixels it asks may not answer (a tile's or the image's edge, a hole, another
    /// surface); a point on another surface answers exactly, the hole nothing; rays for under
    /// a third of the answers (one round of the old rows: one ray per pixel for three lights).
    #[test]
    fn neighbours_share_shadow_rays_within_a_surface_only() {
        let (mesh, pts) = scene();
        let lights = [disk(-0.5), disk(0.0), disk(0.5)];
        let lights: Vec<&GpuLight> = lights.iter().collect();
        let rays = std::cell::Cell::new(0);
        let shared = sight(&mesh, &lights, &pts, WIDTH, &rays);
        let own: Vec<u32> = (pts.iter())
            .map(|pt| match pt {
                Some((x, n)) => (0..lights.len())
                    .filter(|&k| sees_light(&mesh, *x, *n, lights[k]))
                    .fold(0, |s, k| s | 1 << k),
                None => 0,
            })
            .collect();
        let (hole, other) = (3 * WIDTH + 20, 9 * WIDTH + 5);
        assert_eq!(shared[hole], 0);
        assert_eq!(shared[other], own[other]);
        let m = lights.len();
        let lit = |p: usize, k: usize| own[p] >> k & 1 == 1;
        for k in 0..m {
            let dark = (0..pts.len())
                .filter(|&p| pts[p].is_some() && !lit(p, k))
                .count();
            assert!(
                dark >= 40 && dark + 40 <= pts.len(),
                "light {k} shadows {dark} points"
            );
        }
        let wrong: Vec<usize> = (0..pts.len()).filter(|&p| shared[p] != own[p]).collect();
        assert!(
            wrong.len() * 100 <= pts.len(),
            "{} pixels differ",
            wrong.len()
        );
        for p in wrong {
            let (x, y) = (p % WIDTH, p / WIDTH);
            let k = (0..m)
                .find(|&k| (shared[p] ^ own[p]) >> k & 1 == 1)
                .unwrap();
            let cut = candidates(x % SIGHT_TILE, y % SIGHT_TILE, k % m, m)
                .into_iter()
                .any(|(cx, cy)| {
                    let (qx, qy) = (
                        x as isize - (x % SIGHT_TILE) as isize + cx,
                        y as isize - (y % SIGHT_TILE) as isize + cy,
                    );
                    let q = qy * WIDTH as isize + qx;
                    !(0..SIGHT_TILE as isize).contains(&cx)
                        || !(0..SIGHT_TILE as isize).contains(&cy)
                        || qx >= WIDTH as isize
                        || q as usize >= pts.len()
                        || q as usize == hole
                        || q as usize == other
                });
            assert!(
                cut,
                "pixel ({x}, {y}): shared {:b}, own {:b}",
                shared[p], own[p]
            );
        }
        let all = pts.iter().flatten().count() * m;
        assert!(
            rays.get() * 3 < all,
            "{} rays for {all} answers",
            rays.get()
        );
        // A slot that reads the sight cache is left out: the others are dealt out as if they
        // were all, and still answer as their own rays do but at a tile's edges.
        let rest = shared_sight(&mesh, &lights, &pts, WIDTH, 0b010);
        assert!(rest.iter().all(|b| b & 0b010 == 0));
        let wrong = (0..pts.len())
            .filter(|&p| rest[p] != own[p] & 0b101)
            .count();
        assert!(wrong * 100 <= pts.len(), "{wrong} pixels differ");
    }
}
