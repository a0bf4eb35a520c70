//! What the frame passes' CPU references read (tests/frame.rs, tests/glossy.rs): the views,
//! the host maps, the novel G-buffer and the frame's parameters.

use glam::Vec3;

use super::{emitters, lighting, live, maps, HostMaps};
use crate::bake::{GpuLight, ViewData};

/// What the CPU references read: the views, the host maps, the novel G-buffer and the frame's
/// parameters.
pub struct RefInputs<'a> {
    pub data: &'a ViewData,
    pub maps: &'a HostMaps,
    pub gpos: &'a [[f32; 4]],
    pub gnrm: &'a [[f32; 4]],
    pub width: u32,
    pub height: u32,
    pub eye: Vec3,
    pub active: &'a [u32],
    pub intensities: &'a [f32],
    pub alpha_dim: f32,
    /// The view left out of the frame (also by the target mirror).
    pub exclude: Option<u32>,
    /// The added lights' shapes (drawn where seen, in the mirror too).
    pub emitters: &'a [GpuLight],
    /// The declared original lights (drawn where seen, dimmed).
    pub originals: &'a [emitters::GpuOriginal],
    /// Their factors ([`Lighting::originals`]; 1 where missing). `maps.split` of them have E_add
    /// layers, the last ones of `maps.eadd`.
    pub keep: &'a [[f32; 3]],
    /// Live lights, when some are (frame/live.rs).
    pub live: Option<LiveRef<'a>>,
}

/// What the CPU references read of the live lights: the bake mesh, the novel view's triangle
/// ids (+1, 0: none), and per live light its parameters and filtered cache.
pub struct LiveRef<'a> {
    pub mesh: &'a crate::scene::Mesh,
    pub layout: &'a crate::bake::CacheLayout,
    pub gtri: &'a [u32],
    pub lights: &'a [live::GpuLive],
    pub caches: &'a [Vec<[f32; 4]>],
}

impl LiveRef<'_> {
    /// Whether added light l is live.
    pub fn is_live(&self, l: usize) -> bool {
        self.lights.iter().any(|x| x.layer as usize == l)
    }

    /// Σ intensity × E_add of the live lights at x (normal n) on triangle `tri`.
    pub fn eadd(&self, intensities: &[f32], x: Vec3, n: Vec3, tri: usize, key: u32) -> Vec3 {
        let mut e = Vec3::ZERO;
        for (i, l) in self.lights.iter().enumerate() {
            let s = intensities[l.layer as usize];
            if s != 0.0 {
                let c = &self.caches[i];
                e += s * live::reference_eadd(
                    self.mesh,
                    self.layout,
                    l,
                    c,
                    i as u32,
                    x,
                    n,
                    tri,
                    key,
                );
            }
        }
        e
    }
}

impl RefInputs<'_> {
    /// α_dim and the original lights' factors.
    pub fn dim(&self) -> (f32, &[[f32; 3]]) {
        (self.alpha_dim, self.keep)
    }

    /// Whether some original light has a factor of its own ([`Lighting::per_light`]).
    pub fn per_light(&self) -> bool {
        self.keep.iter().any(|c| *c != lighting::AS_CAPTURED)
    }

    /// CPU mirror of `removed_share` (originals.glsl) at view j's pixel px.
    pub fn removed_share(&self, j: usize, px: glam::Vec2) -> Vec3 {
        let (m, nviews) = (self.maps, self.data.cameras.len());
        let first = m.eadd.len() / nviews - m.split;
        let sims: Vec<Vec3> = (0..m.split)
            .map(|l| {
                maps::sample_bilinear(&m.eadd[(first + l) * nviews + j], m.width, m.height, px)
            })
            .collect();
        lighting::removed_share(&sims, self.keep, self.originals.len())
    }

    /// The surface point at pixel p and its normal facing the novel camera.
    pub fn surface(&self, p: usize) -> Option<(Vec3, Vec3)> {
        let g = self.gpos[p];
        if g[3] <= 0.0 {
            return None;
        }
        let x = Vec3::new(g[0], g[1], g[2]);
        let mut n = Vec3::from_slice(&self.gnrm[p][..3]);
        if n.dot(self.eye - x) < 0.0 {
            n = -n;
        }
        Some((x, n))
    }
}
