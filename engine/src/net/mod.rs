//! The network's compute kernels (§5.1). Every kernel has a portable backend and a
//! cooperative-matrix backend (`*_cm.comp`) built from one tiling (a shared include), chosen
//! at run time from the device's capabilities.

mod gemm;

pub use gemm::Gemm;

use crate::gpu::{vk, Caps};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    CoopMatrix,
    Portable,
}

/// The backend for kernels written for 16×16×16 fp16 tiles with fp32 accumulators at subgroup
/// scope, run by one 32-wide subgroup per tile.
pub fn select_backend(caps: &Caps) -> Backend {
    let fits = caps.coop_matrix.iter().any(|s| {
        (s.m, s.n, s.k) == (16, 16, 16)
            && s.a == vk::ComponentTypeKHR::FLOAT16
            && s.b == vk::ComponentTypeKHR::FLOAT16
            && s.c == vk::ComponentTypeKHR::FLOAT32
            && s.result == vk::ComponentTypeKHR::FLOAT32
            && s.scope == vk::ScopeKHR::SUBGROUP
    });
    if fits && caps.subgroup_size == 32 {
        Backend::CoopMatrix
    } else {
        Backend::Portable
    }
}
