//! The novel-view frame (§4.2.2, §4.3, §4.4, §5): G-buffer of the proxy in the novel camera,
//! reprojected composites, irradiance composites, target mirror, the view-dependent layer (glossy
//! mode), the 66-channel features, the network (or the ULR composite) and the output transform. One Rust file and one shader per
//! pass, each with a CPU reference on small inputs (tests/frame.rs). The passes share one
//! push-constant block, [`FrameConstants`] (`frame/frame_constants.glsl`), filled once a frame.

pub mod buffers;
pub mod constants;
pub mod emitters;
pub mod features;
pub mod glossy;
pub mod glossy_fit;
pub mod irradiance;
pub mod lighting;
pub mod live;
pub mod maps;
pub mod mode;
pub mod output;
pub mod reference;
pub mod renderer;
pub mod reproject;
pub mod scene;
pub mod sight;
pub mod sight_cache;
pub mod target_mirror;
pub mod view_cull;

pub use buffers::FrameBuffers;
pub use constants::FrameConstants;
pub use lighting::{added_lights, Lighting};
pub use maps::{HostMaps, LightingMap, MapFormat, ViewMaps};
pub use mode::{Mode, DEFAULT_MODE};
pub use reference::{LiveRef, RefInputs};
pub use renderer::{Renderer, FAR, NEAR};
pub use scene::{load_host_maps, FrameScene};

/// At most this many input views take part in one frame (`constants.table`; which ones:
/// [`view_cull`]).
pub const MAX_ACTIVE: usize = crate::constants::MAX_ACTIVE as usize;
