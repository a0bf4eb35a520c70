//! A loaded scene's checks: views, lights, synthetic metadata and presets, each error naming the
//! file and the field.

use std::path::Path;

use super::{LightingPreset, Scene};
use crate::error::{Error, Result};

impl Scene {
    /// Checks what all formats share: views, cameras, lights, presets.
    pub(crate) fn validate(&self, file: &Path) -> Result<()> {
        if self.views.is_empty() {
            return Err(Error::input(file, "scene has no views"));
        }
        let mut names = std::collections::HashSet::new();
        for v in &self.views {
            v.camera
                .validate()
                .map_err(|m| Error::input(file, format!("view {}: camera: {m}", v.name)))?;
            if !names.insert(&v.name) {
                return Err(Error::input(
                    file,
                    format!("view name {} appears twice", v.name),
                ));
            }
        }
        for l in &self.lights {
            if !l.radiance.iter().all(|v| v.is_finite() && *v >= 0.0) {
                return Err(Error::input(
                    file,
                    format!(
                        "light {}: radiance {:?} must be finite and >= 0",
                        l.name, l.radiance
                    ),
                ));
            }
            l.shape
                .check()
                .map_err(|m| Error::input(file, format!("light {}: {m}", l.name)))?;
        }
        let mut light_names = std::collections::HashSet::new();
        for l in &self.lights {
            if !light_names.insert(&l.name) {
                return Err(Error::input(
                    file,
                    format!(
                        "light name {} appears twice (presets and paths name lights)",
                        l.name
                    ),
                ));
            }
        }
        if let Some(syn) = &self.synthetic {
            for c in &syn.conditions {
                for l in &c.lights {
                    if !self.lights.iter().any(|x| &x.name == l) {
                        return Err(Error::input(
                            file,
                            format!("synthetic.conditions: {} names light \"{l}\", which the scene does not have", c.name),
                        ));
                    }
                }
            }
            for o in &syn.objects {
                if !syn.materials.contains_key(&o.material) {
                    return Err(Error::input(
                        file,
                        format!(
                            "synthetic.objects: {} uses material \"{}\", which is not defined",
                            o.name, o.material
                        ),
                    ));
                }
            }
            for t in &syn.test_views {
                t.camera.to_camera(file, &t.name)?.validate().map_err(|m| {
                    Error::input(
                        file,
                        format!("synthetic.test_views: {}: camera: {m}", t.name),
                    )
                })?;
            }
        }
        for p in &self.presets {
            if !(0.0..=1.0).contains(&p.dim) {
                return Err(Error::input(
                    file,
                    format!(
                        "preset {}: dim = {}; expected 0 (keep) to 1 (remove)",
                        p.name, p.dim
                    ),
                ));
            }
            self.validate_preset(file, p)?;
        }
        Ok(())
    }

    /// A preset's intensities name added lights, its `originals` declared original lights, each
    /// value finite and >= 0.
    fn validate_preset(&self, file: &Path, p: &LightingPreset) -> Result<()> {
        let bad = |m: String| Err(Error::input(file, format!("preset {}: {m}", p.name)));
        let kind = |name: &str| {
            self.lights
                .iter()
                .find(|x| x.name == name)
                .map(|x| x.original)
        };
        for (l, v) in &p.intensities {
            match kind(l) {
                None => {
                    return bad(format!(
                        "names light \"{l}\", which the scene does not have"
                    ))
                }
                Some(true) => {
                    return bad(format!(
                    "intensities: \"{l}\" is an original light; set its factor under \"originals\""
                ))
                }
                Some(false) => {}
            }
            if !(v.is_finite() && *v >= 0.0) {
                return bad(format!("intensity of {l} is {v}; expected >= 0"));
            }
        }
        for (l, v) in &p.originals {
            if kind(l) != Some(true) {
                return bad(format!(
                    "originals: \"{l}\" is not a declared original light of the scene (original lights: {})",
                    self.original_names().join(", ")
                ));
            }
            if !v.iter().all(|c| c.is_finite() && *c >= 0.0) {
                return bad(format!("originals: {l} is {v:?}; expected factors >= 0"));
            }
        }
        Ok(())
    }

    /// The declared original lights' names, in scene order.
    pub fn original_names(&self) -> Vec<String> {
        let o = self.lights.iter().filter(|l| l.original);
        o.map(|l| l.name.clone()).collect()
    }
}
