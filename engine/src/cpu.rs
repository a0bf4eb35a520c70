//! CPU references for the GPU passes: brute-force ray casting in double precision. Slow by
//! design (every triangle for every ray), so only for the tiny inputs tests use.
//!
//! [`MeshBvh`] answers the same queries with the same triangle test through a bounding volume
//! hierarchy, for CPU work on full-size meshes (the light coverage of `relit scene check`).

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

/// A bounding volume hierarchy over a mesh's triangles for CPU ray casting: the same
/// double-precision, two-sided triangle test as [`closest_hit`] and [`occluded`] (so the same
/// answers), visiting only the triangles whose boxes the ray crosses. Built once per mesh
/// (median splits on the longest axis of the centroids, up to 4 triangles per leaf); it owns a
/// copy of the corners, so it does not borrow the mesh.
pub struct MeshBvh {
    nodes: Vec<BvhNode>,
    /// Triangle ids in leaf order.
    tris: Vec<u32>,
    /// Corners of triangle `tris[i]` at `corners[i]`.
    corners: Vec<[DVec3; 3]>,
}

#[derive(Clone, Copy)]
struct BvhNode {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: first index into `tris` and count (> 0). Inner node: `first` is the right child
    /// (the left one follows the node) and `count` is 0.
    first: u32,
    count: u32,
}

const BVH_LEAF: usize = 4;

impl MeshBvh {
    pub fn new(mesh: &Mesh) -> MeshBvh {
        let n = mesh.triangles.len();
        let corners: Vec<[DVec3; 3]> = mesh
            .triangles
            .iter()
            .map(|t| t.map(|v| Vec3::from(mesh.positions[v as usize]).as_dvec3()))
            .collect();
        let centroids: Vec<DVec3> = corners.iter().map(|c| (c[0] + c[1] + c[2]) / 3.0).collect();
        let mut tris: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::with_capacity(2 * n / BVH_LEAF + 1);
        if n > 0 {
            build(&mut nodes, &mut tris, 0, &corners, &centroids);
        }
        let corners = tris.iter().map(|&t| corners[t as usize]).collect();
        MeshBvh {
            nodes,
            tris,
            corners,
        }
    }

    /// Visits the leaves the ray `o + t d`, `t` in `[tmin, tmax]`, may cross; `leaf` gets the
    /// ray's current `tmax` and each triangle's (leaf-order index, hit) and returns the new
    /// `tmax`, or `None` to stop.
    fn walk(
        &self,
        o: DVec3,
        d: DVec3,
        tmin: f64,
        mut tmax: f64,
        mut leaf: impl FnMut(usize, (f64, f64, f64)) -> Option<f64>,
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let inv = DVec3::ONE / d;
        let mut stack = vec![0u32];
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            if !slab(node.lo, node.hi, o, inv, tmin, tmax) {
                continue;
            }
            if node.count == 0 {
                stack.push(node.first);
                stack.push(i + 1);
                continue;
            }
            for k in node.first as usize..(node.first + node.count) as usize {
                let [a, b, c] = self.corners[k];
                if let Some(h) = ray_triangle(o, d, a, b, c) {
                    if h.0 >= tmin && h.0 <= tmax {
                        match leaf(k, h) {
                            Some(t) => tmax = t,
                            None => return,
                        }
                    }
                }
            }
        }
    }

    /// Closest hit with `t` in `[tmin, tmax]`, as [`closest_hit`] (ties between triangles at
    /// exactly the same `t` may resolve to another of them).
    pub fn closest_hit(&self, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<CpuHit> {
        let mut best: Option<CpuHit> = None;
        self.walk(
            o.as_dvec3(),
            d.as_dvec3(),
            tmin as f64,
            tmax as f64,
            |k, (t, u, v)| {
                if best.is_none_or(|h| (t as f32) < h.t) {
                    best = Some(CpuHit {
                        t: t as f32,
                        tri: self.tris[k],
                        bary: [u as f32, v as f32],
                    });
                }
                Some(t.min(tmax as f64))
            },
        );
        best
    }

    /// Is anything on the segment `[tmin, tmax]`? As [`occluded`].
    pub fn occluded(&self, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> bool {
        let mut hit = false;
        self.walk(
            o.as_dvec3(),
            d.as_dvec3(),
            tmin as f64,
            tmax as f64,
            |_, _| {
                hit = true;
                None
            },
        );
        hit
    }
}

/// Builds the subtree over `tris` (a slice of the whole list starting at `offset`), appending
/// its nodes in depth-first order; returns nothing, the subtree's root is the node it pushes
/// first.
fn build(
    nodes: &mut Vec<BvhNode>,
    tris: &mut [u32],
    offset: usize,
    corners: &[[DVec3; 3]],
    centroids: &[DVec3],
) {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let (mut clo, mut chi) = (lo, hi);
    for &t in tris.iter() {
        for c in corners[t as usize] {
            lo = lo.min(c);
            hi = hi.max(c);
        }
        clo = clo.min(centroids[t as usize]);
        chi = chi.max(centroids[t as usize]);
    }
    let me = nodes.len();
    nodes.push(BvhNode {
        lo,
        hi,
        first: offset as u32,
        count: tris.len() as u32,
    });
    let ext = chi - clo;
    if tris.len() <= BVH_LEAF || ext.max_element() <= 0.0 {
        return;
    }
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let mid = tris.len() / 2;
    tris.select_nth_unstable_by(mid, |a, b| {
        centroids[*a as usize][axis].total_cmp(&centroids[*b as usize][axis])
    });
    let (left, right) = tris.split_at_mut(mid);
    build(nodes, left, offset, corners, centroids);
    let r = nodes.len();
    build(nodes, right, offset + mid, corners, centroids);
    nodes[me].first = r as u32;
    nodes[me].count = 0;
}

/// Does the ray cross the box within `[tmin, tmax]`? Boxes are widened by a relative 1e-9 so
/// that rounding never drops a triangle the exact test would hit.
fn slab(lo: DVec3, hi: DVec3, o: DVec3, inv: DVec3, tmin: f64, tmax: f64) -> bool {
    let pad = (hi - lo).max_element() * 1e-9 + 1e-12;
    let (lo, hi) = (lo - DVec3::splat(pad), hi + DVec3::splat(pad));
    let mut t0 = tmin;
    let mut t1 = tmax;
    for a in 0..3 {
        if inv[a].is_infinite() {
            // Parallel to the slab: inside it or never.
            if o[a] < lo[a] || o[a] > hi[a] {
                return false;
            }
            continue;
        }
        let (mut near, mut far) = ((lo[a] - o[a]) * inv[a], (hi[a] - o[a]) * inv[a]);
        if near > far {
            std::mem::swap(&mut near, &mut far);
        }
        t0 = t0.max(near);
        t1 = t1.min(far);
        if t0 > t1 {
            return false;
        }
    }
    true
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
