//! `tools/scenegen`: procedural indoor scenes with the true description needed for ground truth
//! (§6): rooms, materials, lights and lighting conditions, capture cameras, a test path, and the
//! MVS-like proxy mesh. `tools/groundtruth/render.py` renders them with Mitsuba 3.

pub mod prim;
pub mod proxy;
pub mod room;
pub mod texture;

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use relit_engine::scene::{
    self, CameraDoc, ConditionDoc, LightingPreset, ObjectDoc, Scene, SceneFormat, Synthetic,
    TestViewDoc, View,
};

use crate::prim::{tessellate, TriMesh};
use crate::proxy::{proxy_mesh, ProxyParams};
use crate::room::{Room, RoomOptions};

/// Tessellation of the true mesh: exact for the flat primitives, fine enough for cylinders.
pub const TRUE_EDGE: f32 = 0.25;

/// Writes `room` as a Relit scene under `dir` (everything but the rendered images).
pub fn write_room(dir: &Path, room: &Room, proxy: &ProxyParams) -> Result<Scene> {
    for sub in ["textures", "true", "paths", "images"] {
        std::fs::create_dir_all(dir.join(sub))
            .with_context(|| format!("creating {}", dir.join(sub).display()))?;
    }
    for (name, m) in &room.materials {
        if let Some(t) = &m.texture {
            let p = dir.join(format!("textures/{name}.png"));
            let tmp = scene::temp_path(&p);
            t.save_with_format(&tmp, image::ImageFormat::Png)
                .with_context(|| p.display().to_string())?;
            std::fs::rename(&tmp, &p)?;
        }
    }
    // True geometry: one PLY per material (what the renderer needs), and all of it merged.
    let mut by_material: BTreeMap<&str, TriMesh> = BTreeMap::new();
    for o in &room.objects {
        by_material
            .entry(o.material.as_str())
            .or_default()
            .append(&tessellate(&o.prim, TRUE_EDGE));
    }
    let mut objects = Vec::new();
    let mut all = TriMesh::default();
    for (mat, m) in &by_material {
        let rel = format!("true/{mat}.ply");
        scene::write_atomic(&dir.join(&rel), &m.ply_bytes())?;
        objects.push(ObjectDoc {
            name: mat.to_string(),
            mesh: rel,
            material: mat.to_string(),
        });
        all.append(m);
    }
    all.to_mesh().write_ply(&dir.join("true_mesh.ply"))?;
    let proxy_m = proxy_mesh(&room.objects, proxy).to_mesh();
    proxy_m.write_ply(&dir.join("mesh.ply"))?;

    let path_json = serde_json::json!({
        "interpolation": "catmull-rom",
        "keyframes": room.path.iter().map(|(t, p, l)| serde_json::json!({
            "time": t, "position": p.to_array(), "look_at": l.to_array(), "fov_deg": room.path_fov_deg
        })).collect::<Vec<_>>(),
        "lighting": [
            {"time": 0.0, "dim": 0.0, "intensities": {}},
            {"time": room.path.last().map(|k| k.0).unwrap_or(0.0), "dim": 0.5, "intensities": {"extra0": 1.0}}
        ]
    });
    scene::write_atomic(
        &dir.join("paths/test.json"),
        serde_json::to_string_pretty(&path_json)?.as_bytes(),
    )?;

    let views = room
        .cameras
        .iter()
        .enumerate()
        .map(|(i, c)| View {
            name: format!("v{i:03}"),
            image: dir.join(format!("images/v{i:03}.exr")),
            camera: c.clone(),
        })
        .collect();
    let mut presets = Vec::new();
    if room.lights.iter().any(|l| l.name == "extra0") {
        presets.push(LightingPreset {
            name: "extra0_on_dimmed".into(),
            dim: 0.5,
            intensities: BTreeMap::from([("extra0".to_string(), 1.0)]),
            originals: BTreeMap::new(),
        });
    }
    let synthetic = Synthetic {
        seed: room.seed,
        objects,
        materials: room
            .materials
            .iter()
            .map(|(k, m)| (k.clone(), m.doc.clone()))
            .collect(),
        conditions: room
            .conditions
            .iter()
            .map(|(n, l)| ConditionDoc {
                name: n.clone(),
                lights: l.clone(),
            })
            .collect(),
        test_views: room
            .test_cameras
            .iter()
            .enumerate()
            .map(|(i, c)| TestViewDoc {
                name: format!("test{i:03}"),
                camera: CameraDoc::from_camera(c),
            })
            .collect(),
        test_path: "paths/test.json".into(),
        ground_truth: "gt".into(),
        proxy: proxy.to_json(),
    };
    let s = Scene {
        root: dir.to_path_buf(),
        format: SceneFormat::Relit,
        views,
        mesh_path: dir.join("mesh.ply"),
        mesh: proxy_m,
        true_mesh_path: Some(dir.join("true_mesh.ply")),
        lights: room.lights.clone(),
        presets,
        synthetic: Some(synthetic),
    };
    scene::write_scene(dir, &s, SceneFormat::Relit)?;
    Ok(s)
}

/// Generates and writes one scene.
pub fn generate(dir: &Path, seed: u64, opts: &RoomOptions) -> Result<Scene> {
    let room = room::generate(seed, opts);
    let proxy = ProxyParams::scaled(seed, opts.proxy_error);
    write_room(dir, &room, &proxy)
}
