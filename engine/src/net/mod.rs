//! The network of §5.1 in compute shaders. Every matrix kernel has a portable backend and a
//! cooperative-matrix backend (`*_cm.comp`) that share one include (bindings, packing, tiling,
//! epilogue), chosen at run time from the device's capabilities.

mod conv;
#[cfg(feature = "test-support")]
mod gemm;
mod model;
pub(crate) use conv::{CONV_PUSH_LAYOUT, LANES_PUSH_LAYOUT, UP_LANES_PUSH_LAYOUT, UP_PUSH_LAYOUT};
#[cfg(feature = "test-support")]
pub(crate) use gemm::PUSH_LAYOUT as GEMM_PUSH_LAYOUT;

pub use conv::{
    conv_reference, pack_lanes, pack_weights, upsample_add_reference, Conv, Epilogue, LanesConv,
    NetKernels, Storage, Tensor, OCB,
};
#[cfg(feature = "test-support")]
pub use gemm::Gemm;
pub use model::{
    NetBase, NetBuffers, NetConfig, Network, Params, RandomParams, SafetensorsParams, SHIPPED,
    SHIPPED_NAME,
};

use crate::error::{Error, Result};
use crate::gpu::{vk, Caps, Gpu};

/// Channels of the network input (§5: 8 + 8 composites, target mirror, 3 irradiance composites
/// and 6 extra features; the order is the CH_* rows of `engine/constants.table`).
pub const INPUT_CHANNELS: u32 = crate::constants::IN_CHANNELS;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    CoopMatrix,
    Portable,
    /// Kernels shaped for CPU drivers (llvmpipe): lanes are output pixels, weights broadcast
    /// between lanes (conv_lp_f32.comp). Chosen on CPU devices with fp32 storage whose
    /// subgroups have at least 8 lanes and offer subgroupBroadcast (`lanes_fit`).
    CpuLanes,
}

/// The cooperative-matrix shape the `*_cm.comp` kernels run with (`coop_shape.glsl`): one
/// subgroup of `subgroup` lanes per workgroup, `m`×`k` fp16 A tiles, `k`×`n` fp16 B tiles, fp32
/// accumulators.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CoopTile {
    pub subgroup: u32,
    pub m: u32,
    pub n: u32,
    pub k: u32,
}

impl CoopTile {
    /// Specialization constants 0–3 of `coop_shape.glsl`.
    pub fn spec(&self) -> [u32; 4] {
        [self.subgroup, self.m, self.n, self.k]
    }
}

/// The shape for the network's kernels among those the device offers: fp16 A/B, fp32
/// accumulators and result, subgroup scope, sides dividing 16 (a workgroup covers a 16×16 block
/// of the output, so packing and padding stay those of the portable kernels) and at most 4
/// accumulator tiles; the largest such shape. `None`: the portable kernels run.
pub fn coop_tile(caps: &Caps) -> Option<CoopTile> {
    let divides16 = |v: u32| v > 0 && 16 % v == 0;
    caps.coop_matrix
        .iter()
        .filter(|s| {
            s.a == vk::ComponentTypeKHR::FLOAT16
                && s.b == vk::ComponentTypeKHR::FLOAT16
                && s.c == vk::ComponentTypeKHR::FLOAT32
                && s.result == vk::ComponentTypeKHR::FLOAT32
                && s.scope == vk::ScopeKHR::SUBGROUP
                && divides16(s.m)
                && divides16(s.n)
                && divides16(s.k)
                && (16 / s.m) * (16 / s.n) <= 4
        })
        .max_by_key(|s| s.m * s.n * s.k)
        .filter(|_| {
            caps.subgroup_size > 0 && caps.subgroup_size <= caps.max_compute_workgroup_invocations
        })
        .map(|s| CoopTile {
            subgroup: caps.subgroup_size,
            m: s.m,
            n: s.n,
            k: s.k,
        })
}

/// The backend the network runs on for a storage type: the one decision behind both the
/// kernels (`NetKernels::new`, `Gemm::new`) and what `relit info` reports. fp16: cooperative
/// matrices where the device offers a shape that fits (`coop_tile`), else portable. fp32: the
/// CPU-shaped kernels on CPU devices, else portable.
pub fn backend_for(caps: &Caps, storage: Storage) -> Backend {
    match storage {
        Storage::F16 if coop_tile(caps).is_some() => Backend::CoopMatrix,
        Storage::F16 => Backend::Portable,
        Storage::F32 if caps.device_type == vk::PhysicalDeviceType::CPU && lanes_fit(caps) => {
            Backend::CpuLanes
        }
        Storage::F32 => Backend::Portable,
    }
}

/// Whether the CPU-shaped conv can run: its 8 lanes share weights with subgroupBroadcast.
pub fn lanes_fit(caps: &Caps) -> bool {
    caps.subgroup_size >= 8 && caps.subgroup_broadcast
}

/// One line for `relit info`: what runs with `storage`.
pub fn describe_backend(caps: &Caps, storage: Storage) -> String {
    match (backend_for(caps, storage), coop_tile(caps)) {
        (Backend::CoopMatrix, Some(t)) => format!(
            "cooperative matrix ({}x{}x{} fp16 tiles, fp32 accumulators, {} lanes)",
            t.m, t.n, t.k, t.subgroup
        ),
        (Backend::CpuLanes, _) => {
            "CPU-shaped (lanes are pixels, weights broadcast between lanes)".into()
        }
        _ => "portable".into(),
    }
}

/// The specialization constants of a `*_cm.comp` kernel on this device, or why it cannot run.
fn coop_spec(gpu: &Gpu) -> Result<[u32; 4]> {
    coop_tile(&gpu.caps).map(|t| t.spec()).ok_or_else(|| {
        Error::Other(format!(
            "{} offers no cooperative-matrix shape the network kernels fit (fp16 A/B, fp32 \
             accumulators, subgroup scope, sides dividing 16)",
            gpu.caps.name
        ))
    })
}
