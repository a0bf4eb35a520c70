//! The Vulkan backend. It knows nothing of relighting: devices, memory, pipelines from
//! reflected SPIR-V, acceleration structures and timestamps.

mod accel;
mod barrier;
mod device;
pub mod gather;
mod graph;
mod memory;
mod pipeline;
pub mod present;
mod timer;

pub use accel::{AccelStruct, RayScene};
pub use barrier::BarrierCount;
pub use device::{
    list_devices, load_entry, validation_layer_available, Caps, CoopMatrixShape, DeviceChoice, Gpu,
    GpuOptions,
};
pub use graph::{Graph, Use};
pub use memory::{full_barrier, image_barrier, image_barriers, texel_size, Buffer, Image};
pub use pipeline::{
    layout_source, reflect, shaders, spirv, Access, Bind, GraphicsDesc, Pipeline, PushLayout,
    Reflected, Sampler, Shader,
};
pub use present::{PresentMode, Presenter};
pub use timer::Timer;

pub use ash::vk;
pub use gpu_allocator::MemoryLocation;

/// Views a plain-data value as bytes (push constants).
pub fn bytes_of<T: bytemuck::Pod>(v: &T) -> &[u8] {
    bytemuck::bytes_of(v)
}
