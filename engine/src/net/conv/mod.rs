//! Convolution and upsample-and-add kernels of the network (§5.1), on "pack4" tensors
//! (`shaders_glsl/net/conv.glsl`). One generic conv kernel serves the 3×3 convs of the fixup
//! blocks, the 4×4 stride-2 downsampling and the output conv; its epilogue fuses the fixup
//! scalars, per-channel bias, residual and ReLU.
//!
//! Here: a layer and its weight packing. The tensors, the kernels that run layers, the
//! CPU-shaped conv and the CPU references have modules of their own.

mod kernels;
mod lanes;
mod reference;
mod tensor;

use std::sync::Arc;

use half::f16;

use crate::error::Result;
use crate::gpu::{vk, Buffer, Gpu};

pub use kernels::NetKernels;
pub(crate) use kernels::{CONV_PUSH_LAYOUT, UP_LANES_PUSH_LAYOUT, UP_PUSH_LAYOUT};
pub use lanes::LanesConv;
pub(crate) use lanes::LANES_PUSH_LAYOUT;
pub use reference::{conv_reference, upsample_add_reference};
pub use tensor::{Storage, Tensor};

/// Output channels per block (`OCB` in conv.glsl).
pub const OCB: u32 = 16;

/// A convolution layer with its weights packed for the kernels:
/// `[ocb][tap][ic padded to 16][16 output channels]`.
pub struct Conv {
    weights: Buffer,
    bias: Buffer,
    /// The CPU-shaped kernel's packing (`pack_lanes`), when the kernels have one.
    lanes: Option<LanesPack>,
    pub ic: u32,
    pub oc: u32,
    pub k: u32,
    pub stride: u32,
    pub pad: u32,
    icp: u32,
}

/// Packs OIHW weights (PyTorch order) into the kernels' order; returns (packed, icp, blocks).
pub fn pack_weights(w: &[f32], oc: u32, ic: u32, k: u32) -> (Vec<f32>, u32, u32) {
    let icp = ic.div_ceil(16) * 16;
    let blocks = oc.div_ceil(OCB);
    let taps = k * k;
    let mut p = vec![0f32; (blocks * taps * icp * OCB) as usize];
    for o in 0..oc {
        for i in 0..ic {
            for t in 0..taps {
                let src = ((o * ic + i) * taps + t) as usize;
                let dst = (((o / OCB * taps + t) * icp + i) * OCB + o % OCB) as usize;
                p[dst] = w[src];
            }
        }
    }
    (p, icp, blocks)
}

/// A layer's weights and bias in the order conv_lp_f32.comp reads them.
struct LanesPack {
    weights: Buffer,
    bias: Buffer,
}

/// Packs OIHW weights for the CPU-shaped kernel: `[output group of ocn][input group of 4]
/// [tap][4 input channels][ocn]`, zero where a channel does not exist, so the 8 lanes of a
/// vector read 8 output channels' weights of one (tap, input channel) side by side.
pub fn pack_lanes(w: &[f32], oc: u32, ic: u32, k: u32, ocn: u32) -> Vec<f32> {
    let (taps, ocn) = ((k * k) as usize, ocn as usize);
    let (c4, groups) = (ic.div_ceil(4) as usize, (oc as usize).div_ceil(ocn));
    let mut p = vec![0f32; groups * c4 * taps * 4 * ocn];
    for o in 0..oc as usize {
        for i in 0..ic as usize {
            for t in 0..taps {
                let dst = (((o / ocn * c4 + i / 4) * taps + t) * 4 + i % 4) * ocn + o % ocn;
                p[dst] = w[(o * ic as usize + i) * taps + t];
            }
        }
    }
    p
}

impl Conv {
    /// `weights` in OIHW order (`oc × ic × k × k`), `bias` per output channel.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        gpu: &Arc<Gpu>,
        storage: Storage,
        weights: &[f32],
        bias: Option<&[f32]>,
        oc: u32,
        ic: u32,
        k: u32,
        stride: u32,
        pad: u32,
    ) -> Result<Conv> {
        let (packed, icp, blocks) = pack_weights(weights, oc, ic, k);
        let u = vk::BufferUsageFlags::STORAGE_BUFFER;
        let wbuf = match storage {
            Storage::F32 => Buffer::from_slice(gpu, "conv weights", u, &packed)?,
            Storage::F16 => {
                let h: Vec<f16> = packed.iter().map(|&x| f16::from_f32(x)).collect();
                Buffer::from_slice(gpu, "conv weights", u, &h)?
            }
        };
        let mut b = vec![0f32; (blocks * OCB) as usize];
        if let Some(bias) = bias {
            b[..oc as usize].copy_from_slice(bias);
        }
        Ok(Conv {
            weights: wbuf,
            bias: Buffer::from_slice(gpu, "conv bias", u, &b)?,
            lanes: None,
            ic,
            oc,
            k,
            stride,
            pad,
            icp,
        })
    }

    /// Output size; 0 where the padded input is smaller than the kernel (a side of 1 pixel
    /// into a 4×4 conv wrapped around to 2^31 before, and the network never returned).
    pub fn out_size(&self, h: u32, w: u32) -> (u32, u32) {
        let side = |n: u32| {
            (n + 2 * self.pad)
                .checked_sub(self.k)
                .map_or(0, |d| d / self.stride + 1)
        };
        (side(h), side(w))
    }

    /// Multiply-adds × 2 at an input of h × w.
    pub fn flops(&self, h: u32, w: u32) -> f64 {
        let (oh, ow) = self.out_size(h, w);
        2.0 * (oh * ow) as f64 * (self.oc * self.ic * self.k * self.k) as f64
    }
}

/// The scalars and flags fused after a convolution:
/// `y = relu?((conv(x + in_bias) + bias) * scale + out_bias + residual?)`.
#[derive(Clone, Copy)]
pub struct Epilogue<'a> {
    pub in_bias: f32,
    pub out_bias: f32,
    pub scale: f32,
    pub relu: bool,
    pub residual: Option<&'a Tensor>,
}

impl Default for Epilogue<'_> {
    fn default() -> Self {
        Epilogue {
            in_bias: 0.0,
            out_bias: 0.0,
            scale: 1.0,
            relu: false,
            residual: None,
        }
    }
}
