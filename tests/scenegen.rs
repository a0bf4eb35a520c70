//! scenegen: tessellation, lights and conditions, cameras, and the proxy mesh's degradations.

mod common;

use glam::Vec3;
use relit_engine::scene::synth::Rng;
use relit_engine::scene::{LightShape, Scene};
use relit_scenegen::prim::{tessellate, Prim};
use relit_scenegen::proxy::{degrade, ProxyParams};
use relit_scenegen::room::{self, Object, RoomOptions, Surface, CONDITION_POWER};

fn small() -> RoomOptions {
    RoomOptions {
        views: 6,
        width: 32,
        height: 24,
        extra_lights: 3,
        test_views: 2,
        light_views: 3,
        lamp_colours: Default::default(),
        proxy_error: 1.0,
        finishes: Default::default(),
    }
}

#[test]
fn tessellated_normals_follow_the_winding() {
    let prims = [
        Prim::Box {
            lo: Vec3::ZERO,
            hi: Vec3::new(1.0, 0.5, 0.3),
            inward: false,
        },
        Prim::Box {
            lo: Vec3::ZERO,
            hi: Vec3::new(1.0, 0.5, 0.3),
            inward: true,
        },
        Prim::Cylinder {
            base: Vec3::new(0.2, 0.0, 0.1),
            radius: 0.3,
            height: 0.8,
        },
        Prim::Quad {
            corner: Vec3::ZERO,
            u: Vec3::X,
            v: Vec3::Z * 0.5,
        },
    ];
    for p in &prims {
        let m = tessellate(p, 0.1);
        assert!(!m.triangles.is_empty());
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let face = (b - a).cross(c - a).normalize();
            let vn =
                (m.normals[t[0] as usize] + m.normals[t[1] as usize] + m.normals[t[2] as usize])
                    .normalize();
            assert!(
                face.dot(vn) > 0.9,
                "{p:?}: winding normal {face} vs vertex normals {vn}"
            );
        }
    }
}

#[test]
fn lights_conditions_and_cameras_are_consistent() {
    let r = room::generate(5, &small());
    // Every condition emits CONDITION_POWER watts (luminance-weighted): Φ = π A L.
    for (name, lights) in &r.conditions {
        let p: f32 = lights
            .iter()
            .map(|n| {
                let l = r.lights.iter().find(|l| &l.name == n).unwrap();
                let lum = Vec3::from(l.radiance).dot(Vec3::new(0.2126, 0.7152, 0.0722));
                std::f32::consts::PI * l.shape.area() * lum
            })
            .sum();
        assert!(
            (p - CONDITION_POWER).abs() < 1e-3 * CONDITION_POWER,
            "{name}: {p} W"
        );
    }
    assert_eq!(r.conditions[0].0, "original");
    assert_eq!(r.conditions.len(), 1 + small().extra_lights);
    // Quad lights face into the room (their emitting side points away from the nearest wall).
    for l in &r.lights {
        if let LightShape::Quad { edge_u, edge_v, .. } = l.shape {
            let n = edge_u.cross(edge_v).normalize();
            let to_centre = (Vec3::new(0.0, r.size.y / 2.0, 0.0) - l.shape.center()).normalize();
            assert!(
                n.dot(to_centre) > 0.0,
                "light {} faces away from the room",
                l.name
            );
        }
    }
    assert_eq!(r.cameras.len(), small().views);
    for c in r.cameras.iter().chain(&r.test_cameras) {
        let p = c.center();
        assert!(
            p.x.abs() < r.size.x / 2.0 && p.z.abs() < r.size.z / 2.0 && p.y > 0.0 && p.y < r.size.y
        );
        c.validate().unwrap();
    }
}

/// An object of the room, not part of its shell.
fn obj(prim: Prim, surface: Surface) -> Object {
    Object {
        name: "o".into(),
        prim,
        material: "m".into(),
        surface,
        shell: false,
    }
}

/// A 2.5 × 4 m textureless wall (the kind of surface MVS leaves holes in).
fn textureless_wall() -> Object {
    let prim = Prim::Quad {
        corner: Vec3::ZERO,
        u: Vec3::Y * 2.5,
        v: Vec3::Z * 4.0,
    };
    Object {
        shell: true,
        ..obj(prim, Surface::Textureless)
    }
}

#[test]
fn proxy_loses_thin_parts_rounds_corners_and_stays_near_the_surface() {
    let p = ProxyParams::default();
    let mut rng = Rng::new(1);
    // A 1.5 cm leg is lost.
    let leg = obj(
        Prim::Box {
            lo: Vec3::ZERO,
            hi: Vec3::new(0.015, 0.4, 0.015),
            inward: false,
        },
        Surface::Textured,
    );
    assert!(degrade(&leg, &p, &mut rng).triangles.is_empty());
    // A box keeps its extent up to the noise, and no vertex stays on a sharp corner.
    let (lo, hi) = (Vec3::ZERO, Vec3::new(0.6, 0.4, 0.5));
    let b = obj(
        Prim::Box {
            lo,
            hi,
            inward: false,
        },
        Surface::Textured,
    );
    let m = degrade(&b, &p, &mut rng);
    assert!(!m.triangles.is_empty());
    let slack = Vec3::splat(p.noise_amp + 1e-4);
    for q in &m.positions {
        assert!(
            q.cmpge(lo - slack).all() && q.cmple(hi + slack).all(),
            "{q} outside the box"
        );
        let corner_dist = [lo, hi]
            .iter()
            .flat_map(|a| [lo, hi].map(move |b| (a, b)))
            .flat_map(|(a, b)| [lo, hi].map(move |c| Vec3::new(a.x, b.y, c.z)))
            .map(|c| (*q - c).length())
            .fold(f32::MAX, f32::min);
        assert!(corner_dist > 0.005, "vertex {q} sits on a sharp corner");
    }
    // Large textureless walls get holes at this seed (hole_prob 1).
    let holes = ProxyParams {
        hole_prob: 1.0,
        ..p.clone()
    };
    let wall = textureless_wall();
    let full = tessellate(&wall.prim, p.edge).triangles.len();
    let holed = degrade(&wall, &holes, &mut rng).triangles.len();
    assert!(holed < full, "no hole: {holed} of {full}");
}

#[test]
fn proxy_error_scales_the_degradation_and_zero_keeps_the_true_surfaces() {
    let d = ProxyParams::default();
    let half = ProxyParams::scaled(3, 0.5);
    assert_eq!((half.seed, half.edge), (3, d.edge));
    for (h, f) in [
        (half.noise_amp, d.noise_amp),
        (half.wall_bump_amp, d.wall_bump_amp),
        (half.corner_radius, d.corner_radius),
        (half.thin, d.thin),
        (half.hole_prob, d.hole_prob),
    ] {
        assert!((h - 0.5 * f).abs() < 1e-7, "{h} is not half of {f}");
    }
    assert_eq!(ProxyParams::scaled(3, 7.0).noise_amp, d.noise_amp);
    let exact = ProxyParams::scaled(3, 0.0);
    let mut rng = Rng::new(1);
    // A 1.5 cm leg is kept, and a box's vertices lie on its faces (no noise, no rounding).
    let leg = Prim::Box {
        lo: Vec3::ZERO,
        hi: Vec3::new(0.015, 0.4, 0.015),
        inward: false,
    };
    assert!(!degrade(&obj(leg, Surface::Textured), &exact, &mut rng)
        .triangles
        .is_empty());
    let (lo, hi) = (Vec3::ZERO, Vec3::new(0.6, 0.4, 0.5));
    let b = Prim::Box {
        lo,
        hi,
        inward: false,
    };
    for q in &degrade(&obj(b, Surface::Textured), &exact, &mut rng).positions {
        let face = (*q - lo).abs().min((*q - hi).abs()).min_element();
        assert!(
            face < 1e-5 && q.cmpge(lo - 1e-5).all() && q.cmple(hi + 1e-5).all(),
            "{q}"
        );
    }
    // A textureless wall keeps every triangle.
    let wall = textureless_wall();
    let full = tessellate(&wall.prim, exact.edge).triangles.len();
    assert_eq!(degrade(&wall, &exact, &mut rng).triangles.len(), full);
}

#[test]
fn generated_scenes_load_and_are_deterministic() {
    let a = common::tempdir("scenegen-a");
    let b = common::tempdir("scenegen-b");
    relit_scenegen::generate(&a, 21, &small()).unwrap();
    relit_scenegen::generate(&b, 21, &small()).unwrap();
    let ja = std::fs::read_to_string(a.join("scene.json")).unwrap();
    let jb = std::fs::read_to_string(b.join("scene.json")).unwrap();
    assert_eq!(ja, jb.replace(b.to_str().unwrap(), a.to_str().unwrap()));
    assert_eq!(
        std::fs::read(a.join("mesh.ply")).unwrap(),
        std::fs::read(b.join("mesh.ply")).unwrap()
    );
    let s = Scene::load(&a).unwrap();
    let syn = s.synthetic.as_ref().unwrap();
    assert_eq!(syn.test_views.len(), 2);
    assert!(s.true_mesh_path.as_ref().unwrap().exists());
    // The proxy differs from the true mesh (degraded), but spans the same room.
    let t = relit_engine::scene::Mesh::load(s.true_mesh_path.as_ref().unwrap()).unwrap();
    let (tl, th) = t.bounds();
    let (pl, ph) = s.mesh.bounds();
    assert!((tl - pl).abs().max_element() < 0.05 && (th - ph).abs().max_element() < 0.05);
    assert_ne!(t.triangles.len(), s.mesh.triangles.len());
}

#[test]
fn synthetic_block_is_validated() {
    let d = common::tempdir("scenegen-bad");
    relit_scenegen::generate(&d, 3, &small()).unwrap();
    let p = d.join("scene.json");
    let s = std::fs::read_to_string(&p).unwrap();
    std::fs::write(&p, s.replacen("\"extra0\"\n", "\"extra9\"\n", 1)).unwrap();
    let err = Scene::load(&d).unwrap_err().to_string();
    assert!(
        err.contains("scene.json") && err.contains("extra9"),
        "{err}"
    );
    std::fs::write(
        &p,
        s.replacen("\"material\": \"wall\"", "\"material\": \"marble\"", 1),
    )
    .unwrap();
    let err = Scene::load(&d).unwrap_err().to_string();
    assert!(
        err.contains("marble") && err.contains("not defined"),
        "{err}"
    );
}

#[test]
fn mesh_processing_snaps_the_proxys_planes_and_smooths_it() {
    use relit_engine::scene::meshproc::{smooth, snap_planes, vertex_normals, PlaneParams};
    let d = common::tempdir("meshproc");
    relit_scenegen::generate(&d, 4, &small()).unwrap();
    let s = Scene::load(&d).unwrap();
    // Floor vertices of the proxy: near y = 0 (noise and bumps up to ~2 cm), facing up.
    let vn = vertex_normals(&s.mesh);
    let floor: Vec<usize> = (0..s.mesh.positions.len())
        .filter(|&i| s.mesh.positions[i][1].abs() < 0.03 && vn[i].y > 0.9)
        .collect();
    let spread = |m: &relit_engine::scene::Mesh| {
        floor
            .iter()
            .map(|&i| (m.positions[i][1] as f64).powi(2))
            .sum::<f64>()
    };
    let before = spread(&s.mesh);
    let mut smoothed = s.mesh.clone();
    smooth(&mut smoothed, 2);
    assert!(
        spread(&smoothed) < before,
        "smoothing must flatten the bumpy floor"
    );
    let mut snapped = s.mesh.clone();
    let planes = snap_planes(&mut snapped, &PlaneParams::default());
    assert!(planes.len() >= 4, "floor, ceiling and walls: {planes:?}");
    let fl = planes
        .iter()
        .find(|p| p.normal.y.abs() > 0.99 && p.d.abs() < 0.02)
        .expect("a floor plane at y = 0");
    assert!(fl.inliers > 400);
    assert!(
        spread(&snapped) < 0.25 * before,
        "snapping must flatten the floor: {} -> {}",
        before,
        spread(&snapped)
    );
}

/// Options of the coverage tests: the default capture (32 views, 3 views per original light) at
/// a small resolution; coverage does not depend on it (intrinsics scale with the image).
fn capture(light_views: usize) -> RoomOptions {
    RoomOptions {
        width: 64,
        height: 48,
        light_views,
        ..Default::default()
    }
}

#[test]
fn default_capture_views_see_every_original_light_three_times() {
    use relit_engine::scene::{light_coverage, MIN_VIEWS_PER_LIGHT};
    let dir = common::tempdir("scenegen-coverage");
    for seed in 1..=8 {
        let s = relit_scenegen::generate(&dir, seed, &capture(3)).unwrap();
        assert_eq!(s.views.len(), 32);
        let cov = light_coverage(&s);
        assert_eq!(cov.len(), s.lights.iter().filter(|l| l.original).count());
        for c in &cov {
            eprintln!("seed {seed}: {}", c.summary());
            assert!(
                c.views() >= MIN_VIEWS_PER_LIGHT,
                "seed {seed}: {}",
                c.summary()
            );
        }
        // The light views come first and each sees its light (taken in turn) nearly whole.
        for (k, c) in cov.iter().cycle().take(3 * cov.len()).enumerate() {
            let sight = c.seen_by.iter().find(|v| v.view == k);
            assert!(
                sight.is_some_and(|v| v.visible >= 0.75),
                "seed {seed}: view {k} is aimed at {} but sees {sight:?}",
                c.name
            );
        }
    }
}

#[test]
fn scene_check_warns_about_a_light_few_views_see() {
    use relit_engine::scene::image::{write_exr, RgbImage};
    // Seed 4 without light views: 0 of 32 views see its ceiling panel (its window: 11).
    let dir = common::tempdir("scenegen-few-views");
    let s = relit_scenegen::generate(&dir, 4, &capture(0)).unwrap();
    let mut img = RgbImage::new(64, 48);
    img.pixels.fill([0.5; 3]);
    for v in &s.views {
        write_exr(&v.image, &img).unwrap();
    }
    for quick in [false, true] {
        let mut args = vec!["scene", "check", dir.to_str().unwrap()];
        if quick {
            args.push("--quick");
        }
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_relit"))
            .args(&args)
            .output()
            .unwrap();
        let (stdout, stderr) = (
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr),
        );
        assert_eq!(out.status.code(), Some(0), "{stdout}\n{stderr}");
        assert!(
            stdout.contains("light ceiling0: seen by 0 of 32 views"),
            "{stdout}"
        );
        assert!(stdout.contains("light window: seen by "), "{stdout}");
        let warnings: Vec<&str> = stderr
            .lines()
            .filter(|l| l.starts_with("warning:"))
            .collect();
        assert_eq!(warnings.len(), 1, "{stderr}");
        assert!(
            warnings[0].starts_with(
                "warning: original light 'ceiling0' is seen by 0 of 32 input views (fewer than 3)"
            ) && warnings[0].contains("next-event estimation"),
            "{stderr}"
        );
    }
    // The default capture has light views: no warning.
    let ok = common::tempdir("scenegen-light-views");
    relit_scenegen::generate(&ok, 4, &capture(3)).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_relit"))
        .args(["scene", "check", ok.to_str().unwrap(), "--quick"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(!stderr.contains("warning:"), "{stderr}");
}

/// `LampColours::Mixed` tints about half the added lights with saturated colours (a channel
/// under 0.5 of the largest) and changes nothing else: the same room, cameras, light shapes and
/// powers (luminance of the radiance) as `Mild`.
#[test]
fn mixed_lamp_colours_saturate_some_lamps_and_change_nothing_else() {
    let lum = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let sat = |c: [f32; 3]| {
        let m = c[0].max(c[1]).max(c[2]);
        c.iter().any(|&v| v < 0.5 * m)
    };
    let (mut saturated, mut total) = (0, 0);
    for seed in 1..=8 {
        let mild = room::generate(
            seed,
            &RoomOptions {
                extra_lights: 6,
                ..small()
            },
        );
        let mixed = room::generate(
            seed,
            &RoomOptions {
                extra_lights: 6,
                lamp_colours: room::LampColours::Mixed,
                ..small()
            },
        );
        assert_eq!(
            format!("{:?}", mild.objects),
            format!("{:?}", mixed.objects)
        );
        assert_eq!(
            format!("{:?}", mild.cameras),
            format!("{:?}", mixed.cameras)
        );
        for (a, b) in mild.lights.iter().zip(&mixed.lights) {
            assert_eq!(format!("{:?}", a.shape), format!("{:?}", b.shape));
            let (la, lb) = (lum(a.radiance), lum(b.radiance));
            assert!(
                (la - lb).abs() <= 1e-4 * la,
                "{}: power {la} vs {lb}",
                a.name
            );
            assert!(!sat(a.radiance), "{}: mild lamp {:?}", a.name, a.radiance);
            if !b.original {
                total += 1;
                saturated += sat(b.radiance) as usize;
            }
        }
    }
    assert!(
        (total / 4..=3 * total / 4).contains(&saturated),
        "{saturated} of {total} lamps saturated"
    );
}

/// `Finishes::Varied` keeps the classic room of the seed (every object and light) and adds what
/// hand_room2 has: walls of their own colours (some saturated), a near-mirror and a lacquered
/// cabinet, marked glossy so the proxy degrades them as MVS would.
#[test]
fn varied_finishes_add_coloured_walls_a_mirror_and_a_cabinet_and_change_nothing_else() {
    let (mut mirrors, mut cabinets, mut saturated) = (0, 0, 0);
    for seed in 1..=8 {
        let classic = room::generate(seed, &small());
        let varied = room::generate(
            seed,
            &RoomOptions {
                finishes: room::Finishes::Varied,
                ..small()
            },
        );
        assert_eq!(
            format!("{:?}", classic.lights),
            format!("{:?}", varied.lights)
        );
        for o in &classic.objects {
            let v = varied.objects.iter().find(|v| v.name == o.name).unwrap();
            assert_eq!(
                format!("{:?}", o.prim),
                format!("{:?}", v.prim),
                "{}",
                o.name
            );
            assert_eq!(
                o.name.starts_with("wall_"),
                o.material != v.material,
                "{}",
                o.name
            );
        }
        let walls: std::collections::BTreeSet<_> = varied
            .objects
            .iter()
            .filter(|o| o.name.starts_with("wall_"))
            .map(|o| o.material.clone())
            .collect();
        assert_eq!(walls.len(), 4, "seed {seed}: one material per wall");
        for w in &walls {
            let a = varied.materials[w].doc.albedo;
            let max = a.iter().cloned().fold(0.0, f32::max);
            saturated += a.iter().any(|&c| c < 0.5 * max) as usize;
        }
        for o in varied.objects.iter().skip(classic.objects.len()) {
            let m = &varied.materials[&o.material].doc;
            assert_eq!(o.surface, Surface::Glossy, "{}", o.name);
            match o.name.as_str() {
                "mirror" => {
                    assert!(m.kind == "conductor" && m.roughness <= 0.05, "{m:?}");
                    mirrors += 1;
                }
                "cabinet" => {
                    assert!(m.kind == "plastic" && m.roughness <= 0.1, "{m:?}");
                    cabinets += 1;
                }
                n => panic!("seed {seed}: unexpected object {n}"),
            }
        }
    }
    assert!(
        mirrors >= 6 && cabinets >= 6,
        "{mirrors} mirrors, {cabinets} cabinets"
    );
    assert!(
        (6..=26).contains(&saturated),
        "{saturated} of 32 walls saturated"
    );
}

/// The varied room of `seed` and the room of other `finishes` made from it, whose lights are
/// the varied room's.
fn beside_varied(seed: u64, finishes: room::Finishes) -> (room::Room, room::Room) {
    let opts = |finishes| RoomOptions {
        finishes,
        ..small()
    };
    let varied = room::generate(seed, &opts(room::Finishes::Varied));
    let other = room::generate(seed, &opts(finishes));
    assert_eq!(
        format!("{:?}", varied.lights),
        format!("{:?}", other.lights),
        "seed {seed}: {finishes:?} keeps the lights"
    );
    (varied, other)
}

/// `Finishes::Sparse` is the varied room of the seed with only the shell, table, chair, mirror
/// and cabinet left, nothing textured, everything but the mirror and cabinet matte, the same
/// lights, and no material nothing uses.
#[test]
fn sparse_finishes_keep_the_varied_shell_and_few_objects_all_untextured() {
    for seed in 1..=8 {
        let (varied, sparse) = beside_varied(seed, room::Finishes::Sparse);
        assert!(sparse.objects.len() < varied.objects.len(), "seed {seed}");
        for o in &sparse.objects {
            let v = varied.objects.iter().find(|v| v.name == o.name).unwrap();
            assert_eq!(format!("{:?}", o.prim), format!("{:?}", v.prim));
            assert_eq!(o.material, v.material, "{}", o.name);
            assert_ne!(o.surface, Surface::Textured, "{}", o.name);
            let keep = ["table_", "chair_", "mirror", "cabinet"];
            assert!(
                o.shell || keep.iter().any(|k| o.name.starts_with(k)),
                "seed {seed}: {} kept",
                o.name
            );
        }
        for o in varied.objects.iter().filter(|o| o.shell) {
            assert!(
                sparse.objects.iter().any(|s| s.name == o.name),
                "{}",
                o.name
            );
        }
        for (name, m) in &sparse.materials {
            assert!(
                m.texture.is_none() && m.doc.albedo_texture.is_none(),
                "{name}"
            );
            assert!(
                sparse.objects.iter().any(|o| o.material == *name),
                "{name} unused"
            );
            let v = &varied.materials[name].doc;
            if name == "mirror" || name == "cabinet" {
                assert_eq!(
                    format!("{:?}", m.doc),
                    format!("{v:?}"),
                    "{name}: kept glossy"
                );
                continue;
            }
            assert_eq!(m.doc.kind, "diffuse", "{name}: matte");
            let a = if v.kind == "conductor" {
                v.specular
            } else {
                v.albedo
            };
            assert_eq!(
                m.doc.albedo, a,
                "{name}: the texture's mean (a metal's colour)"
            );
        }
    }
}

/// `Finishes::Matte` is the varied room of the seed with every object, light and texture kept
/// and only the gloss gone: every material but the mirror's and the cabinet's diffuse (a
/// metal's colour as its albedo), and no surface the proxy treats as glossy but those two.
#[test]
fn matte_finishes_keep_the_varied_room_and_take_only_the_gloss() {
    let mut glossy_floors = 0;
    for seed in 1..=8 {
        let (varied, matte) = beside_varied(seed, room::Finishes::Matte);
        assert_eq!(varied.objects.len(), matte.objects.len(), "seed {seed}");
        for (o, v) in matte.objects.iter().zip(&varied.objects) {
            assert_eq!(o.name, v.name);
            assert_eq!(format!("{:?}", o.prim), format!("{:?}", v.prim));
            assert_eq!(o.material, v.material, "{}", o.name);
            let kept = o.material == "mirror" || o.material == "cabinet";
            assert_eq!(
                o.surface == Surface::Glossy,
                kept && v.surface == Surface::Glossy
            );
        }
        let floor = &varied.objects.iter().find(|o| o.name == "floor").unwrap();
        glossy_floors += (varied.materials[&floor.material].doc.kind != "diffuse") as usize;
        for (name, m) in &matte.materials {
            let v = &varied.materials[name];
            assert_eq!(
                m.doc.albedo_texture, v.doc.albedo_texture,
                "{name}: texture kept"
            );
            if name == "mirror" || name == "cabinet" {
                assert_eq!(format!("{:?}", m.doc), format!("{:?}", v.doc), "{name}");
                continue;
            }
            assert_eq!(m.doc.kind, "diffuse", "{name}: matte");
            let a = if v.doc.kind == "conductor" {
                v.doc.specular
            } else {
                v.doc.albedo
            };
            assert_eq!(m.doc.albedo, a, "{name}");
        }
    }
    assert_eq!(
        glossy_floors, 8,
        "every varied floor is glossy, so this test tests something"
    );
}
