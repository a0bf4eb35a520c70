//! The network's input (§4.4, §5.2): `shaders_glsl/frame/features.glsl`. The channel order (the
//! CH_* rows of `engine/constants.table`) is the contract between the engine, `relit dump` and
//! the trainer. Its push constants are the frame's ([`super::FrameConstants`]).

use super::RefInputs;
use crate::constants::{
    CH_DISPARITY, CH_E_SRC, CH_I, CH_MIRROR_DIST, CH_M_TGT, CH_NORMAL, CH_VIEW_ANGLE, IN_CHANNELS,
};
use crate::gpu::shaders;

pub const SHADER_F16: crate::gpu::Shader = shaders::FRAME_FEATURES;
pub const SHADER_F32: crate::gpu::Shader = shaders::FRAME_FEATURES_F32;

/// Names of the IN_CHANNELS input channels, in order.
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
/// CPU reference: planar CHW, IN_CHANNELS channels, from the pass outputs (composites,
/// irradiance and mirror planes as the passes wrote them).
pub fn reference(
    r: &RefInputs,
    comp: &[[f32; 4]],
    irr: &[[f32; 4]],
    mirror: &[[f32; 4]],
) -> Vec<f32> {
    let npix = (r.width * r.height) as usize;
    let mut out = vec![0f32; IN_CHANNELS as usize * npix];
    let ch = |c: u32| c as usize;
    let pi = std::f32::consts::PI;
    for p in 0..npix {
        let Some((x, n)) = r.surface(p) else { continue };
        let mut set = |c: usize, v: f32| out[c * npix + p] = v;
        for k in 0..16 {
            for c in 0..3 {
                set(ch(CH_I) + 3 * k + c, tonemap(comp[k * npix + p][c]));
            }
        }
        for c in 0..3 {
            set(ch(CH_M_TGT) + c, tonemap(mirror[p][c]));
        }
        for k in 0..3 {
            for c in 0..3 {
                set(ch(CH_E_SRC) + 3 * k + c, tonemap(irr[k * npix + p][c] / pi));
            }
        }
        let dist = x.distance(r.eye);
        set(ch(CH_DISPARITY), (0.5 / r.gpos[p][3]).min(1.0));
        set(ch(CH_NORMAL), n.x);
        set(ch(CH_NORMAL) + 1, n.y);
        set(ch(CH_NORMAL) + 2, n.z);
        let cosv = n.dot((r.eye - x) / dist).clamp(0.0, 1.0);
        set(ch(CH_VIEW_ANGLE), cosv.acos() / (0.5 * pi));
        set(ch(CH_MIRROR_DIST), mirror[p][3] / dist);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constants::{CH_E_ADD, CH_E_REM, CH_M_SRC};

    #[test]
    fn channel_names_follow_the_constants_table() {
        let n = channel_names();
        assert_eq!(n.len(), IN_CHANNELS as usize);
        let at = |c: u32| n[c as usize].as_str();
        assert_eq!(at(CH_I), "I_1.r");
        assert_eq!(at(CH_M_SRC), "M_src_1.r");
        assert_eq!(at(CH_M_TGT), "M_tgt.r");
        assert_eq!(at(CH_E_SRC), "E_src.r");
        assert_eq!(at(CH_E_ADD), "E_add.r");
        assert_eq!(at(CH_E_REM), "E_rem.r");
        assert_eq!(at(CH_DISPARITY), "disparity");
        assert_eq!(at(CH_NORMAL), "normal.x");
        assert_eq!(at(CH_VIEW_ANGLE), "view_angle");
        assert_eq!(at(CH_MIRROR_DIST), "mirror_distance_ratio");
    }
}
