//! Constants shared with the shaders and the Python tools, generated from `engine/constants.table`
//! (their one source), and the tonemap of §5.2 that `MU` defines.

include!(concat!(env!("OUT_DIR"), "/constants.rs"));

/// log(1 + μx) / log(1 + μ) (§5.2).
pub fn tonemap(x: f32) -> f32 {
    (1.0 + MU * x.max(0.0)).ln() / (1.0 + MU).ln()
}

/// Inverse of [`tonemap`].
pub fn untonemap(y: f32) -> f32 {
    ((1.0 + MU).powf(y.max(0.0)) - 1.0) / MU
}
