//! The SIBR layout the paper's authors used: `cameras/bundle.out` (Bundler v0.3),
//! `meshes/recon.ply|obj`, `images/`, and `scene_metadata.txt` listing the images.
//!
//! Bundler cameras look down −Z with +Y up, and image coordinates have their origin at the image
//! centre with y up. Relit converts with `R_cv = diag(1, −1, −1) R_b`, `t_cv = diag(1, −1, −1) t_b`,
//! `fx = fy = f`, `cx = width / 2`, `cy = height / 2` (the centre in continuous pixel units).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};

use super::{json, Camera, Scene, SceneFormat, View};
use crate::error::{Error, Result};

const MESH_CANDIDATES: &[&str] = &[
    "meshes/recon.ply",
    "meshes/recon.obj",
    "meshes/mesh.ply",
    "meshes/mesh.obj",
];
const METADATA: &str = "scene_metadata.txt";

/// Image names and sizes from `scene_metadata.txt`, or from the `images/` folder when absent.
/// An image path and, when the metadata gives it, its size.
type ImageEntry = (PathBuf, Option<(u32, u32)>);

fn image_list(dir: &Path) -> Result<Vec<ImageEntry>> {
    let meta = dir.join(METADATA);
    if meta.is_file() {
        let text = super::read_text(&meta)?;
        let mut out = Vec::new();
        let mut in_list = false;
        for (i, line) in text.lines().enumerate() {
            let l = line.trim();
            if l.starts_with('[') {
                in_list = l == "[list_images]";
                continue;
            }
            if !in_list || l.is_empty() || l.starts_with('<') || l.starts_with('#') {
                continue;
            }
            let t: Vec<&str> = l.split_whitespace().collect();
            if t.len() < 3 {
                return Err(Error::input(
                    &meta,
                    format!(
                        "line {}: expected \"<filename> <width> <height> [near far]\"",
                        i + 1
                    ),
                ));
            }
            let parse = |s: &str, f: &str| {
                s.parse::<u32>().map_err(|_| {
                    Error::input(
                        &meta,
                        format!("line {}: {f} \"{s}\" is not a whole number", i + 1),
                    )
                })
            };
            out.push((
                dir.join("images").join(t[0]),
                Some((parse(t[1], "width")?, parse(t[2], "height")?)),
            ));
        }
        if out.is_empty() {
            return Err(Error::input(&meta, "no [list_images] entries"));
        }
        return Ok(out);
    }
    let images = dir.join("images");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&images)
        .map_err(|e| Error::io(&images, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                ["exr", "png", "jpg", "jpeg", "tif", "tiff"]
                    .contains(&e.to_ascii_lowercase().as_str())
            })
        })
        .collect();
    files.sort();
    Ok(files.into_iter().map(|p| (p, None)).collect())
}

pub(crate) fn load(dir: &Path, mesh: Option<&Path>) -> Result<Scene> {
    let file = dir.join("cameras/bundle.out");
    let text = super::read_text(&file)?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim_start().starts_with('#') && !l.trim().is_empty());
    let mut next_nums = |what: &str, n: usize| -> Result<(usize, Vec<f64>)> {
        let (i, l) = lines
            .next()
            .ok_or_else(|| Error::input(&file, format!("file ends before {what}")))?;
        let v: Vec<f64> = l
            .split_whitespace()
            .map(|t| t.parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| {
                Error::input(&file, format!("line {}: {what}: expected numbers", i + 1))
            })?;
        if v.len() != n {
            return Err(Error::input(
                &file,
                format!(
                    "line {}: {what}: expected {n} numbers, found {}",
                    i + 1,
                    v.len()
                ),
            ));
        }
        Ok((i + 1, v))
    };
    let (_, counts) = next_nums("the camera and point counts", 2)?;
    let ncams = counts[0] as usize;
    let images = image_list(dir)?;
    if images.len() != ncams {
        return Err(Error::input(
            &file,
            format!(
                "bundle.out has {ncams} cameras but {} images are listed ({})",
                images.len(),
                if dir.join(METADATA).is_file() {
                    METADATA
                } else {
                    "images/"
                }
            ),
        ));
    }
    let flip = Mat3::from_diagonal(Vec3::new(1.0, -1.0, -1.0));
    let mut views = Vec::with_capacity(ncams);
    for (k, (img, size)) in images.into_iter().enumerate() {
        let (ln, fk) = next_nums(&format!("camera {k} (f k1 k2)"), 3)?;
        let r: Vec<Vec<f64>> = (0..3)
            .map(|j| next_nums(&format!("camera {k} rotation row {j}"), 3).map(|x| x.1))
            .collect::<Result<_>>()?;
        let (_, t) = next_nums(&format!("camera {k} translation"), 3)?;
        if fk[1].abs() > 1e-9 || fk[2].abs() > 1e-9 {
            return Err(Error::input(
                &file,
                format!(
                    "line {ln}: camera {k} has radial distortion k1={} k2={}; Relit expects undistorted images (k1 = k2 = 0)",
                    fk[1], fk[2]
                ),
            ));
        }
        let (w, h) = match size {
            Some(s) => s,
            None => super::image::image_size(&img)?,
        };
        let rb = Mat3::from_cols(
            Vec3::new(r[0][0] as f32, r[1][0] as f32, r[2][0] as f32),
            Vec3::new(r[0][1] as f32, r[1][1] as f32, r[2][1] as f32),
            Vec3::new(r[0][2] as f32, r[1][2] as f32, r[2][2] as f32),
        );
        let f = fk[0] as f32;
        views.push(View {
            name: img
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned(),
            image: img,
            camera: Camera {
                width: w,
                height: h,
                fx: f,
                fy: f,
                cx: w as f32 * 0.5,
                cy: h as f32 * 0.5,
                rotation: flip * rb,
                translation: flip * Vec3::new(t[0] as f32, t[1] as f32, t[2] as f32),
            },
        });
    }
    super::capture_scene(dir, SceneFormat::Sibr, views, mesh, MESH_CANDIDATES, &file)
}

/// Writes `cameras/bundle.out` and `scene_metadata.txt` for `scene` (square pixels, principal
/// point at the centre: Bundler cannot express anything else). Images go under `dir/images/`.
pub fn write(dir: &Path, scene: &Scene) -> Result<()> {
    let cams = dir.join("cameras");
    std::fs::create_dir_all(&cams).map_err(|e| Error::io(&cams, e))?;
    let flip = Mat3::from_diagonal(Vec3::new(1.0, -1.0, -1.0));
    let mut b = format!("# Bundle file v0.3\n{} 0\n", scene.views.len());
    let mut meta = String::from(
        "Scene Metadata File\n\n[list_images]\n<filename> <image_width> <image_height> <near_clipping_plane> <far_clipping_plane>\n",
    );
    for v in &scene.views {
        let c = &v.camera;
        if (c.fx - c.fy).abs() > 1e-4 * c.fx
            || (c.cx - c.width as f32 * 0.5).abs() > 1e-3
            || (c.cy - c.height as f32 * 0.5).abs() > 1e-3
        {
            return Err(Error::input(
                &cams,
                format!(
                    "view {}: Bundler needs fx = fy and a centred principal point",
                    v.name
                ),
            ));
        }
        let r = flip * c.rotation;
        let t = flip * c.translation;
        let _ = writeln!(b, "{} 0 0", c.fx);
        for row in 0..3 {
            let rr = r.row(row);
            let _ = writeln!(b, "{} {} {}", rr.x, rr.y, rr.z);
        }
        let _ = writeln!(b, "{} {} {}", t.x, t.y, t.z);
        let name = v.image.file_name().unwrap_or_default().to_string_lossy();
        let _ = writeln!(meta, "{name} {} {} 0.05 100", c.width, c.height);
    }
    super::write_atomic(&cams.join("bundle.out"), b.as_bytes())?;
    super::write_atomic(&dir.join(METADATA), meta.as_bytes())?;
    json::write_sidecar(dir, &scene.lights, &scene.presets)
}
