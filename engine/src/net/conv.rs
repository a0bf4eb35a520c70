//! Convolution and upsample-and-add kernels of the network (§5.1), on "pack4" tensors
//! (`shaders_glsl/net/conv.glsl`). One generic conv kernel serves the 3×3 convs of the fixup
//! blocks, the 4×4 stride-2 downsampling and the output conv; its epilogue fuses the fixup
//! scalars, per-channel bias, residual and ReLU.

use crate::gpu::shaders;
use std::sync::Arc;

use half::f16;

use super::{backend_for, coop_spec, Backend};
use crate::error::{Error, Result};
use crate::gpu::{bytes_of, full_barrier, vk, Bind, Buffer, Gpu, MemoryLocation, Pipeline};

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

/// Output channels per block (`OCB` in conv.glsl).
pub const OCB: u32 = 16;
/// Output pixels per portable invocation (`PX` in conv_portable.glsl).
const PX: u32 = 8;

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

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ConvPush {
    in_w: u32,
    in_h: u32,
    in_c4: u32,
    out_w: u32,
    out_h: u32,
    out_c: u32,
    ksize: u32,
    stride: u32,
    pad: u32,
    icp: u32,
    in_bias: f32,
    out_bias: f32,
    scale: f32,
    flags: u32,
    ocb_base: u32,
}

/// ConvPush as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const CONV_PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    ConvPush,
    [
        shaders::NET_CONV,
        shaders::NET_CONV_F32,
        shaders::NET_CONV_R,
        shaders::NET_CONV_R_F32,
        shaders::NET_CONV_CM
    ],
    [
        in_w, in_h, in_c4, out_w, out_h, out_c, ksize, stride, pad, icp, in_bias, out_bias, scale,
        flags, ocb_base
    ]
);

/// Push constants of conv_lp_f32.comp (scalar layout; addresses as low, high words).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct LanesPush {
    in_addr: [u32; 2],
    out_addr: [u32; 2],
    res_addr: [u32; 2],
    w_addr: [u32; 2],
    bias_addr: [u32; 2],
    in_w: u32,
    in_h: u32,
    in_c4: u32,
    out_w: u32,
    out_h: u32,
    out_c: u32,
    pad: u32,
    flags: u32,
    in_bias: f32,
    out_bias: f32,
    scale: f32,
}

/// LanesPush as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const LANES_PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    LanesPush,
    [shaders::NET_CONV_LP_F32],
    [
        in_addr, out_addr, res_addr, w_addr, bias_addr, in_w, in_h, in_c4, out_w, out_h, out_c,
        pad, flags, in_bias, out_bias, scale
    ]
);

/// A device address as the shader's uvec2 (low, high).
fn words(a: u64) -> [u32; 2] {
    [a as u32, (a >> 32) as u32]
}

/// The CPU-shaped kernel's blocking: (output channels, rows) per invocation. Measured with
/// `relit bench net --width 66 --lanes OCN,ROWS --repeats 3` on lavapipe 25.0.7 (AVX-512
/// host, 2 cores, load 1.8, 2026-11-24; GFLOP/s, two sweeps): (8, 2) 45.0 / 44.1, (8, 3)
/// 51.6 / 52.9, **(8, 4) 60.3 / 56.1**, (8, 5) 56.5 / 54.7, (8, 6) 48.0 / 46.6, (16, 2)
/// 51.0 / 50.4, (16, 3) 40.0 / 39.9, (16, 4) 48.7 / 48.7; at width 32, (8, 4) 56.8 and
/// (16, 2) 58.5. The accumulators spill at all of these; more rows buy fewer gathers per
/// multiply-add. LLVM's register allocation makes these figures move with small changes to
/// the shader: measure again after editing it.
pub const LANES_BLOCKING: (u32, u32) = (8, 4);

/// (kernel size, stride) of the network's convolutions (§5.1): 3×3 blocks and output, 4×4/2
/// downsampling, 1×1 heads.
const LANES_SHAPES: [(u32, u32); 3] = [(3, 1), (4, 2), (1, 1)];

/// The conv kernel shaped for CPU drivers (conv_lp_f32.comp): lanes are 8 output pixels, each
/// invocation holds `ocn` output channels × `rows` rows, weights are broadcast between lanes,
/// one dispatch per layer (see the shader's header). One pipeline per (kernel size, stride).
pub struct LanesConv {
    pipes: Vec<((u32, u32), Pipeline)>,
    pub ocn: u32,
    pub rows: u32,
}

impl LanesConv {
    /// `ocn`: output channels per invocation, 8 to 32 by 8; `rows`: 1 to 8.
    pub fn new(gpu: &Arc<Gpu>, ocn: u32, rows: u32) -> Result<LanesConv> {
        if !super::lanes_fit(&gpu.caps) {
            return Err(Error::Other(format!(
                "conv_lp: {} has {}-lane subgroups{} (the kernel needs 8 or more and subgroupBroadcast)",
                gpu.caps.name,
                gpu.caps.subgroup_size,
                if gpu.caps.subgroup_broadcast { "" } else { " without subgroupBroadcast" }
            )));
        }
        if !(8..=32).contains(&ocn) || !ocn.is_multiple_of(8) || !(1..=8).contains(&rows) {
            return Err(Error::Other(format!(
                "conv_lp: {ocn} output channels per invocation, {rows} rows (expected 8, 16, 24 or 32; 1 to 8)"
            )));
        }
        let pipes = LANES_SHAPES
            .iter()
            .map(|&(k, s)| {
                Pipeline::compute_specialized(gpu, shaders::NET_CONV_LP_F32, &[k, s, ocn, rows])
                    .map(|p| ((k, s), p))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(LanesConv { pipes, ocn, rows })
    }

    /// Records the dispatch of `out = epilogue(conv(input))` and a barrier.
    fn record(
        &self,
        gpu: &Arc<Gpu>,
        cmd: vk::CommandBuffer,
        layer: &Conv,
        input: &Tensor,
        out: &Tensor,
        ep: Epilogue,
    ) -> Result<()> {
        let Some((_, pipe)) = self
            .pipes
            .iter()
            .find(|(ks, _)| *ks == (layer.k, layer.stride))
        else {
            return Err(Error::Other(format!(
                "conv_lp: no kernel for {0}×{0} stride {1}",
                layer.k, layer.stride
            )));
        };
        let Some(pack) = &layer.lanes else {
            return Err(Error::Other(
                "conv_lp: the layer was not packed for these kernels (NetKernels::layer)".into(),
            ));
        };
        let push = LanesPush {
            in_addr: words(input.buf.address),
            out_addr: words(out.buf.address),
            res_addr: words(ep.residual.map_or(0, |r| r.buf.address)),
            w_addr: words(pack.weights.address),
            bias_addr: words(pack.bias.address),
            in_w: input.w,
            in_h: input.h,
            in_c4: input.c4(),
            out_w: out.w,
            out_h: out.h,
            out_c: layer.oc,
            pad: layer.pad,
            flags: u32::from(ep.relu) | if ep.residual.is_some() { 2 } else { 0 },
            in_bias: ep.in_bias,
            out_bias: ep.out_bias,
            scale: ep.scale,
        };
        let grid = (
            out.w.div_ceil(8),
            out.h.div_ceil(4 * self.rows),
            layer.oc.div_ceil(self.ocn),
        );
        pipe.dispatch_groups(cmd, &[], bytes_of(&push), grid)?;
        full_barrier(gpu, cmd);
        Ok(())
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct UpPush {
    src_w: u32,
    src_h: u32,
    dst_w: u32,
    dst_h: u32,
    c4: u32,
}

/// UpPush as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const UP_PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    UpPush,
    [shaders::NET_UPSAMPLE_ADD, shaders::NET_UPSAMPLE_ADD_F32],
    [src_w, src_h, dst_w, dst_h, c4]
);

/// Push constants of upsample_add_lp_f32.comp: the tensors by pointer, then UpPush's sizes.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct UpLanesPush {
    src_addr: [u32; 2],
    dst_addr: [u32; 2],
    sizes: UpPush,
}

/// UpLanesPush as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const UP_LANES_PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    UpLanesPush,
    [shaders::NET_UPSAMPLE_ADD_LP_F32],
    [
        src_addr,
        dst_addr,
        sizes.src_w,
        sizes.src_h,
        sizes.dst_w,
        sizes.dst_h,
        sizes.c4
    ]
);

/// The network's pipelines for one storage type and backend.
pub struct NetKernels {
    pub backend: Backend,
    pub storage: Storage,
    conv: Pipeline,
    /// The CPU-shaped conv, when `backend` is `Backend::CpuLanes`.
    lanes: Option<LanesConv>,
    /// Portable only: the kernel for a last block with at most 4 real channels.
    conv_rem: Option<Pipeline>,
    up: Pipeline,
    pub gpu: Arc<Gpu>,
}

impl NetKernels {
    /// The backend the device supports: cooperative matrices need fp16 storage.
    pub fn new(gpu: &Arc<Gpu>, storage: Storage) -> Result<NetKernels> {
        NetKernels::with_backend(gpu, storage, backend_for(&gpu.caps, storage))
    }

    /// A convolution layer (OIHW `weights`) packed for these kernels.
    #[allow(clippy::too_many_arguments)]
    pub fn layer(
        &self,
        weights: &[f32],
        bias: Option<&[f32]>,
        oc: u32,
        ic: u32,
        k: u32,
        stride: u32,
        pad: u32,
    ) -> Result<Conv> {
        let mut c = Conv::new(
            &self.gpu,
            self.storage,
            weights,
            bias,
            oc,
            ic,
            k,
            stride,
            pad,
        )?;
        if let Some(l) = &self.lanes {
            let w = pack_lanes(weights, oc, ic, k, l.ocn);
            let mut b = vec![0f32; oc.div_ceil(l.ocn) as usize * l.ocn as usize];
            b[..bias.map_or(0, |b| b.len())].copy_from_slice(bias.unwrap_or(&[]));
            let u =
                vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
            c.lanes = Some(LanesPack {
                weights: Buffer::from_slice(&self.gpu, "conv weights (lanes)", u, &w)?,
                bias: Buffer::from_slice(&self.gpu, "conv bias (lanes)", u, &b)?,
            });
        }
        Ok(c)
    }

    /// The CPU-shaped kernels with an explicit blocking (`LanesConv::new`), fp32 storage.
    pub fn with_lanes(gpu: &Arc<Gpu>, ocn: u32, rows: u32) -> Result<NetKernels> {
        let mut k = NetKernels::with_backend(gpu, Storage::F32, Backend::CpuLanes)?;
        k.lanes = Some(LanesConv::new(gpu, ocn, rows)?);
        Ok(k)
    }

    pub fn with_backend(gpu: &Arc<Gpu>, storage: Storage, backend: Backend) -> Result<NetKernels> {
        let conv = match (storage, backend) {
            (Storage::F16, Backend::CoopMatrix) => {
                Pipeline::compute_specialized(gpu, shaders::NET_CONV_CM, &coop_spec(gpu)?)?
            }
            (Storage::F16, Backend::Portable) => Pipeline::compute(gpu, shaders::NET_CONV)?,
            (Storage::F32, Backend::Portable | Backend::CpuLanes) => {
                Pipeline::compute(gpu, shaders::NET_CONV_F32)?
            }
            (Storage::F32, Backend::CoopMatrix) => {
                return Err(Error::Other(
                    "the cooperative-matrix kernels need fp16 storage".into(),
                ))
            }
            (Storage::F16, Backend::CpuLanes) => {
                return Err(Error::Other(
                    "the CPU-shaped kernels need fp32 storage".into(),
                ))
            }
        };
        let up = match (storage, backend) {
            (Storage::F16, _) => shaders::NET_UPSAMPLE_ADD,
            (Storage::F32, Backend::CpuLanes) => shaders::NET_UPSAMPLE_ADD_LP_F32,
            (Storage::F32, _) => shaders::NET_UPSAMPLE_ADD_F32,
        };
        let conv_rem = match (storage, backend) {
            (Storage::F16, Backend::Portable) => Some(Pipeline::compute(gpu, shaders::NET_CONV_R)?),
            (Storage::F32, Backend::Portable) => {
                Some(Pipeline::compute(gpu, shaders::NET_CONV_R_F32)?)
            }
            _ => None,
        };
        let lanes = match backend {
            Backend::CpuLanes => Some(LanesConv::new(gpu, LANES_BLOCKING.0, LANES_BLOCKING.1)?),
            _ => None,
        };
        Ok(NetKernels {
            backend,
            storage,
            conv,
            lanes,
            conv_rem,
            up: Pipeline::compute(gpu, up)?,
            gpu: gpu.clone(),
        })
    }

    /// Records `out = epilogue(conv(input))` and a barrier.
    pub fn conv(
        &self,
        cmd: vk::CommandBuffer,
        layer: &Conv,
        input: &Tensor,
        out: &Tensor,
        ep: Epilogue,
    ) -> Result<()> {
        let (oh, ow) = layer.out_size(input.h, input.w);
        if input.c != layer.ic || out.c != layer.oc || (out.h, out.w) != (oh, ow) {
            return Err(Error::Other(format!(
                "conv {}→{} k{} s{}: input {}x{}x{}, output {}x{}x{} (expected {}x{}x{})",
                layer.ic,
                layer.oc,
                layer.k,
                layer.stride,
                input.c,
                input.h,
                input.w,
                out.c,
                out.h,
                out.w,
                layer.oc,
                oh,
                ow
            )));
        }
        let push = ConvPush {
            in_w: input.w,
            in_h: input.h,
            in_c4: input.c4(),
            out_w: ow,
            out_h: oh,
            out_c: layer.oc,
            ksize: layer.k,
            stride: layer.stride,
            pad: layer.pad,
            icp: layer.icp,
            in_bias: ep.in_bias,
            out_bias: ep.out_bias,
            scale: ep.scale,
            flags: u32::from(ep.relu) | if ep.residual.is_some() { 2 } else { 0 },
            ocb_base: 0,
        };
        let res = ep.residual.unwrap_or(input);
        let binds = [
            ("In", Bind::Buffer(&input.buf)),
            ("Wt", Bind::Buffer(&layer.weights)),
            ("Bias", Bind::Buffer(&layer.bias)),
            ("Res", Bind::Buffer(&res.buf)),
            ("Out", Bind::Buffer(&out.buf)),
        ];
        if let Some(lanes) = &self.lanes {
            return lanes.record(&self.gpu, cmd, layer, input, out, ep);
        }
        let (full, rem) = (layer.oc / OCB, layer.oc % OCB);
        match (&self.conv_rem, self.backend) {
            // A last block with ≤ 4 real channels: the remainder kernel does 1/4 of a block.
            (Some(r), Backend::Portable) if (1..=4).contains(&rem) => {
                let grid = |z| (ow.div_ceil(PX * 8), oh.div_ceil(8), z);
                if full > 0 {
                    self.conv
                        .dispatch_groups(cmd, &binds, bytes_of(&push), grid(full))?;
                }
                let push = ConvPush {
                    ocb_base: full,
                    ..push
                };
                r.dispatch_groups(cmd, &binds, bytes_of(&push), grid(1))?;
            }
            (_, Backend::Portable | Backend::CpuLanes) => {
                let grid = (ow.div_ceil(PX * 8), oh.div_ceil(8), layer.oc.div_ceil(OCB));
                self.conv
                    .dispatch_groups(cmd, &binds, bytes_of(&push), grid)?;
            }
            (_, Backend::CoopMatrix) => {
                let grid = (ow.div_ceil(16), oh, layer.oc.div_ceil(OCB));
                self.conv
                    .dispatch_groups(cmd, &binds, bytes_of(&push), grid)?;
            }
        }
        full_barrier(&self.gpu, cmd);
        Ok(())
    }

    /// Records `dst += bilinear_upsample(src)` and a barrier.
    pub fn upsample_add(&self, cmd: vk::CommandBuffer, src: &Tensor, dst: &Tensor) -> Result<()> {
        if src.c != dst.c {
            return Err(Error::Other("upsample_add: channel counts differ".into()));
        }
        let push = UpPush {
            src_w: src.w,
            src_h: src.h,
            dst_w: dst.w,
            dst_h: dst.h,
            c4: dst.c4(),
        };
        let threads = (dst.w * dst.h * dst.c4(), 1, 1);
        if self.lanes.is_some() {
            let push = UpLanesPush {
                src_addr: words(src.buf.address),
                dst_addr: words(dst.buf.address),
                sizes: push,
            };
            self.up.dispatch(cmd, &[], bytes_of(&push), threads)?;
        } else {
            let binds = [
                ("Src", Bind::Buffer(&src.buf)),
                ("Dst", Bind::Buffer(&dst.buf)),
            ];
            self.up.dispatch(cmd, &binds, bytes_of(&push), threads)?;
        }
        full_barrier(&self.gpu, cmd);
        Ok(())
    }
}

/// CPU reference of [`NetKernels::conv`] on planar CHW data (OIHW weights), in f64.
#[allow(clippy::too_many_arguments)]
pub fn conv_reference(
    x: &[f32],
    (c, h, w): (u32, u32, u32),
    weights: &[f32],
    bias: &[f32],
    oc: u32,
    (k, stride, pad): (u32, u32, u32),
    in_bias: f32,
    out_bias: f32,
    scale: f32,
    relu: bool,
    residual: Option<&[f32]>,
) -> Vec<f32> {
    let oh = (h + 2 * pad - k) / stride + 1;
    let ow = (w + 2 * pad - k) / stride + 1;
    let mut out = vec![0f32; (oc * oh * ow) as usize];
    for o in 0..oc {
        for y in 0..oh {
            for xo in 0..ow {
                let mut acc = 0f64;
                for i in 0..c {
                    for ky in 0..k {
                        for kx in 0..k {
                            let iy = (y * stride + ky) as i64 - pad as i64;
                            let ix = (xo * stride + kx) as i64 - pad as i64;
                            if iy < 0 || ix < 0 || iy >= h as i64 || ix >= w as i64 {
                                continue;
                            }
                            let v = x[((i * h) as i64 * w as i64 + iy * w as i64 + ix) as usize]
                                as f64
                                + in_bias as f64;
                            acc += v * weights[(((o * c + i) * k + ky) * k + kx) as usize] as f64;
                        }
                    }
                }
                let idx = ((o * oh + y) * ow + xo) as usize;
                let mut v = (acc + bias[o as usize] as f64) * scale as f64 + out_bias as f64;
                if let Some(r) = residual {
                    v += r[idx] as f64;
                }
                if relu {
                    v = v.max(0.0);
                }
                out[idx] = v as f32;
            }
        }
    }
    out
}

/// CPU reference of [`NetKernels::upsample_add`]: `dst + up(src)`, planar CHW.
pub fn upsample_add_reference(
    src: &[f32],
    (c, sh, sw): (u32, u32, u32),
    dst: &[f32],
    (dh, dw): (u32, u32),
) -> Vec<f32> {
    let coord = |d: u32, n_in: u32, n_out: u32| {
        let s = ((d as f64 + 0.5) * n_in as f64 / n_out as f64 - 0.5).max(0.0);
        let i0 = (s as u32).min(n_in - 1);
        (i0, (i0 + 1).min(n_in - 1), s - i0 as f64)
    };
    let mut out = dst.to_vec();
    for ch in 0..c {
        for y in 0..dh {
            let (y0, y1, fy) = coord(y, sh, dh);
            for x in 0..dw {
                let (x0, x1, fx) = coord(x, sw, dw);
                let at = |yy: u32, xx: u32| src[((ch * sh + yy) * sw + xx) as usize] as f64;
                let top = at(y0, x0) * (1.0 - fx) + at(y0, x1) * fx;
                let bot = at(y1, x0) * (1.0 - fx) + at(y1, x1) * fx;
                out[((ch * dh + y) * dw + x) as usize] += (top * (1.0 - fy) + bot * fy) as f32;
            }
        }
    }
    out
}
