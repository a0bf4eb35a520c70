//! What the viewer's HUD says: frame rate, per-pass times, mode and whether the frame is the
//! moving or the still one, the lighting, the selected light, recording and playback; and the
//! viewer's keys, one list for the F1 help, the README and the test that checks the README.

/// The viewer's keys: (key, what it does). The README's viewer section lists each one.
pub const KEYS: &[(&str, &str)] = &[
    ("W A S D", "move forward / left / back / right"),
    ("Q E", "move down / up (Shift: faster)"),
    ("arrows, left drag", "look around"),
    ("0", "original lighting"),
    ("1-9", "the scene's lighting presets"),
    ("[ ]", "dim / brighten the original lights (alpha_dim)"),
    ("Tab", "select the next added light"),
    ("T", "select the next original light"),
    (
        "Z X",
        "dim / brighten the selected original light on its own",
    ),
    ("+ -", "selected light's intensity"),
    ("N", "add a lamp where the centre of the window looks"),
    (
        "I K J L",
        "move the selected light forward / back / left / right",
    ),
    ("U O", "move the selected light down / up"),
    (", .", "shrink / grow the selected light"),
    ("C", "change the selected light's colour"),
    (
        "F5",
        "save the lights and the lighting (preset \"viewer\") to scene.json",
    ),
    (
        "M",
        "cycle the mode: network, ULR, ratio, glossy, ratio-filled",
    ),
    (
        "G",
        "frames: auto (cheap while moving, full when still), always full, always cheap",
    ),
    ("R", "drop a keyframe (with --record)"),
    (
        "F6",
        "save the recorded path now (it is also saved on exit)",
    ),
    (
        "V",
        "write the current camera as a camera JSON (for --camera FILE)",
    ),
    ("Space", "pause / resume playback (with --play)"),
    ("P", "save a screenshot of the window"),
    ("H", "show / hide the HUD"),
    ("F1", "show / hide this list of keys"),
    ("F11", "toggle fullscreen"),
    ("Esc", "quit"),
];

/// The F1 help as HUD lines.
pub fn key_lines() -> Vec<String> {
    let w = KEYS.iter().map(|(k, _)| k.len()).max().unwrap_or(0);
    KEYS.iter().map(|(k, d)| format!("{k:<w$}  {d}")).collect()
}

/// The selected added light as the HUD shows it.
#[derive(Clone, Debug, Default)]
pub struct LightInfo {
    pub name: String,
    pub position: [f32; 3],
    /// Disk radius or sphere radius (m).
    pub size: f32,
    /// Radiance (W/(m²·sr)): its colour and strength at intensity 1.
    pub colour: [f32; 3],
    pub intensity: f32,
    /// Paths per texel of its live cache, and the target (None: baked).
    pub live: Option<(u32, u32)>,
}

/// Everything the HUD shows of one frame.
#[derive(Clone, Debug, Default)]
pub struct HudInfo {
    pub fps: f32,
    /// (pass, ms) of the last rendered frame.
    pub passes: Vec<(String, f64)>,
    pub mode: String,
    /// "moving 64x48 ratio" (the cheap frame) or "still 256x192".
    pub frame: String,
    /// Which frames are shown: auto, still or moving (the G key).
    pub policy: String,
    pub lighting: String,
    pub alpha_dim: f32,
    pub light: Option<LightInfo>,
    /// The selected original light and its factor (None: the scene declares none).
    pub original: Option<(String, [f32; 3])>,
    /// Keyframes recorded so far (None: not recording).
    pub recording: Option<usize>,
    /// Playback time and the path's length (s).
    pub playing: Option<(f32, f32)>,
}

impl HudInfo {
    pub fn lines(&self) -> Vec<String> {
        let mut v = vec![
            format!(
                "{:.1} fps   {} frame   mode {}",
                self.fps, self.frame, self.mode
            ),
            format!(
                "frames {}   lighting {}   dim {:.2}",
                self.policy, self.lighting, self.alpha_dim
            ),
        ];
        v.extend(pass_lines(&self.passes));
        if let Some(l) = &self.light {
            let [x, y, z] = l.position;
            let [r, g, b] = l.colour;
            v.push(format!(
                "light {}  at ({x:.2}, {y:.2}, {z:.2})  size {:.2} m",
                l.name, l.size
            ));
            let live = match l.live {
                Some((p, n)) => format!("  live cache {p}/{n} paths"),
                None => String::new(),
            };
            v.push(format!(
                "  radiance ({r:.1}, {g:.1}, {b:.1})  intensity {:.2}{live}",
                l.intensity
            ));
        }
        if let Some((name, [r, g, b])) = &self.original {
            v.push(format!(
                "original light {name}  factor ({r:.2}, {g:.2}, {b:.2})"
            ));
        }
        if let Some(n) = self.recording {
            v.push(format!("REC  {n} keyframe(s)  (R: add, F6: save)"));
        }
        if let Some((t, d)) = self.playing {
            v.push(format!("PLAY  {t:.1} / {d:.1} s"));
        }
        v.push("H: hide   F1: keys".into());
        v
    }
}

/// Per-pass times, the network's stages summed into one entry, three passes to a line.
fn pass_lines(passes: &[(String, f64)]) -> Vec<String> {
    let mut items: Vec<String> = Vec::new();
    let net: f64 = passes
        .iter()
        .filter(|(l, _)| l.starts_with("net: "))
        .map(|p| p.1)
        .sum();
    for (l, ms) in passes.iter().filter(|(l, _)| !l.starts_with("net: ")) {
        if l == "output" && net > 0.0 {
            items.push(format!("network {net:.0}"));
        }
        items.push(format!("{l} {ms:.0}"));
    }
    items
        .chunks(3)
        .enumerate()
        .map(|(i, c)| format!("{}{}", if i == 0 { "ms: " } else { "    " }, c.join(", ")))
        .collect()
}
