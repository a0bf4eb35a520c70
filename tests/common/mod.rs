//! Shared test helpers: a Vulkan device with validation whenever the layer is installed, and
//! a check that no validation error was reported.

#![allow(dead_code)]

use std::sync::Arc;

use relit_engine::gpu::{self, DeviceChoice, Gpu, GpuOptions};

pub fn gpu() -> Arc<Gpu> {
    let entry = gpu::load_entry().expect("Vulkan loader");
    let validation = gpu::validation_layer_available(&entry);
    assert!(
        validation || !require_coop(),
        "the cooperative-matrix run (tools/lavapipe26.sh) needs the validation layer"
    );
    if !validation {
        eprintln!("note: VK_LAYER_KHRONOS_validation not installed; running without validation");
    }
    Gpu::new(&GpuOptions {
        device: DeviceChoice::from_env(),
        validation,
        ..Default::default()
    })
    .unwrap_or_else(|e| panic!("cannot open a Vulkan device: {e}"))
}

/// `RELIT_REQUIRE_COOP=1` (set by tools/lavapipe26.sh): the device must run the network's
/// cooperative-matrix kernels, so the tests that exercise them cannot pass by skipping them.
pub fn require_coop() -> bool {
    std::env::var("RELIT_REQUIRE_COOP").is_ok_and(|v| v == "1")
}

/// Fails the test if the validation layer reported any error on `gpu`.
pub fn assert_no_validation_errors(gpu: &Gpu) {
    unsafe { gpu.device.device_wait_idle().expect("device idle") };
    assert_eq!(
        gpu.validation_errors(),
        0,
        "validation errors were reported (see stderr)"
    );
}

/// A fresh scratch directory for one test: `$TMPDIR/relit-tests/<pid>/<name>`. The first call
/// in a process removes the directories of test processes that no longer run, so runs do not
/// pile up in /tmp.
pub fn tempdir(name: &str) -> std::path::PathBuf {
    let root = std::env::temp_dir().join("relit-tests");
    static SWEEP: std::sync::Once = std::sync::Once::new();
    SWEEP.call_once(|| {
        for e in std::fs::read_dir(&root).into_iter().flatten().flatten() {
            let pid = e.file_name().to_string_lossy().parse::<u32>().ok();
            if pid.is_some_and(|p| !std::path::Path::new(&format!("/proc/{p}")).exists()) {
                let _ = std::fs::remove_dir_all(e.path());
            }
        }
    });
    let d = root.join(std::process::id().to_string()).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs the ground-truth renderer (`tools/groundtruth/render.py`) on a scene directory with
/// extra arguments, failing the test with its stderr.
pub fn render_ground_truth(dir: &std::path::Path, args: &[&str]) {
    let script =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/groundtruth/render.py");
    let out = std::process::Command::new("python3")
        .arg(&script)
        .arg(dir)
        .args(args)
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Runs the relit binary with validation on when the layer is installed; fails the test on any
/// validation error it printed. Returns (exit code, stdout, stderr).
pub fn run_relit(args: &[&str]) -> (i32, String, String) {
    let entry = gpu::load_entry().unwrap();
    let validate = gpu::validation_layer_available(&entry);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_relit"))
        .args(args)
        .env("RELIT_VALIDATE", if validate { "1" } else { "0" })
        .output()
        .expect("run relit");
    let (code, so, se) = (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    );
    assert!(
        !se.contains("[vulkan validation error]"),
        "validation errors in relit {args:?}:\n{se}"
    );
    (code, so, se)
}

/// Copies directory `from` (with everything in it, a scene's bake cache included) to `to`.
#[allow(dead_code)]
pub fn copy_dir(from: &std::path::Path, to: &std::path::Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().map(|e| e.unwrap()) {
        let (src, dst) = (e.path(), to.join(e.file_name()));
        if src.is_dir() {
            copy_dir(&src, &dst);
        } else {
            std::fs::copy(&src, &dst).unwrap();
        }
    }
}
