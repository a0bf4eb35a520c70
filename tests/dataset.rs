//! `relit dataset` and the samples it writes (§6): a tiny dataset is built, resumed without
//! rework, and each sample, mixed by the trainer's assembler (tools/train/samples.py) under a
//! lighting, equals `relit dump` of that lighting. Validation on when installed.

mod common;

use std::path::Path;
use std::process::Command;

fn relit(args: &[&str]) -> (bool, String) {
    let (code, so, se) = common::run_relit(args);
    (code == 0, so + &se)
}

fn ok(args: &[&str]) -> String {
    let (good, text) = relit(args);
    assert!(good, "relit {args:?} failed:\n{text}");
    text
}

const TINY: [&str; 14] = [
    "--views",
    "8",
    "--res",
    "32x24",
    "--spp",
    "8",
    "--extra-lights",
    "2",
    "--test-views",
    "1",
    "--val",
    "0",
    "--train",
    "1",
];

fn modified(p: &Path) -> std::time::SystemTime {
    std::fs::metadata(p).unwrap().modified().unwrap()
}

/// Adds a lighting preset that dims the original light and mixes both added lights.
fn add_mix_preset(scene: &Path) {
    let path = scene.join("scene.json");
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let lights: Vec<String> = doc["lights"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|l| !l["original"].as_bool().unwrap_or(false))
        .map(|l| l["name"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(
        lights.len(),
        2,
        "the tiny dataset's scenes have two added lights"
    );
    let intens = serde_json::json!({ lights[0].clone(): 0.7, lights[1].clone(): 2.5 });
    doc["presets"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({ "name": "mix", "dim": 0.35, "intensities": intens }));
    std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
}

#[test]
fn dataset_builds_resumes_and_its_samples_mix_any_lighting_as_the_engine_does() {
    let out = common::tempdir("dataset");
    let o = out.to_str().unwrap();
    let mut args = vec!["dataset", o];
    args.extend(TINY);
    let log = ok(&args);
    assert!(log.contains("9 training and 0 validation samples"), "{log}");
    let scene = out.join("scenes/train/scene_01000");
    let sample = out.join("train/scene_01000.test000.safetensors");
    let view_sample = out.join("train/scene_01000.v003.safetensors");
    let before = modified(&sample);
    // A second run finds everything done and rewrites nothing; a sample removed is made again,
    // byte for byte the same.
    let bytes = std::fs::read(&view_sample).unwrap();
    std::fs::remove_file(&view_sample).unwrap();
    ok(&args);
    assert_eq!(modified(&sample), before);
    assert!(
        std::fs::read(&view_sample).unwrap() == bytes,
        "a remade sample differs"
    );
    // The same dataset with denoised targets would mix two kinds of ground truth: refused.
    let mut denoised = args.clone();
    denoised.push("--denoise");
    let (good, text) = relit(&denoised);
    assert!(
        !good && text.contains("scene_01000") && text.contains("raw targets"),
        "{text}"
    );
    // So would denoised photographs.
    let mut clean = args.clone();
    clean.push("--denoise-photos");
    let (good, text) = relit(&clean);
    assert!(
        !good && text.contains("raw photographs") && text.contains("denoised photographs"),
        "{text}"
    );

    // The trainer's assembly of a lighting equals the engine's frame under that lighting, on
    // a novel camera and on an input view (left out of its own inputs in both): the input,
    // the targets, the drawn lights and glossy mode's image.
    add_mix_preset(&scene);
    let s = scene.to_str().unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/train/samples.py");
    for (cam, parts) in [("test000", &sample), ("v003", &view_sample)] {
        let dump = out.join(format!("{cam}.mix.safetensors"));
        let d = dump.to_str().unwrap();
        ok(&["dump", s, "--camera", cam, "--lighting", "mix", "--out", d]);
        let r = Command::new("python3")
            .arg(&script)
            .arg("--check")
            .arg(parts)
            .arg(&dump)
            .output()
            .expect("python3");
        let text =
            String::from_utf8_lossy(&r.stdout).into_owned() + &String::from_utf8_lossy(&r.stderr);
        assert!(r.status.success(), "samples.py --check {cam}:\n{text}");
        assert!(
            text.contains("target_total"),
            "{cam}: targets not compared:\n{text}"
        );
        assert!(
            text.contains("drawn original lights"),
            "{cam}: drawn lights not compared:\n{text}"
        );
        // Glossy mode's image (a glossy-base network's base) mixes from its parts too.
        assert!(
            text.contains("glossy_image"),
            "{cam}: glossy mode's image not compared:\n{text}"
        );
    }
}

#[test]
fn dataset_refuses_the_demo_seed_and_overlapping_splits() {
    let out = common::tempdir("dataset-refused");
    let o = out.to_str().unwrap();
    let (good, text) = relit(&["dataset", o, "--seed", "1", "--train", "4"]);
    assert!(!good && text.contains("demo scene"), "{text}");
    let (good, text) = relit(&["dataset", o, "--seed", "10", "--val-seed", "12"]);
    assert!(!good && text.contains("overlap"), "{text}");
}
