//! An added light as the bake's and the frame's passes read it (`common/lights.glsl`), and the
//! sample counts of tracing its light: shared by E_add (`added_irradiance.rs`) and the surface
//! cache (`surface_cache.rs`), which otherwise know nothing of each other.

use glam::Vec3;

use super::random::onb;
use crate::scene::{Light, LightShape, Mesh};

/// A light as `common/lights.glsl` reads it.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuLight {
    pub p0: [f32; 4],
    pub p1: [f32; 4],
    pub p2: [f32; 4],
    pub radiance: [f32; 4],
}

impl GpuLight {
    pub fn new(l: &Light) -> GpuLight {
        let r = [l.radiance[0], l.radiance[1], l.radiance[2], 0.0];
        match l.shape {
            LightShape::Quad {
                corner,
                edge_u,
                edge_v,
            } => GpuLight {
                p0: corner.extend(0.0).into(),
                p1: edge_u.extend(0.0).into(),
                p2: edge_v.extend(0.0).into(),
                radiance: r,
            },
            LightShape::Disk {
                center,
                normal,
                radius,
            } => GpuLight {
                p0: center.extend(1.0).into(),
                p1: normal.extend(0.0).into(),
                p2: [radius, 0.0, 0.0, 0.0],
                radiance: r,
            },
        }
    }

    /// The light as the bake traces it: `new`, and for a declared original light (baked for its
    /// share of E_src, per-light control) the lift of its shadow rays in `radiance.w`: it sits on
    /// the proxy's ceiling or wall, which must not shadow it (`light_direct`'s `lift`).
    pub fn traced(l: &Light) -> GpuLight {
        let mut g = GpuLight::new(l);
        if l.original {
            g.radiance[3] = crate::constants::LIGHT_SKIN;
        }
        g
    }

    /// How far in front of the light its shadow rays end (see [`GpuLight::traced`]).
    pub fn lift(&self) -> f32 {
        self.radiance[3]
    }

    /// The unit normal of the emitting side (`light_normal`).
    pub fn normal(&self) -> Vec3 {
        let v = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
        if self.p0[3] < 0.5 {
            v(self.p1).cross(v(self.p2)).normalize()
        } else {
            v(self.p1).normalize()
        }
    }

    /// CPU mirror of `light_hit`: distance along (o, unit d) to the emitting side.
    pub fn hit(&self, o: Vec3, d: Vec3) -> Option<f32> {
        let v = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
        let n = self.normal();
        let dn = d.dot(n);
        if dn >= 0.0 {
            return None;
        }
        let t = (v(self.p0) - o).dot(n) / dn;
        if t <= 0.0 {
            return None;
        }
        self.within_outline(o + t * d - v(self.p0), 0.0)
            .then_some(t)
    }

    /// CPU mirror of `light_near`: p on the outline grown by `margin`, within `skin` of the plane.
    pub fn near(&self, p: Vec3, skin: f32, margin: f32) -> bool {
        let v = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
        let n = self.normal();
        let q = p - v(self.p0);
        let h = q.dot(n);
        if h.abs() > skin {
            return false;
        }
        self.within_outline(q - h * n, margin)
    }

    /// CPU mirror of `within_outline`: q (from the corner or centre, in the light's plane)
    /// inside the outline grown by `margin` metres. A quad may be any parallelogram: q is
    /// solved in (edge_u, edge_v).
    fn within_outline(&self, q: Vec3, margin: f32) -> bool {
        let v = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
        if self.p0[3] >= 0.5 {
            return q.length() <= self.p2[0] + margin;
        }
        let (u, w) = (v(self.p1), v(self.p2));
        let (uu, uw, ww, qu, qw) = (u.dot(u), u.dot(w), w.dot(w), q.dot(u), q.dot(w));
        let det = uu * ww - uw * uw;
        let (a, b) = ((qu * ww - qw * uw) / det, (qw * uu - qu * uw) / det);
        let (mu, mv) = (margin / uu.sqrt(), margin / ww.sqrt());
        (-mu..=1.0 + mu).contains(&a) && (-mv..=1.0 + mv).contains(&b)
    }

    /// CPU mirror of `light_direct` (common/nee.glsl): direct irradiance at x from one sample.
    pub fn direct(&self, mesh: &Mesh, x: Vec3, n: Vec3, u: [f32; 2], lift: f32) -> Vec3 {
        let (lp, ln, area) = self.sample(u);
        let w = lp - x;
        let d2 = w.length_squared();
        let w = w / d2.sqrt();
        let (cx, cl) = (n.dot(w), -ln.dot(w));
        if cx <= 0.0 || cl <= 0.0 {
            return Vec3::ZERO;
        }
        let o = x + n * 1e-3;
        let e = lp + ln * lift - o;
        let de = e.length();
        if crate::cpu::occluded(mesh, o, e / de, 1e-3, de - 2e-3) {
            return Vec3::ZERO;
        }
        Vec3::from_slice(&self.radiance[..3]) * (cx * cl * area / d2)
    }

    /// CPU mirror of `light_sample`: point, normal, area.
    pub fn sample(&self, u: [f32; 2]) -> (Vec3, Vec3, f32) {
        let v = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
        if self.p0[3] < 0.5 {
            let c = v(self.p1).cross(v(self.p2));
            let area = c.length();
            (
                v(self.p0) + u[0] * v(self.p1) + u[1] * v(self.p2),
                c / area,
                area,
            )
        } else {
            let n = v(self.p1).normalize();
            let r = self.p2[0];
            let (t, b) = onb(n);
            let rr = r * u[0].sqrt();
            let phi = std::f32::consts::TAU * u[1];
            (
                v(self.p0) + t * (rr * phi.cos()) + b * (rr * phi.sin()),
                n,
                std::f32::consts::PI * r * r,
            )
        }
    }
}

/// Sample counts, bounces and seed of E_add.
#[derive(Clone, Copy, Debug)]
pub struct AddedParams {
    /// Shadow rays per pixel for the direct part.
    pub samples: u32,
    /// Paths per texel of the surface cache (the indirect part).
    pub cache_samples: u32,
    pub bounces: u32,
    pub seed: u32,
}

/// Bounces after which Russian roulette may end a path (as in surface_cache.comp).
pub const RR_START: u32 = 2;
