//! `relit view`: the interactive viewer. A winit window with a Vulkan swapchain: each frame is
//! rendered by the engine at the chosen resolution and blitted (scaled) to the window.
//!
//! Keys: W/A/S/D move, Q/E down/up (Shift: faster), drag with the left mouse button or use the
//! arrow keys to look; 0 original lighting, 1–9 the scene's presets; Tab selects an added light,
//! +/− change its intensity; [ ] change α_dim; M cycles network (with weights) / ULR / ratio / ratio-filled (with weights); P saves a screenshot;
//! F11 toggles fullscreen; Esc quits. The title shows fps and per-pass GPU times.
//! Lights (`view_lights.rs`): N adds a lamp where the window's centre looks; I/K/J/L move the
//! selected light forward/back/left/right, U/O down/up; , and . shrink and grow it; C changes
//! its colour; F5 saves the lights and the lighting (preset "viewer") to scene.json.

use std::collections::HashSet;
use std::ffi::CStr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use glam::Vec3;
use raw_window_handle::{HasDisplayHandle, HasWindowHandle};
use relit_engine::frame::{added_lights, Lighting, Mode, Renderer};
use relit_engine::gpu::{image_barrier, vk, Buffer, Gpu, GpuOptions, Image, MemoryLocation, Timer};
use relit_engine::scene::{Camera, Scene};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Fullscreen, Window, WindowId};

pub struct ViewArgs {
    pub scene: PathBuf,
    pub res: (u32, u32),
    pub fullscreen: bool,
    pub frames: Option<u64>,
    pub screenshot: Option<PathBuf>,
    pub camera: Option<String>,
    pub lighting: Option<String>,
    pub frame: crate::render::FrameArgs,
    /// Scripted key presses, "FRAME:KEY,…" (see `view_lights::parse_script`).
    pub keys: Option<String>,
}

struct Swap {
    loader: ash::khr::swapchain::Device,
    raw: vk::SwapchainKHR,
    images: Vec<vk::Image>,
    format: vk::Format,
    extent: vk::Extent2D,
    readable: bool,
    present_sems: Vec<vk::Semaphore>,
}

struct App {
    gpu: Arc<Gpu>,
    renderer: Renderer,
    mode: Mode,
    scene: Scene,
    lighting: Lighting,
    preset_name: String,
    selected_light: usize,
    pos: Vec3,
    yaw: f32,
    pitch: f32,
    fov_deg: f32,
    res: (u32, u32),
    exposure: f32,
    window: Option<Arc<Window>>,
    surface_loader: ash::khr::surface::Instance,
    surface: vk::SurfaceKHR,
    swap: Option<Swap>,
    acquire_sem: vk::Semaphore,
    frame_img: Option<Image>,
    held: HashSet<KeyCode>,
    dragging: bool,
    last_cursor: Option<(f64, f64)>,
    last: Instant,
    fps: f32,
    frames_done: u64,
    max_frames: Option<u64>,
    screenshot_at_end: Option<PathBuf>,
    screenshot_now: Option<PathBuf>,
    shots: u32,
    fullscreen: bool,
    error: Option<anyhow::Error>,
    lights: crate::view_lights::LightEditor,
    /// Scripted key presses (frame index, key), for tests and demos: `--keys`.
    script: Vec<(u64, KeyCode)>,
}

fn camera_from(pos: Vec3, yaw: f32, pitch: f32, fov_deg: f32, (w, h): (u32, u32)) -> Camera {
    let fwd = Vec3::new(
        yaw.sin() * pitch.cos(),
        pitch.sin(),
        -yaw.cos() * pitch.cos(),
    );
    let fx = w as f32 * 0.5 / (fov_deg.to_radians() * 0.5).tan();
    Camera::look_at(pos, pos + fwd, Vec3::Y, w, h, fx)
}

impl App {
    fn camera(&self) -> Camera {
        camera_from(self.pos, self.yaw, self.pitch, self.fov_deg, self.res)
    }

    fn create_swapchain(&mut self) -> Result<()> {
        let gpu = &self.gpu;
        let window = self.window.as_ref().unwrap();
        let size = window.inner_size();
        unsafe {
            if let Some(old) = self.swap.take() {
                gpu.device.device_wait_idle()?;
                for s in &old.present_sems {
                    gpu.device.destroy_semaphore(*s, None);
                }
                old.loader.destroy_swapchain(old.raw, None);
            }
            let sl = &self.surface_loader;
            if !sl.get_physical_device_surface_support(
                gpu.pdevice,
                gpu.queue_family,
                self.surface,
            )? {
                bail!("the Vulkan queue cannot present to this window");
            }
            let caps = sl.get_physical_device_surface_capabilities(gpu.pdevice, self.surface)?;
            let formats = sl.get_physical_device_surface_formats(gpu.pdevice, self.surface)?;
            // Frames arrive sRGB-encoded already: prefer a UNORM target (no second encoding).
            let f = formats
                .iter()
                .find(|f| {
                    matches!(
                        f.format,
                        vk::Format::B8G8R8A8_UNORM | vk::Format::R8G8B8A8_UNORM
                    )
                })
                .or(formats.first())
                .context("the surface offers no formats")?;
            let extent = if caps.current_extent.width != u32::MAX {
                caps.current_extent
            } else {
                vk::Extent2D {
                    width: size
                        .width
                        .clamp(caps.min_image_extent.width, caps.max_image_extent.width),
                    height: size
                        .height
                        .clamp(caps.min_image_extent.height, caps.max_image_extent.height),
                }
            };
            let readable = caps
                .supported_usage_flags
                .contains(vk::ImageUsageFlags::TRANSFER_SRC);
            let mut usage = vk::ImageUsageFlags::TRANSFER_DST;
            if readable {
                usage |= vk::ImageUsageFlags::TRANSFER_SRC;
            }
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
            let raw = loader.create_swapchain(
                &vk::SwapchainCreateInfoKHR::default()
                    .surface(self.surface)
                    .min_image_count(count)
                    .image_format(f.format)
                    .image_color_space(f.color_space)
                    .image_extent(extent)
                    .image_array_layers(1)
                    .image_usage(usage)
                    .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
                    .pre_transform(caps.current_transform)
                    .composite_alpha(alpha)
                    .present_mode(vk::PresentModeKHR::FIFO)
                    .clipped(true),
                None,
            )?;
            let images = loader.get_swapchain_images(raw)?;
            let present_sems = images
                .iter()
                .map(|_| {
                    gpu.device
                        .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
                })
                .collect::<Result<Vec<_>, _>>()?;
            self.swap = Some(Swap {
                loader,
                raw,
                images,
                format: f.format,
                extent,
                readable,
                present_sems,
            });
        }
        Ok(())
    }

    fn update_camera(&mut self, dt: f32) {
        let fast =
            self.held.contains(&KeyCode::ShiftLeft) || self.held.contains(&KeyCode::ShiftRight);
        let speed = if fast { 2.0 } else { 0.6 } * dt;
        let fwd = Vec3::new(self.yaw.sin(), 0.0, -self.yaw.cos());
        let right = Vec3::new(self.yaw.cos(), 0.0, self.yaw.sin());
        let k = |c: KeyCode| if self.held.contains(&c) { 1.0 } else { 0.0 };
        self.pos += fwd * speed * (k(KeyCode::KeyW) - k(KeyCode::KeyS));
        self.pos += right * speed * (k(KeyCode::KeyD) - k(KeyCode::KeyA));
        self.pos.y += speed * (k(KeyCode::KeyE) - k(KeyCode::KeyQ));
        let turn = 1.2 * dt;
        self.yaw += turn * (k(KeyCode::ArrowRight) - k(KeyCode::ArrowLeft));
        self.pitch =
            (self.pitch + turn * (k(KeyCode::ArrowUp) - k(KeyCode::ArrowDown))).clamp(-1.5, 1.5);
    }

    fn key(&mut self, code: KeyCode, el: &ActiveEventLoop) {
        let cam = self.camera();
        match self.lights.key(
            code,
            &cam,
            &mut self.scene,
            &mut self.renderer,
            &mut self.lighting,
            &mut self.selected_light,
        ) {
            Ok(true) => {
                self.preset_name = "custom".into();
                return;
            }
            Ok(false) => {}
            Err(e) => eprintln!("{e:#}"),
        }
        let lights = added_lights(&self.scene);
        match code {
            KeyCode::Escape => el.exit(),
            KeyCode::F11 => {
                self.fullscreen = !self.fullscreen;
                if let Some(w) = &self.window {
                    w.set_fullscreen(self.fullscreen.then_some(Fullscreen::Borderless(None)));
                }
            }
            KeyCode::Digit0 => {
                self.lighting = Lighting::original(&self.scene);
                self.preset_name = "original".into();
            }
            KeyCode::Digit1
            | KeyCode::Digit2
            | KeyCode::Digit3
            | KeyCode::Digit4
            | KeyCode::Digit5
            | KeyCode::Digit6
            | KeyCode::Digit7
            | KeyCode::Digit8
            | KeyCode::Digit9 => {
                let i = code as usize - KeyCode::Digit1 as usize;
                if let Some(p) = self.scene.presets.get(i) {
                    if let Ok(l) = Lighting::preset(&self.scene, &p.name) {
                        self.lighting = l;
                        self.preset_name = p.name.clone();
                    }
                }
            }
            KeyCode::Tab if !lights.is_empty() => {
                self.selected_light = (self.selected_light + 1) % lights.len()
            }
            KeyCode::Equal | KeyCode::NumpadAdd | KeyCode::Minus | KeyCode::NumpadSubtract
                if !lights.is_empty() =>
            {
                let d = if matches!(code, KeyCode::Equal | KeyCode::NumpadAdd) {
                    0.1
                } else {
                    -0.1
                };
                let v = &mut self.lighting.intensities[self.selected_light];
                *v = (*v + d).clamp(0.0, 10.0);
                self.preset_name = "custom".into();
            }
            KeyCode::BracketLeft | KeyCode::BracketRight => {
                let d = if code == KeyCode::BracketRight {
                    0.05
                } else {
                    -0.05
                };
                self.lighting.alpha_dim = (self.lighting.alpha_dim + d).clamp(0.0, 1.0);
                self.preset_name = "custom".into();
            }
            KeyCode::KeyM => {
                // Network (with weights) → ULR → ratio → ratio-filled (with weights) → …
                self.mode = match self.mode {
                    Mode::Network => Mode::Ulr,
                    Mode::Ulr => Mode::Ratio,
                    Mode::Ratio if self.renderer.net.is_some() => Mode::RatioFilled,
                    Mode::Ratio => Mode::Ulr,
                    Mode::RatioFilled => Mode::Network,
                };
            }
            KeyCode::KeyP => {
                self.shots += 1;
                self.screenshot_now = Some(PathBuf::from(format!(
                    "relit-screenshot-{:03}.png",
                    self.shots
                )));
            }
            _ => {}
        }
    }

    /// A light the bake has no entry for (`relit bake` bakes the presets' lights) is traced
    /// live from the frame it is first lit, as a moved one is: the viewer starts at once and the
    /// light shows at the next frame, refining over ~2 s.
    fn trace_unbaked_lights_live(&mut self) -> Result<()> {
        let r = &self.renderer;
        let todo: Vec<(usize, String)> = (r.scene.lights.iter().enumerate())
            .filter(|&(i, n)| {
                self.lighting.intensities.get(i).is_some_and(|&v| v != 0.0)
                    && r.scene.unbaked.contains(n)
                    && !r.live.is_live(i)
            })
            .map(|(i, n)| (i, n.clone()))
            .collect();
        for (i, name) in todo {
            let light = (self.scene.lights.iter())
                .find(|l| l.name == name)
                .context("an added light left the scene")?
                .clone();
            eprintln!("{name}: not in the bake; traced live");
            self.renderer.set_live_light(i, &light)?;
        }
        Ok(())
    }

    fn draw(&mut self, el: &ActiveEventLoop) -> Result<()> {
        // A minimized window has no area to present to.
        if self.window.as_ref().is_some_and(|w| {
            let s = w.inner_size();
            s.width == 0 || s.height == 0
        }) {
            return Ok(());
        }
        let now = Instant::now();
        let dt = (now - self.last).as_secs_f32().min(0.5);
        self.last = now;
        self.update_camera(dt);
        let due: Vec<KeyCode> = self
            .script
            .iter()
            .filter(|(f, _)| *f == self.frames_done)
            .map(|(_, k)| *k)
            .collect();
        for k in due {
            self.key(k, el);
        }
        self.trace_unbaked_lights_live()?;
        // Live lights: a few more paths per texel of their caches each frame.
        self.renderer.refine_live()?;
        let cam = self.camera();
        let mut timer = Timer::new(&self.gpu, 64)?;
        self.renderer.render(
            &cam,
            &self.lighting,
            self.mode,
            self.exposure,
            Some(&mut timer),
        )?;
        let spans = timer.read()?;
        let gpu = self.gpu.clone();
        let (w, h) = self.res;
        if self
            .frame_img
            .as_ref()
            .is_none_or(|i| (i.width, i.height) != (w, h))
        {
            self.frame_img = Some(Image::new(
                &gpu,
                "view frame",
                vk::Format::R8G8B8A8_UNORM,
                w,
                h,
                1,
                vk::ImageUsageFlags::SAMPLED,
            )?);
        }
        if self.swap.is_none() {
            self.create_swapchain()?;
        }
        let swap = self.swap.as_ref().unwrap();
        let idx = match unsafe {
            swap.loader
                .acquire_next_image(swap.raw, u64::MAX, self.acquire_sem, vk::Fence::null())
        } {
            Ok((i, _)) => i,
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => {
                self.create_swapchain()?;
                return Ok(());
            }
            Err(e) => return Err(e.into()),
        };
        let target = swap.images[idx as usize];
        let ext = swap.extent;
        let shot = if self.frames_done + 1 == self.max_frames.unwrap_or(u64::MAX) {
            self.screenshot_at_end
                .clone()
                .or(self.screenshot_now.take())
        } else {
            self.screenshot_now.take()
        };
        let read_back = shot.is_some() && swap.readable;
        // Only a screenshot needs the window's pixels back.
        let readback = Buffer::new(
            &gpu,
            "screenshot",
            if read_back {
                (ext.width * ext.height * 4) as u64
            } else {
                4
            },
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        let fimg = self.frame_img.as_ref().unwrap();
        let ldr = &self.renderer.buffers_ref().unwrap().ldr;
        let color = vk::ImageAspectFlags::COLOR;
        let layers = vk::ImageSubresourceLayers::default()
            .aspect_mask(color)
            .layer_count(1);
        let present_sem = swap.present_sems[idx as usize];
        gpu.submit_sync(
            &[(self.acquire_sem, vk::PipelineStageFlags::TRANSFER)],
            &[present_sem],
            |cmd| unsafe {
                let d = &gpu.device;
                image_barrier(
                    &gpu,
                    cmd,
                    fimg.raw,
                    color,
                    vk::ImageLayout::UNDEFINED,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                );
                d.cmd_copy_buffer_to_image(
                    cmd,
                    ldr.raw,
                    fimg.raw,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    &[vk::BufferImageCopy::default()
                        .image_subresource(layers)
                        .image_extent(vk::Extent3D {
                            width: w,
                            height: h,
                            depth: 1,
                        })],
                );
                image_barrier(
                    &gpu,
                    cmd,
                    fimg.raw,
                    color,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                );
                image_barrier(
                    &gpu,
                    cmd,
                    target,
                    color,
                    vk::ImageLayout::UNDEFINED,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                );
                let same = (w, h) == (ext.width, ext.height);
                d.cmd_blit_image(
                    cmd,
                    fimg.raw,
                    vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                    target,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    &[vk::ImageBlit::default()
                        .src_subresource(layers)
                        .src_offsets([
                            vk::Offset3D::default(),
                            vk::Offset3D {
                                x: w as i32,
                                y: h as i32,
                                z: 1,
                            },
                        ])
                        .dst_subresource(layers)
                        .dst_offsets([
                            vk::Offset3D::default(),
                            vk::Offset3D {
                                x: ext.width as i32,
                                y: ext.height as i32,
                                z: 1,
                            },
                        ])],
                    if same {
                        vk::Filter::NEAREST
                    } else {
                        vk::Filter::LINEAR
                    },
                );
                let mut layout = vk::ImageLayout::TRANSFER_DST_OPTIMAL;
                if read_back {
                    image_barrier(
                        &gpu,
                        cmd,
                        target,
                        color,
                        layout,
                        vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                    );
                    layout = vk::ImageLayout::TRANSFER_SRC_OPTIMAL;
                    d.cmd_copy_image_to_buffer(
                        cmd,
                        target,
                        layout,
                        readback.raw,
                        &[vk::BufferImageCopy::default()
                            .image_subresource(layers)
                            .image_extent(vk::Extent3D {
                                width: ext.width,
                                height: ext.height,
                                depth: 1,
                            })],
                    );
                }
                image_barrier(
                    &gpu,
                    cmd,
                    target,
                    color,
                    layout,
                    vk::ImageLayout::PRESENT_SRC_KHR,
                );
            },
        )?;
        let sems = [present_sem];
        let scs = [swap.raw];
        let idxs = [idx];
        let present = unsafe {
            swap.loader.queue_present(
                gpu.queue,
                &vk::PresentInfoKHR::default()
                    .wait_semaphores(&sems)
                    .swapchains(&scs)
                    .image_indices(&idxs),
            )
        };
        match present {
            Ok(false) => {}
            Ok(true) | Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => self.swap = None,
            Err(e) => return Err(e.into()),
        }
        if let Some(path) = shot {
            self.save_screenshot(&path, read_back, &readback, ext)?;
        }
        self.frames_done += 1;
        self.fps = if self.fps == 0.0 {
            1.0 / dt.max(1e-3)
        } else {
            0.8 * self.fps + 0.2 / dt.max(1e-3)
        };
        let passes: Vec<String> = spans
            .iter()
            .filter(|(l, _)| {
                !l.starts_with("net: level") && !l.starts_with("net: ") || l == "net: trunk"
            })
            .map(|(l, ms)| format!("{l} {ms:.0}"))
            .collect();
        let net_ms: f64 = spans
            .iter()
            .filter(|(l, _)| l.starts_with("net: "))
            .map(|s| s.1)
            .sum();
        let light = added_lights(&self.scene)
            .get(self.selected_light)
            .map(|n| {
                let live = self
                    .renderer
                    .live
                    .progress()
                    .iter()
                    .find(|(l, _)| *l as usize == self.selected_light)
                    .map(|(_, p)| format!(" (cache {p}/{} paths)", self.renderer.live.params.paths))
                    .unwrap_or_default();
                format!(
                    " | light {n} {:.1}{live}",
                    self.lighting.intensities[self.selected_light]
                )
            })
            .unwrap_or_default();
        if let Some(win) = &self.window {
            win.set_title(&format!(
                "relit — {:.2} fps | {:?} | {} | dim {:.2}{light} | ms: {}{}",
                self.fps,
                self.mode,
                self.preset_name,
                self.lighting.alpha_dim,
                passes.join(", "),
                if net_ms > 0.0 {
                    format!(", network {net_ms:.0}")
                } else {
                    String::new()
                }
            ));
        }
        if self.max_frames.is_some_and(|n| self.frames_done >= n) {
            el.exit();
        }
        Ok(())
    }

    fn save_screenshot(
        &self,
        path: &Path,
        from_window: bool,
        buf: &Buffer,
        ext: vk::Extent2D,
    ) -> Result<()> {
        let (w, h, rgba) = if from_window {
            let mut px = buf.download_range(0, (ext.width * ext.height * 4) as u64)?;
            let bgr = matches!(
                self.swap.as_ref().map(|s| s.format),
                Some(vk::Format::B8G8R8A8_UNORM | vk::Format::B8G8R8A8_SRGB)
            );
            if bgr {
                px.chunks_exact_mut(4).for_each(|p| p.swap(0, 2));
            }
            (ext.width, ext.height, px)
        } else {
            (self.res.0, self.res.1, self.renderer.ldr()?)
        };
        relit_engine::scene::image::write_png_rgba8(path, w, h, &rgba)?;
        println!(
            "screenshot: {} ({w}x{h}{})",
            path.display(),
            if from_window {
                ", read back from the window"
            } else {
                ""
            }
        );
        Ok(())
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let attrs = Window::default_attributes()
            .with_title("relit")
            .with_inner_size(winit::dpi::PhysicalSize::new(self.res.0, self.res.1))
            .with_fullscreen(self.fullscreen.then_some(Fullscreen::Borderless(None)));
        let res = (|| -> Result<()> {
            let window = Arc::new(el.create_window(attrs)?);
            self.surface = unsafe {
                ash_window::create_surface(
                    &self.gpu.entry,
                    &self.gpu.instance,
                    window.display_handle()?.as_raw(),
                    window.window_handle()?.as_raw(),
                    None,
                )?
            };
            self.window = Some(window);
            self.create_swapchain()
        })();
        if let Err(e) = res {
            self.error = Some(e.context("opening the window"));
            el.exit();
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => el.exit(),
            WindowEvent::Resized(_) => self.swap = None,
            WindowEvent::KeyboardInput { event, .. } => {
                if let PhysicalKey::Code(code) = event.physical_key {
                    if event.state == ElementState::Pressed {
                        // Moving a light repeats while the key is held.
                        if !event.repeat || crate::view_lights::REPEATS.contains(&code) {
                            self.key(code, el);
                        }
                        self.held.insert(code);
                    } else {
                        self.held.remove(&code);
                    }
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => {
                self.dragging = state == ElementState::Pressed;
                self.last_cursor = None;
            }
            WindowEvent::CursorMoved { position, .. } if self.dragging => {
                if let Some((x, y)) = self.last_cursor {
                    self.yaw += (position.x - x) as f32 * 0.005;
                    self.pitch = (self.pitch - (position.y - y) as f32 * 0.005).clamp(-1.5, 1.5);
                }
                self.last_cursor = Some((position.x, position.y));
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.draw(el) {
                    self.error = Some(e);
                    el.exit();
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, _el: &ActiveEventLoop) {
        if let Some(w) = &self.window {
            w.request_redraw();
        }
    }
}

pub fn view(opts: &GpuOptions, a: ViewArgs) -> Result<()> {
    let el =
        EventLoop::new().context("opening the display (is DISPLAY or WAYLAND_DISPLAY set?)")?;
    let exts = ash_window::enumerate_required_extensions(el.display_handle()?.as_raw())
        .context("the window system has no Vulkan surface extension")?;
    let mut o = opts.clone();
    // The pointers name static extension strings of ash.
    o.instance_extensions = exts.iter().map(|&p| unsafe { CStr::from_ptr(p) }).collect();
    o.swapchain = true;
    let scene = Scene::load(&a.scene)?;
    let gpu = crate::open_gpu(&o)?;
    let lighting = match &a.lighting {
        Some(p) => Lighting::preset(&scene, p)?,
        None => Lighting::original(&scene),
    };
    // Frames render at --res whatever the window size (then scaled to it). The start lighting's
    // lights are baked now if need be; others are traced live when first lit.
    let used = Some(crate::render::lit(&scene, &lighting));
    let (renderer, mode) =
        crate::render::open_renderer(&gpu, &scene, &a.frame, Some(a.res), used, true)?;
    let start = match &a.camera {
        Some(c) => crate::render::resolve_camera(&scene, c, Some(a.res))?,
        None => crate::render::rescale(&scene.views[0].camera, a.res.0, a.res.1),
    };
    // Yaw/pitch of the start camera's forward axis (camera rows: right, down, forward).
    let fwd = start.rotation.row(2);
    let surface_loader = ash::khr::surface::Instance::new(&gpu.entry, &gpu.instance);
    let acquire_sem = unsafe {
        gpu.device
            .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)?
    };
    let script = a
        .keys
        .as_deref()
        .map(crate::view_lights::parse_script)
        .transpose()?
        .unwrap_or_default();
    let mut app = App {
        lights: crate::view_lights::LightEditor::new(&renderer),
        script,
        renderer,
        mode,
        preset_name: a.lighting.clone().unwrap_or_else(|| "original".into()),
        lighting,
        selected_light: 0,
        pos: start.center(),
        yaw: fwd.x.atan2(-fwd.z),
        pitch: fwd.y.clamp(-1.0, 1.0).asin(),
        fov_deg: 2.0 * (start.width as f32 * 0.5 / start.fx).atan().to_degrees(),
        res: a.res,
        exposure: a.frame.exposure,
        window: None,
        surface_loader,
        surface: vk::SurfaceKHR::null(),
        swap: None,
        acquire_sem,
        frame_img: None,
        held: HashSet::new(),
        dragging: false,
        last_cursor: None,
        last: Instant::now(),
        fps: 0.0,
        frames_done: 0,
        max_frames: a.frames,
        screenshot_at_end: a.screenshot.clone(),
        screenshot_now: None,
        shots: 0,
        fullscreen: a.fullscreen,
        error: None,
        scene,
        gpu: gpu.clone(),
    };
    let run = el.run_app(&mut app);
    unsafe {
        let _ = gpu.device.device_wait_idle();
        if let Some(s) = app.swap.take() {
            for x in &s.present_sems {
                gpu.device.destroy_semaphore(*x, None);
            }
            s.loader.destroy_swapchain(s.raw, None);
        }
        gpu.device.destroy_semaphore(app.acquire_sem, None);
        if app.surface != vk::SurfaceKHR::null() {
            app.surface_loader.destroy_surface(app.surface, None);
        }
    }
    app.window = None;
    if let Some(e) = app.error.take() {
        return Err(e);
    }
    run.context("the window event loop")?;
    if a.frames.is_some() && app.frames_done == 0 {
        bail!("no frame was shown");
    }
    if gpu.validation_errors() > 0 {
        bail!(
            "{} Vulkan validation error(s) (see above)",
            gpu.validation_errors()
        );
    }
    Ok(())
}
