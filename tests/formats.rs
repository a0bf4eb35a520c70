//! The examples in docs/formats.md of every format a person writes by hand (the JSON blocks marked
//! `<!-- checked: KIND -->`) load with the engine's own loaders, so the documentation cannot drift
//! from what the code accepts.

mod common;

use std::path::{Path, PathBuf};

use relit_engine::scene::image::{write_exr, write_png, RgbImage};

use relit_engine::scene::path::CameraPath;
use relit_engine::scene::{write_scene, CameraDoc, Scene, SceneFormat};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The checked examples of docs/formats.md: (kind, JSON text).
fn examples() -> Vec<(String, String)> {
    let text = std::fs::read_to_string(Path::new(ROOT).join("docs/formats.md")).unwrap();
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
        .unwrap_or_else(|| panic!("docs/formats.md has no checked {kind} example"))
        .1
}

/// A scene directory for the example scene.json: its mesh (the tiny room's) and images of the
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
fn formats_doc_has_every_checked_example() {
    let kinds: Vec<String> = examples().into_iter().map(|(k, _)| k).collect();
    assert_eq!(
        kinds,
        [
            "scene.json",
            "camera",
            "path",
            "lights.json",
            "transforms.json"
        ]
    );
}

#[test]
fn example_scene_json_loads() {
    let dir = scene_dir("readme-scene");
    let scene = Scene::load(&dir).unwrap();
    assert_eq!(scene.views.len(), 2);
    assert_eq!(scene.lights.len(), 2);
    assert!(scene.lights.iter().any(|l| l.original));
    assert_eq!(scene.presets[0].name, "lamp_on_dimmed");
    assert_eq!(scene.presets[1].originals["ceiling"], [0.6, 0.45, 0.3]);
    let warm = relit_engine::frame::Lighting::preset(&scene, "ceiling_warm").unwrap();
    assert_eq!(
        (warm.intensities, warm.originals),
        (vec![1.0], vec![[0.6, 0.45, 0.3]])
    );
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
fn example_lights_json_loads_beside_a_colmap_capture() {
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
fn example_transforms_json_loads_with_opengl_axes_flipped() {
    let dir = common::tempdir("readme-transforms");
    let mesh = Path::new(ROOT).join("scenes/tiny_room/mesh.ply");
    std::fs::copy(&mesh, dir.join("mesh.ply")).unwrap();
    std::fs::create_dir_all(dir.join("images")).unwrap();
    for name in ["000.png", "001.png"] {
        write_png(&dir.join("images").join(name), &RgbImage::new(64, 48), 1.0).unwrap();
    }
    std::fs::write(dir.join("transforms.json"), example("transforms.json")).unwrap();
    let scene = Scene::load(&dir).unwrap();
    assert_eq!(scene.format, SceneFormat::Transforms);
    scene.check_images().unwrap();
    let (a, b) = (&scene.views[0].camera, &scene.views[1].camera);
    assert_eq!((a.fx, b.fx, b.cx, b.width), (48.0, 40.0, 32.0, 64));
    // Both cameras look at (0, 1.2, 0): it projects to the principal point, and a point above
    // it to a smaller image y (OpenCV's y points down).
    for c in [a, b] {
        let (p, z) = c.project(glam::Vec3::new(0.0, 1.2, 0.0)).unwrap();
        assert!((p - glam::Vec2::new(32.0, 24.0)).length() < 1e-4 && (z - 2.5).abs() < 1e-5);
        let (up, _) = c.project(glam::Vec3::new(0.0, 1.5, 0.0)).unwrap();
        assert!(up.y < 24.0 && (up.x - 32.0).abs() < 1e-4, "{up}");
    }
    // Written back and read again, the cameras are the same.
    let again = common::tempdir("readme-transforms-again");
    write_scene(&again, &scene, SceneFormat::Transforms).unwrap();
    let text = std::fs::read_to_string(again.join("transforms.json")).unwrap();
    std::fs::write(dir.join("transforms.json"), text).unwrap();
    let re = Scene::load(&dir).unwrap();
    for (x, y) in re.views.iter().zip(&scene.views) {
        assert!((x.camera.center() - y.camera.center()).length() < 1e-5);
        assert!(x.camera.rotation.abs_diff_eq(y.camera.rotation, 1e-6));
    }
    // Distortion and a scaled transform are refused by name.
    let t = example("transforms.json");
    std::fs::write(
        dir.join("transforms.json"),
        t.replace("\"k1\": 0", "\"k1\": 0.1"),
    )
    .unwrap();
    let e = Scene::load(&dir).err().unwrap().to_string();
    assert!(e.contains("transforms.json") && e.contains("\"k1\""), "{e}");
    let scaled = t.replace("[[1, 0, 0, 0]", "[[2, 0, 0, 0]");
    std::fs::write(dir.join("transforms.json"), scaled).unwrap();
    let e = Scene::load(&dir).err().unwrap().to_string();
    assert!(e.contains("frame 0") && e.contains("not a rotation"), "{e}");
}

#[test]
fn example_camera_file_loads() {
    let doc: CameraDoc = serde_json::from_str(&example("camera")).unwrap();
    let cam = doc
        .to_camera(Path::new("docs/formats.md"), "camera")
        .unwrap();
    assert_eq!((cam.width, cam.height), (256, 192));
}

#[test]
fn example_camera_path_loads() {
    let dir = common::tempdir("readme-path");
    let file = dir.join("path.json");
    std::fs::write(&file, example("path")).unwrap();
    let path = CameraPath::load(&file).unwrap();
    assert_eq!(path.duration(), 4.0);
    let l = path.lighting_at(3.0).unwrap();
    assert!((l.dim - 0.75).abs() < 1e-6, "{}", l.dim);
    // The ceiling's factor: 0.2 at 2 s, back to 1 (as captured) at 4 s.
    assert!(
        (l.originals["ceiling"][1] - 0.6).abs() < 1e-6,
        "{:?}",
        l.originals
    );
    let c = path.camera_at(4.0, 64, 48);
    assert!((c.rotation.determinant() - 1.0).abs() < 1e-5);
}

/// What a loader says about one malformed input: it must fail (not panic, not accept) and name
/// `file` and `expect`.
fn refused(what: &str, r: std::thread::Result<Result<(), String>>, file: &str, expect: &str) {
    let e = match r {
        Err(_) => panic!("{what}: the loader panicked"),
        Ok(Ok(())) => panic!("{what}: accepted (expected an error with \"{expect}\")"),
        Ok(Err(e)) => e,
    };
    assert!(e.contains(file) && e.contains(expect), "{what}: {e}");
}

/// Malformed variants of the example scene.json (each one edit), camera file and camera path,
/// plus paths that are not what they claim: every one refused with the file and the problem.
#[test]
fn malformed_hand_written_files_are_refused_by_field() {
    let base = example("scene.json");
    let scene_cases: &[(&str, &str, &str, &str)] = &[
        ("version", "\"version\": 1", "\"version\": 2", "version"),
        ("duplicate view", "\"name\": \"001\"", "\"name\": \"000\"", "000"),
        ("negative radiance", "[20, 14, 8]", "[20, -14, 8]", "radiance"),
        ("huge radiance", "[20, 14, 8]", "[20, 1e39, 8]", "radiance"),
        ("dim out of range", "\"dim\": 0.5", "\"dim\": 1.5", "dim"),
        ("negative intensity", "{ \"lamp\": 1.0 }", "{ \"lamp\": -1.0 }", "lamp"),
        ("preset of an unknown light", "{ \"lamp\": 1.0 }", "{ \"lamb\": 1.0 }", "lamb"),
        ("an original light's intensity", "{ \"lamp\": 1.0 }", "{ \"ceiling\": 1.0 }", "originals"),
        ("an added light's factor", "{ \"ceiling\": [0.6, 0.45, 0.3] }", "{ \"lamp\": 0.5 }", "lamp"),
        ("a negative factor", "[0.6, 0.45, 0.3]", "[0.6, -0.45, 0.3]", "ceiling"),
        ("a factor of four channels", "[0.6, 0.45, 0.3]", "[0.6, 0.45, 0.3, 1]", "factor"),
        ("zero quad edge", "\"edge_u\": [0, 0, 0.6]", "\"edge_u\": [0, 0, 0]", "ceiling"),
        ("camera both ways", "\"look_at\": [0.5, 1.0, -0.5]", "\"look_at\": [0.5, 1.0, -0.5], \"rotation\": [[1,0,0],[0,1,0],[0,0,1]]", "rotation"),
        ("test view look_at at its position", "\"look_at\": [0, 1, -1]", "\"look_at\": [0.2, 1.4, 1.0]", "look_at"),
        ("unknown synthetic field", "\"ground_truth\": \"gt\"", "\"ground_truth\": \"gt\", \"seeds\": 3", "seeds"),
        ("negative focal length", "\"fx\": 40.1, \"fy\": 40.1, \"cx\": 32, \"cy\": 24,\n                  \"position\": [-1.0", "\"fx\": -40.1, \"fy\": 40.1, \"cx\": 32, \"cy\": 24,\n                  \"position\": [-1.0", "fx"),
    ];
    for (i, (what, from, to, expect)) in scene_cases.iter().enumerate() {
        let dir = scene_dir(&format!("hostile-scene-{i}"));
        assert!(base.contains(from), "{what}: the example has no {from:?}");
        std::fs::write(dir.join("scene.json"), base.replacen(from, to, 1)).unwrap();
        let r = std::panic::catch_unwind(|| {
            let s = Scene::load(&dir).map_err(|e| e.to_string())?;
            // Test views are cameras too: render --camera NAME builds them.
            for t in &s.synthetic.as_ref().unwrap().test_views {
                t.camera
                    .to_camera(&dir.join("scene.json"), &t.name)
                    .map_err(|e| e.to_string())?;
            }
            Ok(())
        });
        refused(what, r, "scene.json", expect);
    }

    let cam = example("camera");
    let camera_cases: &[(&str, &str, &str, &str)] = &[
        (
            "look_at parallel to up",
            "\"look_at\": [-0.5, 0.8, -1.0]",
            "\"look_at\": [0.5, 0.5, 1.8], \"up\": [0, 1, 0]",
            "parallel",
        ),
        (
            "no orientation",
            ", \"look_at\": [-0.5, 0.8, -1.0]",
            "",
            "rotation",
        ),
        ("zero height", "\"height\": 192", "\"height\": 0", "height"),
        (
            "unknown field",
            "\"cy\": 96",
            "\"cy\": 96, \"k1\": 0.1",
            "k1",
        ),
    ];
    for (what, from, to, expect) in camera_cases {
        assert!(cam.contains(from), "{what}: the example has no {from:?}");
        let text = cam.replacen(from, to, 1);
        let r = std::panic::catch_unwind(|| {
            let doc: CameraDoc =
                serde_json::from_str(&text).map_err(|e| format!("camera.json: {e}"))?;
            doc.to_camera(Path::new("camera.json"), "camera")
                .map(|_| ())
                .map_err(|e| e.to_string())
        });
        refused(what, r, "camera.json", expect);
    }

    let path = example("path");
    let path_cases: &[(&str, &str, &str, &str)] = &[
        ("dim above 1", "\"dim\": 0.5", "\"dim\": 2", "dim"),
        (
            "zero field of view",
            "\"fov_deg\": 70",
            "\"fov_deg\": 0",
            "fov_deg",
        ),
        (
            "times out of order",
            "\"time\": 4, \"position\"",
            "\"time\": -1, \"position\"",
            "time",
        ),
        (
            "lighting times out of order",
            "\"time\": 2, \"dim\"",
            "\"time\": 0, \"dim\"",
            "lighting[1]",
        ),
        (
            "look_at mixed with rotation",
            "\"look_at\": [0.2, 1.2, -2.5]",
            "\"rotation\": [[1, 0, 0], [0, -1, 0], [0, 0, -1]]",
            "every keyframe",
        ),
        (
            "unknown interpolation",
            "\"catmull-rom\"",
            "\"cubic\"",
            "interpolation",
        ),
        (
            "no keyframes",
            "\"keyframes\": [",
            "\"keyframes\": [], \"unused\": [",
            "unused",
        ),
    ];
    let dir = common::tempdir("hostile-path");
    for (i, (what, from, to, expect)) in path_cases.iter().enumerate() {
        assert!(path.contains(from), "{what}: the example has no {from:?}");
        let file = dir.join(format!("path{i}.json"));
        std::fs::write(&file, path.replacen(from, to, 1)).unwrap();
        let r = std::panic::catch_unwind(|| {
            CameraPath::load(&file)
                .map(|_| ())
                .map_err(|e| e.to_string())
        });
        refused(what, r, &format!("path{i}.json"), expect);
    }
    let file = dir.join("empty.json");
    std::fs::write(&file, "{ \"keyframes\": [] }").unwrap();
    let r = std::panic::catch_unwind(|| {
        CameraPath::load(&file)
            .map(|_| ())
            .map_err(|e| e.to_string())
    });
    refused("no keyframes at all", r, "empty.json", "at least one");
}

/// Paths that are not what they claim get a message that says what they are.
#[test]
fn paths_that_are_not_files_say_what_they_are() {
    use std::os::unix::fs::symlink;
    let dir = scene_dir("hostile-links");
    // The mesh a symlink loop, then a dangling link.
    std::fs::remove_file(dir.join("mesh.ply")).unwrap();
    symlink("mesh.ply", dir.join("mesh.ply")).unwrap();
    let e = Scene::load(&dir).err().unwrap().to_string();
    assert!(e.contains("mesh.ply") && e.contains("symlink loop"), "{e}");
    std::fs::remove_file(dir.join("mesh.ply")).unwrap();
    symlink("gone.ply", dir.join("mesh.ply")).unwrap();
    let e = Scene::load(&dir).err().unwrap().to_string();
    assert!(e.contains("mesh.ply") && e.contains("dangling"), "{e}");
    // A scene "directory" below a file.
    let e = Scene::load(&dir.join("scene.json/inner"))
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("not a directory"), "{e}");
    let e = Scene::load(&dir.join("nowhere")).err().unwrap().to_string();
    assert!(e.contains("nowhere") && e.contains("does not exist"), "{e}");
}

/// A buffer the device cannot hold is refused in the user's terms (its name, its size, what to
/// change), not the allocator's ("Invalid AllocationCreateDesc").
#[test]
fn an_impossible_allocation_names_the_buffer_and_its_size() {
    use relit_engine::gpu::{vk, Buffer, MemoryLocation};
    let gpu = common::gpu();
    let e = Buffer::new(
        &gpu,
        "test views",
        1 << 44,
        vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryLocation::GpuOnly,
    )
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("test views") && e.contains("MiB"), "{e}");
    assert!(!e.contains("AllocationCreateDesc"), "{e}");
    common::assert_no_validation_errors(&gpu);
}

/// A path recorded in the viewer loads with `relit fly`'s loader and passes through every
/// keyframe: camera (position, rotation, field of view), α_dim, intensities and light moves at
/// the keyframes' times; times grow with the distance walked and the angle turned.
#[test]
fn a_recorded_path_replays_its_keyframes() {
    use glam::Vec3;
    use relit_engine::scene::Camera;
    use relit_engine::view::recorder::{Keyframe, PathRecorder, GAP_S, MIN_GAP_S};
    use std::collections::BTreeMap;
    let cam = |p: [f32; 3], at: [f32; 3], fx: f32| {
        Camera::look_at(p.into(), at.into(), Vec3::Y, 64, 48, fx)
    };
    let home: BTreeMap<String, Vec3> = [("lamp".to_string(), Vec3::new(1.0, 2.0, 0.0))].into();
    let key = |c: Camera, dim: f32, lamp: f32, at: Vec3| Keyframe {
        camera: c,
        dim,
        intensities: [("lamp".to_string(), lamp)].into(),
        lights: [("lamp".to_string(), at)].into(),
        // The ceiling at a factor of its own once the lamp is on.
        originals: match lamp {
            0.0 => BTreeMap::new(),
            _ => [("ceiling".to_string(), [lamp / 4.0, 0.5, 0.5])].into(),
        },
    };
    let mut rec = PathRecorder::default();
    rec.add(key(
        cam([0.0, 1.5, 0.0], [0.0, 1.5, -1.0], 40.0),
        1.0,
        0.0,
        home["lamp"],
    ));
    rec.add(key(
        cam([0.0, 1.5, -2.0], [1.0, 1.2, -3.0], 40.0),
        0.3,
        1.0,
        home["lamp"],
    ));
    rec.add(key(
        cam([0.1, 1.5, -2.0], [-1.0, 1.5, -2.5], 55.0),
        0.3,
        2.0,
        Vec3::new(1.5, 2.0, 0.0),
    ));
    let times = rec.times();
    assert_eq!(times[0], 0.0);
    // 2 m at 0.5 m/s is 4 s; the last key turns by ~100° in place: over 2 s at 45°/s.
    assert_eq!(times[1], 4.0);
    assert!(times[2] - times[1] >= 2.0f32.max(MIN_GAP_S));
    assert!(
        times.iter().all(|t| (t / GAP_S).fract() == 0.0),
        "{times:?}"
    );
    let file = common::tempdir("recorded-path").join("path.json");
    rec.save(&file, &home).unwrap();
    let path = CameraPath::load(&file).unwrap();
    for (k, t) in rec.keys.iter().zip(&times) {
        let c = path.camera_at(*t, 64, 48);
        assert!((c.center() - k.camera.center()).length() < 1e-5, "t {t}");
        let r = (c.rotation - k.camera.rotation).to_cols_array();
        assert!(r.iter().all(|v| v.abs() < 1e-4), "t {t}: rotation {r:?}");
        assert!(
            (c.fx - k.camera.fx).abs() < 1e-3,
            "t {t}: fx {} against {}",
            c.fx,
            k.camera.fx
        );
        let l = path.lighting_at(*t).unwrap();
        assert!((l.dim - k.dim).abs() < 1e-6);
        assert!((l.intensities["lamp"] - k.intensities["lamp"]).abs() < 1e-6);
        let want = k.originals.get("ceiling").copied().unwrap_or([1.0; 3]);
        let got = l.originals.get("ceiling").copied().unwrap_or([1.0; 3]);
        assert!(
            (Vec3::from(got) - Vec3::from(want)).abs().max_element() < 1e-6,
            "t {t}"
        );
        let moved = home["lamp"] + l.moves.get("lamp").copied().unwrap_or(Vec3::ZERO);
        assert!(
            (moved - k.lights["lamp"]).length() < 1e-6,
            "t {t}: lamp at {moved}"
        );
    }
    // One keyframe is not a path: refused by name, nothing written.
    let one = PathRecorder {
        keys: rec.keys[..1].to_vec(),
    };
    let f1 = file.with_file_name("one.json");
    let e = one.save(&f1, &home).unwrap_err().to_string();
    assert!(e.contains("one.json") && e.contains("two keyframes"), "{e}");
    assert!(!f1.exists());
}

/// EXIF exposure tags: time and f-number as rationals, ISO.
type ExifExposure = ((u32, u32), (u32, u32), u16);

/// A grey JPEG of `w`×`h`, with EXIF exposure tags if given.
fn jpeg_with_exif(path: &Path, (w, h): (u32, u32), grey: u8, exp: Option<ExifExposure>) {
    let img = image::RgbImage::from_pixel(w, h, image::Rgb([grey; 3]));
    let mut jpg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpg, 100)
        .encode_image(&img)
        .unwrap();
    if let Some((t, n, iso)) = exp {
        use exif::{Field, In, Tag, Value};
        let field = |tag, value| Field {
            tag,
            ifd_num: In::PRIMARY,
            value,
        };
        let fields = [
            field(Tag::ExposureTime, Value::Rational(vec![t.into()])),
            field(Tag::FNumber, Value::Rational(vec![n.into()])),
            field(Tag::PhotographicSensitivity, Value::Short(vec![iso])),
        ];
        let mut writer = exif::experimental::Writer::new();
        fields.iter().for_each(|f| writer.push_field(f));
        let mut tiff = std::io::Cursor::new(Vec::new());
        writer.write(&mut tiff, false).unwrap();
        // An APP1 segment right after the JPEG's start-of-image marker.
        let mut app1 = b"Exif\0\0".to_vec();
        app1.extend(tiff.into_inner());
        let mut out = jpg[..2].to_vec();
        out.extend([0xFF, 0xE1]);
        out.extend(((app1.len() + 2) as u16).to_be_bytes());
        out.extend(app1);
        out.extend(&jpg[2..]);
        jpg = out;
    }
    std::fs::write(path, jpg).unwrap();
}

/// Photos taken at different exposures land on one radiance scale: each is multiplied by the
/// median exposure (t · ISO / N²) over the median of its own; ISO counts like time; a set that
/// mixes photos with and without exposure tags, or a tag that is not a positive number, is an
/// error naming the file (and the tag).
#[test]
fn exif_exposure_puts_photos_on_one_scale() {
    use relit_engine::scene::{exposure, synth};
    let dir = common::tempdir("exif").join("room");
    let opts = synth::SynthOptions {
        views: 3,
        width: 16,
        height: 12,
        ..Default::default()
    };
    synth::write_room(&dir, SceneFormat::Relit, &opts).unwrap();
    let mut scene = Scene::load(&dir).unwrap();
    // 1/100 s, 1/50 s and 1/100 s at ISO 400, all at f/2: exposures 1, 2 and 4.
    let exps = [
        ((1, 100), (2, 1), 100),
        ((1, 50), (2, 1), 100),
        ((1, 100), (2, 1), 400),
    ];
    for (v, e) in scene.views.iter_mut().zip(exps) {
        v.image = v.image.with_extension("jpg");
        jpeg_with_exif(&v.image, (16, 12), 100, Some(e));
    }
    let s = exposure::scales(&scene.views).unwrap();
    assert_eq!(
        s,
        vec![2.0, 1.0, 0.5],
        "the median exposure (2) over each photo's"
    );
    let plain = relit_engine::scene::image::load_rgb(&scene.views[0].image).unwrap();
    let imgs = scene.view_images().unwrap();
    for (img, k) in imgs.iter().zip(&s) {
        let want = plain.pixels[0][0] * k;
        assert!(
            (img.pixels[0][0] - want).abs() < 1e-6 * want.max(1.0),
            "{} vs {want}",
            img.pixels[0][0]
        );
    }
    // One photo without EXIF among photos with it.
    jpeg_with_exif(&scene.views[1].image, (16, 12), 100, None);
    let e = exposure::scales(&scene.views).unwrap_err().to_string();
    assert!(
        e.contains(&scene.views[1].image.display().to_string()) && e.contains("EXIF"),
        "{e}"
    );
    // An f-number of zero.
    jpeg_with_exif(
        &scene.views[1].image,
        (16, 12),
        100,
        Some(((1, 50), (0, 1), 100)),
    );
    let e = exposure::scales(&scene.views).unwrap_err().to_string();
    assert!(e.contains("FNumber") && e.contains("positive"), "{e}");
    // No photo with EXIF (or EXR photos): unchanged.
    for v in &scene.views {
        jpeg_with_exif(&v.image, (16, 12), 100, None);
    }
    assert_eq!(exposure::scales(&scene.views).unwrap(), vec![1.0; 3]);
}

/// 8-bit photos mark the pixels where a channel reached the top codes (≥ 250 of 255: JPEG
/// rings around a saturated region) as clipped; 16-bit PNG at its own top; EXR never clips.
#[test]
fn photos_mark_their_clipped_pixels() {
    use relit_engine::scene::image::{load_photo, write_exr};
    let dir = common::tempdir("clipped");
    let png = dir.join("a.png");
    let px = [[255, 10, 10], [249, 249, 249], [250, 0, 0], [128, 128, 128]];
    let img = image::RgbImage::from_fn(2, 2, |x, y| image::Rgb(px[(y * 2 + x) as usize]));
    img.save(&png).unwrap();
    let p = load_photo(&png).unwrap();
    assert_eq!(p.clipped, [true, false, true, false]);
    assert_eq!(p.clipped_count(), 2);
    assert!(
        (p.image.pixels[0][0] - 1.0).abs() < 1e-6,
        "values stay decoded"
    );

    let png16 = dir.join("b.png");
    let img16 = image::ImageBuffer::<image::Rgb<u16>, _>::from_fn(2, 1, |x, _| {
        image::Rgb([if x == 0 { 65535 } else { 60000 }; 3])
    });
    img16.save(&png16).unwrap();
    assert_eq!(load_photo(&png16).unwrap().clipped, [true, false]);

    // TIFF is linear (a RAW converter's output): no sRGB decoding, clipped at the top code.
    let tif = dir.join("raw.tif");
    let img16 = image::ImageBuffer::<image::Rgb<u16>, _>::from_fn(3, 1, |x, _| {
        image::Rgb([[65535, 30000, 65534][x as usize]; 3])
    });
    img16.save(&tif).unwrap();
    let t = load_photo(&tif).unwrap();
    assert_eq!(t.clipped, [true, false, false]);
    assert!(
        (t.image.pixels[1][0] - 30000.0 / 65535.0).abs() < 1e-6,
        "linear"
    );
    let tif8 = dir.join("eight.tif");
    image::RgbImage::from_pixel(2, 2, image::Rgb([90; 3]))
        .save(&tif8)
        .unwrap();
    let e = load_photo(&tif8).unwrap_err().to_string();
    assert!(e.contains("eight.tif") && e.contains("8-bit TIFF"), "{e}");

    let grey = dir.join("c.png");
    image::RgbImage::from_pixel(3, 2, image::Rgb([90; 3]))
        .save(&grey)
        .unwrap();
    assert!(
        load_photo(&grey).unwrap().clipped.is_empty(),
        "none clipped"
    );

    let exr = dir.join("d.exr");
    let mut bright = relit_engine::scene::RgbImage::new(2, 1);
    bright.pixels[0] = [40.0, 40.0, 40.0];
    write_exr(&exr, &bright).unwrap();
    assert!(
        load_photo(&exr).unwrap().clipped.is_empty(),
        "EXR is radiance"
    );
}
