//! Camera paths for `relit fly`: keyframes (time, position, look-at point or rotation, field of
//! view) with smooth interpolation, plus lighting keyframes (α_dim and added-light intensities).
//!
//! ```json
//! { "interpolation": "catmull-rom" | "linear",
//!   "keyframes": [ { "time": 0.0, "position": [x, y, z], "look_at": [x, y, z], "fov_deg": 70 },
//!                  { "time": 2.0, "position": [...], "look_at": [...], "fov_deg": 60 } ],
//!   "lighting": [ { "time": 0.0, "dim": 0.0, "intensities": { "lamp": 1.0 },
//!                   "moves": { "lamp": [dx, dy, dz] } } ] }
//! ```
//! Every keyframe gives `look_at`, or every one gives `rotation` ([[right], [down], [forward]],
//! as scene.json's). Positions and look-at points follow a uniform Catmull-Rom spline through the
//! keyframes (ends clamped), or straight lines; rotations are slerped; the field of view
//! (horizontal, degrees) and the lighting are interpolated linearly. Missing intensities are 0.
//! `moves` displaces an added light from its place in the scene (metres, world axes), also
//! interpolated linearly; a light a keyframe does not move stays where the scene has it.

use std::collections::BTreeMap;
use std::path::Path;

use glam::{Mat3, Quat, Vec3};
use serde::Deserialize;

use super::Camera;
use crate::error::{Error, Result};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PathDoc {
    #[serde(default = "default_interp")]
    interpolation: String,
    keyframes: Vec<KeyDoc>,
    #[serde(default)]
    lighting: Vec<LightKeyDoc>,
}

fn default_interp() -> String {
    "catmull-rom".into()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyDoc {
    time: f32,
    position: [f32; 3],
    #[serde(default)]
    look_at: Option<[f32; 3]>,
    #[serde(default)]
    rotation: Option<[[f32; 3]; 3]>,
    fov_deg: f32,
}

#[derive(Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct LightKeyDoc {
    time: f32,
    #[serde(default)]
    dim: f32,
    #[serde(default)]
    intensities: BTreeMap<String, f32>,
    #[serde(default)]
    moves: BTreeMap<String, [f32; 3]>,
    /// Per declared original light, its factor (one number or RGB; 1: as captured).
    #[serde(default)]
    originals: BTreeMap<String, super::json::Factor>,
}

/// One lighting keyframe: time, α_dim, intensities, light displacements, original lights'
/// factors.
#[derive(Clone, Debug)]
struct LightKey {
    time: f32,
    dim: f32,
    intensities: BTreeMap<String, f32>,
    moves: BTreeMap<String, Vec3>,
    originals: BTreeMap<String, [f32; 3]>,
}

#[derive(Clone, Debug)]
struct Key {
    time: f32,
    position: Vec3,
    look_at: Option<Vec3>,
    /// Camera-to-world rotation (columns: right, down, forward).
    rotation: Option<Quat>,
    fov_deg: f32,
}

#[derive(Clone, Debug)]
pub struct CameraPath {
    keys: Vec<Key>,
    lights: Vec<LightKey>,
    catmull_rom: bool,
}

/// The lighting at one time: α_dim, the intensity of each named added light, and how far each
/// moved light is from its place in the scene, and each named original light's factor.
#[derive(Clone, Debug, PartialEq)]
pub struct PathLighting {
    pub dim: f32,
    pub intensities: BTreeMap<String, f32>,
    pub moves: BTreeMap<String, Vec3>,
    pub originals: BTreeMap<String, [f32; 3]>,
}

fn catmull_rom(p0: Vec3, p1: Vec3, p2: Vec3, p3: Vec3, u: f32) -> Vec3 {
    let (u2, u3) = (u * u, u * u * u);
    0.5 * ((2.0 * p1)
        + (p2 - p0) * u
        + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * u2
        + (3.0 * p1 - p0 - 3.0 * p2 + p3) * u3)
}

/// Keyframe `i` of `keyframes`, checked: its time after the one before, a field of view, a
/// finite position and exactly one valid orientation (look-at point or rotation).
fn camera_key(file: &Path, keyframes: &[KeyDoc], i: usize) -> Result<Key> {
    let k = &keyframes[i];
    let at = |m: &str| Error::input(file, format!("keyframes[{i}]: {m}"));
    if !k.time.is_finite() || (i > 0 && k.time <= keyframes[i - 1].time) {
        return Err(at(
            "time must be finite and increase from keyframe to keyframe",
        ));
    }
    if !(k.fov_deg > 0.0 && k.fov_deg < 180.0) {
        return Err(at("fov_deg must be in (0, 180)"));
    }
    let position = Vec3::from(k.position);
    if !position.is_finite() {
        return Err(at("position must be finite"));
    }
    let rotation = match (&k.look_at, &k.rotation) {
        (Some(l), None) => {
            let d = Vec3::from(*l) - position;
            if !d.is_finite() {
                return Err(at("look_at must be finite"));
            }
            if d.length() < 1e-6 {
                return Err(at("look_at equals position"));
            }
            // The camera's up is +Y: a view straight up or down has no horizon.
            if d.normalize().cross(Vec3::Y).length() < 1e-4 {
                return Err(at(
                    "look_at is straight above or below position (the up direction is +Y)",
                ));
            }
            None
        }
        (None, Some(r)) => {
            let m = Mat3::from_cols(r[0].into(), r[1].into(), r[2].into());
            let off = (m * m.transpose() - Mat3::IDENTITY)
                .to_cols_array()
                .iter()
                .fold(0f32, |a, v| a.max(v.abs()));
            if off.is_nan() || off > 1e-3 || (m.determinant() - 1.0).abs() > 1e-3 {
                return Err(at(
                    "rotation must be a rotation matrix (rows: right, down, forward)",
                ));
            }
            Some(Quat::from_mat3(&m))
        }
        _ => return Err(at("give exactly one of \"look_at\" and \"rotation\"")),
    };
    Ok(Key {
        time: k.time,
        position,
        look_at: k.look_at.map(Vec3::from),
        rotation,
        fov_deg: k.fov_deg,
    })
}

/// Lighting keyframe `i` of `lighting`, checked: its time after the one before, α_dim in
/// [0, 1], intensities, original lights' factors and moves finite (and not negative).
fn light_key(file: &Path, lighting: &[LightKeyDoc], i: usize) -> Result<LightKey> {
    let l = &lighting[i];
    let bad = |m: String| Error::input(file, m);
    if !l.time.is_finite() || (i > 0 && l.time <= lighting[i - 1].time) {
        return Err(bad(format!(
            "lighting[{i}]: time must be finite and increase"
        )));
    }
    if !(0.0..=1.0).contains(&l.dim) {
        return Err(bad(format!("lighting[{i}]: dim must be in [0, 1]")));
    }
    for (name, k) in &l.intensities {
        if !(k.is_finite() && *k >= 0.0) {
            return Err(bad(format!(
                "lighting[{i}]: intensities.{name} = {k}; expected a finite number >= 0"
            )));
        }
    }
    for (name, c) in &l.originals {
        if !c.rgb().iter().all(|v| v.is_finite() && *v >= 0.0) {
            return Err(bad(format!(
                "lighting[{i}]: originals.{name} = {:?}; expected factors >= 0",
                c.rgb()
            )));
        }
    }
    for (name, d) in &l.moves {
        if !Vec3::from(*d).is_finite() {
            return Err(bad(format!(
                "lighting[{i}]: moves.{name} must be finite (metres)"
            )));
        }
    }
    Ok(LightKey {
        time: l.time,
        dim: l.dim,
        intensities: l.intensities.clone(),
        moves: l
            .moves
            .iter()
            .map(|(k, v)| (k.clone(), Vec3::from(*v)))
            .collect(),
        originals: super::json::factors(&l.originals),
    })
}

impl CameraPath {
    pub fn load(file: &Path) -> Result<CameraPath> {
        let doc: PathDoc = super::json::parse(file)?;
        let bad = |m: String| Error::input(file, m);
        let catmull_rom = match doc.interpolation.as_str() {
            "catmull-rom" => true,
            "linear" => false,
            o => {
                return Err(bad(format!(
                    "interpolation \"{o}\": expected \"catmull-rom\" or \"linear\""
                )))
            }
        };
        if doc.keyframes.is_empty() {
            return Err(bad("keyframes: at least one keyframe is needed".into()));
        }
        let mut keys = Vec::new();
        for i in 0..doc.keyframes.len() {
            keys.push(camera_key(file, &doc.keyframes, i)?);
        }
        if keys.iter().any(|k| k.rotation.is_some()) && keys.iter().any(|k| k.look_at.is_some()) {
            return Err(bad(
                "keyframes: use \"look_at\" in every keyframe or \"rotation\" in every keyframe"
                    .into(),
            ));
        }
        let mut lights = Vec::new();
        for i in 0..doc.lighting.len() {
            lights.push(light_key(file, &doc.lighting, i)?);
        }
        Ok(CameraPath {
            keys,
            lights,
            catmull_rom,
        })
    }

    /// Time of the last keyframe (camera or lighting).
    pub fn duration(&self) -> f32 {
        let k = self.keys.last().unwrap().time;
        self.lights.last().map_or(k, |l| l.time.max(k))
    }

    pub fn start(&self) -> f32 {
        self.keys[0].time
    }

    /// Segment index and parameter for time t in a sorted list of times.
    fn segment(times: &[f32], t: f32) -> (usize, f32) {
        if t <= times[0] || times.len() == 1 {
            return (0, 0.0);
        }
        let n = times.len();
        if t >= times[n - 1] {
            return (n - 2, 1.0);
        }
        let i = times.partition_point(|&x| x <= t) - 1;
        (i, (t - times[i]) / (times[i + 1] - times[i]))
    }

    fn interp(&self, i: usize, u: f32, f: impl Fn(&Key) -> Vec3) -> Vec3 {
        let n = self.keys.len();
        if n == 1 {
            return f(&self.keys[0]);
        }
        let p = |j: isize| f(&self.keys[j.clamp(0, n as isize - 1) as usize]);
        let i = i as isize;
        if self.catmull_rom {
            catmull_rom(p(i - 1), p(i), p(i + 1), p(i + 2), u)
        } else {
            p(i).lerp(p(i + 1), u)
        }
    }

    /// The camera at time t with a `width × height` image.
    pub fn camera_at(&self, t: f32, width: u32, height: u32) -> Camera {
        let times: Vec<f32> = self.keys.iter().map(|k| k.time).collect();
        let (i, u) = CameraPath::segment(&times, t);
        let j = (i + 1).min(self.keys.len() - 1);
        let pos = self.interp(i, u, |k| k.position);
        let fov = self.keys[i].fov_deg + (self.keys[j].fov_deg - self.keys[i].fov_deg) * u;
        let fx = width as f32 * 0.5 / (fov.to_radians() * 0.5).tan();
        match self.keys[0].rotation {
            None => {
                let target = self.interp(i, u, |k| k.look_at.unwrap());
                Camera::look_at(pos, target, Vec3::Y, width, height, fx)
            }
            Some(_) => {
                let q = self.keys[i]
                    .rotation
                    .unwrap()
                    .slerp(self.keys[j].rotation.unwrap(), u);
                Camera::from_camera_to_world(Mat3::from_quat(q), pos, width, height, fx, fx)
            }
        }
    }

    /// The lighting at time t (None when the path has no lighting keyframes).
    pub fn lighting_at(&self, t: f32) -> Option<PathLighting> {
        if self.lights.is_empty() {
            return None;
        }
        let (i, j, u) = self.lighting_segment(t)?;
        let (a, b) = (&self.lights[i], &self.lights[j]);
        let mut intensities = BTreeMap::new();
        for name in a.intensities.keys().chain(b.intensities.keys()) {
            let x = a.intensities.get(name).copied().unwrap_or(0.0);
            let y = b.intensities.get(name).copied().unwrap_or(0.0);
            intensities.insert(name.clone(), x + (y - x) * u);
        }
        let mut moves = BTreeMap::new();
        for name in a.moves.keys().chain(b.moves.keys()) {
            let x = a.moves.get(name).copied().unwrap_or(Vec3::ZERO);
            let y = b.moves.get(name).copied().unwrap_or(Vec3::ZERO);
            moves.insert(name.clone(), x + (y - x) * u);
        }
        let mut originals = BTreeMap::new();
        for name in a.originals.keys().chain(b.originals.keys()) {
            let one = [1.0; 3];
            let x = Vec3::from(a.originals.get(name).copied().unwrap_or(one));
            let y = Vec3::from(b.originals.get(name).copied().unwrap_or(one));
            originals.insert(name.clone(), (x + (y - x) * u).into());
        }
        Some(PathLighting {
            originals,
            dim: a.dim + (b.dim - a.dim) * u,
            intensities,
            moves,
        })
    }

    /// The lighting keyframes around time t and the weight of the second: (i, j, u).
    pub fn lighting_segment(&self, t: f32) -> Option<(usize, usize, f32)> {
        if self.lights.is_empty() {
            return None;
        }
        let times: Vec<f32> = self.lights.iter().map(|l| l.time).collect();
        let (i, u) = CameraPath::segment(&times, t);
        Some((i, (i + 1).min(self.lights.len() - 1), u))
    }

    /// Each lighting keyframe's displacement of `light` (zero where it does not move it).
    pub fn moves_at_keys(&self, light: &str) -> Vec<Vec3> {
        self.lights
            .iter()
            .map(|k| k.moves.get(light).copied().unwrap_or(Vec3::ZERO))
            .collect()
    }

    /// The names of the lights some lighting keyframe lights (intensity not zero) or sets a
    /// factor for (an original light).
    pub fn lit_lights(&self) -> Vec<String> {
        let mut v: Vec<String> = (self.lights.iter())
            .flat_map(|k| k.intensities.iter().filter(|(_, &i)| i != 0.0))
            .map(|(n, _)| n.clone())
            .collect();
        // A factor for an original light: that light's entry (the bake adds the others').
        v.extend((self.lights.iter()).flat_map(|k| k.originals.keys().cloned()));
        v.sort();
        v.dedup();
        v
    }

    /// The names of the lights some keyframe moves.
    pub fn moved_lights(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .lights
            .iter()
            .flat_map(|k| k.moves.keys().cloned())
            .collect();
        v.sort();
        v.dedup();
        v
    }
}
