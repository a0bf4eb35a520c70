//! The MVS-like proxy mesh (§6, Fig. 9): the network's inputs are computed on a degraded mesh
//! while the targets use the true one. From the same primitives as the true mesh: remeshed at a
//! few centimetres, rounded corners, noise along normals, bumpy walls, holes in large
//! textureless or glossy regions, and parts thinner than MVS resolves dropped.

use glam::Vec3;
use relit_engine::scene::synth::Rng;

use crate::prim::{tessellate, Prim, TriMesh};
use crate::room::{Object, Surface};

#[derive(Clone, Debug)]
pub struct ProxyParams {
    pub seed: u64,
    /// Target edge length of the remeshed surface (m).
    pub edge: f32,
    /// Amplitude (m) and feature size (m) of the noise along normals everywhere.
    pub noise_amp: f32,
    pub noise_scale: f32,
    /// Extra low-frequency bumps on walls, floor and ceiling.
    pub wall_bump_amp: f32,
    pub wall_bump_scale: f32,
    /// Radius of the rounding of box edges (m).
    pub corner_radius: f32,
    /// Parts thinner than this (m) are lost.
    pub thin: f32,
    /// Probability of a hole per textureless or glossy surface, and hole radius range (m).
    pub hole_prob: f32,
    pub hole_radius: (f32, f32),
}

impl Default for ProxyParams {
    fn default() -> Self {
        ProxyParams {
            seed: 1,
            edge: 0.05,
            noise_amp: 0.007,
            noise_scale: 0.12,
            wall_bump_amp: 0.01,
            wall_bump_scale: 0.7,
            corner_radius: 0.025,
            thin: 0.02,
            hole_prob: 0.5,
            hole_radius: (0.12, 0.35),
        }
    }
}

impl ProxyParams {
    /// The default degradation scaled by `f` (clamped to 0..=1): noise, bumps, rounding, lost
    /// thin parts and holes shrink together; the remeshing edge stays. 0 keeps every surface.
    pub fn scaled(seed: u64, f: f32) -> Self {
        let f = f.clamp(0.0, 1.0);
        let d = ProxyParams::default();
        ProxyParams {
            seed,
            noise_amp: d.noise_amp * f,
            wall_bump_amp: d.wall_bump_amp * f,
            corner_radius: d.corner_radius * f,
            thin: d.thin * f,
            hole_prob: d.hole_prob * f,
            ..d
        }
    }

    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "seed": self.seed, "edge_m": self.edge, "noise_amp_m": self.noise_amp,
            "noise_scale_m": self.noise_scale, "wall_bump_amp_m": self.wall_bump_amp,
            "wall_bump_scale_m": self.wall_bump_scale, "corner_radius_m": self.corner_radius,
            "thin_m": self.thin, "hole_prob": self.hole_prob,
            "hole_radius_m": [self.hole_radius.0, self.hole_radius.1],
        })
    }
}

/// Smooth 3D value noise in [-1, 1] from a hashed lattice (no tables: any seed, any extent).
pub fn noise3(p: Vec3, seed: u64) -> f32 {
    let h = |x: i64, y: i64, z: i64| {
        let mut r = Rng::new(
            seed ^ (x as u64).wrapping_mul(0x9E37_79B9)
                ^ (y as u64).wrapping_mul(0x85EB_CA6B)
                ^ (z as u64).wrapping_mul(0xC2B2_AE35),
        );
        r.f32() * 2.0 - 1.0
    };
    let f = p.floor();
    let t = p - f;
    let s = t * t * (Vec3::splat(3.0) - 2.0 * t);
    let (x, y, z) = (f.x as i64, f.y as i64, f.z as i64);
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let x00 = lerp(h(x, y, z), h(x + 1, y, z), s.x);
    let x10 = lerp(h(x, y + 1, z), h(x + 1, y + 1, z), s.x);
    let x01 = lerp(h(x, y, z + 1), h(x + 1, y, z + 1), s.x);
    let x11 = lerp(h(x, y + 1, z + 1), h(x + 1, y + 1, z + 1), s.x);
    lerp(lerp(x00, x10, s.y), lerp(x01, x11, s.y), s.z)
}

/// The proxy of one object (empty when MVS would lose it).
pub fn degrade(o: &Object, p: &ProxyParams, rng: &mut Rng) -> TriMesh {
    if !o.shell && o.prim.thickness() < p.thin {
        return TriMesh::default();
    }
    let mut m = tessellate(&o.prim, p.edge);
    // Rounded edges: map each point of the box onto the rounded box of radius r.
    if let Prim::Box {
        lo,
        hi,
        inward: false,
    } = o.prim
    {
        let r = p.corner_radius.min(0.45 * (hi - lo).min_element());
        let (ilo, ihi) = (lo + Vec3::splat(r), hi - Vec3::splat(r));
        for (q, n) in m.positions.iter_mut().zip(m.normals.iter_mut()) {
            let inner = q.clamp(ilo, ihi);
            let d = (*q - inner).normalize_or(*n);
            *q = inner + d * r;
            *n = d;
        }
    }
    for (q, n) in m.positions.iter_mut().zip(&m.normals) {
        let mut d = p.noise_amp * noise3(*q / p.noise_scale, p.seed);
        if o.shell {
            d += p.wall_bump_amp * noise3(*q / p.wall_bump_scale, p.seed ^ 0xB0B);
        }
        *q += *n * d;
    }
    if matches!(o.surface, Surface::Textureless | Surface::Glossy)
        && !m.triangles.is_empty()
        && rng.f32() < p.hole_prob
    {
        let c = m.centroid((rng.next_u64() % m.triangles.len() as u64) as usize);
        let r = rng.range(p.hole_radius.0, p.hole_radius.1);
        let keep: Vec<bool> = (0..m.triangles.len())
            .map(|t| (m.centroid(t) - c).length() > r)
            .collect();
        m = m.filter_triangles(|t| keep[t]);
    }
    m
}

/// The proxy of the whole room.
pub fn proxy_mesh(objects: &[Object], p: &ProxyParams) -> TriMesh {
    let mut rng = Rng::new(p.seed ^ 0x9A0C);
    let mut out = TriMesh::default();
    for o in objects {
        out.append(&degrade(o, p, &mut rng));
    }
    out
}
