//! The bake (§4.1–4.2): per-view maps computed once per scene from the input views.
//! One pass per file, each named after the paper's term, each with its CPU reference.

pub mod accuracy;
pub mod added_irradiance;
pub mod added_light;
pub mod albedo_mesh;
pub mod cache;
pub mod denoise;
pub mod light_levels;
pub mod mirror;
pub mod radiance_mesh;
pub mod random;
pub mod run;
pub mod source_cache;
pub mod source_irradiance;
pub mod storage;
pub mod surface_cache;
pub mod views;

pub use added_irradiance::AddedIrradiance;
pub use added_light::{AddedParams, GpuLight};
pub use albedo_mesh::AlbedoMesh;
pub use cache::BakeCache;
pub use denoise::{Denoise, DenoiseParams};
pub use mirror::Mirror;
pub use radiance_mesh::RadianceMesh;
pub use run::{bake, BakeParams, BakeReport, Progress};
pub use source_cache::SourceCache;
pub use source_irradiance::SourceIrradiance;
pub use surface_cache::{CacheLayout, GpuCacheLayout, SurfaceCache};
pub use views::{GpuViews, ViewData};
