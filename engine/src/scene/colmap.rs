//! COLMAP text models: `cameras.txt` and `images.txt` in `sparse/0/` (or the scene directory),
//! photos in `images/`, a mesh beside them. COLMAP's camera space and pixel convention are
//! Relit's own (OpenCV axes, pixel centres at +½), so only the pose parametrisation changes.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glam::{Quat, Vec3};

use super::{json, Camera, Scene, SceneFormat, View};
use crate::error::{Error, Result};

pub(crate) const MESH_CANDIDATES: &[&str] = &[
    "mesh.ply",
    "mesh.obj",
    "meshes/recon.ply",
    "meshes/recon.obj",
];

pub(crate) fn model_dir(dir: &Path) -> Option<PathBuf> {
    [dir.join("sparse/0"), dir.join("sparse"), dir.to_path_buf()]
        .into_iter()
        .find(|d| d.join("cameras.txt").is_file() && d.join("images.txt").is_file())
}

struct Intrinsics {
    width: u32,
    height: u32,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
}

fn num<T: std::str::FromStr>(
    file: &Path,
    line: usize,
    field: &str,
    tok: Option<&str>,
) -> Result<T> {
    let tok = tok.ok_or_else(|| Error::input(file, format!("line {line}: missing {field}")))?;
    tok.parse::<T>().map_err(|_| {
        Error::input(
            file,
            format!("line {line}: {field} \"{tok}\" is not a valid number"),
        )
    })
}

fn parse_cameras(file: &Path) -> Result<HashMap<u32, Intrinsics>> {
    let text = super::read_text(file)?;
    let mut cams = HashMap::new();
    for (i, line) in text.lines().enumerate() {
        let ln = i + 1;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut t = line.split_whitespace();
        let id: u32 = num(file, ln, "CAMERA_ID", t.next())?;
        let model = t.next().unwrap_or("");
        let width: u32 = num(file, ln, "WIDTH", t.next())?;
        let height: u32 = num(file, ln, "HEIGHT", t.next())?;
        let params: Vec<f32> = t
            .map(|p| {
                p.parse::<f32>().map_err(|_| {
                    Error::input(
                        file,
                        format!("line {ln}: parameter \"{p}\" is not a number"),
                    )
                })
            })
            .collect::<Result<_>>()?;
        let need = |n: usize| {
            if params.len() == n {
                Ok(())
            } else {
                Err(Error::input(
                    file,
                    format!(
                        "line {ln}: {model} takes {n} parameters, found {}",
                        params.len()
                    ),
                ))
            }
        };
        let k = match model {
            "PINHOLE" => {
                need(4)?;
                Intrinsics {
                    width,
                    height,
                    fx: params[0],
                    fy: params[1],
                    cx: params[2],
                    cy: params[3],
                }
            }
            "SIMPLE_PINHOLE" => {
                need(3)?;
                Intrinsics {
                    width,
                    height,
                    fx: params[0],
                    fy: params[0],
                    cx: params[1],
                    cy: params[2],
                }
            }
            other => {
                return Err(Error::input(
                    file,
                    format!(
                        "line {ln}: camera model {other} is not supported; expected PINHOLE or \
                         SIMPLE_PINHOLE (undistort the images first, e.g. colmap image_undistorter)"
                    ),
                ))
            }
        };
        if cams.insert(id, k).is_some() {
            return Err(Error::input(
                file,
                format!("line {ln}: camera {id} defined twice"),
            ));
        }
    }
    Ok(cams)
}

pub(crate) fn load(dir: &Path) -> Result<Scene> {
    let model = model_dir(dir).ok_or_else(|| Error::input(dir, "no cameras.txt + images.txt"))?;
    let cam_file = model.join("cameras.txt");
    let img_file = model.join("images.txt");
    let cams = parse_cameras(&cam_file)?;
    let text = super::read_text(&img_file)?;
    // Non-comment lines come in pairs: the image line, then its (possibly empty) 2D points.
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim_start().starts_with('#'))
        .collect();
    let mut views = Vec::new();
    let mut k = 0;
    while k < lines.len() {
        let (i, line) = lines[k];
        k += 1;
        if line.trim().is_empty() {
            continue;
        }
        let ln = i + 1;
        // The POINTS2D line: (X, Y, POINT3D_ID) triples of numbers, possibly none. A line that
        // reads as another image's (10 fields, a name last) means the file has no POINTS2D
        // lines, and skipping it would silently lose every other view.
        if let Some((j, next)) = lines.get(k) {
            let f: Vec<&str> = next.split_whitespace().collect();
            if f.len() == 10 && f[9].parse::<f64>().is_err() {
                return Err(Error::input(
                    &img_file,
                    format!(
                        "line {}: an image line where line {ln}'s POINTS2D line belongs (COLMAP writes one after each image, empty when it has no points)",
                        j + 1
                    ),
                ));
            }
        }
        k += 1; // skip the POINTS2D line
        let mut t = line.split_whitespace();
        let _id: u32 = num(&img_file, ln, "IMAGE_ID", t.next())?;
        let q: Vec<f32> = ["QW", "QX", "QY", "QZ"]
            .iter()
            .map(|f| num(&img_file, ln, f, t.next()))
            .collect::<Result<_>>()?;
        let tr: Vec<f32> = ["TX", "TY", "TZ"]
            .iter()
            .map(|f| num(&img_file, ln, f, t.next()))
            .collect::<Result<_>>()?;
        let cam_id: u32 = num(&img_file, ln, "CAMERA_ID", t.next())?;
        let name: Vec<&str> = t.collect();
        if name.is_empty() {
            return Err(Error::input(
                &img_file,
                format!("line {ln}: missing image NAME"),
            ));
        }
        let name = name.join(" ");
        let quat = Quat::from_xyzw(q[1], q[2], q[3], q[0]);
        if !quat.is_finite() || quat.length() <= 1e-6 {
            return Err(Error::input(
                &img_file,
                format!("line {ln}: quaternion {q:?} is not a rotation"),
            ));
        }
        let k_ = cams.get(&cam_id).ok_or_else(|| {
            Error::input(
                &img_file,
                format!("line {ln}: image {name} uses camera {cam_id}, which cameras.txt does not define"),
            )
        })?;
        views.push(View {
            name: name.clone(),
            image: dir.join("images").join(&name),
            camera: Camera {
                width: k_.width,
                height: k_.height,
                fx: k_.fx,
                fy: k_.fy,
                cx: k_.cx,
                cy: k_.cy,
                rotation: glam::Mat3::from_quat(quat.normalize()),
                translation: Vec3::new(tr[0], tr[1], tr[2]),
            },
        });
    }
    super::capture_scene(dir, SceneFormat::Colmap, views, MESH_CANDIDATES, &img_file)
}

/// Writes `sparse/0/{cameras,images}.txt` (one PINHOLE camera per view) for `scene`, whose
/// images are expected under `dir/images/` with the view names as file names.
pub fn write(dir: &Path, scene: &Scene) -> Result<()> {
    let model = dir.join("sparse/0");
    std::fs::create_dir_all(&model).map_err(|e| Error::io(&model, e))?;
    let mut cams = String::from("# Camera list: CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n");
    let mut imgs = String::from(
        "# Image list: IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n# POINTS2D[]\n",
    );
    for (i, v) in scene.views.iter().enumerate() {
        let c = &v.camera;
        let _ = writeln!(
            cams,
            "{} PINHOLE {} {} {} {} {} {}",
            i + 1,
            c.width,
            c.height,
            c.fx,
            c.fy,
            c.cx,
            c.cy
        );
        let q = Quat::from_mat3(&c.rotation);
        let t = c.translation;
        let _ = writeln!(
            imgs,
            "{} {} {} {} {} {} {} {} {} {}\n",
            i + 1,
            q.w,
            q.x,
            q.y,
            q.z,
            t.x,
            t.y,
            t.z,
            i + 1,
            v.name
        );
    }
    super::write_atomic(&model.join("cameras.txt"), cams.as_bytes())?;
    super::write_atomic(&model.join("images.txt"), imgs.as_bytes())?;
    json::write_sidecar(dir, &scene.lights, &scene.presets)
}
