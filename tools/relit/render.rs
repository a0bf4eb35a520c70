//! `relit render`, `relit fly`, `relit dump`: novel views of a baked scene (§4.2.2–5.2).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{bail, Context, Result};
use relit_engine::bake::BakeParams;
use relit_engine::frame::{self, FrameScene, Lighting, MapFormat, Mode, Renderer};
use relit_engine::gpu::{Gpu, GpuOptions};
use relit_engine::net::{Network, Storage, INPUT_CHANNELS};
use relit_engine::scene::{self, image, path::CameraPath, Camera, CameraDoc, Scene};

/// Options shared by every command that renders frames.
#[derive(clap::Args, Clone)]
pub struct FrameArgs {
    /// Network weights (.safetensors with the "relit.net" configuration) to use instead of the
    /// trained ones built into relit (`engine/weights/`).
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// `network` (the trained network of §5.1), `ulr` (the I_1 composite, no relighting) or
    /// `ratio` (I_1 relit by eq. 5's pseudo-albedo rule: diffuse relighting without the
    /// network). Default: `network` with --weights, else the mode that scores best on the
    /// validation rooms and holds on the held-out ones (`frame::DEFAULT_MODE`: network, since the
    /// shipped network meets the floor; ratio-filled while none did).
    #[arg(long, value_enum)]
    pub mode: Option<ModeArg>,
    /// Which bake to read: the preset's sample counts (default: the complete bake with the most
    /// rays, whatever its parameters).
    #[arg(long, value_enum)]
    pub quality: Option<crate::Quality>,
    /// Element type of the network's tensors in device memory.
    #[arg(long, value_enum, default_value = "auto")]
    pub storage: crate::StorageArg,
    /// Storage of the per-view maps: `bc6h` (1 byte/texel), `rgba16f` (8), or `auto`: BC6H on
    /// GPUs, RGBA16F on CPU devices such as lavapipe, which decode BC6H in software at every
    /// sample (measured: 4× slower frames on the demo scene).
    #[arg(long, value_enum, default_value = "auto")]
    pub maps: MapsArg,
    /// Exposure (a linear scale) of the display transform (PNG, video, screen).
    #[arg(long, default_value_t = 1.0)]
    pub exposure: f32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MapsArg {
    Auto,
    Bc6h,
    Rgba16f,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ModeArg {
    Network,
    Ulr,
    /// The I_1 composite relit by eq. 5's pseudo-albedo rule (diffuse only, no network).
    Ratio,
    /// Ratio where an input view sees the surface, the network in the holes no view sees.
    RatioFilled,
    /// §3's L = a·E + S without the network: the photos' diffuse part relit by eq. 5 plus a
    /// view-dependent layer fitted from the photos and their mirror images (highlights that
    /// move with the view and with a lamp); ratio's image where no fit holds.
    Glossy,
}

/// The best complete bake of `scene` (restricted to a quality preset's sample counts when
/// `quality` is given).
pub fn find_bake(scene: &Scene, quality: Option<crate::Quality>) -> Result<BakeParams> {
    let preset = quality.map(|q| match q {
        crate::Quality::Final => BakeParams::final_quality(),
        crate::Quality::Preview => BakeParams::preview(),
    });
    relit_engine::bake::run::complete_bakes(scene)?
        .into_iter()
        .find(|p| {
            preset.as_ref().is_none_or(|q| {
                let counts = |b: &BakeParams| {
                    let s = (b.irradiance_samples, b.source_cache_samples, b.added_samples);
                    (s, b.cache_samples, b.bounces)
                };
                counts(q) == counts(p)
            })
        })
        .with_context(|| {
            format!(
                "{}: no complete bake found; run `relit bake {} --quality preview` (or final) first",
                scene.root.display(),
                scene.root.display()
            )
        })
}

/// Resolves a camera: a view index, a view or test-view name, or a camera JSON file (the
/// `camera` object of scene.json). `res` rescales the intrinsics.
pub fn resolve_camera(scene: &Scene, spec: &str, res: Option<(u32, u32)>) -> Result<Camera> {
    let cam = if let Ok(i) = spec.parse::<usize>() {
        scene
            .views
            .get(i)
            .map(|v| v.camera.clone())
            .with_context(|| format!("--camera {i}: the scene has {} views", scene.views.len()))?
    } else if let Some(v) = scene.views.iter().find(|v| v.name == spec) {
        v.camera.clone()
    } else if let Some(t) = scene
        .synthetic
        .as_ref()
        .and_then(|s| s.test_views.iter().find(|t| t.name == spec))
    {
        t.camera
            .to_camera(&scene.root.join(scene::SCENE_FILE), &t.name)?
    } else if Path::new(spec).is_file() {
        let bytes = scene::files::read(Path::new(spec), scene::files::FileKind::Text)?;
        let text = String::from_utf8(bytes)
            .map_err(|_| anyhow::anyhow!("{spec}: not UTF-8 text (expected a camera JSON file)"))?;
        let doc: CameraDoc = serde_json::from_str(&text).map_err(|e| {
            anyhow::anyhow!("{spec}: not a camera (the scene.json camera object): {e}")
        })?;
        doc.to_camera(Path::new(spec), "camera")?
    } else {
        bail!("--camera {spec}: not a view index, a view or test-view name, or a camera JSON file");
    };
    Ok(match res {
        Some((w, h)) => rescale(&cam, w, h),
        None => cam,
    })
}

/// The same camera with a `w × h` image (intrinsics scaled).
pub fn rescale(c: &Camera, w: u32, h: u32) -> Camera {
    let (sx, sy) = (w as f32 / c.width as f32, h as f32 / c.height as f32);
    Camera {
        width: w,
        height: h,
        fx: c.fx * sx,
        fy: c.fy * sy,
        cx: c.cx * sx,
        cy: c.cy * sy,
        ..c.clone()
    }
}

/// Opens the scene's bake on the device with the network (`--weights`, else the shipped one).
/// `size`: the frame size when known (it decides `--storage auto`); `used`: the added lights
/// the command will light (None: every one), baked now if the bake has no entry for them;
/// `keep_net`: load the network in every mode (the viewer switches modes).
pub fn open_renderer(
    gpu: &Arc<Gpu>,
    scene: &Scene,
    a: &FrameArgs,
    size: Option<(u32, u32)>,
    used: Option<Vec<String>>,
    keep_net: bool,
) -> Result<(Renderer, Mode)> {
    let mut params = find_bake(scene, a.quality)?;
    params.lights = used;
    let storage: Storage = a.storage.resolve(&gpu.caps, size);
    let cpu_device = gpu.caps.device_type == relit_engine::gpu::vk::PhysicalDeviceType::CPU;
    let format = match a.maps {
        MapsArg::Bc6h if !gpu.caps.bc6h_sampled_linear => {
            bail!("--maps bc6h: the device cannot sample BC6H textures with linear filtering")
        }
        MapsArg::Bc6h => MapFormat::Bc6h,
        MapsArg::Rgba16f => MapFormat::Rgba16f,
        MapsArg::Auto if cpu_device || !gpu.caps.bc6h_sampled_linear => MapFormat::Rgba16f,
        MapsArg::Auto => MapFormat::Bc6h,
    };
    // Used added lights with no entry yet (added or moved since the bake, or never used) are
    // baked now.
    let missing = relit_engine::bake::BakeCache::of(scene, &params)?.missing_lights(scene, &params);
    if !missing.is_empty() {
        let names: Vec<&str> = missing.iter().map(|l| l.name.as_str()).collect();
        eprintln!("baking light(s) {} (not in the bake yet)", names.join(", "));
        let t = std::time::Instant::now();
        relit_engine::bake::run::bake_lights(gpu, scene, &params, &mut |_: &str, _, _, _| {})?;
        eprintln!("  done in {:.1} s", t.elapsed().as_secs_f64());
    }
    let fs = FrameScene::load(gpu, scene, &params, format)?;
    let mode = match a.mode {
        Some(ModeArg::Ulr) => Mode::Ulr,
        Some(ModeArg::Ratio) => Mode::Ratio,
        Some(ModeArg::RatioFilled) => Mode::RatioFilled,
        Some(ModeArg::Glossy) => Mode::Glossy,
        Some(ModeArg::Network) => Mode::Network,
        // Weights a user names are what they want to see; else the best mode we can show.
        None if a.weights.is_some() => Mode::Network,
        None => frame::DEFAULT_MODE,
    };
    // Weights a user names are always loaded, so that a bad file is an error in any mode.
    let net = match (&a.weights, mode.needs_network() || keep_net) {
        (Some(w), _) => Some(Network::load(gpu, w, storage)?),
        (None, true) => Some(Network::shipped(gpu, storage)?),
        (None, false) => None,
    };
    Ok((Renderer::new(gpu, fs, net, storage)?, mode))
}

/// The lights `l` needs baked, by name: the added lights it lights, and the original lights
/// when it sets a factor for one of them.
pub fn lit(scene: &Scene, l: &Lighting) -> Vec<String> {
    let names = relit_engine::frame::added_lights(scene);
    let mut v: Vec<String> = (names.into_iter().zip(&l.intensities))
        .filter(|(_, &i)| i != 0.0)
        .map(|(n, _)| n)
        .collect();
    if l.per_light() {
        v.extend(scene.original_names());
    }
    v
}

fn lighting(scene: &Scene, preset: Option<&str>) -> Result<Lighting> {
    Ok(match preset {
        Some(p) => Lighting::preset(scene, p)?,
        None => Lighting::original(scene),
    })
}

fn write_frame(r: &Renderer, out: &Path) -> Result<()> {
    let b = r.buffers_ref().context("no frame")?;
    match out.extension().and_then(|e| e.to_str()) {
        Some("exr") => {
            let hdr = r.hdr()?;
            let img = relit_engine::scene::RgbImage {
                width: b.width,
                height: b.height,
                pixels: hdr.iter().map(|p| [p[0], p[1], p[2]]).collect(),
            };
            image::write_exr(out, &img)?;
        }
        Some("png") => image::write_png_rgba8(out, b.width, b.height, &r.ldr()?)?,
        _ => bail!("{}: expected a .exr or .png output", out.display()),
    }
    Ok(())
}

/// One render of a `--batch` file.
struct BatchJob {
    camera: String,
    lighting: Option<String>,
    mode: Option<Mode>,
    out: PathBuf,
    leave_out: bool,
}

/// The input view a `--camera` spec names (an index or a view's name), if any.
fn view_index(scene: &Scene, camera: &str) -> Option<usize> {
    match camera.parse::<usize>() {
        Ok(i) => Some(i),
        Err(_) => scene.views.iter().position(|v| v.name == camera),
    }
}

/// The view to leave out of every pass when `leave_out`: the input view the camera names.
fn left_out(scene: &Scene, camera: &str, leave_out: bool) -> Result<Option<u32>> {
    match (leave_out, view_index(scene, camera)) {
        (false, _) => Ok(None),
        (true, Some(i)) => Ok(Some(i as u32)),
        (true, None) => bail!("--leave-out: camera {camera} is not an input view"),
    }
}

/// Reads a `--batch` file: a JSON array of {"camera", "lighting" (optional), "mode" (optional:
/// network, ratio, ratio-filled, glossy or ulr), "leave_out" (optional: true leaves the camera's own
/// input view out), "out"}.
fn batch_jobs(path: &Path) -> Result<Vec<BatchJob>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let doc: serde_json::Value = serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: not JSON (expected an array of renders)",
            path.display()
        )
    })?;
    let items = doc
        .as_array()
        .with_context(|| format!("{}: expected a JSON array of renders", path.display()))?;
    let field = |i: usize, v: &serde_json::Value, k: &str| -> Result<Option<String>> {
        match v.get(k) {
            None | Some(serde_json::Value::Null) => Ok(None),
            Some(serde_json::Value::String(s)) => Ok(Some(s.clone())),
            Some(_) => bail!("{}: render {i}: \"{k}\" must be a string", path.display()),
        }
    };
    let mut jobs = Vec::with_capacity(items.len());
    for (i, v) in items.iter().enumerate() {
        let need = |k: &str| -> Result<String> {
            field(i, v, k)?
                .with_context(|| format!("{}: render {i}: \"{k}\" is missing", path.display()))
        };
        let mode = match field(i, v, "mode")?.as_deref() {
            None => None,
            Some("network") => Some(Mode::Network),
            Some("ratio") => Some(Mode::Ratio),
            Some("ratio-filled") => Some(Mode::RatioFilled),
            Some("ulr") => Some(Mode::Ulr),
            Some("glossy") => Some(Mode::Glossy),
            Some(m) => bail!(
                "{}: render {i}: mode \"{m}\": expected network, ratio, ratio-filled, glossy or ulr",
                path.display()
            ),
        };
        let leave_out = match v.get("leave_out") {
            None | Some(serde_json::Value::Null) => false,
            Some(serde_json::Value::Bool(b)) => *b,
            Some(_) => bail!(
                "{}: render {i}: \"leave_out\" must be true or false",
                path.display()
            ),
        };
        jobs.push(BatchJob {
            camera: need("camera")?,
            lighting: field(i, v, "lighting")?,
            mode,
            out: PathBuf::from(need("out")?),
            leave_out,
        });
    }
    Ok(jobs)
}

/// `relit render --batch FILE`: many renders of one scene with one load of the bake and the
/// network (evaluations render hundreds of views).
pub fn render_batch(
    opts: &GpuOptions,
    dir: &Path,
    jobs: &Path,
    res: Option<(u32, u32)>,
    a: &FrameArgs,
) -> Result<()> {
    let scene = crate::load_scene(dir)?;
    let jobs = batch_jobs(jobs)?;
    let mut cams = Vec::with_capacity(jobs.len());
    let mut lights = Vec::with_capacity(jobs.len());
    let mut excluded = Vec::with_capacity(jobs.len());
    let mut used: Vec<String> = Vec::new();
    for j in &jobs {
        cams.push(resolve_camera(&scene, &j.camera, res)?);
        excluded.push(left_out(&scene, &j.camera, j.leave_out)?);
        let l = lighting(&scene, j.lighting.as_deref())?;
        used.extend(
            lit(&scene, &l)
                .into_iter()
                .filter(|n| !used.contains(n))
                .collect::<Vec<_>>(),
        );
        lights.push(l);
    }
    let gpu = crate::open_gpu(opts)?;
    let size = cams.first().map(|c| (c.width, c.height));
    let need_net = jobs
        .iter()
        .any(|j| j.mode.is_none_or(|m| m.needs_network()));
    let (mut r, mode) = open_renderer(&gpu, &scene, a, size, Some(used), need_net)?;
    r.display_only = true;
    for (((j, cam), light), ex) in jobs.iter().zip(&cams).zip(&lights).zip(excluded) {
        r.exclude = ex;
        r.render(cam, light, j.mode.unwrap_or(mode), a.exposure, None)?;
        write_frame(&r, &j.out)?;
    }
    println!("{}: {} renders", dir.display(), jobs.len());
    Ok(())
}

#[allow(clippy::too_many_arguments)]
pub fn render(
    opts: &GpuOptions,
    dir: &Path,
    camera: &str,
    res: Option<(u32, u32)>,
    preset: Option<&str>,
    out: &Path,
    leave_out: bool,
    a: &FrameArgs,
) -> Result<()> {
    let scene = crate::load_scene(dir)?;
    let cam = resolve_camera(&scene, camera, res)?;
    let exclude = left_out(&scene, camera, leave_out)?;
    let light = lighting(&scene, preset)?;
    let gpu = crate::open_gpu(opts)?;
    let used = Some(lit(&scene, &light));
    let (mut r, mode) = open_renderer(&gpu, &scene, a, Some((cam.width, cam.height)), used, false)?;
    r.display_only = true;
    r.exclude = exclude;
    r.render(&cam, &light, mode, a.exposure, None)?;
    write_frame(&r, out)?;
    println!("{}: {}x{} ({mode:?})", out.display(), cam.width, cam.height);
    Ok(())
}

#[allow(clippy::too_many_arguments)]
pub fn fly(
    opts: &GpuOptions,
    dir: &Path,
    path: &Path,
    out: &Path,
    res: (u32, u32),
    (fps, max_frames): (f32, u64),
    a: &FrameArgs,
) -> Result<()> {
    let scene = crate::load_scene(dir)?;
    let cp = CameraPath::load(path)?;
    let n = fly_frame_count(path, &cp, fps, max_frames)?;
    let t0 = cp.start();
    let gpu = crate::open_gpu(opts)?;
    let (mut r, mode) = open_renderer(&gpu, &scene, a, Some(res), Some(cp.lit_lights()), false)?;
    r.display_only = true;
    let video = out.extension().is_some_and(|e| e == "mp4");
    let (w, h) = res;
    let tmp = scene::temp_path(out);
    let mut ffmpeg = if video {
        Some(start_ffmpeg(res, fps, &tmp)?)
    } else {
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        None
    };
    let bar = indicatif::ProgressBar::new(n);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{prefix} {bar:40} {pos}/{len} {msg} ETA {eta}")
            .unwrap(),
    );
    bar.set_prefix("fly");
    let base = Lighting::original(&scene);
    // Lights the path moves: their caches at each lighting keyframe's place, traced once.
    let params = find_bake(&scene, a.quality)?;
    let moves = relit_engine::frame::live::PathMoves::new(
        &gpu,
        &scene,
        &params,
        &cp,
        &mut |_: &str, _, _, _| {},
    )?;
    let t_start = std::time::Instant::now();
    let mut lines =
        (!crate::progress::on_terminal()).then(|| crate::progress::LogLines::new("fly"));
    for i in 0..n {
        let t = t0 + i as f32 / fps;
        let cam = cp.camera_at(t, w, h);
        let light = match cp.lighting_at(t) {
            Some(l) => Lighting::from_path(&scene, &l, path)?,
            None => base.clone(),
        };
        moves.apply(&mut r, &cp, t)?;
        r.render(&cam, &light, mode, a.exposure, None)?;
        match &mut ffmpeg {
            Some(child) => {
                let px = r.ldr()?;
                child
                    .stdin
                    .as_mut()
                    .unwrap()
                    .write_all(&px)
                    .context("writing a frame to ffmpeg")?;
            }
            None => image::write_png_rgba8(&out.join(format!("frame{i:05}.png")), w, h, &r.ldr()?)?,
        }
        bar.inc(1);
        bar.set_message(format!(
            "{:.2} fps",
            (i + 1) as f64 / t_start.elapsed().as_secs_f64()
        ));
        if let Some(l) = lines.as_mut() {
            l.update("frames", i as usize + 1, n as usize, &|secs| {
                format!("{:.2} fps", (i + 1) as f64 / secs)
            });
        }
    }
    bar.finish();
    if let Some(child) = ffmpeg {
        finish_ffmpeg(child, &tmp, out)?;
    }
    println!(
        "{}: {n} frames at {w}x{h}, {fps} fps ({mode:?}), {:.1} s",
        out.display(),
        t_start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// How many frames `relit fly` renders of the path at `fps`: an error for a rate outside
/// (0, 240] or a path longer than `max_frames` (it would write frames until the disk fills).
fn fly_frame_count(path: &Path, cp: &CameraPath, fps: f32, max_frames: u64) -> Result<u64> {
    if !(fps > 0.0 && fps <= 240.0) {
        bail!("--fps {fps}: expected a value in (0, 240]");
    }
    let (t0, t1) = (cp.start(), cp.duration());
    let frames = ((t1 - t0) as f64 * fps as f64).floor() + 1.0;
    if frames.is_nan() || frames > max_frames as f64 {
        bail!(
            "{}: the path lasts {:.0} s, {frames:.0} frames at {fps} fps; more than --max-frames {max_frames} (raise it for a longer film)",
            path.display(),
            t1 - t0
        );
    }
    Ok(frames as u64)
}

/// ffmpeg reading raw RGBA frames of `w`×`h` on its stdin and encoding them to an H.264 MP4 at
/// `tmp` (MP4's yuv420p needs even sizes).
fn start_ffmpeg((w, h): (u32, u32), fps: f32, tmp: &Path) -> Result<std::process::Child> {
    if w % 2 != 0 || h % 2 != 0 {
        bail!("--res {w}x{h}: MP4 (yuv420p) needs even sizes");
    }
    let child = std::process::Command::new("ffmpeg")
        .args([
            "-loglevel",
            "error",
            "-y",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgba",
            "-s",
        ])
        .arg(format!("{w}x{h}"))
        .args([
            "-r",
            &fps.to_string(),
            "-i",
            "-",
            "-c:v",
            "libx264",
            "-preset",
            "medium",
        ])
        .args([
            "-crf", "18", "-pix_fmt", "yuv420p", "-threads", "1", "-f", "mp4",
        ])
        .arg(tmp)
        .stdin(std::process::Stdio::piped())
        .spawn()
        .context("starting ffmpeg (install it, or give a directory to write PNG frames)")?;
    Ok(child)
}

/// Closes ffmpeg's input, waits for it, and moves its MP4 from `tmp` to `out` (removing it when
/// ffmpeg failed).
fn finish_ffmpeg(mut child: std::process::Child, tmp: &Path, out: &Path) -> Result<()> {
    drop(child.stdin.take());
    let st = child.wait()?;
    if !st.success() {
        let _ = std::fs::remove_file(tmp);
        bail!("ffmpeg failed ({st}) writing {}", out.display());
    }
    std::fs::rename(tmp, out).with_context(|| format!("writing {}", out.display()))?;
    Ok(())
}

/// The ground truth of a synthetic scene for `camera` under `light`, mixed linearly from the
/// per-condition renders: (diffuse, total), when every needed render exists.
fn ground_truth(
    scene: &Scene,
    camera: &str,
    light: &Lighting,
) -> Result<Option<(Vec<f32>, Vec<f32>)>> {
    let Some(syn) = &scene.synthetic else {
        return Ok(None);
    };
    let gt = scene.root.join(&syn.ground_truth);
    let names = frame::added_lights(scene);
    let mut terms = vec![("original".to_string(), 1.0 - light.alpha_dim)];
    for (n, &s) in names.iter().zip(&light.intensities) {
        if s != 0.0 {
            terms.push((n.clone(), s));
        }
    }
    let mut acc: Option<(Vec<f32>, Vec<f32>)> = None;
    for (cond, wgt) in terms {
        let d = gt.join(&cond).join(format!("{camera}.diffuse.exr"));
        let t = gt.join(&cond).join(format!("{camera}.total.exr"));
        if !d.exists() || !t.exists() {
            return Ok(None);
        }
        let (d, t) = (image::load_rgb(&d)?, image::load_rgb(&t)?);
        let (pd, pt) = (planar_rgb(&d.pixels), planar_rgb(&t.pixels));
        match &mut acc {
            None => {
                acc = Some((
                    pd.iter().map(|v| v * wgt).collect(),
                    pt.iter().map(|v| v * wgt).collect(),
                ))
            }
            Some((ad, at)) => {
                if ad.len() != pd.len() {
                    bail!(
                        "{}: ground-truth sizes differ between conditions",
                        gt.display()
                    );
                }
                ad.iter_mut().zip(&pd).for_each(|(a, v)| *a += v * wgt);
                at.iter_mut().zip(&pt).for_each(|(a, v)| *a += v * wgt);
            }
        }
    }
    Ok(acc)
}

/// What `relit dump` writes: one camera's network input under a lighting preset, or (parts)
/// its lighting-dependent channels one light at a time.
pub struct DumpRequest<'a> {
    pub camera: &'a str,
    pub preset: Option<&'a str>,
    pub out: &'a Path,
    pub keep_view: bool,
    pub parts: bool,
}

pub fn dump(opts: &GpuOptions, dir: &Path, req: &DumpRequest, a: &FrameArgs) -> Result<()> {
    let DumpRequest {
        camera,
        preset,
        out,
        keep_view,
        parts,
    } = *req;
    let scene = crate::load_scene(dir)?;
    let cam = resolve_camera(&scene, camera, None)?;
    let light = lighting(&scene, preset)?;
    if parts && preset.is_some() {
        bail!("--parts stores every light separately: it takes no --lighting");
    }
    let gpu = crate::open_gpu(opts)?;
    let mut fa = a.clone();
    fa.weights = None;
    fa.mode = Some(ModeArg::Ulr);
    fa.storage = crate::StorageArg::F32;
    // --parts stores every light.
    let used = (!parts).then(|| lit(&scene, &light));
    let (mut r, _) = open_renderer(
        &gpu,
        &scene,
        &fa,
        Some((cam.width, cam.height)),
        used,
        false,
    )?;
    // An input view's own image must not be among its inputs (the network would learn to copy
    // it): leave it out of every pass unless --keep-view.
    let view_index = view_index(&scene, camera);
    let cam_name = view_index.map_or(camera.to_string(), |i| scene.views[i].name.clone());
    if !keep_view {
        r.exclude = view_index.map(|i| i as u32);
    }
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut meta = std::collections::HashMap::new();
    meta.insert(
        "relit.channels".to_string(),
        serde_json::to_string(&frame::features::channel_names())?,
    );
    meta.insert("relit.camera".to_string(), cam_name.clone());
    meta.insert(
        "relit.left_out_view".to_string(),
        r.exclude
            .map_or("none".to_string(), |i| scene.views[i as usize].name.clone()),
    );
    meta.insert(
        "relit.targets".to_string(),
        "linear radiance; target_total = target_diffuse + target_glossy".to_string(),
    );
    let (tensors, has_gt) = if parts {
        meta.insert(
            "relit.lights".to_string(),
            serde_json::to_string(&frame::added_lights(&scene))?,
        );
        meta.insert("relit.parts".to_string(), PARTS_DOC.to_string());
        meta.insert(
            "relit.camera_params".to_string(),
            serde_json::to_string(&CameraDoc::from_camera(&cam))?,
        );
        parts_tensors(&scene, &mut r, &cam, &cam_name)?
    } else {
        meta.insert(
            "relit.lighting".to_string(),
            serde_json::json!({"alpha_dim": light.alpha_dim, "intensities": frame::added_lights(&scene).iter().zip(&light.intensities).collect::<Vec<_>>()}).to_string(),
        );
        r.render(&cam, &light, Mode::Ratio, 1.0, None)?;
        let input = r.buffers_ref().unwrap().input.download_chw()?;
        let ratio = planar_rgb(&r.hdr()?);
        r.render(&cam, &light, Mode::Glossy, 1.0, None)?;
        let glossy = planar_rgb(&glossy_image(&r)?);
        let mut t = vec![
            (
                "input".to_string(),
                input,
                vec![INPUT_CHANNELS as usize, h, w],
            ),
            ("ratio_image".to_string(), ratio, vec![3, h, w]),
            ("glossy_image".to_string(), glossy, vec![3, h, w]),
        ];
        let gt = ground_truth(&scene, &cam_name, &light)?;
        let has = gt.is_some();
        if let Some((d, tot)) = gt {
            t.extend(target_tensors("", d, tot, w, h, camera)?);
        }
        (t, has)
    };
    write_tensors(out, &tensors, meta)?;
    println!(
        "{}: {}66x{h}x{w}{}",
        out.display(),
        if parts {
            "lighting parts of "
        } else {
            "input "
        },
        if has_gt {
            ", ground-truth targets"
        } else {
            " (no ground truth for this camera)"
        }
    );
    Ok(())
}

/// What `dump --parts` stores (its metadata says the same), so that a trainer can mix any
/// lighting: every lighting-dependent channel is linear in α_dim and the added lights'
/// intensities, except where a mirror ray meets a lit lamp.
const PARTS_DOC: &str = "static: the 66 channels under the original lighting (alpha 0, no added \
light); e_src: E_src (linear, W/m2); m_orig: M_tgt linear under the original lighting; \
light_glow, light_albedo: the glow of the declared original light each pixel shows and the \
albedo of its surface (0 off them; the frame draws (1-alpha) light_glow + light_albedo E_add/pi \
there in every mode); glossy_d, glossy_s, glossy_lobe: the view-dependent layer's diffuse part \
D (3), specular strength s (1) and lobe + 1 (1; 0: no fit), which no lighting changes; s_orig: \
its view-dependent part S under the original lighting; for each \
added light L (relit.lights order) at intensity 1 with the original removed (alpha 1): \
e_add.L (E_add linear), m_add.L (M_tgt linear), dist.L (channel 65), s_add.L (S). Glossy mode's \
image before any light is drawn: D / max(e_src, 1e-4) (e_add + (1-alpha) e_src) + S, S = \
(1-alpha) s_orig + sum_L i_L s_add.L, except where glossy_lobe = 1: there S = glossy_s M. Channels 48-50 = tm(M), \
M = (1-alpha) m_orig + sum_L i_L m_add.L, except where some lit light has dist.L != static[65]: \
there the nearest such light (smallest dist.L) gives M = i_L m_add.L and channel 65 = dist.L; \
51-53 = tm(e_src/pi), 54-56 = tm(sum_L i_L e_add.L/pi), 57-59 = tm(alpha e_src/pi); \
tm(x) = log(1+64 max(x,0))/log(65). Targets: target_diffuse.C, target_total.C per ground-truth \
condition C (original and each added light alone at intensity 1); a lighting's target is \
(1-alpha) C=original + sum_L i_L C=L. depth_true: the renderer's camera-z depth (synthetic \
scenes); relit.camera_params: the camera as scene.json writes it";

/// Renders the original lighting and each added light alone; returns the parts' tensors.
fn parts_tensors(
    scene: &Scene,
    r: &mut Renderer,
    cam: &Camera,
    cam_name: &str,
) -> Result<(Vec<Tensor>, bool)> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let names = frame::added_lights(scene);
    let mut light = Lighting::original(scene);
    r.render(cam, &light, Mode::Glossy, 1.0, None)?;
    let (input, irr, mirror) = frame_planes(r)?;
    let (glow, albedo) = glow_planes(r, cam)?;
    let [d, s, lobe, s_orig] = glossy_planes(r)?;
    let mut t: Vec<Tensor> = vec![
        ("static".into(), input, vec![INPUT_CHANNELS as usize, h, w]),
        ("e_src".into(), irr[0].clone(), vec![3, h, w]),
        ("m_orig".into(), mirror, vec![3, h, w]),
        ("light_glow".into(), glow, vec![3, h, w]),
        ("light_albedo".into(), albedo, vec![3, h, w]),
        ("glossy_d".into(), d, vec![3, h, w]),
        ("glossy_s".into(), s, vec![1, h, w]),
        ("glossy_lobe".into(), lobe, vec![1, h, w]),
        ("s_orig".into(), s_orig, vec![3, h, w]),
    ];
    let mut has_gt = true;
    let mut add_targets = |t: &mut Vec<Tensor>, cond: &str, l: &Lighting| -> Result<()> {
        match ground_truth(scene, cam_name, l)? {
            Some((d, tot)) => {
                t.extend(target_tensors(&format!(".{cond}"), d, tot, w, h, cam_name)?)
            }
            None => has_gt = false,
        }
        Ok(())
    };
    add_targets(&mut t, "original", &light)?;
    if let Some(d) = true_depth(scene, cam_name, w, h)? {
        t.push(("depth_true".into(), d, vec![1, h, w]));
    }
    for (k, name) in names.iter().enumerate() {
        light.alpha_dim = 1.0;
        light.intensities.iter_mut().for_each(|i| *i = 0.0);
        light.intensities[k] = 1.0;
        r.render(cam, &light, Mode::Glossy, 1.0, None)?;
        let (input, irr, mirror) = frame_planes(r)?;
        let dist = input[65 * w * h..].to_vec();
        let [_, _, _, s_add] = glossy_planes(r)?;
        t.push((format!("s_add.{name}"), s_add, vec![3, h, w]));
        t.push((format!("e_add.{name}"), irr[1].clone(), vec![3, h, w]));
        t.push((format!("m_add.{name}"), mirror, vec![3, h, w]));
        t.push((format!("dist.{name}"), dist, vec![1, h, w]));
        add_targets(&mut t, name, &light)?;
    }
    Ok((t, has_gt))
}

/// The renderer's camera-z depth of the true geometry (synthetic scenes; the trainer's
/// multi-view term reprojects with it), when present.
fn true_depth(scene: &Scene, cam: &str, w: usize, h: usize) -> Result<Option<Vec<f32>>> {
    let Some(syn) = &scene.synthetic else {
        return Ok(None);
    };
    let path = scene
        .root
        .join(&syn.ground_truth)
        .join("aov")
        .join(format!("{cam}.depth.exr"));
    if !path.exists() {
        return Ok(None);
    }
    let img = image::load_rgb(&path)?;
    if (img.width as usize, img.height as usize) != (w, h) {
        bail!(
            "{}: {}x{}, expected {w}x{h}",
            path.display(),
            img.width,
            img.height
        );
    }
    Ok(Some(img.pixels.iter().map(|p| p[0]).collect()))
}

type Tensor = (String, Vec<f32>, Vec<usize>);
/// (input, [E_src, E_add, E_rem], M_tgt), planar f32.
type FramePlanes = (Vec<f32>, [Vec<f32>; 3], Vec<f32>);

/// The last frame's 66-channel input, its three irradiance planes (E_src, E_add, E_rem) and
/// M_tgt, the latter planar RGB and linear.
fn frame_planes(r: &Renderer) -> Result<FramePlanes> {
    let b = r.buffers_ref().context("no frame rendered")?;
    let n = (b.width * b.height) as usize;
    let planar = planar_rgb::<4>;
    let irr: Vec<[f32; 4]> = b.irr.download_vec()?;
    let mirror: Vec<[f32; 4]> = b.mirror.download_vec()?;
    Ok((
        b.input.download_chw()?,
        [
            planar(&irr[..n]),
            planar(&irr[n..2 * n]),
            planar(&irr[2 * n..3 * n]),
        ],
        planar(&mirror[..n]),
    ))
}

/// The last frame's view-dependent layer, planar: D (3 planes), s (1), lobe + 1 (1), S (3).
fn glossy_planes(r: &Renderer) -> Result<[Vec<f32>; 4]> {
    let b = r.buffers_ref().context("no frame rendered")?;
    let n = (b.width * b.height) as usize;
    let gl: Vec<[f32; 4]> = b.glossy.download_vec()?;
    let (dp, sp) = (&gl[..n], &gl[n..2 * n]);
    Ok([
        planar_rgb(dp),
        dp.iter().map(|v| v[3]).collect(),
        sp.iter().map(|v| v[3]).collect(),
        planar_rgb(sp),
    ])
}

/// Glossy mode's image of the last frame before any light is drawn over it (the base of a
/// network with base "glossy", as the output pass forms it).
fn glossy_image(r: &Renderer) -> Result<Vec<[f32; 3]>> {
    let b = r.buffers_ref().context("no frame rendered")?;
    let n = (b.width * b.height) as usize;
    let gl: Vec<[f32; 4]> = b.glossy.download_vec()?;
    let irr: Vec<[f32; 4]> = b.irr.download_vec()?;
    Ok(frame::glossy::reference_image(
        &gl[..2 * n],
        &irr[..3 * n],
        n,
    ))
}

/// The glow of the declared original lights the last frame shows and their albedo, each planar
/// 3×H×W, zero off them (`frame::emitters::original_glow_image`).
fn glow_planes(r: &Renderer, cam: &Camera) -> Result<(Vec<f32>, Vec<f32>)> {
    let b = r.buffers_ref().context("no frame rendered")?;
    let n = (b.width * b.height) as usize;
    let g = b.gbuf.download()?;
    let comp = b.composites()?;
    let img =
        frame::emitters::original_glow_image(cam, &g.pos_depth, &comp[..n], &r.scene.originals);
    let (glow, albedo): (Vec<[f32; 3]>, Vec<[f32; 3]>) = img.into_iter().unzip();
    Ok((planar_rgb(&glow), planar_rgb(&albedo)))
}

/// The first three channels of per-pixel values, planar (R plane, G plane, B plane).
fn planar_rgb<const N: usize>(v: &[[f32; N]]) -> Vec<f32> {
    (0..3).flat_map(|c| v.iter().map(move |p| p[c])).collect()
}

/// target_diffuse, target_total and target_glossy (total − diffuse), names ending in `suffix`.
fn target_tensors(
    suffix: &str,
    d: Vec<f32>,
    t: Vec<f32>,
    w: usize,
    h: usize,
    camera: &str,
) -> Result<Vec<Tensor>> {
    if d.len() != 3 * w * h {
        bail!("ground truth of {camera} is not {w}x{h}");
    }
    let glossy: Vec<f32> = t.iter().zip(&d).map(|(t, d)| t - d).collect();
    Ok(vec![
        (format!("target_diffuse{suffix}"), d, vec![3, h, w]),
        (format!("target_total{suffix}"), t, vec![3, h, w]),
        (format!("target_glossy{suffix}"), glossy, vec![3, h, w]),
    ])
}

/// Writes f32 tensors and metadata as one safetensors file (temp file, then rename).
fn write_tensors(
    out: &Path,
    tensors: &[Tensor],
    meta: std::collections::HashMap<String, String>,
) -> Result<()> {
    use safetensors::tensor::TensorView;
    let views: Vec<(String, TensorView)> = tensors
        .iter()
        .map(|(n, v, s)| {
            Ok((
                n.clone(),
                TensorView::new(safetensors::Dtype::F32, s.clone(), bytemuck::cast_slice(v))?,
            ))
        })
        .collect::<Result<_>>()?;
    let mut bytes = safetensors::serialize(views, Some(meta))?;
    sort_header(&mut bytes)?;
    scene::write_atomic(out, &bytes)?;
    Ok(())
}

/// Rewrites a safetensors header with its keys sorted, in the same number of bytes, so the
/// same tensors and metadata give the same file (the metadata is a HashMap, whose order
/// changes from run to run).
fn sort_header(bytes: &mut [u8]) -> Result<()> {
    let n = u64::from_le_bytes(bytes[..8].try_into()?) as usize;
    let header: serde_json::Value = serde_json::from_slice(&bytes[8..8 + n])?;
    // serde_json's maps are ordered by key.
    let sorted = serde_json::to_vec(&header)?;
    if sorted.len() > n {
        bail!("safetensors header grew when sorted");
    }
    bytes[8..8 + sorted.len()].copy_from_slice(&sorted);
    bytes[8 + sorted.len()..8 + n].fill(b' ');
    Ok(())
}
