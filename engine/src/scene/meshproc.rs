//! Geometry processing of the MVS mesh before the bake (§4.4): Laplacian smoothing, and RANSAC
//! plane detection with the vertices near each plane snapped onto it.

use glam::Vec3;

use super::synth::Rng;
use super::Mesh;

/// Vertex neighbours through the triangles.
fn neighbours(mesh: &Mesh) -> Vec<Vec<u32>> {
    let mut n = vec![Vec::new(); mesh.positions.len()];
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if !n[a as usize].contains(&b) {
                n[a as usize].push(b);
            }
            if !n[b as usize].contains(&a) {
                n[b as usize].push(a);
            }
        }
    }
    n
}

/// Taubin λ|μ smoothing (Laplacian steps that do not shrink the mesh), `iterations` pairs.
pub fn smooth(mesh: &mut Mesh, iterations: u32) {
    let nb = neighbours(mesh);
    for _ in 0..iterations {
        for f in [0.5f32, -0.53] {
            let p: Vec<Vec3> = mesh.positions.iter().map(|&q| Vec3::from(q)).collect();
            for (i, q) in mesh.positions.iter_mut().enumerate() {
                if nb[i].is_empty() {
                    continue;
                }
                let avg = nb[i].iter().map(|&j| p[j as usize]).sum::<Vec3>() / nb[i].len() as f32;
                *q = (p[i] + f * (avg - p[i])).into();
            }
        }
    }
}

/// Area-weighted vertex normals.
pub fn vertex_normals(mesh: &Mesh) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; mesh.positions.len()];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = mesh.corners(t);
        let fnrm = (b - a).cross(c - a);
        for &v in tri {
            n[v as usize] += fnrm;
        }
    }
    n.into_iter().map(|v| v.normalize_or_zero()).collect()
}

#[derive(Clone, Copy, Debug)]
pub struct PlaneParams {
    /// Inlier distance (m) and normal agreement (cosine).
    pub distance: f32,
    pub min_cos: f32,
    /// Planes with fewer inliers are not snapped.
    pub min_inliers: usize,
    pub max_planes: usize,
    pub iterations: u32,
    pub seed: u64,
}

impl Default for PlaneParams {
    fn default() -> Self {
        PlaneParams {
            distance: 0.015,
            min_cos: 0.94,
            min_inliers: 400,
            max_planes: 12,
            iterations: 300,
            seed: 1,
        }
    }
}

/// A detected plane: unit normal, offset (n·x = d), and how many vertices were snapped.
#[derive(Clone, Copy, Debug)]
pub struct Plane {
    pub normal: Vec3,
    pub d: f32,
    pub inliers: usize,
}

/// Finds up to `max_planes` planes by RANSAC over the vertices (greedy, largest first) and
/// snaps each plane's inliers onto it. Returns the planes found.
pub fn snap_planes(mesh: &mut Mesh, p: &PlaneParams) -> Vec<Plane> {
    let normals = vertex_normals(mesh);
    let nv = mesh.positions.len();
    let mut free: Vec<bool> = vec![true; nv];
    let mut rng = Rng::new(p.seed);
    let mut planes = Vec::new();
    let pos: Vec<Vec3> = mesh.positions.iter().map(|&q| Vec3::from(q)).collect();
    let inlier = |i: usize, n: Vec3, d: f32| {
        (n.dot(pos[i]) - d).abs() <= p.distance && n.dot(normals[i]).abs() >= p.min_cos
    };
    for _ in 0..p.max_planes {
        let candidates: Vec<usize> = (0..nv).filter(|&i| free[i]).collect();
        if candidates.len() < p.min_inliers {
            break;
        }
        let mut best: Option<(Vec3, f32, usize)> = None;
        for _ in 0..p.iterations {
            let pick = |r: &mut Rng| candidates[(r.next_u64() % candidates.len() as u64) as usize];
            let (a, b, c) = (pick(&mut rng), pick(&mut rng), pick(&mut rng));
            let n = (pos[b] - pos[a]).cross(pos[c] - pos[a]);
            if n.length() < 1e-9 {
                continue;
            }
            let n = n.normalize();
            let d = n.dot(pos[a]);
            // Count on a subsample for speed, then confirm on all.
            let count = candidates
                .iter()
                .step_by(4)
                .filter(|&&i| inlier(i, n, d))
                .count()
                * 4;
            if best.is_none_or(|(_, _, k)| count > k) {
                best = Some((n, d, count));
            }
        }
        let Some((mut n, mut d, _)) = best else { break };
        let mut ins: Vec<usize> = candidates
            .iter()
            .copied()
            .filter(|&i| inlier(i, n, d))
            .collect();
        if ins.len() < p.min_inliers {
            break;
        }
        // Refine: the inliers' mean normal (oriented like n) through their centroid.
        let mean_n = ins
            .iter()
            .map(|&i| {
                if normals[i].dot(n) < 0.0 {
                    -normals[i]
                } else {
                    normals[i]
                }
            })
            .sum::<Vec3>();
        if mean_n.length() > 1e-6 {
            n = mean_n.normalize();
            let c = ins.iter().map(|&i| pos[i]).sum::<Vec3>() / ins.len() as f32;
            d = n.dot(c);
            ins.retain(|&i| inlier(i, n, d));
        }
        for &i in &ins {
            let q = pos[i] - n * (n.dot(pos[i]) - d);
            mesh.positions[i] = q.into();
            free[i] = false;
        }
        planes.push(Plane {
            normal: n,
            d,
            inliers: ins.len(),
        });
    }
    planes
}

/// Splits every edge longer than `max_edge` at its midpoint, shared by both triangles so the
/// mesh stays watertight, until none is longer; the shape does not change. The bake stores
/// per-vertex quantities (albedo, the surface cache), so a hand-made mesh of a few large
/// triangles needs vertices at least this dense.
pub fn refine(mesh: &mut Mesh, max_edge: f32) {
    let too_long = |m: &Mesh, a: u32, b: u32| {
        Vec3::from(m.positions[a as usize]).distance(Vec3::from(m.positions[b as usize])) > max_edge
    };
    // Each pass at least halves every split edge; 24 passes cover 16 million : 1.
    for _ in 0..24 {
        let mut mids = std::collections::HashMap::new();
        for t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]));
                if !mids.contains_key(&(a, b)) && too_long(mesh, a, b) {
                    mids.insert((a, b), mesh.positions.len() as u32);
                    let m = (Vec3::from(mesh.positions[a as usize])
                        + Vec3::from(mesh.positions[b as usize]))
                        / 2.0;
                    mesh.positions.push(m.into());
                    if let Some(c) = mesh.colors.as_mut() {
                        let (ca, cb) = (Vec3::from(c[a as usize]), Vec3::from(c[b as usize]));
                        c.push(((ca + cb) / 2.0).into());
                    }
                }
            }
        }
        if mids.is_empty() {
            return;
        }
        let mid = |a: u32, b: u32| mids.get(&(a.min(b), a.max(b))).copied();
        let mut out = Vec::with_capacity(mesh.triangles.len() * 2);
        for &t in &mesh.triangles {
            split_triangle(t, |k| mid(t[k], t[(k + 1) % 3]), &mut out);
        }
        mesh.triangles = out;
    }
}

/// The triangles of `t` once the edges with a midpoint (edge k runs from corner k to k + 1)
/// are split; winding is kept.
fn split_triangle(t: [u32; 3], mid: impl Fn(usize) -> Option<u32>, out: &mut Vec<[u32; 3]>) {
    let m = [mid(0), mid(1), mid(2)];
    match m.iter().filter(|x| x.is_some()).count() {
        0 => out.push(t),
        1 => {
            // Rotate so the split edge is edge 0: (a, m, c), (m, b, c).
            let k = m.iter().position(|x| x.is_some()).unwrap();
            let (a, b, c, x) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3], m[k].unwrap());
            out.extend([[a, x, c], [x, b, c]]);
        }
        2 => {
            // Rotate so edge 0 is the unsplit one: corners a, b, c with midpoints on b–c
            // (mbc) and c–a (mca).
            let k = m.iter().position(|x| x.is_none()).unwrap();
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            let (mbc, mca) = (m[(k + 1) % 3].unwrap(), m[(k + 2) % 3].unwrap());
            out.extend([[mca, mbc, c], [a, b, mbc], [a, mbc, mca]]);
        }
        _ => {
            let [x, y, z] = [m[0].unwrap(), m[1].unwrap(), m[2].unwrap()];
            out.extend([[t[0], x, z], [x, t[1], y], [z, y, t[2]], [x, y, z]]);
        }
    }
}
