//! `relit dataset`: the training data of §6 in one resumable command. For each seed of two
//! disjoint ranges (training, validation): scenegen's room → Mitsuba's ground truth of every
//! camera and condition → the bake users run → one sample per camera (`relit dump --parts`:
//! lighting kept linear, so the trainer mixes any lighting; tools/train/samples.py).
//!
//! Layout: OUT/scenes/<split>/scene_<seed>/ (the scenes and their bakes) and
//! OUT/<split>/scene_<seed>.<camera>.safetensors. A scene whose ground truth is complete has a
//! `.ground-truth-done` marker; without it the directory is regenerated from scratch. Bakes
//! resume on their own and samples are written atomically, so a killed build continues where
//! it stopped, and never reads a half-written file.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use relit_engine::gpu::GpuOptions;
use relit_engine::scene::Scene;

/// scenes/demo_room's seed (tools/make_demo.sh): never training or validation data.
const DEMO_SEED: u64 = 2;
const DONE: &str = ".ground-truth-done";

#[derive(clap::Args, Clone)]
pub struct DatasetArgs {
    /// Output directory (created; an existing one is continued).
    pub out: PathBuf,
    /// Training scenes: seeds --seed .. --seed + N.
    #[arg(long, default_value_t = 16)]
    pub train: u64,
    /// Validation scenes: seeds --val-seed .. --val-seed + M.
    #[arg(long, default_value_t = 2)]
    pub val: u64,
    #[arg(long, default_value_t = 1000)]
    pub seed: u64,
    #[arg(long, default_value_t = 900_000)]
    pub val_seed: u64,
    /// Capture views per scene.
    #[arg(long, default_value_t = 16)]
    pub views: usize,
    /// Image size WxH of every camera.
    #[arg(long, default_value = "128x96", value_parser = crate::parse_res)]
    pub res: (u32, u32),
    /// Added lights per scene (one ground-truth condition each).
    #[arg(long, default_value_t = 3)]
    pub extra_lights: usize,
    /// Novel cameras along each scene's test path (samples besides the input views).
    #[arg(long, default_value_t = 4)]
    pub test_views: usize,
    /// Capture views aimed at each original light; a list (`3,1,0`) is taken in turn by seed,
    /// so that some rooms' original lights are seen by few views, as in many captures.
    #[arg(long, default_value = "3", value_delimiter = ',', num_args = 1..)]
    pub light_views: Vec<usize>,
    /// Tints of the added lights: `mild` (near white, the datasets before 2026-12-01) or
    /// `mixed` (half of them saturated: red, green, blue, warm, cold).
    #[arg(long, value_enum, default_value = "mixed")]
    pub lamp_colours: relit_scenegen::room::LampColours,
    /// How far each room's proxy is from its true geometry, as a fraction of scenegen's
    /// MVS-like degradation (0: the true surfaces, as in rooms written by hand); a list
    /// (`1,0.5,0`) is taken in turn after `--light-views`: room k has light_views[k mod a] and
    /// proxy_error[(k div a) mod b], so every pair occurs.
    #[arg(long, default_value = "1", value_delimiter = ',', num_args = 1..)]
    pub proxy_error: Vec<f32>,
    /// Each room's surfaces (scenegen's `--finishes`); a list (`classic,varied`) is taken in
    /// turn by seed, as `--light-views` is (lists of coprime lengths give every combination).
    #[arg(long, value_enum, default_value = "classic", value_delimiter = ',', num_args = 1..)]
    pub finishes: Vec<relit_scenegen::room::Finishes>,
    /// Samples per pixel of the ground truth.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Bake quality of every scene (the one the shipped network is run with).
    #[arg(long, value_enum, default_value = "preview")]
    pub quality: crate::Quality,
    /// Denoise the targets with Intel Open Image Denoise (render.py --denoise): at 64 spp the
    /// glossy part gains ~4 dB, about what 256 spp gives, for ~3% more time. Off by default so
    /// that datasets built before it stay consistent; a scene's ground truth records the choice.
    #[arg(long)]
    pub denoise: bool,
    /// Denoise the input photographs too (render.py --denoise-photos): a camera's photo has none
    /// of the path tracer's fireflies, which caustics scatter over a 64 spp image and which the
    /// ratio composite carries into every relit frame. A scene's ground truth records it.
    #[arg(long)]
    pub denoise_photos: bool,
}

/// One scene of the dataset.
struct Job {
    split: &'static str,
    seed: u64,
}

pub fn run(a: &DatasetArgs, opts: &GpuOptions) -> Result<()> {
    let jobs = jobs(a)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let t0 = Instant::now();
    // Seconds of the scenes built from scratch this run: what the ETA extrapolates.
    let mut full: Vec<f64> = Vec::new();
    for (k, job) in jobs.iter().enumerate() {
        let t = Instant::now();
        let fresh = !scene_dir(a, job).join(DONE).exists();
        scene_job(a, opts, job)?;
        let secs = t.elapsed().as_secs_f64();
        if fresh {
            full.push(secs);
        }
        let left = jobs[k + 1..]
            .iter()
            .filter(|j| !scene_dir(a, j).join(DONE).exists())
            .count();
        let eta = match (full.is_empty(), left) {
            (_, 0) => String::new(),
            (true, _) => ", ETA after the first new scene".to_string(),
            (false, n) => {
                let mean = full.iter().sum::<f64>() / full.len() as f64;
                format!(", ETA {:.0} min", mean * n as f64 / 60.0)
            }
        };
        println!(
            "dataset: {}/{} scenes ({:.0}%), scene_{:05} ({}) in {secs:.0} s{eta}",
            k + 1,
            jobs.len(),
            100.0 * (k + 1) as f64 / jobs.len() as f64,
            job.seed,
            job.split,
        );
    }
    let samples = count_samples(&a.out)?;
    println!(
        "dataset {}: {} training and {} validation samples, {:.1} MB on disk, {:.0} s",
        a.out.display(),
        samples.0,
        samples.1,
        dir_size(&a.out) as f64 / 1e6,
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The scenes to build, checked: disjoint seed ranges, without the demo's seed.
fn jobs(a: &DatasetArgs) -> Result<Vec<Job>> {
    let train = a.seed
        ..a.seed
            .checked_add(a.train)
            .context("--seed + --train overflows")?;
    let val = a.val_seed
        ..a.val_seed
            .checked_add(a.val)
            .context("--val-seed + --val overflows")?;
    if train.start < val.end && val.start < train.end {
        bail!("training seeds {train:?} and validation seeds {val:?} overlap: choose --val-seed");
    }
    if train.contains(&DEMO_SEED) || val.contains(&DEMO_SEED) {
        bail!("seed {DEMO_SEED} is the demo scene's: choose --seed/--val-seed past it");
    }
    if a.train == 0 {
        bail!("--train 0: a dataset needs training scenes");
    }
    if let Some(e) = a.proxy_error.iter().find(|e| !(0.0..=1.0).contains(*e)) {
        bail!("--proxy-error {e}: each value must be between 0 (true surfaces) and 1");
    }
    let split =
        |s: &'static str, r: std::ops::Range<u64>| r.map(move |seed| Job { split: s, seed });
    Ok(split("train", train).chain(split("val", val)).collect())
}

fn scene_dir(a: &DatasetArgs, job: &Job) -> PathBuf {
    a.out
        .join("scenes")
        .join(job.split)
        .join(format!("scene_{:05}", job.seed))
}

/// Builds what is missing of one scene.
fn scene_job(a: &DatasetArgs, opts: &GpuOptions, job: &Job) -> Result<()> {
    let name = format!("scene_{:05}", job.seed);
    let dir = scene_dir(a, job);
    if !dir.join(DONE).exists() {
        ground_truth(a, &dir, job.seed)?;
    }
    // The marker says how the ground truth was made: one dataset never mixes two kinds.
    let made = std::fs::read_to_string(dir.join(DONE)).unwrap_or_default();
    if made.trim() != marker(a) {
        bail!(
            "{}: its ground truth was made {}; this run asks for {} (use the same options, or \
             another OUT)",
            dir.display(),
            describe_marker(made.trim()),
            describe_marker(&marker(a))
        );
    }
    let scene = Scene::load(&dir)?;
    let samples = a.out.join(job.split);
    std::fs::create_dir_all(&samples).with_context(|| format!("creating {}", samples.display()))?;
    let cams = cameras(&scene);
    let todo: Vec<&String> = cams
        .iter()
        .filter(|c| !sample_file(&samples, &name, c).exists())
        .collect();
    if todo.is_empty() {
        return Ok(());
    }
    let mut p = crate::quality_params(a.quality);
    p.compress = false;
    crate::bake(&dir, &p, "all", false, opts)?;
    let frame = crate::render::FrameArgs {
        weights: None,
        mode: None,
        quality: Some(a.quality),
        storage: crate::StorageArg::F32,
        maps: crate::render::MapsArg::Rgba16f,
        exposure: 1.0,
    };
    for cam in todo {
        let out = sample_file(&samples, &name, cam);
        let req = crate::render::DumpRequest {
            camera: cam,
            preset: None,
            out: &out,
            keep_view: false,
            parts: true,
        };
        crate::render::dump(opts, &dir, &req, &frame)?;
    }
    Ok(())
}

/// scenegen's room and Mitsuba's ground truth, from scratch, then the marker.
fn ground_truth(a: &DatasetArgs, dir: &Path, seed: u64) -> Result<()> {
    if dir.exists() {
        std::fs::remove_dir_all(dir).with_context(|| format!("removing {}", dir.display()))?;
    }
    let o = relit_scenegen::room::RoomOptions {
        views: a.views,
        width: a.res.0,
        height: a.res.1,
        extra_lights: a.extra_lights,
        test_views: a.test_views,
        light_views: a.light_views[(seed % a.light_views.len() as u64) as usize],
        lamp_colours: a.lamp_colours,
        proxy_error: proxy_error(a, seed),
        finishes: a.finishes[(seed % a.finishes.len() as u64) as usize],
    };
    relit_scenegen::generate(dir, seed, &o)?;
    let script = crate::tools_dir().join("groundtruth/render.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg(dir)
        .args(["--spp", &a.spp.to_string()])
        .args(a.denoise.then_some("--denoise"))
        .args(a.denoise_photos.then_some("--denoise-photos"))
        .output()
        .with_context(|| format!("running python3 {} (run tools/setup.sh)", script.display()))?;
    if !out.status.success() {
        bail!(
            "ground truth of {} failed:\n{}",
            dir.display(),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    std::fs::write(dir.join(DONE), marker(a))?;
    Ok(())
}

/// The proxy error of room `seed`: the list is walked once per full turn of `--light-views`.
fn proxy_error(a: &DatasetArgs, seed: u64) -> f32 {
    let turn = seed / a.light_views.len() as u64;
    a.proxy_error[(turn % a.proxy_error.len() as u64) as usize]
}

/// What the ground-truth marker holds: "denoised" or empty (raw targets, as datasets before
/// `--denoise`), then " mixed-lamps" when the added lights' tints were drawn `mixed`, then
/// " photos-denoised" with `--denoise-photos`.
fn marker(a: &DatasetArgs) -> String {
    let mut m = if a.denoise { "denoised" } else { "" }.to_string();
    if a.lamp_colours == relit_scenegen::room::LampColours::Mixed {
        m.push_str(" mixed-lamps");
    }
    if a.denoise_photos {
        m.push_str(" photos-denoised");
    }
    m.trim().to_string()
}

fn describe_marker(m: &str) -> String {
    let targets = if m.split(' ').any(|w| w == "denoised") {
        "with denoised targets (--denoise)"
    } else {
        "with raw targets (no --denoise)"
    };
    let lamps = if m.split(' ').any(|w| w == "mixed-lamps") {
        "--lamp-colours mixed"
    } else {
        "--lamp-colours mild"
    };
    let photos = if m.split(' ').any(|w| w == "photos-denoised") {
        "denoised photographs (--denoise-photos)"
    } else {
        "raw photographs"
    };
    format!("{targets}, {lamps} and {photos}")
}

/// Every camera with ground truth: the input views (each left out of its own inputs) and the
/// test path's cameras.
fn cameras(scene: &Scene) -> Vec<String> {
    let mut c: Vec<String> = scene.views.iter().map(|v| v.name.clone()).collect();
    if let Some(s) = &scene.synthetic {
        c.extend(s.test_views.iter().map(|t| t.name.clone()));
    }
    c
}

fn sample_file(dir: &Path, scene: &str, cam: &str) -> PathBuf {
    dir.join(format!("{scene}.{cam}.safetensors"))
}

fn count_samples(out: &Path) -> Result<(usize, usize)> {
    let n = |s: &str| -> usize {
        std::fs::read_dir(out.join(s)).map_or(0, |d| {
            d.filter_map(|e| e.ok())
                .filter(|e| e.file_name().to_string_lossy().ends_with(".safetensors"))
                .count()
        })
    };
    Ok((n("train"), n("val")))
}

fn dir_size(p: &Path) -> u64 {
    let Ok(md) = std::fs::symlink_metadata(p) else {
        return 0;
    };
    if !md.is_dir() {
        return md.len();
    }
    std::fs::read_dir(p).map_or(0, |d| {
        d.filter_map(|e| e.ok()).map(|e| dir_size(&e.path())).sum()
    })
}
