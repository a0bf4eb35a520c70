//! The user's lighting (§4.1.4 and beyond): the added lights' intensities, α_dim for the whole
//! original lighting, and a factor for each declared original light on its own.
//!
//! Per-light control. The paper dims the original lighting as one (E_rem = α_dim·E_src, §4.1.4;
//! §8 names per-light control as future work). With a factor c_l per original light (RGB, 1: as
//! captured), what is left of the original light at a point is (1 − α_dim)·Σ_l c_l·E_src,l, so
//!   E_rem = α_dim·E_src + (1 − α_dim)·Σ_l (1 − c_l)·E_src,l.
//! E_src,l — light l's part of the photos' irradiance, its direct light and its share of the
//! bounces — is E_src times l's share of the simulated irradiance: each original light is baked as
//! an added light is (its own E_add entry, from its declared radiance), and
//!   Σ_l (1 − c_l)·E_src,l = E_src · Σ_l (1 − c_l)·E_l / Σ_l E_l   (per channel),
//! taken in each input view before the views are blended. Where no simulated light arrives (or
//! the scene has one original light, which needs no entry) the share is the mean of (1 − c_l).
//! With every c_l = 1 the frame runs exactly the passes it ran before per-light control.

use std::path::Path;

use glam::Vec3;

use crate::error::{Error, Result};
use crate::scene::path::PathLighting;
use crate::scene::Scene;

/// The user's lighting: one intensity per added light (the scene's non-original lights, in
/// scene order), α_dim (§4.1.4: 0 keeps the original lighting, 1 removes it), and one RGB factor
/// per declared original light in scene order (missing ones are 1: as captured).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Lighting {
    pub intensities: Vec<f32>,
    pub alpha_dim: f32,
    pub originals: Vec<[f32; 3]>,
}

/// An original light as captured: factor 1.
pub const AS_CAPTURED: [f32; 3] = [1.0; 3];

impl Lighting {
    /// The captured lighting: no added light, nothing dimmed.
    pub fn original(scene: &Scene) -> Lighting {
        Lighting {
            intensities: vec![0.0; added_lights(scene).len()],
            ..Default::default()
        }
    }

    /// A named preset of the scene (its names were checked when the scene loaded).
    pub fn preset(scene: &Scene, name: &str) -> Result<Lighting> {
        let p = scene.preset(name).ok_or_else(|| {
            let names: Vec<_> = scene.presets.iter().map(|p| p.name.as_str()).collect();
            Error::Other(format!(
                "no lighting preset \"{name}\" in {} (presets: {})",
                scene.root.display(),
                if names.is_empty() {
                    "none".to_string()
                } else {
                    names.join(", ")
                }
            ))
        })?;
        Ok(Lighting {
            intensities: added_lights(scene)
                .iter()
                .map(|l| p.intensities.get(l.as_str()).copied().unwrap_or(0.0))
                .collect(),
            alpha_dim: p.dim,
            originals: factors(scene, &p.originals),
        })
    }

    /// The lighting of a camera path at some time: every light it names must be an added light
    /// (intensities, moves) or a declared original one (`originals`).
    pub fn from_path(scene: &Scene, l: &PathLighting, file: &Path) -> Result<Lighting> {
        let names = added_lights(scene);
        let added = l.intensities.keys().chain(l.moves.keys());
        if let Some(n) = added.clone().find(|n| !names.contains(n)) {
            return Err(Error::input(
                file,
                format!(
                    "lighting: \"{n}\" is not an added light of the scene (added lights: {})",
                    names.join(", ")
                ),
            ));
        }
        let originals = scene.original_names();
        if let Some(n) = l.originals.keys().find(|n| !originals.contains(n)) {
            return Err(Error::input(
                file,
                format!(
                    "lighting: originals: \"{n}\" is not a declared original light of the scene (original lights: {})",
                    originals.join(", ")
                ),
            ));
        }
        Ok(Lighting {
            intensities: names
                .iter()
                .map(|n| l.intensities.get(n).copied().unwrap_or(0.0))
                .collect(),
            alpha_dim: l.dim,
            originals: factors(scene, &l.originals),
        })
    }

    /// Original light `l`'s factor (1 where none is set).
    pub fn factor(&self, l: usize) -> [f32; 3] {
        self.originals.get(l).copied().unwrap_or(AS_CAPTURED)
    }

    /// Whether some original light has a factor of its own (not 1): only then do the frame's
    /// passes split E_src among the original lights.
    pub fn per_light(&self) -> bool {
        self.originals.iter().any(|c| *c != AS_CAPTURED)
    }

    /// The original lights' factors that differ from 1, by name (what presets and paths write).
    pub fn named_factors(&self, scene: &Scene) -> std::collections::BTreeMap<String, [f32; 3]> {
        let names = scene.original_names();
        (names.into_iter().zip(&self.originals))
            .filter(|(_, c)| **c != AS_CAPTURED)
            .map(|(n, c)| (n, *c))
            .collect()
    }

    /// The factors of `norig` original lights as the frame's `Keep` buffer holds them (rgb, 0;
    /// one item when there is none).
    pub fn keep_buffer(&self, norig: usize) -> Vec<[f32; 4]> {
        (0..norig.max(1))
            .map(|l| {
                let c = self.factor(l);
                [c[0], c[1], c[2], 0.0]
            })
            .collect()
    }
}

/// Per declared original light (scene order), its factor in `named` (1 where it is not named).
fn factors(scene: &Scene, named: &std::collections::BTreeMap<String, [f32; 3]>) -> Vec<[f32; 3]> {
    let names = scene.original_names();
    names
        .iter()
        .map(|n| named.get(n).copied().unwrap_or(AS_CAPTURED))
        .collect()
}

/// Names of the added (non-original) lights, in the order of the E_add layers.
pub fn added_lights(scene: &Scene) -> Vec<String> {
    scene
        .lights
        .iter()
        .filter(|l| !l.original)
        .map(|l| l.name.clone())
        .collect()
}

/// CPU mirror of `removed_share` (originals.glsl): the share of one view's E_src the factors
/// remove, from the simulated irradiance of each original light there (`sims`, empty when the
/// scene has no per-light entries).
pub fn removed_share(sims: &[Vec3], keep: &[[f32; 3]], norig: usize) -> Vec3 {
    let off = |l: usize| Vec3::ONE - Vec3::from(keep.get(l).copied().unwrap_or(AS_CAPTURED));
    let mean = (0..norig).map(off).sum::<Vec3>() / norig.max(1) as f32;
    let (mut num, mut den) = (Vec3::ZERO, Vec3::ZERO);
    for (l, s) in sims.iter().enumerate() {
        num += off(l) * *s;
        den += *s;
    }
    let pick = |n: f32, d: f32, m: f32| if d > SHARE_MIN { n / d } else { m };
    Vec3::new(
        pick(num.x, den.x, mean.x),
        pick(num.y, den.y, mean.y),
        pick(num.z, den.z, mean.z),
    )
}

/// Below this simulated irradiance (W/m²) a point's shares are not trusted (`constants.table`).
pub const SHARE_MIN: f32 = crate::constants::SHARE_MIN;
