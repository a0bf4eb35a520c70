//! Images: EXR (half or float, RGB or RGBA) kept linear; PNG/JPEG decoded from sRGB to linear,
//! with the pixels the sensor clipped marked (`Photo`). Headers are checked before any pixel is
//! decoded, so a file claiming 100000×100000 is refused without allocating for it.

use std::path::Path;

use crate::error::{Error, Result};
use crate::scene::MAX_IMAGE_DIM;

/// A linear RGB float image, rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

impl RgbImage {
    pub fn new(width: u32, height: u32) -> RgbImage {
        RgbImage {
            width,
            height,
            pixels: vec![[0.0; 3]; (width * height) as usize],
        }
    }
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[(y * self.width + x) as usize]
    }
    pub fn set(&mut self, x: u32, y: u32, v: [f32; 3]) {
        self.pixels[(y * self.width + x) as usize] = v;
    }
}

pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.0031308 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

fn check_dims(path: &Path, w: u64, h: u64) -> Result<()> {
    if w == 0 || h == 0 || w > MAX_IMAGE_DIM as u64 || h > MAX_IMAGE_DIM as u64 {
        return Err(Error::input(
            path,
            format!("image header claims {w}x{h} pixels; expected 1..={MAX_IMAGE_DIM} per side"),
        ));
    }
    Ok(())
}

/// Width and height from the header only.
pub fn image_size(path: &Path) -> Result<(u32, u32)> {
    // Not `path.exists()`: that is false for a symlink loop or a dangling link too, which the
    // message must tell apart from a missing file.
    if std::fs::metadata(path).is_err() {
        return Err(Error::input(
            path,
            format!(
                "cannot open the image file: {}",
                super::files::describe_missing(path)
            ),
        ));
    }
    super::files::check(path, super::files::FileKind::Image)?;
    if is_exr(path) {
        let meta = exr::meta::MetaData::read_from_file(path, false)
            .map_err(|e| Error::input(path, format!("unreadable EXR header: {e}")))?;
        let h = meta
            .headers
            .first()
            .ok_or_else(|| Error::input(path, "EXR file has no layer"))?;
        let size = h.layer_size;
        check_dims(path, size.0 as u64, size.1 as u64)?;
        // The exr crate's B44 decoder overflows on corrupt blocks (found by fuzzing): B44 is a
        // lossy 16-bit playback format, not one for captured radiance, so it is refused.
        if matches!(
            h.compression,
            exr::compression::Compression::B44 | exr::compression::Compression::B44A
        ) {
            return Err(Error::input(
                path,
                "B44-compressed EXR is not supported (lossy); save it uncompressed or with ZIP, PIZ or RLE",
            ));
        }
        Ok((size.0 as u32, size.1 as u32))
    } else {
        let reader = image::ImageReader::open(path)
            .map_err(|e| Error::io(path, e))?
            .with_guessed_format()
            .map_err(|e| Error::io(path, e))?;
        let (w, h) = reader
            .into_dimensions()
            .map_err(|e| Error::input(path, format!("unreadable image header: {e}")))?;
        check_dims(path, w as u64, h as u64)?;
        Ok((w, h))
    }
}

pub(crate) fn is_exr(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
}

/// A JPEG must end with its end-of-image marker (FF D9; a few bytes of padding after it are
/// allowed): the decoder fills a truncated file's missing rows with grey without a word.
fn check_jpeg_end(path: &Path, data: &[u8]) -> Result<()> {
    if !data.starts_with(&[0xFF, 0xD8]) {
        return Ok(());
    }
    let tail = &data[data.len().saturating_sub(4096)..];
    if tail.windows(2).any(|w| w == [0xFF, 0xD9]) {
        Ok(())
    } else {
        Err(Error::input(
            path,
            "JPEG has no end-of-image marker: the file is truncated",
        ))
    }
}

/// Decodes an EXR's first valid layer as RGB. On one thread, so that a panic inside the exr
/// crate (fuzzing found one in its B44 decompressor with overflow checks on) reaches
/// `catch_unwind` and becomes an error naming the file, instead of aborting the process from a
/// worker thread.
fn decode_exr(path: &Path) -> Result<RgbImage> {
    use exr::prelude::*;
    let data = super::files::read(path, super::files::FileKind::Image)?;
    let decoded = std::panic::catch_unwind(|| {
        read()
            .no_deep_data()
            .largest_resolution_level()
            .rgba_channels(
                |res, _| RgbImage::new(res.width() as u32, res.height() as u32),
                |img: &mut RgbImage, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                    img.set(pos.x() as u32, pos.y() as u32, [r, g, b])
                },
            )
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(std::io::Cursor::new(&data))
    })
    .map_err(|_| {
        crate::Error::input(path, "the EXR decoder failed on this file (corrupt block)")
    })?;
    match decoded {
        Ok(image) => Ok(image.layer_data.channel_data.pixels),
        Err(e) => decode_exr_grey(&data).ok_or_else(|| {
            crate::Error::input(
                path,
                format!(
                    "cannot decode EXR: {e} (relit reads R, G, B channels, or one channel as \
                     grey; the file may also be truncated or corrupt)"
                ),
            )
        }),
    }
}

/// A single-channel EXR (luminance `Y`, or one channel of any name, full resolution) as grey
/// RGB; None for anything else.
fn decode_exr_grey(data: &[u8]) -> Option<RgbImage> {
    use exr::prelude::*;
    let decoded = std::panic::catch_unwind(|| {
        read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(std::io::Cursor::new(data))
    });
    let image = decoded.ok()?.ok()?;
    let layer = &image.layer_data;
    let [channel] = layer.channel_data.list.as_slice() else {
        return None;
    };
    let (w, samples) = (layer.size.width(), &channel.sample_data);
    if samples.len() != layer.size.area() || w == 0 {
        return None;
    }
    let mut out = RgbImage::new(w as u32, layer.size.height() as u32);
    for i in 0..samples.len() {
        let v = samples.value_by_flat_index(i).to_f32();
        out.set((i % w) as u32, (i / w) as u32, [v, v, v]);
    }
    Some(out)
}

/// A photo as the bake reads it: linear radiance, and which pixels clipped.
#[derive(Clone, Debug, PartialEq)]
pub struct Photo {
    pub image: RgbImage,
    /// Per pixel: a channel reached the top of an integer format's range, so the value is a
    /// lower bound, not radiance. Empty when nothing clipped (and always for EXR).
    pub clipped: Vec<bool>,
}

impl Photo {
    pub fn clipped_count(&self) -> usize {
        self.clipped.iter().filter(|&&c| c).count()
    }
}

/// A channel at or above this fraction of an integer format's top code clipped: JPEG's
/// block transform rings around a saturated region, leaving codes a little under 255 there.
pub const CLIP_FRACTION: f32 = 0.98;

/// Loads an image as linear RGB. Refuses non-finite or negative-infinite pixels, naming the first.
pub fn load_rgb(path: &Path) -> Result<RgbImage> {
    Ok(load_photo(path)?.image)
}

/// Loads an image as linear RGB with its clipped pixels (see [`Photo`]).
pub fn load_photo(path: &Path) -> Result<Photo> {
    let (w, h) = image_size(path)?;
    let photo = if is_exr(path) {
        Photo {
            image: decode_exr(path)?,
            clipped: Vec::new(),
        }
    } else {
        decode_integer(path)?
    };
    let img = &photo.image;
    if (img.width, img.height) != (w, h) {
        return Err(Error::input(path, "decoded size differs from the header"));
    }
    if let Some(i) = img
        .pixels
        .iter()
        .position(|p| !p.iter().all(|v| v.is_finite()))
    {
        return Err(Error::input(
            path,
            format!(
                "pixel ({}, {}) is {:?}; radiance must be finite",
                i as u32 % img.width,
                i as u32 / img.width,
                img.pixels[i]
            ),
        ));
    }
    Ok(photo)
}

/// PNG, JPEG and the other formats of the `image` crate: sRGB decoded to linear; in integer
/// formats, pixels with a channel at the top code marked clipped. TIFF is linear (what a RAW
/// converter writes: `dcraw -4 -T -w`), 16-bit or float, never 8-bit.
fn decode_integer(path: &Path) -> Result<Photo> {
    let data = super::files::read(path, super::files::FileKind::Image)?;
    check_jpeg_end(path, &data)?;
    let mut reader = image::ImageReader::new(std::io::Cursor::new(data))
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    let linear = reader.format() == Some(image::ImageFormat::Tiff);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_DIM);
    limits.max_image_height = Some(MAX_IMAGE_DIM);
    reader.limits(limits);
    let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| reader.decode()))
        .map_err(|_| Error::input(path, "the image decoder failed on this file (corrupt)"))?
        .map_err(|e| Error::input(path, format!("cannot decode image: {e}")))?;
    use image::ColorType as C;
    let (integer, eight_bit) = match decoded.color() {
        C::Rgb32F | C::Rgba32F => (false, false),
        C::L8 | C::La8 | C::Rgb8 | C::Rgba8 => (true, true),
        _ => (true, false),
    };
    if linear && eight_bit {
        return Err(Error::input(
            path,
            "8-bit TIFF: relit reads TIFF as linear radiance, which 8 bits cannot hold; \
             write 16-bit linear TIFF (dcraw -4 -T -w RAW) or an sRGB JPEG/PNG",
        ));
    }
    let rgb = decoded.into_rgb32f();
    // 8-bit sRGB clips below the top code (JPEG rings under a saturated region); 16-bit at it.
    let top = match eight_bit {
        true => CLIP_FRACTION - 0.5 / 65535.0,
        false => 1.0 - 0.5 / 65535.0,
    };
    let clips = |p: &image::Rgb<f32>| p.0.iter().any(|&c| c >= top);
    let mut clipped: Vec<bool> = Vec::new();
    if integer && rgb.pixels().any(clips) {
        clipped = rgb.pixels().map(clips).collect();
    }
    let decode = |c: f32| if linear { c } else { srgb_to_linear(c) };
    let pixels = rgb.pixels().map(|p| p.0.map(decode)).collect();
    Ok(Photo {
        image: RgbImage {
            width: rgb.width(),
            height: rgb.height(),
            pixels,
        },
        clipped,
    })
}

/// Writes a half-float RGB EXR (ZIP compressed), through a temp file and a rename.
pub fn write_exr(path: &Path, img: &RgbImage) -> Result<()> {
    use exr::prelude::*;
    let w = img.width as usize;
    let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let p = img.pixels[pos.y() * w + pos.x()];
        (
            f16::from_f32(p[0]),
            f16::from_f32(p[1]),
            f16::from_f32(p[2]),
        )
    });
    let layer = Layer::new(
        (img.width as usize, img.height as usize),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        channels,
    );
    let tmp = crate::scene::temp_path(path);
    Image::from_layer(layer)
        .write()
        .to_file(&tmp)
        .map_err(|e| crate::Error::input(path, format!("cannot write EXR: {e}")))?;
    std::fs::rename(&tmp, path).map_err(|e| crate::Error::io(path, e))
}

/// Writes an 8-bit sRGB PNG of linear values times `exposure`.
pub fn write_png(path: &Path, img: &RgbImage, exposure: f32) -> Result<()> {
    let mut buf = image::RgbImage::new(img.width, img.height);
    for (i, p) in buf.pixels_mut().enumerate() {
        let v = img.pixels[i];
        *p = image::Rgb(v.map(|c| (linear_to_srgb(c * exposure) * 255.0 + 0.5) as u8));
    }
    let tmp = crate::scene::temp_path(path);
    buf.save_with_format(&tmp, image::ImageFormat::Png)
        .map_err(|e| Error::input(path, format!("cannot write PNG: {e}")))?;
    std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))
}

/// Writes 8-bit RGBA pixels (already display-transformed) as an RGB PNG, atomically.
pub fn write_png_rgba8(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
    let rgb: Vec<u8> = rgba
        .chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    let buf = image::RgbImage::from_raw(width, height, rgb).ok_or_else(|| {
        Error::Other(format!(
            "{}: pixel count does not match {width}x{height}",
            path.display()
        ))
    })?;
    let tmp = crate::scene::temp_path(path);
    buf.save_with_format(&tmp, image::ImageFormat::Png)
        .map_err(|e| Error::input(path, format!("cannot write PNG: {e}")))?;
    std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::image_size;

    /// A missing image, a symlink loop and a dangling link each get their own words.
    #[test]
    fn image_paths_that_are_no_file_say_what_they_are() {
        use std::os::unix::fs::symlink;
        let dir = std::env::temp_dir().join(format!("relit-image-links-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let err = |name: &str| image_size(&dir.join(name)).unwrap_err().to_string();

        let e = err("missing.png");
        assert!(
            e.contains("missing.png") && e.contains("does not exist"),
            "{e}"
        );

        symlink("loop.png", dir.join("loop.png")).unwrap();
        let e = err("loop.png");
        assert!(e.contains("loop.png") && e.contains("symlink loop"), "{e}");
        assert!(!e.contains("does not exist"), "{e}");

        symlink("a.exr", dir.join("b.exr")).unwrap();
        symlink("b.exr", dir.join("a.exr")).unwrap();
        let e = err("a.exr");
        assert!(e.contains("symlink loop"), "a two-link loop: {e}");

        symlink("gone.jpg", dir.join("dangling.jpg")).unwrap();
        let e = err("dangling.jpg");
        assert!(e.contains("dangling"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
