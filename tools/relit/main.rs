//! `relit`: the command-line front end. Thin: every subcommand calls into the engine library.

mod bench;
mod dataset;
mod progress;
mod render;
mod view;
mod view_lights;

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context, Result};
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand, ValueEnum};
use relit_engine::gpu::{self, DeviceChoice, Gpu, GpuOptions};
use relit_engine::scene::{self, Scene, SceneFormat};

#[derive(Parser)]
#[command(
    name = "relit",
    version,
    about = "Free-viewpoint indoor neural relighting on Vulkan"
)]
struct Cli {
    /// Vulkan device: an index or part of its name (default: RELIT_DEVICE, else the best one).
    #[arg(long, global = true, env = "RELIT_DEVICE")]
    device: Option<String>,
    /// Turn on the Khronos validation layer (also RELIT_VALIDATE=1).
    #[arg(long, global = true)]
    validate: bool,
    /// The proxy mesh (PLY or OBJ) instead of the one the scene names or keeps beside its
    /// views: a mesh made by another tool for a COLMAP, SIBR or transforms.json capture. Give
    /// it to every command of that scene (the bake cache is keyed by the mesh's contents).
    /// `bench rays`: the mesh to trace.
    #[arg(long, global = true, value_name = "FILE")]
    mesh: Option<PathBuf>,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Print the Vulkan device, its required and optional features, and key limits.
    Info,
    /// Inspect or create scenes.
    Scene {
        #[command(subcommand)]
        cmd: SceneCmd,
    },
    /// Bake a scene's per-view maps (§4.1–4.2) into its cache (SCENE/.relit/bake-<key>/).
    Bake {
        scene: PathBuf,
        /// A slice of views, A..B (to split a big capture across jobs).
        #[arg(long, value_parser = parse_range)]
        views: Option<std::ops::Range<usize>>,
        #[arg(long, value_enum, default_value = "final")]
        quality: Quality,
        /// Rays per pixel for the source irradiance (overrides the quality preset); with the
        /// source cache, shadow rays towards the declared original lights.
        #[arg(long)]
        rays: Option<u32>,
        /// Rays per texel for the source irradiance's indirect part when the scene declares its
        /// original lights (overrides the preset); 0: every ray per pixel.
        #[arg(long)]
        texel_rays: Option<u32>,
        /// Shadow rays per pixel for the added irradiance's direct part (overrides the preset).
        #[arg(long)]
        added_samples: Option<u32>,
        /// Paths per surface-cache texel for the added irradiance's indirect part (overrides
        /// the preset).
        #[arg(long)]
        cache_samples: Option<u32>,
        /// Which added lights to bake: `presets` (the lights the scene's lighting presets light,
        /// and with --eval those of its ground-truth conditions), `all`, or names A,B. Others
        /// are baked when a command first lights them.
        #[arg(long, default_value = "presets")]
        lights: String,
        /// After baking, compare with the scene's ground truth (synthetic scenes).
        #[arg(long)]
        eval: bool,
        /// §4.4 geometry processing of the proxy first: smoothing and RANSAC plane snapping.
        #[arg(long)]
        mesh_process: bool,
        /// Keep the maps uncompressed only (half-float EXR), without their BC6H copies.
        #[arg(long)]
        uncompressed: bool,
    },
    /// Render one novel view of a baked scene to EXR (linear) or PNG (display transform).
    Render {
        scene: PathBuf,
        /// A view index, a view or test-view name, or a camera JSON file.
        #[arg(long, required_unless_present = "batch")]
        camera: Option<String>,
        /// Lighting preset of the scene (default: the original lighting).
        #[arg(long)]
        lighting: Option<String>,
        /// Image size WxH (default: the camera's).
        #[arg(long, value_parser = parse_res)]
        res: Option<(u32, u32)>,
        #[arg(long, required_unless_present = "batch")]
        out: Option<PathBuf>,
        /// Many renders with one load of the bake and the network: a JSON array of
        /// {"camera", "lighting" (optional), "mode" (optional), "out"} in place of --camera,
        /// --lighting and --out.
        #[arg(long, conflicts_with_all = ["camera", "lighting", "out"])]
        batch: Option<PathBuf>,
        /// Leave the input view that --camera names out of every frame pass (leave-one-out:
        /// render a photo from the others and compare; in a batch, "leave_out": true).
        #[arg(long, conflicts_with = "batch")]
        leave_out: bool,
        #[command(flatten)]
        frame: render::FrameArgs,
    },
    /// Record a flythrough along a camera path: an MP4 (ffmpeg) or a directory of PNG frames.
    Fly {
        scene: PathBuf,
        /// Camera path JSON (keyframes and lighting keyframes; see docs/formats.md).
        #[arg(long)]
        path: PathBuf,
        /// video.mp4, or a directory for frame00000.png, …
        #[arg(long)]
        out: PathBuf,
        #[arg(long, default_value = "256x192", value_parser = parse_res)]
        res: (u32, u32),
        #[arg(long, default_value_t = 24.0)]
        fps: f32,
        /// The most frames a path may make (a path whose keyframes span days would write frames
        /// until the disk fills); raise it for a longer film.
        #[arg(long, default_value_t = 100_000)]
        max_frames: u64,
        #[command(flatten)]
        frame: render::FrameArgs,
    },
    /// Write the exact 66-channel network input of a camera (and the ground-truth targets of a
    /// synthetic scene) as safetensors, for the trainer.
    Dump {
        scene: PathBuf,
        #[arg(long)]
        camera: String,
        #[arg(long)]
        lighting: Option<String>,
        #[arg(long)]
        out: PathBuf,
        /// When the camera is an input view, keep that view among the inputs (by default it is
        /// left out of every pass, so the input does not contain the target).
        #[arg(long)]
        keep_view: bool,
        /// Store the lighting linearly, one part per light (the original lighting and each
        /// added light alone), with every ground-truth condition, so a trainer can mix any
        /// lighting (§6): the training samples of tools/dataset.
        #[arg(long)]
        parts: bool,
        #[command(flatten)]
        frame: render::FrameArgs,
    },
    /// Build a training dataset (§6), resumably: per seed, scenegen's room, Mitsuba's ground
    /// truth, the bake and one sample per camera with its lighting kept linear (dump --parts).
    Dataset(dataset::DatasetArgs),
    /// The interactive viewer (winit window, Vulkan swapchain); `relit view --help` lists its keys.
    View {
        scene: PathBuf,
        /// Render resolution WxH (the window starts at this size; frames are scaled to it).
        #[arg(long, default_value = "256x192", value_parser = parse_res)]
        res: (u32, u32),
        #[arg(long)]
        fullscreen: bool,
        /// Exit after N frames (with --screenshot: save the last one).
        #[arg(long)]
        frames: Option<u64>,
        /// Save the window's last frame here (PNG) when exiting after --frames.
        #[arg(long)]
        screenshot: Option<PathBuf>,
        /// Start camera: a view index, a view or test-view name, or a camera JSON file.
        #[arg(long)]
        camera: Option<String>,
        /// Start lighting preset.
        #[arg(long)]
        lighting: Option<String>,
        /// Scripted input "FRAME:KEY,…" (e.g. "2:N,4:J": add a lamp at frame 2, move it left at
        /// frame 4; "1:+W,5:-W" holds W from frame 1 to 5; "3:size=640x480" resizes), for tests
        /// and recorded demos.
        #[arg(long)]
        keys: Option<String>,
        /// Window size WxH (default: two thirds of the screen's height, the frame's aspect);
        /// the frame is scaled to it with its aspect kept.
        #[arg(long, value_parser = parse_res)]
        window: Option<(u32, u32)>,
        /// Presentation: immediate, mailbox or fifo (vsync). Default: the lowest-latency mode the
        /// surface offers, so the frame rate shown is the renderer's.
        #[arg(long, value_parser = parse_present)]
        present: Option<relit_engine::gpu::PresentMode>,
        /// Record a camera path: R drops a keyframe, F6 (and exit) writes PATH in the format
        /// `relit fly` reads.
        #[arg(long, value_name = "PATH")]
        record: Option<PathBuf>,
        /// Play a camera path (as `relit fly` would render it), looping; Space pauses.
        #[arg(long, value_name = "PATH")]
        play: Option<PathBuf>,
        /// Frames: auto (the cheap ratio frame while moving, the full frame once still), still
        /// (always the full frame) or moving (always the cheap one). G cycles them.
        #[arg(long, default_value = "auto", value_parser = parse_fluid)]
        fluid: relit_engine::view::fluid::Policy,
        /// Start with the HUD hidden (H shows it).
        #[arg(long)]
        no_hud: bool,
        #[command(flatten)]
        frame: render::FrameArgs,
    },
    /// Benchmarks (GPU timestamps; figures, never pass/fail).
    Bench {
        #[command(subcommand)]
        cmd: bench::BenchCmd,
    },
}

/// Element type of the network's tensors in device memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum StorageArg {
    /// fp32 on CPU devices (lavapipe: the CPU-shaped kernels, 1.3–1.5× faster there) when the
    /// frame fits, fp16 on GPUs.
    Auto,
    F16,
    F32,
}

impl StorageArg {
    /// `auto`: fp32 on CPU devices when a frame of `size` fits the device's storage-buffer range
    /// (the CPU-shaped kernels need fp32; at 1024×768 the 66-channel input is 214 MB, beyond
    /// lavapipe's 128 MiB), else fp16. No size known: fp16.
    pub fn resolve(
        self,
        caps: &relit_engine::gpu::Caps,
        size: Option<(u32, u32)>,
    ) -> relit_engine::net::Storage {
        use relit_engine::net::{Storage, INPUT_CHANNELS};
        let cpu = caps.device_type == relit_engine::gpu::vk::PhysicalDeviceType::CPU;
        let fits = size.is_some_and(|(w, h)| {
            let bytes = w as u64 * h as u64 * INPUT_CHANNELS.div_ceil(4) as u64 * 16;
            bytes <= caps.max_storage_buffer_range as u64
        });
        match self {
            StorageArg::F16 => Storage::F16,
            StorageArg::F32 => Storage::F32,
            StorageArg::Auto if cpu && fits => Storage::F32,
            StorageArg::Auto => Storage::F16,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Quality {
    Preview,
    Final,
}

fn parse_range(s: &str) -> Result<std::ops::Range<usize>, String> {
    let (a, b) = s
        .split_once("..")
        .ok_or_else(|| format!("\"{s}\": expected A..B"))?;
    let a: usize = a
        .parse()
        .map_err(|_| format!("\"{s}\": {a} is not a view index"))?;
    let b: usize = b
        .parse()
        .map_err(|_| format!("\"{s}\": {b} is not a view index"))?;
    if a >= b {
        return Err(format!("\"{s}\": empty range"));
    }
    Ok(a..b)
}

#[derive(Clone, Copy, ValueEnum)]
enum FormatArg {
    Relit,
    Colmap,
    Sibr,
    /// instant-ngp / nerfstudio transforms.json
    Transforms,
}

#[derive(Subcommand)]
enum SceneCmd {
    /// Load a scene in any format (scene.json, COLMAP binary or text, SIBR, transforms.json) and print a summary, with how
    /// many input views see each original light (a warning when fewer than 3 do).
    Check {
        dir: PathBuf,
        /// Check headers only; do not decode every image.
        #[arg(long)]
        quick: bool,
    },
    /// Find the original lights the photos clip (Appendix A) and estimate their emittance; they
    /// are written to the scene (scene.json, or lights.json beside other formats) as original
    /// lights marked `estimated`, replacing earlier estimated ones.
    FindLights {
        dir: PathBuf,
        /// Print what was found; write nothing.
        #[arg(long)]
        dry_run: bool,
        /// Voxel edge in metres (a pixel's footprint where the photos are coarser).
        #[arg(long, default_value_t = 0.02)]
        voxel: f32,
        /// Views the emittance is estimated from, spread over the capture (fewer: faster).
        #[arg(long, default_value_t = 8)]
        views: usize,
    },
    /// Write the small procedural test room (CPU-shaded EXR views) in one of the formats.
    Synth {
        dir: PathBuf,
        #[arg(long, value_enum, default_value = "relit")]
        format: FormatArg,
        #[arg(long, default_value_t = 6)]
        views: usize,
        /// Image size WxH.
        #[arg(long, default_value = "64x48", value_parser = parse_res)]
        res: (u32, u32),
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
}

fn parse_present(s: &str) -> Result<relit_engine::gpu::PresentMode, String> {
    relit_engine::gpu::PresentMode::parse(s)
        .ok_or_else(|| format!("\"{s}\": expected immediate, mailbox or fifo"))
}

fn parse_fluid(s: &str) -> Result<relit_engine::view::fluid::Policy, String> {
    relit_engine::view::fluid::Policy::parse(s)
        .ok_or_else(|| format!("\"{s}\": expected auto, still or moving"))
}

pub fn parse_res(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("\"{s}\": expected WxH, e.g. 256x192"))?;
    let w: u32 = w
        .parse()
        .map_err(|_| format!("\"{s}\": width is not a number"))?;
    let h: u32 = h
        .parse()
        .map_err(|_| format!("\"{s}\": height is not a number"))?;
    if w == 0 || h == 0 || w > scene::MAX_IMAGE_DIM || h > scene::MAX_IMAGE_DIM {
        return Err(format!(
            "\"{s}\": each side must be 1..={}",
            scene::MAX_IMAGE_DIM
        ));
    }
    Ok((w, h))
}

fn gpu_options(cli: &Cli) -> GpuOptions {
    let mut o = GpuOptions::default();
    if let Some(d) = &cli.device {
        o.device = DeviceChoice::parse(d);
    }
    o.validation |= cli.validate;
    o
}

/// `--mesh`, set once in `main` before any command runs.
static MESH: std::sync::OnceLock<Option<PathBuf>> = std::sync::OnceLock::new();

/// The `--mesh` the command line gave, if any.
pub fn mesh_override() -> Option<&'static std::path::Path> {
    MESH.get().and_then(|m| m.as_deref())
}

/// Loads the scene at `dir` with the command line's `--mesh`, if any.
pub fn load_scene(dir: &std::path::Path) -> Result<Scene> {
    Ok(Scene::load_with_mesh(dir, mesh_override())?)
}

pub fn open_gpu(opts: &GpuOptions) -> Result<Arc<Gpu>> {
    Gpu::new(opts).context("opening the Vulkan device")
}

fn yes(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "no"
    }
}

fn info(opts: &GpuOptions) -> Result<()> {
    let entry = gpu::load_entry()?;
    println!("Vulkan devices:");
    for (i, c) in gpu::list_devices()?.iter().enumerate() {
        let missing = c.missing();
        println!(
            "  [{i}] {} ({:?}), driver {} {}{}",
            c.name,
            c.device_type,
            c.driver_name,
            c.driver_info,
            if missing.is_empty() {
                String::new()
            } else {
                format!(" — cannot run Relit: missing {}", missing.join(", "))
            }
        );
    }
    println!(
        "validation layer installed: {}",
        yes(gpu::validation_layer_available(&entry))
    );
    let g = open_gpu(opts)?;
    let c = &g.caps;
    let v = c.api_version;
    println!("\nusing: {}", c.name);
    println!("  type: {:?}", c.device_type);
    println!("  driver: {} ({})", c.driver_name, c.driver_info);
    println!(
        "  Vulkan: {}.{}.{}",
        gpu::vk::api_version_major(v),
        gpu::vk::api_version_minor(v),
        gpu::vk::api_version_patch(v)
    );
    println!("required features:");
    for (name, ok) in &c.required {
        println!("  {name:<34} {}", yes(*ok));
    }
    println!("optional features:");
    println!(
        "  {:<34} {}",
        "cooperative matrix",
        yes(!c.coop_matrix.is_empty())
    );
    for s in &c.coop_matrix {
        println!(
            "    {}x{}x{} A={:?} B={:?} C={:?} result={:?} scope={:?}",
            s.m, s.n, s.k, s.a, s.b, s.c, s.result, s.scope
        );
    }
    println!(
        "  {:<34} {}",
        "BC texture compression",
        yes(c.bc_compression)
    );
    println!(
        "  {:<34} {}",
        "BC6H sampled with linear filter",
        yes(c.bc6h_sampled_linear)
    );
    // What runs, from the same decision as the kernels (fp32 is `--storage auto`'s choice on
    // CPU devices when the frame fits, fp16 otherwise).
    for storage in [
        relit_engine::net::Storage::F16,
        relit_engine::net::Storage::F32,
    ] {
        println!(
            "network path, {:?} storage: {}",
            storage,
            relit_engine::net::describe_backend(c, storage)
        );
    }
    println!("trained network: {}", shipped_network());
    println!(
        "default mode: {:?} (the best on the held-out rooms; docs/evaluation.md)",
        relit_engine::frame::DEFAULT_MODE
    );
    println!("limits:");
    println!(
        "  maxStorageBufferRange              {} MiB",
        c.max_storage_buffer_range >> 20
    );
    println!(
        "  maxImageDimension2D                {}",
        c.max_image_dimension_2d
    );
    println!(
        "  maxImageArrayLayers                {}",
        c.max_image_array_layers
    );
    println!(
        "  maxPushConstantsSize               {}",
        c.max_push_constants_size
    );
    println!(
        "  maxComputeWorkGroupInvocations     {}",
        c.max_compute_workgroup_invocations
    );
    println!(
        "  maxComputeSharedMemorySize         {} KiB",
        c.max_compute_shared_memory >> 10
    );
    println!("  subgroupSize                       {}", c.subgroup_size);
    println!(
        "  timestampPeriod                    {} ns ({} valid bits)",
        c.timestamp_period_ns, c.timestamp_valid_bits
    );
    println!(
        "  maxPrimitiveCount (BLAS)           {}",
        c.max_primitive_count
    );
    println!(
        "  memory types                       {}",
        c.memory_types.len()
    );
    for (flags, heap) in &c.memory_types {
        println!("    heap {heap}: {flags:?}");
    }
    Ok(())
}

fn find_lights(
    opts: &GpuOptions,
    dir: &std::path::Path,
    dry_run: bool,
    (voxel, views): (f32, usize),
) -> Result<()> {
    use relit_engine::bake::light_levels::{self, FindParams};
    if !(voxel.is_finite() && voxel > 0.0) {
        anyhow::bail!("--voxel {voxel}: expected a positive length in metres");
    }
    let mut s = load_scene(dir)?;
    let gpu = open_gpu(opts)?;
    if views == 0 {
        anyhow::bail!("--views 0: expected at least one view");
    }
    let p = FindParams {
        voxel,
        max_views: views,
        ..Default::default()
    };
    let mut lines = progress::LogLines::new("find-lights");
    let mut progress = |stage: &str, done: usize, total: usize, _rays: u64| {
        lines.update(stage, done, total, &|_| String::new())
    };
    let f = light_levels::find(&gpu, &s, &p, &mut progress)?;
    println!(
        "clipped pixels: {} over {} views ({} on no surface of the proxy mesh); voxel {:.3} m",
        f.clipped_pixels,
        s.views.len(),
        f.off_mesh,
        f.voxel
    );
    if f.clipped_pixels == 0 {
        println!("no photo clips (8-bit photos clip at code 250 of 255; EXR photos never do): nothing to find");
    }
    if let Some(why) = f.why_none(&p) {
        println!("{why}");
    }
    for l in &f.lights {
        let c = l.light.shape.center();
        println!(
            "  {}: quad at [{:.2}, {:.2}, {:.2}], area {:.3} m², radiance [{:.3}, {:.3}, {:.3}], power {:.2} W (luminance); {} clipped pixels in {} views, {} pixel pairs",
            l.light.name, c.x, c.y, c.z, l.light.shape.area(),
            l.light.radiance[0], l.light.radiance[1], l.light.radiance[2],
            { let w = l.power(); 0.2126 * w[0] + 0.7152 * w[1] + 0.0722 * w[2] }, l.pixels, l.views, l.pairs
        );
        if l.pairs == 0 || l.light.radiance.iter().all(|&r| r == 0.0) {
            println!(
                "  warning: {}'s emittance could not be estimated (no pixel it lights pairs with one it does not): set its radiance by hand",
                l.light.name
            );
        }
    }
    if dry_run {
        return Ok(());
    }
    s.lights = light_levels::replace_estimated(&s, &f.lights);
    s.save_lights()?;
    println!(
        "wrote {} estimated light(s) to {}",
        f.lights.len(),
        s.root.display()
    );
    Ok(())
}

fn scene_check(dir: &std::path::Path, quick: bool) -> Result<()> {
    let s = load_scene(dir)?;
    if !quick {
        s.check_images()?;
    }
    let (lo, hi) = s.mesh.bounds();
    let mut sizes: Vec<(u32, u32)> = s
        .views
        .iter()
        .map(|v| (v.camera.width, v.camera.height))
        .collect();
    sizes.sort();
    sizes.dedup();
    println!("scene: {} ({})", s.root.display(), s.format);
    println!("views: {}", s.views.len());
    println!(
        "resolution: {}",
        sizes
            .iter()
            .map(|(w, h)| format!("{w}x{h}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    println!(
        "mesh: {} ({} vertices, {} triangles)",
        s.mesh_path.display(),
        s.mesh.positions.len(),
        s.mesh.triangles.len()
    );
    println!(
        "bounds: [{:.3}, {:.3}, {:.3}] – [{:.3}, {:.3}, {:.3}] m",
        lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
    );
    if let Some(t) = &s.true_mesh_path {
        println!("true mesh: {}", t.display());
    }
    println!("lights: {}", s.lights.len());
    for l in &s.lights {
        let kind = match l.shape {
            scene::LightShape::Quad { .. } => "quad",
            scene::LightShape::Disk { .. } => "disk",
        };
        let c = l.shape.center();
        println!(
            "  {} ({kind}{}) at [{:.2}, {:.2}, {:.2}], area {:.3} m², radiance {:?}",
            l.name,
            match (l.original, l.estimated) {
                (true, true) => ", original, estimated from clipped pixels",
                (true, false) => ", original",
                _ => "",
            },
            c.x,
            c.y,
            c.z,
            l.shape.area(),
            l.radiance
        );
    }
    if !quick {
        let clipped: usize = s.view_photos()?.iter().map(|p| p.clipped_count()).sum();
        println!("clipped pixels: {clipped}");
        if clipped > 0 && !s.lights.iter().any(|l| l.estimated) {
            println!(
                "note: the photos clip; if a light clips, `relit scene find-lights {}` finds it and estimates its emittance (Appendix A)",
                dir.display()
            );
        }
    }
    if !s.lights.iter().any(|l| l.original) {
        println!(
            "warning: no original light is declared or found. A light the photos show clipped is found by `relit scene find-lights`; one no photo shows cannot be found from the photos: declare it in scene.json (docs/formats.md)"
        );
    }
    // The proxy mesh is loaded in both modes, so --quick checks coverage too.
    let coverage = scene::light_coverage(&s);
    for c in &coverage {
        println!("{}", c.summary());
    }
    print_coverage_warnings(&coverage);
    println!("presets: {}", s.presets.len());
    for p in &s.presets {
        println!(
            "  {}: dim {}, intensities {:?}",
            p.name, p.dim, p.intensities
        );
    }
    println!(
        "images: {}",
        if quick {
            "headers not decoded (--quick)"
        } else {
            "all decoded, sizes match cameras, values finite"
        }
    );
    Ok(())
}

/// The warnings for original lights too few input views see, on stderr.
fn print_coverage_warnings(coverage: &[scene::LightCoverage]) {
    for w in coverage.iter().filter_map(|c| c.warning()) {
        eprintln!("{w}");
    }
}

/// The bake parameters of a quality preset.
pub fn quality_params(q: Quality) -> relit_engine::bake::BakeParams {
    match q {
        Quality::Preview => relit_engine::bake::BakeParams::preview(),
        Quality::Final => relit_engine::bake::BakeParams::final_quality(),
    }
}

/// This checkout's tools/ directory (the ground-truth renderer's scripts).
fn tools_dir() -> PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tools")
}

/// The added lights `--lights` names (None: all), checked against the scene.
pub fn bake_lights_arg(scene: &Scene, arg: &str, eval: bool) -> Result<Option<Vec<String>>> {
    let mut added = relit_engine::frame::added_lights(scene);
    Ok(match arg {
        // Every light by name: the original lights' entries too (per-light control).
        "all" => Some(scene.lights.iter().map(|l| l.name.clone()).collect()),
        "presets" => {
            let mut v = scene.preset_lights();
            // A preset with a factor for an original light needs the original lights' entries.
            if scene.presets.iter().any(|p| !p.originals.is_empty()) {
                v.extend(scene.original_names());
                added.extend(scene.original_names());
            }
            if let (true, Some(syn)) = (eval, &scene.synthetic) {
                v.extend(syn.conditions.iter().flat_map(|c| c.lights.iter().cloned()));
            }
            v.retain(|n| added.contains(n));
            v.sort();
            v.dedup();
            Some(v)
        }
        names => {
            let v: Vec<String> = names.split(',').map(|n| n.trim().to_string()).collect();
            // An original light's name asks for every original light's entry (per-light control).
            let originals = scene.original_names();
            if let Some(n) = (v.iter()).find(|n| !added.contains(n) && !originals.contains(n)) {
                anyhow::bail!(
                    "--lights: \"{n}\" is not a light of {} (added lights: {}; original lights: {}; or `presets`, `all`)",
                    scene.root.join("scene.json").display(),
                    added.join(", "),
                    originals.join(", ")
                );
            }
            Some(v)
        }
    })
}

/// The cache and each stage of a bake: items, seconds and ray rate.
pub fn print_stages(report: &relit_engine::bake::BakeReport) {
    println!("cache: {}", report.cache.display());
    for (stage, secs, rays, items) in &report.stages {
        if *items == 0 {
            println!("  {stage}: cached");
        } else {
            println!(
                "  {stage}: {items} item(s) in {secs:.1} s{}",
                if *rays > 0 {
                    // Paths end early by Russian roulette: their count is the most they trace.
                    let most = if stage == "surface cache" {
                        "at most "
                    } else {
                        ""
                    };
                    format!(
                        ", {most}{:.2} M rays/s",
                        *rays as f64 / secs.max(1e-9) * 1e-6
                    )
                } else {
                    String::new()
                }
            );
        }
    }
}

fn bake(
    dir: &std::path::Path,
    p: &relit_engine::bake::BakeParams,
    lights: &str,
    eval: bool,
    opts: &GpuOptions,
) -> Result<()> {
    let scene = load_scene(dir)?;
    let p = &relit_engine::bake::BakeParams {
        lights: bake_lights_arg(&scene, lights, eval)?,
        ..p.clone()
    };
    print_coverage_warnings(&scene::light_coverage(&scene));
    let gpu = open_gpu(opts)?;
    let t0 = std::time::Instant::now();
    let mut bars: Vec<(String, indicatif::ProgressBar)> = Vec::new();
    let multi = indicatif::MultiProgress::new();
    let style = indicatif::ProgressStyle::with_template(
        "{prefix:>26} {bar:30} {pos}/{len} {msg} ETA {eta}",
    )
    .unwrap();
    let mut lines = (!progress::on_terminal()).then(|| progress::LogLines::new("bake"));
    let mut progress = |stage: &str, done: usize, total: usize, rays: u64| {
        if let Some(l) = lines.as_mut() {
            l.update(stage, done, total, &|secs| {
                if rays > 0 {
                    format!("{:.2} M rays/s", rays as f64 / secs * 1e-6)
                } else {
                    String::new()
                }
            });
            return;
        }
        if bars.last().is_none_or(|(s, _)| s != stage) {
            let b = multi.add(indicatif::ProgressBar::new(total as u64));
            b.set_style(style.clone());
            b.set_prefix(stage.to_string());
            bars.push((stage.to_string(), b));
        }
        let (_, b) = bars.last().unwrap();
        b.set_position(done as u64);
        let secs = b.elapsed().as_secs_f64().max(1e-3);
        if rays > 0 {
            b.set_message(format!("{:.2} M rays/s", rays as f64 / secs * 1e-6));
        }
    };
    let report = relit_engine::bake::bake(&gpu, &scene, p, &mut progress)?;
    for (_, b) in &bars {
        b.finish();
    }
    print_stages(&report);
    if !report.albedo_mesh {
        println!("albedo mesh and later stages wait for every view's source irradiance (bake the other slices)");
    }
    println!("done in {:.1} s", t0.elapsed().as_secs_f64());
    if eval && report.albedo_mesh {
        let a = relit_engine::bake::accuracy::evaluate(&gpu, &scene, p)?;
        println!(
            "accuracy against ground truth ({} views; per pixel: median relative error, median ratio relit/truth):",
            a.views
        );
        println!("  E_src vs true irradiance:   {}", a.e_src);
        println!("  albedo mesh vs true albedo: {}", a.albedo);
        if a.m_src.pixels > 0 {
            println!("  M_src vs true mirror image: {}", a.m_src);
        }
        for (l, e) in &a.e_add {
            println!("  E_add {l} vs path tracer:  {e}");
        }
    }
    Ok(())
}

/// The viewer's keys as help text, from the list the viewer's F1 help shows
/// (`view::hud::KEYS`), so `relit --help`, `relit view --help`, F1 and the README agree.
fn viewer_keys_help() -> String {
    let mut s = String::from("Viewer keys (relit view; F1 shows them in the window):\n");
    for line in relit_engine::view::hud::key_lines() {
        s.push_str("  ");
        s.push_str(&line);
        s.push('\n');
    }
    s
}

/// The command line, with the viewer's keys after `relit --help` and `relit view --help`.
fn parse_cli() -> Cli {
    let keys = viewer_keys_help();
    let cmd = Cli::command()
        .after_long_help(keys.clone())
        .mut_subcommand("view", |view| view.after_help(keys));
    Cli::from_arg_matches(&cmd.get_matches()).unwrap_or_else(|e| e.exit())
}

fn main() {
    // Output piped into `head` and the like: a closed pipe ends the process quietly, as other
    // command-line tools do, instead of a panic in println!.
    // SAFETY: restores a signal's default disposition before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = parse_cli();
    let opts = gpu_options(&cli);
    MESH.set(cli.mesh.clone()).expect("set once");
    let res = run(&cli, &opts);
    if let Err(e) = res {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// Runs the command the command line names.
fn run(cli: &Cli, opts: &GpuOptions) -> Result<()> {
    match &cli.cmd {
        Cmd::Info => info(opts),
        Cmd::Scene { cmd } => scene_cmd(cmd, opts),
        Cmd::Bench { cmd } => bench::run(cmd, opts),
        cmd @ Cmd::View { .. } => view::view(opts, view_args(cmd)),
        Cmd::Render {
            scene,
            camera,
            lighting,
            res,
            out,
            batch,
            leave_out,
            frame,
        } => match (batch, camera, out) {
            (Some(b), _, _) => render::render_batch(opts, scene, b, *res, frame),
            (None, Some(c), Some(o)) => render::render(
                opts,
                scene,
                c,
                *res,
                lighting.as_deref(),
                o,
                *leave_out,
                frame,
            ),
            _ => Err(anyhow::anyhow!(
                "relit render: --camera and --out, or --batch"
            )),
        },
        Cmd::Fly {
            scene,
            path,
            out,
            res,
            fps,
            max_frames,
            frame,
        } => render::fly(opts, scene, path, out, *res, (*fps, *max_frames), frame),
        Cmd::Dump {
            scene,
            camera,
            lighting,
            out,
            keep_view,
            parts,
            frame,
        } => render::dump(
            opts,
            scene,
            &render::DumpRequest {
                camera,
                preset: lighting.as_deref(),
                out,
                keep_view: *keep_view,
                parts: *parts,
            },
            frame,
        ),
        Cmd::Dataset(_) if cli.mesh.is_some() => Err(anyhow::anyhow!(
            "--mesh names one scene's proxy; relit dataset makes every room's own"
        )),
        Cmd::Dataset(a) => dataset::run(a, opts),
        Cmd::Bake {
            scene,
            views,
            quality,
            rays,
            texel_rays,
            added_samples,
            cache_samples,
            lights,
            eval,
            mesh_process,
            uncompressed,
        } => {
            let p = bake_params(
                *quality,
                views.clone(),
                (*mesh_process, *uncompressed),
                (*rays, *texel_rays, *added_samples, *cache_samples),
            );
            bake(scene, &p, lights, *eval, opts)
        }
    }
}

/// `relit bake`'s parameters: the quality preset with the command line's views, geometry
/// processing, compression and, where given, sample counts.
fn bake_params(
    quality: Quality,
    views: Option<std::ops::Range<usize>>,
    (mesh_process, uncompressed): (bool, bool),
    (rays, texel_rays, added_samples, cache_samples): (
        Option<u32>,
        Option<u32>,
        Option<u32>,
        Option<u32>,
    ),
) -> relit_engine::bake::BakeParams {
    let mut p = quality_params(quality);
    p.views = views;
    p.mesh_process = mesh_process;
    p.compress = !uncompressed;
    if let Some(r) = rays {
        p.irradiance_samples = r;
    }
    if let Some(t) = texel_rays {
        p.source_cache_samples = t;
    }
    if let Some(a) = added_samples {
        p.added_samples = a;
    }
    if let Some(c) = cache_samples {
        p.cache_samples = c;
    }
    p
}

/// The viewer's arguments from `relit view`'s command line (`cmd` is a `Cmd::View`).
fn view_args(cmd: &Cmd) -> view::ViewArgs {
    let Cmd::View {
        scene,
        res,
        fullscreen,
        frames,
        screenshot,
        camera,
        lighting,
        keys,
        window,
        present,
        record,
        play,
        fluid,
        no_hud,
        frame,
    } = cmd
    else {
        unreachable!("view_args is given `relit view`'s command")
    };
    view::ViewArgs {
        scene: scene.clone(),
        res: *res,
        window: *window,
        present: *present,
        record: record.clone(),
        play: play.clone(),
        fluid: *fluid,
        hud: !*no_hud,
        fullscreen: *fullscreen,
        frames: *frames,
        screenshot: screenshot.clone(),
        camera: camera.clone(),
        lighting: lighting.clone(),
        frame: frame.clone(),
        keys: keys.clone(),
    }
}

/// Runs a `relit scene` command.
fn scene_cmd(cmd: &SceneCmd, opts: &GpuOptions) -> Result<()> {
    match cmd {
        SceneCmd::Check { dir, quick } => scene_check(dir, *quick),
        SceneCmd::FindLights {
            dir,
            dry_run,
            voxel,
            views,
        } => find_lights(opts, dir, *dry_run, (*voxel, *views)),
        SceneCmd::Synth {
            dir,
            format,
            views,
            res,
            seed,
        } => synth(dir, *format, *views, *res, *seed),
    }
}

/// `relit scene synth`: writes the procedural test room in `format`.
fn synth(
    dir: &std::path::Path,
    format: FormatArg,
    views: usize,
    res: (u32, u32),
    seed: u64,
) -> Result<()> {
    let format = match format {
        FormatArg::Relit => SceneFormat::Relit,
        FormatArg::Colmap => SceneFormat::Colmap,
        FormatArg::Sibr => SceneFormat::Sibr,
        FormatArg::Transforms => SceneFormat::Transforms,
    };
    let o = scene::synth::SynthOptions {
        views,
        width: res.0,
        height: res.1,
        seed,
        ..Default::default()
    };
    scene::synth::write_room(dir, format, &o)
        .map(|s| {
            println!(
                "wrote {} views ({format}) to {}",
                s.views.len(),
                dir.display()
            )
        })
        .map_err(Into::into)
}

/// The built-in weights' width and provenance, from their metadata.
fn shipped_network() -> String {
    let meta = safetensors::SafeTensors::read_metadata(relit_engine::net::SHIPPED)
        .ok()
        .and_then(|(_, m)| m.metadata().clone())
        .unwrap_or_default();
    let json = |key: &str| -> serde_json::Value {
        meta.get(key)
            .and_then(|j| serde_json::from_str(j).ok())
            .unwrap_or_default()
    };
    let (net, trained) = (json("relit.net"), json("relit.trained"));
    let steps: Vec<String> = (trained["averaged_with"].as_array())
        .map(|a| a.iter().map(|e| e["step"].to_string()).collect())
        .unwrap_or_default();
    let averaged = match steps.is_empty() {
        true => String::new(),
        false => format!(" averaged with step {}", steps.join(", ")),
    };
    let option = |k: &str| {
        net[k]
            .as_f64()
            .map_or(String::new(), |v| format!(", {k} {v}"))
    };
    let base = match net["base"].as_str() {
        Some(b) => {
            let gain = if net["gain"].as_bool() == Some(true) {
                ", gain"
            } else {
                ""
            };
            let opts = format!(
                "{}{}{gain}{}",
                option("shrink"),
                option("gate"),
                option("agree")
            );
            format!(", base {b}{opts}")
        }
        None => String::new(),
    };
    format!(
        "width {}{base}, run {} at step {}{averaged}, built into relit from {}",
        net["width"],
        trained["run"].as_str().unwrap_or("?"),
        trained["step"],
        relit_engine::net::SHIPPED_NAME
    )
}
