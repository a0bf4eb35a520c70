//! The network's 66-channel input (§4.4, §5.2): `shaders_glsl/frame/features.glsl`. The channel
//! order below is the contract between the engine, `relit dump` and the trainer.

use super::RefInputs;
use crate::gpu::shaders;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Push {
    pub eye: [f32; 4],
    pub width: u32,
    pub height: u32,
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    Push,
    [shaders::FRAME_FEATURES, shaders::FRAME_FEATURES_F32],
    [eye, width, height]
);

pub const SHADER_F16: crate::gpu::Shader = shaders::FRAME_FEATURES;
pub const SHADER_F32: crate::gpu::Shader = shaders::FRAME_FEATURES_F32;

/// Names of the 66 input channels, in order.
pub fn channel_names() -> Vec<String> {
    let mut v = Vec::new();
    for k in 1..=8 {
        for c in ["r", "g", "b"] {
            v.push(format!("I_{k}.{c}"));
        }
    }
    for k in 1..=8 {
        for c in ["r", "g", "b"] {
            v.push(format!("M_src_{k}.{c}"));
        }
    }
    for m in ["M_tgt", "E_src", "E_add", "E_rem"] {
        for c in ["r", "g", "b"] {
            v.push(format!("{m}.{c}"));
        }
    }
    v.push("disparity".into());
    for c in ["x", "y", "z"] {
        v.push(format!("normal.{c}"));
    }
    v.push("view_angle".into());
    v.push("mirror_distance_ratio".into());
    v
}

pub use crate::constants::{tonemap, untonemap};

#[allow(clippy::needless_range_loop)]
/// CPU reference: planar CHW, 66 channels, from the pass outputs (composites, irradiance and
/// mirror planes as the passes wrote them).
pub fn reference(
    r: &RefInputs,
    comp: &[[f32; 4]],
    irr: &[[f32; 4]],
    mirror: &[[f32; 4]],
) -> Vec<f32> {
    let npix = (r.width * r.height) as usize;
    let mut out = vec![0f32; 66 * npix];
    let pi = std::f32::consts::PI;
    for p in 0..npix {
        let Some((x, n)) = r.surface(p) else { continue };
        let mut set = |c: usize, v: f32| out[c * npix + p] = v;
        for k in 0..16 {
            for c in 0..3 {
                set(3 * k + c, tonemap(comp[k * npix + p][c]));
            }
        }
        for c in 0..3 {
            set(48 + c, tonemap(mirror[p][c]));
        }
        for k in 0..3 {
            for c in 0..3 {
                set(51 + 3 * k + c, tonemap(irr[k * npix + p][c] / pi));
            }
        }
        let dist = x.distance(r.eye);
        set(60, (0.5 / r.gpos[p][3]).min(1.0));
        set(61, n.x);
        set(62, n.y);
        set(63, n.z);
        let cosv = n.dot((r.eye - x) / dist).clamp(0.0, 1.0);
        set(64, cosv.acos() / (0.5 * pi));
        set(65, mirror[p][3] / dist);
    }
    out
}
