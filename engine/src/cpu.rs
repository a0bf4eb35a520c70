//! CPU references for the GPU passes: brute-force ray casting in double precision. Slow by
//! design (every triangle for every ray), so only for the tiny inputs tests use.

use glam::{DVec3, Vec3};

use crate::scene::{Camera, Mesh};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CpuHit {
    pub t: f32,
    pub tri: u32,
    /// Barycentrics of corners 1 and 2 (as `rayQueryGetIntersectionBarycentricsEXT`).
    pub bary: [f32; 2],
}

/// Möller–Trumbore, two-sided, in f64. Returns (t, u, v).
pub fn ray_triangle(o: DVec3, d: DVec3, a: DVec3, b: DVec3, c: DVec3) -> Option<(f64, f64, f64)> {
    let e1 = b - a;
    let e2 = c - a;
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-14 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some((e2.dot(q) * inv, u, v))
}

/// Closest hit with `t` in `[tmin, tmax]`.
pub fn closest_hit(mesh: &Mesh, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<CpuHit> {
    let (o, d) = (o.as_dvec3(), d.as_dvec3());
    let mut best: Option<CpuHit> = None;
    for (i, tri) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = tri.map(|v| Vec3::from(mesh.positions[v as usize]).as_dvec3());
        if let Some((t, u, v)) = ray_triangle(o, d, a, b, c) {
            if t >= tmin as f64 && t <= tmax as f64 && best.is_none_or(|h| (t as f32) < h.t) {
                best = Some(CpuHit {
                    t: t as f32,
                    tri: i as u32,
                    bary: [u as f32, v as f32],
                });
            }
        }
    }
    best
}

/// Is anything on the segment `[tmin, tmax]`?
pub fn occluded(mesh: &Mesh, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> bool {
    let (o, d) = (o.as_dvec3(), d.as_dvec3());
    mesh.triangles.iter().any(|tri| {
        let [a, b, c] = tri.map(|v| Vec3::from(mesh.positions[v as usize]).as_dvec3());
        ray_triangle(o, d, a, b, c).is_some_and(|(t, _, _)| t >= tmin as f64 && t <= tmax as f64)
    })
}

/// Per-pixel camera depth, geometric normal and triangle id + 1 (0 = background), by casting
/// the ray through each pixel centre: the reference for the raster G-buffer.
pub struct CpuGbuffer {
    pub depth: Vec<f32>,
    pub normal: Vec<[f32; 3]>,
    pub tri: Vec<u32>,
}

pub fn gbuffer(mesh: &Mesh, cam: &Camera, near: f32, far: f32) -> CpuGbuffer {
    let n = (cam.width * cam.height) as usize;
    let mut g = CpuGbuffer {
        depth: vec![0.0; n],
        normal: vec![[0.0; 3]; n],
        tri: vec![0; n],
    };
    let o = cam.center();
    for y in 0..cam.height {
        for x in 0..cam.width {
            let d = cam.ray_dir(glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
            // `d` has unit camera-z, so t is camera depth.
            if let Some(h) = closest_hit(mesh, o, d, near, far) {
                let i = (y * cam.width + x) as usize;
                g.depth[i] = h.t;
                g.normal[i] = mesh.face_normal(h.tri as usize).into();
                g.tri[i] = h.tri + 1;
            }
        }
    }
    g
}
