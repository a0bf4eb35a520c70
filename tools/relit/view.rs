//! `relit view`: the interactive viewer. Input, the HUD's contents and path recording live
//! here; the frame is the engine's `Renderer`, the window's picture `view::compose`, the
//! swapchain `gpu::present`. While anything moves the viewer shows the cheap frame (`Renderer::moving_mode`:
//! ratio, or glossy for glossy images, at a resolution that keeps up), and the full frame once the view has been still for a moment
//! (`view::fluid`). Every key is listed in `relit_engine::view::hud::KEYS` (F1 shows them).
//! Lights (`view_lights.rs`): N adds a lamp where the window's centre looks; I/K/J/L/U/O move
//! the selected one, , and . resize it, C recolours it, F5 saves the lights to scene.json.

use std::collections::{BTreeMap, HashSet};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use glam::Vec3;
use raw_window_handle::{HasDisplayHandle, HasWindowHandle};
use relit_engine::frame::lighting::AS_CAPTURED;
use relit_engine::frame::live::PathMoves;
use relit_engine::frame::{added_lights, Lighting, Mode, Renderer};
use relit_engine::gpu::{present, Gpu, GpuOptions, Graph, PresentMode, Presenter, Timer};
use relit_engine::scene::path::CameraPath;
use relit_engine::scene::{Camera, LightShape, Scene};
use relit_engine::view::compose::{Compose, HudText};
use relit_engine::view::fluid::{moving_res, Fluid, Next, Policy};
use relit_engine::view::hud::{key_lines, HudInfo, LightInfo};
use relit_engine::view::recorder::{camera_json, Keyframe, PathRecorder};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Fullscreen, Window, WindowId};

use crate::view_lights::Scripted;

pub struct ViewArgs {
    pub scene: PathBuf,
    pub res: (u32, u32),
    /// Window size (None: two thirds of the screen's height, the frame's aspect).
    pub window: Option<(u32, u32)>,
    pub present: Option<PresentMode>,
    pub fullscreen: bool,
    pub frames: Option<u64>,
    pub screenshot: Option<PathBuf>,
    pub camera: Option<String>,
    pub lighting: Option<String>,
    pub frame: crate::render::FrameArgs,
    /// Scripted input, "FRAME:KEY,…" (see `view_lights::parse_script`).
    pub keys: Option<String>,
    pub record: Option<PathBuf>,
    pub play: Option<PathBuf>,
    pub fluid: Policy,
    pub hud: bool,
}

/// A path being played back in the window.
struct Player {
    file: PathBuf,
    path: CameraPath,
    moves: PathMoves,
    t: f32,
    paused: bool,
}

/// What the view looks like, to tell whether anything moved since the last frame.
type Signature = Vec<f32>;

struct App {
    gpu: Arc<Gpu>,
    renderer: Renderer,
    mode: Mode,
    scene: Scene,
    lighting: Lighting,
    preset_name: String,
    selected_light: usize,
    /// The declared original light that Z and X dim and brighten.
    selected_original: usize,
    pos: Vec3,
    yaw: f32,
    pitch: f32,
    fov_deg: f32,
    res: (u32, u32),
    exposure: f32,
    window_size: Option<(u32, u32)>,
    window: Option<Arc<Window>>,
    presenter: Option<Presenter>,
    wanted_present: Option<PresentMode>,
    compose: Compose,
    held: HashSet<KeyCode>,
    dragging: bool,
    last_cursor: Option<(f64, f64)>,
    start: Instant,
    last: Instant,
    fluid: Fluid,
    signature: Option<Signature>,
    /// The last rendered frame: what it was, its wall time, its passes.
    shown: (Next, f64, Vec<(String, f64)>),
    hud_on: bool,
    help_on: bool,
    last_hud: Option<HudText>,
    /// The window's picture must be presented again (first frame, resize, HUD change).
    stale: bool,
    frames_done: u64,
    max_frames: Option<u64>,
    screenshot_at_end: Option<PathBuf>,
    screenshot_now: Option<PathBuf>,
    shots: u32,
    cameras: u32,
    fullscreen: bool,
    error: Option<anyhow::Error>,
    lights: crate::view_lights::LightEditor,
    /// Added lights' centres in scene.json (moves in a recorded path are relative to them).
    home: BTreeMap<String, Vec3>,
    recorder: Option<(PathBuf, PathRecorder)>,
    player: Option<Player>,
    script: Vec<(u64, Scripted)>,
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

/// Centres of the scene's added lights, by name.
fn light_centres(scene: &Scene) -> BTreeMap<String, Vec3> {
    (scene.lights.iter())
        .filter(|l| !l.original)
        .map(|l| (l.name.clone(), l.shape.center()))
        .collect()
}

/// The window's default size: two thirds of the screen's height at the frame's aspect (at most
/// 90% of its width); without a screen to measure, three times the frame.
fn default_window(res: (u32, u32), screen: Option<(u32, u32)>) -> (u32, u32) {
    let aspect = res.0 as f32 / res.1 as f32;
    match screen {
        Some((sw, sh)) if sw > 0 && sh > 0 => {
            let h = (sh as f32 * 2.0 / 3.0).min(sw as f32 * 0.9 / aspect);
            (((h * aspect) as u32).max(1), (h as u32).max(1))
        }
        _ => (res.0 * 3, res.1 * 3),
    }
}

impl App {
    fn camera(&self) -> Camera {
        match &self.player {
            Some(p) => p.path.camera_at(p.t, self.res.0, self.res.1),
            None => camera_from(self.pos, self.yaw, self.pitch, self.fov_deg, self.res),
        }
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

    /// Everything a frame depends on that input can change.
    fn signature(&self) -> Signature {
        let cam = self.camera();
        let mut s: Vec<f32> = cam.center().to_array().into();
        s.extend(cam.rotation.to_cols_array());
        s.extend(&self.lighting.intensities);
        s.push(self.lighting.alpha_dim);
        s.extend(self.lighting.originals.iter().flatten());
        s.push(self.mode as u32 as f32);
        for l in &self.scene.lights {
            s.extend(l.shape.center().to_array());
            s.extend(l.radiance);
            s.push(light_size(&l.shape));
        }
        s
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
                if code == KeyCode::F5 {
                    self.home = light_centres(&self.scene);
                }
                return;
            }
            Ok(false) => {}
            Err(e) => eprintln!("{e:#}"),
        }
        if let Err(e) = self.app_key(code, el) {
            eprintln!("{e:#}");
        }
    }

    /// Keys of the viewer itself (not the light editor's).
    fn app_key(&mut self, code: KeyCode, el: &ActiveEventLoop) -> Result<()> {
        let lights = added_lights(&self.scene);
        let originals = self.scene.original_names();
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
                    self.lighting = Lighting::preset(&self.scene, &p.name)?;
                    self.preset_name = p.name.clone();
                }
            }
            KeyCode::Tab if !lights.is_empty() => {
                self.selected_light = (self.selected_light + 1) % lights.len()
            }
            KeyCode::Equal | KeyCode::NumpadAdd | KeyCode::Minus | KeyCode::NumpadSubtract
                if !lights.is_empty() =>
            {
                let up = matches!(code, KeyCode::Equal | KeyCode::NumpadAdd);
                let v = &mut self.lighting.intensities[self.selected_light];
                *v = (*v + if up { 0.1 } else { -0.1 }).clamp(0.0, 10.0);
                self.preset_name = "custom".into();
            }
            KeyCode::KeyT if !originals.is_empty() => {
                self.selected_original = (self.selected_original + 1) % originals.len()
            }
            KeyCode::KeyZ | KeyCode::KeyX
                if originals.len() >= 2 && self.renderer.scene.split == 0 =>
            {
                bail!(
                    "Z X: the original lights have no entries in the bake yet: run `relit bake {} --lights all` once, then start the viewer again",
                    self.scene.root.display()
                )
            }
            KeyCode::KeyZ | KeyCode::KeyX if !originals.is_empty() => {
                let d = if code == KeyCode::KeyX { 0.1 } else { -0.1 };
                self.lighting.originals.resize(originals.len(), AS_CAPTURED);
                let c = &mut self.lighting.originals[self.selected_original];
                *c = c.map(|v| (v + d).clamp(0.0, 2.0));
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
                // Network (with weights) → ULR → ratio → glossy → ratio-filled (with weights) → …
                self.mode = match self.mode {
                    Mode::Network => Mode::Ulr,
                    Mode::Ulr => Mode::Ratio,
                    Mode::Ratio => Mode::Glossy,
                    Mode::Glossy if self.renderer.net.is_some() => Mode::RatioFilled,
                    Mode::Glossy => Mode::Ulr,
                    Mode::RatioFilled => Mode::Network,
                };
            }
            KeyCode::KeyG => {
                self.fluid.policy = self.fluid.policy.next();
                println!("frames: {:?}", self.fluid.policy);
            }
            KeyCode::KeyH => self.hud_on = !self.hud_on,
            KeyCode::F1 => self.help_on = !self.help_on,
            KeyCode::KeyR => self.add_keyframe()?,
            KeyCode::F6 => self.save_path()?,
            KeyCode::KeyV => self.write_camera()?,
            KeyCode::Space => {
                if let Some(p) = &mut self.player {
                    p.paused = !p.paused;
                }
            }
            KeyCode::KeyP => {
                self.shots += 1;
                let name = format!("relit-screenshot-{:03}.png", self.shots);
                self.screenshot_now = Some(PathBuf::from(name));
            }
            _ => {}
        }
        Ok(())
    }

    fn add_keyframe(&mut self) -> Result<()> {
        let Some((_, rec)) = &mut self.recorder else {
            bail!("R drops a keyframe when recording: start the viewer with --record PATH.json");
        };
        let names = added_lights(&self.scene);
        rec.add(Keyframe {
            camera: camera_from(self.pos, self.yaw, self.pitch, self.fov_deg, self.res),
            dim: self.lighting.alpha_dim,
            intensities: names
                .into_iter()
                .zip(self.lighting.intensities.clone())
                .collect(),
            lights: light_centres(&self.scene),
            originals: self.lighting.named_factors(&self.scene),
        });
        println!("keyframe {}", rec.keys.len());
        Ok(())
    }

    /// Writes the recorded path; lights it names must be in scene.json (F5 saves them).
    fn save_path(&self) -> Result<()> {
        let Some((file, rec)) = &self.recorder else {
            bail!("F6 saves a recorded path: start the viewer with --record PATH.json");
        };
        let mut lit = rec.keys.iter().flat_map(|k| k.intensities.iter());
        if let Some((name, _)) = lit.find(|(n, &v)| v != 0.0 && !self.home.contains_key(*n)) {
            bail!("light \"{name}\" was added in the viewer and is not in scene.json, so `relit fly` would not know it: press F5 to save the lights, then F6");
        }
        rec.save(file, &self.home)?;
        println!(
            "path: {} ({} keyframes, {:.1} s)",
            file.display(),
            rec.keys.len(),
            rec.times().last().copied().unwrap_or(0.0)
        );
        Ok(())
    }

    fn write_camera(&mut self) -> Result<()> {
        self.cameras += 1;
        let file = PathBuf::from(format!("relit-camera-{:03}.json", self.cameras));
        let text = camera_json(&self.camera());
        relit_engine::scene::write_atomic(&file, text.as_bytes())?;
        println!("camera: {} (use it with --camera FILE)", file.display());
        Ok(())
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

    /// Playback: the path's time advances by `dt` (looping), its lighting and light moves apply.
    fn advance_player(&mut self, dt: f32) -> Result<()> {
        let Some(p) = &mut self.player else {
            return Ok(());
        };
        if !p.paused {
            let (t0, t1) = (p.path.start(), p.path.duration());
            p.t += dt;
            if p.t > t1 {
                p.t = t0 + (p.t - t1) % (t1 - t0).max(1e-3);
            }
        }
        if let Some(l) = p.path.lighting_at(p.t) {
            self.lighting = Lighting::from_path(&self.scene, &l, &p.file)?;
            self.preset_name = format!("path {}", p.file.display());
        }
        p.moves.apply(&mut self.renderer, &p.path, p.t)?;
        Ok(())
    }

    fn run_script(&mut self, el: &ActiveEventLoop) {
        let due: Vec<Scripted> = (self.script.iter())
            .filter(|(f, _)| *f == self.frames_done)
            .map(|(_, k)| *k)
            .collect();
        for item in due {
            match item {
                Scripted::Press(k) => self.key(k, el),
                Scripted::Hold(k) => {
                    self.held.insert(k);
                }
                Scripted::Release(k) => {
                    self.held.remove(&k);
                }
                Scripted::Size(w, h) => {
                    if let Some(win) = &self.window {
                        let _ = win.request_inner_size(winit::dpi::PhysicalSize::new(w, h));
                    }
                }
            }
        }
    }

    /// Renders the frame `next` asks for; returns its wall time.
    fn render(&mut self, next: Next) -> Result<()> {
        let full = self.camera();
        let (cam, mode) = match next {
            Next::Moving { divisor } => {
                let (w, h) = moving_res(self.res, divisor);
                let mode = self.renderer.moving_mode(self.mode);
                (crate::render::rescale(&full, w, h), mode)
            }
            _ => (full, self.mode),
        };
        // Moving frames fill the holes no photo sees instead of showing them black.
        self.renderer.fill_holes = matches!(next, Next::Moving { .. });
        let mut timer = Timer::new(&self.gpu, 64)?;
        let t0 = Instant::now();
        (self.renderer).render(&cam, &self.lighting, mode, self.exposure, Some(&mut timer))?;
        let secs = t0.elapsed().as_secs_f64();
        self.fluid.rendered(next, secs);
        self.shown = (next, secs, timer.read()?);
        Ok(())
    }

    fn hud(&self) -> Option<HudText> {
        if self.help_on {
            return Some(HudText::new(&key_lines()));
        }
        if !self.hud_on {
            return None;
        }
        let (next, secs, passes) = &self.shown;
        let frame = match next {
            Next::Moving { divisor } => {
                let (w, h) = moving_res(self.res, *divisor);
                let m = format!("{:?}", self.renderer.moving_mode(self.mode)).to_lowercase();
                format!("moving {w}x{h} {m}")
            }
            _ => format!("still {}x{}", self.res.0, self.res.1),
        };
        let info = HudInfo {
            fps: (1.0 / secs.max(1e-6)) as f32,
            passes: passes.clone(),
            mode: format!("{:?}", self.mode),
            frame,
            policy: format!("{:?}", self.fluid.policy).to_lowercase(),
            lighting: self.preset_name.clone(),
            alpha_dim: self.lighting.alpha_dim,
            light: self.light_info(),
            original: (self.scene.original_names().get(self.selected_original))
                .map(|n| (n.clone(), self.lighting.factor(self.selected_original))),
            recording: self.recorder.as_ref().map(|(_, r)| r.keys.len()),
            playing: (self.player.as_ref()).map(|p| (p.t, p.path.duration())),
        };
        Some(HudText::new(&info.lines()))
    }

    fn light_info(&self) -> Option<LightInfo> {
        let added: Vec<_> = self.scene.lights.iter().filter(|l| !l.original).collect();
        let l = added.get(self.selected_light)?;
        let progress = self.renderer.live.progress();
        let live = (progress.iter())
            .find(|(layer, _)| *layer as usize == self.selected_light)
            .map(|(_, p)| (*p, self.renderer.live.params.paths));
        Some(LightInfo {
            name: l.name.clone(),
            position: l.shape.center().into(),
            size: light_size(&l.shape),
            colour: l.radiance,
            intensity: self.lighting.intensities[self.selected_light],
            live,
        })
    }

    fn draw(&mut self, el: &ActiveEventLoop) -> Result<()> {
        let Some(window) = self.window.clone() else {
            return Ok(());
        };
        let size = window.inner_size();
        // A minimized window has no area to present to.
        if size.width == 0 || size.height == 0 {
            return Ok(());
        }
        let now = Instant::now();
        let dt = (now - self.last).as_secs_f32().min(0.5);
        self.last = now;
        self.run_script(el);
        if self.player.is_some() {
            self.advance_player(dt)?;
        } else {
            self.update_camera(dt);
        }
        self.trace_unbaked_lights_live()?;
        // Live lights: a few more paths per texel of their caches each frame.
        let refined = self.renderer.refine_live()?;
        let sig = self.signature();
        let changed = self.signature.as_ref() != Some(&sig);
        self.signature = Some(sig);
        let next = (self.fluid).next(changed, refined, self.start.elapsed().as_secs_f64());
        if next != Next::Keep {
            self.render(next)?;
            self.stale = true;
        }
        let hud = self.hud();
        if hud != self.last_hud {
            self.stale = true;
        }
        let shot = match (self.screenshot_now.take(), &self.screenshot_at_end) {
            (Some(p), _) => Some(p),
            (None, Some(p)) if self.max_frames == Some(self.frames_done + 1) => Some(p.clone()),
            _ => None,
        };
        if self.stale || shot.is_some() {
            self.present((size.width, size.height), hud.as_ref())?;
            self.last_hud = hud;
        } else {
            // Nothing new to show: do not spin a core.
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        if let Some(path) = shot {
            self.save_screenshot(&path)?;
        }
        self.frames_done += 1;
        window.set_title(&format!(
            "relit — {} — {:.1} fps ({})",
            self.scene.root.display(),
            1.0 / self.shown.1.max(1e-6),
            if self.fluid.showing_still() {
                "still"
            } else {
                "moving"
            }
        ));
        if self.max_frames.is_some_and(|n| self.frames_done >= n) {
            el.exit();
        }
        Ok(())
    }

    /// Composes the last frame and the HUD at the window's size and presents it.
    fn present(&mut self, size: (u32, u32), hud: Option<&HudText>) -> Result<()> {
        let presenter = self.presenter.as_mut().context("no window")?;
        let b = self.renderer.buffers_ref().context("no frame rendered")?;
        let created = presenter.created;
        presenter.extent(size)?;
        let bgr = presenter.bgr();
        let compose = &mut self.compose;
        let gpu = &self.gpu;
        let shown = presenter.present(size, |cmd, ext| {
            let mut g = Graph::new(gpu, cmd, None);
            compose.record(&mut g, &b.ldr, (b.width, b.height), ext, hud, bgr)?;
            // The copy to the swapchain image follows, outside the graph.
            g.finish()?;
            Ok(compose.output().raw)
        })?;
        if presenter.created != created {
            let (w, h) = compose.size();
            let mode = presenter.mode.map(|m| format!("{m:?}")).unwrap_or_default();
            println!("swapchain: {w}x{h}, present mode {}", mode.to_lowercase());
        }
        // Out of date: made again, shown next time round.
        self.stale = !shown;
        Ok(())
    }

    fn save_screenshot(&self, path: &std::path::Path) -> Result<()> {
        let presenter = self.presenter.as_ref().context("no window")?;
        let rgba = self.compose.download_rgba(presenter.bgr())?;
        let (w, h) = self.compose.size();
        relit_engine::scene::image::write_png_rgba8(path, w, h, &rgba)?;
        println!(
            "screenshot: {} ({w}x{h}, the window's picture)",
            path.display()
        );
        Ok(())
    }
}

/// A light's size as the HUD shows it: a disk's radius, a quad's longer edge.
fn light_size(s: &LightShape) -> f32 {
    match s {
        LightShape::Disk { radius, .. } => *radius,
        LightShape::Quad { edge_u, edge_v, .. } => edge_u.length().max(edge_v.length()),
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let screen = (el
            .primary_monitor()
            .or_else(|| el.available_monitors().next()))
        .map(|m| (m.size().width, m.size().height));
        let (w, h) = self.window_size.unwrap_or(default_window(self.res, screen));
        let attrs = Window::default_attributes()
            .with_title("relit")
            .with_inner_size(winit::dpi::PhysicalSize::new(w, h))
            .with_fullscreen(self.fullscreen.then_some(Fullscreen::Borderless(None)));
        let res = (|| -> Result<()> {
            let window = Arc::new(el.create_window(attrs)?);
            self.presenter = Some(Presenter::new(
                &self.gpu,
                window.display_handle()?.as_raw(),
                window.window_handle()?.as_raw(),
                self.wanted_present,
            )?);
            self.window = Some(window);
            Ok(())
        })();
        if let Err(e) = res {
            self.error = Some(e.context("opening the window"));
            el.exit();
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => el.exit(),
            WindowEvent::Resized(_) => {
                if let Some(p) = &mut self.presenter {
                    p.invalidate();
                }
                self.stale = true;
            }
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

fn open_player(
    gpu: &Arc<Gpu>,
    scene: &Scene,
    file: &std::path::Path,
    a: &crate::render::FrameArgs,
) -> Result<Player> {
    let path = CameraPath::load(file)?;
    let params = crate::render::find_bake(scene, a.quality)?;
    let moves = PathMoves::new(gpu, scene, &params, &path, &mut |_: &str, _, _, _| {})?;
    Ok(Player {
        file: file.to_path_buf(),
        t: path.start(),
        path,
        moves,
        paused: false,
    })
}

pub fn view(opts: &GpuOptions, a: ViewArgs) -> Result<()> {
    if a.record.is_some() && a.play.is_some() {
        bail!("--record and --play: give one of them");
    }
    let el =
        EventLoop::new().context("opening the display (is DISPLAY or WAYLAND_DISPLAY set?)")?;
    let mut o = opts.clone();
    o.instance_extensions = present::surface_extensions(el.display_handle()?.as_raw())?;
    o.swapchain = true;
    let scene = crate::load_scene(&a.scene)?;
    let gpu = crate::open_gpu(&o)?;
    let player = match &a.play {
        Some(f) => Some(open_player(&gpu, &scene, f, &a.frame)?),
        None => None,
    };
    let lighting = match &a.lighting {
        Some(p) => Lighting::preset(&scene, p)?,
        None => Lighting::original(&scene),
    };
    // The start lighting's lights (or the path's) are baked now if need be; others are traced
    // live when first lit.
    let used = Some(match &player {
        Some(p) => p.path.lit_lights(),
        None => crate::render::lit(&scene, &lighting),
    });
    let (mut renderer, mode) =
        crate::render::open_renderer(&gpu, &scene, &a.frame, Some(a.res), used, true)?;
    renderer.display_only = true;
    let start = match &a.camera {
        Some(c) => crate::render::resolve_camera(&scene, c, Some(a.res))?,
        None => crate::render::rescale(&scene.views[0].camera, a.res.0, a.res.1),
    };
    // Yaw/pitch of the start camera's forward axis (camera rows: right, down, forward).
    let fwd = start.rotation.row(2);
    let script = (a.keys.as_deref())
        .map(crate::view_lights::parse_script)
        .transpose()?
        .unwrap_or_default();
    let mut app = App {
        lights: crate::view_lights::LightEditor::new(&renderer),
        compose: Compose::new(&gpu)?,
        script,
        renderer,
        mode,
        preset_name: a.lighting.clone().unwrap_or_else(|| "original".into()),
        lighting,
        selected_light: 0,
        selected_original: 0,
        pos: start.center(),
        yaw: fwd.x.atan2(-fwd.z),
        pitch: fwd.y.clamp(-1.0, 1.0).asin(),
        fov_deg: 2.0 * (start.width as f32 * 0.5 / start.fx).atan().to_degrees(),
        res: a.res,
        exposure: a.frame.exposure,
        window_size: a.window,
        window: None,
        presenter: None,
        wanted_present: a.present,
        held: HashSet::new(),
        dragging: false,
        last_cursor: None,
        start: Instant::now(),
        last: Instant::now(),
        fluid: Fluid::new(a.fluid),
        signature: None,
        shown: (Next::Keep, 0.0, Vec::new()),
        hud_on: a.hud,
        help_on: false,
        last_hud: None,
        stale: true,
        frames_done: 0,
        max_frames: a.frames,
        screenshot_at_end: a.screenshot.clone(),
        screenshot_now: None,
        shots: 0,
        cameras: 0,
        fullscreen: a.fullscreen,
        error: None,
        home: light_centres(&scene),
        recorder: a.record.clone().map(|f| (f, PathRecorder::default())),
        player,
        scene,
        gpu: gpu.clone(),
    };
    let run = el.run_app(&mut app);
    // The recorded path is saved on exit, whatever ended the viewer.
    let saved = match &app.recorder {
        Some((_, r)) if !r.keys.is_empty() => app.save_path(),
        _ => Ok(()),
    };
    app.presenter = None;
    app.window = None;
    if let Some(e) = app.error.take() {
        return Err(e);
    }
    run.context("the window event loop")?;
    saved?;
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
