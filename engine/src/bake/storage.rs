//! Compressed view storage (§4.1–4.2 maps): BC6H (`VK_FORMAT_BC6H_UFLOAT_BLOCK`) encoded on the
//! CPU with Intel's ISPC texture compressor (intel_tex_2), and the log-space PSNR (μ = 64, the
//! network's tonemapping, §5.2) against the half-float original that decides whether the
//! compression is good enough. BC6H holds 1 byte per pixel against RGBA16F's 8.

use crate::gpu::shaders;
use std::sync::Arc;

use half::f16;

use crate::error::{Error, Result};
use crate::gpu::{
    bytes_of, vk, Bind, Buffer, Gpu, Graph, Image, MemoryLocation, Pipeline, Sampler,
};

/// Encodes an RGB float image (rows top to bottom) as BC6H unsigned blocks. Sizes need not be
/// multiples of 4: edges are replicated into the padding. Negative values clamp to 0.
pub fn encode_bc6h(width: u32, height: u32, px: &[[f32; 4]], quality: Bc6hQuality) -> Vec<u8> {
    let (pw, ph) = (width.div_ceil(4) * 4, height.div_ceil(4) * 4);
    let mut data = vec![f16::ZERO; (pw * ph * 4) as usize];
    for y in 0..ph {
        for x in 0..pw {
            let s = px[(y.min(height - 1) * width + x.min(width - 1)) as usize];
            let o = ((y * pw + x) * 4) as usize;
            for k in 0..3 {
                // BC6H UFLOAT holds [0, 65504]; non-finite values become 0.
                let v = if s[k].is_finite() {
                    s[k].clamp(0.0, 65000.0)
                } else {
                    0.0
                };
                data[o + k] = f16::from_f32(v);
            }
            data[o + 3] = f16::ONE;
        }
    }
    let surf = intel_tex_2::RgbaSurface {
        width: pw,
        height: ph,
        stride: pw * 8,
        data: bytemuck::cast_slice(&data),
    };
    let settings = match quality {
        Bc6hQuality::Fast => intel_tex_2::bc6h::very_fast_settings(),
        Bc6hQuality::Basic => intel_tex_2::bc6h::basic_settings(),
        Bc6hQuality::Slow => intel_tex_2::bc6h::slow_settings(),
    };
    intel_tex_2::bc6h::compress_blocks(&settings, &surf)
}

#[derive(Clone, Copy, Debug)]
pub enum Bc6hQuality {
    Fast,
    Basic,
    Slow,
}

pub use crate::constants::tonemap;

/// PSNR (dB) between two RGB images in the tonemapped space.
pub fn log_psnr(a: &[[f32; 4]], b: &[[f32; 4]]) -> f64 {
    let mut se = 0.0f64;
    for (p, q) in a.iter().zip(b) {
        for k in 0..3 {
            se += ((tonemap(p[k]) - tonemap(q[k])) as f64).powi(2);
        }
    }
    let mse = se / (3 * a.len().max(1)) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (1.0 / mse).log10()
    }
}

/// A BC6H map file: "RBC6", width, height (u32 LE), then the blocks. Written atomically.
pub fn write_bc6h(path: &std::path::Path, width: u32, height: u32, blocks: &[u8]) -> Result<()> {
    let mut out = b"RBC6".to_vec();
    out.extend_from_slice(&width.to_le_bytes());
    out.extend_from_slice(&height.to_le_bytes());
    out.extend_from_slice(blocks);
    crate::scene::write_atomic(path, &out)
}

/// Reads a BC6H map file: (width, height, blocks).
pub fn read_bc6h(path: &std::path::Path) -> Result<(u32, u32, Vec<u8>)> {
    let b = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if b.len() < 12 || &b[..4] != b"RBC6" {
        return Err(Error::input(
            path,
            "not a BC6H map file (expected the RBC6 header)",
        ));
    }
    let w = u32::from_le_bytes(b[4..8].try_into().unwrap());
    let h = u32::from_le_bytes(b[8..12].try_into().unwrap());
    let expect = (w.div_ceil(4) * h.div_ceil(4) * 16) as usize;
    if b.len() != 12 + expect {
        return Err(Error::input(
            path,
            format!(
                "{}x{} needs {expect} bytes of blocks, file has {}",
                w,
                h,
                b.len() - 12
            ),
        ));
    }
    Ok((w, h, b[12..].to_vec()))
}

/// A BC6H texture on the device, one layer per map.
pub struct Bc6hTexture {
    pub image: Image,
}

impl Bc6hTexture {
    /// A texture array of cached BC6H maps (all of one size), one layer per file in order.
    pub fn from_files(gpu: &Arc<Gpu>, files: &[std::path::PathBuf]) -> Result<Bc6hTexture> {
        let mut layers = Vec::with_capacity(files.len());
        let mut size = None;
        for f in files {
            let (w, h, blocks) = read_bc6h(f)?;
            if *size.get_or_insert((w, h)) != (w, h) {
                return Err(Error::input(
                    f,
                    "maps of one texture array must share one size",
                ));
            }
            layers.push(blocks);
        }
        let (w, h) = size.ok_or_else(|| Error::Other("no BC6H maps given".into()))?;
        Bc6hTexture::upload(gpu, w, h, &layers)
    }

    /// Uploads already-encoded layers (each `encode_bc6h` output of one width × height map).
    pub fn upload(
        gpu: &Arc<Gpu>,
        width: u32,
        height: u32,
        layers: &[Vec<u8>],
    ) -> Result<Bc6hTexture> {
        if !gpu.caps.bc6h_sampled_linear {
            return Err(Error::Device(
                "the device cannot sample BC6H textures with linear filtering".into(),
            ));
        }
        // The image extent is the padded one: blocks cover whole 4×4 tiles.
        let (pw, ph) = (width.div_ceil(4) * 4, height.div_ceil(4) * 4);
        let image = Image::new_array(
            gpu,
            "bc6h maps",
            vk::Format::BC6H_UFLOAT_BLOCK,
            pw,
            ph,
            layers.len() as u32,
            vk::ImageUsageFlags::SAMPLED,
        )?;
        let bytes: Vec<u8> = layers.concat();
        image.upload(&bytes, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)?;
        Ok(Bc6hTexture { image })
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    width: u32,
    height: u32,
    layer: u32,
}

/// Push as its shaders' push block declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout =
    crate::push_layout!(Push, [shaders::GPU_FETCH], [width, height, layer]);

/// Reads a layer of a sampled texture back through the sampler (`gpu/fetch.comp`).
pub struct Fetch {
    pipeline: Pipeline,
    sampler: Sampler,
}

impl Fetch {
    pub fn new(gpu: &Arc<Gpu>) -> Result<Fetch> {
        Ok(Fetch {
            pipeline: Pipeline::compute(gpu, shaders::GPU_FETCH)?,
            sampler: Sampler::linear(gpu)?,
        })
    }

    /// The `width` × `height` top-left texels of `layer`, sampled at texel centres.
    pub fn run(&self, image: &Image, layer: u32, width: u32, height: u32) -> Result<Vec<[f32; 4]>> {
        let gpu = &self.pipeline.gpu;
        // Texel centres of the padded image: sample with the padded size, keep the top-left.
        let push = Push {
            width: image.width,
            height: image.height,
            layer,
        };
        let full = Buffer::new(
            gpu,
            "fetch full",
            (image.width * image.height) as u64 * 16,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        let mut res = Ok(());
        gpu.submit(|cmd| {
            res = Graph::new(gpu, cmd, None).dispatch_with(
                "fetch",
                &self.pipeline,
                &[
                    ("tex", Bind::Sampled(image, self.sampler.raw)),
                    ("Out", Bind::Buffer(&full)),
                ],
                bytes_of(&push),
                (image.width, image.height, 1),
            )
        })?;
        res?;
        let all: Vec<[f32; 4]> = full.download_vec()?;
        Ok((0..height)
            .flat_map(|y| (0..width).map(move |x| (y * image.width + x) as usize))
            .map(|i| all[i])
            .collect())
    }
}

/// A per-vertex or per-texel table on disk: a 4-byte tag, the count (u32), then one vec4 per
/// entry, little-endian f32 (the albedo mesh "RALB", a surface cache "RCAC").
pub fn write_vec4s(path: &std::path::Path, tag: &[u8; 4], v: &[[f32; 4]]) -> Result<()> {
    let mut out = tag.to_vec();
    out.extend_from_slice(&(v.len() as u32).to_le_bytes());
    out.extend_from_slice(bytemuck::cast_slice(v));
    crate::scene::write_atomic(path, &out)
}

/// Reads a table written by [`write_vec4s`]: it must carry `tag` (else "not a `what` file")
/// and hold `expected` entries of `unit` (else an error naming both counts).
pub fn read_vec4s(
    path: &std::path::Path,
    tag: &[u8; 4],
    expected: usize,
    what: &str,
    unit: &str,
) -> Result<Vec<[f32; 4]>> {
    let b = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if b.len() < 8 || &b[..4] != tag {
        return Err(Error::input(path, format!("not a {what} file")));
    }
    let n = u32::from_le_bytes(b[4..8].try_into().unwrap()) as usize;
    if n != expected || b.len() != 8 + 16 * n {
        return Err(Error::input(
            path,
            format!("holds {n} {unit}; the bake mesh has {expected}"),
        ));
    }
    Ok(bytemuck::pod_collect_to_vec(&b[8..]))
}
