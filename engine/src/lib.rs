//! Relit engine: free-viewpoint neural relighting of captured indoor scenes
//! (Philip et al., ACM TOG 2021) on hand-written Vulkan.
//!
//! - [`gpu`]: the Vulkan backend. It knows nothing of relighting: device, memory, pipelines
//!   built from reflected SPIR-V, acceleration structures, timestamps.
//! - [`scene`]: scene formats (Relit's `scene.json`, COLMAP text, SIBR/Bundler), meshes, images.
//! - [`raster`]: the G-buffer of a mesh seen from a camera.
//! - [`trace`]: generic ray casting with ray queries (tests, `relit bench rays`).
//! - [`net`]: the network's kernels (§5.1), each with a cooperative-matrix and a portable backend.
//! - [`bake`]: the per-view maps of §4.1–4.2 (source irradiance, …).
//! - [`cpu`]: CPU references used by the tests and by tools.

pub mod bake;
pub mod cpu;
pub mod error;
pub mod frame;
pub mod gpu;
pub mod net;
pub mod raster;
pub mod scene;
pub mod trace;

pub use error::{Error, Result};
