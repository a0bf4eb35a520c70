//! The per-view maps the frame samples (§4.1–4.2): input images I, source mirrors M_src, source
//! irradiance E_src and added irradiance E_add per light, each kind one 2D texture array (one
//! layer per view; E_add layer = light × views + view). Stored BC6H-compressed by default, or
//! uncompressed for comparison and for the reference tests.

use std::sync::Arc;

use half::f16;

use crate::bake::storage::{encode_bc6h, Bc6hQuality, Bc6hTexture};
use crate::error::{Error, Result};
use crate::gpu::{vk, Gpu, Image};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapFormat {
    /// `VK_FORMAT_BC6H_UFLOAT_BLOCK` (1 byte per texel).
    Bc6h,
    /// RGBA16F (8 bytes per texel).
    Rgba16f,
    /// RGBA32F: exact, for the reference tests.
    Rgba32f,
}

/// Host copies of the maps, layer-major (what the textures hold before compression).
#[derive(Clone, Default)]
pub struct HostMaps {
    pub width: u32,
    pub height: u32,
    pub img: Vec<Vec<[f32; 4]>>,
    pub msrc: Vec<Vec<[f32; 4]>>,
    pub esrc: Vec<Vec<[f32; 4]>>,
    /// Layer `light * views + view`: the added lights, then (the last `split` lights) the
    /// declared original lights when the bake splits E_src among them (frame/lighting.rs).
    pub eadd: Vec<Vec<[f32; 4]>>,
    pub split: usize,
    /// Added lights the bake has no entry for (not used yet): their layers are zero.
    pub unbaked: Vec<String>,
}

/// The maps the bake makes, one texture array each.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightingMap {
    Msrc,
    Esrc,
    Eadd,
}

pub struct ViewMaps {
    pub img: Image,
    pub msrc: Image,
    pub esrc: Image,
    pub eadd: Image,
    pub format: MapFormat,
}

/// Uploads `layers` (each width × height) as a sampled texture array.
pub fn upload_layers(
    gpu: &Arc<Gpu>,
    name: &str,
    width: u32,
    height: u32,
    layers: &[Vec<[f32; 4]>],
    format: MapFormat,
) -> Result<Image> {
    if layers.is_empty() {
        return Err(Error::Other(format!("{name}: no layers")));
    }
    if let Some(l) = layers.iter().find(|l| l.len() != (width * height) as usize) {
        return Err(Error::Other(format!(
            "{name}: a layer has {} texels, expected {width}x{height}",
            l.len()
        )));
    }
    let sampled = vk::ImageUsageFlags::SAMPLED;
    let n = layers.len() as u32;
    match format {
        MapFormat::Bc6h => {
            let blocks: Vec<Vec<u8>> = layers
                .iter()
                .map(|l| encode_bc6h(width, height, l, Bc6hQuality::Basic))
                .collect();
            Ok(Bc6hTexture::upload(gpu, width, height, &blocks)?.image)
        }
        MapFormat::Rgba16f => {
            let img = Image::new_array(
                gpu,
                name,
                vk::Format::R16G16B16A16_SFLOAT,
                width,
                height,
                n,
                sampled,
            )?;
            let data: Vec<f16> = layers
                .iter()
                .flatten()
                .flat_map(|p| p.map(|v| f16::from_f32(if v.is_finite() { v } else { 0.0 })))
                .collect();
            img.upload(
                bytemuck::cast_slice(&data),
                vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
            )?;
            Ok(img)
        }
        MapFormat::Rgba32f => {
            let img = Image::new_array(
                gpu,
                name,
                vk::Format::R32G32B32A32_SFLOAT,
                width,
                height,
                n,
                sampled,
            )?;
            let data: Vec<[f32; 4]> = layers.iter().flatten().copied().collect();
            img.upload(
                bytemuck::cast_slice(&data),
                vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
            )?;
            Ok(img)
        }
    }
}

impl ViewMaps {
    pub fn upload(gpu: &Arc<Gpu>, m: &HostMaps, format: MapFormat) -> Result<ViewMaps> {
        let (w, h) = (m.width, m.height);
        // A scene without added lights still binds a (black) E_add array.
        let black = vec![vec![[0f32; 4]; (w * h) as usize]];
        let eadd = if m.eadd.is_empty() { &black } else { &m.eadd };
        Ok(ViewMaps {
            img: upload_layers(gpu, "maps: I", w, h, &m.img, format)?,
            msrc: upload_layers(gpu, "maps: M_src", w, h, &m.msrc, format)?,
            esrc: upload_layers(gpu, "maps: E_src", w, h, &m.esrc, format)?,
            eadd: upload_layers(gpu, "maps: E_add", w, h, eadd, format)?,
            format,
        })
    }
}

impl ViewMaps {
    /// `upload` one type at a time: `load(kind, m)` fills that type's layers of `m` just before
    /// they go to the device, and they are freed right after (at the paper's scale each type
    /// is a GB on the host).
    fn upload_streamed(
        gpu: &Arc<Gpu>,
        mut m: HostMaps,
        load: &mut dyn FnMut(LightingMap, &mut HostMaps) -> Result<()>,
        format: MapFormat,
    ) -> Result<ViewMaps> {
        let (w, h) = (m.width, m.height);
        let one = |name: &str, layers: &mut Vec<Vec<[f32; 4]>>| {
            let image = upload_layers(gpu, name, w, h, layers, format);
            *layers = Vec::new();
            image
        };
        let img = one("maps: I", &mut m.img)?;
        load(LightingMap::Msrc, &mut m)?;
        let msrc = one("maps: M_src", &mut m.msrc)?;
        load(LightingMap::Esrc, &mut m)?;
        let esrc = one("maps: E_src", &mut m.esrc)?;
        load(LightingMap::Eadd, &mut m)?;
        if m.eadd.is_empty() {
            m.eadd = vec![vec![[0f32; 4]; (w * h) as usize]];
        }
        let eadd = one("maps: E_add", &mut m.eadd)?;
        Ok(ViewMaps {
            img,
            msrc,
            esrc,
            eadd,
            format,
        })
    }

    /// The maps of a baked scene in `format`; BC6H layers come from the cache's `.bc6h` copies
    /// when they are all there (no re-encoding; the images, not in the cache, are encoded here),
    /// else from `load` (one type at a time, [`ViewMaps::upload_streamed`]). `host` holds the
    /// images.
    pub fn upload_cached(
        gpu: &Arc<Gpu>,
        scene: &crate::scene::Scene,
        params: &crate::bake::BakeParams,
        host: HostMaps,
        load: &mut dyn FnMut(LightingMap, &mut HostMaps) -> Result<()>,
        format: MapFormat,
    ) -> Result<ViewMaps> {
        use crate::bake::BakeCache;
        let cache = BakeCache::of(scene, params)?;
        let files = |f: &dyn Fn(&str) -> std::path::PathBuf| -> Option<Vec<std::path::PathBuf>> {
            let v: Vec<_> = scene
                .views
                .iter()
                .map(|v| BakeCache::bc6h(&f(&v.name)))
                .collect();
            v.iter().all(|p| p.exists()).then_some(v)
        };
        let msrc = files(&|v| cache.msrc(v));
        let esrc = files(&|v| cache.esrc(v));
        let lights = super::scene::layer_lights(scene, &cache, params);
        let mut eadd = Some(Vec::new());
        for l in &lights {
            match (files(&|v| cache.eadd(v, l, params)), eadd.as_mut()) {
                (Some(f), Some(all)) => all.extend(f),
                _ => eadd = None,
            }
        }
        let (Some(msrc), Some(esrc), Some(eadd), MapFormat::Bc6h) = (msrc, esrc, eadd, format)
        else {
            return ViewMaps::upload_streamed(gpu, host, load, format);
        };
        let (w, h) = (host.width, host.height);
        Ok(ViewMaps {
            img: upload_layers(gpu, "maps: I", w, h, &host.img, format)?,
            msrc: Bc6hTexture::from_files(gpu, &msrc)?.image,
            esrc: Bc6hTexture::from_files(gpu, &esrc)?.image,
            eadd: if lights.is_empty() {
                upload_layers(
                    gpu,
                    "maps: E_add",
                    w,
                    h,
                    &[vec![[0f32; 4]; (w * h) as usize]],
                    format,
                )?
            } else {
                Bc6hTexture::from_files(gpu, &eadd)?.image
            },
            format,
        })
    }
}

/// CPU mirror of `sample_map` in frame.glsl: bilinear, clamp to edge, at continuous pixel
/// coordinate `px` (texel centres at +½).
pub fn sample_bilinear(map: &[[f32; 4]], w: u32, h: u32, px: glam::Vec2) -> glam::Vec3 {
    let u = px.x - 0.5;
    let v = px.y - 0.5;
    let (x0, y0) = (u.floor(), v.floor());
    let (fx, fy) = (u - x0, v - y0);
    let at = |x: f32, y: f32| {
        let xi = (x as i64).clamp(0, w as i64 - 1) as usize;
        let yi = (y as i64).clamp(0, h as i64 - 1) as usize;
        let p = map[yi * w as usize + xi];
        glam::Vec3::new(p[0], p[1], p[2])
    };
    let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1.0, y0) * fx;
    let bot = at(x0, y0 + 1.0) * (1.0 - fx) + at(x0 + 1.0, y0 + 1.0) * fx;
    top * (1.0 - fy) + bot * fy
}
