//! Scenes: calibrated views, a proxy mesh, lights and lighting presets, loaded from Relit's
//! `scene.json`, a COLMAP model (binary or text), the SIBR/Bundler layout of the paper's authors,
//! or a NeRF-style `transforms.json`.
//! Every loader converts cameras to the one convention of [`camera`].

pub mod camera;
mod colmap;
pub mod coverage;
pub mod exposure;
pub mod files;
pub mod image;
mod json;
pub mod mesh;
pub mod meshproc;
pub mod path;
mod sibr;
pub mod synth;
mod transforms;
mod validate;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::Vec3;

pub use camera::{Camera, GpuCamera};
pub use coverage::{light_coverage, LightCoverage, MIN_VIEWS_PER_LIGHT};
pub use image::{Photo, RgbImage};
pub use json::{
    write_lights, CameraDoc, ConditionDoc, MaterialDoc, ObjectDoc, Synthetic, TestViewDoc,
    SCENE_FILE,
};
pub use mesh::Mesh;

use crate::error::{Error, Result};

/// Largest accepted image side, in pixels.
pub const MAX_IMAGE_DIM: u32 = 16384;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneFormat {
    Relit,
    Colmap,
    Sibr,
    /// instant-ngp / nerfstudio `transforms.json`.
    Transforms,
}

impl std::fmt::Display for SceneFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SceneFormat::Relit => "relit scene.json",
            SceneFormat::Colmap => "COLMAP",
            SceneFormat::Sibr => "SIBR (Bundler)",
            SceneFormat::Transforms => "transforms.json (instant-ngp, nerfstudio)",
        })
    }
}

/// One input photograph and its camera.
#[derive(Clone, Debug)]
pub struct View {
    pub name: String,
    pub image: PathBuf,
    pub camera: Camera,
}

#[derive(Clone, Debug, PartialEq)]
pub enum LightShape {
    /// A parallelogram: `corner`, `corner + edge_u`, `corner + edge_v`, `corner + edge_u + edge_v`;
    /// it emits on the side of `edge_u × edge_v`.
    Quad {
        corner: Vec3,
        edge_u: Vec3,
        edge_v: Vec3,
    },
    /// A disk emitting on the side of `normal`.
    Disk {
        center: Vec3,
        normal: Vec3,
        radius: f32,
    },
}

impl LightShape {
    /// What is wrong with the shape's numbers, if anything: positions and edges finite, a quad
    /// of non-zero area, a disk with a positive finite radius and a non-zero normal.
    pub fn check(&self) -> std::result::Result<(), String> {
        let finite = |n: &str, v: Vec3| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(format!("{n} {v} must be finite"))
            }
        };
        match self {
            LightShape::Quad {
                corner,
                edge_u,
                edge_v,
            } => {
                finite("corner", *corner)?;
                finite("edge_u", *edge_u)?;
                finite("edge_v", *edge_v)?;
                if edge_u.cross(*edge_v).length() <= 1e-12 {
                    return Err("edge_u and edge_v span no area (zero or parallel)".into());
                }
            }
            LightShape::Disk {
                center,
                normal,
                radius,
            } => {
                finite("center", *center)?;
                finite("normal", *normal)?;
                if normal.length() <= 1e-12 {
                    return Err("normal is zero; expected the direction the disk emits to".into());
                }
                if !(radius.is_finite() && *radius > 0.0) {
                    return Err(format!(
                        "radius {radius}; expected a positive finite number"
                    ));
                }
            }
        }
        Ok(())
    }

    pub fn area(&self) -> f32 {
        match self {
            LightShape::Quad { edge_u, edge_v, .. } => edge_u.cross(*edge_v).length(),
            LightShape::Disk { radius, .. } => std::f32::consts::PI * radius * radius,
        }
    }
    pub fn center(&self) -> Vec3 {
        match self {
            LightShape::Quad {
                corner,
                edge_u,
                edge_v,
            } => *corner + 0.5 * (*edge_u + *edge_v),
            LightShape::Disk { center, .. } => *center,
        }
    }
    /// Unit normal of the emitting side.
    pub fn normal(&self) -> Vec3 {
        match self {
            LightShape::Quad { edge_u, edge_v, .. } => edge_u.cross(*edge_v).normalize_or_zero(),
            LightShape::Disk { normal, .. } => normal.normalize_or_zero(),
        }
    }
    /// The centres of an `n × n` grid of cells on the light: on a quad its parameter grid, on
    /// a disk the same grid through the concentric (Shirley–Chiu) square-to-disk map.
    pub fn grid_points(&self, n: usize) -> Vec<Vec3> {
        let cells = (0..n * n).map(|k| {
            let s = ((k % n) as f32 + 0.5) / n as f32;
            let t = ((k / n) as f32 + 0.5) / n as f32;
            (s, t)
        });
        match self {
            LightShape::Quad {
                corner,
                edge_u,
                edge_v,
            } => cells
                .map(|(s, t)| *corner + s * *edge_u + t * *edge_v)
                .collect(),
            LightShape::Disk {
                center,
                normal,
                radius,
            } => {
                let n = normal.normalize_or_zero();
                let (t1, t2) = n.any_orthonormal_pair();
                cells
                    .map(|(s, t)| {
                        let (a, b) = (2.0 * s - 1.0, 2.0 * t - 1.0);
                        let (r, phi) = if a == 0.0 && b == 0.0 {
                            (0.0, 0.0)
                        } else if a.abs() > b.abs() {
                            (a, std::f32::consts::FRAC_PI_4 * (b / a))
                        } else {
                            (
                                b,
                                std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (a / b),
                            )
                        };
                        *center + *radius * r * (phi.cos() * t1 + phi.sin() * t2)
                    })
                    .collect()
            }
        }
    }
}

/// An area light with constant emitted radiance (§4.1.3).
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    pub name: String,
    pub shape: LightShape,
    pub radiance: [f32; 3],
    /// Part of the captured (original) lighting rather than a light the user adds.
    pub original: bool,
    /// Found from the photos' clipped pixels (`relit scene find-lights`, Appendix A) rather
    /// than declared: a later search replaces it; editing it is fine.
    pub estimated: bool,
}

impl Light {
    /// The same light moved by `d`.
    pub fn translated(&self, d: Vec3) -> Light {
        let shape = match self.shape {
            LightShape::Quad {
                corner,
                edge_u,
                edge_v,
            } => LightShape::Quad {
                corner: corner + d,
                edge_u,
                edge_v,
            },
            LightShape::Disk {
                center,
                normal,
                radius,
            } => LightShape::Disk {
                center: center + d,
                normal,
                radius,
            },
        };
        Light {
            shape,
            ..self.clone()
        }
    }

    /// The same light scaled about its centre by `f` (its radiance unchanged: a bigger lamp
    /// gives more light).
    pub fn scaled(&self, f: f32) -> Light {
        let c = self.shape.center();
        let shape = match self.shape {
            LightShape::Quad { edge_u, edge_v, .. } => LightShape::Quad {
                corner: c - 0.5 * f * (edge_u + edge_v),
                edge_u: f * edge_u,
                edge_v: f * edge_v,
            },
            LightShape::Disk { normal, radius, .. } => LightShape::Disk {
                center: c,
                normal,
                radius: f * radius,
            },
        };
        Light {
            shape,
            ..self.clone()
        }
    }
}

/// Intensities of the added lights and the dimming of the original lighting, `α_dim` (§4.1.4),
/// and each declared original light's own factor (RGB; 1: as captured), on top of α_dim.
#[derive(Clone, Debug, PartialEq)]
pub struct LightingPreset {
    pub name: String,
    pub dim: f32,
    pub intensities: BTreeMap<String, f32>,
    pub originals: BTreeMap<String, [f32; 3]>,
}

#[derive(Clone, Debug)]
pub struct Scene {
    pub root: PathBuf,
    pub format: SceneFormat,
    pub views: Vec<View>,
    pub mesh_path: PathBuf,
    pub mesh: Mesh,
    /// The exact geometry of a synthetic scene (absent for real captures).
    pub true_mesh_path: Option<PathBuf>,
    pub lights: Vec<Light>,
    pub presets: Vec<LightingPreset>,
    /// Ground-truth description of a synthetic scene (absent for real captures).
    pub synthetic: Option<Synthetic>,
}

impl Scene {
    /// Loads a scene directory in whichever format it holds (or a `scene.json` path).
    pub fn load(path: &Path) -> Result<Scene> {
        Scene::load_with_mesh(path, None)
    }

    /// [`Scene::load`] with `mesh`, when given, as the proxy instead of the one the scene
    /// names or keeps beside its views (`relit --mesh`: a mesh made by another tool).
    pub fn load_with_mesh(path: &Path, mesh: Option<&Path>) -> Result<Scene> {
        if path.is_file() && path.file_name().is_some_and(|n| n == SCENE_FILE) {
            return json::load(path.parent().unwrap_or(Path::new(".")), mesh);
        }
        if !path.is_dir() {
            return Err(Error::input(
                path,
                format!("not a scene directory: {}", files::describe_missing(path)),
            ));
        }
        match detect(path) {
            Some(SceneFormat::Relit) => json::load(path, mesh),
            Some(SceneFormat::Colmap) => colmap::load(path, mesh),
            Some(SceneFormat::Sibr) => sibr::load(path, mesh),
            Some(SceneFormat::Transforms) => transforms::load(path, mesh),
            None => Err(Error::input(
                path,
                format!(
                    "no scene found: expected {SCENE_FILE}, a COLMAP model (cameras.bin + images.bin \
                     or cameras.txt + images.txt, in sparse/0/, sparse/ or the directory), or \
                     SIBR's cameras/bundle.out, or a transforms.json (instant-ngp, nerfstudio)"
                ),
            )),
        }
    }

    /// The views' photos as radiance on one scale: each decoded (8-bit ones from sRGB) and
    /// multiplied by its exposure scale from EXIF ([`exposure::scales`]).
    pub fn view_images(&self) -> Result<Vec<RgbImage>> {
        Ok(self.view_photos()?.into_iter().map(|p| p.image).collect())
    }

    /// The views' photos on one radiance scale (EXIF exposure), with their clipped pixels.
    pub fn view_photos(&self) -> Result<Vec<Photo>> {
        let scales = exposure::scales(&self.views)?;
        (0..self.views.len())
            .map(|j| self.view_photo(j, scales[j]))
            .collect()
    }

    /// The scale of each view's photo onto one radiance scale (EXIF exposure).
    pub fn photo_scales(&self) -> Result<Vec<f32>> {
        exposure::scales(&self.views)
    }

    /// View `j`'s photo times `scale` (from [`Scene::photo_scales`]): one photo at a time,
    /// where a capture's photos would not all fit.
    pub fn view_photo(&self, j: usize, scale: f32) -> Result<Photo> {
        let mut photo = image::load_photo(&self.views[j].image)?;
        if scale != 1.0 {
            (photo.image.pixels.iter_mut().flatten()).for_each(|c| *c *= scale);
        }
        Ok(photo)
    }

    /// Loads every image and checks it against its camera (size, finite values).
    pub fn check_images(&self) -> Result<()> {
        for v in &self.views {
            let (w, h) = image::image_size(&v.image)?;
            if (w, h) != (v.camera.width, v.camera.height) {
                return Err(Error::input(
                    &v.image,
                    format!(
                        "image is {w}x{h} but its camera (view {}) says {}x{}",
                        v.name, v.camera.width, v.camera.height
                    ),
                ));
            }
            image::load_rgb(&v.image)?;
        }
        exposure::scales(&self.views)?;
        Ok(())
    }

    /// Writes the lights and presets back where this scene's format keeps them (scene.json, or
    /// lights.json beside a COLMAP, SIBR or transforms.json capture).
    pub fn save_lights(&self) -> Result<()> {
        match self.format {
            SceneFormat::Relit => json::write_lights(&self.root, &self.lights, &self.presets),
            _ => json::write_sidecar(&self.root, &self.lights, &self.presets),
        }
    }

    pub fn preset(&self, name: &str) -> Option<&LightingPreset> {
        self.presets.iter().find(|p| p.name == name)
    }

    /// The names of the added lights some lighting preset lights (intensity not zero).
    pub fn preset_lights(&self) -> Vec<String> {
        let mut v: Vec<String> = (self.presets.iter())
            .flat_map(|p| p.intensities.iter().filter(|(_, &i)| i != 0.0))
            .map(|(n, _)| n.clone())
            .collect();
        v.sort();
        v.dedup();
        v
    }
}

/// Writes `scene`'s cameras, lights and presets in `format` under `dir` (images and mesh are
/// expected to be there already, at the paths the scene names).
pub fn write_scene(dir: &Path, scene: &Scene, format: SceneFormat) -> Result<()> {
    match format {
        SceneFormat::Relit => json::write(dir, scene),
        SceneFormat::Colmap => colmap::write(dir, scene),
        SceneFormat::Sibr => sibr::write(dir, scene),
        SceneFormat::Transforms => transforms::write(dir, scene),
    }
}

/// Which format a directory holds.
pub fn detect(dir: &Path) -> Option<SceneFormat> {
    if dir.join(SCENE_FILE).is_file() {
        Some(SceneFormat::Relit)
    } else if colmap::model_dir(dir).is_some() {
        Some(SceneFormat::Colmap)
    } else if dir.join("cameras/bundle.out").is_file() {
        Some(SceneFormat::Sibr)
    } else if dir.join(transforms::FILE).is_file() {
        Some(SceneFormat::Transforms)
    } else {
        None
    }
}

/// The temp file beside `path` that [`write_atomic`] renames into place.
pub fn temp_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".{}.tmp", std::process::id()));
    path.with_file_name(name)
}

/// Writes a file so that readers never see it half-written: temp file, fsync, rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let tmp = temp_path(path);
    let res = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if res.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    res.map_err(|e| Error::io(path, e))
}

/// Reads a text file, naming it in the error.
pub(crate) fn read_text(path: &Path) -> Result<String> {
    let bytes = files::read(path, files::FileKind::Text)?;
    String::from_utf8(bytes).map_err(|_| Error::input(path, "file is not valid UTF-8 text"))
}

/// A capture from its views: `mesh` or else the mesh beside them, lights and presets from the
/// `lights.json` sidecar, validated against `file` (the camera file, named in errors).
pub(crate) fn capture_scene(
    dir: &Path,
    format: SceneFormat,
    views: Vec<View>,
    mesh: Option<&Path>,
    mesh_candidates: &[&str],
    file: &Path,
) -> Result<Scene> {
    let mesh_path = match mesh {
        Some(m) => m.to_path_buf(),
        None => find_mesh(dir, mesh_candidates)?,
    };
    let (lights, presets) = json::load_sidecar(dir)?;
    let scene = Scene {
        root: dir.to_path_buf(),
        format,
        views,
        mesh: Mesh::load(&mesh_path)?,
        mesh_path,
        true_mesh_path: None,
        synthetic: None,
        lights,
        presets,
    };
    scene.validate(file)?;
    Ok(scene)
}

/// The mesh file of a capture: the first of `candidates` (relative to `dir`) that exists.
pub(crate) fn find_mesh(dir: &Path, candidates: &[&str]) -> Result<PathBuf> {
    candidates
        .iter()
        .map(|c| dir.join(c))
        .find(|p| p.is_file())
        .ok_or_else(|| {
            Error::input(
                dir,
                format!("no mesh found; expected one of {}", candidates.join(", ")),
            )
        })
}
