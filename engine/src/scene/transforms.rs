//! NeRF-style captures: `transforms.json` as instant-ngp, nerfstudio and most phone capture apps
//! write it. Each frame has a camera-to-world `transform_matrix` in OpenGL camera axes (x right,
//! y up, looking down −z); Relit's cameras are world-to-camera in OpenCV axes (y down, +z
//! forward), so the y and z axes flip. Intrinsics (`fl_x`, `fl_y`, `cx`, `cy`, `w`, `h`, or
//! instant-ngp's `camera_angle_x`) are shared at the top level or given per frame; pixel centres
//! sit at +½ in both conventions. Distortion keys must be zero (undistort first); `aabb_scale`
//! and other training settings are ignored. The mesh is nerfstudio's `ply_file_path` when that
//! holds faces, else `mesh.ply` / `mesh.obj` beside the file.

use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};
use serde_json::{Map, Value};

use super::{Camera, Scene, SceneFormat, View};
use crate::error::{Error, Result};

pub(crate) const FILE: &str = "transforms.json";
const MESH_CANDIDATES: &[&str] = &["mesh.ply", "mesh.obj"];
const DISTORTION: &[&str] = &["k1", "k2", "k3", "k4", "p1", "p2"];
/// Camera models that are a pinhole once their distortion keys are zero.
const PINHOLE_MODELS: &[&str] = &["OPENCV", "PINHOLE", "SIMPLE_PINHOLE"];

/// A number under `key` in the frame, else at the top level.
fn number(
    file: &Path,
    at: &str,
    frame: &Map<String, Value>,
    top: &Map<String, Value>,
    key: &str,
) -> Result<Option<f64>> {
    match frame.get(key).or_else(|| top.get(key)) {
        None => Ok(None),
        Some(v) => match v.as_f64() {
            Some(x) if x.is_finite() => Ok(Some(x)),
            _ => Err(Error::input(
                file,
                format!("{at}: \"{key}\" is {v}; expected a finite number"),
            )),
        },
    }
}

/// The frame's pinhole intrinsics: (width, height, fx, fy, cx, cy).
fn intrinsics(
    file: &Path,
    at: &str,
    f: &Map<String, Value>,
    top: &Map<String, Value>,
) -> Result<(u32, u32, f32, f32, f32, f32)> {
    let num = |key: &str| number(file, at, f, top, key);
    let need = |key: &str| {
        num(key)?.ok_or_else(|| {
            Error::input(
                file,
                format!("{at}: no \"{key}\" in the frame or at the top level"),
            )
        })
    };
    if let Some(m) = f.get("camera_model").or_else(|| top.get("camera_model")) {
        if !m.as_str().is_some_and(|m| PINHOLE_MODELS.contains(&m)) {
            return Err(Error::input(file, format!(
                "{at}: camera_model {m}; relit reads pinhole images (OPENCV with zero distortion): undistort them first"
            )));
        }
    }
    for key in DISTORTION {
        if num(key)?.is_some_and(|d| d != 0.0) {
            return Err(Error::input(file, format!(
                "{at}: lens distortion \"{key}\" is not zero; relit reads pinhole images: undistort them \
                 (e.g. colmap image_undistorter) and drop the distortion keys"
            )));
        }
    }
    let size = |key: &str| -> Result<u32> {
        let v = need(key)?;
        let max = super::MAX_IMAGE_DIM;
        if v.fract() != 0.0 || !(1.0..=max as f64).contains(&v) {
            return Err(Error::input(
                file,
                format!("{at}: \"{key}\" is {v}; expected a whole number of pixels, 1..={max}"),
            ));
        }
        Ok(v as u32)
    };
    let (w, h) = (size("w")?, size("h")?);
    let fx = match num("fl_x")? {
        Some(fx) => fx,
        None => {
            let angle = num("camera_angle_x")?.ok_or_else(|| {
                Error::input(
                    file,
                    format!("{at}: no focal length: expected \"fl_x\" or \"camera_angle_x\""),
                )
            })?;
            0.5 * w as f64 / (0.5 * angle).tan()
        }
    };
    let fy = match num("fl_y")? {
        Some(fy) => fy,
        None => match num("camera_angle_y")? {
            Some(a) => 0.5 * h as f64 / (0.5 * a).tan(),
            None => fx,
        },
    };
    if !(fx > 0.0 && fy > 0.0 && fx.is_finite() && fy.is_finite()) {
        return Err(Error::input(
            file,
            format!("{at}: focal lengths {fx}, {fy}; expected positive"),
        ));
    }
    let cx = num("cx")?.unwrap_or(w as f64 * 0.5);
    let cy = num("cy")?.unwrap_or(h as f64 * 0.5);
    Ok((w, h, fx as f32, fy as f32, cx as f32, cy as f32))
}

/// Rotation (columns: the camera's right, down, forward in world space) and centre of a
/// camera-to-world matrix in OpenGL axes; refused unless it is a rigid motion.
fn pose(file: &Path, at: &str, f: &Map<String, Value>) -> Result<(Mat3, Vec3)> {
    let bad = || {
        Error::input(
            file,
            format!("{at}: \"transform_matrix\" must be 4 rows of 4 finite numbers (or 3 rows)"),
        )
    };
    let rows = f
        .get("transform_matrix")
        .and_then(Value::as_array)
        .ok_or_else(bad)?;
    if !(3..=4).contains(&rows.len()) {
        return Err(bad());
    }
    let mut m = [[0.0f64; 4]; 3];
    for (r, row) in m.iter_mut().zip(rows) {
        let row = row.as_array().filter(|r| r.len() == 4).ok_or_else(bad)?;
        for (x, v) in r.iter_mut().zip(row) {
            *x = v.as_f64().filter(|x| x.is_finite()).ok_or_else(bad)?;
        }
    }
    let col = |c: usize| Vec3::new(m[0][c] as f32, m[1][c] as f32, m[2][c] as f32);
    let (right, up, back) = (col(0), col(1), col(2));
    let axes = Mat3::from_cols(right, -up, -back);
    let ortho = (axes.transpose() * axes - Mat3::IDENTITY)
        .to_cols_array()
        .iter()
        .all(|e| e.abs() < 1e-3);
    if !ortho || axes.determinant() <= 0.0 {
        return Err(Error::input(file, format!(
            "{at}: \"transform_matrix\" is not a rotation and a translation (scaled or mirrored axes)"
        )));
    }
    Ok((axes, col(3)))
}

/// The image of a frame: `file_path` relative to the file's directory; instant-ngp's synthetic
/// scenes leave the extension off (`./train/r_0` is `train/r_0.png`).
fn image_path(dir: &Path, rel: &str) -> PathBuf {
    let p = dir.join(rel);
    if p.extension().is_none() && !p.exists() {
        return p.with_extension("png");
    }
    p
}

pub(crate) fn load(dir: &Path, mesh: Option<&Path>) -> Result<Scene> {
    let file = dir.join(FILE);
    let doc: Value = super::json::parse(&file)?;
    let top = doc
        .as_object()
        .ok_or_else(|| Error::input(&file, "expected a JSON object"))?;
    let frames = top.get("frames").and_then(Value::as_array).ok_or_else(|| {
        Error::input(
            &file,
            "no \"frames\" array (a transforms.json lists its photos there)",
        )
    })?;
    let mut views = Vec::with_capacity(frames.len());
    for (i, f) in frames.iter().enumerate() {
        let f = f
            .as_object()
            .ok_or_else(|| Error::input(&file, format!("frame {i}: expected an object")))?;
        let rel = f
            .get("file_path")
            .and_then(Value::as_str)
            .ok_or_else(|| Error::input(&file, format!("frame {i}: no \"file_path\" string")))?;
        let at = format!("frame {i} ({rel})");
        let (w, h, fx, fy, cx, cy) = intrinsics(&file, &at, f, top)?;
        let (axes, centre) = pose(&file, &at, f)?;
        let mut camera = Camera::from_camera_to_world(axes, centre, w, h, fx, fy);
        (camera.cx, camera.cy) = (cx, cy);
        let image = image_path(dir, rel);
        let name = image
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        views.push(View {
            name,
            image,
            camera,
        });
    }
    let mut candidates: Vec<&str> = MESH_CANDIDATES.to_vec();
    let ply = top.get("ply_file_path").and_then(Value::as_str);
    match ply {
        _ if mesh.is_some() => {}
        Some(ply) if has_faces(&dir.join(ply)) => candidates.insert(0, ply),
        Some(ply) if super::find_mesh(dir, &candidates).is_err() => {
            return Err(Error::input(&file, format!(
                "ply_file_path {ply} is not a mesh with faces (nerfstudio writes a point cloud there); \
                 put the proxy mesh at {}", MESH_CANDIDATES.join(" or ")
            )))
        }
        _ => {}
    }
    super::capture_scene(
        dir,
        SceneFormat::Transforms,
        views,
        mesh,
        &candidates,
        &file,
    )
}

/// Whether a PLY declares faces (nerfstudio's `ply_file_path` is often a sparse point cloud,
/// which cannot be the proxy mesh). Reads the header only.
fn has_faces(path: &Path) -> bool {
    use std::io::Read;
    if super::files::check(path, super::files::FileKind::Mesh).is_err() {
        return false;
    }
    let mut head = Vec::new();
    let read = std::fs::File::open(path).and_then(|f| f.take(4096).read_to_end(&mut head));
    let head = String::from_utf8_lossy(&head);
    read.is_ok()
        && head
            .lines()
            .take_while(|l| l.trim() != "end_header")
            .any(|l| {
                let f: Vec<&str> = l.split_whitespace().collect();
                f.len() == 3
                    && f[..2] == ["element", "face"]
                    && f[2].parse::<u64>().is_ok_and(|n| n > 0)
            })
}

/// Writes `transforms.json` (per-frame intrinsics, OpenGL camera-to-world matrices) for `scene`,
/// whose images are expected at the paths it names, and its lights sidecar.
pub fn write(dir: &Path, scene: &Scene) -> Result<()> {
    let frames: Vec<Value> = scene
        .views
        .iter()
        .map(|v| {
            let c = &v.camera;
            let axes = c.rotation.transpose();
            let (right, up, back) = (axes.x_axis, -axes.y_axis, -axes.z_axis);
            let p = c.center();
            let row = |k: usize| {
                let a = [right, up, back, p].map(|v| v.to_array()[k] as f64);
                serde_json::json!([a[0], a[1], a[2], a[3]])
            };
            let rel = v.image.strip_prefix(dir).unwrap_or(&v.image);
            serde_json::json!({
                "file_path": rel.to_string_lossy(),
                "w": c.width, "h": c.height,
                "fl_x": c.fx, "fl_y": c.fy, "cx": c.cx, "cy": c.cy,
                "transform_matrix": [row(0), row(1), row(2), [0.0, 0.0, 0.0, 1.0]],
            })
        })
        .collect();
    let mesh = scene
        .mesh_path
        .strip_prefix(dir)
        .unwrap_or(&scene.mesh_path);
    let doc = serde_json::json!({
        "camera_model": "OPENCV",
        "ply_file_path": mesh.to_string_lossy(),
        "frames": frames,
    });
    let text = serde_json::to_string_pretty(&doc).map_err(|e| Error::Other(e.to_string()))?;
    super::write_atomic(&dir.join(FILE), text.as_bytes())?;
    super::json::write_sidecar(dir, &scene.lights, &scene.presets)
}
