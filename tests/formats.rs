//! The README's examples of every format a person writes by hand (the JSON blocks marked
//! `<!-- checked: KIND -->`) load with the engine's own loaders, so the documentation cannot drift
//! from what the code accepts.

mod common;

use std::path::{Path, PathBuf};

use relit_engine::scene::image::{write_exr, write_png, RgbImage};

use relit_engine::scene::path::CameraPath;
use relit_engine::scene::{write_scene, CameraDoc, Scene, SceneFormat};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The README's checked examples: (kind, JSON text).
fn examples() -> Vec<(String, String)> {
    let text = std::fs::read_to_string(Path::new(ROOT).join("README.md")).unwrap();
    let mut out = Vec::new();
    let mut lines = text.lines();
    while let Some(l) = lines.next() {
        let Some(kind) = l
            .strip_prefix("<!-- checked: ")
            .and_then(|k| k.strip_suffix(" -->"))
        else {
            continue;
        };
        assert_eq!(
            lines.next(),
            Some("```json"),
            "{kind}: a json block follows"
        );
        let body: Vec<&str> = lines.by_ref().take_while(|l| *l != "```").collect();
        out.push((kind.to_string(), body.join("\n")));
    }
    out
}

fn example(kind: &str) -> String {
    examples()
        .into_iter()
        .find(|(k, _)| k == kind)
        .unwrap_or_else(|| panic!("README has no checked {kind} example"))
        .1
}

/// A scene directory for the README's scene.json: its mesh (the tiny room's) and images of the
/// cameras' sizes at the paths it names.
fn scene_dir(name: &str) -> PathBuf {
    let dir = common::tempdir(name);
    let text = example("scene.json");
    let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mesh = Path::new(ROOT).join("scenes/tiny_room/mesh.ply");
    for key in ["mesh", "true_mesh"] {
        std::fs::copy(&mesh, dir.join(doc[key].as_str().unwrap())).unwrap();
    }
    for v in doc["views"].as_array().unwrap() {
        let path = dir.join(v["image"].as_str().unwrap());
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        let (w, h) = (
            v["camera"]["width"].as_u64().unwrap() as u32,
            v["camera"]["height"].as_u64().unwrap() as u32,
        );
        let img = RgbImage {
            width: w,
            height: h,
            pixels: vec![[0.4, 0.3, 0.2]; (w * h) as usize],
        };
        match path.extension().and_then(|e| e.to_str()) {
            Some("exr") => write_exr(&path, &img).unwrap(),
            _ => write_png(&path, &img, 1.0).unwrap(),
        }
    }
    std::fs::write(dir.join("scene.json"), text).unwrap();
    dir
}

#[test]
fn readme_has_every_checked_example() {
    let kinds: Vec<String> = examples().into_iter().map(|(k, _)| k).collect();
    assert_eq!(kinds, ["scene.json", "camera", "path", "lights.json"]);
}

#[test]
fn readme_scene_json_loads() {
    let dir = scene_dir("readme-scene");
    let scene = Scene::load(&dir).unwrap();
    assert_eq!(scene.views.len(), 2);
    assert_eq!(scene.lights.len(), 2);
    assert!(scene.lights.iter().any(|l| l.original));
    assert_eq!(scene.presets[0].name, "lamp_on_dimmed");
    let syn = scene.synthetic.as_ref().unwrap();
    assert_eq!(syn.test_views[0].name, "test000");
    assert_eq!(syn.ground_truth, "gt");
    // The look_at camera looks where it says: the target projects to the principal point.
    let cam = &scene.views[1].camera;
    let q = cam.rotation * glam::Vec3::new(0.5, 1.0, -0.5) + cam.translation;
    assert!(
        q.z > 0.0 && (q.x / q.z).abs() < 1e-5 && (q.y / q.z).abs() < 1e-5,
        "{q}"
    );
    // One field misspelt is an error that names it.
    let text = std::fs::read_to_string(dir.join("scene.json")).unwrap();
    std::fs::write(
        dir.join("scene.json"),
        text.replace("\"ground_truth\"", "\"groundtruth\""),
    )
    .unwrap();
    let e = Scene::load(&dir).err().unwrap().to_string();
    assert!(e.contains("scene.json") && e.contains("groundtruth"), "{e}");
}

#[test]
fn readme_lights_json_loads_beside_a_colmap_capture() {
    let scene = Scene::load(&scene_dir("readme-lights-src")).unwrap();
    let dir = common::tempdir("readme-lights");
    write_scene(&dir, &scene, SceneFormat::Colmap).unwrap();
    std::fs::copy(&scene.mesh_path, dir.join("mesh.ply")).unwrap();
    std::fs::write(dir.join("lights.json"), example("lights.json")).unwrap();
    let loaded = Scene::load(&dir).unwrap();
    assert_eq!(loaded.format, SceneFormat::Colmap);
    let names: Vec<&str> = loaded.lights.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["window", "lamp"]);
    assert_eq!(loaded.presets[0].name, "evening");
}

#[test]
fn readme_camera_file_loads() {
    let doc: CameraDoc = serde_json::from_str(&example("camera")).unwrap();
    let cam = doc.to_camera(Path::new("README.md"), "camera").unwrap();
    assert_eq!((cam.width, cam.height), (256, 192));
}

#[test]
fn readme_camera_path_loads() {
    let dir = common::tempdir("readme-path");
    let file = dir.join("path.json");
    std::fs::write(&file, example("path")).unwrap();
    let path = CameraPath::load(&file).unwrap();
    assert_eq!(path.duration(), 4.0);
    let l = path.lighting_at(3.0).unwrap();
    assert!((l.dim - 0.75).abs() < 1e-6, "{}", l.dim);
    let c = path.camera_at(4.0, 64, 48);
    assert!((c.rotation.determinant() - 1.0).abs() < 1e-5);
}
