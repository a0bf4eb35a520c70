//! CPU mirror of `shaders_glsl/common/random.glsl`, bit for bit in the integer part.

use glam::Vec3;

pub fn pcg3d(v: [u32; 3]) -> [u32; 3] {
    let mut v = v.map(|x| x.wrapping_mul(1664525).wrapping_add(1013904223));
    v[0] = v[0].wrapping_add(v[1].wrapping_mul(v[2]));
    v[1] = v[1].wrapping_add(v[2].wrapping_mul(v[0]));
    v[2] = v[2].wrapping_add(v[0].wrapping_mul(v[1]));
    v = v.map(|x| x ^ (x >> 16));
    v[0] = v[0].wrapping_add(v[1].wrapping_mul(v[2]));
    v[1] = v[1].wrapping_add(v[2].wrapping_mul(v[0]));
    v[2] = v[2].wrapping_add(v[0].wrapping_mul(v[1]));
    v
}

pub fn rand2(key: [u32; 3]) -> [f32; 2] {
    let h = pcg3d(key);
    [
        (h[0] >> 8) as f32 / 16777216.0,
        (h[1] >> 8) as f32 / 16777216.0,
    ]
}

pub fn onb(n: Vec3) -> (Vec3, Vec3) {
    let s = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (s + n.z);
    let c = n.x * n.y * a;
    (
        Vec3::new(1.0 + s * n.x * n.x * a, s * c, -s * n.x),
        Vec3::new(c, s + n.y * n.y * a, -n.y),
    )
}

pub fn cosine_dir(n: Vec3, u: [f32; 2]) -> Vec3 {
    let (t, b) = onb(n);
    let r = u[0].sqrt();
    let phi = std::f32::consts::TAU * u[1];
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u[0]).max(0.0).sqrt()).normalize()
}
