//! `scenegen`: procedural indoor scenes with ground truth (§6).
//!
//! - `scenegen room DIR --seed S`: one scene's description (no renders).
//! - `scenegen batch OUT --count N`: N scenes with their Mitsuba ground truth, for training.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use relit_scenegen::room::RoomOptions;

#[derive(Parser)]
#[command(
    name = "scenegen",
    about = "Procedural indoor scenes with ground truth for Relit"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(clap::Args, Clone)]
struct SceneArgs {
    /// Capture views.
    #[arg(long, default_value_t = 32)]
    views: usize,
    /// Image size WxH.
    #[arg(long, default_value = "256x192", value_parser = parse_res)]
    res: (u32, u32),
    /// Extra lights (one lighting condition each, besides the original lighting).
    #[arg(long, default_value_t = 6)]
    extra_lights: usize,
    /// Views sampled along the test path (ground truth only).
    #[arg(long, default_value_t = 8)]
    test_views: usize,
    /// Capture views aimed at each original light (the first ones; at most half of --views).
    #[arg(long, default_value_t = 3)]
    light_views: usize,
    /// Tints of the extra lights: mild (near white) or mixed (half saturated).
    #[arg(long, value_enum, default_value = "mild")]
    lamp_colours: relit_scenegen::room::LampColours,
    /// Proxy error as a fraction of the default MVS-like degradation (0: the true surfaces).
    #[arg(long, default_value_t = 1.0)]
    proxy_error: f32,
    /// Surfaces: classic (pale plaster walls), varied (coloured walls, a mirror, a lacquered
    /// cabinet), sparse (the varied room untextured, with few objects, matte but the mirror
    /// and cabinet) or matte (the varied room, matte but the mirror and cabinet).
    #[arg(long, value_enum, default_value = "classic")]
    finishes: relit_scenegen::room::Finishes,
}

impl SceneArgs {
    fn options(&self) -> RoomOptions {
        RoomOptions {
            views: self.views,
            width: self.res.0,
            height: self.res.1,
            extra_lights: self.extra_lights,
            test_views: self.test_views,
            light_views: self.light_views,
            lamp_colours: self.lamp_colours,
            proxy_error: self.proxy_error,
            finishes: self.finishes,
        }
    }
}

#[derive(Subcommand)]
enum Cmd {
    /// Write one scene's description: meshes, materials, textures, lights, cameras, test path.
    Room {
        dir: PathBuf,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[command(flatten)]
        args: SceneArgs,
    },
    /// Generate N scenes (seeds seed, seed+1, …) and render their ground truth with Mitsuba 3.
    Batch {
        out: PathBuf,
        #[arg(long, default_value_t = 4)]
        count: u64,
        #[arg(long, default_value_t = 1000)]
        seed: u64,
        /// Samples per pixel of the ground-truth renders.
        #[arg(long, default_value_t = 128)]
        spp: u32,
        #[command(flatten)]
        args: SceneArgs,
    },
}

fn parse_res(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("\"{s}\": expected WxH"))?;
    match (w.parse::<u32>(), h.parse::<u32>()) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 && w <= 16384 && h <= 16384 => Ok((w, h)),
        _ => Err(format!("\"{s}\": expected WxH with sides 1..=16384")),
    }
}

/// `tools/groundtruth/render.py` in this checkout.
pub fn render_script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../groundtruth/render.py")
}

fn render(dir: &Path, spp: u32) -> Result<()> {
    let out = Command::new("python3")
        .arg(render_script())
        .arg(dir)
        .args(["--spp", &spp.to_string()])
        .output()
        .context("running python3 tools/groundtruth/render.py (run tools/setup.sh first)")?;
    if !out.status.success() {
        bail!(
            "ground truth of {} failed:\n{}{}",
            dir.display(),
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok(())
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.cmd {
        Cmd::Room { dir, seed, args } => {
            let s = relit_scenegen::generate(&dir, seed, &args.options())?;
            println!(
                "wrote {} ({} views, {} proxy triangles, {} lights)",
                dir.display(),
                s.views.len(),
                s.mesh.triangles.len(),
                s.lights.len()
            );
        }
        Cmd::Batch {
            out,
            count,
            seed,
            spp,
            args,
        } => {
            let bar = indicatif::ProgressBar::new(count);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{bar:40} {pos}/{len} scenes  {elapsed_precise} elapsed, ETA {eta_precise}  {msg}",
                )
                .unwrap(),
            );
            let t0 = Instant::now();
            for i in 0..count {
                let s = seed + i;
                let dir = out.join(format!("scene_{s:05}"));
                let t = Instant::now();
                relit_scenegen::generate(&dir, s, &args.options())?;
                render(&dir, spp)?;
                bar.set_message(format!("last: {:.1} s", t.elapsed().as_secs_f64()));
                bar.inc(1);
            }
            bar.finish();
            println!(
                "{count} scenes in {:.1} s: {:.1} s per scene ({} views, {}x{}, {spp} spp)",
                t0.elapsed().as_secs_f64(),
                t0.elapsed().as_secs_f64() / count.max(1) as f64,
                args.views,
                args.res.0,
                args.res.1
            );
        }
    }
    Ok(())
}
