//! Which input views see each original light: E_src (§4.1.1) knows the captured lights only
//! through their images, so a light that few views see is a light the bake can lose.
//!
//! A light is sampled on an `n × n` grid of cell centres ([`LightShape::grid_points`]). A view
//! sees a sample when the sample projects inside its image, the light's emitting side faces the
//! camera, and the segment from the sample (lifted [`SURFACE_OFFSET`] along the light's normal,
//! into the room) to the camera centre crosses no triangle of the proxy mesh. A view sees the
//! light when it sees at least one sample.

use super::{Camera, Light, LightShape, Scene, View};
use crate::cpu::MeshBvh;

/// Fewest input views that should see each original light. E_src takes the radiance of a ray
/// that hits a light from the input views that see the point it hits; with fewer than a few
/// such views, many directions toward the light find no view (or one at a grazing angle, with
/// the light at its image's edge), and the light's share of E_src is lost or noisy.
pub const MIN_VIEWS_PER_LIGHT: usize = 3;

/// Samples per side of the grid on each light (`COVERAGE_GRID²` samples).
pub const COVERAGE_GRID: usize = 4;

/// How far (m) the start of a visibility ray is lifted off the light along its normal: the proxy
/// mesh of a ceiling panel is the ceiling around it, a few millimetres off and noisy.
pub const SURFACE_OFFSET: f32 = 0.01;

/// One view that sees a light.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewSight {
    /// Index into the scene's views.
    pub view: usize,
    pub name: String,
    /// Fraction of the light's samples this view sees (> 0).
    pub visible: f32,
}

/// How the input views cover one original light.
#[derive(Clone, Debug, PartialEq)]
pub struct LightCoverage {
    /// The light's name.
    pub name: String,
    /// Input views of the scene.
    pub total_views: usize,
    /// The views that see at least one sample of the light, in view order.
    pub seen_by: Vec<ViewSight>,
}

impl LightCoverage {
    /// Views that see the light.
    pub fn views(&self) -> usize {
        self.seen_by.len()
    }

    pub fn view_names(&self) -> Vec<&str> {
        self.seen_by.iter().map(|s| s.name.as_str()).collect()
    }

    /// Fewer than [`MIN_VIEWS_PER_LIGHT`] views see the light.
    pub fn too_few(&self) -> bool {
        self.views() < MIN_VIEWS_PER_LIGHT
    }

    /// "light NAME: seen by K of N views", with the views' names when there are a few.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "light {}: seen by {} of {} views",
            self.name,
            self.views(),
            self.total_views
        );
        if (1..=8).contains(&self.views()) {
            let names: Vec<String> = self
                .seen_by
                .iter()
                .map(|v| format!("{} {:.0}%", v.name, 100.0 * v.visible))
                .collect();
            s.push_str(&format!(" ({})", names.join(", ")));
        }
        s
    }

    /// The warning for a light too few views see, `None` when enough do.
    pub fn warning(&self) -> Option<String> {
        self.too_few().then(|| {
            format!(
                "warning: original light '{}' is seen by {} of {} input views (fewer than {}): \
                 E_src finds its radiance only in views that see it, so the bake takes the \
                 direct light from the declared light by next-event estimation instead; capture \
                 more photos showing '{}', since images of it also feed the other features \
                 (its mirror reflections, its indirect light, novel views looking at it)",
                self.name,
                self.views(),
                self.total_views,
                MIN_VIEWS_PER_LIGHT,
                self.name
            )
        })
    }
}

/// The coverage of every original light of `scene` by its input views, tested against its proxy
/// mesh (in the order the scene declares the lights; added lights are skipped).
pub fn light_coverage(scene: &Scene) -> Vec<LightCoverage> {
    if !scene.lights.iter().any(|l| l.original) {
        return Vec::new();
    }
    coverage(&MeshBvh::new(&scene.mesh), &scene.views, &scene.lights)
}

/// The coverage of the original ones of `lights` by `views`, with occlusion by the mesh `bvh`
/// was built from.
pub fn coverage(bvh: &MeshBvh, views: &[View], lights: &[Light]) -> Vec<LightCoverage> {
    lights
        .iter()
        .filter(|l| l.original)
        .map(|l| {
            let samples = l.shape.grid_points(COVERAGE_GRID);
            let normal = l.shape.normal();
            let seen_by = views
                .iter()
                .enumerate()
                .filter_map(|(i, v)| {
                    let seen = samples
                        .iter()
                        .filter(|p| sees(bvh, &v.camera, **p, normal))
                        .count();
                    (seen > 0).then(|| ViewSight {
                        view: i,
                        name: v.name.clone(),
                        visible: seen as f32 / samples.len() as f32,
                    })
                })
                .collect();
            LightCoverage {
                name: l.name.clone(),
                total_views: views.len(),
                seen_by,
            }
        })
        .collect()
}

/// Fraction of the light's [`COVERAGE_GRID`]² samples that `camera` sees.
pub fn visible_fraction(bvh: &MeshBvh, camera: &Camera, shape: &LightShape) -> f32 {
    let samples = shape.grid_points(COVERAGE_GRID);
    let normal = shape.normal();
    let seen = samples
        .iter()
        .filter(|p| sees(bvh, camera, **p, normal))
        .count();
    seen as f32 / samples.len() as f32
}

/// Does `camera` see the point `p` of a light emitting along `normal`?
pub fn sees(bvh: &MeshBvh, camera: &Camera, p: glam::Vec3, normal: glam::Vec3) -> bool {
    let c = camera.center();
    if normal.dot(c - p) <= 0.0 {
        return false;
    }
    let Some((px, _)) = camera.project(p) else {
        return false;
    };
    if !(px.x >= 0.0 && px.y >= 0.0 && px.x < camera.width as f32 && px.y < camera.height as f32) {
        return false;
    }
    let o = p + normal * SURFACE_OFFSET;
    let d = c - o;
    let dist = d.length();
    if dist <= 1e-6 {
        return true;
    }
    !bvh.occluded(o, d / dist, 0.0, dist)
}
