//! Camera paths made in the viewer: each keyframe holds the camera, the lighting and where the
//! added lights are; saved in the format `relit fly` reads (`scene::path`), with times from the
//! distance walked and the angle turned, so that playback moves at a walking pace.

use std::collections::BTreeMap;
use std::path::Path;

use glam::Vec3;
use serde_json::json;

use crate::error::{Error, Result};
use crate::scene::{Camera, CameraDoc};

/// Walking pace (m/s) and turning pace (degrees/s) of a recorded path.
pub const WALK_M_PER_S: f32 = 0.5;
pub const TURN_DEG_PER_S: f32 = 45.0;
/// The shortest gap between keyframes; gaps are whole multiples of it, so a `relit fly` at
/// 1 / GAP_S frames a second (or a multiple) renders a frame at every keyframe.
pub const GAP_S: f32 = 0.25;
/// The first gap that is long enough for a pause at a keyframe.
pub const MIN_GAP_S: f32 = 1.0;

#[derive(Clone, Debug)]
pub struct Keyframe {
    pub camera: Camera,
    pub dim: f32,
    /// Intensity of each added light, by name.
    pub intensities: BTreeMap<String, f32>,
    /// Centre of each added light, by name.
    pub lights: BTreeMap<String, Vec3>,
    /// Factor of each declared original light set apart from 1, by name.
    pub originals: BTreeMap<String, [f32; 3]>,
}

impl Keyframe {
    fn fov_deg(&self) -> f32 {
        2.0 * (self.camera.width as f32 * 0.5 / self.camera.fx)
            .atan()
            .to_degrees()
    }
}

#[derive(Clone, Debug, Default)]
pub struct PathRecorder {
    pub keys: Vec<Keyframe>,
}

/// The angle (degrees) between two cameras' forward axes.
fn turn_deg(a: &Camera, b: &Camera) -> f32 {
    let (fa, fb) = (a.rotation.row(2), b.rotation.row(2));
    fa.dot(fb).clamp(-1.0, 1.0).acos().to_degrees()
}

impl PathRecorder {
    pub fn add(&mut self, k: Keyframe) {
        self.keys.push(k);
    }

    /// Keyframe times: 0, then each gap the longer of the walk and the turn, at least
    /// [`MIN_GAP_S`], rounded up to a multiple of [`GAP_S`].
    pub fn times(&self) -> Vec<f32> {
        let mut t = 0.0;
        let mut out = Vec::with_capacity(self.keys.len());
        for (i, k) in self.keys.iter().enumerate() {
            if i > 0 {
                let p = &self.keys[i - 1].camera;
                let walk = (k.camera.center() - p.center()).length() / WALK_M_PER_S;
                let turn = turn_deg(p, &k.camera) / TURN_DEG_PER_S;
                let gap = walk.max(turn).max(MIN_GAP_S);
                t += (gap / GAP_S).ceil() * GAP_S;
            }
            out.push(t);
        }
        out
    }

    /// The path document; light moves are relative to `home`, the added lights' centres in the
    /// scene `relit fly` will load.
    pub fn to_json(&self, home: &BTreeMap<String, Vec3>) -> serde_json::Value {
        let times = self.times();
        let keys: Vec<serde_json::Value> = (self.keys.iter().zip(&times))
            .map(|(k, t)| {
                let doc = CameraDoc::from_camera(&k.camera);
                json!({ "time": t, "position": doc.position, "rotation": doc.rotation,
                        "fov_deg": k.fov_deg() })
            })
            .collect();
        let lighting: Vec<serde_json::Value> = (self.keys.iter().zip(&times))
            .map(|(k, t)| {
                let moves: BTreeMap<&String, [f32; 3]> = (k.lights.iter())
                    .filter_map(|(n, p)| home.get(n).map(|h| (n, (*p - *h).into())))
                    .filter(|(_, d): &(_, [f32; 3])| d.iter().any(|v| v.abs() > 1e-6))
                    .collect();
                let mut key = json!({ "time": t, "dim": k.dim, "intensities": k.intensities,
                                      "moves": moves });
                if !k.originals.is_empty() {
                    key["originals"] = json!(k.originals);
                }
                key
            })
            .collect();
        json!({ "interpolation": "catmull-rom", "keyframes": keys, "lighting": lighting })
    }

    /// Writes the path to `file` atomically. A path needs two keyframes.
    pub fn save(&self, file: &Path, home: &BTreeMap<String, Vec3>) -> Result<()> {
        if self.keys.len() < 2 {
            return Err(Error::input(
                file,
                format!(
                    "a path needs at least two keyframes; {} recorded (R drops one)",
                    self.keys.len()
                ),
            ));
        }
        let text = serde_json::to_string_pretty(&self.to_json(home))
            .map_err(|e| Error::Other(format!("{}: {e}", file.display())))?;
        crate::scene::write_atomic(file, text.as_bytes())
    }
}

/// `cam` as the camera JSON `--camera FILE` reads (scene.json's camera object).
pub fn camera_json(cam: &Camera) -> String {
    serde_json::to_string_pretty(&CameraDoc::from_camera(cam)).expect("a camera serializes")
}
