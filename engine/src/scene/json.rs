//! Relit's own scene format, `scene.json` (schema in docs/formats.md). Also the `lights.json`
//! sidecar that gives lights and presets to COLMAP and SIBR captures.

use std::collections::BTreeMap;
use std::path::Path;

use glam::{Mat3, Vec3};
use serde::{Deserialize, Serialize};

use super::{Camera, Light, LightShape, LightingPreset, Mesh, Scene, SceneFormat, View};
use crate::error::{Error, Result};

pub const SCENE_FILE: &str = "scene.json";
pub const LIGHTS_FILE: &str = "lights.json";

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SceneDoc {
    pub version: u32,
    pub mesh: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub true_mesh: Option<String>,
    pub views: Vec<ViewDoc>,
    #[serde(default)]
    pub lights: Vec<LightDoc>,
    #[serde(default)]
    pub presets: Vec<PresetDoc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub synthetic: Option<Synthetic>,
}

/// What a synthetic scene adds to the format (`tools/scenegen` writes it, `tools/groundtruth`
/// renders it): the true objects and materials, the lighting conditions, the test views and
/// where their ground truth lives. Real captures have none of this. Every field may be left out
/// (a hand-written scene often gives only `test_views` and `ground_truth`); what needs a field
/// says so when it is missing.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Synthetic {
    #[serde(default)]
    pub seed: u64,
    /// The true geometry, one mesh per material assignment.
    #[serde(default)]
    pub objects: Vec<ObjectDoc>,
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialDoc>,
    /// Lighting conditions: the original one and one per extra light, each a set of lights at
    /// intensity 1 (§6). Their renders mix linearly.
    #[serde(default)]
    pub conditions: Vec<ConditionDoc>,
    /// Novel views sampled along the test path, with ground truth but no input image.
    #[serde(default)]
    pub test_views: Vec<TestViewDoc>,
    /// The test camera path (keyframes), relative to the scene directory ("": none).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub test_path: String,
    /// Ground truth directory: `<dir>/<condition>/<view>.{total,diffuse,glossy}.exr` and
    /// `<dir>/aov/<view>.{albedo,normal,depth}.exr`.
    #[serde(default = "default_ground_truth")]
    pub ground_truth: String,
    /// How the proxy mesh was degraded from the true one.
    #[serde(default)]
    pub proxy: serde_json::Value,
}

fn default_ground_truth() -> String {
    "gt".into()
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectDoc {
    pub name: String,
    pub mesh: String,
    pub material: String,
}

/// `kind`: "diffuse" (Lambertian), "plastic" (Lambertian base under a GGX dielectric coat) or
/// "conductor" (GGX metal). `albedo` is the diffuse reflectance (multiplied by the texture when
/// one is given); `specular` tints the conductor; `roughness` is GGX alpha.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDoc {
    pub kind: String,
    pub albedo: [f32; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub albedo_texture: Option<String>,
    /// Texture repeats per metre of surface (texture coordinates are in metres).
    #[serde(default = "one")]
    pub texture_scale: f32,
    #[serde(default)]
    pub roughness: f32,
    #[serde(default)]
    pub specular: [f32; 3],
}

fn one() -> f32 {
    1.0
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConditionDoc {
    pub name: String,
    pub lights: Vec<String>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TestViewDoc {
    pub name: String,
    pub camera: CameraDoc,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LightsDoc {
    #[serde(default)]
    pub lights: Vec<LightDoc>,
    #[serde(default)]
    pub presets: Vec<PresetDoc>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ViewDoc {
    pub name: String,
    pub image: String,
    pub camera: CameraDoc,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDoc {
    pub width: u32,
    pub height: u32,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    /// Camera centre in world space.
    pub position: [f32; 3],
    /// World-to-camera rotation, row-major: its rows are the camera's right, down and forward
    /// axes in world space. Give this or `look_at`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation: Option<[[f32; 3]; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub look_at: Option<[f32; 3]>,
    /// World up for `look_at` (default +Y).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub up: Option<[f32; 3]>,
}

#[derive(Serialize, Deserialize)]
#[serde(tag = "shape", rename_all = "lowercase", deny_unknown_fields)]
pub(crate) enum LightDoc {
    Quad {
        name: String,
        corner: [f32; 3],
        edge_u: [f32; 3],
        edge_v: [f32; 3],
        radiance: [f32; 3],
        #[serde(default)]
        original: bool,
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        estimated: bool,
    },
    Disk {
        name: String,
        center: [f32; 3],
        normal: [f32; 3],
        radius: f32,
        radiance: [f32; 3],
        #[serde(default)]
        original: bool,
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        estimated: bool,
    },
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PresetDoc {
    pub name: String,
    #[serde(default)]
    pub dim: f32,
    #[serde(default)]
    pub intensities: BTreeMap<String, f32>,
    /// Per declared original light, its factor: one number (grey) or RGB.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub originals: BTreeMap<String, Factor>,
}

/// A light's factor as a document writes it: one number for all channels, or RGB.
#[derive(Clone, Copy, Serialize, Deserialize)]
#[serde(
    untagged,
    expecting = "an original light's factor: one number or [r, g, b]"
)]
pub(crate) enum Factor {
    Grey(f32),
    Rgb([f32; 3]),
}

impl Factor {
    pub fn rgb(self) -> [f32; 3] {
        match self {
            Factor::Grey(v) => [v; 3],
            Factor::Rgb(c) => c,
        }
    }

    /// Grey when the channels agree, so a document keeps what its author wrote.
    pub fn of(c: [f32; 3]) -> Factor {
        if c[0] == c[1] && c[1] == c[2] {
            Factor::Grey(c[0])
        } else {
            Factor::Rgb(c)
        }
    }
}

/// Factors by light name, as RGB.
pub(crate) fn factors(m: &BTreeMap<String, Factor>) -> BTreeMap<String, [f32; 3]> {
    m.iter().map(|(k, v)| (k.clone(), v.rgb())).collect()
}

impl CameraDoc {
    /// The camera this document describes; errors name `file` and `view`.
    pub fn to_camera(&self, file: &Path, view: &str) -> Result<Camera> {
        let bad = |m: &str| Error::input(file, format!("view {view}: camera: {m}"));
        let position = Vec3::from(self.position);
        let rotation = match (&self.rotation, &self.look_at) {
            (Some(r), None) => Mat3::from_cols(r[0].into(), r[1].into(), r[2].into()).transpose(),
            (None, Some(target)) => {
                let up = Vec3::from(self.up.unwrap_or([0.0, 1.0, 0.0]));
                let fwd = Vec3::from(*target) - position;
                if fwd.length() < 1e-9 || fwd.cross(up).length() < 1e-9 * fwd.length() {
                    return Err(bad("look_at equals position or is parallel to up"));
                }
                Camera::look_at(position, (*target).into(), up, 1, 1, 1.0).rotation
            }
            (Some(_), Some(_)) => {
                return Err(bad("give either \"rotation\" or \"look_at\", not both"))
            }
            (None, None) => return Err(bad("missing field \"rotation\" (or \"look_at\")")),
        };
        let cam = Camera {
            width: self.width,
            height: self.height,
            fx: self.fx,
            fy: self.fy,
            cx: self.cx,
            cy: self.cy,
            rotation,
            translation: -(rotation * position),
        };
        // Every way a camera enters (scene.json, test views, `--camera FILE`) is checked alike.
        cam.validate().map_err(|m| bad(&m))?;
        Ok(cam)
    }

    pub fn from_camera(c: &Camera) -> CameraDoc {
        let r = c.rotation.transpose(); // columns of Rᵀ are the rows of R
        CameraDoc {
            width: c.width,
            height: c.height,
            fx: c.fx,
            fy: c.fy,
            cx: c.cx,
            cy: c.cy,
            position: c.center().into(),
            rotation: Some([r.x_axis.into(), r.y_axis.into(), r.z_axis.into()]),
            look_at: None,
            up: None,
        }
    }
}

impl LightDoc {
    pub fn to_light(&self) -> Light {
        match self {
            LightDoc::Quad {
                name,
                corner,
                edge_u,
                edge_v,
                radiance,
                original,
                estimated,
            } => Light {
                name: name.clone(),
                shape: LightShape::Quad {
                    corner: (*corner).into(),
                    edge_u: (*edge_u).into(),
                    edge_v: (*edge_v).into(),
                },
                radiance: *radiance,
                original: *original,
                estimated: *estimated,
            },
            LightDoc::Disk {
                name,
                center,
                normal,
                radius,
                radiance,
                original,
                estimated,
            } => Light {
                name: name.clone(),
                shape: LightShape::Disk {
                    center: (*center).into(),
                    normal: Vec3::from(*normal).normalize_or_zero(),
                    radius: *radius,
                },
                radiance: *radiance,
                original: *original,
                estimated: *estimated,
            },
        }
    }

    pub fn from_light(l: &Light) -> LightDoc {
        match l.shape {
            LightShape::Quad {
                corner,
                edge_u,
                edge_v,
            } => LightDoc::Quad {
                name: l.name.clone(),
                corner: corner.into(),
                edge_u: edge_u.into(),
                edge_v: edge_v.into(),
                radiance: l.radiance,
                original: l.original,
                estimated: l.estimated,
            },
            LightShape::Disk {
                center,
                normal,
                radius,
            } => LightDoc::Disk {
                name: l.name.clone(),
                center: center.into(),
                normal: normal.into(),
                radius,
                radiance: l.radiance,
                original: l.original,
                estimated: l.estimated,
            },
        }
    }
}

fn presets(docs: &[PresetDoc]) -> Vec<LightingPreset> {
    docs.iter()
        .map(|p| LightingPreset {
            name: p.name.clone(),
            dim: p.dim,
            intensities: p.intensities.clone(),
            originals: factors(&p.originals),
        })
        .collect()
}

fn preset_docs(p: &[LightingPreset]) -> Vec<PresetDoc> {
    p.iter()
        .map(|p| PresetDoc {
            name: p.name.clone(),
            dim: p.dim,
            intensities: p.intensities.clone(),
            originals: p
                .originals
                .iter()
                .map(|(k, v)| (k.clone(), Factor::of(*v)))
                .collect(),
        })
        .collect()
}

pub(crate) fn parse<T: for<'a> Deserialize<'a>>(file: &Path) -> Result<T> {
    let text = super::read_text(file)?;
    serde_json::from_str(&text).map_err(|e| Error::input(file, format!("{e}")))
}

pub(crate) fn load(dir: &Path, mesh: Option<&Path>) -> Result<Scene> {
    let file = dir.join(SCENE_FILE);
    let doc: SceneDoc = parse(&file)?;
    if doc.version != 1 {
        return Err(Error::input(
            &file,
            format!("version {}; this Relit reads version 1", doc.version),
        ));
    }
    let mut views = Vec::with_capacity(doc.views.len());
    for v in &doc.views {
        views.push(View {
            name: v.name.clone(),
            image: dir.join(&v.image),
            camera: v.camera.to_camera(&file, &v.name)?,
        });
    }
    let mesh_path = mesh.map_or_else(|| dir.join(&doc.mesh), Path::to_path_buf);
    let scene = Scene {
        root: dir.to_path_buf(),
        format: SceneFormat::Relit,
        views,
        mesh: Mesh::load(&mesh_path)?,
        mesh_path,
        true_mesh_path: doc.true_mesh.as_ref().map(|m| dir.join(m)),
        lights: doc.lights.iter().map(LightDoc::to_light).collect(),
        presets: presets(&doc.presets),
        synthetic: doc.synthetic,
    };
    scene.validate(&file)?;
    Ok(scene)
}

/// Lights and presets from `lights.json` beside a COLMAP or SIBR capture (none if absent).
pub(crate) fn load_sidecar(dir: &Path) -> Result<(Vec<Light>, Vec<LightingPreset>)> {
    let file = dir.join(LIGHTS_FILE);
    if !file.exists() {
        return Ok((Vec::new(), Vec::new()));
    }
    let doc: LightsDoc = parse(&file)?;
    Ok((
        doc.lights.iter().map(LightDoc::to_light).collect(),
        presets(&doc.presets),
    ))
}

pub(crate) fn write_sidecar(dir: &Path, lights: &[Light], p: &[LightingPreset]) -> Result<()> {
    let doc = LightsDoc {
        lights: lights.iter().map(LightDoc::from_light).collect(),
        presets: preset_docs(p),
    };
    let text = serde_json::to_string_pretty(&doc).map_err(|e| Error::Other(e.to_string()))?;
    super::write_atomic(&dir.join(LIGHTS_FILE), text.as_bytes())
}

/// Writes `scene.json` for `scene` (paths made relative to `dir` where possible).
pub fn write(dir: &Path, scene: &Scene) -> Result<()> {
    let rel = |p: &Path| {
        p.strip_prefix(dir)
            .unwrap_or(p)
            .to_string_lossy()
            .replace('\\', "/")
    };
    let doc = SceneDoc {
        version: 1,
        mesh: rel(&scene.mesh_path),
        true_mesh: scene.true_mesh_path.as_deref().map(rel),
        views: scene
            .views
            .iter()
            .map(|v| ViewDoc {
                name: v.name.clone(),
                image: rel(&v.image),
                camera: CameraDoc::from_camera(&v.camera),
            })
            .collect(),
        lights: scene.lights.iter().map(LightDoc::from_light).collect(),
        presets: preset_docs(&scene.presets),
        synthetic: scene.synthetic.clone(),
    };
    let text = serde_json::to_string_pretty(&doc).map_err(|e| Error::Other(e.to_string()))?;
    super::write_atomic(&dir.join(SCENE_FILE), text.as_bytes())
}

/// Replaces the lights and presets of `dir`'s scene.json and keeps everything else as written
/// (rewriting the cameras would round their numbers and change the bake's key).
pub fn write_lights(dir: &Path, lights: &[Light], presets: &[LightingPreset]) -> Result<()> {
    let path = dir.join(SCENE_FILE);
    let text = super::files::read(&path, super::files::FileKind::Text)?;
    let mut doc: serde_json::Value =
        serde_json::from_slice(&text).map_err(|e| Error::input(&path, e.to_string()))?;
    let Some(obj) = doc.as_object_mut() else {
        return Err(Error::input(&path, "expected a JSON object"));
    };
    let err = |e: serde_json::Error| Error::Other(e.to_string());
    let lights: Vec<LightDoc> = lights.iter().map(LightDoc::from_light).collect();
    obj.insert("lights".into(), serde_json::to_value(lights).map_err(err)?);
    obj.insert(
        "presets".into(),
        serde_json::to_value(preset_docs(presets)).map_err(err)?,
    );
    let text = serde_json::to_string_pretty(&doc).map_err(|e| Error::Other(e.to_string()))?;
    super::write_atomic(&path, text.as_bytes())
}
