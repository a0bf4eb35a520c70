//! Per-frame view culling (§4.3 at the paper's scale): `shaders_glsl/frame/view_cull.comp` finds
//! which input views see which points of a coarse grid over the novel view; [`choose`] picks
//! the frame's active views from that on the host. The pass keeps a push block of its own
//! ([`Push`]) rather than the frame's constants ([`super::FrameConstants`]): it runs in a
//! submission of its own before the active views are chosen, and its grid is its alone.
//!
//! The composites' cost grows with the views that see each pixel, not with the capture: in a
//! 300-view capture the 32 views nearest the camera see each pixel about 1.5× as often as the
//! 32 views of a sparse one. So up to [`CULL_ABOVE`] views (the captures the network is trained
//! on) every view takes part, as before; above, [`choose`] first covers every grid point some
//! view sees (up to [`MIN_COVER`] views each), then adds the most relevant views while the
//! average count of views per covered point stays within [`VIEW_BUDGET`].

use glam::Vec3;

use super::MAX_ACTIVE;
use crate::bake::ViewData;
use crate::gpu::shaders;
use crate::scene::Camera;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Push {
    pub eye: [f32; 4],
    pub width: u32,
    pub height: u32,
    pub grid_w: u32,
    pub grid_h: u32,
    pub nviews: u32,
    pub view_w: u32,
    pub view_h: u32,
    pub words: u32,
}

/// Push as its shader's push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    Push,
    [shaders::FRAME_VIEW_CULL],
    [eye, width, height, grid_w, grid_h, nviews, view_w, view_h, words]
);

pub const SHADER: crate::gpu::Shader = shaders::FRAME_VIEW_CULL;

/// Up to this many views (after a left-out one) all take part in a frame.
pub const CULL_ABOVE: usize = 32;
/// Above [`CULL_ABOVE`], the mean number of active views that see a covered grid point.
pub const VIEW_BUDGET: f32 = 12.0;
/// Each grid point that some view sees is covered by this many active views where it can be.
pub const MIN_COVER: u32 = 3;
/// The grid: at most this many points across and down.
pub const GRID: (u32, u32) = (32, 24);

/// The grid for a `width × height` frame.
pub fn grid(width: u32, height: u32) -> (u32, u32) {
    (GRID.0.min(width), GRID.1.min(height))
}

/// 32-bit words per view in the visibility bits.
pub fn words(grid: (u32, u32)) -> usize {
    (grid.0 * grid.1).div_ceil(32) as usize
}

/// The novel-view pixel of grid point `s` (the shader's `grid_pixel`).
pub fn grid_pixel(s: u32, (w, h): (u32, u32), (gw, gh): (u32, u32)) -> usize {
    let (gx, gy) = (s % gw, s / gw);
    let x = (2 * gx + 1) * w / (2 * gw);
    let y = (2 * gy + 1) * h / (2 * gh);
    (y * w + x) as usize
}

/// CPU reference of the pass: the visibility bits (view-major, [`words`] per view) and the grid
/// points (w = 1 where the novel view has a surface), from the novel G-buffer `gpos`.
pub fn reference(
    data: &ViewData,
    gpos: &[[f32; 4]],
    size: (u32, u32),
    grid: (u32, u32),
) -> (Vec<u32>, Vec<[f32; 4]>) {
    let (nw, npts) = (words(grid), grid.0 * grid.1);
    let points: Vec<[f32; 4]> = (0..npts)
        .map(|s| {
            let g = gpos[grid_pixel(s, size, grid)];
            if g[3] > 0.0 {
                [g[0], g[1], g[2], 1.0]
            } else {
                [0.0; 4]
            }
        })
        .collect();
    let mut seen = vec![0u32; nw * data.cameras.len()];
    for (j, bits) in seen.chunks_exact_mut(nw).enumerate() {
        for (s, p) in points.iter().enumerate() {
            if p[3] > 0.0 && data.visible_pixel(j, Vec3::new(p[0], p[1], p[2])).is_some() {
                bits[s / 32] |= 1 << (s % 32);
            }
        }
    }
    (seen, points)
}

/// When a frame culls and how far: [`CULL_ABOVE`], [`VIEW_BUDGET`] and [`MIN_COVER`] but in
/// tests, which lower them to cull a small room.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Culling {
    /// Frames over more views than this choose their active views.
    pub above: usize,
    /// The mean number of active views that see a covered grid point.
    pub budget: f32,
    /// Views kept per seen grid point, whatever the budget.
    pub min_cover: u32,
}

impl Default for Culling {
    fn default() -> Self {
        Culling {
            above: CULL_ABOVE,
            budget: VIEW_BUDGET,
            min_cover: MIN_COVER,
        }
    }
}

impl Culling {
    /// Whether a frame over `nviews` views, `exclude` left out, needs the culling pass.
    pub fn needed(&self, nviews: usize, exclude: Option<u32>) -> bool {
        let left_out = exclude.is_some_and(|e| (e as usize) < nviews);
        nviews - left_out as usize > self.above
    }
}

/// The active views, ascending, from the pass's visibility bits: first views that cover the
/// grid points seen least (greedy, up to `c.min_cover` views per point), then views by
/// relevance (the sum over the points they see of the composites' weights w1·w2, §4.3.1) while
/// the mean views per covered point stays within `c.budget`; at most [`MAX_ACTIVE`].
pub fn choose(
    c: &Culling,
    seen: &[u32],
    points: &[[f32; 4]],
    cameras: &[Camera],
    eye: Vec3,
    exclude: Option<u32>,
) -> Vec<u32> {
    let nw = seen.len() / cameras.len().max(1);
    let bits = |j: usize| &seen[j * nw..(j + 1) * nw];
    let count = |j: usize| bits(j).iter().map(|b| b.count_ones()).sum::<u32>();
    let cand: Vec<usize> = (0..cameras.len())
        .filter(|&j| Some(j as u32) != exclude && count(j) > 0)
        .collect();
    let rel: Vec<f32> = (0..cameras.len())
        .map(|j| relevance(bits(j), points, &cameras[j], eye))
        .collect();
    // Per point: how many more active views should see it.
    let mut need = vec![0u32; points.len()];
    for &j in &cand {
        for_each_bit(bits(j), |s| need[s] += 1);
    }
    let covered = need.iter().filter(|&&n| n > 0).count();
    need.iter_mut().for_each(|n| *n = (*n).min(c.min_cover));
    let mut chosen: Vec<usize> = Vec::new();
    let mut taken = vec![false; cameras.len()];
    while chosen.len() < MAX_ACTIVE {
        let gain = |j: usize| {
            let mut g = 0;
            for_each_bit(bits(j), |s| g += (need[s] > 0) as u32);
            g
        };
        let best = (cand.iter().copied().filter(|&j| !taken[j]))
            .map(|j| (gain(j), j))
            .filter(|&(g, _)| g > 0)
            .max_by(|a, b| a.0.cmp(&b.0).then(rel[a.1].total_cmp(&rel[b.1])));
        let Some((_, j)) = best else { break };
        for_each_bit(bits(j), |s| need[s] = need[s].saturating_sub(1));
        taken[j] = true;
        chosen.push(j);
    }
    let budget = (c.budget * covered as f32) as u32;
    let mut load: u32 = chosen.iter().map(|&j| count(j)).sum();
    let mut rest: Vec<usize> = cand.iter().copied().filter(|&j| !taken[j]).collect();
    rest.sort_by(|&a, &b| rel[b].total_cmp(&rel[a]).then(a.cmp(&b)));
    for j in rest {
        if chosen.len() >= MAX_ACTIVE {
            break;
        }
        if load + count(j) <= budget {
            load += count(j);
            chosen.push(j);
        }
    }
    let mut out: Vec<u32> = chosen.into_iter().map(|j| j as u32).collect();
    out.sort_unstable();
    out
}

/// Σ over the grid points view `c` sees of w1·w2 (§4.3.1): near the novel camera, and seeing
/// the points from the novel camera's side.
fn relevance(bits: &[u32], points: &[[f32; 4]], c: &Camera, eye: Vec3) -> f32 {
    let ci = c.center();
    let w1 = 1.0 / ci.distance_squared(eye).max(1e-8);
    let mut sum = 0.0;
    for_each_bit(bits, |s| {
        let x = Vec3::new(points[s][0], points[s][1], points[s][2]);
        let cw = (eye - x)
            .normalize_or_zero()
            .dot((ci - x).normalize_or_zero());
        sum += cw * cw;
    });
    w1 * sum
}

fn for_each_bit(bits: &[u32], mut f: impl FnMut(usize)) {
    for (w, &b) in bits.iter().enumerate() {
        let mut b = b;
        while b != 0 {
            f(w * 32 + b.trailing_zeros() as usize);
            b &= b - 1;
        }
    }
}
