//! The network's conv and upsample-add pipelines for one storage type and backend, their push
//! constants, and the recording of a layer on the backend chosen.

use std::sync::Arc;

use super::lanes::{words, LanesConv, LANES_BLOCKING};
use super::{pack_lanes, Conv, Epilogue, LanesPack, Storage, Tensor, OCB};
use crate::error::{Error, Result};
use crate::gpu::shaders;
use crate::gpu::{bytes_of, vk, Bind, Buffer, Gpu, Graph, Pipeline, Use};
use crate::net::{backend_for, coop_spec, Backend};

/// Output pixels per portable invocation (`PX` in conv_portable.glsl).
const PX: u32 = 8;

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

    /// Records `out = epilogue(conv(input))` as a pass of `g` (the weights are constant: they
    /// never need a barrier).
    pub fn conv(
        &self,
        g: &mut Graph,
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
        let res = ep.residual.unwrap_or(input);
        let uses = [
            Use::Read(Bind::Buffer(&input.buf)),
            Use::Read(Bind::Buffer(&res.buf)),
            Use::Write(Bind::Buffer(&out.buf)),
        ];
        g.compute("conv", &uses, |cmd| {
            self.record_conv(cmd, layer, input, out, ep)
        })
    }

    /// The dispatches of one layer on the chosen backend (shapes checked by `conv`).
    fn record_conv(
        &self,
        cmd: vk::CommandBuffer,
        layer: &Conv,
        input: &Tensor,
        out: &Tensor,
        ep: Epilogue,
    ) -> Result<()> {
        let (oh, ow) = (out.h, out.w);
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
            return lanes.record(cmd, layer, input, out, ep);
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
        Ok(())
    }

    /// Records `dst += bilinear_upsample(src)` as a pass of `g`.
    pub fn upsample_add(&self, g: &mut Graph, src: &Tensor, dst: &Tensor) -> Result<()> {
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
        let uses = [
            Use::Read(Bind::Buffer(&src.buf)),
            Use::ReadWrite(Bind::Buffer(&dst.buf)),
        ];
        g.compute("upsample add", &uses, |cmd| {
            self.record_up(cmd, src, dst, push, threads)
        })
    }

    fn record_up(
        &self,
        cmd: vk::CommandBuffer,
        src: &Tensor,
        dst: &Tensor,
        push: UpPush,
        threads: (u32, u32, u32),
    ) -> Result<()> {
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
        Ok(())
    }
}
