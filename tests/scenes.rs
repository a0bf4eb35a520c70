//! Scene loaders: camera conventions agree across formats, meshes and images round-trip, and
//! malformed input gets an error naming the file and the problem (never a panic).

mod common;

use std::path::{Path, PathBuf};

use glam::Vec3;
use relit_engine::scene::image::{load_rgb, write_exr, RgbImage};
use relit_engine::scene::synth::{self, Rng, SynthOptions};
use relit_engine::scene::{Mesh, Scene, SceneFormat};

fn opts() -> SynthOptions {
    SynthOptions {
        views: 4,
        width: 40,
        height: 30,
        seed: 5,
        wall_subdiv: 2,
    }
}

#[test]
fn camera_conventions_round_trip_through_all_formats() {
    let truth = synth::capture_cameras(&opts());
    let mut rng = Rng::new(11);
    let points: Vec<Vec3> = (0..200)
        .map(|_| {
            Vec3::new(
                rng.range(-1.9, 1.9),
                rng.range(0.1, 2.5),
                rng.range(-1.7, 1.7),
            )
        })
        .collect();
    let formats = [
        SceneFormat::Relit,
        SceneFormat::Colmap,
        SceneFormat::Sibr,
        SceneFormat::Transforms,
    ];
    for format in formats {
        let dir = common::tempdir(&format!("roundtrip-{format:?}"));
        synth::write_room(&dir, format, &opts()).unwrap();
        let s = Scene::load(&dir).unwrap();
        assert_eq!(s.format, format);
        assert_eq!(s.views.len(), truth.len());
        s.check_images().unwrap();
        for (v, t) in s.views.iter().zip(&truth) {
            let mut checked = 0;
            for p in &points {
                let (Some((a, za)), Some((b, zb))) = (v.camera.project(*p), t.project(*p)) else {
                    assert_eq!(v.camera.project(*p).is_some(), t.project(*p).is_some());
                    continue;
                };
                // Only points in the image: far outside, f32 rounding exceeds the tolerance.
                if b.x < 0.0 || b.y < 0.0 || b.x > t.width as f32 || b.y > t.height as f32 {
                    continue;
                }
                // Tolerance: 1e-3 px and 1e-5 relative depth (text formats print f32 exactly
                // enough; COLMAP's quaternion adds a little rounding).
                assert!((a - b).length() < 1e-3, "{format:?} {}: {a} vs {b}", v.name);
                assert!(
                    (za - zb).abs() < 1e-5 * zb,
                    "{format:?}: depth {za} vs {zb}"
                );
                checked += 1;
            }
            assert!(checked > 10, "{checked} points in view");
            assert!((v.camera.center() - t.center()).length() < 1e-4);
        }
    }
}

/// COLMAP's binary encoding of a text model (cameras.txt, images.txt → .bin, as
/// `colmap model_converter --output_type BIN` writes them), each image with `points` 2D points.
fn colmap_text_to_binary(model: &Path, points: u64) {
    let models = [
        "SIMPLE_PINHOLE",
        "PINHOLE",
        "SIMPLE_RADIAL",
        "RADIAL",
        "OPENCV",
    ];
    let cams = std::fs::read_to_string(model.join("cameras.txt")).unwrap();
    let lines: Vec<Vec<&str>> = cams
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| l.split_whitespace().collect())
        .collect();
    let mut b = (lines.len() as u64).to_le_bytes().to_vec();
    for f in &lines {
        b.extend(f[0].parse::<u32>().unwrap().to_le_bytes());
        let id = models.iter().position(|m| *m == f[1]).unwrap() as u32;
        b.extend(id.to_le_bytes());
        for v in &f[2..4] {
            b.extend(v.parse::<u64>().unwrap().to_le_bytes());
        }
        for v in &f[4..] {
            b.extend(v.parse::<f64>().unwrap().to_le_bytes());
        }
    }
    std::fs::write(model.join("cameras.bin"), b).unwrap();
    let imgs = std::fs::read_to_string(model.join("images.txt")).unwrap();
    let lines: Vec<Vec<&str>> = imgs
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| l.split_whitespace().collect())
        .collect();
    let mut b = (lines.len() as u64).to_le_bytes().to_vec();
    for f in &lines {
        b.extend(f[0].parse::<u32>().unwrap().to_le_bytes());
        for v in &f[1..8] {
            b.extend(v.parse::<f64>().unwrap().to_le_bytes());
        }
        b.extend(f[8].parse::<u32>().unwrap().to_le_bytes());
        b.extend(f[9..].join(" ").as_bytes());
        b.push(0);
        b.extend(points.to_le_bytes());
        for k in 0..points {
            b.extend((k as f64).to_le_bytes());
            b.extend(0.5f64.to_le_bytes());
            b.extend((-1i64).to_le_bytes());
        }
    }
    std::fs::write(model.join("images.bin"), b).unwrap();
    std::fs::remove_file(model.join("cameras.txt")).unwrap();
    std::fs::remove_file(model.join("images.txt")).unwrap();
}

#[test]
fn colmap_binary_models_load_as_their_text_twins() {
    let dir = room("colmap-bin", SceneFormat::Colmap);
    let text = Scene::load(&dir).unwrap();
    colmap_text_to_binary(&dir.join("sparse/0"), 3);
    let bin = Scene::load(&dir).unwrap();
    assert_eq!(bin.format, SceneFormat::Colmap);
    assert_eq!(bin.views.len(), text.views.len());
    for (a, b) in bin.views.iter().zip(&text.views) {
        assert_eq!((&a.name, &a.image), (&b.name, &b.image));
        let (ca, cb) = (&a.camera, &b.camera);
        assert_eq!(
            (ca.width, ca.height, ca.fx, ca.fy, ca.cx, ca.cy),
            (cb.width, cb.height, cb.fx, cb.fy, cb.cx, cb.cy)
        );
        assert!(ca.rotation.abs_diff_eq(cb.rotation, 1e-6) && ca.translation == cb.translation);
    }
    bin.check_images().unwrap();

    // A distorted model is refused with the undistorter command; zero distortion is a pinhole.
    let dir = room("colmap-distorted", SceneFormat::Colmap);
    let cams = dir.join("sparse/0/cameras.txt");
    let s = std::fs::read_to_string(&cams).unwrap();
    let opencv: Vec<String> = s
        .lines()
        .map(|l| match l.starts_with('#') {
            true => l.to_string(),
            false => l.replace(" PINHOLE ", " OPENCV ") + " 0 0 0 0",
        })
        .collect();
    std::fs::write(&cams, opencv.join("\n") + "\n").unwrap();
    let zero = Scene::load(&dir).unwrap();
    assert_eq!(zero.views[0].camera.fx, text.views[0].camera.fx);
    edit(&cams, " 0 0 0 0\n", " 0.1 0 0 0\n");
    colmap_text_to_binary(&dir.join("sparse/0"), 0);
    expect_error(&dir, "cameras.bin", "colmap image_undistorter --image_path");

    // Truncated files and counts past the end name the file and the byte.
    let dir = room("colmap-bin-bad", SceneFormat::Colmap);
    colmap_text_to_binary(&dir.join("sparse/0"), 2);
    let imgs = dir.join("sparse/0/images.bin");
    let good = std::fs::read(&imgs).unwrap();
    std::fs::write(&imgs, &good[..good.len() - 5]).unwrap();
    expect_error(
        &dir,
        "images.bin",
        "a number of 2D points is 2, more than the",
    );
    std::fs::write(&imgs, &good[..330]).unwrap();
    expect_error(
        &dir,
        "images.bin",
        "byte 328: an image NAME has no terminating NUL",
    );
    let mut huge = good.clone();
    huge[..8].copy_from_slice(&u64::MAX.to_le_bytes());
    std::fs::write(&imgs, &huge).unwrap();
    expect_error(&dir, "images.bin", "more than the");
    std::fs::write(&imgs, [good.as_slice(), &[7]].concat()).unwrap();
    expect_error(&dir, "images.bin", "1 bytes after the last image");
    std::fs::write(&imgs, &good).unwrap();
    let cams = dir.join("sparse/0/cameras.bin");
    let mut c = std::fs::read(&cams).unwrap();
    c[12..16].copy_from_slice(&99u32.to_le_bytes()); // the first camera's MODEL_ID
    std::fs::write(&cams, &c).unwrap();
    expect_error(&dir, "cameras.bin", "model id 99");
}

/// An EXR of the given channels (each `w`·`h` floats).
fn write_exr_channels(path: &Path, w: usize, h: usize, channels: &[(&str, Vec<f32>)]) {
    use exr::prelude::*;
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels
        .iter()
        .map(|(n, v)| AnyChannel::new(*n, FlatSamples::F32(v.clone())))
        .collect();
    let layer = Layer::new(
        (w, h),
        LayerAttributes::default(),
        Encoding::UNCOMPRESSED,
        AnyChannels::sort(list),
    );
    Image::from_layer(layer).write().to_file(path).unwrap();
}

#[test]
fn single_channel_exr_loads_as_grey_and_other_channel_sets_are_refused_by_name() {
    let dir = common::tempdir("exr-grey");
    let ys: Vec<f32> = (0..12).map(|i| i as f32 * 0.25).collect();
    let grey = dir.join("grey.exr");
    write_exr_channels(&grey, 4, 3, &[("Y", ys.clone())]);
    let img = load_rgb(&grey).unwrap();
    assert_eq!((img.width, img.height), (4, 3));
    for (p, y) in img.pixels.iter().zip(&ys) {
        assert_eq!(*p, [*y, *y, *y]);
    }
    let two = dir.join("two.exr");
    write_exr_channels(&two, 4, 3, &[("Y", ys.clone()), ("Z", ys)]);
    let e = load_rgb(&two).unwrap_err().to_string();
    assert!(
        e.contains("two.exr") && e.contains("one channel as grey"),
        "{e}"
    );
}

#[test]
fn ply_ascii_binary_and_obj_load_the_same_mesh() {
    let dir = common::tempdir("meshes");
    let (mesh, _) = synth::room(2);
    mesh.write_ply(&dir.join("b.ply")).unwrap();
    mesh.write_obj(&dir.join("m.obj")).unwrap();
    let mut ascii = format!(
        "ply\nformat ascii 1.0\ncomment test\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    );
    for p in &mesh.positions {
        ascii += &format!("{} {} {} 255 128 0\n", p[0], p[1], p[2]);
    }
    for t in &mesh.triangles {
        ascii += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    std::fs::write(dir.join("a.ply"), ascii).unwrap();
    let a = Mesh::load(&dir.join("a.ply")).unwrap();
    let b = Mesh::load(&dir.join("b.ply")).unwrap();
    let o = Mesh::load(&dir.join("m.obj")).unwrap();
    for m in [&a, &b, &o] {
        assert_eq!(m.positions, mesh.positions);
        assert_eq!(m.triangles, mesh.triangles);
    }
    let c = a.colors.unwrap()[0];
    assert!(
        (c[0] - 1.0).abs() < 1e-6 && (c[1] - 0.2158605).abs() < 1e-4 && c[2] == 0.0,
        "sRGB-decoded colour {c:?}"
    );
}

#[test]
fn exr_and_png_round_trip() {
    let dir = common::tempdir("images");
    let mut img = RgbImage::new(7, 5);
    for y in 0..5 {
        for x in 0..7 {
            img.set(x, y, [x as f32 * 0.5, y as f32 * 3.0, 100.0]);
        }
    }
    write_exr(&dir.join("a.exr"), &img).unwrap();
    let back = load_rgb(&dir.join("a.exr")).unwrap();
    for (p, q) in img.pixels.iter().zip(&back.pixels) {
        for k in 0..3 {
            // Half-float storage: 2^-11 relative.
            assert!((p[k] - q[k]).abs() <= p[k].abs() * 1e-3, "{p:?} vs {q:?}");
        }
    }
    let mut ldr = RgbImage::new(2, 1);
    ldr.set(0, 0, [0.5, 0.0, 1.0]);
    relit_engine::scene::image::write_png(&dir.join("a.png"), &ldr, 1.0).unwrap();
    let back = load_rgb(&dir.join("a.png")).unwrap();
    assert!(
        (back.get(0, 0)[0] - 0.5).abs() < 0.01,
        "sRGB decode {:?}",
        back.get(0, 0)
    );
}

/// A CRC-32 (PNG's) for hand-made chunks.
fn crc32(data: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in data {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A PNG whose header claims `w`×`h` and which has no pixel data.
fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    out.extend_from_slice(&13u32.to_be_bytes());
    out.extend_from_slice(&ihdr);
    out.extend_from_slice(&crc32(&ihdr).to_be_bytes());
    // A token IDAT: decoders read the header up to the first data chunk.
    let idat = b"IDAT\x78\x9c\x03\x00\x00\x00\x00\x01";
    out.extend_from_slice(&((idat.len() - 4) as u32).to_be_bytes());
    out.extend_from_slice(idat);
    out.extend_from_slice(&crc32(idat).to_be_bytes());
    out.extend_from_slice(&0u32.to_be_bytes());
    out.extend_from_slice(b"IEND");
    out.extend_from_slice(&crc32(b"IEND").to_be_bytes());
    out
}

/// A fresh copy of the small room in `format`.
fn room(name: &str, format: SceneFormat) -> PathBuf {
    let dir = common::tempdir(name);
    synth::write_room(&dir, format, &opts()).unwrap();
    dir
}

fn edit(path: &Path, from: &str, to: &str) {
    let s = std::fs::read_to_string(path).unwrap();
    assert!(s.contains(from), "{} has no {from:?}", path.display());
    std::fs::write(path, s.replacen(from, to, 1)).unwrap();
}

/// Loads the scene (and its images) and returns the error text; fails if it loads, and
/// checks that the message names `file` and contains `expect`.
fn expect_error(dir: &Path, file: &str, expect: &str) {
    let res = std::panic::catch_unwind(|| Scene::load(dir).and_then(|s| s.check_images()));
    let err = match res {
        Err(_) => panic!("{}: the loader panicked", dir.display()),
        Ok(Ok(())) => panic!(
            "{}: malformed input was accepted (expected \"{expect}\")",
            dir.display()
        ),
        Ok(Err(e)) => e.to_string(),
    };
    eprintln!("ok: {err}");
    assert!(err.contains(file), "error does not name {file}: {err}");
    assert!(
        err.to_lowercase().contains(&expect.to_lowercase()),
        "error lacks \"{expect}\": {err}"
    );
}

#[test]
fn malformed_inputs_get_clear_errors() {
    let j = SceneFormat::Relit;
    let mut cases = 0;

    // 1. Truncated EXR.
    let d = room("bad-exr-trunc", j);
    let f = d.join("images/001.exr");
    let bytes = std::fs::read(&f).unwrap();
    std::fs::write(&f, &bytes[..bytes.len() / 2]).unwrap();
    expect_error(&d, "001.exr", "EXR");
    cases += 1;

    // 1b. A truncated JPEG (the decoder filled the missing rows with grey without a word).
    let d = common::tempdir("bad-jpeg-trunc");
    let f = d.join("cut.jpg");
    let img = image::RgbImage::from_fn(64, 48, |x, y| {
        image::Rgb([(x * 4) as u8, (y * 5) as u8, 90])
    });
    img.save(&f).unwrap();
    assert!(load_rgb(&f).is_ok(), "the whole JPEG loads");
    let bytes = std::fs::read(&f).unwrap();
    std::fs::write(&f, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let e = load_rgb(&f).unwrap_err().to_string();
    assert!(e.contains("cut.jpg") && e.contains("truncated"), "{e}");
    cases += 1;

    // 2-3. NaN and Inf pixels.
    for (k, v) in [("nan", f32::NAN), ("inf", f32::INFINITY)] {
        let d = room(&format!("bad-exr-{k}"), j);
        let mut img = load_rgb(&d.join("images/002.exr")).unwrap();
        img.set(3, 4, [0.1, v, 0.2]);
        write_exr(&d.join("images/002.exr"), &img).unwrap();
        expect_error(&d, "002.exr", "pixel (3, 4)");
        cases += 1;
    }

    // 4. Image header claiming 100000×100000.
    let d = room("bad-png-huge", j);
    std::fs::write(d.join("images/huge.png"), png_header_only(100_000, 100_000)).unwrap();
    edit(&d.join("scene.json"), "images/000.exr", "images/huge.png");
    expect_error(&d, "huge.png", "100000x100000");
    cases += 1;

    // 5. Image size different from its camera.
    let d = room("bad-size", j);
    write_exr(&d.join("images/000.exr"), &RgbImage::new(8, 8)).unwrap();
    expect_error(&d, "000.exr", "8x8");
    cases += 1;

    // 6. Missing image file.
    let d = room("bad-missing-image", j);
    std::fs::remove_file(d.join("images/003.exr")).unwrap();
    expect_error(&d, "003.exr", "does not exist");
    cases += 1;

    // 7. Unreadable mesh (a directory where the file should be).
    let d = room("bad-unreadable", j);
    std::fs::remove_file(d.join("mesh.ply")).unwrap();
    std::fs::create_dir(d.join("mesh.ply")).unwrap();
    expect_error(&d, "mesh.ply", "directory");
    cases += 1;

    // 8. JSON missing a field, and a misspelt one.
    let d = room("bad-json-missing", j);
    let s = std::fs::read_to_string(d.join("scene.json")).unwrap();
    let a = s.find("\"fy\": ").unwrap();
    let b = a + s[a..].find('\n').unwrap() + 1;
    std::fs::write(d.join("scene.json"), format!("{}{}", &s[..a], &s[b..])).unwrap();
    expect_error(&d, "scene.json", "missing field `fy`");
    let d = room("bad-json-field", j);
    edit(&d.join("scene.json"), "\"fx\":", "\"fx_typo\":");
    expect_error(&d, "scene.json", "unknown field `fx_typo`");
    cases += 1;

    // 9. Not JSON at all.
    let d = room("bad-json-syntax", j);
    std::fs::write(d.join("scene.json"), "{ \"version\": 1, \"mesh\": ").unwrap();
    expect_error(&d, "scene.json", "EOF");
    cases += 1;

    // 10. Zero focal length.
    let d = room("bad-zero-focal", j);
    let s = std::fs::read_to_string(d.join("scene.json")).unwrap();
    let fx_pos = s.find("\"fx\": ").unwrap() + 6;
    let end = fx_pos + s[fx_pos..].find(',').unwrap();
    std::fs::write(
        d.join("scene.json"),
        format!("{}0.0{}", &s[..fx_pos], &s[end..]),
    )
    .unwrap();
    expect_error(&d, "scene.json", "focal length fx = 0");
    cases += 1;

    // 11. A preset that names a light the scene lacks.
    let d = room("bad-preset", j);
    edit(&d.join("scene.json"), "\"lamp\": 1.0", "\"desk\": 1.0");
    expect_error(&d, "scene.json", "desk");
    cases += 1;

    // 12. OBJ face index out of range.
    let d = room("bad-obj", j);
    std::fs::write(
        d.join("mesh.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n",
    )
    .unwrap();
    edit(&d.join("scene.json"), "mesh.ply", "mesh.obj");
    expect_error(&d, "mesh.obj", "out of range");
    cases += 1;

    // 13. PLY whose header declares more vertices than the file holds.
    let d = room("bad-ply-count", j);
    let ply = std::fs::read(d.join("mesh.ply")).unwrap();
    let text = String::from_utf8_lossy(&ply);
    let n = text
        .split("element vertex ")
        .nth(1)
        .unwrap()
        .split('\n')
        .next()
        .unwrap()
        .to_string();
    let fixed = String::from_utf8_lossy(&ply).replacen(
        &format!("element vertex {n}"),
        &format!("element vertex {}", 100 * n.parse::<usize>().unwrap()),
        1,
    );
    // Rebuild from bytes: only the header is text.
    let hdr_end = ply.windows(10).position(|w| w == b"end_header").unwrap() + 11;
    let new_hdr = fixed.split("end_header\n").next().unwrap().to_string() + "end_header\n";
    let mut out = new_hdr.into_bytes();
    out.extend_from_slice(&ply[hdr_end..]);
    std::fs::write(d.join("mesh.ply"), out).unwrap();
    expect_error(&d, "mesh.ply", "header declares");
    cases += 1;

    // 14. ASCII PLY with fewer faces than declared.
    let d = room("bad-ply-ascii", j);
    std::fs::write(
        d.join("mesh.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
         element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    )
    .unwrap();
    expect_error(&d, "mesh.ply", "file ends inside face 1");
    cases += 1;

    // 14b. ASCII PLY declaring 10^15 vertices, and an element without properties and as many:
    // refused at the header (the fuzzer's hang), not read value by value.
    let d = room("bad-ply-huge", j);
    std::fs::write(
        d.join("mesh.ply"),
        "ply\nformat ascii 1.0\nelement vertex 1000000000000000\nproperty float x\n\
         property float y\nproperty float z\nend_header\n0 0 0\n",
    )
    .unwrap();
    expect_error(&d, "mesh.ply", "header declares 1000000000000000 vertex");
    cases += 1;

    // 15. PLY face index out of range.
    let d = room("bad-ply-index", j);
    std::fs::write(
        d.join("mesh.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n",
    )
    .unwrap();
    expect_error(&d, "mesh.ply", "references vertex 7");
    cases += 1;

    // 15a. ASCII values that do not fit their declared type: a fraction and "nan" as vertex
    // indices (both became some index), and a count past its uchar.
    let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                end_header\n0 0 0\n1 0 0\n0 1 0\n";
    for (face, expect) in [
        (
            "3 0 1.5 2",
            "face 0: property vertex_indices is \"1.5\", not of its type int",
        ),
        (
            "3 0 nan 2",
            "face 0: property vertex_indices is \"nan\", not of its type int",
        ),
        (
            "300 0 1 2",
            "face 0: property vertex_indices is \"300\", not of its type uchar",
        ),
    ] {
        let d = room("bad-ply-type", j);
        std::fs::write(d.join("mesh.ply"), format!("{head}{face}\n")).unwrap();
        expect_error(&d, "mesh.ply", expect);
    }
    cases += 1;

    // 15b. A PLY whose declared face count does not match its data (the ASCII faces are
    // triangles, but the header says the vertex list has one element more than it does): the
    // message says the header and the data disagree, not only "face 1 has 0 vertices".
    let d = room("bad-ply-list", j);
    std::fs::write(
        d.join("mesh.ply"),
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
         element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n\
         3 0 1 2\n0 0 1\n",
    )
    .unwrap();
    expect_error(
        &d,
        "mesh.ply",
        "header's counts or property types do not match the data",
    );
    cases += 1;

    // 16. Big-endian PLY.
    let d = room("bad-ply-be", j);
    std::fs::write(
        d.join("mesh.ply"),
        "ply\nformat binary_big_endian 1.0\nelement vertex 0\nend_header\n",
    )
    .unwrap();
    expect_error(&d, "mesh.ply", "binary_big_endian");
    cases += 1;

    // 17. COLMAP camera model with distortion.
    let d = room("bad-colmap-model", SceneFormat::Colmap);
    let cams = d.join("sparse/0/cameras.txt");
    let s = std::fs::read_to_string(&cams).unwrap();
    let line = s.lines().nth(1).unwrap().to_string();
    std::fs::write(
        &cams,
        s.replace(
            &line,
            &(line.replace("PINHOLE", "OPENCV") + " 0.1 0.01 0 0"),
        ),
    )
    .unwrap();
    expect_error(&d, "cameras.txt", "OPENCV");
    cases += 1;

    // 18. COLMAP image using an undefined camera (image count ≠ camera count).
    let d = room("bad-colmap-count", SceneFormat::Colmap);
    let cams = d.join("sparse/0/cameras.txt");
    let s = std::fs::read_to_string(&cams).unwrap();
    let last = s.lines().last().unwrap().to_string();
    std::fs::write(&cams, s.replace(&(last + "\n"), "")).unwrap();
    expect_error(&d, "images.txt", "does not define");
    cases += 1;

    // 18a. An OBJ face with two vertices (it was dropped without a word).
    let d = room("bad-obj-face", SceneFormat::Relit);
    let obj = d.join("two.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\n").unwrap();
    let e = relit_engine::scene::Mesh::load(&obj)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("two.obj") && e.contains("line 5") && e.contains("found 2"),
        "{e}"
    );
    cases += 1;

    // 18b. COLMAP images.txt without its POINTS2D lines (half the views were lost silently).
    let d = room("bad-colmap-points", SceneFormat::Colmap);
    let imgs = d.join("sparse/0/images.txt");
    let s = std::fs::read_to_string(&imgs).unwrap();
    let kept: Vec<&str> = s.lines().filter(|l| !l.trim().is_empty()).collect();
    std::fs::write(&imgs, kept.join("\n") + "\n").unwrap();
    expect_error(&d, "images.txt", "POINTS2D line belongs");
    cases += 1;

    // 19. SIBR: image count ≠ camera count.
    let d = room("bad-sibr-count", SceneFormat::Sibr);
    edit(&d.join("cameras/bundle.out"), "\n4 0\n", "\n5 0\n");
    expect_error(&d, "bundle.out", "5 cameras but 4 images");
    cases += 1;

    // 20. SIBR: radial distortion.
    let d = room("bad-sibr-distortion", SceneFormat::Sibr);
    let b = d.join("cameras/bundle.out");
    let s = std::fs::read_to_string(&b).unwrap();
    let l = s.lines().nth(2).unwrap().to_string();
    std::fs::write(&b, s.replacen(&l, &l.replace(" 0 0", " 0.05 0"), 1)).unwrap();
    expect_error(&d, "bundle.out", "radial distortion");
    cases += 1;

    // 21. A rotation that is not a rotation.
    let d = room("bad-rotation", j);
    let s = std::fs::read_to_string(d.join("scene.json")).unwrap();
    let r = s.find("\"rotation\": [").unwrap() + 13;
    let r = r + s[r..].find('[').unwrap() + 1;
    let e = r + s[r..].find(',').unwrap();
    std::fs::write(d.join("scene.json"), format!("{}3.0{}", &s[..r], &s[e..])).unwrap();
    expect_error(&d, "scene.json", "not a proper rotation");
    cases += 1;

    assert!(cases >= 15);
}

#[test]
fn the_bundled_scenes_load() {
    for name in ["tiny_room", "demo_room"] {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name);
        let s = Scene::load(&dir).unwrap();
        s.check_images().unwrap();
        assert!(s.views.len() >= 4);
        assert!(!s.lights.is_empty() && !s.presets.is_empty());
    }
    let demo =
        Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/demo_room")).unwrap();
    let p = &demo.presets[0];
    assert!(
        p.dim > 0.0 && p.intensities.len() == 1,
        "demo preset: one added light, original dimmed"
    );
    assert!((24..=40).contains(&demo.views.len()));
}

/// The synthetic room plus random triangles (thin, crossing, some far outside), as a BVH's
/// worst cases: overlapping boxes, degenerate extents, triangles spanning the room.
fn bvh_test_mesh() -> Mesh {
    let (mut mesh, _) = synth::room(6);
    let mut rng = Rng::new(17);
    for _ in 0..300 {
        let c = Vec3::new(
            rng.range(-3.0, 3.0),
            rng.range(-0.5, 3.0),
            rng.range(-3.0, 3.0),
        );
        let s = if rng.f32() < 0.1 { 3.0 } else { 0.3 };
        let base = mesh.positions.len() as u32;
        for _ in 0..3 {
            let p = c + s * Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            );
            mesh.positions.push(p.into());
        }
        mesh.triangles.push([base, base + 1, base + 2]);
    }
    mesh
}

#[test]
fn mesh_bvh_matches_brute_force_ray_casting() {
    use relit_engine::cpu::{closest_hit, occluded, MeshBvh};
    let mesh = bvh_test_mesh();
    let bvh = MeshBvh::new(&mesh);
    // Origins inside the closed room (4 × 2.6 × 3.5 m), so that most rays hit.
    let (lo, hi) = (Vec3::new(-1.9, 0.1, -1.6), Vec3::new(1.9, 2.5, 1.6));
    let mut rng = Rng::new(5);
    let mut hits = 0;
    for i in 0..3000 {
        let o = lo + (hi - lo) * Vec3::new(rng.f32(), rng.f32(), rng.f32());
        // Every 10th ray runs along an axis (zero direction components).
        let d = if i % 10 == 0 {
            [Vec3::X, Vec3::NEG_Y, Vec3::Z][i / 10 % 3]
        } else {
            Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            )
            .normalize()
        };
        let (tmin, tmax) = (rng.range(0.0, 0.2), rng.range(0.05, 8.0));
        assert_eq!(
            bvh.occluded(o, d, tmin, tmax),
            occluded(&mesh, o, d, tmin, tmax),
            "ray {i}: occlusion differs"
        );
        let (a, b) = (
            closest_hit(&mesh, o, d, tmin, 100.0),
            bvh.closest_hit(o, d, tmin, 100.0),
        );
        assert_eq!(
            a.map(|h| h.t),
            b.map(|h| h.t),
            "ray {i}: closest hit differs"
        );
        if let (Some(a), Some(b)) = (a, b) {
            hits += 1;
            // Another triangle only as a tie at the same t.
            if a.tri != b.tri {
                assert_eq!(a.t, b.t);
            } else {
                assert_eq!(a.bary, b.bary);
            }
        }
    }
    assert!(hits > 2700, "{hits} hits");
}

#[test]
fn light_coverage_counts_the_views_that_see_each_original_light() {
    use relit_engine::cpu::MeshBvh;
    use relit_engine::scene::coverage::coverage;
    use relit_engine::scene::{Camera, Light, LightShape, View, MIN_VIEWS_PER_LIGHT};
    // A wall in the plane z = 0 (x, y in [-2, 2]); cameras at z = 3 look at it.
    let mesh = Mesh {
        positions: vec![
            [-2.0, -2.0, 0.0],
            [2.0, -2.0, 0.0],
            [2.0, 2.0, 0.0],
            [-2.0, 2.0, 0.0],
        ],
        colors: None,
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    };
    let bvh = MeshBvh::new(&mesh);
    let cam =
        |x: f32, look: Vec3| Camera::look_at(Vec3::new(x, 0.0, 3.0), look, Vec3::Y, 64, 48, 40.0);
    let views: Vec<View> = [
        cam(-1.0, Vec3::new(0.0, 0.0, 1.0)),
        cam(0.0, Vec3::new(0.0, 0.0, 1.0)),
        cam(1.0, Vec3::new(0.0, 0.0, 1.0)),
        // Looks away from the wall: sees nothing.
        cam(0.0, Vec3::new(0.0, 0.0, 6.0)),
    ]
    .into_iter()
    .enumerate()
    .map(|(i, camera)| View {
        name: format!("v{i}"),
        image: format!("v{i}.exr").into(),
        camera,
    })
    .collect();
    let quad = |z: f32, facing: f32| LightShape::Quad {
        corner: Vec3::new(-0.2, -0.2, z),
        edge_u: Vec3::new(0.4 * facing, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.4, 0.0),
    };
    let light = |name: &str, shape, original| Light {
        name: name.into(),
        shape,
        radiance: [1.0; 3],
        original,
        estimated: false,
    };
    let lights = vec![
        // Behind the wall, facing the cameras: the wall hides it.
        light("behind", quad(-1.0, 1.0), true),
        // In front of the wall, facing the cameras: the three that look at it see it whole.
        light("front", quad(1.0, 1.0), true),
        // In front, but emitting toward the wall: no camera is on its emitting side.
        light("backwards", quad(1.0, -1.0), true),
        // A disk in front, facing the cameras.
        light(
            "disk",
            LightShape::Disk {
                center: Vec3::new(0.0, 0.0, 1.0),
                normal: Vec3::Z,
                radius: 0.2,
            },
            true,
        ),
        // An added light is not measured.
        light("added", quad(1.0, 1.0), false),
    ];
    let c = coverage(&bvh, &views, &lights);
    let names: Vec<&str> = c.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["behind", "front", "backwards", "disk"]);
    let by = |n: &str| c.iter().find(|l| l.name == n).unwrap();
    assert_eq!(by("behind").views(), 0);
    assert_eq!(by("backwards").views(), 0);
    for n in ["front", "disk"] {
        let l = by(n);
        assert_eq!(l.view_names(), ["v0", "v1", "v2"], "{n}");
        assert!(
            l.seen_by.iter().all(|s| s.visible == 1.0),
            "{n}: {:?}",
            l.seen_by
        );
        assert_eq!(l.total_views, 4);
        assert!(l.warning().is_none());
    }
    let w = by("behind")
        .warning()
        .expect("a warning for a light no view sees");
    assert!(
        w.contains("'behind'")
            && w.contains("0 of 4")
            && w.contains(&format!("fewer than {MIN_VIEWS_PER_LIGHT}")),
        "{w}"
    );
    assert_eq!(
        by("front").summary(),
        "light front: seen by 3 of 4 views (v0 100%, v1 100%, v2 100%)"
    );
    // Half hidden: a light straddling the wall's edge (x = 2) seen from straight ahead.
    let edge = vec![light(
        "edge",
        LightShape::Quad {
            corner: Vec3::new(1.8, -0.2, -1.0),
            edge_u: Vec3::new(0.4, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.4, 0.0),
        },
        true,
    )];
    let straight = [View {
        name: "s".into(),
        image: "s.exr".into(),
        camera: Camera::look_at(
            Vec3::new(2.0, 0.0, 3.0),
            Vec3::new(2.0, 0.0, -1.0),
            Vec3::Y,
            64,
            48,
            40.0,
        ),
    }];
    let e = &coverage(&bvh, &straight, &edge)[0];
    assert_eq!(e.views(), 1);
    assert_eq!(e.seen_by[0].visible, 0.5);
}
