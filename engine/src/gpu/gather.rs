//! A storage-access probe: the same gather kernel reading its table through a storage-buffer
//! binding or through a buffer-device-address pointer (`shaders_glsl/gpu/gather*.comp`), so that
//! `relit bench gather` can show what a driver makes of each (on Mesa 25.0's llvmpipe: a loop
//! over the lanes with bounds checks, or one masked gather).

use crate::gpu::shaders;
use std::sync::Arc;

use super::{bytes_of, vk, Bind, Buffer, Gpu, Graph, MemoryLocation, Pipeline, Timer};
use crate::error::{Error, Result};

/// Loads per invocation (`LOADS` in gather.glsl).
pub const LOADS: u32 = 16;

/// How the kernel reads its table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    StorageBuffer,
    DeviceAddress,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    table_addr: [u32; 2],
    count: u32,
    mask: u32,
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    Push,
    [shaders::GPU_GATHER_SSBO, shaders::GPU_GATHER_BDA],
    [table_addr, count, mask]
);

/// The table index of load `k` of invocation `i` (`gather_index` in gather.glsl).
pub fn index(i: u32, k: u32, mask: u32) -> u32 {
    let mut h = i.wrapping_mul(2654435761) ^ k.wrapping_mul(40503).wrapping_add(0x9e3779b9);
    h ^= h >> 15;
    h = h.wrapping_mul(2246822519);
    h ^= h >> 13;
    h & mask
}

/// CPU reference: each invocation's sum of its loads.
pub fn reference(table: &[[f32; 4]], count: u32) -> Vec<[f32; 4]> {
    let mask = table.len() as u32 - 1;
    (0..count)
        .map(|i| {
            let mut s = [0f32; 4];
            for k in 0..LOADS {
                let v = table[index(i, k, mask) as usize];
                for c in 0..4 {
                    s[c] += v[c];
                }
            }
            s
        })
        .collect()
}

pub struct GatherProbe {
    ssbo: Pipeline,
    bda: Pipeline,
    table: Buffer,
    out: Buffer,
    mask: u32,
    count: u32,
    gpu: Arc<Gpu>,
}

impl GatherProbe {
    /// A probe over `table` (its length a power of two) with `count` invocations.
    pub fn new(gpu: &Arc<Gpu>, table: &[[f32; 4]], count: u32) -> Result<GatherProbe> {
        if !table.len().is_power_of_two() || table.len() > u32::MAX as usize {
            return Err(Error::Other(format!(
                "gather probe: the table has {} entries; expected a power of two",
                table.len()
            )));
        }
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        Ok(GatherProbe {
            ssbo: Pipeline::compute(gpu, shaders::GPU_GATHER_SSBO)?,
            bda: Pipeline::compute(gpu, shaders::GPU_GATHER_BDA)?,
            table: Buffer::from_slice(
                gpu,
                "gather table",
                usage | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                table,
            )?,
            out: Buffer::new(
                gpu,
                "gather sums",
                count as u64 * 16,
                usage,
                MemoryLocation::GpuOnly,
            )?,
            mask: table.len() as u32 - 1,
            count,
            gpu: gpu.clone(),
        })
    }

    /// Runs the kernel once with `access`; returns the sums and the GPU time in ms.
    pub fn run(&self, access: Access) -> Result<(Vec<[f32; 4]>, f64)> {
        let a = self.table.address;
        let push = Push {
            table_addr: [a as u32, (a >> 32) as u32],
            count: self.count,
            mask: self.mask,
        };
        let pipe = match access {
            Access::StorageBuffer => &self.ssbo,
            Access::DeviceAddress => &self.bda,
        };
        let binds: Vec<(&str, Bind)> = [
            ("Table", Bind::Buffer(&self.table)),
            ("Out", Bind::Buffer(&self.out)),
        ]
        .into_iter()
        .filter(|(n, _)| pipe.has_binding(n))
        .collect();
        let mut timer = Timer::new(&self.gpu, 1)?;
        let mut err = Ok(());
        self.gpu.submit(|cmd| {
            let mut g = Graph::new(&self.gpu, cmd, Some(&mut timer));
            err = g.dispatch_with("gather", pipe, &binds, bytes_of(&push), (self.count, 1, 1));
        })?;
        err?;
        let ms = timer.read()?[0].1;
        Ok((self.out.download_vec()?, ms))
    }
}
