//! The `relit` binary end to end: exit codes and messages users see.

mod common;

use std::path::Path;

use relit_engine::net::{describe_backend, Storage};
use std::process::Command;

fn relit(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_relit"))
        .args(args)
        .env("RELIT_VALIDATE", "0")
        .output()
        .expect("run relit");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn scene_check_summarises_the_bundled_scene() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/tiny_room");
    let (code, out, err) = relit(&["scene", "check", dir]);
    assert_eq!(code, 0, "{err}");
    for want in [
        "views: 8",
        "resolution: 64x48",
        "triangles",
        "bounds:",
        "lights: 2",
        "presets: 1",
    ] {
        assert!(out.contains(want), "missing \"{want}\" in:\n{out}");
    }
}

#[test]
fn bad_input_exits_non_zero_with_the_file_named() {
    let dir = common::tempdir("cli-bad");
    let (code, _, err) = relit(&["scene", "check", dir.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(
        err.contains(dir.to_str().unwrap()) && err.contains("no scene found"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    std::fs::write(dir.join("scene.json"), "[]").unwrap();
    let (code, _, err) = relit(&["scene", "check", dir.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("scene.json"), "{err}");
    let (code, _, err) = relit(&["scene", "synth", dir.to_str().unwrap(), "--res", "0x5"]);
    assert_eq!(code, 2, "clap usage errors exit 2");
    assert!(err.contains("0x5"), "{err}");
}

/// Output into a pipe closed early (`relit info | head -0`): the process ends without a panic.
#[test]
fn a_closed_stdout_ends_quietly() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_relit"))
        .arg("info")
        .env("RELIT_VALIDATE", "0")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run relit");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("wait");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn info_reports_features_and_network_path() {
    let (code, out, err) = relit(&["info", "--validate"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("VK_KHR_ray_query (ray query)") && out.contains("network path, "),
        "{out}"
    );
    assert!(!err.contains("validation error"), "{err}");
    // The same decision as the kernels', from the same device's capabilities.
    let gpu = common::gpu();
    for storage in [Storage::F16, Storage::F32] {
        let line = format!(
            "network path, {storage:?} storage: {}",
            describe_backend(&gpu.caps, storage)
        );
        assert!(out.contains(&line), "{line}\n{out}");
    }
    let cm = out
        .lines()
        .find(|l| l.contains("cooperative matrix "))
        .unwrap();
    let offered = if gpu.caps.coop_matrix.is_empty() {
        "no"
    } else {
        "yes"
    };
    assert!(cm.trim_end().ends_with(offered), "{cm}");
    let rq = out
        .lines()
        .find(|l| l.contains("VK_KHR_ray_query"))
        .unwrap();
    assert!(rq.trim_end().ends_with("yes"), "{rq}");
}

#[test]
fn bench_rays_runs_on_a_tiny_batch() {
    let dir = common::tempdir("cli-bench");
    let json = dir.join("rays.json");
    let mesh = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/tiny_room/mesh.ply");
    let (code, out, err) = relit(&[
        "bench",
        "rays",
        "--mesh",
        mesh,
        "--rays",
        "512",
        "--repeats",
        "1",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("closest hit") && out.contains("any hit"),
        "{out}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["results"].as_array().unwrap().len(), 2);
    // A closed room: every closest-hit ray from inside hits something.
    assert_eq!(v["results"][0]["hit_fraction"].as_f64().unwrap(), 1.0);
}

/// A scene whose mesh is a FIFO or a character device: refused by name at once (a FIFO used to
/// block forever, /dev/zero to eat all memory).
#[test]
fn special_files_are_refused_without_reading_them() {
    let mut mesh = String::new();
    let dir = demo_with("cli-special-files", |d| {
        mesh = d["mesh"].as_str().unwrap().into()
    });
    for (name, make) in [("FIFO", "fifo"), ("character device", "zero")] {
        let _ = std::fs::remove_file(dir.join(&mesh));
        if make == "fifo" {
            let ok = std::process::Command::new("mkfifo")
                .arg(dir.join(&mesh))
                .status()
                .is_ok_and(|s| s.success());
            if !ok {
                continue;
            }
        } else {
            std::os::unix::fs::symlink("/dev/zero", dir.join(&mesh)).unwrap();
        }
        let t = std::time::Instant::now();
        let (code, _, err) = relit(&["scene", "check", dir.to_str().unwrap()]);
        assert_eq!(code, 1, "{err}");
        assert!(err.contains(&mesh) && err.contains(name), "{err}");
        assert!(t.elapsed().as_secs() < 30, "took {:?}", t.elapsed());
    }
}

/// A frame too small for the network's pyramid is an error at once (a side under 16 pixels
/// wrapped a size around and the network never returned).
#[test]
fn network_too_small_for_its_pyramid_says_so() {
    let t = std::time::Instant::now();
    let (code, _, err) = relit(&["bench", "net", "--width", "8", "--res", "16x12"]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("16x12 is too small for 5 pyramid levels"),
        "{err}"
    );
    assert!(t.elapsed().as_secs() < 60, "took {:?}", t.elapsed());
}

/// A path whose keyframes span 1e9 s is refused before anything renders (it wrote frames until
/// the disk filled); `--max-frames` raises the bound.
#[test]
fn fly_refuses_a_path_longer_than_max_frames() {
    let dir = common::tempdir("cli-long-path");
    let path = dir.join("long.json");
    let key = |t: f64, x: f64| serde_json::json!({ "time": t, "position": [x, 1.5, 0.0], "look_at": [0.0, 1.0, 1.0], "fov_deg": 60.0 });
    let doc = serde_json::json!({ "interpolation": "linear", "keyframes": [key(0.0, 0.0), key(1e9, 1.0)] });
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/demo_room");
    let out = dir.join("frames");
    let t = std::time::Instant::now();
    let (code, _, err) = relit(&[
        "fly",
        scene.to_str().unwrap(),
        "--path",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("long.json") && err.contains("--max-frames 100000"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written");
    assert!(t.elapsed().as_secs() < 30, "took {:?}", t.elapsed());
}

/// `--camera FILE` gets the same checks as the cameras of scene.json: a zero or infinite focal
/// length, a zero width, a rotation that is not orthonormal are refused by field.
#[test]
fn camera_files_are_validated_like_scene_cameras() {
    let dir = common::tempdir("cli-bad-camera");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/demo_room");
    let base = serde_json::json!({
        "width": 64, "height": 48, "fx": 50.0, "fy": 50.0, "cx": 32.0, "cy": 24.0,
        "position": [0.0, 1.5, 0.0],
        "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    });
    let cases: [(&str, serde_json::Value, &str); 4] = [
        ("fx0", serde_json::json!({ "fx": 0.0 }), "fx"),
        ("fxinf", serde_json::json!({ "fx": 1e39 }), "fx"),
        ("w0", serde_json::json!({ "width": 0 }), "image size"),
        (
            "skew",
            serde_json::json!({ "rotation": [[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]] }),
            "rotation",
        ),
    ];
    for (name, patch, want) in cases {
        let mut doc = base.clone();
        for (k, v) in patch.as_object().unwrap() {
            doc[k] = v.clone();
        }
        let f = dir.join(format!("{name}.json"));
        std::fs::write(&f, serde_json::to_vec(&doc).unwrap()).unwrap();
        let (code, _, err) = relit(&[
            "render",
            scene.to_str().unwrap(),
            "--camera",
            f.to_str().unwrap(),
            "--out",
            dir.join("x.png").to_str().unwrap(),
        ]);
        assert_eq!(code, 1, "{name}: {err}");
        assert!(
            err.contains(&format!("{name}.json")) && err.contains(want),
            "{name}: {err}"
        );
    }
}

/// The bundled scene in a temp dir with scene.json passed through `edit` (everything else
/// linked).
fn demo_with(name: &str, edit: impl FnOnce(&mut serde_json::Value)) -> std::path::PathBuf {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/demo_room");
    let dir = common::tempdir(name);
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(src.join("scene.json")).unwrap()).unwrap();
    edit(&mut doc);
    std::fs::write(dir.join("scene.json"), serde_json::to_vec(&doc).unwrap()).unwrap();
    for e in std::fs::read_dir(&src).unwrap() {
        let e = e.unwrap().file_name();
        if e != "scene.json" && e != ".relit" {
            std::os::unix::fs::symlink(src.join(&e), dir.join(&e)).unwrap();
        }
    }
    dir
}

/// Lights with a duplicate name, a negative radius, a zero normal or parallel edges fail
/// `scene check`, naming the light and the field.
#[test]
fn bad_lights_are_refused_by_name_and_field() {
    let disk = |name: &str, normal: [f32; 3], radius: f32| {
        serde_json::json!({ "shape": "disk", "name": name, "center": [0.0, 1.0, 0.0],
            "normal": normal, "radius": radius, "radiance": [5.0, 5.0, 5.0] })
    };
    let cases: [(&str, serde_json::Value, &str); 4] = [
        (
            "dup",
            disk("ceiling0", [0.0, -1.0, 0.0], 0.1),
            "ceiling0 appears twice",
        ),
        ("negr", disk("lamp", [0.0, -1.0, 0.0], -0.1), "radius -0.1"),
        (
            "zeron",
            disk("lamp", [0.0, 0.0, 0.0], 0.1),
            "normal is zero",
        ),
        (
            "flat",
            serde_json::json!({ "shape": "quad", "name": "lamp", "corner": [0.0, 1.0, 0.0],
                "edge_u": [0.2, 0.0, 0.0], "edge_v": [0.4, 0.0, 0.0], "radiance": [5.0, 5.0, 5.0] }),
            "span no area",
        ),
    ];
    for (name, light, want) in cases {
        let dir = demo_with(&format!("cli-light-{name}"), |d| {
            d["lights"].as_array_mut().unwrap().push(light)
        });
        let (code, _, err) = relit(&["scene", "check", dir.to_str().unwrap()]);
        assert_eq!(code, 1, "{name}: {err}");
        assert!(
            err.contains("scene.json") && err.contains(want),
            "{name}: {err}"
        );
    }
}

/// Path keyframes with an infinite look_at, a look_at straight above, a skewed rotation or a
/// negative intensity are refused before anything renders.
#[test]
fn bad_path_keyframes_are_refused() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/demo_room");
    let dir = common::tempdir("cli-bad-paths");
    let key = |t: f64, look: serde_json::Value| serde_json::json!({ "time": t, "position": [0.0, 1.5, 0.0], "look_at": look, "fov_deg": 60.0 });
    let ok = serde_json::json!([1.0, 1.0, 1.0]);
    let cases: [(&str, serde_json::Value, &str); 4] = [
        (
            "inf",
            serde_json::json!({ "keyframes": [key(0.0, serde_json::json!([1e39, 1.0, 1.0])), key(1.0, ok.clone())] }),
            "look_at must be finite",
        ),
        (
            "up",
            serde_json::json!({ "keyframes": [key(0.0, serde_json::json!([0.0, 3.0, 0.0])), key(1.0, ok.clone())] }),
            "straight above or below",
        ),
        (
            "skew",
            serde_json::json!({ "keyframes": [
                { "time": 0.0, "position": [0.0, 1.5, 0.0], "rotation": [[1.0, 0.3, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "fov_deg": 60.0 },
                { "time": 1.0, "position": [0.0, 1.5, 0.0], "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "fov_deg": 60.0 }] }),
            "rotation must be a rotation matrix",
        ),
        (
            "negk",
            serde_json::json!({ "keyframes": [key(0.0, ok.clone()), key(1.0, ok.clone())],
                "lighting": [{ "time": 0.0, "dim": 0.0, "intensities": { "extra0": -1.0 } }] }),
            "intensities.extra0 = -1",
        ),
    ];
    for (name, mut doc, want) in cases {
        doc["interpolation"] = serde_json::json!("linear");
        let f = dir.join(format!("{name}.json"));
        std::fs::write(&f, serde_json::to_vec(&doc).unwrap()).unwrap();
        let (code, _, err) = relit(&[
            "fly",
            scene.to_str().unwrap(),
            "--path",
            f.to_str().unwrap(),
            "--out",
            dir.join(name).to_str().unwrap(),
        ]);
        assert_eq!(code, 1, "{name}: {err}");
        assert!(
            err.contains(&format!("{name}.json")) && err.contains(want),
            "{name}: {err}"
        );
    }
}

#[test]
fn mesh_option_gives_a_capture_its_proxy() {
    let root = common::tempdir("cli-mesh");
    let dir = root.join("capture");
    let d = dir.to_str().unwrap();
    let (code, _, err) = relit(&["scene", "synth", d, "--format", "colmap", "--views", "3"]);
    assert_eq!(code, 0, "{err}");
    // The mesh made elsewhere, as a user's MVS tool would leave it.
    let mesh = root.join("from_mvs.ply");
    std::fs::rename(dir.join("mesh.ply"), &mesh).unwrap();
    let (code, _, err) = relit(&["scene", "check", "--quick", d]);
    assert_ne!(code, 0);
    assert!(err.contains("no mesh found"), "{err}");
    let m = mesh.to_str().unwrap();
    let (code, out, err) = relit(&["scene", "check", "--quick", d, "--mesh", m]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains(&format!("mesh: {m}")), "{out}");
    let (code, _, err) = relit(&["scene", "check", "--quick", d, "--mesh", "nowhere.ply"]);
    assert_ne!(code, 0);
    assert!(err.contains("nowhere.ply"), "{err}");
    let (code, _, err) = relit(&["dataset", d, "--mesh", m]);
    assert_ne!(code, 0);
    assert!(err.contains("--mesh"), "{err}");
}
