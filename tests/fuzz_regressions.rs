//! Every input the fuzzers found (tools/fuzz/regressions/<target>/) and every seed
//! (tools/fuzz/corpus/<target>/), run through the same function as its fuzz target: none may
//! panic. Tests build with overflow checks on, as the fuzz builds do.

#[path = "../tools/fuzz/src/harness.rs"]
mod harness;

fn inputs(kind: &str, target: &str) -> Vec<std::path::PathBuf> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tools/fuzz")
        .join(kind)
        .join(target);
    std::fs::read_dir(&dir)
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default()
}

#[test]
fn fuzz_findings_and_seeds_are_handled_without_panics() {
    let mut n = 0;
    for (target, run) in harness::TARGETS {
        for path in inputs("regressions", target)
            .into_iter()
            .chain(inputs("corpus", target))
        {
            let data = std::fs::read(&path).unwrap();
            let r = std::panic::catch_unwind(|| run(&data));
            assert!(r.is_ok(), "{target}: {} panicked", path.display());
            n += 1;
        }
    }
    // The harness wrote the inputs into this process's scratch directory.
    let _ = std::fs::remove_dir_all(harness::scratch());
    assert!(n >= 10, "only {n} inputs found under tools/fuzz");
    assert!(
        !inputs("regressions", "image").is_empty(),
        "the EXR decoder findings are kept"
    );
}

/// The EXR findings are B44-compressed: refused by name before the decoder sees them.
#[test]
fn b44_exr_is_refused_with_a_clear_error() {
    for path in inputs("regressions", "image") {
        let data = std::fs::read(&path).unwrap();
        let exr = std::env::temp_dir().join(format!("relit-b44-{}.exr", std::process::id()));
        std::fs::write(&exr, &data[1..]).unwrap();
        let e = relit_engine::scene::image::load_rgb(&exr)
            .unwrap_err()
            .to_string();
        assert!(e.contains("B44") && e.contains("relit-b44"), "{e}");
    }
}
