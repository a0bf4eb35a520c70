//! Presenting to a window: the surface, the swapchain (made again when the window's size
//! changes or the driver says it is out of date), acquire and present. The picture to show is
//! a buffer of 4-byte pixels in the swapchain's byte order ([`Presenter::bgr`]), copied to the
//! acquired image in the same submission as the commands that make it.

use std::ffi::CStr;
use std::sync::Arc;

use ash::vk;
use raw_window_handle::{RawDisplayHandle, RawWindowHandle};

use super::{image_barrier, Gpu};
use crate::error::{Error, Result, VkContext};

/// How frames reach the screen (VkPresentModeKHR).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PresentMode {
    /// At once, tearing allowed: the frame rate is the renderer's.
    Immediate,
    /// The newest frame at the next vertical blank, without waiting: no tearing, no cap.
    Mailbox,
    /// Vsync: the frame rate is capped at the display's.
    Fifo,
}

impl PresentMode {
    pub fn parse(s: &str) -> Option<PresentMode> {
        match s {
            "immediate" => Some(PresentMode::Immediate),
            "mailbox" => Some(PresentMode::Mailbox),
            "fifo" => Some(PresentMode::Fifo),
            _ => None,
        }
    }

    fn vk(self) -> vk::PresentModeKHR {
        match self {
            PresentMode::Immediate => vk::PresentModeKHR::IMMEDIATE,
            PresentMode::Mailbox => vk::PresentModeKHR::MAILBOX,
            PresentMode::Fifo => vk::PresentModeKHR::FIFO,
        }
    }

    /// `wanted` if the surface offers it, else the lowest-latency mode it offers (FIFO always is).
    pub fn choose(
        wanted: Option<PresentMode>,
        offered: &[vk::PresentModeKHR],
    ) -> Result<PresentMode> {
        let has = |m: PresentMode| offered.contains(&m.vk());
        match wanted {
            Some(m) if has(m) => Ok(m),
            Some(m) => Err(Error::Other(format!(
                "--present {}: the surface offers only {}",
                format!("{m:?}").to_lowercase(),
                (offered.iter())
                    .map(|o| format!("{o:?}").to_lowercase())
                    .collect::<Vec<_>>()
                    .join(", ")
            ))),
            None => Ok([PresentMode::Immediate, PresentMode::Mailbox]
                .into_iter()
                .find(|&m| has(m))
                .unwrap_or(PresentMode::Fifo)),
        }
    }
}

/// The instance extensions a surface on `display` needs.
pub fn surface_extensions(display: RawDisplayHandle) -> Result<Vec<&'static CStr>> {
    let exts = ash_window::enumerate_required_extensions(display)
        .vk("the window system has no Vulkan surface extension")?;
    // The pointers name static extension strings of ash.
    Ok(exts.iter().map(|&p| unsafe { CStr::from_ptr(p) }).collect())
}

struct Swapchain {
    loader: ash::khr::swapchain::Device,
    raw: vk::SwapchainKHR,
    images: Vec<vk::Image>,
    format: vk::Format,
    extent: vk::Extent2D,
    present_sems: Vec<vk::Semaphore>,
}

pub struct Presenter {
    gpu: Arc<Gpu>,
    surface_loader: ash::khr::surface::Instance,
    surface: vk::SurfaceKHR,
    swap: Option<Swapchain>,
    acquire_sem: vk::Semaphore,
    wanted: Option<PresentMode>,
    /// The mode in use (after the first swapchain).
    pub mode: Option<PresentMode>,
    /// Swapchains made so far, and the size of the last.
    pub created: u32,
}

impl Presenter {
    /// A presenter for the window with these handles; the device must have been made with the
    /// [`surface_extensions`] and the swapchain extension.
    pub fn new(
        gpu: &Arc<Gpu>,
        display: RawDisplayHandle,
        window: RawWindowHandle,
        wanted: Option<PresentMode>,
    ) -> Result<Presenter> {
        let surface =
            unsafe { ash_window::create_surface(&gpu.entry, &gpu.instance, display, window, None) }
                .vk("create window surface")?;
        let surface_loader = ash::khr::surface::Instance::new(&gpu.entry, &gpu.instance);
        let acquire_sem = unsafe {
            gpu.device
                .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
        }
        .vk("create semaphore")?;
        Ok(Presenter {
            gpu: gpu.clone(),
            surface_loader,
            surface,
            swap: None,
            acquire_sem,
            wanted,
            mode: None,
            created: 0,
        })
    }

    /// The swapchain is made again before the next frame (the window was resized).
    pub fn invalidate(&mut self) {
        self.destroy_swapchain();
    }

    /// Whether the picture's bytes are B, G, R, A (else R, G, B, A).
    pub fn bgr(&self) -> bool {
        matches!(
            self.swap.as_ref().map(|s| s.format),
            Some(vk::Format::B8G8R8A8_UNORM | vk::Format::B8G8R8A8_SRGB)
        )
    }

    /// The swapchain's size, making it for a window of `size` if there is none.
    pub fn extent(&mut self, size: (u32, u32)) -> Result<(u32, u32)> {
        if self.swap.is_none() {
            self.create(size)?;
        }
        let e = self.swap.as_ref().unwrap().extent;
        Ok((e.width, e.height))
    }

    fn destroy_swapchain(&mut self) {
        if let Some(old) = self.swap.take() {
            unsafe {
                let _ = self.gpu.device.device_wait_idle();
                for s in &old.present_sems {
                    self.gpu.device.destroy_semaphore(*s, None);
                }
                old.loader.destroy_swapchain(old.raw, None);
            }
        }
    }

    fn create(&mut self, size: (u32, u32)) -> Result<()> {
        self.destroy_swapchain();
        let (gpu, sl) = (&self.gpu, &self.surface_loader);
        let (pd, surface) = (gpu.pdevice, self.surface);
        unsafe {
            if !(sl.get_physical_device_surface_support(pd, gpu.queue_family, surface))
                .vk("query surface support")?
            {
                return Err(Error::Other(
                    "the Vulkan queue cannot present to this window".into(),
                ));
            }
            let caps = (sl.get_physical_device_surface_capabilities(pd, surface))
                .vk("query surface capabilities")?;
            let formats = (sl.get_physical_device_surface_formats(pd, surface))
                .vk("query surface formats")?;
            let modes = (sl.get_physical_device_surface_present_modes(pd, surface))
                .vk("query present modes")?;
            let mode = PresentMode::choose(self.wanted, &modes)?;
            // Pictures arrive sRGB-encoded already: a UNORM target (no second encoding).
            let f = (formats.iter())
                .find(|f| {
                    matches!(
                        f.format,
                        vk::Format::B8G8R8A8_UNORM | vk::Format::R8G8B8A8_UNORM
                    )
                })
                .or(formats.first())
                .ok_or_else(|| Error::Other("the surface offers no formats".into()))?;
            let extent = if caps.current_extent.width != u32::MAX {
                caps.current_extent
            } else {
                vk::Extent2D {
                    width: size
                        .0
                        .clamp(caps.min_image_extent.width, caps.max_image_extent.width),
                    height: (size.1)
                        .clamp(caps.min_image_extent.height, caps.max_image_extent.height),
                }
            };
            let mut count = caps.min_image_count + 1;
            if caps.max_image_count > 0 {
                count = count.min(caps.max_image_count);
            }
            let alpha = [
                vk::CompositeAlphaFlagsKHR::OPAQUE,
                vk::CompositeAlphaFlagsKHR::INHERIT,
                vk::CompositeAlphaFlagsKHR::PRE_MULTIPLIED,
                vk::CompositeAlphaFlagsKHR::POST_MULTIPLIED,
            ]
            .into_iter()
            .find(|a| caps.supported_composite_alpha.contains(*a))
            .unwrap_or(vk::CompositeAlphaFlagsKHR::OPAQUE);
            let loader = ash::khr::swapchain::Device::new(&gpu.instance, &gpu.device);
            let info = vk::SwapchainCreateInfoKHR::default()
                .surface(surface)
                .min_image_count(count)
                .image_format(f.format)
                .image_color_space(f.color_space)
                .image_extent(extent)
                .image_array_layers(1)
                .image_usage(vk::ImageUsageFlags::TRANSFER_DST)
                .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
                .pre_transform(caps.current_transform)
                .composite_alpha(alpha)
                .present_mode(mode.vk())
                .clipped(true);
            let raw = loader
                .create_swapchain(&info, None)
                .vk("create swapchain")?;
            let images = loader
                .get_swapchain_images(raw)
                .vk("get swapchain images")?;
            let present_sems = (images.iter())
                .map(|_| {
                    gpu.device
                        .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
                })
                .collect::<std::result::Result<Vec<_>, _>>()
                .vk("create semaphore")?;
            self.swap = Some(Swapchain {
                loader,
                raw,
                images,
                format: f.format,
                extent,
                present_sems,
            });
            self.mode = Some(mode);
            self.created += 1;
        }
        Ok(())
    }

    /// Shows one picture in a window of `size`: `record` records the commands that make it
    /// (given the swapchain's size) and returns the buffer that holds it, which is then copied
    /// to the acquired image and presented. Ok(false): the swapchain was out of date and is
    /// made again for the next call.
    pub fn present(
        &mut self,
        size: (u32, u32),
        record: impl FnOnce(vk::CommandBuffer, (u32, u32)) -> Result<vk::Buffer>,
    ) -> Result<bool> {
        let ext = self.extent(size)?;
        let swap = self.swap.as_ref().unwrap();
        let acquired = unsafe {
            (swap.loader).acquire_next_image(
                swap.raw,
                u64::MAX,
                self.acquire_sem,
                vk::Fence::null(),
            )
        };
        let idx = match acquired {
            Ok((i, _)) => i,
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => {
                self.destroy_swapchain();
                return Ok(false);
            }
            Err(e) => {
                return Err(Error::Vk {
                    what: "acquire swapchain image",
                    result: e,
                })
            }
        };
        let (target, sem) = (swap.images[idx as usize], swap.present_sems[idx as usize]);
        let gpu = self.gpu.clone();
        let wait = [(self.acquire_sem, vk::PipelineStageFlags::TRANSFER)];
        let recorded = gpu.submit_sync(&wait, &[sem], |cmd| -> Result<()> {
            let src = record(cmd, ext)?;
            copy_to_image(&gpu, cmd, src, target, ext);
            Ok(())
        })?;
        // An error while recording still submitted the (empty) commands that signal the semaphore.
        recorded?;
        let (sems, scs, idxs) = ([sem], [swap.raw], [idx]);
        let info = vk::PresentInfoKHR::default()
            .wait_semaphores(&sems)
            .swapchains(&scs)
            .image_indices(&idxs);
        match unsafe { swap.loader.queue_present(gpu.queue, &info) } {
            Ok(false) => Ok(true),
            Ok(true) | Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => {
                self.destroy_swapchain();
                Ok(true)
            }
            Err(e) => Err(Error::Vk {
                what: "present",
                result: e,
            }),
        }
    }
}

/// Copies a picture buffer into a swapchain image and leaves the image ready to present.
fn copy_to_image(
    gpu: &Gpu,
    cmd: vk::CommandBuffer,
    src: vk::Buffer,
    image: vk::Image,
    ext: (u32, u32),
) {
    let color = vk::ImageAspectFlags::COLOR;
    let layers = vk::ImageSubresourceLayers::default()
        .aspect_mask(color)
        .layer_count(1);
    image_barrier(
        gpu,
        cmd,
        image,
        color,
        vk::ImageLayout::UNDEFINED,
        vk::ImageLayout::TRANSFER_DST_OPTIMAL,
    );
    let region = vk::BufferImageCopy::default()
        .image_subresource(layers)
        .image_extent(vk::Extent3D {
            width: ext.0,
            height: ext.1,
            depth: 1,
        });
    unsafe {
        (gpu.device).cmd_copy_buffer_to_image(
            cmd,
            src,
            image,
            vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            &[region],
        )
    };
    image_barrier(
        gpu,
        cmd,
        image,
        color,
        vk::ImageLayout::TRANSFER_DST_OPTIMAL,
        vk::ImageLayout::PRESENT_SRC_KHR,
    );
}

impl Drop for Presenter {
    fn drop(&mut self) {
        self.destroy_swapchain();
        unsafe {
            let _ = self.gpu.device.device_wait_idle();
            self.gpu.device.destroy_semaphore(self.acquire_sem, None);
            self.surface_loader.destroy_surface(self.surface, None);
        }
    }
}
