//! `relit render`, `fly` and `dump` end to end on a tiny baked scene (the procedural test room,
//! 6 views at 32×24, a cheap preview bake), validation on when installed.

mod common;

use std::path::Path;
use std::process::Command;

fn relit(args: &[&str]) -> (i32, String, String) {
    common::run_relit(args)
}

fn ok(args: &[&str]) -> String {
    let (code, so, se) = relit(args);
    assert_eq!(code, 0, "relit {args:?} failed:\n{so}\n{se}");
    so + &se
}

/// The tiny room, baked, in a directory of its own named `name` (tests change their copy). The
/// bake (its per-mesh caches are most of a test's time) runs once per test binary.
fn baked_tiny(name: &str) -> std::path::PathBuf {
    static BAKED: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();
    let s = common::tempdir(name).join("room");
    common::copy_dir(BAKED.get_or_init(bake_tiny), &s);
    s
}

fn bake_tiny() -> std::path::PathBuf {
    let s = common::tempdir("baked-template").join("room");
    let sp = s.to_str().unwrap();
    ok(&["scene", "synth", sp, "--views", "6", "--res", "32x24"]);
    // Before the bake: a clear error that says what to run.
    let (code, _, se) = relit(&["render", sp, "--camera", "0", "--out", "/tmp/x.png"]);
    assert_ne!(code, 0);
    assert!(se.contains("relit bake"), "{se}");
    ok(&[
        "bake",
        sp,
        "--quality",
        "preview",
        "--rays",
        "8",
        "--added-samples",
        "2",
    ]);
    s
}

fn png(path: &Path) -> image::RgbImage {
    image::open(path).unwrap().to_rgb8()
}

#[test]
fn render_fly_dump_on_a_tiny_baked_scene() {
    let s = baked_tiny("fly");
    let sp = s.to_str().unwrap();
    let d = s.parent().unwrap();
    let out_png = d.join("v0.png");
    let notice = ok(&[
        "render",
        sp,
        "--camera",
        "0",
        "--out",
        out_png.to_str().unwrap(),
        "--maps",
        "bc6h",
    ]);
    let default = format!("({:?})", relit_engine::frame::DEFAULT_MODE);
    assert!(
        notice.contains(&default) && !notice.contains("notice"),
        "the default mode renders by default: {notice}"
    );
    let img = png(&out_png);
    assert_eq!(img.dimensions(), (32, 24));
    let lit = img.pixels().filter(|p| p.0.iter().any(|&c| c > 8)).count();
    assert!(lit * 2 > 32 * 24, "most pixels show the room");
    // ULR at an input view's own camera reproduces that view: w1 = 1/|c_new - c_i|^2 makes
    // it dominate the I_1 blend, sampled at its texel centres.
    let exr = d.join("v0.exr");
    ok(&[
        "render",
        sp,
        "--camera",
        "0",
        "--out",
        exr.to_str().unwrap(),
        "--lighting",
        "lamp_on_dimmed",
        "--maps",
        "rgba16f",
        "--mode",
        "ulr",
    ]);
    let scene = relit_engine::scene::Scene::load(&s).unwrap();
    let input = relit_engine::scene::image::load_rgb(&scene.views[0].image).unwrap();
    let got = relit_engine::scene::image::load_rgb(&exr).unwrap();
    let (mut diff, mut sum) = (0f64, 0f64);
    for (a, b) in got.pixels.iter().zip(&input.pixels) {
        for k in 0..3 {
            diff += (a[k] - b[k]).abs() as f64;
            sum += b[k].abs() as f64;
        }
    }
    // Half-float maps and EXR: 1% of the mean.
    assert!(
        diff <= 0.01 * sum,
        "ULR at an input camera: relative difference {}",
        diff / sum
    );

    // A path with camera and lighting keyframes.
    let path = d.join("path.json");
    std::fs::write(
        &path,
        r#"{ "interpolation": "catmull-rom",
             "keyframes": [
               { "time": 0.0, "position": [0.0, 1.4, 1.2], "look_at": [0.0, 1.0, -1.0], "fov_deg": 70 },
               { "time": 0.5, "position": [0.3, 1.4, 1.0], "look_at": [0.2, 1.0, -1.0], "fov_deg": 65 },
               { "time": 1.0, "position": [0.5, 1.5, 0.8], "look_at": [0.4, 1.0, -1.0], "fov_deg": 60 } ],
             "lighting": [ { "time": 0.0, "dim": 0.0 }, { "time": 1.0, "dim": 0.5, "intensities": { "lamp": 1.0 } } ] }"#,
    )
    .unwrap();
    let pp = path.to_str().unwrap();
    let (f1, f2) = (d.join("frames1"), d.join("frames2"));
    for f in [&f1, &f2] {
        let log = ok(&[
            "fly",
            sp,
            "--path",
            pp,
            "--out",
            f.to_str().unwrap(),
            "--res",
            "32x24",
            "--fps",
            "4",
        ]);
        // Not on a terminal: a plain progress line (at least the last frame's).
        assert!(log.contains("fly: frames 5/5 (100%)"), "{log}");
    }
    let n = std::fs::read_dir(&f1).unwrap().count();
    assert_eq!(n, 5, "1 s at 4 fps: frames at t = 0, 0.25, …, 1");
    for i in 0..n {
        let name = format!("frame{i:05}.png");
        assert_eq!(
            std::fs::read(f1.join(&name)).unwrap(),
            std::fs::read(f2.join(&name)).unwrap(),
            "{name}: the same inputs give the same frames"
        );
    }
    assert_ne!(
        std::fs::read(f1.join("frame00000.png")).unwrap(),
        std::fs::read(f1.join("frame00004.png")).unwrap(),
        "the camera and the lighting move"
    );
    if Command::new("ffmpeg").arg("-version").output().is_ok() {
        let mp4 = d.join("fly.mp4");
        ok(&[
            "fly",
            sp,
            "--path",
            pp,
            "--out",
            mp4.to_str().unwrap(),
            "--res",
            "32x24",
            "--fps",
            "4",
        ]);
        let b = std::fs::read(&mp4).unwrap();
        assert!(b.len() > 100 && &b[4..8] == b"ftyp", "an MP4 file");
    }

    // dump: the 66-channel input as safetensors, with the channel order in the metadata.
    let dump = d.join("v1.safetensors");
    ok(&["dump", sp, "--camera", "1", "--out", dump.to_str().unwrap()]);
    let bytes = std::fs::read(&dump).unwrap();
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let t = st.tensor("input").unwrap();
    assert_eq!(t.shape(), &[66, 24, 32]);
    let v: Vec<f32> = bytemuck::pod_collect_to_vec(t.data());
    assert!(v.iter().all(|x| x.is_finite()));
    let (_, meta) = safetensors::SafeTensors::read_metadata(&bytes).unwrap();
    let ch = meta
        .metadata()
        .as_ref()
        .unwrap()
        .get("relit.channels")
        .unwrap();
    assert!(ch.starts_with("[\"I_1.r\""), "{ch}");
    let left = meta
        .metadata()
        .as_ref()
        .unwrap()
        .get("relit.left_out_view")
        .unwrap();
    assert_ne!(
        left, "none",
        "an input camera is left out of its own inputs"
    );

    // Bad input: names what is wrong.
    let (code, _, se) = relit(&["render", sp, "--camera", "99", "--out", "/tmp/x.png"]);
    assert_ne!(code, 0);
    assert!(se.contains("99") && se.contains("6 views"), "{se}");
    let (code, _, se) = relit(&["render", sp, "--camera", "0", "--out", "/tmp/x.tiff"]);
    assert_ne!(code, 0);
    assert!(se.contains(".exr or .png"), "{se}");
    // Named weights are checked in every mode, the baselines too, not ignored.
    for mode in ["network", "ulr"] {
        let (code, _, se) = relit(&[
            "render",
            sp,
            "--camera",
            "0",
            "--weights",
            pp,
            "--mode",
            mode,
            "--out",
            "/tmp/x.png",
        ]);
        assert_ne!(code, 0, "{mode}");
        assert!(
            se.contains("path.json") && se.contains("safetensors"),
            "{mode}: {se}"
        );
    }
    std::fs::write(
        &path,
        r#"{ "keyframes": [ { "time": 0, "position": [0,1,0], "fov_deg": 70 } ] }"#,
    )
    .unwrap();
    let (code, _, se) = relit(&["fly", sp, "--path", pp, "--out", f1.to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(se.contains("path.json") && se.contains("look_at"), "{se}");
}

/// `relit view` under Xvfb: the window's last frame, read back from the swapchain image,
/// equals `relit render` of the same camera (the viewer blits 1:1 at its start size).
#[test]
fn view_shows_the_scene_in_a_window_under_xvfb() {
    assert!(
        Command::new("xvfb-run").arg("--help").output().is_ok(),
        "xvfb-run is missing: run tools/setup.sh (Debian package xvfb)"
    );
    let s = baked_tiny("view");
    let sp = s.to_str().unwrap();
    let d = s.parent().unwrap();
    let (shot, want) = (d.join("shot.png"), d.join("render.png"));
    let args = [
        &PLAIN[..],
        &["--res", "64x48", "--camera", "0", "--frames", "3"],
    ]
    .concat();
    let (a, so) = run_view(&s, &args, &shot);
    assert!(so.contains("the window's picture"), "{so}");
    ok(&[
        "render",
        sp,
        "--camera",
        "0",
        "--res",
        "64x48",
        "--out",
        want.to_str().unwrap(),
    ]);
    let b = png(&want);
    assert_eq!(a.dimensions(), (64, 48));
    let lit = a.pixels().filter(|p| p.0.iter().any(|&c| c > 8)).count();
    assert!(
        lit * 2 > 64 * 48,
        "the window shows the room, not a blank frame"
    );
    let worst = a
        .pixels()
        .zip(b.pixels())
        .flat_map(|(p, q)| (0..3).map(move |k| (p.0[k] as i32 - q.0[k] as i32).abs()))
        .max()
        .unwrap();
    assert!(
        worst <= 1,
        "window and render differ by up to {worst} code values"
    );
}

/// The viewer's settings for comparing pixels: the window as large as the frame, the full
/// frame every time, no HUD.
const PLAIN: [&str; 5] = ["--window", "64x48", "--fluid", "still", "--no-hud"];

/// Runs `relit view SCENE ARGS --screenshot SHOT` under Xvfb (validation on when installed), in
/// SHOT's directory (where P saves its screenshots); returns the last frame and stdout.
fn run_view(scene: &Path, args: &[&str], shot: &Path) -> (image::RgbImage, String) {
    let entry = relit_engine::gpu::load_entry().unwrap();
    let validate = relit_engine::gpu::validation_layer_available(&entry);
    let out = Command::new("xvfb-run")
        .current_dir(shot.parent().unwrap())
        .args([
            "-a",
            "-s",
            "-screen 0 640x480x24",
            env!("CARGO_BIN_EXE_relit"),
        ])
        .args(["view", scene.to_str().unwrap()])
        .args(args)
        .arg("--screenshot")
        .arg(shot)
        .env("RELIT_VALIDATE", if validate { "1" } else { "0" })
        .output()
        .unwrap();
    let se = String::from_utf8_lossy(&out.stderr);
    let so = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "relit view {args:?} failed:\n{so}\n{se}"
    );
    assert!(!se.contains("[vulkan validation error]"), "{se}");
    (png(shot), so)
}

/// `relit view` with scripted keys, 64×48 from view 0, ratio mode (so lighting shows).
fn view_frame(scene: &Path, keys: &str, frames: u32, shot: &Path) -> image::RgbImage {
    let frames = frames.to_string();
    let args = [
        "--res", "64x48", "--camera", "0", "--mode", "ratio", "--frames", &frames,
    ];
    run_view(
        scene,
        &[&PLAIN[..], &args[..], &["--keys", keys]].concat(),
        shot,
    )
    .0
}

/// Per pixel, how much brighter `a` is than `b` (sum over channels, code values).
fn brighter(a: &image::RgbImage, b: &image::RgbImage) -> Vec<f32> {
    a.pixels()
        .zip(b.pixels())
        .map(|(p, q)| {
            (0..3)
                .map(|k| p.0[k] as f32 - q.0[k] as f32)
                .sum::<f32>()
                .max(0.0)
        })
        .collect()
}

/// The x coordinate of the brightening's centre of mass, and its total.
fn centroid_x(d: &[f32], w: usize) -> (f32, f32) {
    let total: f32 = d.iter().sum();
    let x = d
        .iter()
        .enumerate()
        .map(|(i, v)| (i % w) as f32 * v)
        .sum::<f32>()
        / total.max(1e-6);
    (x, total)
}

/// The viewer adds a lamp where its centre looks (N), moves it (J: 10 cm left per press), and
/// the frame lights up there and follows it; F5 saves it to scene.json, and `relit render` then
/// bakes the new light on demand and renders its preset.
#[test]
fn view_adds_and_moves_a_light_under_xvfb() {
    let s = baked_tiny("view-lights");
    let d = s.parent().unwrap().to_path_buf();
    let base = view_frame(&s, "", 3, &d.join("base.png"));
    let lit = view_frame(&s, "1:N", 4, &d.join("lit.png"));
    let moved = view_frame(&s, "1:N,2:J,2:J,2:J,2:J", 5, &d.join("moved.png"));
    let w = base.width() as usize;
    let (x_lit, sum_lit) = centroid_x(&brighter(&lit, &base), w);
    let (x_moved, sum_moved) = centroid_x(&brighter(&moved, &base), w);
    eprintln!("brightening: at x {x_lit:.1} (sum {sum_lit:.0}), moved: x {x_moved:.1} (sum {sum_moved:.0})");
    assert!(
        sum_lit > 2000.0,
        "the new lamp must light the frame ({sum_lit})"
    );
    assert!(
        (x_lit - w as f32 / 2.0).abs() < w as f32 / 4.0,
        "the lamp lights where the centre looked (x {x_lit:.1} of {w})"
    );
    assert!(sum_moved > 2000.0);
    assert!(
        x_moved < x_lit - 2.0,
        "moved 40 cm left, its light must move left: {x_lit:.1} → {x_moved:.1}"
    );

    // Save (F5), then render the saved preset: the lamp is baked on demand.
    let _ = view_frame(&s, "1:N,2:F5", 4, &d.join("saved.png"));
    let text = std::fs::read_to_string(s.join("scene.json")).unwrap();
    assert!(
        text.contains("lamp") && text.contains("\"viewer\""),
        "{text}"
    );
    let out = d.join("viewer.png");
    let log = ok(&[
        "render",
        s.to_str().unwrap(),
        "--camera",
        "0",
        "--res",
        "64x48",
        "--mode",
        "ratio",
        "--lighting",
        "viewer",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(log.contains("baking light(s) lamp"), "{log}");
    let (x, sum) = centroid_x(&brighter(&png(&out), &base), w);
    eprintln!("baked lamp: brightening at x {x:.1} (sum {sum:.0})");
    assert!(sum > 2000.0 && (x - x_lit).abs() < w as f32 / 8.0);
}

/// A light the bake left out (`relit bake` bakes the presets' lights; here its entry is
/// removed) is traced live when a preset turns it on in the viewer: the frame brightens at
/// once, and the viewer writes no entry (it bakes nothing).
#[test]
fn view_traces_a_light_the_bake_left_out_live_under_xvfb() {
    let s = baked_tiny("view-unbaked");
    let d = s.parent().unwrap().to_path_buf();
    let entries = || -> Vec<std::path::PathBuf> {
        let mut v = Vec::new();
        for b in std::fs::read_dir(s.join(".relit")).unwrap() {
            for e in std::fs::read_dir(b.unwrap().path()).unwrap() {
                let p = e.unwrap().path();
                if p.file_name()
                    .unwrap()
                    .to_string_lossy()
                    .starts_with("light-")
                {
                    v.push(p);
                }
            }
        }
        v
    };
    for e in entries() {
        std::fs::remove_dir_all(e).unwrap();
    }
    // Preset 1 lights the lamp at 1 and dims the original to ½: compare with the frame of the
    // same preset where the lamp is off, so only the lamp's light counts.
    let lit = view_frame(&s, "1:1", 4, &d.join("lit.png"));
    let off = view_frame(
        &s,
        "1:1,1:Minus,1:Minus,1:Minus,1:Minus,1:Minus,1:Minus,1:Minus,1:Minus,1:Minus,1:Minus",
        4,
        &d.join("off.png"),
    );
    let (_, sum) = centroid_x(&brighter(&lit, &off), lit.width() as usize);
    eprintln!("the live lamp brightens the frame by {sum:.0}");
    assert!(sum > 2000.0, "the lamp must light the frame ({sum})");
    assert!(entries().is_empty(), "the viewer baked {:?}", entries());
}

/// A camera path may move an added light (`moves` in its lighting keyframes): `fly` renders it
/// where the path has it, close to a render of a scene with the light baked at that place.
#[test]
fn fly_moves_a_light_along_the_path() {
    let s = baked_tiny("fly-moves");
    let d = s.parent().unwrap().to_path_buf();
    let sp = s.to_str().unwrap();
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(s.join("scene.json")).unwrap()).unwrap();
    let cam = &doc["views"][0]["camera"];
    let (pos, rot) = (cam["position"].clone(), cam["rotation"].clone());
    let key =
        |t: f32| serde_json::json!({ "time": t, "position": pos, "rotation": rot, "fov_deg": 70 });
    let delta = [-0.6, 0.0, 0.3];
    let path = serde_json::json!({
        "interpolation": "linear",
        "keyframes": [key(0.0), key(1.0)],
        "lighting": [
            { "time": 0, "dim": 1.0, "intensities": { "lamp": 1.0 } },
            { "time": 1, "dim": 1.0, "intensities": { "lamp": 1.0 }, "moves": { "lamp": delta } }
        ]
    });
    let pp = d.join("moves.json");
    std::fs::write(&pp, path.to_string()).unwrap();
    let frames = d.join("frames");
    ok(&[
        "fly",
        sp,
        "--path",
        pp.to_str().unwrap(),
        "--out",
        frames.to_str().unwrap(),
        "--res",
        "64x48",
        "--fps",
        "2",
        "--mode",
        "ratio",
    ]);
    let (f0, f2) = (
        png(&frames.join("frame00000.png")),
        png(&frames.join("frame00002.png")),
    );

    // The same light baked at the moved place (scene.json edited; render bakes it on demand).
    let mut doc = doc.clone();
    for l in doc["lights"].as_array_mut().unwrap() {
        if l["name"] == "lamp" {
            for k in 0..3 {
                let v = l["center"][k].as_f64().unwrap();
                l["center"][k] = serde_json::json!(v + delta[k]);
            }
        }
    }
    std::fs::write(
        s.join("scene.json"),
        serde_json::to_vec_pretty(&doc).unwrap(),
    )
    .unwrap();
    let preset_path = d.join("still.json");
    std::fs::write(
        &preset_path,
        serde_json::json!({
            "interpolation": "linear",
            "keyframes": [key(0.0), key(1.0)],
            "lighting": [{ "time": 0, "dim": 1.0, "intensities": { "lamp": 1.0 } }]
        })
        .to_string(),
    )
    .unwrap();
    let still = d.join("still");
    let log = ok(&[
        "fly",
        sp,
        "--path",
        preset_path.to_str().unwrap(),
        "--out",
        still.to_str().unwrap(),
        "--res",
        "64x48",
        "--fps",
        "1",
        "--mode",
        "ratio",
    ]);
    assert!(log.contains("baking light(s) lamp"), "{log}");
    let baked = png(&still.join("frame00000.png"));
    let diff = |a: &image::RgbImage, b: &image::RgbImage| -> f64 {
        a.pixels()
            .zip(b.pixels())
            .flat_map(|(p, q)| (0..3).map(move |k| (p.0[k] as f64 - q.0[k] as f64).abs()))
            .sum::<f64>()
            / (a.width() * a.height() * 3) as f64
    };
    let (moved_vs_start, moved_vs_baked) = (diff(&f2, &f0), diff(&f2, &baked));
    eprintln!("mean |Δ| code values: moved vs start {moved_vs_start:.2}, moved vs baked there {moved_vs_baked:.2}");
    assert!(
        moved_vs_start > 2.0,
        "moving the light must change the frame"
    );
    assert!(
        moved_vs_baked < 0.35 * moved_vs_start,
        "the moved light must look like the light baked there"
    );
}

/// `render --batch`: several cameras and modes from one load give the files single renders
/// give; a bad batch file is an error that names the file and the render.
#[test]
fn render_batch_equals_single_renders_and_names_bad_entries() {
    let s = baked_tiny("batch");
    let sp = s.to_str().unwrap();
    let d = s.parent().unwrap();
    let jobs = d.join("jobs.json");
    let out = |n: &str| d.join(n).to_str().unwrap().to_string();
    let doc = serde_json::json!([
        { "camera": "1", "mode": "ratio", "out": out("b_ratio.exr") },
        { "camera": "2", "mode": "ulr", "out": out("b_ulr.exr") },
        { "camera": "1", "mode": "network", "out": out("b_net.exr") },
    ]);
    std::fs::write(&jobs, serde_json::to_vec(&doc).unwrap()).unwrap();
    ok(&["render", sp, "--batch", jobs.to_str().unwrap()]);
    for (cam, mode, name) in [
        ("1", "ratio", "b_ratio"),
        ("2", "ulr", "b_ulr"),
        ("1", "network", "b_net"),
    ] {
        let single = out(&format!("s_{name}.exr"));
        ok(&[
            "render", sp, "--camera", cam, "--mode", mode, "--out", &single,
        ]);
        assert_eq!(
            std::fs::read(out(&format!("{name}.exr"))).unwrap(),
            std::fs::read(&single).unwrap(),
            "{name}: the batch render differs from the single one"
        );
    }
    std::fs::write(
        &jobs,
        br#"[{"camera": "1", "mode": "fancy", "out": "x.exr"}]"#,
    )
    .unwrap();
    let (code, _, err) = relit(&["render", sp, "--batch", jobs.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("jobs.json") && err.contains("render 0") && err.contains("fancy"),
        "{err}"
    );
    std::fs::write(&jobs, br#"[{"mode": "ulr", "out": "x.exr"}]"#).unwrap();
    let (_, _, err) = relit(&["render", sp, "--batch", jobs.to_str().unwrap()]);
    assert!(err.contains("\"camera\" is missing"), "{err}");
}

/// Pixels whose largest channel difference exceeds 2 code values, and the mean difference.
fn differ(a: &image::RgbImage, b: &image::RgbImage) -> (usize, f64) {
    assert_eq!(a.dimensions(), b.dimensions());
    let d: Vec<i32> = (a.pixels().zip(b.pixels()))
        .map(|(p, q)| {
            (0..3)
                .map(|k| (p.0[k] as i32 - q.0[k] as i32).abs())
                .max()
                .unwrap()
        })
        .collect();
    let mean = d.iter().sum::<i32>() as f64 / d.len() as f64;
    (d.iter().filter(|&&v| v > 2).count(), mean)
}

/// A path recorded in the viewer with scripted keys (walk, strafe, a lighting preset, dimming;
/// R drops keyframes, P takes screenshots there) is written on exit; `relit fly` renders it, and
/// its frames at the keyframes' times equal the viewer's screenshots there (tolerance: at most
/// 1% of pixels more than 2 code values apart, from the interpolated rotation's rounding).
/// `--play` paused at the start shows fly's first frame.
#[test]
fn view_records_a_path_that_fly_replays_under_xvfb() {
    let s = baked_tiny("view-record");
    let (sp, d) = (s.to_str().unwrap(), s.parent().unwrap().to_path_buf());
    let path = d.join("walk.json");
    let keys = "1:R,1:P,2:+W,4:-W,5:+D,6:-D,7:1,7:[,7:[,8:R,8:P,9:+A,10:-A,11:+E,12:-E,13:R,13:P";
    let base = ["--res", "64x48", "--camera", "0", "--mode", "ratio"];
    let rec = [
        "--frames",
        "15",
        "--keys",
        keys,
        "--record",
        path.to_str().unwrap(),
    ];
    let (_, so) = run_view(&s, &[&PLAIN[..], &base, &rec].concat(), &d.join("last.png"));
    assert!(
        so.contains("keyframe 3") && so.contains("(3 keyframes"),
        "{so}"
    );
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let times: Vec<f64> = (doc["keyframes"].as_array().unwrap().iter())
        .map(|k| k["time"].as_f64().unwrap())
        .collect();
    assert_eq!(times.len(), 3);
    let frames = d.join("fly");
    let fly = [
        "fly",
        sp,
        "--path",
        path.to_str().unwrap(),
        "--out",
        frames.to_str().unwrap(),
    ];
    ok(&[
        &fly[..],
        &["--res", "64x48", "--fps", "4", "--mode", "ratio"],
    ]
    .concat());
    let shots: Vec<image::RgbImage> = (1..=3)
        .map(|k| png(&d.join(format!("relit-screenshot-{k:03}.png"))))
        .collect();
    for (k, t) in times.iter().enumerate() {
        let frame = png(&frames.join(format!("frame{:05}.png", (t * 4.0).round() as usize)));
        let (n, mean) = differ(&shots[k], &frame);
        eprintln!("keyframe {k} at {t} s: {n} pixels differ by more than 2, mean {mean:.3}");
        assert!(
            n * 100 <= 64 * 48 && mean < 1.0,
            "keyframe {k}: {n} pixels, mean {mean}"
        );
    }
    let (n, mean) = differ(&shots[0], &shots[1]);
    assert!(
        n > 64 * 48 / 10 && mean > 2.0,
        "the keyframes must differ ({n}, {mean})"
    );
    let play = [
        "--frames",
        "3",
        "--keys",
        "0:Space",
        "--play",
        path.to_str().unwrap(),
    ];
    let (first, _) = run_view(
        &s,
        &[&PLAIN[..], &base, &play].concat(),
        &d.join("play.png"),
    );
    let (n, mean) = differ(&first, &png(&frames.join("frame00000.png")));
    assert!(
        n * 100 <= 64 * 48 && mean < 1.0,
        "playback's first frame: {n} pixels, {mean}"
    );
}

/// The HUD is drawn into the window's picture (white text on a dimmed box, top left) and H
/// hides it; F1 shows the keys instead. A scripted resize makes the swapchain again at the new
/// size (no validation error: `run_view` checks). `relit bench frame` prints the moving and
/// the still frame rates on lines of their own.
#[test]
fn view_hud_resize_and_frame_rates_under_xvfb() {
    use image::GenericImageView;
    let s = baked_tiny("view-hud");
    let d = s.parent().unwrap().to_path_buf();
    let base = [
        "--res", "64x48", "--camera", "0", "--mode", "ratio", "--fluid", "still",
    ];
    let base = [&base[..], &["--window", "256x192", "--frames", "3"]].concat();
    let shot = |name: &str, keys: &str| {
        let args = [&base[..], &["--keys", keys]].concat();
        run_view(&s, &args, &d.join(name))
    };
    let (hud, _) = shot("hud.png", "");
    let (plain, _) = shot("plain.png", "1:H");
    let (help, _) = shot("help.png", "1:F1");
    let white = |img: &image::RgbImage, y0: u32, y1: u32| {
        (img.enumerate_pixels())
            .filter(|(_, y, p)| (y0..y1).contains(y) && p.0 == [255, 255, 255])
            .count()
    };
    let (with, without) = (white(&hud, 0, 60), white(&plain, 0, 60));
    eprintln!("white pixels at the top: {with} with the HUD, {without} without");
    assert!(
        with > without + 150,
        "the HUD's text shows ({with} against {without})"
    );
    assert!(
        white(&help, 0, 192) > white(&hud, 0, 192) + 300,
        "F1 lists the keys"
    );
    // Below the HUD's box the pictures are the same.
    let below = |img: &image::RgbImage| img.view(0, 120, 256, 72).to_image();
    assert_eq!(below(&hud), below(&plain));

    let (big, so) = shot("resized.png", "1:size=96x72");
    assert!(
        so.contains("swapchain: 256x192") && so.contains("swapchain: 96x72"),
        "{so}"
    );
    assert_eq!(big.dimensions(), (96, 72));

    let json = d.join("bench.json");
    let sp = s.to_str().unwrap();
    let out = ok(&[
        "bench", "frame", sp, "--res", "32x24", "--frames", "2", "--mode", "ratio",
    ]
    .into_iter()
    .chain(["--json", json.to_str().unwrap()])
    .collect::<Vec<_>>());
    for label in ["moving: ", "still: "] {
        let line = out
            .lines()
            .find(|l| l.starts_with(label))
            .unwrap_or_else(|| panic!("{out}"));
        let fps: f64 = line[label.len()..]
            .split(' ')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!(fps > 0.0, "{line}");
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(v["moving_fps"].as_f64().unwrap() > 0.0 && v["still_fps"].as_f64().unwrap() > 0.0);
}
