//! Feature maps in pack4 layout and their element type in device memory.

use std::sync::Arc;

use half::f16;

use crate::error::{Error, Result};
use crate::gpu::{vk, Buffer, Gpu, MemoryLocation};

/// Element type of activations and weights in device memory (arithmetic is fp32 either way).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Storage {
    F16,
    F32,
}

impl Storage {
    pub fn bytes(self) -> u64 {
        match self {
            Storage::F16 => 2,
            Storage::F32 => 4,
        }
    }
}

/// A feature map in pack4 layout: channel groups of 4, index `(c4 * h + y) * w + x`.
pub struct Tensor {
    pub buf: Buffer,
    pub c: u32,
    pub h: u32,
    pub w: u32,
    pub storage: Storage,
}

impl Tensor {
    pub fn new(
        gpu: &Arc<Gpu>,
        name: &str,
        c: u32,
        h: u32,
        w: u32,
        storage: Storage,
    ) -> Result<Tensor> {
        let size = (c.div_ceil(4) * 4 * h * w) as u64 * storage.bytes();
        let buf = Buffer::new(
            gpu,
            name,
            size.max(16),
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST
                | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
            MemoryLocation::GpuOnly,
        )?;
        Ok(Tensor {
            buf,
            c,
            h,
            w,
            storage,
        })
    }

    pub fn c4(&self) -> u32 {
        self.c.div_ceil(4)
    }

    /// Converts planar CHW floats to this tensor's layout and element type.
    pub fn pack(&self, chw: &[f32]) -> Vec<u8> {
        let hw = (self.h * self.w) as usize;
        let mut v = vec![0f32; self.c4() as usize * 4 * hw];
        for c in 0..self.c as usize {
            for i in 0..hw {
                v[((c / 4) * hw + i) * 4 + c % 4] = chw[c * hw + i];
            }
        }
        match self.storage {
            Storage::F32 => bytemuck::cast_slice(&v).to_vec(),
            Storage::F16 => {
                let h: Vec<f16> = v.iter().map(|&x| f16::from_f32(x)).collect();
                bytemuck::cast_slice(&h).to_vec()
            }
        }
    }

    pub fn upload_chw(&self, chw: &[f32]) -> Result<()> {
        if chw.len() != (self.c * self.h * self.w) as usize {
            return Err(Error::Other(format!(
                "tensor upload: {} values for {}x{}x{}",
                chw.len(),
                self.c,
                self.h,
                self.w
            )));
        }
        self.buf.upload(&self.pack(chw))
    }

    /// Planar CHW floats (real channels only).
    pub fn download_chw(&self) -> Result<Vec<f32>> {
        let hw = (self.h * self.w) as usize;
        let n = self.c4() as usize * 4 * hw;
        let bytes = self
            .buf
            .download_range(0, n as u64 * self.storage.bytes())?;
        let v: Vec<f32> = match self.storage {
            Storage::F32 => bytemuck::pod_collect_to_vec(&bytes),
            Storage::F16 => bytemuck::pod_collect_to_vec::<u8, f16>(&bytes)
                .iter()
                .map(|x| x.to_f32())
                .collect(),
        };
        let mut out = vec![0f32; self.c as usize * hw];
        for c in 0..self.c as usize {
            for i in 0..hw {
                out[c * hw + i] = v[((c / 4) * hw + i) * 4 + c % 4];
            }
        }
        Ok(out)
    }
}
