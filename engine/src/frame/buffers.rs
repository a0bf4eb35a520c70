//! A frame's buffers at one resolution: the G-buffer and every pass's output.

use std::sync::Arc;

use super::{glossy, irradiance, reproject, view_cull, FrameScene, MAX_ACTIVE};
use crate::error::Result;
use crate::gpu::{vk, Buffer, Gpu, MemoryLocation};
use crate::net::{Network, Storage, Tensor, INPUT_CHANNELS};
use crate::raster::Gbuffer;

// The views seen per pixel are a uvec2 of bits (reproject.comp).
const _: () = assert!(MAX_ACTIVE <= 64);

/// Per-resolution buffers of a frame.
pub struct FrameBuffers {
    pub width: u32,
    pub height: u32,
    pub gbuf: Gbuffer,
    pub comp: Buffer,
    /// Per pixel, bit a: whether active view a sees its point (written by reproject, read by
    /// the glossy layer).
    pub views_seen: Buffer,
    pub irr: Buffer,
    pub mirror: Buffer,
    /// The view-dependent layer: (D, s), (S, lobe + 1) per pixel ([`glossy`]).
    pub glossy: Buffer,
    /// The layer's per-pixel sums over the views, which its pass pools ([`glossy`]).
    pub glossy_sums: Buffer,
    pub active: Buffer,
    /// The novel camera (`NovelCamera`, a [`crate::scene::GpuCamera`]): the output pass's
    /// rays, too large for [`super::FrameConstants`].
    pub camera: Buffer,
    /// The view culling's visibility bits and grid points (host-readable).
    pub cull_seen: Buffer,
    pub cull_points: Buffer,
    pub intensity: Buffer,
    /// The original lights' factors (`Keep`, [`Lighting::keep_buffer`]).
    pub keep: Buffer,
    /// Each glossy slot's column in the sight cache (`SightCols`, [`super::sight_cache`]).
    pub sight_cols: Buffer,
    pub input: Tensor,
    pub hdr: Buffer,
    pub ldr: Buffer,
    pub(crate) net: Option<crate::net::NetBuffers>,
    pub(crate) dummy_net_out: Tensor,
}

impl FrameBuffers {
    /// The buffers of `scene`'s frames at `width` × `height`, with the network's when there is
    /// one.
    pub fn new(
        gpu: &Arc<Gpu>,
        scene: &FrameScene,
        (net, storage): (Option<&Network>, Storage),
        width: u32,
        height: u32,
    ) -> Result<FrameBuffers> {
        let n = (width * height) as u64;
        let alloc = |name: &str, size: u64, at: MemoryLocation| {
            let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
            Buffer::new(gpu, name, size.max(16), usage, at)
        };
        let buf = |name: &str, size: u64| alloc(name, size, MemoryLocation::GpuOnly);
        // The view culling's bits are read back by the host.
        let readable = |name: &str, size: u64| alloc(name, size, MemoryLocation::GpuToCpu);
        let grid = view_cull::grid(width, height);
        let nl = scene.lights.len().max(1) as u64;
        Ok(FrameBuffers {
            width,
            height,
            gbuf: Gbuffer::new(gpu, width, height)?,
            comp: buf("frame composites", reproject::PLANES as u64 * n * 8)?,
            views_seen: buf("frame views seen", n * 8)?,
            irr: buf("frame irradiance", irradiance::PLANES as u64 * n * 16)?,
            mirror: buf("frame target mirror", n * 16)?,
            glossy: buf("frame glossy layer", glossy::PLANES as u64 * n * 16)?,
            glossy_sums: buf("frame glossy sums", glossy::SUM_PLANES as u64 * n * 16)?,
            active: buf("frame active views", MAX_ACTIVE as u64 * 4)?,
            camera: buf(
                "frame novel camera",
                std::mem::size_of::<crate::scene::GpuCamera>() as u64,
            )?,
            cull_seen: readable(
                "view culling bits",
                (view_cull::words(grid) * scene.views.count as usize * 4) as u64,
            )?,
            cull_points: readable("view culling points", (grid.0 * grid.1 * 16) as u64)?,
            intensity: buf("frame intensities", nl * 4)?,
            keep: buf(
                "frame original factors",
                scene.originals.len().max(1) as u64 * 16,
            )?,
            sight_cols: buf(
                "frame sight columns",
                super::sight_cache::COLUMNS as u64 * 4,
            )?,
            input: Tensor::new(gpu, "frame input", INPUT_CHANNELS, height, width, storage)?,
            hdr: buf("frame hdr", n * 16)?,
            ldr: buf("frame ldr", n * 4)?,
            net: match net {
                Some(net) => Some(net.buffers(height, width)?),
                None => None,
            },
            dummy_net_out: Tensor::new(gpu, "no network", 6, 1, 1, storage)?,
        })
    }

    /// The 16 composite planes (I_1..8, M_src_1..8; stored as half floats) as f32.
    pub fn composites(&self) -> Result<Vec<[f32; 4]>> {
        let n = reproject::PLANES * (self.width * self.height) as usize;
        let h: Vec<half::f16> =
            bytemuck::pod_collect_to_vec(&self.comp.download_range(0, n as u64 * 8)?);
        Ok(h.chunks_exact(4)
            .map(|c| [c[0].to_f32(), c[1].to_f32(), c[2].to_f32(), c[3].to_f32()])
            .collect())
    }
}
