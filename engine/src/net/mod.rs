//! The network of §5.1 in compute shaders. Every matrix kernel has a portable backend and a
//! cooperative-matrix backend (`*_cm.comp`) that share one include (bindings, packing, tiling,
//! epilogue), chosen at run time from the device's capabilities.

mod conv;
mod gemm;
mod model;

pub use conv::{
    conv_reference, pack_weights, upsample_add_reference, Conv, Epilogue, LanesConv, NetKernels,
    Storage, Tensor, OCB,
};
pub use gemm::Gemm;
pub use model::{NetBuffers, NetConfig, Network, Params, RandomParams, SafetensorsParams};

use crate::gpu::{vk, Caps};

/// Channels of the network input (§5: 8 + 8 composites, target mirror, 3 irradiance composites
/// and 6 extra features; the order is in `frame::features`).
pub const INPUT_CHANNELS: u32 = 66;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    CoopMatrix,
    Portable,
    /// Kernels shaped for CPU drivers (llvmpipe): lanes are output pixels, weights at uniform
    /// addresses (conv_lp_f32.comp). Chosen on CPU devices with fp32 storage.
    CpuLanes,
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
