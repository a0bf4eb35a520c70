//! The network's kernels (§5.1) against CPU references, and the whole network against the
//! PyTorch module `tools/train/model.py` (golden files in tests/golden, written by
//! `tools/train/golden.py`).

mod common;

use relit_engine::gpu::shaders;
use relit_engine::gpu::{self, vk};
use relit_engine::net::{
    backend_for, conv_reference, coop_tile, lanes_fit, upsample_add_reference, Backend, Epilogue,
    NetKernels, Network, Storage, Tensor,
};
use relit_engine::scene::synth::Rng;

fn random(rng: &mut Rng, n: usize, lo: f32, hi: f32) -> Vec<f32> {
    (0..n).map(|_| rng.range(lo, hi)).collect()
}

fn max_err(a: &[f32], b: &[f32]) -> (f32, f32) {
    let scale = b.iter().fold(0f32, |m, x| m.max(x.abs()));
    let e = a.iter().zip(b).fold(0f32, |m, (x, y)| m.max((x - y).abs()));
    (e, scale)
}

/// (ic, oc, h, w, k, stride): the fixup 3×3 conv with every epilogue option, and the 4×4
/// stride-2 downsampling conv at odd sizes; channel counts that are not multiples of 4 or 16.
#[test]
fn conv_kernels_match_cpu() {
    let gpu = common::gpu();
    let mut rng = Rng::new(5);
    // The portable kernels in both storages, and the CPU-shaped one (fp32) at several
    // blockings: 8, 16, 24 output channels per invocation (a last group with 4 real ones, a
    // layer narrower than one group), 1 to 6 rows (a workgroup's rows past the image's last).
    let mut kernels = vec![
        NetKernels::with_backend(&gpu, Storage::F32, Backend::Portable).unwrap(),
        NetKernels::with_backend(&gpu, Storage::F16, Backend::Portable).unwrap(),
    ];
    if lanes_fit(&gpu.caps) {
        for (ocn, rows) in [(8, 6), (8, 1), (16, 3), (24, 2)] {
            kernels.push(NetKernels::with_lanes(&gpu, ocn, rows).unwrap());
        }
    }
    // The cooperative-matrix kernel where the device offers a shape (lavapipe >= 26:
    // tools/lavapipe26.sh runs this test there).
    if coop_tile(&gpu.caps).is_some() || common::require_coop() {
        kernels.push(NetKernels::with_backend(&gpu, Storage::F16, Backend::CoopMatrix).unwrap());
    }
    for kern in &kernels {
        let storage = kern.storage;
        for &(ic, oc, h, w, k, stride) in &[
            (6u32, 20u32, 7u32, 19u32, 3u32, 1u32),
            (18, 18, 9, 11, 4, 2),
            (12, 6, 5, 17, 3, 1),
            (20, 10, 6, 9, 1, 1),
        ] {
            let x = random(&mut rng, (ic * h * w) as usize, -1.0, 1.0);
            let wt = random(&mut rng, (oc * ic * k * k) as usize, -0.3, 0.3);
            let bias = random(&mut rng, oc as usize, -0.2, 0.2);
            let layer = kern.layer(&wt, Some(&bias), oc, ic, k, stride, 1).unwrap();
            let (oh, ow) = layer.out_size(h, w);
            let res_ok = oc == ic && stride == 1;
            let resid = random(&mut rng, (oc * oh * ow) as usize, -1.0, 1.0);
            let xt = Tensor::new(&gpu, "x", ic, h, w, storage).unwrap();
            xt.upload_chw(&x).unwrap();
            let rt = Tensor::new(&gpu, "r", oc, oh, ow, storage).unwrap();
            let yt = Tensor::new(&gpu, "y", oc, oh, ow, storage).unwrap();
            if res_ok {
                rt.upload_chw(&resid).unwrap();
            }
            let ep = Epilogue {
                in_bias: 0.1,
                out_bias: -0.05,
                scale: 0.8,
                relu: true,
                residual: res_ok.then_some(&rt),
            };
            let mut r = Ok(());
            gpu.submit(|cmd| {
                r = kern.conv(&mut gpu::Graph::new(&gpu, cmd, None), &layer, &xt, &yt, ep)
            })
            .unwrap();
            r.unwrap();
            let got = yt.download_chw().unwrap();
            // The reference sees what the device sees: inputs rounded to the storage type.
            let q = |v: &[f32]| -> Vec<f32> {
                match storage {
                    Storage::F32 => v.to_vec(),
                    Storage::F16 => v.iter().map(|&x| half::f16::from_f32(x).to_f32()).collect(),
                }
            };
            let want = conv_reference(
                &q(&x),
                (ic, h, w),
                &q(&wt),
                &bias,
                oc,
                (k, stride, 1),
                0.1,
                -0.05,
                0.8,
                true,
                res_ok.then_some(&q(&resid)[..]),
            );
            let (e, s) = max_err(&got, &want);
            // fp32: accumulation-order error only; fp16: the output's rounding (2^-11 relative).
            let tol = match storage {
                Storage::F32 => 1e-5 * s.max(1.0),
                Storage::F16 => 1e-3 * s.max(1.0),
            };
            assert!(
                e <= tol,
                "{storage:?} {:?} conv {ic}->{oc} k{k} s{stride}: max error {e} (scale {s})",
                kern.backend
            );
        }
    }
    common::assert_no_validation_errors(&gpu);
}

#[test]
fn upsample_add_matches_cpu() {
    let gpu = common::gpu();
    let mut rng = Rng::new(9);
    // The portable kernel (storage bindings) and the CPU-shaped one (pointers).
    let mut kernels =
        vec![NetKernels::with_backend(&gpu, Storage::F32, Backend::Portable).unwrap()];
    if lanes_fit(&gpu.caps) {
        kernels.push(NetKernels::with_lanes(&gpu, 8, 4).unwrap());
    }
    let (c, sh, sw, dh, dw) = (7u32, 3u32, 5u32, 24u32, 40u32);
    for kern in &kernels {
        let src = random(&mut rng, (c * sh * sw) as usize, -1.0, 1.0);
        let dst = random(&mut rng, (c * dh * dw) as usize, -1.0, 1.0);
        let st = Tensor::new(&gpu, "s", c, sh, sw, Storage::F32).unwrap();
        let dt = Tensor::new(&gpu, "d", c, dh, dw, Storage::F32).unwrap();
        st.upload_chw(&src).unwrap();
        dt.upload_chw(&dst).unwrap();
        let mut r = Ok(());
        gpu.submit(|cmd| r = kern.upsample_add(&mut gpu::Graph::new(&gpu, cmd, None), &st, &dt))
            .unwrap();
        r.unwrap();
        let want = upsample_add_reference(&src, (c, sh, sw), &dst, (dh, dw));
        let (e, _) = max_err(&dt.download_chw().unwrap(), &want);
        assert!(e < 1e-5, "{:?}: max error {e}", kern.backend);
    }
    common::assert_no_validation_errors(&gpu);
}

fn golden(name: &str) -> (std::path::PathBuf, Vec<f32>, Vec<f32>, Vec<usize>) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden");
    let io = std::fs::read(dir.join(format!("{name}.io.safetensors"))).unwrap();
    let st = safetensors::SafeTensors::deserialize(&io).unwrap();
    let get = |k: &str| -> (Vec<f32>, Vec<usize>) {
        let t = st.tensor(k).unwrap();
        (bytemuck::pod_collect_to_vec(t.data()), t.shape().to_vec())
    };
    let (x, xs) = get("input");
    let (y, _) = get("output");
    (dir.join(format!("{name}.safetensors")), x, y, xs)
}

/// The engine's network against PyTorch (float64) with random weights on a random input.
/// Tolerances, relative to the output's largest magnitude: fp32 storage 1e-4 (accumulation
/// order over ~40 layers); fp16 storage 5e-3 (activations rounded to 11 bits at every layer).
#[test]
fn network_matches_pytorch_golden() {
    let gpu = common::gpu();
    for name in ["net_w12", "net_w66", "net_w12r"] {
        let (weights, x, y, shape) = golden(name);
        let (h, w) = (shape[1] as u32, shape[2] as u32);
        for (storage, tol) in [(Storage::F32, 1e-4f32), (Storage::F16, 5e-3)] {
            let net = Network::load(&gpu, &weights, storage).unwrap();
            eprintln!("{name} {storage:?}: {:?} kernels", net.kernels.backend);
            if storage == Storage::F16 && common::require_coop() {
                assert_eq!(net.kernels.backend, Backend::CoopMatrix);
            }
            let got = net.run(&x, h, w).unwrap();
            let (e, s) = max_err(&got, &y);
            eprintln!("{name} {storage:?}: max error {e} (output scale {s})");
            assert!(e <= tol * s, "{name} {storage:?}: max error {e}, scale {s}");
        }
    }
    common::assert_no_validation_errors(&gpu);
}

/// A network with base "ratio": the output pass's CPU reference (`reference_network` with the
/// input) turns the raw golden output into the image PyTorch composes (`model.py`: the ratio
/// base added to O_d), within 1e-4 of the image's scale, without `shrink` or `gate`, with the
/// golden's shrink (every correction soft-thresholded), with its gate (every correction scaled
/// by the input's change of lighting), with the gate and `gain` (the diffuse correction a gain
/// on the base) and with those and `agree` (every correction scaled by the input views'
/// disagreement, on an input with holes); the GPU output pass is held to that reference by
/// tests/frame.rs.
#[test]
fn ratio_base_matches_pytorch_golden() {
    use relit_engine::frame::output::{reference_network, Corrections};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden");
    let io = std::fs::read(dir.join("net_w12r.io.safetensors")).unwrap();
    let (_, meta) = safetensors::SafeTensors::read_metadata(&io).unwrap();
    let value = |k: &str| -> f32 { meta.metadata().as_ref().unwrap()[k].parse().unwrap() };
    let (shrink, gate, agree) = (value("shrink"), value("gate"), value("agree"));
    assert!(shrink > 0.0 && gate > 0.0 && agree > 0.0);
    let st = safetensors::SafeTensors::deserialize(&io).unwrap();
    let (_, x, y, shape) = golden("net_w12r");
    let npix = shape[1] * shape[2];
    let untm = relit_engine::frame::features::untonemap;
    let c = |shrink, gate, gain, agree| Corrections {
        shrink,
        gate,
        gain,
        agree,
    };
    for (key, options) in [
        ("image", c(0.0, 0.0, false, 0.0)),
        ("image_shrink", c(shrink, 0.0, false, 0.0)),
        ("image_gate", c(0.0, gate, false, 0.0)),
        ("image_gain", c(0.0, gate, true, 0.0)),
        ("image_agree", c(0.0, gate, true, agree)),
    ] {
        let image: Vec<f32> = bytemuck::pod_collect_to_vec(st.tensor(key).unwrap().data());
        let got = reference_network(&y, Some(&x), options, shape[2], &vec![true; npix]);
        let want: Vec<f32> = (0..3)
            .flat_map(|k| (0..npix).map(move |p| (k, p)))
            .map(|(k, p)| untm(image[k * npix + p] + image[(k + 3) * npix + p]))
            .collect();
        let got: Vec<f32> = (0..3).flat_map(|k| got.iter().map(move |c| c[k])).collect();
        let (e, s) = max_err(&got, &want);
        assert!(e <= 1e-4 * s, "{key}: max error {e}, scale {s}");
    }
}

/// A network with base "glossy" (`model.py`): its diffuse corrections land on tm of glossy
/// mode's image instead of the ratio base, the keys (gate, gain, agreement) as with base
/// "ratio". The golden's random linear image stands in for glossy mode's; the output pass's CPU
/// reference (`reference_network_on` with that image) must give PyTorch's image within 1e-4 of
/// its scale. tests/frame.rs holds the GPU pass to the reference.
#[test]
fn glossy_base_matches_pytorch_golden() {
    use relit_engine::frame::output::{reference_network_on, Corrections};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden");
    let io = std::fs::read(dir.join("net_w12r.io.safetensors")).unwrap();
    let (_, meta) = safetensors::SafeTensors::read_metadata(&io).unwrap();
    let value = |k: &str| -> f32 { meta.metadata().as_ref().unwrap()[k].parse().unwrap() };
    let st = safetensors::SafeTensors::deserialize(&io).unwrap();
    let (_, x, y, shape) = golden("net_w12r");
    let npix = shape[1] * shape[2];
    let planar: Vec<f32> = bytemuck::pod_collect_to_vec(st.tensor("glossy").unwrap().data());
    let base: Vec<[f32; 3]> = (0..npix)
        .map(|p| [0, 1, 2].map(|k| planar[k * npix + p]))
        .collect();
    let keys = Corrections {
        shrink: 0.0,
        gate: value("gate"),
        gain: true,
        agree: value("agree"),
    };
    let image: Vec<f32> = bytemuck::pod_collect_to_vec(st.tensor("image_glossy").unwrap().data());
    let untm = relit_engine::frame::features::untonemap;
    let got = reference_network_on(&y, Some(&x), Some(&base), keys, shape[2], &vec![true; npix]);
    let want: Vec<f32> = (0..3)
        .flat_map(|k| (0..npix).map(move |p| (k, p)))
        .map(|(k, p)| untm(image[k * npix + p] + image[(k + 3) * npix + p]))
        .collect();
    let got: Vec<f32> = (0..3).flat_map(|k| got.iter().map(move |c| c[k])).collect();
    let (e, s) = max_err(&got, &want);
    assert!(e <= 1e-4 * s, "image_glossy: max error {e}, scale {s}");
    // The base matters: the same corrections on the ratio base give another image.
    let ratio = relit_engine::frame::output::reference_network(
        &y,
        Some(&x),
        keys,
        shape[2],
        &vec![true; npix],
    );
    let ratio: Vec<f32> = (0..3)
        .flat_map(|k| ratio.iter().map(move |c| c[k]))
        .collect();
    assert!(
        max_err(&ratio, &want).0 > 10.0 * e.max(1e-6),
        "the glossy base changes the image"
    );
}

/// The trained network built into relit against PyTorch (float64) on a random input: the
/// golden file is of these weights (their metadata match), and fp32 storage is within 1e-4 of
/// the output's largest magnitude, as for random weights.
#[test]
fn shipped_network_matches_pytorch_golden() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden");
    let io = std::fs::read(dir.join("net_shipped.io.safetensors")).unwrap();
    let (_, meta) = safetensors::SafeTensors::read_metadata(&io).unwrap();
    let (_, shipped) = safetensors::SafeTensors::read_metadata(relit_engine::net::SHIPPED).unwrap();
    for key in ["relit.net", "relit.trained"] {
        assert_eq!(
            meta.metadata().as_ref().unwrap().get(key),
            shipped.metadata().as_ref().unwrap().get(key),
            "{key}: tests/golden/net_shipped.io.safetensors is stale \
             (tools/train/golden.py tests/golden --shipped engine/weights/relit.safetensors)"
        );
    }
    let (_, x, y, shape) = golden("net_shipped");
    let gpu = common::gpu();
    let net = Network::shipped(&gpu, Storage::F32).unwrap();
    let got = net.run(&x, shape[1] as u32, shape[2] as u32).unwrap();
    let (e, s) = max_err(&got, &y);
    eprintln!("shipped network: max error {e} (output scale {s})");
    assert!(e <= 1e-4 * s, "shipped network: max error {e}, scale {s}");
    common::assert_no_validation_errors(&gpu);
}

#[test]
fn network_weights_errors_name_the_problem() {
    let gpu = common::gpu();
    // A character device is refused before reading (it used to be read until memory ran out).
    let e = Network::load(&gpu, std::path::Path::new("/dev/zero"), Storage::F32)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("/dev/zero") && e.contains("character device"),
        "{e}"
    );
    let dir = common::tempdir("netweights");
    let bad = dir.join("bad.safetensors");
    std::fs::write(&bad, b"not a safetensors file").unwrap();
    let e = Network::load(&gpu, &bad, Storage::F32)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("bad.safetensors") && e.contains("safetensors"),
        "{e}"
    );
    // A valid file without the configuration metadata.
    let (_, x, _, _) = golden("net_w12");
    let data = bytemuck::cast_slice::<f32, u8>(&x[..4]).to_vec();
    let view =
        safetensors::tensor::TensorView::new(safetensors::Dtype::F32, vec![4], &data).unwrap();
    let nometa = dir.join("nometa.safetensors");
    safetensors::serialize_to_file([("a", view)], None, &nometa).unwrap();
    let e = Network::load(&gpu, &nometa, Storage::F32)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("relit.net"), "{e}");
}

#[test]
fn conv_coop_matrix_module_is_built_and_selected_only_when_it_fits() {
    let gpu = common::gpu();
    // OpCapability CooperativeMatrixKHR (6022) in the module, and the portable twin's layout.
    let words = gpu::spirv(shaders::NET_CONV_CM).unwrap();
    assert!(words
        .windows(2)
        .any(|w| w[0] == (2 << 16 | 17) && w[1] == 6022));
    let (cm, portable) = (
        gpu::reflect(shaders::NET_CONV_CM).unwrap(),
        gpu::reflect(shaders::NET_CONV).unwrap(),
    );
    assert_eq!(cm.sets, portable.sets);
    assert_eq!(cm.push_size, portable.push_size);
    // fp32 storage never takes the coop-matrix path; fp16 takes what backend_for says, and
    // forcing it on a device without a fitting shape is an error, not a crash.
    assert!(NetKernels::with_backend(&gpu, Storage::F32, Backend::CoopMatrix).is_err());
    let k = NetKernels::new(&gpu, Storage::F16).unwrap();
    assert_eq!(k.backend, backend_for(&gpu.caps, Storage::F16));
    if coop_tile(&gpu.caps).is_none() {
        assert_eq!(k.backend, Backend::Portable);
        let e = NetKernels::with_backend(&gpu, Storage::F16, Backend::CoopMatrix)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("no cooperative-matrix shape"), "{e}");
    }
    let _ = vk::ComponentTypeKHR::FLOAT16;
}
