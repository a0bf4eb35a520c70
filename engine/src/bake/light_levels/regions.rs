//! Steps 1–2: overexposed voxels, their clusters, and a quad fitted to each cluster's pixels.

use std::collections::{HashMap, HashSet};

use glam::Vec3;

use super::{FindParams, FoundLight, SKIN};
use crate::bake::views::ViewData;
use crate::scene::{Light, LightShape};

/// `voxel`, or the median footprint of a clipped pixel on its surface where that is larger
/// (coarse photos put one pixel in a voxel of 2 cm only now and then).
pub(super) fn voxel_size(d: &ViewData, voxel: f32) -> f32 {
    let mut fp: Vec<f32> = (0..d.pos.len())
        .filter(|&q| d.clipped(q) && d.pos[q][3] > 0.0)
        .map(|q| d.pos[q][3] / d.cameras[q / d.pixels()].fx)
        .collect();
    if fp.is_empty() {
        return voxel;
    }
    let mid = fp.len() / 2;
    fp.select_nth_unstable_by(mid, f32::total_cmp);
    voxel.max(fp[mid])
}

type Key = [i32; 3];

fn key(p: [f32; 4], voxel: f32) -> Key {
    [0, 1, 2].map(|i| (p[i] / voxel).floor() as i32)
}

/// The clipped pixels of each overexposed region (global pixel indices).
pub(super) fn regions(d: &ViewData, voxel: f32, p: &FindParams) -> Vec<Vec<usize>> {
    let mut count: HashMap<Key, (u32, u32)> = HashMap::new();
    for (q, g) in d.pos.iter().enumerate().filter(|(_, g)| g[3] > 0.0) {
        let c = count.entry(key(*g, voxel)).or_default();
        c.0 += 1;
        c.1 += d.clipped(q) as u32;
    }
    let over: HashSet<Key> = (count.iter())
        .filter(|(_, &(n, c))| c > 0 && c as f32 >= p.min_clipped * n as f32)
        .map(|(k, _)| *k)
        .collect();
    let clusters = merge_spheres(components(&over), voxel);
    let of: HashMap<Key, usize> = (clusters.iter().enumerate())
        .filter(|(_, c)| c.len() >= p.min_voxels)
        .flat_map(|(i, c)| c.iter().map(move |k| (*k, i)))
        .collect();
    let mut pixels = vec![Vec::new(); clusters.len()];
    for q in (0..d.pos.len()).filter(|&q| d.clipped(q) && d.pos[q][3] > 0.0) {
        if let Some(&i) = of.get(&key(d.pos[q], voxel)) {
            pixels[i].push(q);
        }
    }
    pixels.retain(|r| !r.is_empty());
    pixels
}

/// Sets of overexposed voxels that touch (26-neighbourhood).
fn components(over: &HashSet<Key>) -> Vec<Vec<Key>> {
    let mut seen: HashSet<Key> = HashSet::new();
    let mut out = Vec::new();
    let mut sorted: Vec<Key> = over.iter().copied().collect();
    sorted.sort();
    for start in sorted {
        if !seen.insert(start) {
            continue;
        }
        let (mut comp, mut stack) = (vec![], vec![start]);
        while let Some(k) = stack.pop() {
            comp.push(k);
            for d in (0..27).map(|i| [i % 3 - 1, i / 3 % 3 - 1, i / 9 - 1]) {
                let n = [k[0] + d[0], k[1] + d[1], k[2] + d[2]];
                if over.contains(&n) && seen.insert(n) {
                    stack.push(n);
                }
            }
        }
        out.push(comp);
    }
    out
}

/// Centre and radius of the sphere around a cluster's voxels.
fn bounding_sphere(c: &[Key], voxel: f32) -> (Vec3, f32) {
    let at = |k: &Key| (Vec3::new(k[0] as f32, k[1] as f32, k[2] as f32) + 0.5) * voxel;
    let centre = c.iter().map(at).sum::<Vec3>() / c.len() as f32;
    let r = c.iter().map(|k| at(k).distance(centre)).fold(0.0, f32::max);
    (centre, r + 0.87 * voxel)
}

/// Merges clusters while the bounding spheres of two of them intersect: each pass joins every
/// intersecting pair at once (union-find), then the merged clusters' spheres are measured again.
/// One pair a pass took O(n³) on a dense proxy, where a capture's clipped pixels make thousands
/// of small clusters (AliceVision's buddha: > 45 min).
fn merge_spheres(mut clusters: Vec<Vec<Key>>, voxel: f32) -> Vec<Vec<Key>> {
    loop {
        let spheres: Vec<_> = clusters.iter().map(|c| bounding_sphere(c, voxel)).collect();
        let n = clusters.len();
        let mut parent: Vec<usize> = (0..n).collect();
        let mut merged = false;
        for i in 0..n {
            for j in i + 1..n {
                if spheres[i].0.distance(spheres[j].0) <= spheres[i].1 + spheres[j].1 {
                    let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                    if a != b {
                        parent[a.max(b)] = a.min(b);
                        merged = true;
                    }
                }
            }
        }
        if !merged {
            return clusters;
        }
        let mut joined: Vec<Vec<Key>> = vec![Vec::new(); n];
        for (i, c) in clusters.into_iter().enumerate() {
            joined[root(&mut parent, i)].extend(c);
        }
        clusters = joined.into_iter().filter(|c| !c.is_empty()).collect();
    }
}

/// The representative of `i`'s set (path halving).
fn root(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// A quad over a region's clipped pixels: principal axes of their surface points, the normal
/// towards the views that saw them, the extent of the points along the two larger axes.
pub(super) fn fit_quad(d: &ViewData, pixels: &[usize], index: usize) -> FoundLight {
    let pts: Vec<Vec3> = pixels
        .iter()
        .map(|&q| Vec3::from_slice(&d.pos[q][..3]))
        .collect();
    let mean = pts.iter().sum::<Vec3>() / pts.len() as f32;
    let mut cov = [[0.0f32; 3]; 3];
    for p in &pts {
        let x = *p - mean;
        for (i, row) in cov.iter_mut().enumerate() {
            for (j, c) in row.iter_mut().enumerate() {
                *c += x[i] * x[j];
            }
        }
    }
    let axes = principal_axes(cov);
    let mut n = axes[2];
    let towards: Vec3 = (pixels.iter().zip(&pts))
        .map(|(&q, p)| (d.cameras[q / d.pixels()].center() - *p).normalize_or_zero())
        .sum();
    if n.dot(towards) < 0.0 {
        n = -n;
    }
    let u = axes[0];
    let v = if u.cross(axes[1]).dot(n) < 0.0 {
        -axes[1]
    } else {
        axes[1]
    };
    let range = |a: Vec3| {
        let s = pts.iter().map(|p| (*p - mean).dot(a));
        let lo = s.clone().fold(f32::INFINITY, f32::min);
        (lo, s.fold(f32::NEG_INFINITY, f32::max) - lo)
    };
    let ((u0, du), (v0, dv)) = (range(u), range(v));
    let views: HashSet<usize> = pixels.iter().map(|&q| q / d.pixels()).collect();
    FoundLight {
        light: Light {
            name: format!("estimated{index}"),
            shape: LightShape::Quad {
                corner: mean + u0 * u + v0 * v + SKIN * n,
                edge_u: du.max(1e-3) * u,
                edge_v: dv.max(1e-3) * v,
            },
            radiance: [1.0; 3],
            original: true,
            estimated: true,
        },
        pixels: pixels.len(),
        views: views.len(),
        pairs: 0,
    }
}

/// Eigenvectors of a symmetric 3×3 matrix, largest eigenvalue first (Jacobi rotations).
fn principal_axes(m: [[f32; 3]; 3]) -> [Vec3; 3] {
    let mut a = m.map(|r| r.map(f64::from));
    let mut v = [[1.0f64, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..50 {
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q].abs() < 1e-30 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let (c, s) = (1.0 / (t * t + 1.0).sqrt(), t / (t * t + 1.0).sqrt());
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (rp, rq) = (a[p], a[q]);
            a[p] = [0, 1, 2].map(|k| c * rp[k] - s * rq[k]);
            a[q] = [0, 1, 2].map(|k| s * rp[k] + c * rq[k]);
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| a[j][j].total_cmp(&a[i][i]));
    order.map(|i| Vec3::new(v[0][i] as f32, v[1][i] as f32, v[2][i] as f32).normalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn principal_axes_of_a_flat_cloud_put_its_normal_last() {
        // Points spread 1 m along x, 0.5 m along z, flat in y.
        let mut cov = [[0.0f32; 3]; 3];
        cov[0][0] = 1.0;
        cov[2][2] = 0.25;
        cov[0][2] = 0.01;
        cov[2][0] = 0.01;
        let a = principal_axes(cov);
        assert!(
            a[0].x.abs() > 0.99 && a[1].z.abs() > 0.99 && a[2].y.abs() > 0.99,
            "{a:?}"
        );
    }

    #[test]
    fn touching_voxels_and_meeting_spheres_make_one_region() {
        let over: HashSet<Key> = [[0, 0, 0], [1, 0, 0], [2, 1, 0], [9, 0, 0], [30, 0, 0]]
            .into_iter()
            .collect();
        let c = components(&over);
        assert_eq!(c.len(), 3);
        // [9,0,0]'s sphere (r 0.87) misses the first cluster's (centre x ≈ 1.5, r ≈ 2.2).
        let m = merge_spheres(c, 1.0);
        assert_eq!(m.len(), 3, "{m:?}");
        // A 4 × 4 patch and a voxel one gap away: two components, one sphere each, meeting.
        let mut over2: HashSet<Key> = (0..16).map(|i| [i % 4, i / 4, 0]).collect();
        over2.insert([5, 1, 0]);
        assert_eq!(components(&over2).len(), 2);
        assert_eq!(merge_spheres(components(&over2), 1.0).len(), 1);
    }

    #[test]
    fn thousands_of_clusters_merge_by_their_spheres() {
        // 3000 single voxels 3 apart (spheres of r 0.87 miss) and, far off, a chain of 2 × 2
        // patches one gap apart (spheres of r 1.58 meet across the gap: one region).
        let mut over: HashSet<Key> = (0..3000).map(|i| [3 * i, 0, 0]).collect();
        for i in 0..20 {
            over.extend([
                [3 * i, 100, 0],
                [3 * i + 1, 100, 0],
                [3 * i, 101, 0],
                [3 * i + 1, 101, 0],
            ]);
        }
        let m = merge_spheres(components(&over), 1.0);
        assert_eq!(m.len(), 3001, "3000 apart, the chain one");
        assert!(m.iter().any(|c| c.len() == 80));
    }
}
