//! Frame passes (§4.2.2, §4.3, §4.4, §5.2) against their CPU references on a tiny scene: the
//! procedural test room, 6 views at 32×24, a novel camera at 40×30, exact (RGBA32F) maps,
//! validation on.

mod common;

use glam::Vec3;
use relit_engine::frame::{
    self, emitters, features, irradiance, output, reproject, target_mirror, view_cull, FrameScene,
    HostMaps, Lighting, MapFormat, Mode, RefInputs, Renderer,
};
use relit_engine::net::{NetBase, NetConfig, NetKernels, Network, Params, RandomParams, Storage};
use relit_engine::raster::GbufferPixels;
use relit_engine::scene::synth::{self, SynthOptions};
use relit_engine::scene::{Camera, Light, LightShape, Mesh};

struct Tiny {
    mesh: Mesh,
    cams: Vec<Camera>,
    host: HostMaps,
    novel: Camera,
    /// Two added lights: "a", a small disk 0.8 m in front of the novel camera facing it, and
    /// "b" near the ceiling.
    lights: Vec<Light>,
    /// A declared original light: a 0.8 m square on the surface the novel camera sees at its
    /// pixel (8, 8), facing it.
    original: Light,
}

/// Smooth, positive, position-dependent fields stand in for the baked maps (the passes only
/// resample them); images are CPU-shaded.
fn tiny() -> Tiny {
    let o = SynthOptions {
        views: 6,
        width: 32,
        height: 24,
        seed: 3,
        wall_subdiv: 2,
    };
    let (mesh, albedo) = synth::room(o.wall_subdiv);
    let (lights, _) = synth::room_lights();
    let cams = synth::capture_cameras(&o);
    let mut host = HostMaps {
        width: 32,
        height: 24,
        ..Default::default()
    };
    let field = |c: &Camera, f: &dyn Fn(Vec3) -> [f32; 4]| -> Vec<[f32; 4]> {
        let mut v = Vec::new();
        for y in 0..c.height {
            for x in 0..c.width {
                let d = c.ray_dir(glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
                let p = match relit_engine::cpu::closest_hit(&mesh, c.center(), d, 0.0, 1e4) {
                    Some(h) => c.center() + d * h.t,
                    None => Vec3::ZERO,
                };
                v.push(f(p));
            }
        }
        v
    };
    for c in &cams {
        let img = synth::shade(&mesh, &albedo, c, &lights[0]);
        host.img
            .push(img.pixels.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect());
        host.msrc.push(field(c, &|p| {
            [0.2 + 0.1 * p.x.sin(), 0.3 + 0.1 * p.y.cos(), 0.25, 1.0]
        }));
        host.esrc.push(field(c, &|p| {
            [2.0 + p.y, 2.5 + 0.5 * p.x.cos(), 3.0 + 0.3 * p.z, 1.0]
        }));
    }
    for l in 0..2 {
        for c in &cams {
            host.eadd.push(field(c, &|p| {
                let s = 1.0 + l as f32;
                [
                    s * (1.0 + 0.2 * p.x),
                    s * 0.8,
                    s * (0.5 + 0.1 * p.z.abs()),
                    1.0,
                ]
            }));
        }
    }
    let c0 = &cams[0];
    let eye = c0.center() + Vec3::new(0.15, -0.05, 0.1);
    let target = eye + c0.rotation.transpose() * Vec3::Z + Vec3::new(0.1, 0.0, 0.0);
    let novel = Camera::look_at(eye, target, Vec3::Y, 40, 30, 30.0);
    let fwd = (target - eye).normalize();
    let disk = |name: &str, center: Vec3, normal: Vec3| Light {
        name: name.into(),
        shape: LightShape::Disk {
            center,
            normal,
            radius: 0.08,
        },
        radiance: [40.0, 30.0, 20.0],
        original: false,
        estimated: false,
    };
    let lights = vec![
        disk("a", eye + fwd * 0.8 + fwd.cross(Vec3::Y) * 0.1, -fwd),
        disk("b", Vec3::new(0.5, 2.3, 0.5), Vec3::NEG_Y),
    ];
    let original = on_surface(&mesh, &novel, (8, 8));
    Tiny {
        mesh,
        cams,
        host,
        novel,
        lights,
        original,
    }
}

/// A declared original light (a 0.8 m square, 5 mm off the surface) where `cam`'s pixel `px`
/// meets the proxy, facing the camera.
fn on_surface(mesh: &Mesh, cam: &Camera, px: (u32, u32)) -> Light {
    let d = cam.ray_dir(glam::Vec2::new(px.0 as f32 + 0.5, px.1 as f32 + 0.5));
    let h = relit_engine::cpu::closest_hit(mesh, cam.center(), d, 0.0, 1e4).unwrap();
    let mut n = mesh.face_normal(h.tri as usize);
    if n.dot(d) > 0.0 {
        n = -n;
    }
    let u = n.any_orthonormal_vector() * 0.8;
    let v = n.cross(u);
    let centre = cam.center() + d * h.t + n * 0.005;
    Light {
        name: "panel".into(),
        shape: LightShape::Quad {
            corner: centre - 0.5 * (u + v),
            edge_u: u,
            edge_v: v,
        },
        radiance: [9.0, 8.0, 6.0],
        original: true,
        estimated: false,
    }
}

/// (fraction of pixels where any channel differs by more than `tol` relative to the scale of
/// the reference, worst difference).
fn mismatch(gpu: &[[f32; 4]], cpu: &[[f32; 4]], tol: f32) -> (f32, f32) {
    let scale = cpu
        .iter()
        .flat_map(|p| p[..3].iter())
        .fold(0f32, |m, v| m.max(v.abs()))
        .max(1e-6);
    let mut bad = 0;
    let mut worst = 0f32;
    for (g, c) in gpu.iter().zip(cpu) {
        let e = (0..4).map(|k| (g[k] - c[k]).abs()).fold(0f32, f32::max) / scale;
        worst = worst.max(e);
        if e > tol {
            bad += 1;
        }
    }
    (bad as f32 / gpu.len().max(1) as f32, worst)
}
/// The CPU references' inputs for the frame `r` last rendered from `cam` (without live lights).
fn ref_inputs<'a>(
    r: &'a Renderer,
    t: &'a Tiny,
    g: &'a GbufferPixels,
    cam: &Camera,
    active: &'a [u32],
    lighting: &'a Lighting,
) -> RefInputs<'a> {
    RefInputs {
        data: &r.scene.data,
        maps: &t.host,
        gpos: &g.pos_depth,
        gnrm: &g.normal,
        width: cam.width,
        height: cam.height,
        eye: cam.center(),
        active,
        intensities: &lighting.intensities,
        alpha_dim: lighting.alpha_dim,
        exclude: r.exclude,
        emitters: &r.scene.emitters,
        originals: &r.scene.originals,
        keep: &lighting.originals,
        live: None,
    }
}

/// A renderer without a network over exact maps, two added lights, one of them on, and the
/// declared original light.
fn ulr_renderer(gpu: &std::sync::Arc<relit_engine::gpu::Gpu>, t: &Tiny) -> (Renderer, Lighting) {
    let lights = [t.lights.clone(), vec![t.original.clone()]].concat();
    let scene = FrameScene::from_parts(gpu, &t.mesh, &t.cams, &t.host, &lights, MapFormat::Rgba32f)
        .unwrap();
    let lighting = Lighting {
        intensities: vec![0.7, 0.0],
        alpha_dim: 0.4,
        ..Default::default()
    };
    (
        Renderer::new(gpu, scene, None, Storage::F32).unwrap(),
        lighting,
    )
}

#[test]
fn frame_passes_match_cpu_references() {
    let gpu = common::gpu();
    let t = tiny();
    let (mut r, lighting) = ulr_renderer(&gpu, &t);
    r.render(&t.novel, &lighting, Mode::Ulr, 1.0, None).unwrap();
    let b = r.buffers_ref().unwrap();
    let g = b.gbuf.download().unwrap();
    let npix = (t.novel.width * t.novel.height) as usize;
    let surf = g.pos_depth.iter().filter(|p| p[3] > 0.0).count();
    assert!(surf * 10 > npix * 9, "the novel view must see the room");
    let active = r.active_views().to_vec();
    assert_eq!(
        active.len(),
        r.scene.data.cameras.len(),
        "6 views: all take part"
    );
    let inputs = ref_inputs(&r, &t, &g, &t.novel, &active, &lighting);
    let dl = |buf: &relit_engine::gpu::Buffer, planes: usize| {
        let mut v: Vec<[f32; 4]> = buf.download_vec().unwrap();
        v.truncate(planes * npix);
        v
    };

    // Reproject: the depth test and the luminance ranks can flip at edges where GPU and CPU
    // projections differ in the last bit; bilinear weights on lavapipe are 8-bit fixed point.
    // 1% of the reference's scale on ≥ 97% of pixels, per plane.
    let comp = b.composites().unwrap();
    let comp_ref = reproject::reference(&inputs);
    for k in 0..reproject::PLANES {
        let s = k * npix..(k + 1) * npix;
        let (bad, worst) = mismatch(&comp[s.clone()], &comp_ref[s.clone()], 0.01);
        eprintln!("composite {k}: {:.2}% over, worst {worst:.4}", bad * 100.0);
        assert!(
            bad <= 0.03,
            "composite plane {k}: {:.1}% differ",
            bad * 100.0
        );
        let defined = comp_ref[s].iter().filter(|p| p[3] > 0.0).count();
        assert!(
            defined * 10 > surf * 8,
            "plane {k}: most surface pixels have data"
        );
    }
    // The views that see each pixel's point (the glossy layer's photos' part reads them): the
    // depth test can flip at edges, as above.
    let seen: Vec<[u32; 2]> = b.views_seen.download_vec().unwrap();
    let seen_ref = reproject::views_seen_reference(&inputs);
    let bad = (seen[..npix].iter().zip(&seen_ref))
        .filter(|(a, b)| a != b)
        .count();
    let any = seen_ref.iter().filter(|s| s[0] != 0).count();
    assert!(
        bad * 100 <= 3 * npix,
        "views seen: {bad} of {npix} pixels differ"
    );
    assert!(
        any * 10 > surf * 8,
        "views seen: {any} of {surf} surface pixels are seen"
    );
    // I_5 (max) ≥ I_7 (median) ≥ I_8 (min) in luminance, where defined.
    let lum = |p: [f32; 4]| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    for p in 0..npix {
        let (hi, med, lo) = (
            comp_ref[4 * npix + p],
            comp_ref[6 * npix + p],
            comp_ref[7 * npix + p],
        );
        assert!(lum(hi) + 1e-6 >= lum(med) && lum(med) + 1e-6 >= lum(lo));
    }

    let irr = dl(&b.irr, irradiance::PLANES);
    let irr_ref = irradiance::reference(&inputs);
    for k in 0..irradiance::PLANES {
        let s = k * npix..(k + 1) * npix;
        let (bad, worst) = mismatch(&irr[s.clone()], &irr_ref[s], 0.01);
        eprintln!("irradiance {k}: {:.2}% over, worst {worst:.4}", bad * 100.0);
        assert!(
            bad <= 0.03,
            "irradiance plane {k}: {:.1}% differ",
            bad * 100.0
        );
    }

    // Target mirror: the ray hit and the best view may differ at edges: same bounds.
    let mirror = dl(&b.mirror, 1);
    let mirror_ref = target_mirror::reference(&inputs, &t.mesh);
    let (bad, worst) = mismatch(&mirror, &mirror_ref, 0.01);
    eprintln!("target mirror: {:.2}% over, worst {worst:.4}", bad * 100.0);
    assert!(bad <= 0.03, "target mirror: {:.1}% differ", bad * 100.0);
    assert!(mirror_ref.iter().filter(|p| p[3] > 0.0).count() * 2 > surf);

    // Features from the GPU's own pass outputs: exact up to float rounding (1e-4).
    let feats = b.input.download_chw().unwrap();
    let feats_ref = features::reference(&inputs, &comp, &irr, &mirror);
    assert_eq!(feats.len(), 66 * npix);
    for c in 0..66 {
        for p in 0..npix {
            let (a, e) = (feats[c * npix + p], feats_ref[c * npix + p]);
            assert!(
                (a - e).abs() <= 1e-4 * e.abs().max(1.0),
                "channel {c} ({}) pixel {p}: {a} vs {e}",
                features::channel_names()[c]
            );
        }
    }

    // ULR output: I_1 as linear HDR, display = exposure + sRGB (±1 code value).
    let hdr = r.hdr().unwrap();
    let ldr = r.ldr().unwrap();
    // The lit added light "a" is drawn over the composite where the camera sees it.
    let ulr: Vec<[f32; 3]> = (0..npix)
        .map(|p| {
            let c = comp[p];
            if g.pos_depth[p][3] > 0.0 {
                [c[0], c[1], c[2]]
            } else {
                [0.0; 3]
            }
        })
        .collect();
    let (added, originals) = (r.scene.emitters.clone(), r.scene.originals.clone());
    let drawn = emitters::Drawn {
        added: &added,
        intensities: &lighting.intensities,
        originals: &originals,
        alpha_dim: lighting.alpha_dim,
        keep: &lighting.originals,
    };
    let draw = |base: &[[f32; 3]]| {
        emitters::reference_emitters(
            &t.novel,
            &g.pos_depth,
            (&comp, &irr[npix..2 * npix]),
            &drawn,
            base,
        )
    };
    let ulr_want = draw(&ulr);
    let w = t.novel.width;
    let ray = |p: usize| {
        let xy = glam::Vec2::new((p as u32 % w) as f32 + 0.5, (p as u32 / w) as f32 + 0.5);
        t.novel.ray_dir(xy).normalize()
    };
    let eye = t.novel.center();
    let lit = |p| emitters::nearest_emitter(&added, drawn.intensities, eye, ray(p), 1e30);
    let (mut by_a, mut by_panel) = (0, 0);
    for p in (0..npix).filter(|&p| ulr_want[p] != ulr[p]) {
        if lit(p).is_some() {
            by_a += 1
        } else {
            by_panel += 1
        }
    }
    assert!(
        (10..npix / 4).contains(&by_a),
        "light a covers {by_a} pixels"
    );
    // The panel shows 0.6 of its glow in I_1 (α_dim 0.4) plus its reflection of light a.
    assert!(
        (10..npix / 4).contains(&by_panel),
        "the panel covers {by_panel} pixels"
    );
    let p = (8 * t.novel.width + 8) as usize;
    let ea = Vec3::from_slice(&irr[npix + p][..3]);
    let albedo = emitters::EMITTER_ALBEDO; // no albedo mesh here
    let i1 = Vec3::from_slice(&comp[p][..3]);
    assert!(i1 != Vec3::ZERO, "a view sees the panel's centre");
    let want = 0.6 * i1 + albedo / std::f32::consts::PI * ea;
    assert!(
        (Vec3::from(ulr_want[p]) - want).abs().max_element() < 1e-4,
        "panel pixel {p}"
    );
    for p in 0..npix {
        let want = ulr_want[p];
        for k in 0..3 {
            assert!((hdr[p][k] - want[k]).abs() <= 1e-6, "hdr pixel {p}");
        }
        let d = output::display([want[0], want[1], want[2]], 1.0);
        for k in 0..3 {
            assert!(
                (ldr[4 * p + k] as i32 - d[k] as i32).abs() <= 1,
                "ldr pixel {p}"
            );
        }
    }
    // Ratio mode: I_1 relit by eq. 5's pseudo-albedo rule, from the passes' own outputs.
    r.render(&t.novel, &lighting, Mode::Ratio, 1.0, None)
        .unwrap();
    let hdr = r.hdr().unwrap();
    let ratio: Vec<[f32; 3]> = output::reference_ratio(&comp, &irr, npix)
        .into_iter()
        .enumerate()
        .map(|(p, w)| if g.pos_depth[p][3] > 0.0 { w } else { [0.0; 3] })
        .collect();
    let want = draw(&ratio);
    for p in 0..npix {
        let w = want[p];
        for k in 0..3 {
            assert!(
                (hdr[p][k] - w[k]).abs() <= 1e-5 * w[k].abs().max(1.0),
                "ratio pixel {p}: {} vs {}",
                hdr[p][k],
                w[k]
            );
        }
    }
    common::assert_no_validation_errors(&gpu);
}

/// Leave-one-out (`relit dump` of an input view): the excluded view takes part in no pass,
/// and the passes still match their references.
#[test]
fn leave_one_out_excludes_the_view_from_every_pass() {
    let gpu = common::gpu();
    let t = tiny();
    let (mut r, lighting) = ulr_renderer(&gpu, &t);
    // The novel camera is view 0 itself: with it left out, nothing may copy it.
    let cam = t.cams[0].clone();
    let npix = (cam.width * cam.height) as usize;
    let dl = |buf: &relit_engine::gpu::Buffer, planes: usize| {
        let mut v: Vec<[f32; 4]> = buf.download_vec().unwrap();
        v.truncate(planes * npix);
        v
    };
    r.render(&cam, &lighting, Mode::Ulr, 1.0, None).unwrap();
    let with0 = r.buffers_ref().unwrap().composites().unwrap();
    r.exclude = Some(0);
    r.render(&cam, &lighting, Mode::Ulr, 1.0, None).unwrap();
    let b = r.buffers_ref().unwrap();
    let g = b.gbuf.download().unwrap();
    let active = r.active_views().to_vec();
    assert!(!active.contains(&0));
    let inputs = ref_inputs(&r, &t, &g, &cam, &active, &lighting);
    let comp = b.composites().unwrap();
    let (bad, _) = mismatch(&comp, &reproject::reference(&inputs), 0.01);
    assert!(bad <= 0.03, "composites: {:.1}% differ", bad * 100.0);
    // With view 0 in, I_1 at its own camera is view 0's image; without it, it is not.
    let (same, _) = mismatch(&with0[..npix], &t.host.img[0], 0.01);
    let (left_out, _) = mismatch(&comp[..npix], &t.host.img[0], 0.01);
    assert!(
        same < 0.05 && left_out > 0.2,
        "I_1 vs view 0: {same} with it, {left_out} without"
    );
    let (bad, _) = mismatch(
        &dl(&b.mirror, 1),
        &target_mirror::reference(&inputs, &t.mesh),
        0.01,
    );
    assert!(bad <= 0.03, "target mirror: {:.1}% differ", bad * 100.0);
    common::assert_no_validation_errors(&gpu);
}

/// Network mode end to end: the frame's output equals the output transform applied to the
/// network run separately on the frame's own input tensor, for both bases (the ratio base is
/// formed from that input by `output::ratio_base`, as `model.py` forms it), with `shrink`, and
/// with `gate` under a dimmed original light and a lamp (the lamp's share of the light, 0.3–0.5,
/// below the gate's 1: every correction scaled), with `gain` alone and gated, and with `agree`
/// alone and with the gate and gain (the check that each option changes the image keeps the
/// cases honest).
#[test]
fn network_mode_output_matches_network_on_the_frame_input() {
    // The tiny scene's views agree closely (D's quartiles ~3e-6, 2e-4, 7e-4; largest 0.016):
    // at this A about two thirds of the covered pixels' corrections are scaled down.
    const AGREE: f32 = 5e-4;
    let gpu = common::gpu();
    let t = tiny();
    for (storage, base, shrink, gate, gain, agree) in [
        (Storage::F32, NetBase::None, 0.0, 0.0, false, 0.0),
        (Storage::F16, NetBase::None, 0.0, 0.0, false, 0.0),
        (Storage::F32, NetBase::Ratio, 0.0, 0.0, false, 0.0),
        (Storage::F16, NetBase::Ratio, 0.0, 0.0, false, 0.0),
        (Storage::F32, NetBase::Ratio, 0.02, 0.0, false, 0.0),
        (Storage::F32, NetBase::Ratio, 0.0, 1.0, false, 0.0),
        (Storage::F16, NetBase::Ratio, 0.02, 1.0, false, 0.0),
        (Storage::F32, NetBase::Ratio, 0.0, 0.0, true, 0.0),
        (Storage::F32, NetBase::Ratio, 0.0, 1.0, true, 0.0),
        (Storage::F32, NetBase::Ratio, 0.0, 0.0, false, AGREE),
        (Storage::F16, NetBase::Ratio, 0.0, 1.0, true, AGREE),
        (Storage::F32, NetBase::Glossy, 0.0, 0.0, false, 0.0),
        (Storage::F16, NetBase::Glossy, 0.0, 1.0, true, AGREE),
    ] {
        let lights = if gate > 0.0 { &t.lights[..] } else { &[] };
        let scene =
            FrameScene::from_parts(&gpu, &t.mesh, &t.cams, &t.host, lights, MapFormat::Rgba16f)
                .unwrap();
        let mut cfg = NetConfig::paper(8);
        cfg.levels = 3;
        cfg.base = base;
        cfg.shrink = shrink;
        cfg.gate = gate;
        cfg.gain = gain;
        cfg.agree = agree;
        let mk = || {
            Network::from_params(
                NetKernels::new(&gpu, storage).unwrap(),
                cfg.clone(),
                &RandomParams(4),
            )
            .unwrap()
        };
        let mut r = Renderer::new(&gpu, scene, Some(mk()), storage).unwrap();
        let lighting = match gate > 0.0 {
            true => Lighting {
                intensities: vec![0.0, 0.5],
                alpha_dim: 0.5,
                ..Default::default()
            },
            false => Lighting {
                intensities: vec![],
                alpha_dim: 0.0,
                ..Default::default()
            },
        };
        r.render(&t.novel, &lighting, Mode::Network, 2.0, None)
            .unwrap();
        let b = r.buffers_ref().unwrap();
        let (w, h) = (t.novel.width, t.novel.height);
        let input = b.input.download_chw().unwrap();
        let has = surface_mask(b);
        let out = mk().run(&input, h, w).unwrap();
        let ratio_in = (base != NetBase::None).then_some(&input[..]);
        // Base glossy: glossy mode's image from the frame's own glossy and irradiance planes.
        let npix = (w * h) as usize;
        let glossy_image = (base == NetBase::Glossy).then(|| {
            let mut gl: Vec<[f32; 4]> = b.glossy.download_vec().unwrap();
            gl.truncate(frame::glossy::PLANES * npix);
            let mut irr: Vec<[f32; 4]> = b.irr.download_vec().unwrap();
            irr.truncate(irradiance::PLANES * npix);
            frame::glossy::reference_image(&gl, &irr, npix)
        });
        let glossy_in = glossy_image.as_deref();
        let c = output::Corrections {
            shrink,
            gate,
            gain,
            agree,
        };
        let want = output::reference_network_on(&out, ratio_in, glossy_in, c, w as usize, &has);
        let without_agree = output::Corrections { agree: 0.0, ..c };
        for other in [output::Corrections::default(), without_agree] {
            if c != other {
                let plain = output::reference_network_on(
                    &out, ratio_in, glossy_in, other, w as usize, &has,
                );
                assert!(
                    want != plain,
                    "{c:?} against {other:?} changed nothing: not a test"
                );
            }
        }
        assert_close(
            &r.hdr().unwrap(),
            &want,
            1e-3,
            &format!("{storage:?} {base:?} {c:?}"),
        );
        assert!(r
            .render(&t.novel, &lighting, Mode::Network, 1.0, None)
            .is_ok());
    }
    common::assert_no_validation_errors(&gpu);
}

/// The viewer's moving frame fills holes (`Renderer::fill_holes`): in ratio, glossy and ULR
/// modes each hole takes the mean of the nearest covered pixels along 8 directions, as
/// `output::fill_holes` computes from the mode's own image without the fill (within 1e-5);
/// covered pixels keep their value.
#[test]
fn holes_are_filled_from_their_covered_neighbours_when_asked() {
    let gpu = common::gpu();
    let t = tiny();
    let scene =
        FrameScene::from_parts(&gpu, &t.mesh, &t.cams, &t.host, &[], MapFormat::Rgba32f).unwrap();
    let mut r = Renderer::new(&gpu, scene, None, Storage::F32).unwrap();
    let lighting = Lighting {
        intensities: vec![],
        alpha_dim: 0.3,
        ..Default::default()
    };
    let npix = (t.novel.width * t.novel.height) as usize;
    for mode in [Mode::Ratio, Mode::Glossy, Mode::Ulr] {
        r.fill_holes = false;
        r.render(&t.novel, &lighting, mode, 1.0, None).unwrap();
        let plain = rgb(&r);
        let b = r.buffers_ref().unwrap();
        let surface = surface_mask(b);
        let comp = b.composites().unwrap();
        let covered: Vec<bool> = (0..npix).map(|p| comp[p][..3] != [0.0; 3]).collect();
        let holes = (0..npix).filter(|&p| surface[p] && !covered[p]).count();
        assert!(holes > 0, "the tiny view has holes");
        r.fill_holes = true;
        r.render(&t.novel, &lighting, mode, 1.0, None).unwrap();
        let want = output::fill_holes(&plain, &covered, &surface, t.novel.width as usize);
        let filled = (0..npix).filter(|&p| want[p] != plain[p]).count();
        assert!(
            filled * 2 > holes,
            "{mode:?}: {filled} of {holes} holes filled"
        );
        assert_close(&r.hdr().unwrap(), &want, 1e-5, &format!("{mode:?} filled"));
    }
    common::assert_no_validation_errors(&gpu);
}

/// A network with base "ratio" whose output conv is zero (as `model.py` initializes it, before
/// any training) renders the ratio image: relative 1e-4 with fp32 storage (the input channels
/// are tonemapped and untonemapped once), 2e-2 with fp16 (11-bit channels).
#[test]
fn untrained_ratio_network_renders_the_ratio_image() {
    struct ZeroOut(RandomParams);
    impl Params for ZeroOut {
        fn get(&self, name: &str, shape: &[usize]) -> relit_engine::Result<Vec<f32>> {
            let v = self.0.get(name, shape)?;
            Ok(if name.starts_with("out_conv.") {
                vec![0.0; v.len()]
            } else {
                v
            })
        }
    }
    let gpu = common::gpu();
    let t = tiny();
    for (storage, tol) in [(Storage::F32, 1e-4), (Storage::F16, 2e-2)] {
        let mut r = tiny_renderer(&gpu, &t, storage, NetBase::Ratio, &ZeroOut(RandomParams(5)));
        let lighting = Lighting {
            intensities: vec![],
            alpha_dim: 0.5,
            ..Default::default()
        };
        r.render(&t.novel, &lighting, Mode::Ratio, 1.0, None)
            .unwrap();
        let ratio = rgb(&r);
        assert!(ratio.iter().any(|c| c[0] > 0.0), "the ratio image is black");
        r.render(&t.novel, &lighting, Mode::Network, 1.0, None)
            .unwrap();
        assert_close(&r.hdr().unwrap(), &ratio, tol, &format!("{storage:?}"));
    }
    common::assert_no_validation_errors(&gpu);
}

/// A gated network (`gate` > 0, random weights, so every correction is large) where no lamp
/// reaches (the photos' lighting, and the original light dimmed alone: the new light's share is
/// 0) renders ratio mode's image on every covered pixel (the same arithmetic: within 1e-6, with
/// fp32 and fp16 storage alike) and still fills the holes; with a lamp on, the same network
/// does not render it.
#[test]
fn gated_network_renders_the_ratio_image_where_no_lamp_reaches() {
    let gpu = common::gpu();
    let t = tiny();
    for storage in [Storage::F32, Storage::F16] {
        let scene = FrameScene::from_parts(
            &gpu,
            &t.mesh,
            &t.cams,
            &t.host,
            &t.lights,
            MapFormat::Rgba16f,
        )
        .unwrap();
        let mut cfg = NetConfig::paper(8);
        (cfg.levels, cfg.base, cfg.gate) = (3, NetBase::Ratio, 0.25);
        let kernels = NetKernels::new(&gpu, storage).unwrap();
        let net = Network::from_params(kernels, cfg, &RandomParams(7)).unwrap();
        let mut r = Renderer::new(&gpu, scene, Some(net), storage).unwrap();
        let mut frame = |lamp: f32, alpha_dim, mode| {
            let lighting = Lighting {
                intensities: vec![0.0, lamp],
                alpha_dim,
                ..Default::default()
            };
            r.render(&t.novel, &lighting, mode, 1.0, None).unwrap();
            (rgb(&r), r.buffers_ref().unwrap().composites().unwrap())
        };
        let (ulr, comp) = frame(0.0, 0.0, Mode::Ulr);
        let npix = ulr.len();
        let covered: Vec<usize> = (0..npix)
            .filter(|&p| comp[p][..3].iter().any(|&c| c != 0.0))
            .collect();
        assert!(covered.len() < npix, "no holes: not a test of them");
        let pick =
            |img: &[[f32; 3]]| -> Vec<[f32; 3]> { covered.iter().map(|&p| img[p]).collect() };
        let four = |img: Vec<[f32; 3]>| -> Vec<[f32; 4]> {
            img.iter().map(|c| [c[0], c[1], c[2], 1.0]).collect()
        };
        for alpha_dim in [0.0, 0.5] {
            let (ratio, _) = frame(0.0, alpha_dim, Mode::Ratio);
            let (network, _) = frame(0.0, alpha_dim, Mode::Network);
            let what = format!("{storage:?} α_dim {alpha_dim}, covered");
            assert_close(&four(pick(&network)), &pick(&ratio), 1e-6, &what);
            let holes_lit = (0..npix).any(|p| !covered.contains(&p) && network[p][0] > 0.0);
            assert!(holes_lit, "{storage:?}: the gate blanked the holes");
        }
        let (lit_ratio, _) = frame(1.0, 0.5, Mode::Ratio);
        let (lit_net, _) = frame(1.0, 0.5, Mode::Network);
        let moved = covered.iter().filter(|&&p| {
            (lit_net[p][0] - lit_ratio[p][0]).abs() > 0.05 * lit_ratio[p][0].abs().max(1.0)
        });
        assert!(
            moved.count() > 0,
            "{storage:?}: with a lamp on, the gate let nothing through"
        );
    }
    common::assert_no_validation_errors(&gpu);
}

/// Ratio-filled mode is ratio where the composite `I_1` is not black and the network's image in
/// the holes (`output::reference_ratio_filled` over the two modes' own frames), exactly; the
/// novel camera here looks past the views' coverage, so both kinds of pixel occur.
#[test]
fn ratio_filled_mode_is_ratio_with_the_networks_holes() {
    let gpu = common::gpu();
    let t = tiny();
    let mut r = tiny_renderer(&gpu, &t, Storage::F32, NetBase::None, &RandomParams(6));
    let lighting = Lighting {
        intensities: vec![],
        alpha_dim: 0.3,
        ..Default::default()
    };
    let mut frame = |mode| {
        r.render(&t.novel, &lighting, mode, 1.0, None).unwrap();
        (rgb(&r), r.buffers_ref().unwrap().composites().unwrap())
    };
    let (ratio, comp) = frame(Mode::Ratio);
    let (network, _) = frame(Mode::Network);
    let (filled, _) = frame(Mode::RatioFilled);
    let holes = (0..ratio.len())
        .filter(|&p| comp[p][..3].iter().all(|&c| c == 0.0))
        .count();
    eprintln!("ratio-filled: {holes} of {} pixels are holes", ratio.len());
    // Measured 172 of 1200: both branches of the mode are exercised.
    assert!(holes > 0 && holes < ratio.len(), "{holes} holes");
    let want = output::reference_ratio_filled(&comp, &ratio, &network);
    let got: Vec<[f32; 4]> = filled.iter().map(|c| [c[0], c[1], c[2], 1.0]).collect();
    assert_close(&got, &want, 1e-6, "ratio-filled");
    common::assert_no_validation_errors(&gpu);
}

/// A renderer over the tiny room with a width-8, 3-level network of `base` and `params`.
fn tiny_renderer(
    gpu: &std::sync::Arc<relit_engine::gpu::Gpu>,
    t: &Tiny,
    storage: Storage,
    base: NetBase,
    params: &dyn Params,
) -> Renderer {
    let scene =
        FrameScene::from_parts(gpu, &t.mesh, &t.cams, &t.host, &[], MapFormat::Rgba16f).unwrap();
    let mut cfg = NetConfig::paper(8);
    cfg.levels = 3;
    cfg.base = base;
    let net = Network::from_params(NetKernels::new(gpu, storage).unwrap(), cfg, params).unwrap();
    Renderer::new(gpu, scene, Some(net), storage).unwrap()
}

/// The last frame's linear RGB.
fn rgb(r: &Renderer) -> Vec<[f32; 3]> {
    r.hdr()
        .unwrap()
        .iter()
        .map(|p| [p[0], p[1], p[2]])
        .collect()
}

fn surface_mask(b: &relit_engine::frame::FrameBuffers) -> Vec<bool> {
    let g = b.gbuf.download().unwrap();
    g.pos_depth.iter().map(|p| p[3] > 0.0).collect()
}

/// Every pixel's RGB within `rel` of `want` (relative to max(|want|, 1)).
fn assert_close(got: &[[f32; 4]], want: &[[f32; 3]], rel: f32, what: &str) {
    for (p, (g, w)) in got.iter().zip(want).enumerate() {
        for k in 0..3 {
            let tol = rel * w[k].abs().max(1.0);
            assert!(
                (g[k] - w[k]).abs() <= tol,
                "{what} pixel {p}: {} vs {}",
                g[k],
                w[k]
            );
        }
    }
}

#[test]
fn lighting_presets_and_errors() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/demo_room");
    let scene = relit_engine::scene::Scene::load(&dir).unwrap();
    let l = Lighting::preset(&scene, "extra0_on_dimmed").unwrap();
    let names = frame::added_lights(&scene);
    assert_eq!(l.intensities.len(), names.len());
    let i = names.iter().position(|n| n == "extra0").unwrap();
    assert_eq!(l.intensities[i], 1.0);
    assert_eq!(l.alpha_dim, 0.5);
    let e = Lighting::preset(&scene, "nope").unwrap_err().to_string();
    assert!(e.contains("nope") && e.contains("extra0_on_dimmed"), "{e}");
    // A path's lighting may set the declared original lights' factors, by name, and no other.
    let file = std::path::Path::new("path.json");
    let mut pl = relit_engine::scene::path::PathLighting {
        dim: 0.2,
        intensities: [("extra0".to_string(), 1.0)].into(),
        moves: Default::default(),
        originals: [(scene.original_names()[1].clone(), [0.0, 0.5, 1.0])].into(),
    };
    let l = Lighting::from_path(&scene, &pl, file).unwrap();
    assert_eq!(l.originals.len(), scene.original_names().len());
    assert_eq!(
        (l.originals[0], l.originals[1]),
        ([1.0; 3], [0.0, 0.5, 1.0])
    );
    assert!(l.per_light());
    pl.originals = [("extra0".to_string(), [0.5; 3])].into();
    let e = Lighting::from_path(&scene, &pl, file)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("path.json") && e.contains("extra0") && e.contains("original"),
        "{e}"
    );
}

/// View culling (frame/view_cull.rs): the pass's visibility bits match the CPU reference, and a
/// frame that culls (the threshold lowered so that the 6-view room culls) renders its
/// composites from its chosen views as the CPU reference does from the same views.
#[test]
fn view_culling_matches_cpu_reference_and_culled_frames_too() {
    let gpu = common::gpu();
    let t = tiny();
    let (mut r, lighting) = ulr_renderer(&gpu, &t);
    // Each of the 6 views alone sees some grid point, so only a budget without a cover (1 view
    // per point on average, the most relevant first) leaves some out.
    r.culling = view_cull::Culling {
        above: 2,
        budget: 1.0,
        min_cover: 0,
    };
    r.render(&t.novel, &lighting, Mode::Ulr, 1.0, None).unwrap();
    let active = r.active_views().to_vec();
    let (seen, points) = r.view_visibility(&t.novel, None).unwrap();
    let b = r.buffers_ref().unwrap();
    let g = b.gbuf.download().unwrap();
    let size = (t.novel.width, t.novel.height);
    let grid = view_cull::grid(size.0, size.1);
    let (seen_ref, points_ref) = view_cull::reference(&r.scene.data, &g.pos_depth, size, grid);
    assert_eq!(
        points, points_ref,
        "grid points are copied from the G-buffer"
    );
    let ones: u32 = seen_ref.iter().map(|b| b.count_ones()).sum();
    let differ: u32 = (seen.iter().zip(&seen_ref))
        .map(|(a, b)| (a ^ b).count_ones())
        .sum();
    eprintln!("view culling: {ones} (view, point) pairs seen, {differ} differ");
    assert!(ones > 200, "the views see the grid");
    // The depth test can flip where GPU and CPU projections differ in the last bit.
    assert!(
        differ * 100 <= ones,
        "{differ} of {ones} visibility bits differ"
    );
    let eye = t.novel.center();
    assert_eq!(
        active,
        view_cull::choose(&r.culling, &seen, &points, &r.scene.data.cameras, eye, None)
    );
    eprintln!("active views: {active:?}");
    assert!(!active.is_empty() && active.len() < t.cams.len());

    let npix = (size.0 * size.1) as usize;
    let inputs = ref_inputs(&r, &t, &g, &t.novel, &active, &lighting);
    let comp = b.composites().unwrap();
    let comp_ref = reproject::reference(&inputs);
    let (bad, worst) = mismatch(&comp[..4 * npix], &comp_ref[..4 * npix], 0.01);
    eprintln!(
        "culled composites I_1..4: {:.2}% over, worst {worst:.4}",
        bad * 100.0
    );
    assert!(bad <= 0.03, "culled composites: {:.1}% differ", bad * 100.0);
}

/// The choice of active views: every grid point some view sees keeps up to MIN_COVER views,
/// however irrelevant the only view that sees it; then the views nearest the novel camera, within
/// the budget; never the left-out view, never a view that sees no point.
#[test]
fn view_choice_covers_every_seen_point_within_budget() {
    let c = view_cull::Culling::default();
    assert!(!c.needed(32, None));
    assert!(c.needed(33, None));
    assert!(!c.needed(33, Some(3)));
    assert!(c.needed(33, Some(40)));
    // 100 cameras on a line looking at +z; 64 points on a wall at z = 5.
    let cams: Vec<Camera> = (0..100)
        .map(|i| {
            let c = Vec3::new(i as f32 * 0.1, 0.0, 0.0);
            Camera::look_at(c, c + Vec3::Z, Vec3::Y, 8, 8, 8.0)
        })
        .collect();
    let points: Vec<[f32; 4]> = (0..64)
        .map(|s| [(s % 8) as f32 * 0.5, (s / 8) as f32 * 0.5 - 2.0, 5.0, 1.0])
        .collect();
    let nw = 2;
    // Every view but 99 sees points 1..63; point 0 only view 99 sees; view 98 sees nothing.
    let mut seen = vec![0u32; nw * cams.len()];
    for j in 0..cams.len() {
        let bits = &mut seen[j * nw..(j + 1) * nw];
        match j {
            99 => bits[0] = 1,
            98 => {}
            _ => {
                bits[0] = !1;
                bits[1] = !0;
            }
        }
    }
    let eye = Vec3::new(3.0, 0.0, 0.0);
    let a = view_cull::choose(&c, &seen, &points, &cams, eye, Some(30));
    eprintln!("chosen: {a:?}");
    assert!(a.windows(2).all(|w| w[0] < w[1]), "ascending");
    assert!(a.contains(&99), "the only view of point 0 takes part");
    assert!(!a.contains(&98) && !a.contains(&30));
    assert!(a.len() <= frame::MAX_ACTIVE);
    // Points 1..63 are seen by every chosen view but 99; the budget bounds their count.
    let budget = (view_cull::VIEW_BUDGET * 64.0) as usize;
    let load = (a.len() - 1) * 63 + 1;
    assert!(load <= budget, "{} views over the budget", a.len());
    assert!(a.len() > view_cull::MIN_COVER as usize);
    assert!(load + 63 > budget, "the budget is used");
    // The nearest views to the eye (x = 3: view 30, left out) come first.
    for j in [29, 31, 28, 32] {
        assert!(a.contains(&j), "view {j} is among the nearest");
    }
    assert!(!a.contains(&0) && !a.contains(&97));
}

/// Lights moved or added in the viewer (frame/live.rs): their E_add, evaluated at the novel
/// view's points and at the target mirror's hits from direct light + a progressively refined
/// surface cache, matches the CPU reference; moving a light moves its light.
#[test]
fn live_lights_match_cpu_reference_and_light_where_they_are() {
    let gpu = common::gpu();
    let t = tiny();
    let mut fs = FrameScene::from_parts(
        &gpu,
        &t.mesh,
        &t.cams,
        &t.host,
        &t.lights,
        MapFormat::Rgba32f,
    )
    .unwrap();
    // The albedo mesh is a bake product; a known grey stands in.
    fs.albedo = Some(vec![[0.5, 0.5, 0.5, 1.0]; t.mesh.positions.len()]);
    let mut r = Renderer::new(&gpu, fs, None, Storage::F32).unwrap();
    let npix = (t.novel.width * t.novel.height) as usize;
    let render = |r: &mut Renderer, l: &Lighting| {
        r.render(&t.novel, l, Mode::Ratio, 1.0, None).unwrap();
        let b = r.buffers_ref().unwrap();
        let mut irr: Vec<[f32; 4]> = b.irr.download_vec().unwrap();
        irr.truncate(irradiance::PLANES * npix);
        let mut m: Vec<[f32; 4]> = b.mirror.download_vec().unwrap();
        m.truncate(npix);
        (irr, m)
    };
    // Light "b" alone (layer 1), baked maps, then live at a new place: the wall the novel
    // camera looks at, 0.4 m in front of it, facing it.
    let only_b = Lighting {
        intensities: vec![0.0, 1.0],
        alpha_dim: 0.0,
        ..Default::default()
    };
    let (baked, _) = render(&mut r, &only_b);
    let g = r.buffers_ref().unwrap().gbuf.download().unwrap();
    let centre = (t.novel.height / 2 * t.novel.width + t.novel.width / 2) as usize;
    let wall = Vec3::from_slice(&g.pos_depth[centre][..3]);
    let n = Vec3::from_slice(&g.normal[centre][..3]);
    let n = if n.dot(t.novel.center() - wall) < 0.0 {
        -n
    } else {
        n
    };
    let moved = Light {
        name: "b".into(),
        shape: LightShape::Disk {
            center: wall + 0.4 * n,
            normal: -n,
            radius: 0.1,
        },
        radiance: [30.0, 30.0, 30.0],
        original: false,
        estimated: false,
    };
    r.set_live_light(1, &moved).unwrap();
    assert!(r.refine_live().unwrap() && r.refine_live().unwrap());
    // The texels the last frame showed were refined first: 2 steps of 2 paths each on them,
    // none yet elsewhere.
    let tri = r.buffers_ref().unwrap().gbuf.download().unwrap().tri;
    let shown = r.live.texels_shown(&tri);
    let paths = r.live.texel_paths(1).unwrap();
    let p = r.live.params.paths_per_step;
    assert!(!shown.is_empty() && shown.len() < paths.len());
    for (i, &n) in paths.iter().enumerate() {
        let want = if shown.binary_search(&(i as u32)).is_ok() {
            2 * p
        } else {
            0
        };
        assert_eq!(n, want, "texel {i}");
    }
    // A third light, new, near the ceiling.
    let new = Light {
        name: "c".into(),
        shape: LightShape::Disk {
            center: Vec3::new(-0.5, 2.2, -0.3),
            normal: Vec3::NEG_Y,
            radius: 0.1,
        },
        radiance: [20.0, 10.0, 5.0],
        original: false,
        estimated: false,
    };
    r.set_live_light(2, &new).unwrap();
    r.refine_live().unwrap();
    let lighting = Lighting {
        intensities: vec![0.7, 1.0, 1.5],
        alpha_dim: 0.3,
        ..Default::default()
    };
    let (irr, mirror) = render(&mut r, &lighting);
    let g = r.buffers_ref().unwrap().gbuf.download().unwrap();
    let active = r.active_views().to_vec();
    let lights = r.live.lights();
    let caches = r.live.caches().unwrap();
    assert_eq!(lights.len(), 2);
    assert!(caches.iter().all(|c| c.iter().any(|v| v[0] > 0.0)));
    let inputs = RefInputs {
        live: Some(frame::LiveRef {
            mesh: &r.scene.geom,
            layout: r.live.layout(),
            gtri: &g.tri,
            lights: &lights,
            caches: &caches,
        }),
        ..ref_inputs(&r, &t, &g, &t.novel, &active, &lighting)
    };
    // Same random numbers; a shadow ray grazing an edge may flip: 2% of the scale on ≥ 95%.
    let irr_ref = irradiance::reference(&inputs);
    let s = npix..2 * npix;
    let (bad, worst) = mismatch(&irr[s.clone()], &irr_ref[s], 0.02);
    eprintln!("live E_add: {:.2}% over, worst {worst:.4}", bad * 100.0);
    assert!(bad <= 0.05, "live E_add: {:.1}% differ", bad * 100.0);
    let mirror_ref = target_mirror::reference(&inputs, &r.scene.geom);
    let (bad, worst) = mismatch(&mirror, &mirror_ref, 0.02);
    eprintln!(
        "live target mirror: {:.2}% over, worst {worst:.4}",
        bad * 100.0
    );
    assert!(bad <= 0.05, "live mirror: {:.1}% differ", bad * 100.0);

    // Light b moved to the wall in view: E_add there is now far above the baked map's.
    let (live_b, _) = render(
        &mut r,
        &Lighting {
            intensities: vec![0.0, 1.0, 0.0],
            alpha_dim: 0.0,
            ..Default::default()
        },
    );
    let (a, b) = (live_b[npix + centre][1], baked[npix + centre][1]);
    eprintln!("E_add at the centre: baked {b:.3}, moved {a:.3}");
    assert!(a > 3.0 * b && a > 1.0, "baked {b}, moved {a}");
    common::assert_no_validation_errors(&gpu);
}

/// A declared original light's albedo is the albedo mesh's mean over the vertices around it
/// (10–40 cm outside its outline, in its plane; each channel at most 1), 0.8 grey without a
/// mesh or a vertex there.
#[test]
fn an_original_lights_albedo_is_the_albedo_mesh_around_it() {
    let light = Light {
        name: "panel".into(),
        shape: LightShape::Quad {
            corner: Vec3::new(0.0, 2.59, 0.0),
            edge_u: Vec3::new(1.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, -1.0),
        },
        radiance: [5.0; 3],
        original: true,
        estimated: false,
    };
    // On the light (glow in its albedo), 5 cm beside it (bleeding), 20 cm and 30 cm beside it
    // (1 cm under its plane), 60 cm beside it, 10 cm below it.
    let positions = vec![
        [0.5, 2.58, -0.5],
        [1.05, 2.58, -0.5],
        [1.2, 2.58, -0.5],
        [0.5, 2.58, 0.3],
        [1.6, 2.58, -0.5],
        [1.2, 2.49, -0.5],
    ];
    let albedo = [
        [1.4, 1.0, 1.9, 0.0],
        [0.9, 0.6, 0.9, 1.0],
        [0.6, 0.1, 1.3, 1.0],
        [0.4, 0.1, 0.5, 1.0],
        [0.9, 0.9, 0.9, 1.0],
        [0.9, 0.9, 0.9, 1.0],
    ];
    let mesh = |positions: Vec<[f32; 3]>| Mesh {
        positions,
        colors: None,
        triangles: vec![],
    };
    let o = emitters::GpuOriginal::new(&light, Some((&mesh(positions.clone()), &albedo)));
    let want = Vec3::new(0.5, 0.1, 0.75);
    let got = Vec3::from_slice(&o.albedo[..3]);
    assert!((got - want).abs().max_element() < 1e-6, "{:?}", o.albedo);
    let grey = [emitters::EMITTER_ALBEDO; 3];
    assert_eq!(emitters::GpuOriginal::new(&light, None).albedo[..3], grey);
    let none_around = mesh(vec![positions[0], positions[1], positions[4]]);
    let o = emitters::GpuOriginal::new(&light, Some((&none_around, &albedo[..3])));
    assert_eq!(o.albedo[..3], grey);
}

/// Per-light control (frame/lighting.rs): the tiny scene with two declared original lights, each
/// with simulated irradiance layers of its own (different smooth fields, so that their shares
/// vary over the room). Factors of 1 render exactly what no factor renders; factors of their own
/// match the CPU references (E_rem, the target mirror, ratio mode with the panels drawn); equal
/// factors k on both act as α_dim' = α + (1 − α)(1 − k), whatever the shares.
#[test]
fn each_original_light_dims_on_its_own_as_its_cpu_reference() {
    let gpu = common::gpu();
    let mut t = tiny();
    let mut second = on_surface(&t.mesh, &t.novel, (30, 20));
    second.name = "panel2".into();
    let sims: [&dyn Fn(Vec3) -> [f32; 4]; 2] = [
        &|p| [1.0 + 0.8 * (2.0 * p.x).sin(), 1.2, 0.9 + 0.3 * p.z, 1.0],
        &|p| [0.6 + 0.2 * p.y, 1.0 + 0.7 * (1.5 * p.z).cos(), 0.7, 1.0],
    ];
    for f in sims {
        for c in &t.cams {
            t.host.eadd.push(field_of(&t.mesh, c, f));
        }
    }
    t.host.split = 2;
    let lights = [t.lights.clone(), vec![t.original.clone(), second]].concat();
    let scene =
        FrameScene::from_parts(&gpu, &t.mesh, &t.cams, &t.host, &lights, MapFormat::Rgba32f)
            .unwrap();
    assert_eq!((scene.split, scene.split_layer), (2, 2 * 6));
    let mut r = Renderer::new(&gpu, scene, None, Storage::F32).unwrap();
    let npix = (t.novel.width * t.novel.height) as usize;
    let lit = |originals: Vec<[f32; 3]>| Lighting {
        intensities: vec![0.7, 0.0],
        alpha_dim: 0.4,
        originals,
    };
    let mut frame = |l: &Lighting, mode: Mode| {
        r.render(&t.novel, l, mode, 1.0, None).unwrap();
        let b = r.buffers_ref().unwrap();
        let mut irr: Vec<[f32; 4]> = b.irr.download_vec().unwrap();
        irr.truncate(irradiance::PLANES * npix);
        let mut mirror: Vec<[f32; 4]> = b.mirror.download_vec().unwrap();
        mirror.truncate(npix);
        (irr, mirror, r.hdr().unwrap())
    };
    // Factors of 1: the very same frame as none.
    let none = frame(&lit(vec![]), Mode::Ratio);
    assert_eq!(none, frame(&lit(vec![[1.0; 3]; 2]), Mode::Ratio));
    // Equal factors: α_dim' = 0.4 + 0.6 · 0.5 = 0.7 (1e-5 relative: the shares sum to 1).
    let (irr_eq, ..) = frame(&lit(vec![[0.5; 3]; 2]), Mode::Ratio);
    for p in 0..npix {
        let (es, rem) = (irr_eq[p], irr_eq[2 * npix + p]);
        for k in 0..3 {
            assert!(
                (rem[k] - 0.7 * es[k]).abs() <= 1e-5 * es[k].max(1.0),
                "pixel {p}"
            );
        }
    }
    // Off, and a green-less half: against the CPU references.
    let l = lit(vec![[0.0; 3], [1.0, 0.5, 1.0]]);
    let (irr, mirror, hdr) = frame(&l, Mode::Ratio);
    let b = r.buffers_ref().unwrap();
    let g = b.gbuf.download().unwrap();
    let comp = b.composites().unwrap();
    let active = r.active_views().to_vec();
    let inputs = ref_inputs(&r, &t, &g, &t.novel, &active, &l);
    let irr_ref = irradiance::reference(&inputs);
    let s = 2 * npix..3 * npix;
    let (bad, worst) = mismatch(&irr[s.clone()], &irr_ref[s.clone()], 0.01);
    eprintln!(
        "per-light E_rem: {:.2}% over, worst {worst:.4}",
        bad * 100.0
    );
    assert!(bad <= 0.03, "per-light E_rem: {:.1}% differ", bad * 100.0);
    // Between the two lights' extremes, and apart from the uniform case somewhere.
    let mut moved = 0;
    for p in (0..npix).filter(|&p| irr_ref[p][3] > 0.0) {
        let (es, rem) = (irr_ref[p][0], irr_ref[2 * npix + p][0]);
        assert!(
            rem >= 0.4 * es - 1e-4 && rem <= es + 1e-4,
            "pixel {p}: {rem} of {es}"
        );
        moved += ((rem - irr_eq[2 * npix + p][0]).abs() > 0.02 * es) as usize;
    }
    assert!(
        moved * 2 > npix,
        "the shares move E_rem on {moved} of {npix} pixels"
    );
    let mirror_ref = target_mirror::reference(&inputs, &t.mesh);
    let (bad, worst) = mismatch(&mirror, &mirror_ref, 0.01);
    eprintln!(
        "per-light target mirror: {:.2}% over, worst {worst:.4}",
        bad * 100.0
    );
    assert!(
        bad <= 0.03,
        "per-light target mirror: {:.1}% differ",
        bad * 100.0
    );
    // Ratio mode from the passes' own outputs, the panels drawn at their own factors: the
    // first, off, shows only its reflection of light a.
    let (added, originals) = (r.scene.emitters.clone(), r.scene.originals.clone());
    let drawn = emitters::Drawn {
        added: &added,
        intensities: &l.intensities,
        originals: &originals,
        alpha_dim: l.alpha_dim,
        keep: &l.originals,
    };
    let ratio: Vec<[f32; 3]> = output::reference_ratio(&comp, &irr, npix)
        .into_iter()
        .enumerate()
        .map(|(p, w)| if g.pos_depth[p][3] > 0.0 { w } else { [0.0; 3] })
        .collect();
    let ea = &irr[npix..2 * npix];
    let want = emitters::reference_emitters(&t.novel, &g.pos_depth, (&comp, ea), &drawn, &ratio);
    for p in 0..npix {
        for k in 0..3 {
            let w = want[p][k];
            assert!(
                (hdr[p][k] - w).abs() <= 1e-5 * w.abs().max(1.0),
                "ratio pixel {p}"
            );
        }
    }
    let p = (8 * t.novel.width + 8) as usize;
    let glow = emitters::EMITTER_ALBEDO / std::f32::consts::PI * Vec3::from_slice(&ea[p][..3]);
    assert!(
        (Vec3::from(want[p]) - glow).abs().max_element() < 1e-4,
        "the first panel is off"
    );
    common::assert_no_validation_errors(&gpu);
}

/// `f` at the proxy point each pixel of `c` sees (zero where none).
fn field_of(mesh: &Mesh, c: &Camera, f: &dyn Fn(Vec3) -> [f32; 4]) -> Vec<[f32; 4]> {
    let mut v = Vec::new();
    for y in 0..c.height {
        for x in 0..c.width {
            let d = c.ray_dir(glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
            v.push(
                match relit_engine::cpu::closest_hit(mesh, c.center(), d, 0.0, 1e4) {
                    Some(h) => f(c.center() + d * h.t),
                    None => f(Vec3::ZERO),
                },
            );
        }
    }
    v
}
