//! One function per fuzz target: what the target does with an input. Shared by the fuzz
//! targets (fuzz_targets/*.rs) and by the regression test (tests/fuzz_regressions.rs), which
//! runs every input the fuzzers once found through the same function. The loaders read files,
//! so each input is written to a scratch directory of this process first.

use std::path::{Path, PathBuf};

use relit_engine::net::{Params, SafetensorsParams};
use relit_engine::scene::path::CameraPath;
use relit_engine::scene::{CameraDoc, Mesh, Scene};

/// The repository root, whether this file is compiled in tools/fuzz or in the main crate.
fn root() -> PathBuf {
    let m = Path::new(env!("CARGO_MANIFEST_DIR"));
    if m.join("tools/fuzz").exists() {
        m.to_path_buf()
    } else {
        m.join("../..")
    }
}

/// This process's scratch directory, created once.
pub fn scratch() -> PathBuf {
    let d = std::env::temp_dir().join(format!("relit-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("scratch directory");
    d
}

/// Writes `data` to `dir/name` and returns the path.
pub fn put(dir: &Path, name: &str, data: &[u8]) -> PathBuf {
    let p = dir.join(name);
    if let Some(parent) = p.parent() {
        std::fs::create_dir_all(parent).expect("scratch subdirectory");
    }
    std::fs::write(&p, data).expect("scratch file");
    p
}

/// Splits one input into `n` files' contents at the byte 0x1E (record separator), so a single
/// fuzz input can be a multi-file format; missing parts are empty.
pub fn parts(data: &[u8], n: usize) -> Vec<&[u8]> {
    let mut v: Vec<&[u8]> = data.splitn(n, |b| *b == 0x1e).collect();
    v.resize(n, &[]);
    v
}

fn copy_tree(src: &Path, dst: &Path) {
    std::fs::create_dir_all(dst).expect("scratch copy");
    for e in std::fs::read_dir(src).expect("source directory").flatten() {
        let to = dst.join(e.file_name());
        if e.path().is_dir() {
            copy_tree(&e.path(), &to);
        } else if e.file_name() != "scene.json" {
            std::fs::copy(e.path(), &to).expect("file copy");
        }
    }
}

/// A scratch copy (made once) of `src` relative to the repository root, without scene.json.
fn scene_dir(name: &str, src: &str) -> PathBuf {
    let d = scratch().join(name);
    if !d.exists() {
        copy_tree(&root().join(src), &d);
    }
    d
}

/// scene.json, beside scenes/tiny_room's mesh and images: load, check images, light coverage.
pub fn scene_json(data: &[u8]) {
    let dir = scene_dir("scene", "scenes/tiny_room");
    put(&dir, "scene.json", data);
    if let Ok(s) = Scene::load(&dir) {
        let _ = s.check_images();
        let _ = relit_engine::scene::light_coverage(&s);
    }
}

/// COLMAP text: sparse/0/cameras.txt and images.txt (split at 0x1E), beside a template scene.
pub fn colmap(data: &[u8]) {
    let dir = scene_dir("colmap", "tools/fuzz/templates/colmap");
    let p = parts(data, 2);
    put(&dir, "sparse/0/cameras.txt", p[0]);
    put(&dir, "sparse/0/images.txt", p[1]);
    if let Ok(s) = Scene::load(&dir) {
        let _ = s.check_images();
    }
}

/// COLMAP binary: sparse/0/cameras.bin and images.bin. Binary data holds any byte, so the input
/// starts with the length of cameras.bin (u32, little-endian) instead of a separator.
pub fn colmap_bin(data: &[u8]) {
    let dir = scene_dir("colmap_bin", "tools/fuzz/templates/colmap");
    let (len, rest) = data.split_at(data.len().min(4));
    let mut n = [0u8; 4];
    n[..len.len()].copy_from_slice(len);
    let (cams, imgs) = rest.split_at((u32::from_le_bytes(n) as usize).min(rest.len()));
    put(&dir, "sparse/0/cameras.bin", cams);
    put(&dir, "sparse/0/images.bin", imgs);
    if let Ok(s) = Scene::load(&dir) {
        let _ = s.check_images();
    }
}

/// instant-ngp / nerfstudio transforms.json, beside a template scene's images and mesh.
pub fn transforms(data: &[u8]) {
    let dir = scene_dir("transforms", "tools/fuzz/templates/colmap");
    put(&dir, "transforms.json", data);
    if let Ok(s) = Scene::load(&dir) {
        let _ = s.check_images();
    }
}

/// SIBR / Bundler: cameras/bundle.out and scene_metadata.txt (split at 0x1E), beside a
/// template scene.
pub fn bundler(data: &[u8]) {
    let dir = scene_dir("sibr", "tools/fuzz/templates/sibr");
    let p = parts(data, 2);
    put(&dir, "cameras/bundle.out", p[0]);
    put(&dir, "scene_metadata.txt", p[1]);
    if let Ok(s) = Scene::load(&dir) {
        let _ = s.check_images();
    }
}

fn mesh(data: &[u8], name: &str) {
    let p = put(&scratch(), name, data);
    if let Ok(m) = Mesh::load(&p) {
        let _ = m.validate();
    }
}

pub fn mesh_obj(data: &[u8]) {
    mesh(data, "m.obj")
}

pub fn mesh_ply(data: &[u8]) {
    mesh(data, "m.ply")
}

/// EXR, PNG, JPEG and TIFF: the first byte picks the extension the loader dispatches on.
pub fn image(data: &[u8]) {
    let Some((&kind, rest)) = data.split_first() else {
        return;
    };
    let ext = ["exr", "png", "jpg", "tif"][kind as usize % 4];
    let p = put(&scratch(), &format!("i.{ext}"), rest);
    let _ = relit_engine::scene::image::image_size(&p);
    let _ = relit_engine::scene::image::load_photo(&p);
}

/// Camera JSON (`--camera FILE`, first byte even) or a camera path (`fly --path`, odd); a path
/// that loads is sampled at its ends and middle.
pub fn camera_path(data: &[u8]) {
    let Some((&kind, rest)) = data.split_first() else {
        return;
    };
    let p = put(&scratch(), "c.json", rest);
    if kind % 2 == 0 {
        if let Ok(doc) = serde_json::from_slice::<CameraDoc>(rest) {
            let _ = doc.to_camera(&p, "fuzz");
        }
    } else if let Ok(path) = CameraPath::load(&p) {
        let (t0, d) = (path.start(), path.duration());
        for t in [t0, t0 + 0.5 * d, t0 + d] {
            let _ = path.camera_at(t, 64, 48);
            let _ = path.lighting_at(t);
        }
    }
}

/// Network weights: open, then read every tensor the file declares at its declared shape.
pub fn weights(data: &[u8]) {
    let p = put(&scratch(), "w.safetensors", data);
    let Ok((params, _)) = SafetensorsParams::open(&p) else {
        return;
    };
    if let Ok(st) = safetensors::SafeTensors::deserialize(data) {
        for (name, t) in st.tensors() {
            let _ = params.get(&name, t.shape());
        }
    }
}

/// A fuzz target: what it does with one input.
pub type Target = fn(&[u8]);

/// Every target by name, for the regression test.
pub const TARGETS: [(&str, Target); 10] = [
    ("scene_json", scene_json),
    ("colmap", colmap),
    ("colmap_bin", colmap_bin),
    ("transforms", transforms),
    ("bundler", bundler),
    ("mesh_obj", mesh_obj),
    ("mesh_ply", mesh_ply),
    ("image", image),
    ("camera_path", camera_path),
    ("weights", weights),
];
