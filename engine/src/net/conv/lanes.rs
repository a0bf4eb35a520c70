//! The conv kernel shaped for CPU drivers (conv_lp_f32.comp): its push constants, blocking
//! and pipelines, one per (kernel size, stride).

use std::sync::Arc;

use super::{Conv, Epilogue, Tensor};
use crate::error::{Error, Result};
use crate::gpu::shaders;
use crate::gpu::{bytes_of, vk, Gpu, Pipeline};

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
pub(super) fn words(a: u64) -> [u32; 2] {
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
        if !crate::net::lanes_fit(&gpu.caps) {
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

    /// Records the dispatch of `out = epilogue(conv(input))`.
    pub(super) fn record(
        &self,
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
        pipe.dispatch_groups(cmd, &[], bytes_of(&push), grid)
    }
}
