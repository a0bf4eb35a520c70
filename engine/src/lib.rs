//! Relit engine: free-viewpoint neural relighting of captured indoor scenes
//! (Philip et al., ACM TOG 2021) on hand-written Vulkan.
//!
//! - [`gpu`]: the Vulkan backend. It knows nothing of relighting: device, memory, pipelines
//!   built from reflected SPIR-V, acceleration structures, timestamps.
//! - [`scene`]: scene formats (Relit's `scene.json`, COLMAP binary or text, SIBR/Bundler), meshes, images.
//! - [`raster`]: the G-buffer of a mesh seen from a camera.
//! - [`trace`]: generic ray casting with ray queries (tests, `relit bench rays`).
//! - [`net`]: the network's kernels (§5.1), each with a cooperative-matrix and a portable backend.
//! - [`bake`]: the per-view maps of §4.1–4.2 (source irradiance, …).
//! - [`cpu`]: CPU references used by the tests and by tools.
//! - [`constants`]: what Rust, GLSL and Python share (`engine/constants.table`).

pub mod bake;
pub mod constants;
pub mod cpu;
pub mod error;
pub mod frame;
pub mod gpu;
pub mod net;
pub mod raster;
pub mod scene;
pub mod trace;
pub mod view;

pub use error::{Error, Result};

/// Every pass's push-constant struct as Rust lays it out; tests/gpu.rs holds each against the
/// block its shaders declare (reflected member offsets and size).
pub fn push_layouts() -> Vec<gpu::PushLayout> {
    #[cfg_attr(not(feature = "test-support"), allow(unused_mut))]
    let mut all = vec![
        crate::net::CONV_PUSH_LAYOUT,
        crate::net::LANES_PUSH_LAYOUT,
        crate::net::UP_PUSH_LAYOUT,
        crate::net::UP_LANES_PUSH_LAYOUT,
        crate::trace::PUSH_LAYOUT,
        crate::frame::constants::PUSH_LAYOUT,
        crate::frame::view_cull::PUSH_LAYOUT,
        crate::frame::sight_cache::PUSH_LAYOUT,
        crate::bake::surface_cache::PUSH_LAYOUT,
        crate::bake::source_irradiance::PUSH_LAYOUT,
        crate::bake::radiance_mesh::PUSH_LAYOUT,
        crate::bake::storage::PUSH_LAYOUT,
        crate::bake::added_irradiance::PUSH_LAYOUT,
        crate::bake::denoise::PUSH_LAYOUT,
        crate::bake::mirror::PUSH_LAYOUT,
        crate::bake::albedo_mesh::PUSH_LAYOUT,
        crate::gpu::gather::PUSH_LAYOUT,
        crate::view::compose::PUSH_LAYOUT,
        crate::raster::PUSH_LAYOUT,
    ];
    #[cfg(feature = "test-support")]
    all.push(crate::net::GEMM_PUSH_LAYOUT);
    all
}
