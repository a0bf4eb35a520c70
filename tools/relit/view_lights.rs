//! Placing and moving added lights in `relit view`: a new lamp goes where the centre of the
//! window looks (on the surface, lifted off it), the selected one moves, grows, shrinks and
//! changes colour by keys; each edit makes it live (frame/live.rs) and the frame shows it at
//! once while its surface cache refines. F5 saves the lights and the current lighting (preset
//! "viewer") to scene.json, so `relit bake` (or the next render) bakes them.

use anyhow::{bail, Result};
use glam::Vec3;
use relit_engine::cpu::MeshBvh;
use relit_engine::frame::{Lighting, Renderer};
use relit_engine::scene::{Camera, Light, LightShape, LightingPreset, Scene};
use winit::keyboard::KeyCode;

/// A new lamp: a disk of this radius (m) this far off the surface, facing it.
const NEW_RADIUS: f32 = 0.1;
const NEW_LIFT: f32 = 0.4;
/// Its radiance (W/(m²·sr)); the scene's own lights set the scale when it has some.
const NEW_RADIANCE: f32 = 30.0;
/// Per key press: a move of 10 cm, a size step of 25%.
const STEP: f32 = 0.1;
const GROW: f32 = 1.25;
/// Colours the C key cycles through (relative RGB, mean 1).
const COLOURS: [[f32; 3]; 4] = [
    [1.0, 1.0, 1.0],
    [1.25, 1.0, 0.75],
    [0.8, 0.95, 1.25],
    [1.5, 0.9, 0.6],
];

pub struct LightEditor {
    /// The frame's (bake) mesh, and a BVH over it for picking.
    mesh: relit_engine::scene::Mesh,
    bvh: MeshBvh,
    colour: usize,
}

impl LightEditor {
    pub fn new(r: &Renderer) -> LightEditor {
        LightEditor {
            mesh: r.scene.geom.clone(),
            bvh: MeshBvh::new(&r.scene.geom),
            colour: 0,
        }
    }

    /// Handles an editing key; Ok(true) when it was one. `selected` indexes the added lights.
    pub fn key(
        &mut self,
        code: KeyCode,
        cam: &Camera,
        scene: &mut Scene,
        r: &mut Renderer,
        lighting: &mut Lighting,
        selected: &mut usize,
    ) -> Result<bool> {
        let added: Vec<usize> = (0..scene.lights.len())
            .filter(|&i| !scene.lights[i].original)
            .collect();
        let fwd = {
            let f = cam.rotation.row(2);
            Vec3::new(f.x, 0.0, f.z).normalize_or_zero()
        };
        let right = fwd.cross(Vec3::Y);
        let edit = |l: &Light| -> Option<Light> {
            Some(match code {
                KeyCode::KeyI => l.translated(fwd * STEP),
                KeyCode::KeyK => l.translated(-fwd * STEP),
                KeyCode::KeyJ => l.translated(-right * STEP),
                KeyCode::KeyL => l.translated(right * STEP),
                KeyCode::KeyU => l.translated(-Vec3::Y * STEP),
                KeyCode::KeyO => l.translated(Vec3::Y * STEP),
                KeyCode::Comma => l.scaled(1.0 / GROW),
                KeyCode::Period => l.scaled(GROW),
                _ => return None,
            })
        };
        match code {
            KeyCode::KeyN => {
                let light = self.place(cam, scene, added.len())?;
                r.set_live_light(added.len(), &light)?;
                scene.lights.push(light);
                lighting.intensities.push(1.0);
                *selected = added.len();
                Ok(true)
            }
            KeyCode::KeyC if !added.is_empty() => {
                self.colour = (self.colour + 1) % COLOURS.len();
                let i = added[*selected];
                let l = &scene.lights[i];
                let lum = l.radiance.iter().sum::<f32>() / 3.0;
                let c = COLOURS[self.colour];
                let light = Light {
                    radiance: [lum * c[0], lum * c[1], lum * c[2]],
                    ..l.clone()
                };
                r.set_live_light(*selected, &light)?;
                scene.lights[i] = light;
                Ok(true)
            }
            KeyCode::F5 => {
                save(scene, lighting)?;
                eprintln!(
                    "saved {} added light(s) and preset \"viewer\" to {}",
                    added.len(),
                    scene.root.join("scene.json").display()
                );
                Ok(true)
            }
            _ if !added.is_empty() => {
                let i = added[*selected];
                let Some(light) = edit(&scene.lights[i]) else {
                    return Ok(false);
                };
                r.set_live_light(*selected, &light)?;
                scene.lights[i] = light;
                Ok(true)
            }
            _ => Ok(false),
        }
    }

    /// A new disk lamp where the window's centre ray meets the surface, lifted off it, facing
    /// it; in front of the camera when the ray meets nothing.
    fn place(&self, cam: &Camera, scene: &Scene, n_added: usize) -> Result<Light> {
        let o = cam.center();
        let d = cam.rotation.row(2).normalize();
        let (center, normal) = match self.bvh.closest_hit(o, d, 0.0, 1e4) {
            Some(h) => {
                let mut n = self.mesh.face_normal(h.tri as usize);
                if n.dot(d) > 0.0 {
                    n = -n;
                }
                let lift = NEW_LIFT.min(0.5 * h.t);
                (o + d * h.t + n * lift, -n)
            }
            None => (o + d, -d),
        };
        let scale = scene
            .lights
            .iter()
            .map(|l| l.radiance.iter().sum::<f32>() / 3.0)
            .fold(0.0f32, f32::max);
        let rad = if scale > 0.0 { scale } else { NEW_RADIANCE };
        let mut k = n_added + 1;
        while scene.lights.iter().any(|l| l.name == format!("lamp{k}")) {
            k += 1;
        }
        Ok(Light {
            name: format!("lamp{k}"),
            shape: LightShape::Disk {
                center,
                normal,
                radius: NEW_RADIUS,
            },
            radiance: [rad; 3],
            original: false,
            estimated: false,
        })
    }
}

/// Writes the scene's lights and the current lighting as preset "viewer" to scene.json.
fn save(scene: &mut Scene, lighting: &Lighting) -> Result<()> {
    if relit_engine::scene::detect(&scene.root) != Some(relit_engine::scene::SceneFormat::Relit) {
        bail!(
            "{}: lights can be saved into a scene.json only (this scene is in another format)",
            scene.root.display()
        );
    }
    let names: Vec<String> = scene
        .lights
        .iter()
        .filter(|l| !l.original)
        .map(|l| l.name.clone())
        .collect();
    let preset = LightingPreset {
        name: "viewer".into(),
        dim: lighting.alpha_dim,
        intensities: names
            .iter()
            .zip(&lighting.intensities)
            .map(|(n, &v)| (n.clone(), v))
            .collect(),
        originals: lighting.named_factors(scene),
    };
    scene.presets.retain(|p| p.name != "viewer");
    scene.presets.push(preset);
    scene.save_lights()?;
    Ok(())
}

/// Keys that act again while held (moves and size steps).
pub const REPEATS: [KeyCode; 8] = [
    KeyCode::KeyI,
    KeyCode::KeyK,
    KeyCode::KeyJ,
    KeyCode::KeyL,
    KeyCode::KeyU,
    KeyCode::KeyO,
    KeyCode::Comma,
    KeyCode::Period,
];

/// One scripted input of `--keys`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scripted {
    /// A press (and release) of a key.
    Press(KeyCode),
    /// A key held down from this frame on, or let go.
    Hold(KeyCode),
    Release(KeyCode),
    /// A request for this window size (a resize).
    Size(u32, u32),
}

/// Parses `--keys`: comma-separated `FRAME:KEY` presses, `FRAME:+KEY` / `FRAME:-KEY` to hold a
/// key down and let it go, `FRAME:size=WxH` to resize the window. KEY is a letter, a digit,
/// Tab, Space, F1, F5, F6, Comma, Period, Plus, Minus, [ or ]; e.g. "2:N,4:J,4:J" adds a lamp at
/// frame 2 and moves it 20 cm left at frame 4; "1:+W,5:-W" walks forward for four frames.
pub fn parse_script(s: &str) -> Result<Vec<(u64, Scripted)>> {
    s.split(',')
        .filter(|x| !x.trim().is_empty())
        .map(|item| {
            let (f, k) = item.trim().split_once(':').ok_or_else(|| {
                anyhow::anyhow!("--keys: \"{item}\": expected FRAME:KEY, e.g. 2:N")
            })?;
            let frame: u64 = f.parse().map_err(|_| {
                anyhow::anyhow!("--keys: \"{item}\": frame \"{f}\" is not a whole number")
            })?;
            let unknown = || {
                anyhow::anyhow!("--keys: \"{item}\": unknown key \"{k}\" (letters, digits, Tab, Space, F1, F5, F6, Comma, Period, Plus, Minus, [, ]; +KEY holds, -KEY lets go; size=WxH resizes)")
            };
            let what = if let Some(size) = k.strip_prefix("size=") {
                let (w, h) = crate::parse_res(size).map_err(|e| anyhow::anyhow!("--keys: \"{item}\": {e}"))?;
                Scripted::Size(w, h)
            } else if let Some(key) = k.strip_prefix('+').filter(|r| !r.is_empty()) {
                Scripted::Hold(key_code(key).ok_or_else(unknown)?)
            } else if let Some(key) = k.strip_prefix('-').filter(|r| !r.is_empty()) {
                Scripted::Release(key_code(key).ok_or_else(unknown)?)
            } else {
                Scripted::Press(key_code(k).ok_or_else(unknown)?)
            };
            Ok((frame, what))
        })
        .collect()
}

fn key_code(k: &str) -> Option<KeyCode> {
    use KeyCode::*;
    const LETTERS: [KeyCode; 26] = [
        KeyA, KeyB, KeyC, KeyD, KeyE, KeyF, KeyG, KeyH, KeyI, KeyJ, KeyK, KeyL, KeyM, KeyN, KeyO,
        KeyP, KeyQ, KeyR, KeyS, KeyT, KeyU, KeyV, KeyW, KeyX, KeyY, KeyZ,
    ];
    const DIGITS: [KeyCode; 10] = [
        Digit0, Digit1, Digit2, Digit3, Digit4, Digit5, Digit6, Digit7, Digit8, Digit9,
    ];
    let c = k.chars().next()?;
    Some(match k {
        "Tab" => Tab,
        "Space" => Space,
        "F1" => F1,
        "F5" => F5,
        "F6" => F6,
        "Comma" => Comma,
        "Period" => Period,
        "Plus" => Equal,
        "Minus" => Minus,
        "[" => BracketLeft,
        "]" => BracketRight,
        _ if k.len() == 1 && c.is_ascii_alphabetic() => {
            LETTERS[(c.to_ascii_uppercase() as u8 - b'A') as usize]
        }
        _ if k.len() == 1 && c.is_ascii_digit() => DIGITS[(c as u8 - b'0') as usize],
        _ => return None,
    })
}
