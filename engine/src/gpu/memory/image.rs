//! 2D images (arrays) with one view, uploaded and read back through staging buffers.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::Allocation;
use gpu_allocator::MemoryLocation;

use super::buffer::Staging;
use super::{creation_error, image_barrier, Gpu};
use crate::error::{Error, Result};

/// A 2D image (array) with one view over all layers.
pub struct Image {
    pub gpu: Arc<Gpu>,
    pub raw: vk::Image,
    pub view: vk::ImageView,
    pub format: vk::Format,
    pub width: u32,
    pub height: u32,
    pub layers: u32,
    pub aspect: vk::ImageAspectFlags,
    alloc: Option<Allocation>,
}

/// Bytes per texel of the uncompressed formats the engine reads back.
pub fn texel_size(format: vk::Format) -> Option<u32> {
    Some(match format {
        vk::Format::R8G8B8A8_UNORM | vk::Format::R8G8B8A8_SRGB | vk::Format::B8G8R8A8_UNORM => 4,
        vk::Format::R32_SFLOAT | vk::Format::R32_UINT | vk::Format::D32_SFLOAT => 4,
        vk::Format::R16G16B16A16_SFLOAT => 8,
        vk::Format::R32G32B32A32_SFLOAT => 16,
        vk::Format::R16_SFLOAT => 2,
        _ => return None,
    })
}

impl Image {
    pub fn new(
        gpu: &Arc<Gpu>,
        name: &str,
        format: vk::Format,
        width: u32,
        height: u32,
        layers: u32,
        usage: vk::ImageUsageFlags,
    ) -> Result<Image> {
        Image::create(
            gpu,
            name,
            format,
            (width, height, layers),
            usage,
            layers > 1,
        )
    }

    /// An image whose view is a 2D array even with one layer (`sampler2DArray` in shaders).
    pub fn new_array(
        gpu: &Arc<Gpu>,
        name: &str,
        format: vk::Format,
        width: u32,
        height: u32,
        layers: u32,
        usage: vk::ImageUsageFlags,
    ) -> Result<Image> {
        Image::create(gpu, name, format, (width, height, layers), usage, true)
    }

    fn create(
        gpu: &Arc<Gpu>,
        name: &str,
        format: vk::Format,
        (width, height, layers): (u32, u32, u32),
        usage: vk::ImageUsageFlags,
        array: bool,
    ) -> Result<Image> {
        let d = &gpu.device;
        let aspect = if format == vk::Format::D32_SFLOAT {
            vk::ImageAspectFlags::DEPTH
        } else {
            vk::ImageAspectFlags::COLOR
        };
        let usage = usage | vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST;
        let raw = unsafe {
            d.create_image(
                &vk::ImageCreateInfo::default()
                    .image_type(vk::ImageType::TYPE_2D)
                    .format(format)
                    .extent(vk::Extent3D {
                        width,
                        height,
                        depth: 1,
                    })
                    .mip_levels(1)
                    .array_layers(layers)
                    .samples(vk::SampleCountFlags::TYPE_1)
                    .tiling(vk::ImageTiling::OPTIMAL)
                    .usage(usage)
                    .initial_layout(vk::ImageLayout::UNDEFINED),
                None,
            )
        }
        .map_err(|r| {
            let texel = 16u64; // the widest format the engine uses (RGBA32F)
            creation_error(
                name,
                width as u64 * height as u64 * layers as u64 * texel,
                r,
            )
        })?;
        let req = unsafe { d.get_image_memory_requirements(raw) };
        let alloc = match gpu.allocate(name, req, MemoryLocation::GpuOnly, false) {
            Ok(a) => a,
            Err(e) => {
                unsafe { d.destroy_image(raw, None) };
                return Err(e);
            }
        };
        let bound = unsafe { d.bind_image_memory(raw, alloc.memory(), alloc.offset()) };
        let view = bound.and_then(|_| unsafe {
            d.create_image_view(
                &vk::ImageViewCreateInfo::default()
                    .image(raw)
                    .view_type(if array {
                        vk::ImageViewType::TYPE_2D_ARRAY
                    } else {
                        vk::ImageViewType::TYPE_2D
                    })
                    .format(format)
                    .subresource_range(
                        vk::ImageSubresourceRange::default()
                            .aspect_mask(aspect)
                            .level_count(1)
                            .layer_count(layers),
                    ),
                None,
            )
        });
        let view = match view {
            Ok(v) => v,
            Err(e) => {
                unsafe { d.destroy_image(raw, None) };
                gpu.free(alloc);
                return Err(Error::Vk {
                    what: "bind image memory / create view",
                    result: e,
                });
            }
        };
        Ok(Image {
            gpu: gpu.clone(),
            raw,
            view,
            format,
            width,
            height,
            layers,
            aspect,
            alloc: Some(alloc),
        })
    }

    /// Uploads tightly packed texels (all layers, layer-major) and leaves the image in `layout`.
    pub fn upload(&self, bytes: &[u8], layout: vk::ImageLayout) -> Result<()> {
        let staging = Staging::new(&self.gpu, bytes.len() as u64, MemoryLocation::CpuToGpu)?;
        staging.write(bytes);
        self.gpu.submit(|cmd| unsafe {
            image_barrier(
                &self.gpu,
                cmd,
                self.raw,
                self.aspect,
                vk::ImageLayout::UNDEFINED,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            );
            let region = [self.copy_region()];
            self.gpu.device.cmd_copy_buffer_to_image(
                cmd,
                staging.0.raw,
                self.raw,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &region,
            );
            image_barrier(
                &self.gpu,
                cmd,
                self.raw,
                self.aspect,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                layout,
            );
        })
    }

    /// Reads all layers back (tightly packed), the image being in `layout`, which it keeps.
    pub fn download(&self, layout: vk::ImageLayout) -> Result<Vec<u8>> {
        let texel = texel_size(self.format).ok_or_else(|| {
            Error::Other(format!(
                "readback of {:?} images is not supported",
                self.format
            ))
        })? as u64;
        let len = texel * self.width as u64 * self.height as u64 * self.layers as u64;
        let staging = Staging::new(&self.gpu, len, MemoryLocation::GpuToCpu)?;
        self.gpu.submit(|cmd| unsafe {
            image_barrier(
                &self.gpu,
                cmd,
                self.raw,
                self.aspect,
                layout,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
            );
            let region = [self.copy_region()];
            self.gpu.device.cmd_copy_image_to_buffer(
                cmd,
                self.raw,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                staging.0.raw,
                &region,
            );
            image_barrier(
                &self.gpu,
                cmd,
                self.raw,
                self.aspect,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                layout,
            );
        })?;
        Ok(staging.read(len as usize))
    }

    fn copy_region(&self) -> vk::BufferImageCopy {
        vk::BufferImageCopy::default()
            .image_subresource(
                vk::ImageSubresourceLayers::default()
                    .aspect_mask(self.aspect)
                    .layer_count(self.layers),
            )
            .image_extent(vk::Extent3D {
                width: self.width,
                height: self.height,
                depth: 1,
            })
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        unsafe {
            self.gpu.device.destroy_image_view(self.view, None);
            self.gpu.device.destroy_image(self.raw, None);
        }
        if let Some(a) = self.alloc.take() {
            self.gpu.free(a);
        }
    }
}
