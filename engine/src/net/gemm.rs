//! C = A·B on fp16 storage (`shaders_glsl/net/gemm*.comp`): the matrix core that the network's
//! convolutions are built on, and the smallest kernel that exercises both backends.

use crate::gpu::shaders;
use std::sync::Arc;

use half::f16;

use super::{backend_for, coop_spec, Backend, Storage};
use crate::error::{Error, Result};
use crate::gpu::{bytes_of, vk, Bind, Buffer, Gpu, MemoryLocation, Pipeline};

pub const TILE: u32 = 16;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    m: u32,
    n: u32,
    k: u32,
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout =
    crate::push_layout!(Push, [shaders::NET_GEMM, shaders::NET_GEMM_CM], [m, n, k]);

pub struct Gemm {
    pub backend: Backend,
    pipeline: Pipeline,
}

impl Gemm {
    pub fn new(gpu: &Arc<Gpu>) -> Result<Gemm> {
        Gemm::with_backend(gpu, backend_for(&gpu.caps, Storage::F16))
    }

    pub fn with_backend(gpu: &Arc<Gpu>, backend: Backend) -> Result<Gemm> {
        let pipeline = match backend {
            Backend::CoopMatrix => {
                Pipeline::compute_specialized(gpu, shaders::NET_GEMM_CM, &coop_spec(gpu)?)?
            }
            Backend::Portable | Backend::CpuLanes => Pipeline::compute(gpu, shaders::NET_GEMM)?,
        };
        Ok(Gemm { backend, pipeline })
    }

    /// `a` is m×k, `b` is k×n, row-major; all sizes multiples of [`TILE`]. Returns m×n in f32.
    pub fn run(&self, a: &[f16], b: &[f16], m: u32, n: u32, k: u32) -> Result<Vec<f32>> {
        if ![m, n, k].iter().all(|s| s.is_multiple_of(TILE)) {
            return Err(Error::Other(format!(
                "gemm {m}x{n}x{k}: sizes must be multiples of {TILE}"
            )));
        }
        if a.len() != (m * k) as usize || b.len() != (k * n) as usize {
            return Err(Error::Other(
                "gemm: matrix sizes do not match m, n, k".into(),
            ));
        }
        let gpu = &self.pipeline.gpu;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let ab = Buffer::from_slice(gpu, "gemm a", usage, a)?;
        let bb = Buffer::from_slice(gpu, "gemm b", usage, b)?;
        let cb = Buffer::new(
            gpu,
            "gemm c",
            (m * n * 4) as u64,
            usage,
            MemoryLocation::GpuOnly,
        )?;
        let push = Push { m, n, k };
        let mut res = Ok(());
        gpu.submit(|cmd| {
            res = self.pipeline.dispatch_groups(
                cmd,
                &[
                    ("MatA", Bind::Buffer(&ab)),
                    ("MatB", Bind::Buffer(&bb)),
                    ("MatC", Bind::Buffer(&cb)),
                ],
                bytes_of(&push),
                (n / TILE, m / TILE, 1),
            )
        })?;
        res?;
        let mut c: Vec<f32> = cb.download_vec()?;
        c.truncate((m * n) as usize);
        Ok(c)
    }
}
