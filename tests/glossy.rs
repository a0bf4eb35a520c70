//! The view-dependent layer (§3, `frame/glossy.comp`, `frame/glossy_fit/`) and glossy mode on
//! a small room whose floor is glossy: its photos hold the diffuse shading plus S_TRUE × the
//! ceiling panel through the GGX lobe of roughness GLOSSY_LOBE_2 seen from each view. The layer
//! must match its CPU reference, the fit per surface must find that lobe and strength on the
//! floor and none on the walls; under the original lighting glossy mode must be ratio's image
//! where there is no fit and move the photos' highlights to the novel view where there is one;
//! and it must put a lamp's highlight where the mirror direction puts it, also after the lamp
//! moves. Validation on.

mod common;

use glam::{Vec2, Vec3};
use relit_engine::bake::GpuLight;
use relit_engine::constants::GLOSSY_LOBE_2;
use relit_engine::frame::{
    emitters, glossy, irradiance, FrameScene, HostMaps, Lighting, MapFormat, Mode, RefInputs,
    Renderer,
};
use relit_engine::net::Storage;
use relit_engine::scene::synth::{self, SynthOptions};
use relit_engine::scene::{Camera, Light, LightShape, Mesh};

/// The floor's specular strength in the photos: a dielectric's, within GLOSSY_WIDE_S (a wider
/// lobe stronger than that is out).
const S_TRUE: f32 = 0.07;

struct Room {
    mesh: Mesh,
    cams: Vec<Camera>,
    host: HostMaps,
    novel: Camera,
    /// The novel view under the panel, as the photos are made.
    novel_truth: Vec<[f32; 4]>,
    /// The added lamp (a small disk facing down) and the ceiling panel (original).
    lights: Vec<Light>,
}

fn lamp_at(center: Vec3) -> Light {
    Light {
        name: "lamp".into(),
        shape: LightShape::Disk {
            center,
            normal: Vec3::NEG_Y,
            radius: 0.12,
        },
        radiance: [40.0, 32.0, 24.0],
        original: false,
        estimated: false,
    }
}

/// Per view pixel: the surface point and its normal facing the camera.
fn surface_points(mesh: &Mesh, c: &Camera) -> Vec<Option<(Vec3, Vec3)>> {
    let mut v = Vec::new();
    for y in 0..c.height {
        for x in 0..c.width {
            let d = c.ray_dir(Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
            v.push(
                relit_engine::cpu::closest_hit(mesh, c.center(), d, 0.0, 1e4).map(|h| {
                    let mut n = mesh.face_normal(h.tri as usize);
                    if n.dot(d) > 0.0 {
                        n = -n;
                    }
                    (c.center() + d * h.t, n)
                }),
            );
        }
    }
    v
}

fn room() -> Room {
    let o = SynthOptions {
        views: 24,
        width: 40,
        height: 30,
        seed: 5,
        wall_subdiv: 2,
    };
    let (mesh, albedo) = synth::room(o.wall_subdiv);
    // The procedural room's ceiling panel, declared facing down (its emitting side).
    let panel = Light {
        name: "ceiling".into(),
        shape: LightShape::Quad {
            corner: Vec3::new(-0.4, 2.59, -0.3),
            edge_u: Vec3::new(0.8, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, 0.6),
        },
        radiance: [8.0, 7.6, 7.0],
        original: true,
        estimated: false,
    };
    let cams = synth::capture_cameras(&o);
    let mut host = HostMaps {
        width: o.width,
        height: o.height,
        ..Default::default()
    };
    for c in &cams {
        host.img.push(photo(&mesh, &albedo, c, &panel));
        let pts = surface_points(&mesh, c);
        let field = |f: &dyn Fn(Vec3) -> [f32; 4]| -> Vec<[f32; 4]> {
            pts.iter()
                .map(|s| s.map_or([0.0; 4], |(x, _)| f(x)))
                .collect()
        };
        host.msrc
            .push(field(&|p| [0.2 + 0.05 * p.x.sin(), 0.25, 0.2, 1.0]));
        host.esrc
            .push(field(&|p| [2.0 + 0.2 * p.x, 2.2, 2.4 + 0.1 * p.z, 1.0]));
    }
    for c in &cams {
        let pts = surface_points(&mesh, c);
        host.eadd.push(
            pts.iter()
                .map(|s| s.map_or([0.0; 4], |(x, _)| [1.0 + 0.1 * x.x, 0.9, 0.8, 1.0]))
                .collect(),
        );
    }
    let eye = Vec3::new(-0.9, 1.6, -1.1);
    let novel = Camera::look_at(eye, Vec3::new(0.4, 0.0, 0.3), Vec3::Y, 48, 36, 30.0);
    let novel_truth = photo(&mesh, &albedo, &novel, &panel);
    let lights = vec![lamp_at(Vec3::new(0.0, 2.0, 0.0)), panel];
    Room {
        mesh,
        cams,
        host,
        novel,
        novel_truth,
        lights,
    }
}

/// What camera c sees under the panel: the diffuse shading, plus on the floor S_TRUE × the
/// panel through lobe GLOSSY_LOBE_2 seen from c.
fn photo(mesh: &Mesh, albedo: &[[f32; 3]], c: &Camera, panel: &Light) -> Vec<[f32; 4]> {
    let gpanel = GpuLight::new(panel);
    let img = synth::shade(mesh, albedo, c, panel);
    let pts = surface_points(mesh, c);
    (img.pixels.iter().zip(&pts))
        .map(|(d, s)| {
            let g = match s {
                Some((x, n)) if n.y > 0.9 && glossy::sees_light(mesh, *x, *n, &gpanel) => {
                    let v = (c.center() - *x).normalize();
                    S_TRUE * glossy::lobe_light(*x, v, *n, GLOSSY_LOBE_2, &gpanel)
                }
                _ => Vec3::ZERO,
            };
            [d[0] + g.x, d[1] + g.y, d[2] + g.z, 1.0]
        })
        .collect()
}

fn renderer(gpu: &std::sync::Arc<relit_engine::gpu::Gpu>, t: &Room) -> Renderer {
    let fs = FrameScene::from_parts(
        gpu,
        &t.mesh,
        &t.cams,
        &t.host,
        &t.lights,
        MapFormat::Rgba32f,
    )
    .unwrap();
    // The albedo mesh is a bake product (live lights read it); a known grey stands in.
    let mut fs = fs;
    fs.albedo = Some(vec![[0.5, 0.5, 0.5, 1.0]; t.mesh.positions.len()]);
    Renderer::new(gpu, fs, None, Storage::F32).unwrap()
}

/// The last frame's planes of a buffer.
fn planes(buf: &relit_engine::gpu::Buffer, n: usize) -> Vec<[f32; 4]> {
    let mut v: Vec<[f32; 4]> = buf.download_vec().unwrap();
    v.truncate(n);
    v
}

/// The layer's planes `got` against `want`: the choice of lobe can flip where two explain the
/// views almost equally; bilinear weights on lavapipe are 8-bit fixed point: 1% of the plane's
/// scale on ≥ 97% of the pixels.
fn assert_planes_match(got: &[[f32; 4]], want: &[[f32; 4]], npix: usize, what: &str) {
    for k in 0..glossy::PLANES {
        let s = k * npix..(k + 1) * npix;
        let scale = (want[s.clone()].iter().flat_map(|p| p[..3].iter()))
            .fold(1e-6f32, |m, v| m.max(v.abs()));
        let bad = (got[s.clone()].iter().zip(&want[s]))
            .filter(|(a, b)| (0..3).any(|c| (a[c] - b[c]).abs() > 0.01 * scale))
            .count();
        assert!(
            bad * 100 <= 3 * npix,
            "{what}: glossy plane {k}: {bad} of {npix} pixels differ"
        );
    }
}

#[test]
fn glossy_layer_matches_cpu_reference_and_recovers_the_photos_fit() {
    let gpu = common::gpu();
    let t = room();
    let mut r = renderer(&gpu, &t);
    let lighting = Lighting {
        intensities: vec![0.8],
        alpha_dim: 0.5,
        ..Default::default()
    };
    let npix = (t.novel.width * t.novel.height) as usize;
    // Without the sight cache every slot traces, shared between neighbours (frame/sight.glsl).
    r.use_sight_cache = false;
    r.render(&t.novel, &lighting, Mode::Glossy, 1.0, None)
        .unwrap();
    let traced = planes(&r.buffers_ref().unwrap().glossy, glossy::PLANES * npix);
    r.use_sight_cache = true;
    r.render(&t.novel, &lighting, Mode::Glossy, 1.0, None)
        .unwrap();
    let b = r.buffers_ref().unwrap();
    let g = b.gbuf.download().unwrap();
    let comp = b.composites().unwrap();
    let irr = planes(&b.irr, irradiance::PLANES * npix);
    let gl = planes(&b.glossy, glossy::PLANES * npix);
    let hdr = r.hdr().unwrap();
    // The sums over the views, which the fit's renders take instead of the layer.
    r.render_glossy_sums(&t.novel, &lighting).unwrap();
    let sums = planes(
        &r.buffers_ref().unwrap().glossy_sums,
        glossy::SUM_PLANES * npix,
    );
    let active = r.active_views().to_vec();
    let inputs = RefInputs {
        data: &r.scene.data,
        maps: &t.host,
        gpos: &g.pos_depth,
        gnrm: &g.normal,
        width: t.novel.width,
        height: t.novel.height,
        eye: t.novel.center(),
        active: &active,
        intensities: &lighting.intensities,
        alpha_dim: lighting.alpha_dim,
        exclude: None,
        emitters: &r.scene.emitters,
        originals: &r.scene.originals,
        keep: &lighting.originals,
        live: None,
    };
    // The sums: 1% of each plane's scale on ≥ 97% of the pixels (bilinear weights on lavapipe
    // are 8-bit fixed point; the depth test can flip at edges).
    let sums_want = glossy::sums_reference(&inputs, &t.mesh, &comp);
    for k in 0..glossy::SUM_PLANES {
        let s = k * npix..(k + 1) * npix;
        let scale = (sums_want[s.clone()].iter().flat_map(|p| p.iter()))
            .fold(1e-6f32, |m, v| m.max(v.abs()));
        let bad = (sums[s.clone()].iter().zip(&sums_want[s]))
            .filter(|(a, b)| (0..4).any(|c| (a[c] - b[c]).abs() > 0.01 * scale))
            .count();
        assert!(
            bad * 100 <= 3 * npix,
            "glossy sums plane {k}: {bad} of {npix} pixels differ"
        );
    }
    // The layer.
    let per_tri = r
        .glossy_fit()
        .unwrap()
        .expect("a glossy frame made the fit");
    let sight = r
        .sight_cache_data(&lighting)
        .unwrap()
        .expect("a glossy frame made the cache");
    let fit = glossy::SurfaceFit {
        per_tri: &per_tri,
        gtri: &g.tri,
        sight: Some(glossy::CachedSight {
            layout: sight.layout,
            vis: &sight.vis,
            cols: &sight.cols,
        }),
    };
    let want = glossy::reference(&inputs, &t.mesh, &comp, &irr, &fit);
    assert_planes_match(&gl, &want, npix, "sight cache");
    let fit = glossy::SurfaceFit { sight: None, ..fit };
    let want_traced = glossy::reference(&inputs, &t.mesh, &comp, &irr, &fit);
    assert_planes_match(&traced, &want_traced, npix, "rays");
    // The cache stands in for the rays: the penumbrae's middle where the rays to the lights'
    // centres put the shadows' edges.
    assert_planes_match(&gl, &traced, npix, "cache against rays");
    // The floor's fit: most floor pixels fitted, led by the photos' lobe (GLOSSY_LOBE_2: the
    // second, plane value 2), D between the darkest photo and I_1.
    let floor: Vec<usize> = (0..npix)
        .filter(|&p| g.pos_depth[p][3] > 0.0 && g.pos_depth[p][1].abs() < 1e-3)
        .collect();
    assert!(floor.len() * 3 > npix, "the novel view looks at the floor");
    let fitted: Vec<usize> = floor
        .iter()
        .copied()
        .filter(|&p| gl[npix + p][3] > 0.0)
        .collect();
    // Where enough views see the point and the panel, its sums hold views.
    let fittable = floor
        .iter()
        .filter(|&&p| sums[2 * npix + p][1] > 0.0)
        .count();
    assert!(
        fittable * 3 > floor.len(),
        "{fittable} of {} floor pixels have sums",
        floor.len()
    );
    // Many of them see the panel through no view's lobe: their photos agree (within
    // GLOSSY_SPREAD) and are rightly taken as diffuse. A fifth must hold a fit.
    assert!(
        fitted.len() * 5 >= fittable,
        "{} of {fittable} floor pixels fitted",
        fitted.len()
    );
    let led = fitted.iter().filter(|&&p| gl[npix + p][3] == 2.0).count();
    assert!(
        led * 10 >= fitted.len() * 8,
        "{led} of {} fits led by lobe 2",
        fitted.len()
    );
    for &p in &fitted {
        for k in 0..3 {
            let lo = comp[7 * npix + p][k].min(comp[p][k]);
            assert!(
                gl[p][k] <= comp[p][k] + 1e-6 && gl[p][k] >= lo - 1e-6,
                "D at pixel {p}"
            );
        }
    }
    // Vertical surfaces are diffuse in the photos: (almost) no fit there.
    let walls = (0..npix).filter(|&p| g.pos_depth[p][3] > 0.0 && g.normal[p][1].abs() < 0.1);
    let (nw, wf) = walls.fold((0, 0), |(n, f), p| {
        (n + 1, f + (gl[npix + p][3] > 0.0) as usize)
    });
    assert!(wf * 20 <= nw, "{wf} of {nw} wall pixels fitted");

    // Glossy mode: D relit by eq. 5 plus S, the lights drawn over it.
    let image = glossy::reference_image(&gl, &irr, npix);
    let image: Vec<[f32; 3]> = (0..npix)
        .map(|p| {
            if g.pos_depth[p][3] > 0.0 {
                image[p]
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
    let image = emitters::reference_emitters(
        &t.novel,
        &g.pos_depth,
        (&comp, &irr[npix..2 * npix]),
        &drawn,
        &image,
    );
    for p in 0..npix {
        for k in 0..3 {
            let w = image[p][k];
            assert!(
                (hdr[p][k] - w).abs() <= 1e-5 * w.abs().max(1.0),
                "pixel {p}: {} vs {w}",
                hdr[p][k]
            );
        }
    }

    original_lighting_moves_the_photos_highlights(&mut r, &t);
    // One original light at factor c is α_dim' = α + (1 − α)(1 − c) for the whole frame, the
    // photos' own highlights (S's first term) included: per-light control's glossy term.
    let frame = |r: &mut Renderer, l: &Lighting| {
        r.render(&t.novel, l, Mode::Glossy, 1.0, None).unwrap();
        let b = r.buffers_ref().unwrap();
        (planes(&b.glossy, glossy::PLANES * npix), r.hdr().unwrap())
    };
    let factor = Lighting {
        intensities: vec![0.8],
        alpha_dim: 0.5,
        originals: vec![[0.5; 3]],
    };
    let global = Lighting {
        intensities: vec![0.8],
        alpha_dim: 0.75,
        ..Default::default()
    };
    let (a, b) = (frame(&mut r, &factor), frame(&mut r, &global));
    for (x, y) in a.0.iter().chain(&a.1).zip(b.0.iter().chain(&b.1)) {
        for k in 0..3 {
            assert!(
                (x[k] - y[k]).abs() <= 1e-5 * y[k].abs().max(1.0),
                "{x:?} vs {y:?}"
            );
        }
    }
    common::assert_no_validation_errors(&gpu);
}

#[test]
fn the_fit_per_surface_finds_the_floors_strength_and_leaves_the_walls_diffuse() {
    let gpu = common::gpu();
    let t = room();
    let mut r = renderer(&gpu, &t);
    let lighting = Lighting {
        intensities: vec![0.0],
        ..Default::default()
    };
    r.render(&t.novel, &lighting, Mode::Glossy, 1.0, None)
        .unwrap();
    let fit = r
        .glossy_fit()
        .unwrap()
        .expect("a glossy frame made the fit");
    // The fits, then the surface normals.
    assert_eq!(fit.len(), 2 * t.mesh.triangles.len());
    let (fit, normals) = fit.split_at(t.mesh.triangles.len());
    let (mut floor, mut floor_ok, mut walls, mut walls_fit) = (0, 0, 0, 0);
    for (i, f) in fit.iter().enumerate() {
        let n = t.mesh.face_normal(i);
        let y = t.mesh.positions[t.mesh.triangles[i][0] as usize][1];
        if n.y > 0.99 && y.abs() < 1e-3 {
            // (Facing up: the boxes' bottoms lie on the floor too.) The photos' lobe (GLOSSY_LOBE_2) alone, at S_TRUE within 15 %.
            floor += 1;
            let ok = f[0] == 0.0 && f[2] == 0.0 && (f[1] - S_TRUE).abs() <= 0.15 * S_TRUE;
            // A flat floor's triangles take its normal.
            assert!(normals[i][1].abs() > 0.9999, "{:?}", normals[i]);
            floor_ok += ok as usize;
        } else if n.y.abs() < 0.1 {
            walls += 1;
            walls_fit += (f[..3] != [0.0; 3]) as usize;
        }
    }
    assert!(floor > 0 && walls > 0);
    assert!(
        floor_ok * 10 >= floor * 9,
        "{floor_ok} of {floor} floor triangles hold S_TRUE in lobe 2"
    );
    assert!(
        walls_fit * 20 <= walls,
        "{walls_fit} of {walls} wall triangles fitted"
    );
    common::assert_no_validation_errors(&gpu);
}

/// Under the original lighting glossy mode is ratio's image (the photos' blend) where the layer
/// has no fit, and on the fitted pixels D plus the photos' highlights moved to the novel view:
/// nearer the truth than the blend of the photos' own highlights, by half at least.
fn original_lighting_moves_the_photos_highlights(r: &mut Renderer, t: &Room) {
    let original = Lighting {
        intensities: vec![0.0],
        alpha_dim: 0.0,
        ..Default::default()
    };
    r.render(&t.novel, &original, Mode::Glossy, 1.0, None)
        .unwrap();
    let glossy_hdr = r.hdr().unwrap();
    let npix = glossy_hdr.len();
    let gl = planes(&r.buffers_ref().unwrap().glossy, glossy::PLANES * npix);
    r.render(&t.novel, &original, Mode::Ratio, 1.0, None)
        .unwrap();
    let ratio_hdr = r.hdr().unwrap();
    let (mut err_g, mut err_r) = (0.0, 0.0);
    for p in 0..npix {
        for k in 0..3 {
            let (a, b) = (glossy_hdr[p][k], ratio_hdr[p][k]);
            if gl[npix + p][3] > 0.0 {
                err_g += (a - t.novel_truth[p][k]).abs();
                err_r += (b - t.novel_truth[p][k]).abs();
            } else {
                assert!(
                    (a - b).abs() <= 1e-5 * b.abs().max(1.0),
                    "original lighting, pixel {p} (no fit): {a} vs {b}"
                );
            }
        }
    }
    assert!(
        err_g <= 0.5 * err_r,
        "fitted pixels' error against the truth: glossy {err_g}, ratio {err_r}"
    );
}

/// The novel-view pixel where a horizontal plane at height `h` (the floor, a table top)
/// mirrors `lamp` towards the eye.
fn mirror_pixel(cam: &Camera, lamp: Vec3, h: f32) -> Vec2 {
    let e = cam.center();
    let l = Vec3::new(lamp.x, 2.0 * h - lamp.y, lamp.z);
    let m = e + (l - e) * ((e.y - h) / (e.y - l.y));
    let q = cam.to_camera(m);
    Vec2::new(cam.fx * q.x / q.z + cam.cx, cam.fy * q.y / q.z + cam.cy)
}

/// Where the lamp's highlight peaks near `want`: among the fitted pixels of horizontal surfaces
/// (the floor, the table: the photos' glossy ones) within 6 px, the one whose view-dependent
/// part per unit of strength (luminance of S / Σ w_c) is largest. Also that value.
fn highlight_near(r: &Renderer, npix: usize, width: u32, want: Vec2) -> (Vec2, f32) {
    let b = r.buffers_ref().unwrap();
    let gl = planes(&b.glossy, 2 * npix);
    let g = b.gbuf.download().unwrap();
    let s = |p: usize| gl[npix + p];
    let lum = |p: usize| (0.2126 * s(p)[0] + 0.7152 * s(p)[1] + 0.0722 * s(p)[2]) / gl[p][3];
    let at = |p: usize| {
        Vec2::new(
            (p as u32 % width) as f32 + 0.5,
            (p as u32 / width) as f32 + 0.5,
        )
    };
    let near = (0..npix)
        .filter(|&p| g.pos_depth[p][3] > 0.0 && g.normal[p][1].abs() > 0.99 && gl[p][3] > 0.0);
    let p = near
        .filter(|&p| at(p).distance(want) <= 6.0)
        .max_by(|&a, &b| lum(a).total_cmp(&lum(b)))
        .expect("fitted pixels near the mirror point");
    (at(p), lum(p))
}

/// The mirror pixel of `lamp` on the horizontal surface the camera sees there (the floor, or
/// the table top in front of it).
fn mirror_on_surface(r: &Renderer, cam: &Camera, lamp: Vec3) -> Vec2 {
    let pos = r.buffers_ref().unwrap().gbuf.download().unwrap().pos_depth;
    let mut want = mirror_pixel(cam, lamp, 0.0);
    for _ in 0..2 {
        let p =
            (want.y as u32).min(cam.height - 1) * cam.width + (want.x as u32).min(cam.width - 1);
        want = mirror_pixel(cam, lamp, pos[p as usize][1]);
    }
    want
}

#[test]
fn a_lamps_highlight_sits_where_the_mirror_direction_puts_it_and_moves_with_it() {
    let gpu = common::gpu();
    let t = room();
    let mut r = renderer(&gpu, &t);
    // The lamp alone: the ceiling panel off, so the floor's view-dependent part is the lamp's.
    let alone = Lighting {
        intensities: vec![1.0],
        alpha_dim: 1.0,
        ..Default::default()
    };
    let npix = (t.novel.width * t.novel.height) as usize;
    let mut seen = Vec::new();
    for (i, c) in [Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.45, 2.0, -0.2)]
        .into_iter()
        .enumerate()
    {
        if i > 0 {
            // Moved as the viewer moves it: live, no bake.
            r.set_live_light(0, &lamp_at(c)).unwrap();
        }
        r.render(&t.novel, &alone, Mode::Glossy, 1.0, None).unwrap();
        let want = mirror_on_surface(&r, &t.novel, c);
        let (got, value) = highlight_near(&r, npix, t.novel.width, want);
        assert!(value > 0.03, "lamp at {c}: a highlight shows ({value})");
        assert!(
            got.distance(want) <= 2.0,
            "lamp at {c}: highlight at {got}, the mirror direction puts it at {want}"
        );
        seen.push((got, want));
    }
    let (moved, predicted) = (seen[1].0 - seen[0].0, seen[1].1 - seen[0].1);
    assert!(
        predicted.length() > 4.0,
        "the test moves the mirror point: {predicted}"
    );
    assert!(
        moved.distance(predicted) <= 2.0,
        "the highlight moves with the lamp: {moved} (mirror point: {predicted})"
    );
    common::assert_no_validation_errors(&gpu);
}

/// The sight cache (frame/sight_cache.rs) against its CPU reference: each point's count of the
/// rays to its lights' areas equal at ≥ 99 % of the point-light pairs (a ray grazing an edge may
/// go either way in two tracers), and on the floor around the table it holds the lamp's full
/// shadow, the fully lit floor and the panel's penumbrae between.
#[test]
fn sight_cache_matches_cpu_reference() {
    use relit_engine::constants::SIGHT_CACHE_SAMPLES;
    use relit_engine::frame::sight_cache::{self, WORDS};
    let gpu = common::gpu();
    let t = room();
    let mut r = renderer(&gpu, &t);
    let lighting = Lighting {
        intensities: vec![1.0],
        alpha_dim: 0.5,
        ..Default::default()
    };
    // The panel alone first (its column), then the lamp lit too: the cache grows its column.
    let off = Lighting {
        intensities: vec![0.0],
        ..lighting.clone()
    };
    r.rebuild_sight_cache(&off).unwrap();
    assert_eq!(r.sight_cache_size().1, 1);
    r.render(&t.novel, &lighting, Mode::Glossy, 1.0, None)
        .unwrap();
    let got = r.sight_cache_data(&lighting).unwrap().unwrap();
    // The panel (original) first, then the lamp; both columns read, the lamp's marked small
    // (its hard shadows' edges trace).
    assert_eq!(got.lights.len(), 2);
    assert_eq!(&got.cols[..2], &[0, 1 | sight_cache::SHARP]);
    let want = sight_cache::reference(&r.scene.geom, got.layout, &got.lights);
    let count = |v: &[u32], p: usize, c: usize| v[p * WORDS + c / 4] >> (8 * (c % 4)) & 255;
    let points = got.layout.points();
    assert!(
        points > r.scene.geom.positions.len(),
        "large triangles take grids"
    );
    let mut differ = 0;
    for p in 0..points {
        for c in 0..2 {
            differ += (count(&got.vis, p, c) != count(&want, p, c)) as usize;
        }
    }
    assert!(
        differ * 100 <= 2 * points,
        "{differ} of {} counts differ",
        2 * points
    );
    let floor: Vec<usize> = (0..points)
        .filter(|&p| got.layout.pos[p][1].abs() < 1e-4 && got.layout.pos[p][0].abs() < 1.2)
        .collect();
    for (c, what) in [(0, "panel"), (1, "lamp")] {
        let n = |f: &dyn Fn(u32) -> bool| floor.iter().filter(|&&p| f(count(&want, p, c))).count();
        let (dark, lit) = (n(&|k| k == 0), n(&|k| k == SIGHT_CACHE_SAMPLES));
        let part = n(&|k| k > 0 && k < SIGHT_CACHE_SAMPLES);
        assert!(
            dark > 0 && lit > 0 && part > 0,
            "{what}: floor points dark {dark}, lit {lit}, partly {part}"
        );
    }
    // A lamp moved live has no column while it moves; one that has settled (its cache
    // finished, where it was in the last frame) gets one.
    let moved = lamp_at(Vec3::new(0.45, 2.0, -0.2));
    let finished = vec![[0.0f32; 4]; r.live.layout().texels()];
    r.set_live_light(0, &moved).unwrap();
    r.render(&t.novel, &lighting, Mode::Glossy, 1.0, None)
        .unwrap();
    let cols = r.sight_cache_data(&lighting).unwrap().unwrap().cols;
    assert_eq!(cols[1], sight_cache::NO_COLUMN, "a moving lamp traces");
    r.set_live_light_cached(0, &moved, finished).unwrap();
    for _ in 0..2 {
        r.render(&t.novel, &lighting, Mode::Glossy, 1.0, None)
            .unwrap();
    }
    let got = r.sight_cache_data(&lighting).unwrap().unwrap();
    assert_eq!(got.lights.len(), 3);
    assert_eq!(
        got.cols[1],
        2 | sight_cache::SHARP,
        "the settled lamp reads its column"
    );
    common::assert_no_validation_errors(&gpu);
}
