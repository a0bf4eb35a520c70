//! `relit bench …`: throughput figures from GPU timestamps. Nothing here passes or fails.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::Subcommand;
use glam::Vec3;
use relit_engine::gpu::{vk, Buffer, GpuOptions, Graph, MemoryLocation, RayScene, Timer};
use relit_engine::scene::{synth, Mesh};
use relit_engine::trace::{Hit, Ray, RayCaster};

#[derive(Subcommand)]
pub enum BenchCmd {
    /// Ray-query rays per second (closest hit and any hit) and BLAS build time.
    Rays {
        /// Rays per dispatch (the mesh traced: `--mesh`, default a procedural room of ~100k
        /// triangles).
        #[arg(long, default_value_t = 1 << 18)]
        rays: u32,
        /// Timed dispatches per mode (the median is reported).
        #[arg(long, default_value_t = 3)]
        repeats: u32,
        /// Also write the figures as JSON.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// BC6H view storage: encode time, size ratio and log-space PSNR (μ = 64) against the
    /// half-float maps of a baked scene's cache, decoded by sampling on the device.
    Bc6h {
        /// A bake cache directory (SCENE/.relit/bake-<key>).
        cache: PathBuf,
        /// Maps to encode (the first N files of each kind).
        #[arg(long, default_value_t = 4)]
        maps: usize,
    },
    /// Seconds per view and rays/s of each bake stage (GPU timestamps, nothing cached), next to
    /// the raw ray-query rate on the same mesh.
    Bake {
        scene: PathBuf,
        #[arg(long, value_enum, default_value = "final")]
        quality: crate::Quality,
        /// Added lights to bake, as `relit bake --lights`: presets, all, or names A,B.
        #[arg(long, default_value = "presets")]
        lights: String,
    },
    /// Whole frames of a baked scene along its test path (or its views): GPU time per pass
    /// (G-buffer, reproject, irradiance, target mirror, features, each network stage, output),
    /// fps median and p95. The network is the shipped one, or --weights, or random weights of
    /// --width.
    Frame {
        scene: PathBuf,
        #[arg(long, default_value = "256x192", value_parser = crate::parse_res)]
        res: (u32, u32),
        /// Timed frames after one warm-up frame.
        #[arg(long, default_value_t = 5)]
        frames: u32,
        /// A network of this width with random weights instead of the trained one.
        #[arg(long)]
        width: Option<u32>,
        #[arg(long)]
        json: Option<PathBuf>,
        /// The lighting preset to time (default: the scene's first preset, else the original
        /// lighting).
        #[arg(long)]
        lighting: Option<String>,
        #[command(flatten)]
        frame: crate::render::FrameArgs,
    },
    /// Moving a light in the viewer: time from the move to the first frame that shows it, and
    /// to a converged E_add (the live light's surface cache at the bake's paths per texel), on
    /// a baked scene from its first view, ratio mode (the first added light moves 30 cm).
    Light {
        scene: PathBuf,
        #[arg(long, default_value = "128x96", value_parser = crate::parse_res)]
        res: (u32, u32),
        /// Paths per texel that count as converged (preview bake: 32).
        #[arg(long, default_value_t = 32)]
        paths: u32,
        #[command(flatten)]
        frame: crate::render::FrameArgs,
    },
    /// The network alone (§5.1, random weights): ms per inference, GFLOP/s, per-stage times.
    /// `tools/train/bench_torch.py` times the same network with PyTorch on the CPU.
    Net {
        /// Feature width W (the paper: 66).
        #[arg(long, default_value_t = 66)]
        width: u32,
        /// Input size WxH.
        #[arg(long, default_value = "256x192", value_parser = crate::parse_res)]
        res: (u32, u32),
        /// Element type of activations and weights in memory.
        #[arg(long, value_enum, default_value = "auto")]
        storage: crate::StorageArg,
        /// Use the portable kernels even where the device would take others (the CPU-shaped
        /// ones on lavapipe, cooperative matrices on GPUs): the same network both ways.
        #[arg(long)]
        portable: bool,
        /// The CPU-shaped kernels with this blocking, OCN,ROWS (output channels and rows per
        /// invocation), instead of the measured default; fp32 storage.
        #[arg(long, value_parser = parse_lanes)]
        lanes: Option<(u32, u32)>,
        /// Timed inferences after one warm-up (the median is reported).
        #[arg(long, default_value_t = 3)]
        repeats: u32,
        /// Also write the figures as JSON.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Then time the same network with PyTorch on the CPU (tools/train/bench_torch.py) with
        /// as many threads as lavapipe uses (LP_NUM_THREADS, else the CPU count).
        #[arg(long)]
        torch: bool,
    },
    /// Storage access: the same gather kernel (16 loads per invocation at indices that differ
    /// per invocation) reading its table through a storage-buffer binding and through a
    /// buffer-device-address pointer; ms per dispatch and loads per second for each.
    Gather {
        /// Invocations per dispatch.
        #[arg(long, default_value_t = 1 << 20)]
        count: u32,
        /// Table length (a power of two; 16 bytes each). The default fits the CPU's L2 cache, so
        /// the loads' instructions show, not the memory.
        #[arg(long, default_value_t = 1 << 12)]
        table: u32,
        /// Timed dispatches per variant (the median is reported).
        #[arg(long, default_value_t = 5)]
        repeats: u32,
    },
}

pub fn run(cmd: &BenchCmd, opts: &GpuOptions) -> Result<()> {
    match cmd {
        BenchCmd::Rays {
            rays,
            repeats,
            json,
        } => rays_bench(crate::mesh_override(), *rays, *repeats, json.as_ref(), opts),
        BenchCmd::Bake {
            scene,
            quality,
            lights,
        } => bake_bench(scene, *quality, lights, opts),
        BenchCmd::Bc6h { cache, maps } => bc6h_bench(cache, *maps, opts),
        BenchCmd::Gather {
            count,
            table,
            repeats,
        } => gather_bench(*count, *table, *repeats, opts),
        BenchCmd::Light {
            scene,
            res,
            paths,
            frame,
        } => light_bench(scene, *res, *paths, frame, opts),
        BenchCmd::Frame {
            scene,
            res,
            frames,
            width,
            json,
            lighting,
            frame,
        } => frame_bench(
            scene,
            (*res, *frames),
            (*width, lighting.as_deref()),
            json.as_ref(),
            frame,
            opts,
        ),
        BenchCmd::Net {
            width,
            res,
            storage,
            portable,
            lanes,
            repeats,
            json,
            torch,
        } => {
            net_bench(
                *width,
                *res,
                (*storage, *portable, *lanes),
                *repeats,
                json.as_ref(),
                opts,
            )?;
            if *torch {
                torch_bench(*width, *res, *repeats)?;
            }
            Ok(())
        }
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// Random rays from points inside the mesh's bounds, uniform directions. Occlusion rays are
/// short (0.2–2 m), like shadow and visibility rays in the bake.
fn make_rays(mesh: &Mesh, n: u32, occlusion: bool, seed: u64) -> Vec<Ray> {
    let (lo, hi) = mesh.bounds();
    let mut rng = synth::Rng::new(seed);
    (0..n)
        .map(|_| {
            let o = lo
                + (hi - lo)
                    * Vec3::new(
                        rng.range(0.1, 0.9),
                        rng.range(0.1, 0.9),
                        rng.range(0.1, 0.9),
                    );
            let z = rng.range(-1.0, 1.0);
            let phi = rng.range(0.0, std::f32::consts::TAU);
            let r = (1.0 - z * z).max(0.0).sqrt();
            let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            Ray {
                origin: o.into(),
                tmin: 1e-4,
                dir: d.into(),
                tmax: if occlusion { rng.range(0.2, 2.0) } else { 1e4 },
            }
        })
        .collect()
}

/// The procedural room at ~100k triangles with every vertex moved up to 1 cm, so that walls are
/// not flat quads (closer to an MVS mesh than a clean model is).
fn bumpy_room() -> Mesh {
    let (mut m, _) = synth::room(91);
    let mut rng = synth::Rng::new(3);
    for p in &mut m.positions {
        for c in p.iter_mut() {
            *c += rng.range(-0.01, 0.01);
        }
    }
    m
}

fn gather_bench(count: u32, table: u32, repeats: u32, opts: &GpuOptions) -> Result<()> {
    use relit_engine::gpu::gather::{Access, GatherProbe, LOADS};
    if !table.is_power_of_two() {
        anyhow::bail!("--table {table}: expected a power of two");
    }
    let gpu = crate::open_gpu(opts)?;
    println!("device: {}", gpu.caps.name);
    let data: Vec<[f32; 4]> = (0..table).map(|i| [i as f32, 1.0, 0.5, 0.25]).collect();
    let probe = GatherProbe::new(&gpu, &data, count)?;
    println!("{count} invocations x {LOADS} vec4 loads from a {table}-entry table");
    let mut first = None;
    for access in [Access::StorageBuffer, Access::DeviceAddress] {
        // The first dispatch compiles the shader on lavapipe: warm up untimed.
        let (sums, _) = probe.run(access)?;
        let times = (0..repeats.max(1))
            .map(|_| probe.run(access).map(|r| r.1))
            .collect::<relit_engine::Result<Vec<f64>>>()?;
        let ms = median(times);
        let loads = count as f64 * LOADS as f64 / (ms * 1e-3);
        println!("{access:?}: {ms:.2} ms, {:.1} M loads/s", loads / 1e6);
        match &first {
            None => first = Some(sums),
            Some(f) if *f != sums => anyhow::bail!("the two variants disagree"),
            Some(_) => {}
        }
    }
    Ok(())
}

fn rays_bench(
    mesh_path: Option<&std::path::Path>,
    n: u32,
    repeats: u32,
    json: Option<&PathBuf>,
    opts: &GpuOptions,
) -> Result<()> {
    let (mesh, name) = match mesh_path {
        Some(p) => (Mesh::load(p)?, p.display().to_string()),
        None => (
            bumpy_room(),
            "procedural room, subdivision 91, 1 cm bumps".to_string(),
        ),
    };
    let gpu = crate::open_gpu(opts)?;
    println!("device: {}", gpu.caps.name);
    println!("mesh: {name}: {} triangles", mesh.triangles.len());
    let t0 = Instant::now();
    let scene = RayScene::new(&gpu, &mesh.positions, &mesh.triangles)?;
    let build_s = t0.elapsed().as_secs_f64();
    println!("BLAS+TLAS build (wall, incl. upload): {:.3} s", build_s);
    let caster = RayCaster::new(&gpu)?;
    let hits = Buffer::new(
        &gpu,
        "hits",
        n as u64 * std::mem::size_of::<Hit>() as u64,
        vk::BufferUsageFlags::STORAGE_BUFFER,
        MemoryLocation::GpuOnly,
    )?;
    let mut results = Vec::new();
    for (mode, occlusion) in [("closest hit", false), ("any hit (occlusion)", true)] {
        let rays = make_rays(&mesh, n, occlusion, 7);
        let rb = Buffer::from_slice(&gpu, "rays", vk::BufferUsageFlags::STORAGE_BUFFER, &rays)?;
        // The first dispatch compiles the shader on lavapipe: warm up untimed.
        let mut err = Ok(());
        gpu.submit(|cmd| {
            let g = &mut Graph::new(&gpu, cmd, None);
            err = caster.record(g, &scene, &rb, &hits, n.min(1024), occlusion)
        })?;
        err?;
        let mut times = Vec::new();
        for _ in 0..repeats.max(1) {
            times.push(timed(&gpu, |g| {
                caster.record(g, &scene, &rb, &hits, n, occlusion)
            })?);
        }
        let ms = median(times);
        let hit_frac = {
            let h: Vec<Hit> = hits.download_vec()?;
            h.iter()
                .take(n as usize)
                .filter(|h| h.tri != u32::MAX)
                .count() as f64
                / n as f64
        };
        let rate = n as f64 / (ms * 1e-3);
        println!(
            "{mode:<22} {n} rays in {ms:.1} ms: {:.3} M rays/s ({:.0}% hit)",
            rate * 1e-6,
            hit_frac * 100.0
        );
        results.push(format!(
            "{{\"mode\": \"{mode}\", \"rays\": {n}, \"ms\": {ms:.3}, \"mrays_per_s\": {:.4}, \"hit_fraction\": {hit_frac:.4}}}",
            rate * 1e-6
        ));
    }
    if let Some(p) = json {
        let text = format!(
            "{{\"device\": {:?}, \"mesh\": {:?}, \"triangles\": {}, \"build_s\": {build_s:.4}, \"results\": [{}]}}\n",
            gpu.caps.name,
            name,
            mesh.triangles.len(),
            results.join(", ")
        );
        relit_engine::scene::write_atomic(p, text.as_bytes())?;
    }
    Ok(())
}

/// Times the passes `record` puts in a graph with GPU timestamps; returns milliseconds.
fn timed(
    gpu: &std::sync::Arc<relit_engine::gpu::Gpu>,
    record: impl FnOnce(&mut Graph) -> relit_engine::Result<()>,
) -> Result<f64> {
    let mut timer = Timer::new(gpu, 1)?;
    let mut err = Ok(());
    gpu.submit(|cmd| {
        let mut g = Graph::new(gpu, cmd, Some(&mut timer));
        err = record(&mut g);
    })?;
    err?;
    Ok(timer.read()?[0].1)
}

/// The bake users run (`relit bake`), from scratch into a scratch cache (the scene's own cache
/// is left alone): wall time, rays and rate per stage, peak host memory, and the raw
/// closest-hit rate on the same mesh for comparison.
fn bake_bench(
    dir: &std::path::Path,
    quality: crate::Quality,
    lights: &str,
    opts: &GpuOptions,
) -> Result<()> {
    let mut scene = crate::load_scene(dir)?;
    let p = relit_engine::bake::BakeParams {
        lights: crate::bake_lights_arg(&scene, lights, false)?,
        ..crate::quality_params(quality)
    };
    // The cache lives under the scene's root; the photos and the mesh are read where they are.
    let scratch = std::env::temp_dir().join(format!("relit-bench-bake-{}", std::process::id()));
    std::fs::create_dir_all(&scratch)?;
    scene.root = scratch.clone();
    let gpu = crate::open_gpu(opts)?;
    println!("device: {}", gpu.caps.name);
    println!(
        "scene: {} views at {}x{}, {} proxy triangles",
        scene.views.len(),
        scene.views[0].camera.width,
        scene.views[0].camera.height,
        scene.mesh.triangles.len()
    );
    let t0 = Instant::now();
    let report = relit_engine::bake::bake(&gpu, &scene, &p, &mut |_: &str, _, _, _| {});
    let secs = t0.elapsed().as_secs_f64();
    let _ = std::fs::remove_dir_all(&scratch);
    crate::print_stages(&report?);
    println!("bake: {secs:.1} s, peak host memory {}", peak_memory());
    raw_rate(&gpu, &scene.mesh)
}

/// The process's peak resident memory (Linux: VmHWM).
fn peak_memory() -> String {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            let l = s.lines().find(|l| l.starts_with("VmHWM:"))?;
            let kb: f64 = l.split_whitespace().nth(1)?.parse().ok()?;
            Some(format!("{:.2} GB", kb / 1e6 * 1.024))
        })
        .unwrap_or_else(|| "unknown".into())
}

/// The raw closest-hit rate of random rays on `mesh`.
fn raw_rate(gpu: &std::sync::Arc<relit_engine::gpu::Gpu>, mesh: &Mesh) -> Result<()> {
    let rs = RayScene::new(gpu, &mesh.positions, &mesh.triangles)?;
    let caster = RayCaster::new(gpu)?;
    let rays = make_rays(mesh, 1 << 17, false, 3);
    let rb = Buffer::from_slice(gpu, "rays", vk::BufferUsageFlags::STORAGE_BUFFER, &rays)?;
    let hits = Buffer::new(
        gpu,
        "hits",
        (rays.len() * 16) as u64,
        vk::BufferUsageFlags::STORAGE_BUFFER,
        MemoryLocation::GpuOnly,
    )?;
    timed(gpu, |g| caster.record(g, &rs, &rb, &hits, 1024, false))?;
    let ms = timed(gpu, |g| {
        caster.record(g, &rs, &rb, &hits, rays.len() as u32, false)
    })?;
    println!(
        "raw closest-hit rate on this mesh: {:.3} M rays/s",
        rays.len() as f64 / (ms * 1e-3) * 1e-6
    );
    Ok(())
}

fn light_bench(
    dir: &std::path::Path,
    res: (u32, u32),
    paths: u32,
    fa: &crate::render::FrameArgs,
    opts: &GpuOptions,
) -> Result<()> {
    use relit_engine::frame::{Lighting, Mode};
    let scene = crate::load_scene(dir)?;
    let gpu = crate::open_gpu(opts)?;
    let mut args = fa.clone();
    args.mode = Some(crate::render::ModeArg::Ratio);
    let (mut r, _) = crate::render::open_renderer(&gpu, &scene, &args, None, None, false)?;
    let added: Vec<&relit_engine::scene::Light> =
        scene.lights.iter().filter(|l| !l.original).collect();
    let Some(first) = added.first() else {
        anyhow::bail!("{}: the scene has no added light to move", dir.display());
    };
    let cam = crate::render::rescale(&scene.views[0].camera, res.0, res.1);
    let mut lighting = Lighting::original(&scene);
    lighting.intensities[0] = 1.0;
    r.live.params.paths = paths;
    // Warm-up: shader compilation, and the live pipelines once.
    r.render(&cam, &lighting, Mode::Ratio, 1.0, None)?;
    r.set_live_light(0, first)?;
    r.refine_live()?;
    r.render(&cam, &lighting, Mode::Ratio, 1.0, None)?;
    let t0 = Instant::now();
    r.render(&cam, &lighting, Mode::Ratio, 1.0, None)?;
    let frame_s = t0.elapsed().as_secs_f64();
    // The move: the next frame shows it (direct light exact, the old cache until the new one
    // has a few paths), then refine + frame until converged.
    let eadd = |r: &relit_engine::frame::Renderer| -> Result<Vec<f32>> {
        let n = (res.0 * res.1) as usize;
        let irr: Vec<[f32; 4]> = r.buffers_ref().unwrap().irr.download_vec()?;
        Ok(irr[n..2 * n].iter().map(|p| p[0] + p[1] + p[2]).collect())
    };
    let moved = first.translated(glam::Vec3::new(0.3, 0.0, 0.0));
    let t0 = Instant::now();
    r.set_live_light(0, &moved)?;
    r.render(&cam, &lighting, Mode::Ratio, 1.0, None)?;
    let first_s = t0.elapsed().as_secs_f64();
    let mut shots = vec![(first_s, eadd(&r)?)];
    let mut t_frames = first_s;
    loop {
        let t = Instant::now();
        if !r.refine_live()? {
            break;
        }
        r.render(&cam, &lighting, Mode::Ratio, 1.0, None)?;
        t_frames += t.elapsed().as_secs_f64();
        shots.push((t_frames, eadd(&r)?));
    }
    // Median relative difference of each frame's E_add from the converged one.
    let last = shots.last().unwrap().1.clone();
    let diff = |e: &[f32]| {
        let mut d: Vec<f32> = e
            .iter()
            .zip(&last)
            .filter(|(_, l)| **l > 1e-4)
            .map(|(a, l)| (a - l).abs() / l)
            .collect();
        d.sort_by(f32::total_cmp);
        d.get(d.len() / 2).copied().unwrap_or(0.0)
    };
    println!("device: {}", gpu.caps.name);
    println!(
        "scene: {} ({} cache texels), {}x{}, ratio mode, light {} moved 30 cm",
        dir.display(),
        r.live.layout().texels(),
        res.0,
        res.1,
        first.name
    );
    println!("frame with a live light (no refinement): {:.3} s", frame_s);
    println!(
        "first frame showing the move: {:.3} s ({} shadow rays/px; the old cache)",
        first_s, r.live.params.samples
    );
    for (t, e) in &shots {
        println!(
            "  {:6.2} s: E_add median {:5.1}% from converged",
            t,
            100.0 * diff(e)
        );
    }
    let within = shots.iter().find(|(_, e)| diff(e) <= 0.05).map(|x| x.0);
    println!(
        "within 5% of converged ({} paths/texel, {} per step): {}",
        paths,
        r.live.params.paths_per_step,
        within.map_or("never".into(), |t| format!("{t:.2} s"))
    );
    Ok(())
}

fn bc6h_bench(cache: &std::path::Path, maps: usize, opts: &GpuOptions) -> Result<()> {
    use relit_engine::bake::storage::{encode_bc6h, log_psnr, Bc6hQuality, Bc6hTexture, Fetch};
    let gpu = crate::open_gpu(opts)?;
    let fetch = Fetch::new(&gpu)?;
    // The cache's maps and those of its lights' entries (light-*/).
    let mut files: Vec<PathBuf> = Vec::new();
    for e in std::fs::read_dir(cache)?.flatten() {
        if e.path().is_dir() {
            files.extend(std::fs::read_dir(e.path())?.flatten().map(|f| f.path()));
        } else {
            files.push(e.path());
        }
    }
    files.retain(|p| p.extension().is_some_and(|e| e == "exr"));
    files.sort();
    println!("device: {}", gpu.caps.name);
    for kind in [".esrc.", ".msrc.", ".eadd."] {
        let pick: Vec<_> = files
            .iter()
            .filter(|p| p.to_string_lossy().contains(kind))
            .take(maps)
            .collect();
        if pick.is_empty() {
            continue;
        }
        for q in [Bc6hQuality::Fast, Bc6hQuality::Basic] {
            let (mut psnr, mut ms, mut bytes, mut raw) = (0.0, 0.0, 0usize, 0usize);
            for f in &pick {
                let img = relit_engine::scene::image::load_rgb(f)?;
                let px: Vec<[f32; 4]> =
                    img.pixels.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect();
                let t = Instant::now();
                let blocks = encode_bc6h(img.width, img.height, &px, q);
                ms += t.elapsed().as_secs_f64() * 1e3;
                bytes += blocks.len();
                raw += (img.width * img.height * 8) as usize;
                let tex = Bc6hTexture::upload(&gpu, img.width, img.height, &[blocks])?;
                psnr += log_psnr(&fetch.run(&tex.image, 0, img.width, img.height)?, &px);
            }
            let n = pick.len() as f64;
            println!(
                "{:<6} {q:?}: {} maps, {:.1} ms/map to encode, {:.1}x smaller than RGBA16F, log-space PSNR {:.1} dB",
                kind.trim_matches('.'),
                pick.len(),
                ms / n,
                raw as f64 / bytes as f64,
                psnr / n
            );
        }
    }
    Ok(())
}

/// `OCN,ROWS` for `bench net --lanes`.
fn parse_lanes(s: &str) -> std::result::Result<(u32, u32), String> {
    let bad = || format!("expected OCN,ROWS (two whole numbers, e.g. 8,6), got {s:?}");
    let (a, b) = s.split_once(',').ok_or_else(bad)?;
    Ok((
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    ))
}

fn net_bench(
    width: u32,
    (w, h): (u32, u32),
    (storage, portable, lanes): (crate::StorageArg, bool, Option<(u32, u32)>),
    repeats: u32,
    json: Option<&PathBuf>,
    opts: &GpuOptions,
) -> Result<()> {
    use relit_engine::net::{
        Backend, NetConfig, NetKernels, Network, RandomParams, Storage, Tensor,
    };
    let gpu = crate::open_gpu(opts)?;
    let storage = storage.resolve(&gpu.caps, Some((w, h)));
    let cfg = NetConfig::paper(width);
    let kernels = match (lanes, portable, storage) {
        (Some(_), true, _) | (Some(_), _, Storage::F16) => {
            anyhow::bail!("--lanes runs the CPU-shaped kernels: fp32 storage, not --portable")
        }
        (Some((ocn, rows)), false, Storage::F32) => NetKernels::with_lanes(&gpu, ocn, rows)?,
        (None, true, _) => NetKernels::with_backend(&gpu, storage, Backend::Portable)?,
        (None, false, _) => NetKernels::new(&gpu, storage)?,
    };
    let net = Network::from_params(kernels, cfg.clone(), &RandomParams(1))?;
    let bufs = net.buffers(h, w)?;
    let x = Tensor::new(&gpu, "input", cfg.in_channels, h, w, storage)?;
    let mut rng = synth::Rng::new(3);
    let input: Vec<f32> = (0..cfg.in_channels * h * w).map(|_| rng.f32()).collect();
    x.upload_chw(&input)?;
    let flops = net.flops(h, w);
    println!("device: {}", gpu.caps.name);
    println!(
        "network: width {width}, {w}x{h}, {storage:?} storage, {:?} kernels, {:.2} GFLOP per inference",
        net.kernels.backend,
        flops * 1e-9
    );
    // Warm-up: lavapipe compiles each shader at its first dispatch.
    let t0 = Instant::now();
    gpu.submit(|cmd| net.record(&mut Graph::new(&gpu, cmd, None), &bufs, &x))??;
    println!(
        "first run (includes shader compilation): {:.2} s",
        t0.elapsed().as_secs_f64()
    );
    let mut totals = Vec::new();
    let mut stages: Vec<(String, Vec<f64>)> = Vec::new();
    for _ in 0..repeats.max(1) {
        let mut timer = Timer::new(&gpu, 64)?;
        gpu.submit(|cmd| net.record(&mut Graph::new(&gpu, cmd, Some(&mut timer)), &bufs, &x))??;
        totals.push(collect_spans(&timer, &mut stages)?);
    }
    let total = median(totals);
    println!("{:<22} {:>10}", "stage", "ms");
    for (label, v) in &stages {
        println!("{:<22} {:>10.1}", label, median(v.clone()));
    }
    println!(
        "total: {:.1} ms per inference, {:.2} GFLOP/s",
        total,
        flops * 1e-9 / (total * 1e-3)
    );
    if let Some(path) = json {
        let doc = serde_json::json!({
            "device": gpu.caps.name,
            "width": width, "res": [w, h], "storage": format!("{storage:?}"),
            "backend": format!("{:?}", net.kernels.backend),
            "gflop": flops * 1e-9, "ms": total, "gflops": flops * 1e-9 / (total * 1e-3),
            "stages_ms": stages.iter().map(|(l, v)| (l.clone(), median(v.clone()))).collect::<std::collections::BTreeMap<_, _>>(),
        });
        relit_engine::scene::write_atomic(path, serde_json::to_string_pretty(&doc)?.as_bytes())?;
    }
    Ok(())
}

/// Adds a run's spans to `stages` (label → ms per run, in first-seen order); returns the
/// run's total ms.
fn collect_spans(timer: &Timer, stages: &mut Vec<(String, Vec<f64>)>) -> Result<f64> {
    let spans = timer.read()?;
    let total = spans.iter().map(|s| s.1).sum::<f64>();
    for (label, ms) in spans {
        match stages.iter_mut().find(|s| s.0 == label) {
            Some(s) => s.1.push(ms),
            None => stages.push((label, vec![ms])),
        }
    }
    Ok(total)
}

fn percentile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[((v.len() - 1) as f64 * q).round() as usize]
}

#[allow(clippy::too_many_arguments)]
/// The viewer's moving frames along `cams` for the chosen `mode` (`Renderer::moving_mode`) at
/// the resolution `view::fluid` settles on (it halves the resolution while a frame misses
/// 8 fps). Returns the median fps over the frames at the final resolution, and that resolution.
fn moving_frames(
    r: &mut relit_engine::frame::Renderer,
    cams: &[relit_engine::scene::Camera],
    light: &relit_engine::frame::Lighting,
    (mode, frames): (relit_engine::frame::Mode, u32),
) -> Result<(f64, (u32, u32))> {
    let moving = r.moving_mode(mode);
    use relit_engine::view::fluid::{moving_res, Fluid, Next, Policy};
    let mut fluid = Fluid::new(Policy::Moving);
    let res = (cams[0].width, cams[0].height);
    r.display_only = true;
    let mut times: Vec<(u32, f64)> = Vec::new();
    // Enough frames for the divisor to settle (at most two halvings), then `frames` more.
    for i in 0..(frames.max(1) as usize + 4) {
        let next = fluid.next(true, false, i as f64);
        let Next::Moving { divisor } = next else {
            unreachable!("the moving policy renders moving frames")
        };
        let (mw, mh) = moving_res(res, divisor);
        let cam = crate::render::rescale(&cams[(i + 1) % cams.len()], mw, mh);
        let t = Instant::now();
        r.render(&cam, light, moving, 1.0, None)?;
        let secs = t.elapsed().as_secs_f64();
        fluid.rendered(next, secs);
        times.push((divisor, secs * 1e3));
    }
    // The divisor of the last frame rendered (the policy may change it after that frame, when
    // no frame at the new one exists yet).
    let last = times.last().map_or(fluid.divisor, |t| t.0);
    let at_last: Vec<f64> = times
        .iter()
        .filter(|(d, _)| *d == last)
        .map(|t| t.1)
        .collect();
    Ok((1e3 / median(at_last), moving_res(res, last)))
}

/// The renderer `relit bench frame` times, with every added light (and the original lights'
/// entries when the preset needs them); with `--width` (`random`), a network of that width
/// with random weights in place of the trained one.
fn bench_renderer(
    gpu: &std::sync::Arc<relit_engine::gpu::Gpu>,
    scene: &relit_engine::scene::Scene,
    args: &crate::render::FrameArgs,
    (w, h): (u32, u32),
    light: &relit_engine::frame::Lighting,
    (random_net, width): (bool, Option<u32>),
) -> Result<(relit_engine::frame::Renderer, relit_engine::frame::Mode)> {
    use relit_engine::frame::{Mode, Renderer};
    use relit_engine::net::{NetConfig, NetKernels, Network, RandomParams};
    let mut used = relit_engine::frame::added_lights(scene);
    used.extend(crate::render::lit(scene, light));
    let (r, mut mode) =
        crate::render::open_renderer(gpu, scene, args, Some((w, h)), Some(used), false)?;
    let r = if let (true, Some(width)) = (random_net, width) {
        let storage = args.storage.resolve(&gpu.caps, Some((w, h)));
        let net = Network::from_params(
            NetKernels::new(gpu, storage)?,
            NetConfig::paper(width),
            &RandomParams(1),
        )?;
        mode = Mode::Network;
        Renderer::new(gpu, r.scene, Some(net), storage)?
    } else {
        r
    };
    Ok((r, mode))
}

/// The benchmark's cameras at `w`×`h`: `frames` + 1 along the synthetic test path when there is
/// one, else the input views.
fn bench_cameras(
    scene: &relit_engine::scene::Scene,
    frames: u32,
    (w, h): (u32, u32),
) -> Result<Vec<relit_engine::scene::Camera>> {
    let path = scene
        .synthetic
        .as_ref()
        .filter(|s| !s.test_path.is_empty())
        .map(|s| scene.root.join(&s.test_path))
        .filter(|p| p.is_file());
    Ok(match &path {
        Some(p) => {
            let cp = relit_engine::scene::path::CameraPath::load(p)?;
            let n = frames.max(1) + 1;
            (0..n)
                .map(|i| {
                    cp.camera_at(
                        cp.start() + (cp.duration() - cp.start()) * i as f32 / n as f32,
                        w,
                        h,
                    )
                })
                .collect()
        }
        None => scene
            .views
            .iter()
            .map(|v| crate::render::rescale(&v.camera, w, h))
            .collect(),
    })
}

/// The network's width and kernels for the benchmark's header line (empty without a network).
fn network_note(r: &relit_engine::frame::Renderer, random_net: bool) -> String {
    match (&r.net, random_net) {
        (Some(n), true) => format!(
            " (random weights, width {}, {:?} kernels)",
            n.config.width, n.kernels.backend
        ),
        (Some(n), false) => format!(
            " (width {}, {:?} kernels)",
            n.config.width, n.kernels.backend
        ),
        _ => String::new(),
    }
}

/// Each pass's GPU times (label → ms per frame), in first-seen order.
type PassTimes = Vec<(String, Vec<f64>)>;

/// Per-pass GPU times, and per-frame GPU and wall times (ms), of `frames` frames along `cams`
/// from the second camera on (the first warmed up).
fn timed_frames(
    gpu: &std::sync::Arc<relit_engine::gpu::Gpu>,
    r: &mut relit_engine::frame::Renderer,
    cams: &[relit_engine::scene::Camera],
    light: &relit_engine::frame::Lighting,
    (mode, frames): (relit_engine::frame::Mode, u32),
) -> Result<(PassTimes, Vec<f64>, Vec<f64>)> {
    let mut stages: PassTimes = Vec::new();
    let (mut totals, mut walls) = (Vec::new(), Vec::new());
    for i in 0..frames.max(1) as usize {
        let cam = &cams[(i + 1) % cams.len()];
        let mut timer = Timer::new(gpu, 64)?;
        let tw = Instant::now();
        r.render(cam, light, mode, 1.0, Some(&mut timer))?;
        walls.push(tw.elapsed().as_secs_f64() * 1e3);
        totals.push(collect_spans(&timer, &mut stages)?);
    }
    Ok((stages, totals, walls))
}

fn frame_bench(
    dir: &std::path::Path,
    ((w, h), frames): ((u32, u32), u32),
    (width, preset): (Option<u32>, Option<&str>),
    json: Option<&PathBuf>,
    fa: &crate::render::FrameArgs,
    opts: &GpuOptions,
) -> Result<()> {
    use relit_engine::frame::Lighting;
    let scene = crate::load_scene(dir)?;
    let gpu = crate::open_gpu(opts)?;
    let mut args = fa.clone();
    // The frame benchmark times the network unless another mode is asked for.
    args.mode = args.mode.or(Some(crate::render::ModeArg::Network));
    let random_net = width.is_some() && args.mode != Some(crate::render::ModeArg::Ulr);
    if random_net {
        if args.weights.is_some() {
            anyhow::bail!("--width gives the network random weights: it takes no --weights");
        }
        args.mode = Some(crate::render::ModeArg::Ulr);
    }
    let light = match preset.or(scene.presets.first().map(|p| p.name.as_str())) {
        Some(p) => Lighting::preset(&scene, p)?,
        None => Lighting::original(&scene),
    };
    let (mut r, mode) = bench_renderer(&gpu, &scene, &args, (w, h), &light, (random_net, width))?;
    // As users' frames: ratio and ULR skip the passes that only feed the network.
    r.display_only = true;
    let cams = bench_cameras(&scene, frames, (w, h))?;
    println!("device: {}", gpu.caps.name);
    println!(
        "scene: {} ({} views), {w}x{h}, mode {mode:?}{}, {:?} storage, {:?} maps",
        dir.display(),
        scene.views.len(),
        network_note(&r, random_net),
        r.storage,
        r.scene.maps.format
    );
    let t0 = Instant::now();
    r.render(&cams[0], &light, mode, 1.0, None)?;
    println!(
        "warm-up frame (includes shader compilation): {:.2} s",
        t0.elapsed().as_secs_f64()
    );
    if r.runs_glossy(mode) {
        let fit = r.refit_glossy()?;
        println!(
            "glossy fit per surface (once per scene, before its first glossy frame): {:.2} s",
            fit.as_secs_f64()
        );
        let sight = r.rebuild_sight_cache(&light)?;
        let (points, lights) = r.sight_cache_size();
        println!(
            "sight cache ({points} points x {lights} lights, once per scene; a light lit later adds its column): {:.2} s",
            sight.as_secs_f64()
        );
    }
    r.render(&cams[1 % cams.len()], &light, mode, 1.0, None)?;
    let plain = r.last_barriers();
    let (stages, totals, walls) = timed_frames(&gpu, &mut r, &cams, &light, (mode, frames))?;
    let spanned = r.last_barriers();
    println!(
        "barriers per frame: {plain}; with the timer's spans: {}",
        spanned.commands
    );
    println!(
        "  (and the G-buffer pass's own {} layout changes, inside it)",
        relit_engine::raster::GbufferPass::LAYOUT_BARRIERS
    );
    println!("{:<22} {:>10} {:>10}", "pass", "median ms", "p95 ms");
    for (label, v) in &stages {
        println!(
            "{:<22} {:>10.2} {:>10.2}",
            label,
            median(v.clone()),
            percentile(v.clone(), 0.95)
        );
    }
    let (gm, gp) = (median(totals.clone()), percentile(totals.clone(), 0.95));
    let (wm, wp) = (median(walls.clone()), percentile(walls.clone(), 0.95));
    println!(
        "GPU total: {gm:.1} ms median, {gp:.1} ms p95 -> {:.2} fps median, {:.2} fps p95",
        1e3 / gm,
        1e3 / gp
    );
    println!(
        "wall (submit to readable): {wm:.1} ms median, {wp:.1} ms p95 -> {:.2} fps median",
        1e3 / wm
    );
    let (moving_fps, (mw, mh)) = moving_frames(&mut r, &cams, &light, (mode, frames))?;
    let moving = r.moving_mode(mode);
    println!("moving: {moving_fps:.1} fps (the viewer's cheap frame: {moving:?} mode at {mw}x{mh}, the resolution it settles on here)");
    println!(
        "still: {:.2} fps (the full frame: {mode:?} mode at {w}x{h}, wall median)",
        1e3 / wm
    );
    if let Some(path) = json {
        let doc = serde_json::json!({
            "moving_fps": moving_fps, "moving_res": [mw, mh], "still_fps": 1e3 / wm,
            "device": gpu.caps.name, "scene": dir.display().to_string(), "res": [w, h],
            "mode": format!("{mode:?}"), "storage": format!("{:?}", r.storage),
            "network_width": r.net.as_ref().map(|n| n.config.width),
            "frames": frames,
            "barriers_per_frame": { "commands": plain.commands, "buffer": plain.buffers,
                "image": plain.images, "memory": plain.memory,
                "commands_with_timer": spanned.commands, "gbuffer_layout": relit_engine::raster::GbufferPass::LAYOUT_BARRIERS },
            "passes_ms_median": stages.iter().map(|(l, v)| (l.clone(), median(v.clone()))).collect::<std::collections::BTreeMap<_, _>>(),
            "gpu_ms": { "median": gm, "p95": gp }, "wall_ms": { "median": wm, "p95": wp },
            "fps": { "median": 1e3 / gm, "p95": 1e3 / gp },
        });
        relit_engine::scene::write_atomic(path, serde_json::to_string_pretty(&doc)?.as_bytes())?;
    }
    Ok(())
}

/// Runs tools/train/bench_torch.py (needs PyTorch: see torch_python) with lavapipe's thread count.
fn torch_bench(width: u32, (w, h): (u32, u32), repeats: u32) -> Result<()> {
    let threads = std::env::var("LP_NUM_THREADS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let script = [
        "tools/train/bench_torch.py",
        concat!(env!("CARGO_MANIFEST_DIR"), "/tools/train/bench_torch.py"),
    ]
    .into_iter()
    .map(PathBuf::from)
    .find(|p| p.exists())
    .ok_or_else(|| {
        anyhow::anyhow!("tools/train/bench_torch.py not found (run from the repository root)")
    })?;
    let python = torch_python();
    let st = std::process::Command::new(&python)
        .arg(&script)
        .args(["--width", &width.to_string(), "--res", &format!("{w}x{h}")])
        .args([
            "--threads",
            &threads.to_string(),
            "--repeats",
            &repeats.max(1).to_string(),
        ])
        .status()
        .map_err(|e| anyhow::anyhow!("running {} {}: {e}", python.display(), script.display()))?;
    if !st.success() {
        anyhow::bail!(
            "{} failed ({st}); it needs PyTorch: run tools/setup.sh (the trainer's environment) or set RELIT_PYTHON",
            script.display()
        );
    }
    Ok(())
}

/// RELIT_PYTHON, else the trainer's environment that tools/setup.sh makes, else python3.
fn torch_python() -> PathBuf {
    if let Some(p) = std::env::var_os("RELIT_PYTHON") {
        return PathBuf::from(p);
    }
    let venv = std::env::var_os("RELIT_TRAIN_VENV")
        .map(PathBuf::from)
        .or_else(|| {
            std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/relit/train-venv"))
        });
    venv.map(|v| v.join("bin/python"))
        .filter(|p| p.exists())
        .unwrap_or_else(|| PathBuf::from("python3"))
}
