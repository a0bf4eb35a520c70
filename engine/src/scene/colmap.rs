//! COLMAP models, binary (`cameras.bin`, `images.bin`: COLMAP's default) or text (`cameras.txt`,
//! `images.txt`), in `sparse/0/`, `sparse/` or the scene directory; photos in `images/`, a mesh
//! beside them. Distorted camera models are refused with the undistorter command to run. COLMAP's camera space and pixel convention are
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

/// A model's encoding: COLMAP writes binary by default, text on export.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Encoding {
    Text,
    Binary,
}

/// The model directory (`sparse/0`, `sparse` or the scene directory) and its encoding; text
/// when a directory holds both.
pub(crate) fn model_dir(dir: &Path) -> Option<(PathBuf, Encoding)> {
    let has = |d: &Path, ext: &str| {
        d.join(format!("cameras.{ext}")).is_file() && d.join(format!("images.{ext}")).is_file()
    };
    [dir.join("sparse/0"), dir.join("sparse"), dir.to_path_buf()]
        .into_iter()
        .find_map(|d| {
            if has(&d, "txt") {
                Some((d, Encoding::Text))
            } else if has(&d, "bin") {
                Some((d, Encoding::Binary))
            } else {
                None
            }
        })
}

/// COLMAP's camera models: name and parameter count, indexed by the binary model id.
const MODELS: &[(&str, usize)] = &[
    ("SIMPLE_PINHOLE", 3),
    ("PINHOLE", 4),
    ("SIMPLE_RADIAL", 4),
    ("RADIAL", 5),
    ("OPENCV", 8),
    ("OPENCV_FISHEYE", 8),
    ("FULL_OPENCV", 12),
    ("FOV", 5),
    ("SIMPLE_RADIAL_FISHEYE", 4),
    ("RADIAL_FISHEYE", 5),
    ("THIN_PRISM_FISHEYE", 12),
    ("RAD_TAN_THIN_PRISM_FISHEYE", 16),
];

/// One camera as the model stores it; `at` says where, for errors ("line 3", "camera 2").
struct RawCamera {
    at: String,
    model: String,
    width: u64,
    height: u64,
    params: Vec<f64>,
}

/// One image as the model stores it.
struct RawImage {
    at: String,
    q: [f64; 4],
    t: [f64; 3],
    camera: u32,
    name: String,
}

struct Intrinsics {
    width: u32,
    height: u32,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
}

/// A camera's pinhole intrinsics. Models with lens distortion are taken when every distortion
/// coefficient is zero (the image is already a pinhole image); otherwise the error gives the
/// exact `colmap image_undistorter` command that writes an undistorted model.
fn intrinsics(file: &Path, dir: &Path, model_dir: &Path, c: &RawCamera) -> Result<Intrinsics> {
    let at = &c.at;
    let Some(&(_, n)) = MODELS.iter().find(|(m, _)| *m == c.model) else {
        let known: Vec<&str> = MODELS.iter().map(|(m, _)| *m).collect();
        return Err(Error::input(
            file,
            format!(
                "{at}: camera model \"{}\" is not one COLMAP writes ({})",
                c.model,
                known.join(", ")
            ),
        ));
    };
    if c.params.len() != n {
        return Err(Error::input(
            file,
            format!(
                "{at}: {} takes {n} parameters, found {}",
                c.model,
                c.params.len()
            ),
        ));
    }
    let p = &c.params;
    // (fx, fy, cx, cy, distortion coefficients) of the models that are a pinhole without them.
    let (f, dist) = match c.model.as_str() {
        "SIMPLE_PINHOLE" | "SIMPLE_RADIAL" | "RADIAL" => ([p[0], p[0], p[1], p[2]], &p[3..]),
        "PINHOLE" | "OPENCV" | "FULL_OPENCV" => ([p[0], p[1], p[2], p[3]], &p[4..]),
        _ => ([0.0; 4], &p[..0]),
    };
    let pinhole = f[0] != 0.0 && dist.iter().all(|&d| d == 0.0);
    if !pinhole || c.model.contains("FISHEYE") || c.model == "FOV" {
        let out = dir.with_file_name(format!(
            "{}-undistorted",
            dir.file_name().unwrap_or_default().to_string_lossy()
        ));
        return Err(Error::input(
            file,
            format!(
                "{at}: camera model {} with lens distortion; relit reads pinhole images. \
                 Undistort them with\n  colmap image_undistorter --image_path {} --input_path {} \
                 --output_path {} --output_type COLMAP\nthen copy the mesh into {} and load that \
                 directory",
                c.model,
                dir.join("images").display(),
                model_dir.display(),
                out.display(),
                out.display()
            ),
        ));
    }
    let size = |v: u64, what: &str| {
        u32::try_from(v)
            .ok()
            .filter(|&v| (1..=super::MAX_IMAGE_DIM).contains(&v))
            .ok_or_else(|| {
                let max = super::MAX_IMAGE_DIM;
                Error::input(file, format!("{at}: {what} {v}; expected 1..={max} pixels"))
            })
    };
    Ok(Intrinsics {
        width: size(c.width, "WIDTH")?,
        height: size(c.height, "HEIGHT")?,
        fx: f[0] as f32,
        fy: f[1] as f32,
        cx: f[2] as f32,
        cy: f[3] as f32,
    })
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

fn read_cameras_txt(file: &Path) -> Result<Vec<(u32, RawCamera)>> {
    let text = super::read_text(file)?;
    let mut cams = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let ln = i + 1;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut t = line.split_whitespace();
        let id: u32 = num(file, ln, "CAMERA_ID", t.next())?;
        let model = t.next().unwrap_or("").to_string();
        let width: u64 = num(file, ln, "WIDTH", t.next())?;
        let height: u64 = num(file, ln, "HEIGHT", t.next())?;
        let params = t
            .map(|p| num(file, ln, "parameter", Some(p)))
            .collect::<Result<_>>()?;
        let at = format!("line {ln}");
        cams.push((
            id,
            RawCamera {
                at,
                model,
                width,
                height,
                params,
            },
        ));
    }
    Ok(cams)
}

fn read_images_txt(file: &Path) -> Result<Vec<RawImage>> {
    let text = super::read_text(file)?;
    // Non-comment lines come in pairs: the image line, then its (possibly empty) 2D points.
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim_start().starts_with('#'))
        .collect();
    let mut out = Vec::new();
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
                    file,
                    format!(
                        "line {}: an image line where line {ln}'s POINTS2D line belongs (COLMAP writes one after each image, empty when it has no points)",
                        j + 1
                    ),
                ));
            }
        }
        k += 1; // skip the POINTS2D line
        let mut t = line.split_whitespace();
        let _id: u32 = num(file, ln, "IMAGE_ID", t.next())?;
        let mut q = [0.0; 4];
        for (v, f) in q.iter_mut().zip(["QW", "QX", "QY", "QZ"]) {
            *v = num(file, ln, f, t.next())?;
        }
        let mut tr = [0.0; 3];
        for (v, f) in tr.iter_mut().zip(["TX", "TY", "TZ"]) {
            *v = num(file, ln, f, t.next())?;
        }
        let camera: u32 = num(file, ln, "CAMERA_ID", t.next())?;
        let name: Vec<&str> = t.collect();
        if name.is_empty() {
            return Err(Error::input(file, format!("line {ln}: missing image NAME")));
        }
        let (at, name) = (format!("line {ln}"), name.join(" "));
        out.push(RawImage {
            at,
            q,
            t: tr,
            camera,
            name,
        });
    }
    Ok(out)
}

/// A little-endian reader over a binary model that names the file and the offset in errors
/// and checks every count against the bytes left before allocating.
struct Bin<'a> {
    file: &'a Path,
    data: &'a [u8],
    pos: usize,
}

impl<'a> Bin<'a> {
    fn new(file: &'a Path, data: &'a [u8]) -> Bin<'a> {
        Bin { file, data, pos: 0 }
    }
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if self.data.len() - self.pos < n {
            return Err(Error::input(
                self.file,
                format!("byte {}: the file ends inside {what}", self.pos),
            ));
        }
        self.pos += n;
        Ok(&self.data[self.pos - n..self.pos])
    }
    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    /// A record count, each record at least `min` bytes: more than the file can hold is an
    /// error, not an allocation.
    fn count(&mut self, what: &str, min: usize) -> Result<usize> {
        let at = self.pos;
        let n = self.u64(what)?;
        let left = (self.data.len() - self.pos) as u64;
        if n > left / min as u64 {
            return Err(Error::input(
                self.file,
                format!("byte {at}: {what} is {n}, more than the {left} bytes left can hold"),
            ));
        }
        Ok(n as usize)
    }
    /// A NUL-terminated UTF-8 string.
    fn cstr(&mut self, what: &str) -> Result<String> {
        let at = self.pos;
        let rest = &self.data[self.pos..];
        let end = rest.iter().position(|&b| b == 0).ok_or_else(|| {
            Error::input(
                self.file,
                format!("byte {at}: {what} has no terminating NUL"),
            )
        })?;
        self.pos += end + 1;
        String::from_utf8(rest[..end].to_vec())
            .map_err(|_| Error::input(self.file, format!("byte {at}: {what} is not UTF-8")))
    }
}

fn read_bin(file: &Path) -> Result<Vec<u8>> {
    super::files::read(file, super::files::FileKind::Binary)
}

fn read_cameras_bin(file: &Path) -> Result<Vec<(u32, RawCamera)>> {
    let data = read_bin(file)?;
    let mut b = Bin::new(file, &data);
    let n = b.count("the number of cameras", 24)?;
    let mut cams = Vec::with_capacity(n);
    for k in 0..n {
        let id = b.u32("a CAMERA_ID")?;
        let model_id = b.u32("a MODEL_ID")?;
        let &(model, np) = MODELS.get(model_id as usize).ok_or_else(|| {
            Error::input(
                file,
                format!(
                    "camera {id}: model id {model_id}; COLMAP's run 0..={}",
                    MODELS.len() - 1
                ),
            )
        })?;
        let (width, height) = (b.u64("a WIDTH")?, b.u64("a HEIGHT")?);
        let params = (0..np)
            .map(|_| b.f64("camera parameters"))
            .collect::<Result<_>>()?;
        let (at, model) = (format!("camera {id} (record {})", k + 1), model.to_string());
        cams.push((
            id,
            RawCamera {
                at,
                model,
                width,
                height,
                params,
            },
        ));
    }
    Ok(cams)
}

fn read_images_bin(file: &Path) -> Result<Vec<RawImage>> {
    let data = read_bin(file)?;
    let mut b = Bin::new(file, &data);
    let n = b.count("the number of images", 77)?;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let id = b.u32("an IMAGE_ID")?;
        let mut q = [0.0; 4];
        for v in &mut q {
            *v = b.f64("a rotation")?;
        }
        let mut t = [0.0; 3];
        for v in &mut t {
            *v = b.f64("a translation")?;
        }
        let camera = b.u32("a CAMERA_ID")?;
        let name = b.cstr("an image NAME")?;
        // The 2D points (x, y as f64, POINT3D_ID as i64): relit does not use them.
        let points = b.count("a number of 2D points", 24)?;
        b.take(points * 24, "2D points")?;
        let at = format!("image {id} (record {})", k + 1);
        out.push(RawImage {
            at,
            q,
            t,
            camera,
            name,
        });
    }
    if b.pos != data.len() {
        let extra = data.len() - b.pos;
        return Err(Error::input(
            file,
            format!("{extra} bytes after the last image"),
        ));
    }
    Ok(out)
}

pub(crate) fn load(dir: &Path, mesh: Option<&Path>) -> Result<Scene> {
    let (model, enc) = model_dir(dir).ok_or_else(|| {
        Error::input(
            dir,
            "no cameras.txt + images.txt or cameras.bin + images.bin",
        )
    })?;
    let ext = if enc == Encoding::Text { "txt" } else { "bin" };
    let cam_file = model.join(format!("cameras.{ext}"));
    let img_file = model.join(format!("images.{ext}"));
    let (raw_cams, images) = match enc {
        Encoding::Text => (read_cameras_txt(&cam_file)?, read_images_txt(&img_file)?),
        Encoding::Binary => (read_cameras_bin(&cam_file)?, read_images_bin(&img_file)?),
    };
    let mut cams = HashMap::new();
    for (id, c) in &raw_cams {
        let k = intrinsics(&cam_file, dir, &model, c)?;
        if cams.insert(*id, k).is_some() {
            return Err(Error::input(
                &cam_file,
                format!("{}: camera {id} defined twice", c.at),
            ));
        }
    }
    let mut views = Vec::with_capacity(images.len());
    for im in images {
        views.push(view(dir, &img_file, &cams, im)?);
    }
    super::capture_scene(
        dir,
        SceneFormat::Colmap,
        views,
        mesh,
        MESH_CANDIDATES,
        &img_file,
    )
}

fn view(dir: &Path, file: &Path, cams: &HashMap<u32, Intrinsics>, im: RawImage) -> Result<View> {
    let [w, x, y, z] = im.q.map(|v| v as f32);
    let quat = Quat::from_xyzw(x, y, z, w);
    if !quat.is_finite() || quat.length() <= 1e-6 {
        let q = im.q;
        return Err(Error::input(
            file,
            format!("{}: quaternion {q:?} is not a rotation", im.at),
        ));
    }
    let k = cams.get(&im.camera).ok_or_else(|| {
        Error::input(
            file,
            format!(
                "{}: image {} uses camera {}, which the cameras file does not define",
                im.at, im.name, im.camera
            ),
        )
    })?;
    Ok(View {
        image: dir.join("images").join(&im.name),
        name: im.name,
        camera: Camera {
            width: k.width,
            height: k.height,
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            rotation: glam::Mat3::from_quat(quat.normalize()),
            translation: Vec3::from(im.t.map(|v| v as f32)),
        },
    })
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
