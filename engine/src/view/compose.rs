//! The window's picture (`shaders_glsl/view/compose.comp`): the rendered frame scaled into the
//! window with its aspect kept, the HUD drawn over it, in the swapchain's byte order. One pass
//! at window size, so the HUD's text is sharp whatever the render resolution.

use std::sync::Arc;

use crate::error::Result;
use crate::gpu::{bytes_of, shaders, vk, Bind, Buffer, Gpu, Graph, MemoryLocation, Pipeline};

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Push {
    pub src_w: u32,
    pub src_h: u32,
    pub dst_w: u32,
    pub dst_h: u32,
    pub fit_x: u32,
    pub fit_y: u32,
    pub fit_w: u32,
    pub fit_h: u32,
    pub hud_x: u32,
    pub hud_y: u32,
    pub cols: u32,
    pub rows: u32,
    pub scale: u32,
    pub bgr: u32,
}

/// Push as its shader's push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    Push,
    [shaders::VIEW_COMPOSE],
    [
        src_w, src_h, dst_w, dst_h, fit_x, fit_y, fit_w, fit_h, hud_x, hud_y, cols, rows, scale,
        bgr
    ]
);

/// Text for the HUD: `rows` lines of `cols` character codes (ASCII; others show as '?').
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HudText {
    pub cols: u32,
    pub rows: u32,
    pub cells: Vec<u32>,
}

impl HudText {
    pub fn new(lines: &[String]) -> HudText {
        let cols = lines.iter().map(|l| l.chars().count()).max().unwrap_or(0) as u32;
        let mut cells = Vec::with_capacity((cols as usize) * lines.len());
        for l in lines {
            let mut row: Vec<u32> = (l.chars())
                .map(|c| if c.is_ascii() { c as u32 } else { '?' as u32 })
                .collect();
            row.resize(cols as usize, ' ' as u32);
            cells.extend(row);
        }
        HudText {
            cols,
            rows: lines.len() as u32,
            cells,
        }
    }
}

/// The font's glyphs as the shader reads them: glyph g's rows r at word 2g + r/4, byte r%4.
pub fn font_words() -> Vec<u32> {
    font8x8::legacy::BASIC_LEGACY
        .iter()
        .flat_map(|g| {
            [
                u32::from_le_bytes([g[0], g[1], g[2], g[3]]),
                u32::from_le_bytes([g[4], g[5], g[6], g[7]]),
            ]
        })
        .collect()
}

/// The rectangle (x, y, w, h) a `src`-sized frame fills in a `dst`-sized window, aspect kept.
pub fn fit(src: (u32, u32), dst: (u32, u32)) -> (u32, u32, u32, u32) {
    let (sw, sh) = (src.0.max(1) as u64, src.1.max(1) as u64);
    let (dw, dh) = (dst.0 as u64, dst.1 as u64);
    let (w, h) = if dw * sh <= dh * sw {
        (dw, (dw * sh / sw).max(1))
    } else {
        ((dh * sw / sh).max(1), dh)
    };
    (
        ((dw - w) / 2) as u32,
        ((dh - h) / 2) as u32,
        w as u32,
        h as u32,
    )
}

/// Font pixels per screen pixel for a window of height `h`: text stays readable on large screens.
pub fn hud_scale(h: u32) -> u32 {
    (h / 480).clamp(1, 4)
}

/// The push constants for a frame of size `src` in a window of size `dst`.
pub fn push(src: (u32, u32), dst: (u32, u32), hud: Option<&HudText>, bgr: bool) -> Push {
    let (fit_x, fit_y, fit_w, fit_h) = fit(src, dst);
    let scale = hud_scale(dst.1);
    Push {
        src_w: src.0,
        src_h: src.1,
        dst_w: dst.0,
        dst_h: dst.1,
        fit_x,
        fit_y,
        fit_w,
        fit_h,
        hud_x: 4 * scale,
        hud_y: 4 * scale,
        cols: hud.map_or(0, |t| t.cols),
        rows: hud.map_or(0, |t| t.rows),
        scale,
        bgr: bgr as u32,
    }
}

/// CPU reference of compose.comp: the window's pixels as the shader packs them (little-endian
/// words, so RGBA or BGRA bytes).
pub fn reference(src: &[u8], p: &Push, text: &[u32], font: &[u32]) -> Vec<u8> {
    let texel = |x: usize, y: usize, k: usize| src[4 * (y * p.src_w as usize + x) + k] as f32;
    let frame = |x: u32, y: u32| -> [u32; 3] {
        if x < p.fit_x || y < p.fit_y || x >= p.fit_x + p.fit_w || y >= p.fit_y + p.fit_h {
            return [0; 3];
        }
        let u = ((x - p.fit_x) as f32 + 0.5) * (p.src_w as f32 / p.fit_w as f32) - 0.5;
        let v = ((y - p.fit_y) as f32 + 0.5) * (p.src_h as f32 / p.fit_h as f32) - 0.5;
        let (u, v) = (
            u.clamp(0.0, (p.src_w - 1) as f32),
            v.clamp(0.0, (p.src_h - 1) as f32),
        );
        let (x0, y0) = (u as usize, v as usize);
        let x1 = (x0 + 1).min(p.src_w as usize - 1);
        let y1 = (y0 + 1).min(p.src_h as usize - 1);
        let (fx, fy) = (u - x0 as f32, v - y0 as f32);
        [0, 1, 2].map(|k| {
            let top = texel(x0, y0, k) * (1.0 - fx) + texel(x1, y0, k) * fx;
            let bot = texel(x0, y1, k) * (1.0 - fx) + texel(x1, y1, k) * fx;
            (top * (1.0 - fy) + bot * fy + 0.5) as u32
        })
    };
    let hud = |x: u32, y: u32, c: [u32; 3]| -> [u32; 3] {
        let (s, margin) = (p.scale, 2 * p.scale);
        let (cw, lh) = (8 * s, 10 * s);
        if p.rows == 0 || x + margin < p.hud_x || y + margin < p.hud_y {
            return c;
        }
        if x >= p.hud_x + p.cols * cw + margin || y >= p.hud_y + p.rows * lh + margin {
            return c;
        }
        let c = c.map(|v| (v * 90) >> 8);
        if x < p.hud_x || y < p.hud_y {
            return c;
        }
        let (col, row) = ((x - p.hud_x) / cw, (y - p.hud_y) / lh);
        let (gx, gy) = ((x - p.hud_x) % cw / s, (y - p.hud_y) % lh / s);
        if col >= p.cols || row >= p.rows || gy >= 8 {
            return c;
        }
        let ch = text[(row * p.cols + col) as usize] & 127;
        let bits = font[(ch * 2 + gy / 4) as usize] >> (8 * (gy % 4));
        if (bits >> gx) & 1 != 0 {
            [255; 3]
        } else {
            c
        }
    };
    let mut out = Vec::with_capacity((p.dst_w * p.dst_h * 4) as usize);
    for y in 0..p.dst_h {
        for x in 0..p.dst_w {
            let mut c = hud(x, y, frame(x, y));
            if p.bgr != 0 {
                c.swap(0, 2);
            }
            out.extend([c[0] as u8, c[1] as u8, c[2] as u8, 255]);
        }
    }
    out
}

/// The compose pass and its buffers: the window's picture stays on the device for the copy to
/// the swapchain image, and can be read back for a screenshot.
pub struct Compose {
    gpu: Arc<Gpu>,
    pipe: Pipeline,
    font: Buffer,
    text: Buffer,
    out: Buffer,
    size: (u32, u32),
}

impl Compose {
    pub fn new(gpu: &Arc<Gpu>) -> Result<Compose> {
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        Ok(Compose {
            gpu: gpu.clone(),
            pipe: Pipeline::compute(gpu, shaders::VIEW_COMPOSE)?,
            font: Buffer::from_slice(gpu, "hud font", usage, &font_words())?,
            text: Buffer::new(gpu, "hud text", 16, usage, MemoryLocation::CpuToGpu)?,
            out: Buffer::new(gpu, "window picture", 16, usage, MemoryLocation::GpuOnly)?,
            size: (0, 0),
        })
    }

    /// Records the pass: `src` (RGBA8, `src_size`) into the window picture of `dst_size`.
    pub fn record(
        &mut self,
        g: &mut Graph,
        src: &Buffer,
        src_size: (u32, u32),
        dst_size: (u32, u32),
        hud: Option<&HudText>,
        bgr: bool,
    ) -> Result<()> {
        if self.size != dst_size {
            let bytes = (dst_size.0 as u64 * dst_size.1 as u64 * 4).max(16);
            let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
            self.out = Buffer::new(
                &self.gpu,
                "window picture",
                bytes,
                usage,
                MemoryLocation::GpuOnly,
            )?;
            self.size = dst_size;
        }
        let cells = hud.map(|t| &t.cells[..]).unwrap_or(&[0]);
        let bytes: &[u8] = bytemuck::cast_slice(if cells.is_empty() { &[0u32] } else { cells });
        if self.text.size < bytes.len() as u64 {
            let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
            let n = (bytes.len() as u64).next_power_of_two();
            self.text = Buffer::new(&self.gpu, "hud text", n, usage, MemoryLocation::CpuToGpu)?;
        }
        self.text.upload(bytes)?;
        let push = push(src_size, dst_size, hud, bgr);
        let binds = [
            ("Src", Bind::Buffer(src)),
            ("Dst", Bind::Buffer(&self.out)),
            ("Font", Bind::Buffer(&self.font)),
            ("Text", Bind::Buffer(&self.text)),
        ];
        let threads = (dst_size.0, dst_size.1, 1);
        g.dispatch_with("compose", &self.pipe, &binds, bytes_of(&push), threads)
    }

    /// The window picture's size.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// The window picture of the last [`Compose::record`] (4 bytes a pixel).
    pub fn output(&self) -> &Buffer {
        &self.out
    }

    /// Its pixels as RGBA8 (`bgr`: as recorded, swapped back).
    pub fn download_rgba(&self, bgr: bool) -> Result<Vec<u8>> {
        let n = self.size.0 as u64 * self.size.1 as u64 * 4;
        let mut px = self.out.download_range(0, n)?;
        if bgr {
            px.chunks_exact_mut(4).for_each(|p| p.swap(0, 2));
        }
        Ok(px)
    }
}
