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
