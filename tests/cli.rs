//! The `relit` binary end to end: exit codes and messages users see.

mod common;

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

#[test]
fn info_reports_features_and_network_path() {
    let (code, out, err) = relit(&["info", "--validate"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("VK_KHR_ray_query (ray query)") && out.contains("network path:"),
        "{out}"
    );
    assert!(!err.contains("validation error"), "{err}");
    if out.contains("llvmpipe") {
        assert!(out.contains("network path: portable"), "{out}");
        let rq = out
            .lines()
            .find(|l| l.contains("VK_KHR_ray_query"))
            .unwrap();
        assert!(rq.trim_end().ends_with("yes"), "{rq}");
        let cm = out
            .lines()
            .find(|l| l.contains("cooperative matrix"))
            .unwrap();
        assert!(cm.trim_end().ends_with("no"), "{cm}");
    }
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
