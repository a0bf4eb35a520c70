//! The smoothing of the fit between patches (see `Near`).

use std::collections::HashMap;

use glam::Vec3;

use super::{same_surface, Cell, CellFits, Patches, CELL, LOBES};

/// The smoothing of the fit between patches: a triangle takes the mean of the fits of its
/// surface's patches (`same_surface` with its own) weighted by their area and a tent of width
/// SMOOTH around its centre, so that a strength and its lobe change over half a metre instead
/// of at a cell's edge (hand_room2's mirror took other lobes and strengths patch by patch and
/// glowed in triangles around the lamp).
pub(super) struct Near {
    /// Per patch (cell, index in its cell's list): its surface's patches whose centres lie
    /// within SMOOTH + a cell's diagonal, as (centre, area, fit).
    lists: HashMap<(Cell, usize), Vec<Neighbour>>,
}

/// A neighbouring patch's centre, area, fit and normal.
type Neighbour = (Vec3, f32, [f32; 4], Vec3);

/// Width of the smoothing's tent (m).
const SMOOTH: f32 = 2.0 * CELL;
/// The least area (m²) of a surface that gives its triangles its normal (`Near::normal`).
const PLANE_AREA: f32 = 0.25;

impl Near {
    pub(super) fn new(patches: &Patches, fits: &HashMap<Cell, CellFits>) -> Near {
        let reach = (SMOOTH / CELL).ceil() as i32 + 1;
        let mut lists = HashMap::new();
        for (&(x, y, z, axis), list) in patches {
            for (i, (_, p)) in list.iter().enumerate() {
                let mut near = Vec::new();
                for (dx, dy, dz) in (-reach..=reach).flat_map(|a| {
                    (-reach..=reach).flat_map(move |b| (-reach..=reach).map(move |c| (a, b, c)))
                }) {
                    let k = (x + dx, y + dy, z + dz, axis);
                    let (Some(qs), Some(fs)) = (patches.get(&k), fits.get(&k)) else {
                        continue;
                    };
                    for ((_, q), f) in qs.iter().zip(fs).filter(|((_, q), _)| same_surface(p, q)) {
                        near.push((q.centre, q.area, f.1, q.normal));
                    }
                }
                lists.insert(((x, y, z, axis), i), near);
            }
        }
        Near { lists }
    }

    /// The smoothed strengths at `centre` of a triangle of patch `key` (`own`: the patch's
    /// fit, whose t it keeps).
    pub(super) fn at(&self, key: &(Cell, usize), centre: Vec3, own: [f32; 4]) -> [f32; 4] {
        let (mut w, mut sum) = ([0f32; LOBES], 0f32);
        for (c, area, f, _) in self.lists.get(key).into_iter().flatten() {
            let k = area * (1.0 - c.distance(centre) / SMOOTH).max(0.0);
            for l in 0..LOBES {
                w[l] += k * f[l];
            }
            sum += k;
        }
        match sum > 0.0 {
            true => [w[0] / sum, w[1] / sum, w[2] / sum, own[3]],
            false => own,
        }
    }

    /// The surface's normal at `centre` of a triangle of patch `key`: its patches' normals under
    /// the same tent and areas; zero where the surface around (its patches in the list) covers
    /// under PLANE_AREA: a curved surface's facets are narrow planes.
    pub(super) fn normal(&self, key: &(Cell, usize), centre: Vec3) -> Vec3 {
        let near = self.lists.get(key).map_or(&[][..], |v| &v[..]);
        if near.iter().map(|q| q.1).sum::<f32>() < PLANE_AREA {
            return Vec3::ZERO;
        }
        (near.iter())
            .map(|(c, area, _, n)| area * (1.0 - c.distance(centre) / SMOOTH).max(0.0) * *n)
            .sum::<Vec3>()
            .normalize_or_zero()
    }
}

#[cfg(test)]
mod tests {
    use super::super::{cell, FitSums, Patch};
    use super::*;

    /// Between a patch of strength 0.3 and its neighbours of none on the same surface, the
    /// strength falls along a ramp half a metre wide, and each side keeps its own value beyond.
    #[test]
    fn strengths_change_smoothly_between_patches() {
        let mut patches = Patches::new();
        let mut fits: HashMap<Cell, CellFits> = HashMap::new();
        for i in 0..8 {
            let centre = Vec3::new((i as f32 + 0.5) * CELL, 0.0, 0.5 * CELL);
            let s = if i < 4 { 0.3 } else { 0.0 };
            let p = Patch {
                sums: FitSums {
                    pixels: 100.0,
                    albedo: Vec3::splat(40.0),
                    ..Default::default()
                },
                centre,
                normal: Vec3::Y,
                area: CELL * CELL,
            };
            let k = cell(centre, Vec3::Y);
            patches.insert(k, vec![([0; 3], p)]);
            fits.insert(k, vec![([0; 3], [0.0, s, 0.0, 20.0])]);
        }
        let near = Near::new(&patches, &fits);
        let at = |x: f32| {
            let c = Vec3::new(x, 0.0, 0.5 * CELL);
            let own = fits[&cell(c, Vec3::Y)][0].1;
            near.at(&(cell(c, Vec3::Y), 0), c, own)
        };
        let xs: Vec<f32> = (0..40).map(|i| i as f32 * 0.05).collect();
        let w: Vec<f32> = xs.iter().map(|&x| at(x)[1]).collect();
        assert!(w.windows(2).all(|p| p[1] <= p[0] + 1e-6), "{w:?}");
        assert!((at(0.1)[1] - 0.3).abs() < 1e-6 && at(1.9)[1] == 0.0);
        assert!(
            (at(4.0 * CELL)[1] - 0.15).abs() < 0.02,
            "{}",
            at(4.0 * CELL)[1]
        );
        // Between points 5 cm apart no step above 0.04 (the cell's edge was one of 0.3).
        assert!(w.windows(2).all(|p| p[0] - p[1] < 0.04), "{w:?}");
        assert_eq!(at(0.6)[3], 20.0, "t stays the patch's own");
    }
}
